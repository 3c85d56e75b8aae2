//! POSITIONS payloads: a band's quantized residuals in the rANS, plain-varint or sparse coding
//! (proto/container.md, "Positions").

use super::*;

/// Largest residual step a positions chunk may use (units of 2^shift quanta).
pub const MAX_SHIFT: u32 = 16;

/// Positions chunks code their first number as `shift + 32 * coding`: coding 0 is rANS (what
/// versions 3 and 4 always use), 1 plain zigzag varints, three per node.
const CODING_RANS: u32 = 0;
const CODING_VARINTS: u32 = 1;
/// Coding 2: only the nodes whose residuals are not all zero, each after the count of zero
/// nodes skipped to reach it. Skinning predicts most of a skinned band exactly, so its chunk
/// costs two bytes plus a few per node it misses instead of rANS's tables and states (23
/// bytes for a band of zeros) or three bytes per node.
const CODING_SPARSE: u32 = 2;
/// Bands up to this many nodes also try plain varints.
const SMALL_BAND: usize = 2048;

/// POSITIONS band j: `shift`, three rANS frequency tables (x, y, z), the rANS stream of the
/// residuals' zigzag codes (x y z per node; codes from `rans::ESCAPE` up are escaped), then
/// the escaped codes minus `ESCAPE` as varints, in decoding order. Residuals are in units of
/// `2^shift` quanta.
pub fn write_positions(shift: u32, residuals: &[[i32; 3]]) -> Vec<u8> {
    let rans = write_positions_rans(shift, residuals);
    let sparse = write_positions_sparse(shift, residuals);
    if residuals.len() > SMALL_BAND {
        // Neither compresses much further: the shorter as it is.
        return if sparse.len() < rans.len() { sparse } else { rans };
    }
    // A small band's three frequency tables and rANS states cost more than its residuals
    // save: plain varints under zstd take a quarter less for the horse's bands 3 to 5. The
    // encoder keeps whichever compresses smaller (the chunk is compressed either way).
    let mut plain = Vec::with_capacity(residuals.len() * 3 + 2);
    put(&mut plain, shift + 32 * CODING_VARINTS);
    for r in residuals {
        for &x in r {
            put(&mut plain, zigzag(x));
        }
    }
    // `compress` remembers the last three inputs, so the chosen payload, compressed again when
    // stored, is not compressed twice.
    let size =
        |b: &[u8]| crate::format::compress(b, crate::format::zstd_level(crate::ChunkKind::Positions, b)).map_or(usize::MAX, |z| z.len());
    let sparse_size = size(&sparse);
    let (rans_size, plain_size) = (size(&rans), size(&plain));
    if sparse_size < rans_size.min(plain_size) {
        sparse
    } else if plain_size < rans_size {
        plain
    } else {
        rans
    }
}

/// Coding 2 (see [`CODING_SPARSE`]): `shift + 64`, the count `k` of nodes listed, then per
/// listed node the number of unlisted (all-zero) nodes since the previous listed one (or the
/// band's start) and its three zigzag residuals.
fn write_positions_sparse(shift: u32, residuals: &[[i32; 3]]) -> Vec<u8> {
    let listed = residuals.iter().filter(|r| **r != [0; 3]).count();
    let mut out = Vec::with_capacity(2 + listed * 5);
    put(&mut out, shift + 32 * CODING_SPARSE);
    put(&mut out, listed as u32);
    let mut gap = 0u32;
    for r in residuals {
        if *r == [0; 3] {
            gap += 1;
            continue;
        }
        put(&mut out, gap);
        gap = 0;
        for &x in r {
            put(&mut out, zigzag(x));
        }
    }
    out
}

