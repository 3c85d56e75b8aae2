//! Development probe: the cost of `Decoder::mesh` at triangle budgets on a decoded frame (what
//! the server's LOD endpoint spends per request on a warm state).
//! `cargo run --release -p pmcodec-container --example lod_cost -- FILE.pmc [budget]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{Decoder, MeshTarget, Reader};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let bytes = std::fs::read(&args[1]).expect("read");
    let reader = Reader::open(bytes.as_slice()).expect("open");
    let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
    d.seek(reader.header().frame_count / 2).expect("seek");
    let budgets: Vec<u32> = match args.get(2) {
        Some(b) => vec![b.parse().expect("budget")],
        None => vec![500, 2000, 8000, 16000],
    };
    for budget in budgets {
        let n = 200;
        let t = std::time::Instant::now();
        let mut tris = 0;
        for _ in 0..n {
            tris = d.mesh(MeshTarget::Triangles(budget)).expect("mesh").triangles.len();
        }
        println!("budget {budget}: {tris} triangles, {:.3} ms per mesh", t.elapsed().as_secs_f64() * 1e3 / n as f64);
    }
}
