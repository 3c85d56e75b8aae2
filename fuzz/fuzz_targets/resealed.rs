//! Structure-aware fuzzing of the container decoders: the inputs are whole `.pmc` files whose
//! checksums are always right. The custom mutator takes a file apart
//! (`pmcodec_container::testing::Unsealed`), damages the header, the index or a decompressed
//! chunk payload (with our structural mutations or libFuzzer's own byte mutations), and seals
//! it again, so nearly every input gets past the CRCs to the payload readers, rANS, the
//! predictors and the replay. Every error must be a typed one (a panic is a crash), and
//! decoding must allocate within the bound proto/container.md states.
//!
//! `cargo +nightly fuzz run resealed -- -max_len=16384 -jobs=1 -workers=1 -max_total_time=1800`
//! (seeds: `crates/pmcodec-container/tests/corpus/valid-*.pmc`; the corpus it grows is
//! minimized into `crates/pmcodec-container/tests/resealed/`).
#![no_main]

use libfuzzer_sys::{fuzz_mutator, fuzz_target, fuzzer_mutate};
use pmcodec_container::Reader;
use pmcodec_container::testing::{Rng, Unsealed, allocation_bound, allocation_bound_unopened, exercise, mutate};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::AtomicUsize;
use std::sync::atomic::Ordering::Relaxed;

static SEEDS: [&[u8]; 8] = [
    include_bytes!("../../crates/pmcodec-container/tests/corpus/valid-cloth-k0.pmc"),
    include_bytes!("../../crates/pmcodec-container/tests/corpus/valid-cloth-k1.pmc"),
    include_bytes!("../../crates/pmcodec-container/tests/corpus/valid-tube-k2.pmc"),
    include_bytes!("../../crates/pmcodec-container/tests/corpus/valid-tube-affine.pmc"),
    include_bytes!("../../crates/pmcodec-container/tests/corpus/valid-tube-mean-input.pmc"),
    include_bytes!("../../crates/pmcodec-container/tests/corpus/valid-skinned-character.pmc"),
    include_bytes!("../../crates/pmcodec-container/tests/corpus/valid-textured-cloth.pmc"),
    include_bytes!("../../crates/pmcodec-container/tests/corpus/valid-fitted-tube.pmc"),
];

/// Counts the bytes Rust code holds (zstd's own buffers are C allocations, bounded by the
/// chunk sizes), and the most it held, so that each input is held to the allocation bound.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            let now = LIVE.fetch_add(l.size(), Relaxed) + l.size();
            PEAK.fetch_max(now, Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        LIVE.fetch_sub(l.size(), Relaxed);
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

fuzz_target!(|data: &[u8]| {
    let base = LIVE.load(Relaxed);
    PEAK.store(base, Relaxed);
    let _ = exercise(data);
    let peak = PEAK.load(Relaxed).saturating_sub(base);
    let bound = match Reader::open(data) {
        Ok(reader) => allocation_bound(&reader),
        Err(_) => allocation_bound_unopened(data.len()),
    };
    assert!(peak <= bound, "held {peak} bytes, bound {bound}");
});

fuzz_mutator!(|data: &mut [u8], size: usize, max_size: usize, seed: u32| {
    let mut rng = Rng::new(seed as u64 ^ ((size as u64) << 32));
    let current = if rng.chance(32) { None } else { Unsealed::open(&data[..size]).ok() };
    let mut u = match current {
        Some(u) => u,
        None => match Unsealed::open(SEEDS[rng.below(SEEDS.len())]) {
            Ok(u) => u,
            Err(_) => return fuzzer_mutate(data, size, max_size),
        },
    };
    if rng.chance(3) && !u.chunks.is_empty() {
        // libFuzzer's own mutations (which insert the values comparisons were seen to want)
        // on one decompressed payload or on the header's bytes.
        let i = rng.below(u.chunks.len() + 1);
        let target = if i < u.chunks.len() { &mut u.chunks[i].raw } else { &mut u.header };
        let len = target.len();
        let cap = (len * 2).max(64);
        target.resize(cap, 0);
        let n = fuzzer_mutate(target, len, cap);
        target.truncate(n);
    } else {
        mutate(&mut u, &mut rng);
    }
    let out = u.seal();
    if out.len() > max_size {
        return fuzzer_mutate(data, size, max_size);
    }
    data[..out.len()].copy_from_slice(&out);
    out.len()
});
