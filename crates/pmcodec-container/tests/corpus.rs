//! The committed fuzz corpus as a regular test: valid files verify, damaged ones give errors,
//! and every single-byte corruption of the valid files is survived without a panic.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{Decoder, MeshTarget, Reader, verify};

fn exercise(bytes: &[u8]) -> Result<(), String> {
    let reader = Reader::open(bytes).map_err(|e| e.to_string())?;
    verify(&reader).map_err(|e| e.to_string())?;
    let mut d = Decoder::new(reader.borrowed(), 0).map_err(|e| e.to_string())?;
    d.seek(reader.header().frame_count - 1).map_err(|e| e.to_string())?;
    d.mesh(MeshTarget::Triangles(50)).map_err(|e| e.to_string())?;
    // A level-1 client reads the faces and corners chunks a full one skips.
    if reader.header().levels() > 1 {
        let mut d = Decoder::new(reader.borrowed(), 1).map_err(|e| e.to_string())?;
        for f in 0..reader.header().frame_count {
            d.seek(f).map_err(|e| e.to_string())?;
        }
        d.mesh(MeshTarget::Triangles(30)).map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn corpus() -> Vec<(String, Vec<u8>)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .expect("tests/corpus")
        .map(|e| {
            let p = e.expect("entry").path();
            (p.file_name().unwrap_or_default().to_string_lossy().into_owned(), std::fs::read(&p).expect("read"))
        })
        .collect();
    files.sort();
    files
}

#[test]
fn corpus_files_behave() {
    let files = corpus();
    assert!(files.len() >= 30, "corpus has {} files", files.len());
    for (name, bytes) in &files {
        let r = exercise(bytes);
        if name.starts_with("valid-") {
            r.unwrap_or_else(|e| panic!("{name}: {e}"));
        } else {
            assert!(r.is_err(), "{name}: damage not detected");
        }
    }
}

#[test]
fn every_byte_flip_is_survived() {
    for (name, bytes) in corpus().into_iter().filter(|(n, _)| n.starts_with("valid-")) {
        for at in 0..bytes.len() {
            let mut b = bytes.clone();
            b[at] ^= 0xFF;
            // Either an error or (for bytes no check covers, such as reserved fields) success;
            // never a panic, never an unbounded allocation.
            let _ = exercise(&b);
        }
        let _ = name;
    }
}
