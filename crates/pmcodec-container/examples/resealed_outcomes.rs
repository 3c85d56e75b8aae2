//! Records what each file of the resealed regression corpus (tests/resealed/*.pmc: the fuzz
//! target's minimized corpus and its crashers) gives today, in tests/resealed/outcomes.txt,
//! which `tests/resealed.rs` then holds every later build to. Run it after adding files, and
//! read the changes it makes: a file that used to be refused and now plays needs a reason.
//! `cargo run -p pmcodec-container --features test-support --example resealed_outcomes`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::testing::outcome;
use std::fmt::Write;

fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/resealed");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .expect("tests/resealed")
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".pmc"))
        .collect();
    names.sort();
    let mut out = String::from(
        "# The resealed fuzz corpus and crashers: NAME OUTCOME (ok, or the ContainerError variant the file must give).\n\
         # Regenerate the lines with `cargo run -p pmcodec-container --features test-support --example resealed_outcomes`.\n",
    );
    let mut counts = std::collections::BTreeMap::new();
    for n in &names {
        let bytes = std::fs::read(dir.join(n)).expect("read");
        let o = outcome(&bytes);
        *counts.entry(o).or_insert(0) += 1;
        let _ = writeln!(out, "{n} {o}");
    }
    std::fs::write(dir.join("outcomes.txt"), out).expect("write outcomes.txt");
    println!("{} files: {counts:?}", names.len());
}
