//! What decoding may allocate (proto/container.md, "Limits"): a header declaring absurd sizes is
//! refused by name, a payload claiming more elements than it can hold is refused before
//! anything is sized from the claim, and no resealed damage makes a decoder allocate more than
//! the stated multiple of the header's declared sizes.
#![allow(clippy::unwrap_used, clippy::expect_used)]
// Counting allocations means implementing GlobalAlloc, an unsafe trait: the one place of the
// workspace with unsafe code (pmcodec-container's Cargo.toml lowers `forbid` to `deny` for it).
#![allow(unsafe_code)]

use pmcodec_container::format::{MAX_FRAMES, MAX_NODES, MAX_TRIANGLES, MAX_VERTICES};
use pmcodec_container::testing::{Rng, Unsealed, allocation_bound, allocation_bound_unopened, exercise, mutate, reseal};
use pmcodec_container::{ContainerError, Header, Reader, payload};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// Counts the bytes each thread has allocated and not freed, and the most it has held: the
/// tests below run on one thread each, so their figures are their own.
struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            grow(l.size() as isize);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        grow(-(l.size() as isize));
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(l) };
        if !p.is_null() {
            grow(l.size() as isize);
        }
        p
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, l, new) };
        if !q.is_null() {
            grow(new as isize - l.size() as isize);
        }
        q
    }
}

fn grow(by: isize) {
    // `try_with`: a thread being torn down has no counters left, and its frees do not matter.
    let _ = LIVE.try_with(|live| {
        let now = live.get() + by;
        live.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// The most `f` held at once beyond what was held before it, in bytes.
fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let out = f();
    (out, (PEAK.with(Cell::get) - base).max(0) as usize)
}

/// The committed seed files (a few hundred nodes each), and one larger file (some thousands),
/// on which the per-element part of the bound, not its constant, is what is measured.
fn seeds() -> Vec<Vec<u8>> {
    let mut out = committed_seeds();
    let opts = pmcodec_container::EncodeOptions { keyframe_interval: 2, ..Default::default() };
    out.push(pmcodec_container::encode(&pmcodec_mesh::samples::twisting_tube(48, 40, 3), &opts, |_| {}).expect("encode"));
    out
}

fn committed_seeds() -> Vec<Vec<u8>> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .expect("tests/corpus")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("valid-")))
        .collect();
    names.sort();
    assert!(names.len() >= 5, "valid seed files in {}", dir.display());
    names.iter().map(|p| std::fs::read(p).expect("read")).collect()
}

/// A seed with its header changed by `f`, resealed.
fn with_header(bytes: &[u8], f: impl FnOnce(&mut Header)) -> Vec<u8> {
    reseal(bytes, |u| {
        let mut h = u.parsed_header().expect("header");
        f(&mut h);
        u.set_header(&h);
    })
    .expect("reseal")
}

fn corrupt_header(bytes: &[u8]) -> String {
    match Reader::open(bytes) {
        Err(ContainerError::Corrupt { what, detail }) if what == "header" => detail,
        Err(e) => panic!("expected a corrupt header, got {e}"),
        Ok(_) => panic!("expected a corrupt header, it opened"),
    }
}

#[test]
fn absurd_declared_sizes_are_refused_by_name() {
    let seed = &committed_seeds()[0];
    let d = corrupt_header(&with_header(seed, |h| {
        h.vertex_count = MAX_VERTICES + 1;
        h.level_sizes[0] = MAX_VERTICES + 1;
    }));
    assert!(d.contains("vertices, more than"), "{d}");
    let d = corrupt_header(&with_header(seed, |h| h.triangle_count = MAX_TRIANGLES + 1));
    assert!(d.contains("triangles, more than"), "{d}");
    let d = corrupt_header(&with_header(seed, |h| h.frame_count = MAX_FRAMES + 1));
    assert!(d.contains("frames, more than"), "{d}");
    let d = corrupt_header(&with_header(seed, |h| {
        h.vertex_count = MAX_VERTICES;
        h.level_sizes = vec![MAX_VERTICES; 3];
    }));
    assert!(d.contains(&format!("nodes in all levels, more than the {MAX_NODES}")), "{d}");
    let d = corrupt_header(&with_header(seed, |h| h.level_sizes = vec![h.vertex_count; 65]));
    assert!(d.contains("65 levels"), "{d}");
    // Within the caps but beyond what the chunks hold: the index refuses it at open, before a
    // decoder sizes anything from the header.
    let e = Reader::open(with_header(seed, |h| h.triangle_count = 1 << 20).as_slice()).err().expect("refused");
    assert!(e.to_string().contains("below the"), "{e}");
    // And a chunk declaring more than its kind can hold.
    let big = reseal(seed, |u| {
        let i = u.chunks.iter().position(|c| c.entry.kind == pmcodec_container::ChunkKind::Delta).expect("a delta chunk");
        u.chunks[i].raw.resize(1 << 20, 0);
    })
    .expect("reseal");
    let e = Reader::open(big.as_slice()).err().expect("refused");
    assert!(e.to_string().contains("beyond the"), "{e}");
}

