//! The bit I/O of the Joints chunk (proto/container.md, "Joints"): bits least significant
//! first within each byte, zigzag-mapped signed numbers and Exp-Golomb codes of a chosen order;
//! the reader's errors name the chunk.

use crate::ContainerError;

pub(super) fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

pub(super) fn unzigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

/// Bits, least significant first within each byte.
#[derive(Default)]
pub(super) struct Bits {
    pub(super) out: Vec<u8>,
    pub(super) used: u32,
}

impl Bits {
    pub(super) fn put(&mut self, v: u64, n: u32) {
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

    /// Exp-Golomb of order k: `u + 2^k` in `m` bits after `m - 1 - k` zeros.
    pub(super) fn golomb(&mut self, u: u64, k: u32) {
        let v = u as u128 + (1u128 << k);
        let m = 128 - v.leading_zeros();
        self.put(0, m - 1 - k);
        for i in (0..m).rev() {
            self.put((v >> i) as u64 & 1, 1);
        }
    }
}

/// Bits of the Exp-Golomb code of order `k` of `u`.
pub(super) fn golomb_len(u: u64, k: u32) -> u64 {
    let v = u as u128 + (1u128 << k);
    (2 * (128 - v.leading_zeros()) - 1 - k) as u64
}

pub(super) struct BitReader<'a> {
    pub(super) bytes: &'a [u8],
    pub(super) bit: usize,
    pub(super) what: &'a str,
}

impl BitReader<'_> {
    pub(super) fn corrupt(&self, detail: impl Into<String>) -> ContainerError {
        ContainerError::Corrupt { what: self.what.to_string(), detail: detail.into() }
    }

    pub(super) fn bit(&mut self) -> Result<u64, ContainerError> {
        let Some(&b) = self.bytes.get(self.bit / 8) else {
            return Err(self.corrupt(format!("ends inside its bits at byte {}", self.bytes.len())));
        };
        let v = (b >> (self.bit % 8) & 1) as u64;
        self.bit += 1;
        Ok(v)
    }

    pub(super) fn get(&mut self, n: u32) -> Result<u64, ContainerError> {
        let mut v = 0;
        for i in 0..n {
            v |= self.bit()? << i;
        }
        Ok(v)
    }

    pub(super) fn golomb(&mut self, k: u32) -> Result<u64, ContainerError> {
        let mut zeros = 0u32;
        while self.bit()? == 0 {
            zeros += 1;
            if zeros + k >= 64 {
                return Err(self.corrupt("a number beyond 64 bits"));
            }
        }
        let mut v: u64 = 1;
        for _ in 0..zeros + k {
            v = v << 1 | self.bit()?;
        }
        Ok(v - (1u64 << k))
    }

    /// The payload ends in this byte, with its unused bits 0.
    pub(super) fn finish(&self) -> Result<(), ContainerError> {
        let end = self.bit.div_ceil(8);
        if end != self.bytes.len() {
            return Err(self.corrupt(format!("{} bytes left over", self.bytes.len() - end)));
        }
        if !self.bit.is_multiple_of(8) && self.bytes[end - 1] >> (self.bit % 8) != 0 {
            return Err(self.corrupt("bits set after its last number"));
        }
        Ok(())
    }
}
