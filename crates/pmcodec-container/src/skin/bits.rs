//! The bit I/O of the Joints chunk (proto/container.md, "Joints"): the crate's shared bit I/O
//! ([`crate::bits`]: bits least significant first within each byte, Exp-Golomb codes of a chosen
//! order, errors naming the chunk) and zigzag-mapped signed 64-bit numbers.

pub(super) use crate::bits::{BitReader, Bits, golomb_len};

pub(super) fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

pub(super) fn unzigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}
