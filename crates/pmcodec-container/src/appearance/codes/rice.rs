//! The adaptive Rice form of a RESIDUALS section (proto/container.md, "Attributes",
//! *Adaptive Rice residuals*): each channel's codes Golomb-Rice coded with a parameter that
//! follows the running mean of the codes before, as LOCO-I does (Weinberger, Seroussi &
//! Sapiro, "The LOCO-I lossless image compression algorithm", 2000). Why: a small band's
//! rANS frequency tables and final states cost more than its codes (Fox's coarsest band: 33
//! texture coordinates, 158 B as rANS, 110 as adaptive Rice), while an adaptive code needs
//! no table at all; large bands keep rANS where it is shorter.

use crate::ContainerError;
use crate::bits::{BitReader, Bits, Running};
use crate::payload::{Cursor, put};

/// A quotient this large or larger is escaped: `LIMIT` one bits, the code's bit length minus
/// one in 5 bits, then its bits below the highest.
const LIMIT: u32 = 24;
/// The starting parameters the encoder tries per channel (the first code's Rice parameter).
const LARGEST_START: u32 = 16;

/// A channel's adaptive state: the sum of its codes seen from `2^start` (the first code's
/// parameter is `start`), over their count from 1, halved together at 16 codes.
fn state(start: u32) -> Running {
    Running::starting(1u64 << start)
}

/// The largest Rice parameter (codes are below 2^32).
const MOST: u32 = 31;

fn bit_length(z: u32) -> u32 {
    32 - z.leading_zeros()
}

/// Bits of one code under parameter `k`.
fn cost(z: u32, k: u32) -> u64 {
    let q = (z >> k) as u64;
    if q < LIMIT as u64 { q + 1 + k as u64 } else { LIMIT as u64 + 5 + bit_length(z) as u64 - 1 }
}

fn put_code(bits: &mut Bits, z: u32, k: u32) {
    let q = z >> k;
    if q < LIMIT {
        bits.put(u64::MAX, q);
        bits.put(0, 1);
        bits.put(z as u64, k);
    } else {
        let b = bit_length(z);
        bits.put(u64::MAX, LIMIT);
        bits.put((b - 1) as u64, 5);
        bits.put(z as u64, b - 1);
    }
}

/// The bits a channel's codes take from starting parameter `start`.
fn channel_bits(codes: &[u32], start: u32) -> u64 {
    let mut s = state(start);
    let mut bits = 0;
    for &z in codes {
        bits += cost(z, s.order(MOST));
        s.update(z);
    }
    bits
}

/// The section: `0`; per channel its starting parameter (varint, 0 to 16; the one of these
/// that codes the channel shortest); the length of the bits in bytes and the bits: per
/// channel, per code, under the channel's current parameter k, its quotient `z >> k` in unary
/// (that many one bits and a zero) and its k low bits, or, for a quotient of [`LIMIT`] or
/// more, `LIMIT` one bits, `b - 1` in 5 bits and the `b - 1` bits below the highest (b the
/// code's bit length).
pub(super) fn section(codes: &[u32], m: usize, channels: usize) -> Vec<u8> {
    let mut out = Vec::new();
    put(&mut out, 0);
    let mut bits = Bits::default();
    let mut starts = Vec::with_capacity(channels);
    for q in 0..channels {
        let chan = &codes[(q * m).min(codes.len())..((q + 1) * m).min(codes.len())];
        let start = (0..=LARGEST_START).min_by_key(|&s| (channel_bits(chan, s), s)).unwrap_or(0);
        put(&mut out, start);
        starts.push(start);
    }
    for (q, &start) in starts.iter().enumerate() {
        let mut s = state(start);
        for &z in &codes[(q * m).min(codes.len())..((q + 1) * m).min(codes.len())] {
            put_code(&mut bits, z, s.order(MOST));
            s.update(z);
        }
    }
    put(&mut out, bits.out.len() as u32);
    out.extend_from_slice(&bits.out);
    out
}

