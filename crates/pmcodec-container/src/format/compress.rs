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

/// Inputs up to this size go through [`compress`]'s kept context and are remembered (a small
/// band's Positions payload is compressed to choose its coding, then again to be stored).
/// Larger ones get a context of their own, freed after: zstd sizes a context's tables by its
/// largest input, and a kept one sized by a 135k-vertex band added 20 MiB to the encoder's peak
/// memory, while creating a context costs little beside compressing that much.
const REMEMBERED: usize = 1 << 16;

/// How many of the last small inputs [`compress`] remembers: a small band's Positions payload
/// tries three codings (sparse, rANS, varints) and the chosen one is compressed again when
/// stored; with two remembered, a chosen sparse payload (tried first) was compressed twice.
const REMEMBERED_INPUTS: usize = 3;

/// What [`compress`] keeps per thread: its context, and the last small input with its frame.
#[derive(Default)]
struct Compression {
    /// One context per level used (an encode uses two: [`ZSTD_LEVEL`] and
    /// [`RANS_ZSTD_LEVEL`], chunk after chunk).
    contexts: Vec<(i32, zstd::bulk::Compressor<'static>)>,
    last: Vec<(i32, Vec<u8>, Vec<u8>)>,
}

thread_local! {
    static CCTX: std::cell::RefCell<Compression> = std::cell::RefCell::new(Compression::default());
}

/// `raw` as one zstd frame at `level`, the same bytes as `zstd::bulk::compress` gives. Small
/// inputs go through one context per thread (creating a level-19 context per chunk cost about
/// 2% of a whole encode of the horse), and the last three are remembered with their frames, so a
/// payload compressed once to measure it and once to store it is compressed once.
pub fn compress(raw: &[u8], level: i32) -> std::io::Result<Vec<u8>> {
    if raw.len() > REMEMBERED {
        return zstd::bulk::compress(raw, level);
    }
    CCTX.with(|cell| {
        let Ok(mut state) = cell.try_borrow_mut() else {
            return zstd::bulk::compress(raw, level);
        };
        if let Some((_, _, z)) = state.last.iter().find(|(l, r, _)| *l == level && r.as_slice() == raw) {
            return Ok(z.clone());
        }
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
        let z = state.contexts[at].1.compress(raw)?;
        if state.last.len() == REMEMBERED_INPUTS {
            state.last.remove(0);
        }
        state.last.push((level, raw.to_vec(), z.clone()));
        Ok(z)
    })
}
