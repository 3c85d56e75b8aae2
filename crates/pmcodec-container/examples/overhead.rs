//! Issue 17, "overhead on small meshes": a file's bits per vertex per frame beyond its position
//! bits (tables, chunk framing, index), written as files were before the preamble flags (every
//! chunk a zstd frame, empty ones too) and as today's encoder writes them (`format::FLAGS`).
//! Without arguments: a generated waving cloth of 54 x 54 = 2,916 vertices and 200 frames; with
//! a glTF path, its animations played back to back (as the `skinned` example).
//! `cargo run --release -p pmcodec-container --example overhead -- [file.glb]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{EncodeOptions, QuantizationChoice, Reader, encode, summary};
use pmcodec_mesh::gltf_input::RiggedMesh;

fn main() {
    let seq = match std::env::args().nth(1) {
        None => pmcodec_mesh::samples::waving_cloth(54, 54, 200),
        Some(path) => {
            let mut rig = RiggedMesh::from_path(std::path::Path::new(&path)).expect("load");
            rig.weld();
            let mut out: Option<pmcodec_mesh::Sequence> = None;
            for a in 0..rig.animations.len() {
                let s = rig.to_sequence(Some(a), 30.0).expect("sample");
                match out.as_mut() {
                    None => out = Some(s),
                    Some(o) => {
                        o.frames.extend(s.frames);
                        o.frame_names.extend(s.frame_names);
                        if let (Some(a), Some(b)) = (o.skin.as_mut(), s.skin) {
                            a.matrices.extend(b.matrices);
                        }
                    }
                }
            }
            out.expect("animations")
        }
    };
    let (n, frames) = (seq.vertex_count(), seq.frame_count());
    println!("{n} vertices, {frames} frames, 12-bit quantization");
    for flags in [0, pmcodec_container::format::FLAGS] {
        let opts = EncodeOptions { quantization: QuantizationChoice::Bits(12), chunk_flags: flags, ..Default::default() };
        let bytes = encode(&seq, &opts, |_| {}).expect("encode");
        let r = Reader::open(bytes.as_slice()).expect("open");
        let s = summary(&r);
        let total = bytes.len() as f64 * 8.0 / (n * frames) as f64;
        let stored = r.index().chunks.iter().filter(|e| e.stored_len == e.raw_len).count();
        println!(
            "  flags {flags}: {} bytes, {total:.3} bits/vertex/frame, positions {:.3}, overhead {:.3}; \
             {} chunks ({stored} stored as is), preamble+header+index {} B",
            bytes.len(),
            s.positions_bits_per_vertex_frame,
            total - s.positions_bits_per_vertex_frame,
            r.index().chunks.len(),
            r.data_start()
        );
    }
}