/// Reads `m * channels` codes as [`section`] wrote them; errors name the chunk's residuals.
pub(super) fn read_section(c: &mut Cursor<'_>, m: usize, channels: usize) -> Result<Vec<u32>, ContainerError> {
    let corrupt = |detail: String| ContainerError::Corrupt { what: "attribute residuals".into(), detail };
    c.get()?;
    let mut starts = Vec::with_capacity(channels);
    for _ in 0..channels {
        starts.push(c.count(LARGEST_START as u64, "Rice start parameter")? as u32);
    }
    let len = c.get()? as usize;
    let bytes = c.take(len)?;
    // Every code takes a bit at least: more codes than bits is a corrupt section, refused before
    // anything is allocated for them.
    if m.saturating_mul(channels) > 8 * len {
        return Err(corrupt(format!("{} codes in {len} bytes", m.saturating_mul(channels))));
    }
    let mut r = BitReader { bytes, bit: 0, what: "attribute residuals" };
    let mut codes = Vec::with_capacity(m * channels);
    for &start in &starts {
        let mut s = state(start);
        for _ in 0..m {
            let k = s.order(MOST);
            let mut q = 0;
            while q < LIMIT && r.bit()? == 1 {
                q += 1;
            }
            let z = if q < LIMIT {
                let low = r.get(k)?;
                u32::try_from(((q as u64) << k) | low).map_err(|_| corrupt(format!("a residual of {} bits", k + 5)))?
            } else {
                let b = r.get(5)? as u32;
                let z = (1u64 << b) | r.get(b)?;
                let z = u32::try_from(z).map_err(|_| corrupt(format!("a residual of {} bits", b + 1)))?;
                if z >> k < LIMIT {
                    return Err(corrupt("an escaped residual that a quotient codes".into()));
                }
                z
            };
            codes.push(z);
            s.update(z);
        }
    }
    if r.bit.div_ceil(8) != bytes.len() {
        return Err(corrupt(format!("{} Rice bytes where the codes take {}", bytes.len(), r.bit.div_ceil(8))));
    }
    Ok(codes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::Rng;

    /// Codes of a few scales in runs (as a band's residuals change scale from chart to chart),
    /// with zeros, the largest code and codes that escape.
    fn codes(rng: &mut Rng, n: usize) -> Vec<u32> {
        let mut out = Vec::with_capacity(n);
        let mut scale = 3;
        for i in 0..n {
            if i % 17 == 0 {
                scale = rng.below(20) as u32;
            }
            out.push(match rng.below(40) {
                0 => u32::MAX,
                1 => 0,
                2 => rng.next_u64() as u32,
                _ => (rng.next_u64() as u32) >> (31 - scale.min(31)) >> 1,
            });
        }
        out
    }

    #[test]
    fn sections_round_trip_every_scale_and_channel_count() {
        let mut rng = Rng::new(7);
        for (m, channels) in [(0, 2), (1, 1), (5, 3), (33, 2), (400, 2), (1000, 1)] {
            let c = codes(&mut rng, m * channels);
            let bytes = section(&c, m, channels);
            let mut cur = Cursor::new(&bytes, "test");
            assert_eq!(read_section(&mut cur, m, channels).unwrap(), c, "m {m} channels {channels}");
            cur.finish().unwrap();
        }
    }

    /// The bytes web/test/codes.test.ts decodes too: both decoders read one spec.
    const GOLDEN: [u8; 29] =
        [0, 4, 11, 25, 64, 200, 254, 31, 29, 224, 255, 255, 223, 2, 45, 49, 2, 32, 1, 8, 56, 208, 11, 125, 150, 7, 0, 2, 0];

    #[test]
    fn a_known_section_reads_as_written() {
        let c = [0u32, 1, 2, 3, 100, 7, 0, 5_000_000, 1, 9, 4, 4000, 4001, 3990, 0, 2];
        assert_eq!(section(&c, 8, 2), GOLDEN);
        assert_eq!(read_section(&mut Cursor::new(&GOLDEN, "t"), 8, 2).unwrap(), c);
        // More codes than the section has bits: refused before any is read.
        let err = read_section(&mut Cursor::new(&GOLDEN, "t"), 1_000_000, 2).unwrap_err();
        assert!(err.to_string().contains("codes in"), "{err}");
    }

    #[test]
    fn the_parameter_follows_the_codes_and_beats_a_fixed_one() {
        // Small codes then large ones: the adaptive parameter follows, where the best single
        // parameter for the whole channel pays for one scale or the other.
        let mut c: Vec<u32> = (0..200).map(|i| i % 3).collect();
        c.extend((0..200).map(|i| 3000 + (i * 37) % 1000));
        let adaptive = section(&c, c.len(), 1).len() as u64 * 8;
        let fixed = (0..24).map(|k| c.iter().map(|&z| cost(z, k)).sum::<u64>()).min().unwrap();
        assert!(adaptive < fixed * 3 / 4, "adaptive {adaptive} bits, best fixed {fixed}");
    }

    #[test]
    fn damaged_sections_are_errors_never_panics() {
        let mut rng = Rng::new(11);
        let c = codes(&mut rng, 120);
        let bytes = section(&c, 60, 2);
        for cut in 0..bytes.len() {
            assert!(read_section(&mut Cursor::new(&bytes[..cut], "t"), 60, 2).is_err(), "cut at {cut}");
        }
        // A byte too many is named (not silently skipped): the same bits framed one byte longer.
        let mut cur = Cursor::new(&bytes[3..], "t");
        let len = cur.get().unwrap();
        let body = cur.take(len as usize).unwrap();
        let mut long = bytes[..3].to_vec();
        put(&mut long, len + 1);
        long.extend_from_slice(body);
        long.push(0);
        let err = read_section(&mut Cursor::new(&long, "t"), 60, 2).unwrap_err();
        assert!(err.to_string().contains("Rice bytes"), "{err}");
        // A start parameter beyond the largest.
        let mut big = bytes.clone();
        big[1] = LARGEST_START as u8 + 1;
        assert!(read_section(&mut Cursor::new(&big, "t"), 60, 2).is_err());
        for _ in 0..2000 {
            let mut bad = bytes.clone();
            let i = 1 + rng.below(bad.len() - 1);
            bad[i] ^= 1 << rng.below(8);
            let _ = read_section(&mut Cursor::new(&bad, "t"), 60, 2);
        }
    }

    #[test]
    fn escapes_that_a_quotient_codes_and_codes_beyond_32_bits_are_refused() {
        let framed = |bits: Bits| {
            let mut out = vec![0, 0];
            put(&mut out, bits.out.len() as u32);
            out.extend_from_slice(&bits.out);
            out
        };
        // Start 0 (k = 0): 5 escaped, where its quotient 5 is below the limit.
        let mut bits = Bits::default();
        bits.put(u64::MAX, LIMIT);
        bits.put(2, 5);
        bits.put(1, 2);
        let err = read_section(&mut Cursor::new(&framed(bits), "t"), 1, 1).unwrap_err();
        assert!(err.to_string().contains("quotient"), "{err}");
        // The largest code raises k to 31; then a quotient of 2 would be 2^32.
        let mut bits = Bits::default();
        put_code(&mut bits, u32::MAX, 0);
        bits.put(0b011, 3);
        bits.put(0, 31);
        let err = read_section(&mut Cursor::new(&framed(bits), "t"), 2, 1).unwrap_err();
        assert!(err.to_string().contains("bits"), "{err}");
    }
}
