//! Static-model rANS (range asymmetric numeral systems, J. Duda; byte-wise renormalisation as
//! in F. Giesen's `rans_byte`), the entropy stage of position chunks (proto/container.md,
//! "Positions, band j").
//!
//! Why rANS with a frequency table per chunk rather than zstd or an adaptive binary coder:
//! position residuals are small integers with a skewed, nearly memoryless distribution, which
//! a byte-oriented LZ coder cannot model below about one byte per value, while an adaptive
//! binary coder spends several dependent, branchy decisions per value and was too slow for
//! 1,000 frames per second. Decoding one symbol here is a table look-up, a multiply and a byte
//! read now and then, in 32-bit integers that JavaScript computes exactly too.
//!
//! State `x` stays in `[L, 2^31)` with `L = 2^23`; frequencies are 12-bit (`M = 4096`), so
//! `freq * (x >> 12) < 2^31` never overflows.

/// Frequencies of a table add up to this.
pub const SCALE_BITS: u32 = 12;
pub const M: u32 = 1 << SCALE_BITS;
/// Lower end of the normalised state interval.
pub const L: u32 = 1 << 23;
/// Symbols per table: values 0..ESCAPE are coded directly, ESCAPE says "read the value from
/// the escape list".
pub const SYMBOLS: usize = 32;
pub const ESCAPE: u32 = SYMBOLS as u32 - 1;

/// Frequencies (summing to M) for symbol counts: every symbol that occurs gets at least 1.
pub fn normalize(counts: &[u64]) -> Vec<u32> {
    let used = counts.iter().rposition(|&c| c > 0).map_or(1, |i| i + 1);
    let total: u64 = counts[..used].iter().sum();
    if total == 0 {
        let mut f = vec![0u32; 1];
        f[0] = M;
        return f;
    }
    let mut f: Vec<u32> =
        counts[..used].iter().map(|&c| if c == 0 { 0 } else { ((c as u128 * M as u128 / total as u128) as u32).max(1) }).collect();
    // Fix the sum on the largest entry (it loses the least by the change). An excess comes
    // only from rare symbols raised to 1, at most 31, while the largest entry is then above
    // M / 32 = 128, so it stays positive.
    let sum: u32 = f.iter().sum();
    let i = (0..f.len()).max_by_key(|&i| (f[i], std::cmp::Reverse(i))).unwrap_or(0);
    if sum > M {
        f[i] -= sum - M;
    } else {
        f[i] += M - sum;
    }
    f
}

/// A table as stored: symbol count n (1..=SYMBOLS), then n frequencies, varints.
pub fn write_table(out: &mut Vec<u8>, freqs: &[u32]) {
    crate::payload::put(out, freqs.len() as u32);
    for &f in freqs {
        crate::payload::put(out, f);
    }
}

/// A decoding table: for each of the M slots, its symbol (bits 25..30), its symbol's
/// frequency (bits 0..12) and its offset in the symbol's range (bits 13..24), packed so that
/// decoding a symbol is one look-up. Filling the 4096 slots costs more than decoding a small
/// band, so small bands keep only the cumulative frequencies and search them.
pub struct Table {
    slot: Option<Box<[u32; M as usize]>>,
    /// `cum[s]..cum[s + 1]` is symbol s's range; unused entries stay at M.
    cum: [u32; SYMBOLS + 1],
}

impl Table {
    /// From stored frequencies; they must add up to exactly M. `symbols` is how many symbols
    /// the table will decode (it picks the look-up or the search).
    pub fn new(freqs: &[u32], symbols: usize) -> Option<Table> {
        if freqs.is_empty() || freqs.len() > SYMBOLS || freqs.iter().map(|&f| f as u64).sum::<u64>() != M as u64 {
            return None;
        }
        let mut cum = [M; SYMBOLS + 1];
        let mut at = 0u32;
        for (s, &f) in freqs.iter().enumerate() {
            cum[s] = at;
            at += f;
        }
        let mut slot = None;
        if symbols >= 2048 {
            let mut t = Box::new([0u32; M as usize]);
            for (s, &f) in freqs.iter().enumerate() {
                for k in 0..f {
                    t[(cum[s] + k) as usize] = f | (k << 13) | ((s as u32) << 25);
                }
            }
            slot = Some(t);
        }
        Some(Table { slot, cum })
    }

