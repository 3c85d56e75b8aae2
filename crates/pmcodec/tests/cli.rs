//! The `pmcodec` binary end to end on a generated OBJ sequence: encode, info, verify, decode,
//! and the errors and exit codes users see.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_pmcodec"))
}

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pmcodec-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes a small waving sheet as OBJ frames named so that natural order differs from plain
/// string order (f2 before f10).
fn write_sequence(dir: &Path, frames: usize) {
    let seq = pmcodec_mesh::samples::waving_cloth(14, 10, frames as u32);
    for f in 0..frames {
        let mesh = seq.frame_mesh(f).unwrap();
        pmcodec_mesh::write::write_mesh_file(&dir.join(format!("f{}.obj", f + 1)), &mesh).unwrap();
    }
}

fn ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{cmd:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn encode_info_verify_decode() {
    let dir = temp("main");
    let frames_dir = dir.join("in");
    std::fs::create_dir_all(&frames_dir).unwrap();
    write_sequence(&frames_dir, 12);
    let pmc = dir.join("seq.pmc");
    ok(bin().args(["encode", "-q", "--keyframe-interval", "4", "--quant-bits", "14"]).arg(&frames_dir).arg("-o").arg(&pmc));
    let info: serde_json::Value = serde_json::from_str(&ok(bin().arg("info").arg(&pmc).arg("--json"))).unwrap();
    assert_eq!(info["header"]["frame_count"], 12);
    assert_eq!(info["header"]["vertex_count"], 140);
    assert_eq!((&info["header"]["motion"], &info["header"]["order"]), (&"keyframe-affine".into(), &"breadth-first".into()));
    assert!(ok(bin().arg("verify").arg(&pmc)).contains("ok"));
    // Version 4's prediction, asked for by name, is what the header then says.
    let v4 = dir.join("v4.pmc");
    ok(bin().args(["encode", "-q", "--motion", "mean", "--order", "input"]).arg(&frames_dir).arg("-o").arg(&v4));
    let table = ok(bin().arg("info").arg(&v4));
    assert!(table.contains("mean motion between keyframes, input vertices in input order"), "{table}");
    // Level 0 of frame 9 is the input frame f10.obj: same faces, positions within the bound.
    let out = dir.join("f9.obj");
    ok(bin().args(["decode", "-q", "--frame", "9", "--level", "0"]).arg(&pmc).arg("-o").arg(&out));
    let decoded = pmcodec_mesh::obj::read_obj(&out).unwrap();
    let input = pmcodec_mesh::obj::read_obj(&frames_dir.join("f10.obj")).unwrap();
    assert_eq!(decoded.triangles, input.triangles);
    for (a, b) in decoded.positions.iter().zip(&input.positions) {
        assert!((*a - *b).length() < 1e-3, "{a} vs {b}");
    }
    // A budget, as GLB.
    let glb = dir.join("b.glb");
    ok(bin().args(["decode", "-q", "--frame", "3", "--triangles", "60"]).arg(&pmc).arg("-o").arg(&glb));
    let g = gltf::Gltf::from_slice(&std::fs::read(&glb).unwrap()).unwrap();
    let count = g.meshes().next().unwrap().primitives().next().unwrap().indices().unwrap().count();
    assert!(count <= 180 && count > 0, "{count}");
    // Every frame, names in frame order.
    let all = dir.join("all");
    ok(bin().args(["decode", "-q", "--all-frames", "--level", "1"]).arg(&pmc).arg("-o").arg(&all));
    let mut names: Vec<String> = std::fs::read_dir(&all).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(names.len(), 12);
    assert_eq!(names[0], "frame-0000.obj");
    assert_eq!(names[11], "frame-0011.obj");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_input_is_reported_with_exit_code_and_no_output() {
    let dir = temp("bad");
    // Frames that disagree: the error names the frame.
    let frames_dir = dir.join("in");
    std::fs::create_dir_all(&frames_dir).unwrap();
    write_sequence(&frames_dir, 3);
    std::fs::write(frames_dir.join("f3.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let pmc = dir.join("x.pmc");
    let out = bin().arg("encode").arg(&frames_dir).arg("-o").arg(&pmc).output().unwrap();
    assert_eq!(out.status.code(), Some(3));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("f3.obj") && err.contains("vertices"), "{err}");
    assert!(!pmc.exists(), "no half file");
    assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().contains("tmp")));
    // Not a container.
    std::fs::write(dir.join("junk.pmc"), b"hello").unwrap();
    let out = bin().arg("info").arg(dir.join("junk.pmc")).output().unwrap();
    assert_eq!(out.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a .pmc file"));
    // Usage errors are clap's exit code 2.
    assert_eq!(bin().args(["decode", "x.pmc", "--triangles", "5", "--level", "1", "-o", "y.obj"]).output().unwrap().status.code(), Some(2));
    std::fs::remove_dir_all(&dir).ok();
}

/// `eval --pmc` measures a container's own cuts beside the methods asked for, and refuses a
/// container of another sequence by name.
#[test]
fn eval_measures_a_container() {
    let dir = temp("eval");
    let frames_dir = dir.join("in");
    std::fs::create_dir_all(&frames_dir).unwrap();
    write_sequence(&frames_dir, 5);
    let pmc = dir.join("seq.pmc");
    ok(bin().args(["encode", "-q"]).arg(&frames_dir).arg("-o").arg(&pmc));
    let out = ok(bin()
        .args([
            "eval",
            "-q",
            "--methods",
            "static,direct",
            "--vertices",
            "40",
            "--coherence-triangles",
            "60",
            "--samples",
            "2000",
            "--json",
        ])
        .arg(&frames_dir)
        .arg("--pmc")
        .arg(&pmc));
    let report: serde_json::Value = serde_json::from_str(&out).unwrap();
    let methods = report["methods"].as_array().unwrap();
    // What a client gets leads (issue 15).
    assert_eq!(methods.iter().map(|m| m["method"].as_str().unwrap()).collect::<Vec<_>>(), ["container", "static", "direct"]);
    let container = &methods[0];
    assert_eq!(container["rms"].as_array().unwrap().len(), 5);
    let rms = container["mean_rms"].as_f64().unwrap();
    assert!(rms > 0.0 && rms < 10.0, "{rms}");
    // Coherence by cluster content for every method; by node ids where nodes persist.
    for m in methods {
        let changed = m["mean_changed_share"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&changed), "{changed}");
        assert_eq!(m["changed_share"].as_array().unwrap().len(), 5);
    }
    assert!(methods[0]["mean_changed_share_by_node_ids"].is_f64() && methods[1]["mean_changed_share_by_node_ids"].is_f64());
    assert!(methods[2]["mean_changed_share_by_node_ids"].is_null(), "direct has no persistent node ids");
    // Static keeps one cut of one hierarchy: no triangle changes, by either identity.
    assert_eq!(methods[1]["mean_changed_share"].as_f64().unwrap(), 0.0);
    assert_eq!(methods[1]["mean_changed_share_by_node_ids"].as_f64().unwrap(), 0.0);
    // A container of another mesh is refused, naming the file.
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    let seq = pmcodec_mesh::samples::waving_cloth(6, 5, 5);
    for f in 0..5 {
        pmcodec_mesh::write::write_mesh_file(&other.join(format!("f{}.obj", f + 1)), &seq.frame_mesh(f).unwrap()).unwrap();
    }
    let out = bin().args(["eval", "-q", "--methods", "static", "--vertices", "10"]).arg(&other).arg("--pmc").arg(&pmc).output().unwrap();
    assert_eq!(out.status.code(), Some(3), "bad input");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("seq.pmc") && err.contains("not an encoding of it"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Runs `cmd`, expecting it to fail with `code`; returns its stderr.
fn fails(cmd: &mut Command, code: i32) -> String {
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "{cmd:?}: {err}");
    err
}

/// A 12-frame container of the small sheet (140 vertices, 234 triangles), keyframes every 4.
fn small_container(dir: &Path) -> PathBuf {
    let frames_dir = dir.join("in");
    std::fs::create_dir_all(&frames_dir).unwrap();
    write_sequence(&frames_dir, 12);
    let pmc = dir.join("seq.pmc");
    ok(bin().args(["encode", "-q", "--keyframe-interval", "4"]).arg(&frames_dir).arg("-o").arg(&pmc));
    pmc
}

/// Values out of the file's range are bad input (exit 3) naming the value and the range, as the
/// server answers 400, and nothing is written.
#[test]
fn decode_targets_out_of_range_are_bad_input() {
    let dir = temp("range");
    let pmc = small_container(&dir);
    let out = dir.join("x.obj");
    let levels = {
        let info: serde_json::Value = serde_json::from_str(&ok(bin().arg("info").arg(&pmc).arg("--json"))).unwrap();
        info["header"]["level_sizes"].as_array().unwrap().len()
    };
    let decode = |extra: &[&str]| {
        let mut c = bin();
        c.arg("decode").arg(&pmc).arg("-o").arg(&out).args(extra);
        c
    };
    let err = fails(&mut decode(&["--level", "99"]), 3);
    assert!(err.contains("--level 99") && err.contains(&format!("0..={}", levels - 1)), "{err}");
    for bad in ["NaN", "-1", "inf", "-inf"] {
        let err = fails(&mut decode(&["--max-error", bad]), 3);
        assert!(err.contains("--max-error") && err.contains(">= 0"), "{bad}: {err}");
    }
    let err = fails(&mut decode(&["--frame", "999"]), 3);
    assert!(err.contains("--frame 999") && err.contains("12 frames"), "{err}");
    for bad in ["0%", "150%", "NaN%"] {
        let err = fails(&mut decode(&["--triangles", bad]), 3);
        assert!(err.contains("--triangles") && err.contains("at most 100%"), "{bad}: {err}");
    }
    // Not a count at all is a usage error, as is an output format that does not exist.
    fails(&mut decode(&["--triangles", "many"]), 2);
    let err = fails(bin().arg("decode").arg(&pmc).arg("-o").arg(dir.join("x.stl")), 2);
    assert!(err.contains(".glb or .obj"), "{err}");
    assert!(!out.exists() && !dir.join("x.stl").exists(), "nothing written");
    // The last level and a zero error bound are in range.
    ok(decode(&["-q", "--level", &(levels - 1).to_string()]).arg("--frame").arg("11"));
    ok(&mut decode(&["-q", "--max-error", "0"]));
    std::fs::remove_dir_all(&dir).ok();
}

/// Flips a byte inside the stored bytes of frame `frame`'s band-0 positions chunk, leaving the
/// header and index intact (so the file still opens).
fn damage_positions(pmc: &Path, frame: u32) {
    let mut bytes = std::fs::read(pmc).unwrap();
    let (at, name) = {
        let r = pmcodec_container::Reader::open(bytes.as_slice()).unwrap();
        let e = r.find(pmcodec_container::ChunkKind::Positions, frame, 0).expect("a band-0 positions chunk");
        (r.data_start() + e.offset + e.stored_len as u64 / 2, e.describe())
    };
    bytes[at as usize] ^= 0x40;
    std::fs::write(pmc, bytes).unwrap();
    assert!(name.contains(&format!("frame {frame}")), "{name}");
}

/// A damaged chunk is bad input from every command that reads it (exit 3, naming the file, the
/// frame and the chunk), and a failed `--all-frames` decode leaves no files behind.
#[test]
fn damaged_chunk_is_bad_input_everywhere() {
    let dir = temp("crc");
    let pmc = small_container(&dir);
    damage_positions(&pmc, 5);
    let name = pmc.display().to_string();
    // Frame 3 is before the damage: still decodes.
    ok(bin().args(["decode", "-q", "--frame", "3"]).arg(&pmc).arg("-o").arg(dir.join("f3.obj")));
    let out = dir.join("f6.obj");
    let err = fails(bin().args(["decode", "--frame", "6"]).arg(&pmc).arg("-o").arg(&out), 3);
    assert!(err.contains(&name) && err.contains("frame 5 band 0 positions") && err.contains("checksum"), "{err}");
    assert!(!out.exists());
    let err = fails(bin().arg("verify").arg(&pmc), 3);
    assert!(err.contains(&name) && err.contains("frame 5 band 0 positions: checksum"), "{err}");
    let all = dir.join("all");
    let err = fails(bin().args(["decode", "-q", "--all-frames"]).arg(&pmc).arg("-o").arg(&all), 3);
    assert!(err.contains("checksum"), "{err}");
    assert!(!all.exists(), "a failed --all-frames decode leaves nothing");
    // A damaged header is bad input for info too.
    let mut bytes = std::fs::read(&pmc).unwrap();
    bytes[20] ^= 0xff;
    std::fs::write(&pmc, bytes).unwrap();
    fails(bin().arg("info").arg(&pmc), 3);
    std::fs::remove_dir_all(&dir).ok();
}

/// `--triangles 25%` is a share of the full-resolution triangles, as `lod` takes; a budget below
/// the coarsest cut gives that cut with a warning (and `over_budget` in `--json`).
#[test]
fn decode_budgets_as_percentages_and_over_budget_warning() {
    let dir = temp("pct");
    let pmc = small_container(&dir);
    let info: serde_json::Value = serde_json::from_str(&ok(bin().arg("info").arg(&pmc).arg("--json"))).unwrap();
    let full = info["header"]["triangle_count"].as_u64().unwrap();
    let decoded = |flag: &str, budget: &str| -> (serde_json::Value, String) {
        let out =
            bin().args(["decode", "--json", "--frame", "7", flag, budget]).arg(&pmc).arg("-o").arg(dir.join("b.obj")).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{flag} {budget}: {err}");
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (json[0].clone(), err)
    };
    let (quarter, err) = decoded("--triangles", "25%");
    let n = quarter["triangles"].as_u64().unwrap();
    assert!(n <= full / 4 && n > full / 8, "{n} of {full}");
    assert!(quarter["over_budget"].is_null() && !err.contains("warning"), "{quarter} {err}");
    // The same as the count it stands for.
    let (count, _) = decoded("--triangles", &(full / 4).to_string());
    assert_eq!(count["triangles"], quarter["triangles"]);
    let (v, _) = decoded("--vertices", "10%");
    assert!(v["vertices"].as_u64().unwrap() <= 14 || v["over_budget"]["of"] == "vertices", "{v}");
    // One triangle is below any cut: the coarsest is written, and said to be over budget.
    let (coarsest, err) = decoded("--triangles", "1");
    let got = coarsest["triangles"].as_u64().unwrap();
    assert!(got > 1, "{coarsest}");
    assert_eq!(coarsest["over_budget"]["asked"], 1);
    assert_eq!(coarsest["over_budget"]["got"], got);
    assert!(err.contains("warning") && err.contains(&format!("{got} triangles, more than the 1 asked for")), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `info` prints the encoding options as rows a person reads, not a Rust `Debug` struct.
#[test]
fn info_prints_encoding_options_as_rows() {
    let dir = temp("info");
    let pmc = small_container(&dir);
    let table = ok(bin().arg("info").arg(&pmc));
    assert!(!table.contains("EncodedWith") && !table.contains('{'), "{table}");
    for row in ["  base poses      first", "  homeomorphism   no", "  max passes      16", "  quantization    max error 0.0001"] {
        assert!(table.lines().any(|l| l == row || l.starts_with(row)), "no row {row:?} in\n{table}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `eval --sweep N` measures the container's cut (encoded in memory), direct and static at N
/// budgets from 1% to 50% of the vertices, on frames spread over the sequence, and `--plot`
/// writes a PNG of the ratios.
#[test]
fn eval_sweep_table_and_plot() {
    let dir = temp("sweep");
    let frames_dir = dir.join("in");
    std::fs::create_dir_all(&frames_dir).unwrap();
    let seq = pmcodec_mesh::samples::waving_cloth(30, 20, 6);
    for f in 0..6 {
        pmcodec_mesh::write::write_mesh_file(&frames_dir.join(format!("f{}.obj", f + 1)), &seq.frame_mesh(f).unwrap()).unwrap();
    }
    let png_path = dir.join("sweep.png");
    let out = ok(bin()
        .args(["eval", "-q", "--sweep", "12", "--frames", "3", "--samples", "500", "--json"])
        .arg(&frames_dir)
        .arg("--plot")
        .arg(&png_path));
    let report: serde_json::Value = serde_json::from_str(&out).unwrap();
    let all_rows = report["rows"].as_array().unwrap();
    // The 12 budgets, and the container's levels in their range as rows of their own.
    let rows: Vec<&serde_json::Value> = all_rows.iter().filter(|r| r["swept"] == true).collect();
    assert_eq!(rows.len(), 12);
    assert!(all_rows.iter().any(|r| r["level"].as_u64() == Some(1)), "level 1 is within 1%..50%");
    assert!(report["worst_frame0_at_levels"].as_f64().unwrap() > 0.0);
    assert_eq!(report["frames_measured"], serde_json::json!([0, 3, 5]));
    let vertices: Vec<u64> = rows.iter().map(|r| r["vertices"].as_u64().unwrap()).collect();
    assert!(vertices.windows(2).all(|w| w[1] > w[0]) && vertices[11] == 300, "{vertices:?}");
    for r in all_rows {
        for m in ["container", "direct", "static"] {
            let rms = r[m]["mean_rms"].as_f64().unwrap();
            assert!(rms > 0.0 && rms < 20.0, "{m} {rms}");
        }
        // Finer budgets are closer for the direct method (one QEM run, snapshotted).
        assert!(r["container_over_direct"].as_f64().unwrap() > 0.0);
    }
    assert!(rows[11]["direct"]["mean_rms"].as_f64().unwrap() < rows[0]["direct"]["mean_rms"].as_f64().unwrap());
    let mut reader = png::Decoder::new(std::io::Cursor::new(std::fs::read(&png_path).unwrap())).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert!(info.width >= 400 && info.height >= 300);
    // The text table has a line per budget.
    let table = ok(bin().args(["eval", "-q", "--sweep", "4", "--frames", "2", "--samples", "300"]).arg(&frames_dir));
    let rows = table.lines().filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit())).count();
    let levels = table.lines().filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit()) && l.contains(" L")).count();
    assert!(rows >= 4 && rows <= 4 + levels, "{table}");
    // --plot without --sweep is a usage error.
    assert_eq!(bin().args(["eval", "-q", "--plot", "x.png"]).arg(&frames_dir).output().unwrap().status.code(), Some(2));
    std::fs::remove_dir_all(&dir).ok();
}

/// A sweep over a mesh of many small parts (12 bumpy 5 x 5 grids): its coarsest cuts collapse
/// every part to a point or a line and have no surface, so those budgets are left out (named in
/// `left_out` and a warning) instead of failing the sweep, as it did on RobotExpressive.
#[test]
fn eval_sweep_leaves_out_budgets_without_a_surface() {
    let dir = temp("sweepparts");
    let frames_dir = dir.join("in");
    std::fs::create_dir_all(&frames_dir).unwrap();
    for f in 0..3 {
        let mut obj = String::new();
        for p in 0..12 {
            let (x0, y0) = ((p % 4) as f32 * 6.0, (p / 4) as f32 * 6.0);
            for j in 0..5 {
                for i in 0..5 {
                    let z = ((i * 7 + j * 3 + p) % 5) as f32 * 0.2 + 0.1 * f as f32 * (i as f32);
                    obj += &format!("v {} {} {}\n", x0 + i as f32, y0 + j as f32, z);
                }
            }
            let b = 25 * p + 1;
            for j in 0..4 {
                for i in 0..4 {
                    let v = b + 5 * j + i;
                    obj += &format!("f {} {} {}\nf {} {} {}\n", v, v + 1, v + 6, v, v + 6, v + 5);
                }
            }
        }
        std::fs::write(frames_dir.join(format!("f{}.obj", f + 1)), obj).unwrap();
    }
    let out = bin().args(["eval", "--sweep", "12", "--samples", "300", "--json"]).arg(&frames_dir).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let left_out: Vec<u64> = report["left_out"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap()).collect();
    assert!(!left_out.is_empty() && left_out.iter().all(|&v| v < 36), "{left_out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("left out"), "the warning names the budgets");
    let rows = report["rows"].as_array().unwrap();
    assert!(rows.len() >= 3, "{rows:?}");
    assert!(rows.iter().all(|r| r["vertices"].as_u64().unwrap() >= 12 && r["container"]["mean_rms"].as_f64().unwrap() > 0.0));
    std::fs::remove_dir_all(&dir).ok();
}

/// `eval` checks its values before any work: out of range is bad input naming the value and the
/// range (`--vertices 0` used to never return).
#[test]
fn eval_values_out_of_range_are_bad_input() {
    let dir = temp("evalrange");
    let frames_dir = dir.join("in");
    std::fs::create_dir_all(&frames_dir).unwrap();
    write_sequence(&frames_dir, 2);
    for (args, says) in [
        (&["--vertices", "0"][..], "--vertices 0: the input has 140 vertices; use 1..=140"),
        (&["--vertices", "141"], "use 1..=140"),
        (&["--vertices", "40", "--samples", "0"], "--samples 0"),
        (&["--vertices", "40", "--branching", "1"], "--branching 1: use 2..=16"),
        (&["--vertices", "40", "--beta", "NaN"], "--beta NaN: use a finite number >= 0"),
        (&["--vertices", "40", "--min-benefit", "-1"], "--min-benefit -1"),
    ] {
        let err = fails(bin().args(["eval", "-q", "--methods", "static"]).arg(&frames_dir).args(args), 3);
        assert!(err.contains(says), "{args:?}: {err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `encode` refuses values out of range as bad input, each named once, and writes nothing.
#[test]
fn encode_values_out_of_range_are_bad_input() {
    let dir = temp("encrange");
    let frames_dir = dir.join("in");
    std::fs::create_dir_all(&frames_dir).unwrap();
    write_sequence(&frames_dir, 2);
    let pmc = dir.join("x.pmc");
    for (args, says) in [
        (&["--fps", "1e-30"][..], "--fps 1e-30: use 0.01..=1000"),
        (&["--fps", "1001"], "--fps 1001.0"),
        (&["--beta", "NaN"], "--beta NaN: use a finite number >= 0"),
        (&["--min-benefit", "-1"], "--min-benefit -1"),
        (&["--branching", "99"], "branching factor 99 is outside 2..=16"),
        (&["--quant-bits", "40"], "4..=24 bits"),
        (&["--level-anchors", "50%,60%"], "percentages must decrease"),
    ] {
        let err = fails(bin().args(["encode", "-q"]).arg(&frames_dir).arg("-o").arg(&pmc).args(args), 3);
        assert_eq!(err.matches(says).count(), 1, "{args:?}: {err}");
        assert!(!pmc.exists());
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `play` against a server on loopback: an asset the server does not have is bad input (its
/// 404 named), a server that cannot be reached is a failure, and a played asset reports every
/// frame.
#[test]
fn play_exit_codes_follow_the_server_answers() {
    let dir = temp("play");
    let seq = pmcodec_mesh::samples::waving_cloth(14, 10, 6);
    let bytes = pmcodec_container::encode(&seq, &Default::default(), |_| {}).unwrap();
    std::fs::write(dir.join("cloth.pmc"), &bytes).unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let config = pmcodec_server::Config {
        store: pmcodec_server::config::StoreConfig::Local { path: dir.clone() },
        listen: "127.0.0.1:0".parse().unwrap(),
        ..Default::default()
    };
    let server = rt.block_on(pmcodec_server::start(config)).unwrap();
    let url = server.url();
    let out = ok(bin().args(["play", "--json", "--asset", "cloth", "--triangles", "50"]).arg(&url));
    let lines: Vec<serde_json::Value> = out.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 7, "six frames and a summary: {out}");
    assert_eq!(lines[6]["frames"], 6);
    let err = fails(bin().args(["play", "--asset", "nope"]).arg(&url), 3);
    assert!(err.contains("nope") && err.contains("404"), "{err}");
    drop(server);
    drop(rt);
    // Nothing listens on a port just freed: a failure, not bad input.
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    fails(bin().args(["play", "--asset", "cloth"]).arg(format!("http://127.0.0.1:{port}")), 1);
    std::fs::remove_dir_all(&dir).ok();
}

/// `encode` and `eval` take the same reclustering flags (one flattened set): what `encode` was
/// given is what the file says it was encoded with, a flag left out keeps the library's default,
/// and both commands refuse the same out-of-range value the same way.
#[test]
fn encode_and_eval_share_the_reclustering_flags() {
    let dir = temp("recluster");
    let frames_dir = dir.join("in");
    std::fs::create_dir_all(&frames_dir).unwrap();
    write_sequence(&frames_dir, 3);
    let pmc = dir.join("seq.pmc");
    ok(bin()
        .args(["encode", "-q", "--max-passes", "3", "--max-swaps", "5", "--estimated-benefit", "--beta", "2.5"])
        .arg(&frames_dir)
        .arg("-o")
        .arg(&pmc));
    let table = ok(bin().arg("info").arg(&pmc));
    for says in ["max passes      3", "exact benefit   no", "beta            2.5", "min benefit     1"] {
        assert!(table.contains(says), "{says}: {table}");
    }
    let defaults = dir.join("defaults.pmc");
    ok(bin().args(["encode", "-q"]).arg(&frames_dir).arg("-o").arg(&defaults));
    let table = ok(bin().arg("info").arg(&defaults));
    for says in ["max passes      16", "exact benefit   yes", "beta            4"] {
        assert!(table.contains(says), "{says}: {table}");
    }
    ok(bin()
        .args(["eval", "-q", "--methods", "pmcodec", "--vertices", "40", "--samples", "200", "--max-swaps", "5", "--max-passes", "2"])
        .arg(&frames_dir));
    for cmd in ["encode", "eval"] {
        let mut c = bin();
        c.args([cmd, "-q", "--max-passes", "2", "--min-benefit", "-1"]).arg(&frames_dir);
        if cmd == "encode" {
            c.arg("-o").arg(dir.join("bad.pmc"));
        } else {
            c.args(["--vertices", "40"]);
        }
        let err = fails(&mut c, 3);
        assert!(err.contains("--min-benefit -1: use a finite number >= 0"), "{cmd}: {err}");
    }
    assert!(!dir.join("bad.pmc").exists());
    std::fs::remove_dir_all(&dir).ok();
}
