//! Chunk compression: zstd frames, kept contexts and the *stored* flag ([`FLAG_STORED`],
//! proto/container.md "Chunks").

use super::FLAG_STORED;
#[cfg(doc)]
use super::{RANS_ZSTD_LEVEL, ZSTD_LEVEL};

/// A chunk's stored bytes in a file with preamble `flags`: its zstd frame at `level`, or, with
/// [`FLAG_STORED`], the payload itself when the frame would be no shorter (a frame exactly as
/// long as the payload would read as a stored payload, so it is stored too).
pub fn store_chunk(raw: &[u8], level: i32, flags: u16) -> std::io::Result<Vec<u8>> {
    let z = compress(raw, level)?;
    Ok(if flags & FLAG_STORED != 0 && z.len() >= raw.len() { raw.to_vec() } else { z })
}

/// Inputs up to this size go through [`compress`]'s kept context (creating a level-19 context
/// per chunk cost about 2% of a whole encode of the horse). Larger ones get a context of their
/// own, freed after: zstd sizes a context's tables by its largest input, and a kept one sized
/// by a 135k-vertex band added 20 MiB to the encoder's peak memory, while creating a context
/// costs little beside compressing that much.
const REMEMBERED: usize = 1 << 16;

/// Inputs and frames [`compress`] remembers, at most this many bytes of them per thread, the
/// least recently used forgotten first. Remembered are the inputs up to [`REMEMBERED`] bytes
/// (a small band's Positions payload is compressed to choose its coding, then again to be
/// stored) and every input at the file's level [`ZSTD_LEVEL`] (a Key payload is sized in each
/// of its codings at every keyframe, and where the hierarchy did not change since, they are
/// the same bytes: the 34,102-vertex character of scripts/benchmarks.py, never reclustered,
/// spent 8% of its encode compressing them again).
const REMEMBERED_BYTES: usize = 4 << 20;

/// What [`compress`] keeps per thread: one context per level used (an encode uses two:
/// [`ZSTD_LEVEL`] and [`RANS_ZSTD_LEVEL`], chunk after chunk), and the inputs remembered.
#[derive(Default)]
struct Compression {
    contexts: Vec<(i32, zstd::bulk::Compressor<'static>)>,
    memo: Memo,
}

/// An input's zstd level, length and CRC-32.
type MemoKey = (i32, usize, u32);

/// A remembered input: the number of its last use, the input and its frame.
type Remembered = (u64, Vec<u8>, Vec<u8>);

/// Inputs with their frames by (level, length, CRC-32 of the input); `order` their uses,
/// oldest first, each with the use's number (an input used again is found further on with a
/// later number, and its earlier place is passed over when forgetting).
#[derive(Default)]
struct Memo {
    entries: std::collections::HashMap<MemoKey, Remembered>,
    order: std::collections::VecDeque<(MemoKey, u64)>,
    bytes: usize,
    uses: u64,
}

impl Memo {
    /// The frame of `raw` at `level` (its CRC-32 `crc`), if remembered.
    fn get(&mut self, key: MemoKey, raw: &[u8]) -> Option<Vec<u8>> {
        let entry = self.entries.get_mut(&key).filter(|e| e.1 == raw)?;
        self.uses += 1;
        entry.0 = self.uses;
        self.order.push_back((key, self.uses));
        let z = entry.2.clone();
        if self.order.len() > 2 * self.entries.len() + 64 {
            let entries = &self.entries;
            self.order.retain(|(k, n)| entries.get(k).is_some_and(|e| e.0 == *n));
        }
        Some(z)
    }

    fn put(&mut self, key: MemoKey, raw: &[u8], z: &[u8]) {
        if raw.len() + z.len() > REMEMBERED_BYTES / 4 {
            return;
        }
        self.uses += 1;
        self.bytes += raw.len() + z.len();
        if let Some(old) = self.entries.insert(key, (self.uses, raw.to_vec(), z.to_vec())) {
            self.bytes -= old.1.len() + old.2.len();
        }
        self.order.push_back((key, self.uses));
        while self.bytes > REMEMBERED_BYTES {
            let Some((k, n)) = self.order.pop_front() else { break };
            if self.entries.get(&k).is_some_and(|e| e.0 == n)
                && let Some(old) = self.entries.remove(&k)
            {
                self.bytes -= old.1.len() + old.2.len();
            }
        }
    }
}

thread_local! {
    static CCTX: std::cell::RefCell<Compression> = std::cell::RefCell::new(Compression::default());
}

/// `raw` as one zstd frame at `level`, the same bytes as `zstd::bulk::compress` gives. Small
/// inputs go through one context per thread, and inputs compressed lately are remembered
/// with their frames ([`REMEMBERED_BYTES`]), so a payload compressed once to measure it and
/// once to store it, or the same payload at every keyframe, is compressed once.
pub fn compress(raw: &[u8], level: i32) -> std::io::Result<Vec<u8>> {
    if raw.len() > REMEMBERED && level < super::ZSTD_LEVEL {
        return zstd::bulk::compress(raw, level);
    }
    CCTX.with(|cell| {
        let Ok(mut state) = cell.try_borrow_mut() else {
            return zstd::bulk::compress(raw, level);
        };
        let key = (level, raw.len(), crc32fast::hash(raw));
        if let Some(z) = state.memo.get(key, raw) {
            return Ok(z);
        }
        let z = if raw.len() > REMEMBERED {
            zstd::bulk::compress(raw, level)?
        } else {
            let at = match state.contexts.iter().position(|(l, _)| *l == level) {
                Some(at) => at,
                None => {
                    // A caller cycling through many levels keeps at most four contexts.
                    if state.contexts.len() == 4 {
                        state.contexts.remove(0);
                    }
                    state.contexts.push((level, zstd::bulk::Compressor::new(level)?));
                    state.contexts.len() - 1
                }
            };
            state.contexts[at].1.compress(raw)?
        };
        state.memo.put(key, raw, &z);
        Ok(z)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes that compress to something of their own: a few runs of a number in `seed`'s order.
    fn input(seed: u32, len: usize) -> Vec<u8> {
        (0..len as u32).map(|i| ((i / 7).wrapping_mul(seed.wrapping_mul(2_654_435_761) | 1) >> 5) as u8).collect()
    }

    #[test]
    fn remembered_frames_are_zstd_s_own() {
        // Small and large inputs, at the file's level and a fast one, each asked for again
        // after enough others that the first are forgotten (more than REMEMBERED_BYTES).
        let sizes = [10, 3_000, 70_000, 500_000];
        let mut asked = Vec::new();
        for round in 0..2 {
            for seed in 0..40u32 {
                let raw = input(seed, sizes[seed as usize % sizes.len()]);
                for level in [super::super::ZSTD_LEVEL, 1] {
                    let got = compress(&raw, level).unwrap();
                    assert_eq!(got, zstd::bulk::compress(&raw, level).unwrap(), "seed {seed} level {level} round {round}");
                    asked.push(got.len());
                }
            }
        }
        CCTX.with(|c| assert!(c.borrow().memo.bytes <= REMEMBERED_BYTES));
        assert_eq!(asked[..asked.len() / 2], asked[asked.len() / 2..]);
    }
}