#[test]
fn payload_claims_are_refused_before_allocating() {
    // A million faces, triangles, parents, moves or nodes claimed in a few bytes.
    let mut claim = Vec::new();
    payload::put(&mut claim, 1_000_000);
    claim.extend_from_slice(&[1, 2, 3, 4]);
    let sizes = [2_000_000u32, 1_000_000, 1];
    let (r, peak) = peak_of(|| payload::read_faces(&claim, "t", 1_000_000, 2_000_000, 5));
    assert!(r.unwrap_err().to_string().contains("1000000 faces in 4 bytes"));
    assert!(peak < 4096, "read_faces held {peak} bytes");
    let (r, peak) = peak_of(|| payload::read_triangles(&claim, "t", 1_000_000, 3_000_000, 7));
    assert!(r.is_err() && peak < 4096, "read_triangles held {peak} bytes");
    let (r, peak) = peak_of(|| payload::read_key(&claim, "t", &sizes[1..], 0, 7));
    assert!(r.is_err() && peak < 4096, "read_key held {peak} bytes");
    let (r, peak) = peak_of(|| payload::read_delta(&claim, "t", &sizes, 0));
    assert!(r.is_err() && peak < 4096, "read_delta held {peak} bytes");
    let held = vec![[0u32, 1, 2]; 2_000_000];
    let (r, peak) = peak_of(|| payload::read_corner_updates(&claim, "t", 10, &held));
    assert!(r.is_err() && peak < 4096, "read_corner_updates held {peak} bytes");
    // Positions coded as varints: three per node.
    let (r, peak) = peak_of(|| payload::read_positions(&[32, 0, 0, 0], "t", 1_000_000));
    assert!(r.unwrap_err().to_string().contains("1000000 nodes in 3 bytes"));
    assert!(peak < 4096, "read_positions held {peak} bytes");
}

/// The seeded resealed mutations, each measured: what open, verify and three decoders hold at
/// most stays within the stated bound of the declared sizes.
#[test]
fn decoding_stays_within_the_stated_multiple_of_the_declared_sizes() {
    let mut worst = 0f64;
    let mut per_element = 0f64;
    let mut measured = 0;
    for (k, seed) in seeds().iter().enumerate() {
        let base = Unsealed::open(seed).expect("seed");
        // Fewer mutations of the larger file: each costs more.
        let runs = if seed.len() > 10_000 { 20 } else { 120 };
        for i in 0..runs {
            let mut u = base.clone();
            if i > 0 {
                mutate(&mut u, &mut Rng::new(0x6d65_6d00 ^ (k as u64) << 32 ^ i));
            }
            let file = u.seal();
            let (_, peak) = peak_of(|| exercise(&file));
            // The bound of the header as declared (files that do not open have allocated only
            // while reading their tables).
            let Ok(reader) = Reader::open(file.as_slice()) else {
                let b = allocation_bound_unopened(file.len());
                assert!(peak <= b, "a file that does not open held {peak} bytes, bound {b}");
                continue;
            };
            let b = allocation_bound(&reader);
            assert!(peak <= b, "seed {k} mutation {i}: held {peak} bytes, bound {b}");
            worst = worst.max(peak as f64 / b as f64);
            let h = reader.header();
            per_element = per_element.max(peak as f64 / (h.node_count() + h.triangle_count as u64 + h.frame_count as u64) as f64);
            measured += 1;
        }
    }
    eprintln!("{measured} files that open: at most {:.1}% of the bound, {per_element:.0} bytes per declared element", worst * 100.0);
}
