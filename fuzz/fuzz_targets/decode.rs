//! Arbitrary bytes through the container reader, verifier and decoder: must never panic or
//! allocate without bound. `cargo +nightly fuzz run decode -- -max_total_time=600`
#![no_main]

use libfuzzer_sys::fuzz_target;
use pmcodec_container::{CutTarget, Decoder, Reader, verify};

fuzz_target!(|data: &[u8]| {
    if let Ok(reader) = Reader::open(data) {
        let _ = verify(&reader);
        // Full resolution, and a level-1 client (which reads the faces and corners chunks).
        for level in [0, 1] {
            if let Ok(mut d) = Decoder::new(reader.borrowed(), level) {
                if d.seek(reader.header().frame_count.saturating_sub(1)).is_ok() {
                    let _ = d.mesh(CutTarget::Triangles(100));
                }
            }
        }
    }
});
