//! Reclustering speed on the 8,431-vertex horse gallop (issue bars: encode under 10 ms per
//! frame on one core; a client applying one frame's deltas and updating a 2,000-triangle cut
//! under 0.1 ms).
//!
//! `cargo bench -p pmcodec-hierarchy --bench recluster`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_hierarchy::CutTarget;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::cut::ChildIndex;
use pmcodec_hierarchy::progressive::{Encoder, FrameDelta, Replay};
use pmcodec_hierarchy::recluster::ReclusterOptions;
use pmcodec_hierarchy::*;
use pmcodec_mesh::Sequence;
use std::cell::RefCell;
use std::path::PathBuf;
use std::sync::OnceLock;

fn main() {
    divan::main();
}

fn horse() -> &'static Sequence {
    static SEQ: OnceLock<Sequence> = OnceLock::new();
    SEQ.get_or_init(|| {
        let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/horse-gallop"));
        pmcodec_mesh::obj::load_obj_sequence(&dir, 30.0).expect("the horse gallop in ../shared/data")
    })
}

fn encoder(seq: &Sequence) -> (Encoder, Hierarchy) {
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(seq, &topo, &BaseOptions::default());
    let h = build(&topo, &q, &BuildOptions::default()).expect("build");
    (Encoder::new(h.clone(), topo, seq.triangles.clone(), ReclusterOptions::default()), h)
}

/// One frame of reclustering plus its degenerate-set and corner deltas: the encoder's whole
/// per-frame cost. Frames cycle through the gallop (the encoder keeps adapting, as it would on
/// a looping animation).
#[divan::bench]
fn encode_frame_horse(bencher: divan::Bencher) {
    let seq = horse();
    let (enc, _) = encoder(seq);
    let state = RefCell::new((enc, 0usize));
    bencher.bench_local(|| {
        let mut s = state.borrow_mut();
        let f = s.1 % seq.frame_count();
        s.1 += 1;
        s.0.encode_frame(&seq.frames[f]).1.swaps
    });
}

/// Replay states before each frame, with a 2,000-triangle cut, and the frame's delta.
fn replay_inputs() -> &'static Vec<(Replay, FrameDelta)> {
    static INPUTS: OnceLock<Vec<(Replay, FrameDelta)>> = OnceLock::new();
    INPUTS.get_or_init(|| {
        let seq = horse();
        let (mut enc, base) = encoder(seq);
        let mut replay = Replay::new(base, &seq.triangles);
        let mut out = Vec::new();
        for (f, frame) in seq.frames.iter().enumerate() {
            let (delta, _) = enc.encode_frame(frame);
            if f == 0 {
                replay.apply(&delta).expect("delta");
                let h = enc.hierarchy();
                let d = DegenerateSets::from_nodes(h.node_count(), enc.degeneration().to_vec());
                let c = pmcodec_eval::select_cut(h, &d, &ChildIndex::new(h), enc.nodes(), CutTarget::Triangles(2000));
                replay.set_cut(&c.expanded);
                continue;
            }
            out.push((replay.clone(), delta.clone()));
            replay.apply(&delta).expect("delta");
        }
        out
    })
}

/// What a playback client does per frame: apply the swaps and degenerate-set deltas and
/// update the shown triangles of its cut (section 5.1).
#[divan::bench]
fn apply_frame_delta_2000_triangles(bencher: divan::Bencher) {
    let inputs = replay_inputs();
    let mut i = 0usize;
    bencher
        .with_inputs(|| {
            i += 1;
            inputs[i % inputs.len()].clone()
        })
        .bench_local_values(|(mut replay, delta)| {
            replay.apply(&delta).expect("delta");
            (replay.shown().len(), replay)
        });
}
