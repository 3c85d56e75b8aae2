//! An attribute table's value residuals, as varints or as a RESIDUALS section
//! (proto/container.md, "Attributes"): the bit length of each residual code entropy-coded per
//! channel with the crate's rANS coder, the bits below its highest stored raw, longer codes
//! whole; or, where shorter, the codes adaptive-Rice coded (`rice`).

use crate::ContainerError;
use crate::payload::{Cursor, put};

mod rice;

/// The residual codes a rANS table codes directly: bit lengths 0 to 30; [`rans::ESCAPE`]
/// (31) stands for a longer code, stored whole as a varint.
pub(super) const LONGEST_DIRECT: u32 = 30;

/// Bit length of a code: 0 for 0, else the position of its highest set bit plus one.
pub(super) fn bit_length(z: u32) -> u32 {
    32 - z.leading_zeros()
}

/// The value residuals of a table: `codes` (zigzag codes, channel after channel, `m` per
/// channel) as varints, or, with `rans`, as a *RESIDUALS* section: per channel a rANS
/// frequency table ([`rans::write_table`]) over the codes' bit lengths `b` (0 to 30; 31
/// escapes); the length of the rANS stream and the stream (code i on state `i % 3` with its
/// channel's table, as the position chunks' coder: Duda's rANS, 12-bit frequencies); the
/// length of the *mantissa* bytes and those bytes: per code of length b from 2 to 30 its
/// `b - 1` bits below the highest, least significant first, packed from bit 0 of byte 0 on;
/// then each escaped code as a varint, in order. A code is then `2^(b-1) + mantissa` (0 and
/// 1 for b = 0 and 1). Why: the residuals of texture coordinates spread over several bits
/// (Fox's band 0: about 7 below the highest on average) while their lengths cluster, so coding the length
/// with a per-channel model and the bits below it raw is what Draco's tagged residual coding
/// does too (its "RAnsSymbolEncoder" over bit lengths); varints under zstd spend a byte or
/// two per code whatever the distribution. The section may instead take the *adaptive Rice*
/// form ([`rice::section`], first varint 0 where a frequency table's count is at least 1),
/// whichever is shorter: a small band's tables and final states cost more than its codes.
pub(super) fn put_codes(out: &mut Vec<u8>, codes: &[u32], m: usize, channels: usize, rans: bool) {
    if !rans {
        for &z in codes {
            put(out, z);
        }
        return;
    }
    let at = out.len();
    put_rans_section(out, codes, m, channels);
    let rice = rice::section(codes, m, channels);
    if rice.len() < out.len() - at {
        out.truncate(at);
        out.extend_from_slice(&rice);
    }
}

/// The rANS form of the RESIDUALS section (see [`put_codes`]).
fn put_rans_section(out: &mut Vec<u8>, codes: &[u32], m: usize, channels: usize) {
    use crate::rans::{self, ESCAPE, SYMBOLS};
    let sym = |z: u32| if bit_length(z) > LONGEST_DIRECT { ESCAPE } else { bit_length(z) };
    let mut counts = vec![[0u64; SYMBOLS]; channels];
    for (i, &z) in codes.iter().enumerate() {
        counts[i / m.max(1)][sym(z) as usize] += 1;
    }
    let freqs: Vec<Vec<u32>> = counts.iter().map(|c| rans::normalize(c)).collect();
    let starts: Vec<Vec<u32>> =
        freqs.iter().map(|f| f.iter().scan(0u32, |acc, &x| Some(std::mem::replace(acc, *acc + x))).collect()).collect();
    for f in &freqs {
        rans::write_table(out, f);
    }
    let mut e = rans::Encoder::default();
    for (i, &z) in codes.iter().enumerate().rev() {
        let (k, s) = (i / m.max(1), sym(z) as usize);
        e.put(i % rans::WAYS, starts[k][s], freqs[k][s]);
    }
    let stream = e.finish();
    put(out, stream.len() as u32);
    out.extend_from_slice(&stream);
    let mut bits = Vec::new();
    let mut at = 0usize;
    for &z in codes {
        let b = bit_length(z);
        if (2..=LONGEST_DIRECT).contains(&b) {
            for x in 0..b - 1 {
                if at.is_multiple_of(8) {
                    bits.push(0u8);
                }
                bits[at / 8] |= (((z >> x) & 1) as u8) << (at % 8);
                at += 1;
            }
        }
    }
    put(out, bits.len() as u32);
    out.extend_from_slice(&bits);
    for &z in codes {
        if sym(z) == ESCAPE {
            put(out, z);
        }
    }
}

/// Reads `m * channels` residual codes as [`put_codes`] wrote them (varints, or with `rans`
/// its rANS section); errors name the chunk.
pub(super) fn read_codes(c: &mut Cursor<'_>, m: usize, channels: usize, rans: bool) -> Result<Vec<u32>, ContainerError> {
    use crate::rans::{self, ESCAPE, SYMBOLS};
    let n = m * channels;
    let mut codes = Vec::with_capacity(n);
    if !rans {
        for _ in 0..n {
            codes.push(c.get()?);
        }
        return Ok(codes);
    }
    if c.peek() == Some(0) {
        return rice::read_section(c, m, channels);
    }
    let mut tables = Vec::with_capacity(channels);
    for _ in 0..channels {
        let k = c.count(SYMBOLS as u64, "symbols")?;
        let mut f = [0u32; SYMBOLS];
        for x in f.iter_mut().take(k) {
            *x = c.get()?;
        }
        let bad = ContainerError::Corrupt { what: "attribute residuals".into(), detail: "frequency table does not add up to 4096".into() };
        tables.push(rans::Table::new(&f[..k], m).ok_or(bad)?);
    }
    let len = c.get()? as usize;
    let stream = c.take(len)?;
    let corrupt = |detail: &str| ContainerError::Corrupt { what: "attribute residuals".into(), detail: detail.into() };
    let mut d = rans::Decoder::new(stream).map_err(corrupt)?;
    let mut lengths = Vec::with_capacity(n);
    for i in 0..n {
        lengths.push(d.get(i % rans::WAYS, &tables[i / m.max(1)]));
    }
    d.finish().map_err(corrupt)?;
    let len = c.get()? as usize;
    let bits = c.take(len)?;
    let mut at = 0usize;
    for b in lengths {
        let z = match b {
            0 | 1 => b,
            ESCAPE => {
                let z = c.get()?;
                if bit_length(z) <= LONGEST_DIRECT {
                    return Err(corrupt("an escaped residual that a length codes"));
                }
                z
            }
            _ => {
                let mut z = 1u32 << (b - 1);
                if at + (b as usize - 1) > bits.len() * 8 {
                    return Err(corrupt("mantissa bits end early"));
                }
                for x in 0..b - 1 {
                    z |= (((bits[at / 8] >> (at % 8)) & 1) as u32) << x;
                    at += 1;
                }
                z
            }
        };
        codes.push(z);
    }
    if at.div_ceil(8) != bits.len() {
        return Err(corrupt("mantissa bytes left over"));
    }
    Ok(codes)
}
