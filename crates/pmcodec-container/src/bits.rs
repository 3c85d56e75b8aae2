//! Bit I/O shared by the bit-coded chunks (proto/container.md: Key, Faces, Delta and Corners
//! coding 1, the Joints chunk and the adaptive Rice residuals of the appearance chunks): bits
//! least significant first within each byte, Exp-Golomb codes of a given order, a stream that
//! ends in the byte of its last bit with the later bits 0, and the running sum an adaptive
//! code's order follows. The reader's errors name the chunk.

use crate::ContainerError;

/// When a [`Running`] state has counted this many numbers, its sum and count are halved, so the
/// order follows the recent ones.
const HALVE_AT: u64 = 16;

/// The running sum and count an adaptive code's order is chosen from: the smallest k with
/// `count * 2^k >= sum`, as LOCO-I chooses its Golomb parameter (Weinberger, Seroussi &
/// Sapiro, "The LOCO-I lossless image compression algorithm", 2000).
#[derive(Clone, Copy)]
pub(crate) struct Running {
    sum: u64,
    count: u64,
}

impl Running {
    /// A state whose first order follows a sum of 1 (order 0).
    pub(crate) fn new() -> Self {
        Running::starting(1)
    }

    /// A state whose first order follows a sum of `sum` over a count of 1.
    pub(crate) fn starting(sum: u64) -> Self {
        Running { sum, count: 1 }
    }

    /// The smallest k, at most `most`, with `count * 2^k >= sum`.
    pub(crate) fn order(&self, most: u32) -> u32 {
        let mut k = 0;
        while k < most && (self.count << k) < self.sum {
            k += 1;
        }
        k
    }

    /// Counts `u`; at [`HALVE_AT`] numbers the sum and count are halved.
    pub(crate) fn update(&mut self, u: u32) {
        self.sum += u as u64;
        self.count += 1;
        if self.count >= HALVE_AT {
            self.sum >>= 1;
            self.count >>= 1;
        }
    }
}

/// Bits, least significant first within each byte, after the bytes it starts with.
#[derive(Default)]
pub(crate) struct Bits {
    pub(crate) out: Vec<u8>,
    /// Bits used of the last byte (0: a new byte is due).
    pub(crate) used: u32,
}

impl Bits {
    /// A stream that continues `bytes` (a payload's byte-aligned start).
    pub(crate) fn after(bytes: Vec<u8>) -> Self {
        Bits { out: bytes, used: 0 }
    }

    /// The low `n` bits of `v`, least significant first.
    pub(crate) fn put(&mut self, v: u64, n: u32) {
        for i in 0..n {
            if self.used == 0 {
                self.out.push(0);
            }
            if let Some(last) = self.out.last_mut() {
                *last |= ((v >> i & 1) as u8) << self.used;
            }
            self.used = (self.used + 1) % 8;
        }
    }

    /// Exp-Golomb of order k: `u + 2^k` in `m` bits, most significant first, after `m - 1 - k`
    /// zeros.
    pub(crate) fn golomb(&mut self, u: u64, k: u32) {
        let v = u as u128 + (1u128 << k);
        let m = 128 - v.leading_zeros();
        self.put(0, m - 1 - k);
        for i in (0..m).rev() {
            self.put((v >> i) as u64 & 1, 1);
        }
    }
}

/// Bits of the Exp-Golomb code of order `k` of `u`.
pub(crate) fn golomb_len(u: u64, k: u32) -> u64 {
    let v = u as u128 + (1u128 << k);
    (2 * (128 - v.leading_zeros()) - 1 - k) as u64
}

/// Reads what [`Bits`] writes, from the start of `bytes`.
pub(crate) struct BitReader<'a> {
    pub(crate) bytes: &'a [u8],
    pub(crate) bit: usize,
    pub(crate) what: &'a str,
}

impl BitReader<'_> {
    pub(crate) fn corrupt(&self, detail: impl Into<String>) -> ContainerError {
        ContainerError::Corrupt { what: self.what.to_string(), detail: detail.into() }
    }

    pub(crate) fn bit(&mut self) -> Result<u64, ContainerError> {
        let Some(&b) = self.bytes.get(self.bit / 8) else {
            return Err(self.corrupt(format!("ends inside its bits at byte {}", self.bytes.len())));
        };
        let v = (b >> (self.bit % 8) & 1) as u64;
        self.bit += 1;
        Ok(v)
    }

    /// `n` bits, least significant first.
    pub(crate) fn get(&mut self, n: u32) -> Result<u64, ContainerError> {
        let mut v = 0;
        for i in 0..n {
            v |= self.bit()? << i;
        }
        Ok(v)
    }

    /// An Exp-Golomb code of order `k` of a number below 2^64.
    pub(crate) fn golomb(&mut self, k: u32) -> Result<u64, ContainerError> {
        self.golomb_within(k, 63)
    }

    /// An Exp-Golomb code of order `k` whose `zeros + k` stays at most `limit` (below 64), else
    /// the chunk is corrupt.
    pub(crate) fn golomb_within(&mut self, k: u32, limit: u32) -> Result<u64, ContainerError> {
        let mut zeros = 0u32;
        while self.bit()? == 0 {
            zeros += 1;
            if zeros + k > limit {
                return Err(self.corrupt(format!("a number beyond {} bits", limit + 1)));
            }
        }
        let mut v: u64 = 1;
        for _ in 0..zeros + k {
            v = v << 1 | self.bit()?;
        }
        Ok(v - (1u64 << k))
    }

    /// The payload ends in this byte, with its unused bits 0.
    pub(crate) fn finish(&self) -> Result<(), ContainerError> {
        let end = self.bit.div_ceil(8);
        if end != self.bytes.len() {
            return Err(self.corrupt(format!("{} bytes left over", self.bytes.len().saturating_sub(end))));
        }
        if !self.bit.is_multiple_of(8) && self.bytes[end - 1] >> (self.bit % 8) != 0 {
            return Err(self.corrupt("bits set after its last number"));
        }
        Ok(())
    }
}