    /// The packed entry of a slot.
    #[inline(always)]
    fn entry(&self, slot: u32) -> u32 {
        match &self.slot {
            Some(t) => t[slot as usize],
            None => {
                // The last symbol whose range starts at or below the slot and is not empty.
                let mut s = 0usize;
                while s + 1 < SYMBOLS && self.cum[s + 1] <= slot {
                    s += 1;
                }
                let f = self.cum[s + 1] - self.cum[s];
                f | ((slot - self.cum[s]) << 13) | ((s as u32) << 25)
            }
        }
    }
}

/// Number of interleaved states: symbol i of a stream is coded with state `i % WAYS`, so a
/// decoder works on three independent dependency chains at once (about twice as fast as one).
pub const WAYS: usize = 3;

/// Encoder: symbols are given in reverse order of decoding, each with the state it belongs
/// to; [`Encoder::finish`] returns the stream in decoding order.
pub struct Encoder {
    x: [u32; WAYS],
    rev: Vec<u8>,
}

impl Default for Encoder {
    fn default() -> Self {
        Encoder { x: [L; WAYS], rev: Vec::new() }
    }
}

impl Encoder {
    /// Pushes a symbol of frequency `freq` starting at `start` (freq > 0) on state `way`.
    #[inline]
    pub fn put(&mut self, way: usize, start: u32, freq: u32) {
        let x_max = ((L >> SCALE_BITS) << 8) * freq;
        let mut x = self.x[way];
        while x >= x_max {
            self.rev.push(x as u8);
            x >>= 8;
        }
        self.x[way] = ((x / freq) << SCALE_BITS) + x % freq + start;
    }

    /// The stream: the final states (state 0 first, each big-endian), then the renormalisation
    /// bytes in the order the decoder reads them.
    pub fn finish(mut self) -> Vec<u8> {
        for way in (0..WAYS).rev() {
            self.rev.extend_from_slice(&self.x[way].to_le_bytes());
        }
        self.rev.reverse();
        self.rev
    }
}

/// Decoder over one stream. Past the end it reads zero bytes and remembers that it did, so the
/// hot loop has no error path; [`Decoder::finish`] reports it.
pub struct Decoder<'a> {
    bytes: &'a [u8],
    pos: usize,
    x: [u32; WAYS],
    overrun: bool,
}