fn write_positions_rans(shift: u32, residuals: &[[i32; 3]]) -> Vec<u8> {
    use crate::rans::{self, ESCAPE, SYMBOLS};
    let sym = |r: i32| zigzag(r).min(ESCAPE);
    let mut counts = [[0u64; SYMBOLS]; 3];
    for r in residuals {
        for a in 0..3 {
            counts[a][sym(r[a]) as usize] += 1;
        }
    }
    let freqs: Vec<Vec<u32>> = counts.iter().map(|c| rans::normalize(c)).collect();
    let starts: Vec<Vec<u32>> = freqs
        .iter()
        .map(|f| {
            f.iter()
                .scan(0u32, |acc, &x| {
                    let s = *acc;
                    *acc += x;
                    Some(s)
                })
                .collect()
        })
        .collect();
    let mut out = Vec::with_capacity(residuals.len() + 64);
    put(&mut out, shift);
    for f in &freqs {
        rans::write_table(&mut out, f);
    }
    let mut e = rans::Encoder::default();
    for r in residuals.iter().rev() {
        for a in (0..3).rev() {
            let s = sym(r[a]) as usize;
            e.put(a, starts[a][s], freqs[a][s]);
        }
    }
    let stream = e.finish();
    put(&mut out, stream.len() as u32);
    out.extend_from_slice(&stream);
    for r in residuals {
        for &x in r {
            if zigzag(x) >= ESCAPE {
                put(&mut out, zigzag(x) - ESCAPE);
            }
        }
    }
    out
}

/// Reads a positions chunk of `count` nodes: (shift, residuals in units of 2^shift quanta).
pub fn read_positions(bytes: &[u8], what: &str, count: u32) -> Result<(u32, Vec<[i32; 3]>), ContainerError> {
    use crate::rans::{self, ESCAPE, SYMBOLS};
    let mut c = Cursor::new(bytes, what);
    let first = c.get()?;
    let (shift, coding) = (first % 32, first / 32);
    if shift > MAX_SHIFT {
        return Err(c.corrupt(format!("residual shift {shift} beyond {MAX_SHIFT}")));
    }
    match coding {
        CODING_RANS => {}
        CODING_VARINTS => {
            let left = bytes.len() - c.pos;
            if (count as usize).saturating_mul(3) > left {
                return Err(c.corrupt(format!("{count} nodes in {left} bytes (each takes at least 3)")));
            }
            let mut out = Vec::with_capacity(count as usize);
            for _ in 0..count {
                out.push([unzigzag(c.get()?), unzigzag(c.get()?), unzigzag(c.get()?)]);
            }
            c.finish()?;
            return Ok((shift, out));
        }
        CODING_SPARSE => {
            // Each listed node takes at least four bytes: checked before allocating.
            let listed = c.count_within(count as u64, 4, "listed nodes")?;
            let mut out = vec![[0i32; 3]; count as usize];
            let mut next = 0u64;
            for _ in 0..listed {
                let v = next + c.get()? as u64;
                let Some(slot) = out.get_mut(v as usize) else {
                    return Err(c.corrupt(format!("listed node {v} beyond the band's {count}")));
                };
                *slot = [unzigzag(c.get()?), unzigzag(c.get()?), unzigzag(c.get()?)];
                next = v + 1;
            }
            c.finish()?;
            return Ok((shift, out));
        }
        _ => return Err(c.corrupt(format!("residual coding {coding} (0 rANS, 1 varints, 2 sparse)"))),
    }
    let mut tables = Vec::with_capacity(3);
    for _ in 0..3 {
        let n = c.count(SYMBOLS as u64, "symbols")?;
        let mut f = [0u32; SYMBOLS];
        for x in f.iter_mut().take(n) {
            *x = c.get()?;
        }
        tables.push(rans::Table::new(&f[..n], count as usize).ok_or_else(|| c.corrupt("frequency table does not add up to 4096"))?);
    }
    let len = c.count(bytes.len() as u64, "stream bytes")?;
    let stream = bytes.get(c.pos..c.pos + len).ok_or_else(|| c.corrupt("rANS stream beyond the chunk"))?;
    c.pos += len;
    let mut d = rans::Decoder::new(stream).map_err(|e| c.corrupt(e))?;
    let mut codes = Vec::with_capacity(count as usize);
    d.get_triples([&tables[0], &tables[1], &tables[2]], count as usize, &mut codes);
    // Escapes are read in decoding order, after the stream.
    let mut out = Vec::with_capacity(count as usize);
    for mut z in codes {
        for x in &mut z {
            if *x == ESCAPE {
                *x = c.get()?.checked_add(ESCAPE).ok_or_else(|| c.corrupt("escaped residual beyond 32 bits"))?;
            }
        }
        out.push([unzigzag(z[0]), unzigzag(z[1]), unzigzag(z[2])]);
    }
    d.finish().map_err(|e| c.corrupt(e))?;
    c.finish()?;
    Ok((shift, out))
}