impl<'a> Decoder<'a> {
    pub fn new(bytes: &'a [u8]) -> Result<Self, &'static str> {
        let mut x = [0u32; WAYS];
        for (way, x) in x.iter_mut().enumerate() {
            let Some(b) = bytes.get(4 * way..4 * way + 4) else { return Err("rANS stream shorter than its states") };
            *x = u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
            if !(L..1 << 31).contains(x) {
                return Err("rANS state out of range");
            }
        }
        Ok(Decoder { bytes, pos: 4 * WAYS, x, overrun: false })
    }

    /// The next symbol of state `way` (the one-symbol reference the tests check the payload
    /// reader's unrolled loop against; the attribute tables' residuals, whose table changes
    /// by channel rather than by state, decode one at a time with it).
    #[inline(always)]
    pub fn get(&mut self, way: usize, t: &Table) -> u32 {
        let x = self.x[way];
        let e = t.entry(x & (M - 1));
        let mut x = (e & 0x1FFF) * (x >> SCALE_BITS) + ((e >> 13) & 0xFFF);
        while x < L {
            let b = match self.bytes.get(self.pos) {
                Some(&b) => b,
                None => {
                    self.overrun = true;
                    // Any state >= L ends the loop; the stream is reported corrupt anyway.
                    x = L;
                    break;
                }
            };
            self.pos += 1;
            x = (x << 8) | b as u32;
        }
        self.x[way] = x;
        e >> 25
    }

    /// Decodes `count` triples, symbol `3 i + a` with state and table `a`, appending the
    /// symbols to `out`. The same as calling [`Decoder::get`] in turn, with the states held in
    /// registers (the three chains then overlap, which is what the interleaving is for).
    pub fn get_triples(&mut self, tables: [&Table; 3], count: usize, out: &mut Vec<[u32; 3]>) {
        let [mut x0, mut x1, mut x2] = self.x;
        let bytes = self.bytes;
        let mut pos = self.pos;
        let mut overrun = false;
        #[inline(always)]
        fn step(x: &mut u32, e: u32, bytes: &[u8], pos: &mut usize, overrun: &mut bool) {
            let mut y = (e & 0x1FFF) * (*x >> SCALE_BITS) + ((e >> 13) & 0xFFF);
            while y < L {
                match bytes.get(*pos) {
                    Some(&b) => {
                        *pos += 1;
                        y = (y << 8) | b as u32;
                    }
                    None => {
                        *overrun = true;
                        y = L;
                    }
                }
            }
            *x = y;
        }
        if let (Some(t0), Some(t1), Some(t2)) = (&tables[0].slot, &tables[1].slot, &tables[2].slot) {
            for _ in 0..count {
                let e0 = t0[(x0 & (M - 1)) as usize];
                let e1 = t1[(x1 & (M - 1)) as usize];
                let e2 = t2[(x2 & (M - 1)) as usize];
                step(&mut x0, e0, bytes, &mut pos, &mut overrun);
                step(&mut x1, e1, bytes, &mut pos, &mut overrun);
                step(&mut x2, e2, bytes, &mut pos, &mut overrun);
                out.push([e0 >> 25, e1 >> 25, e2 >> 25]);
            }
        } else {
            for _ in 0..count {
                let e0 = tables[0].entry(x0 & (M - 1));
                step(&mut x0, e0, bytes, &mut pos, &mut overrun);
                let e1 = tables[1].entry(x1 & (M - 1));
                step(&mut x1, e1, bytes, &mut pos, &mut overrun);
                let e2 = tables[2].entry(x2 & (M - 1));
                step(&mut x2, e2, bytes, &mut pos, &mut overrun);
                out.push([e0 >> 25, e1 >> 25, e2 >> 25]);
            }
        }
        self.x = [x0, x1, x2];
        self.pos = pos;
        self.overrun |= overrun;
    }

    /// A valid stream is consumed exactly and leaves every state where the encoder began.
    pub fn finish(&self) -> Result<(), &'static str> {
        if self.overrun {
            Err("rANS stream ends early")
        } else if self.pos != self.bytes.len() || self.x != [L; WAYS] {
            Err("rANS stream does not end where it should")
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_rejects_garbage() {
        let symbols: Vec<u32> = (0..20_000u32).map(|i| (i.wrapping_mul(2654435761) >> 27).min(ESCAPE) % 7).collect();
        let mut counts = [0u64; SYMBOLS];
        for &s in &symbols {
            counts[s as usize] += 1;
        }
        let f = normalize(&counts);
        assert_eq!(f.iter().sum::<u32>(), M);
        let t = Table::new(&f, 1 << 20).unwrap();
        let small = Table::new(&f, 1).unwrap();
        for slot in 0..M {
            assert_eq!(t.entry(slot), small.entry(slot));
        }
        let start: Vec<u32> = f
            .iter()
            .scan(0, |a, &x| {
                let s = *a;
                *a += x;
                Some(s)
            })
            .collect();
        let mut e = Encoder::default();
        for (i, &s) in symbols.iter().enumerate().rev() {
            e.put(i % WAYS, start[s as usize], f[s as usize]);
        }
        let bytes = e.finish();
        let mut d = Decoder::new(&bytes).unwrap();
        for (i, &s) in symbols.iter().enumerate() {
            assert_eq!(d.get(i % WAYS, &t), s);
        }
        d.finish().unwrap();
        // The batched decoder agrees with the one-symbol decoder, with slots or searching.
        for table in [&t, &small] {
            let mut d = Decoder::new(&bytes).unwrap();
            let mut out = Vec::new();
            d.get_triples([table, table, table], symbols.len() / 3, &mut out);
            for (i, tr) in out.iter().enumerate() {
                assert_eq!(*tr, [symbols[3 * i], symbols[3 * i + 1], symbols[3 * i + 2]]);
            }
        }
        // Skewed counts with rare symbols keep every used symbol codable.
        let mut c = [0u64; SYMBOLS];
        c[0] = 1_000_000;
        c[31] = 1;
        c[5] = 1;
        let f = normalize(&c);
        assert!(f[31] >= 1 && f[5] >= 1 && f.iter().sum::<u32>() == M);
        for seed in 0..200u32 {
            let junk: Vec<u8> = (0..32u32).map(|i| (i.wrapping_add(seed).wrapping_mul(2654435761) >> 24) as u8).collect();
            if let Ok(mut d) = Decoder::new(&junk) {
                for i in 0..100 {
                    d.get(i % WAYS, &t);
                }
                let _ = d.finish();
            }
        }
        assert!(Table::new(&[4095], 1).is_none());
        assert!(Table::new(&[], 1).is_none());
    }
}
