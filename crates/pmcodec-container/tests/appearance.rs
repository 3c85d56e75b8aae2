//! Version 6 appearance: texture coordinates, colours and materials stored once per level,
//! read back at every level, every cut inside its chart, normals from decoded positions.
#![allow(clippy::unwrap_used, clippy::expect_used)]
// Corners index several parallel arrays in step (triangles, wedges, ancestors).
#![allow(clippy::needless_range_loop)]

use pmcodec_container::{CutTarget, Decoder, EncodeOptions, QuantizationChoice, Reader, encode, format::ChunkKind, summary, verify};
use pmcodec_mesh::samples::textured_cloth;

const W: u32 = 24;
const H: u32 = 16;

fn encoded(frames: u32) -> (pmcodec_mesh::Sequence, Vec<u8>) {
    let seq = textured_cloth(W, H, frames, 16);
    let opts = EncodeOptions { keyframe_interval: 4, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let bytes = encode(&seq, &opts, |_| {}).expect("encode");
    (seq, bytes)
}

/// The texture-coordinate region of each material in the cloth: u within these bounds.
fn u_range(material: u32) -> (f32, f32) {
    let split = ((W - 1) / 2) as f32 / (W - 1) as f32;
    if material == 0 { (0.0, split) } else { (split + 0.25, 1.25) }
}

#[test]
fn every_level_reads_back_inside_its_charts() {
    let (seq, bytes) = encoded(6);
    let input = seq.appearance.as_ref().unwrap();
    let reader = Reader::open(bytes.as_slice()).expect("open");
    assert_eq!(reader.version(), pmcodec_container::format::VERSION);
    verify(&reader).expect("verify");
    let info = reader.header().appearance.clone().expect("appearance in the header");
    assert_eq!((info.uv_sets, info.colors, info.materials, info.images), (1, true, 2, 1));
    let levels = reader.header().levels();
    assert!(levels >= 3, "{levels} levels");
    for level in 0..levels {
        let mut d = Decoder::new(reader.borrowed(), level).expect("decoder");
        for f in 0..6 {
            d.seek(f).expect("seek");
            let plain = d.mesh(CutTarget::Level(level)).expect("mesh");
            let (mesh, app) = d.textured_mesh(CutTarget::Level(level)).expect("textured");
            assert_eq!(mesh.triangles.len(), plain.triangles.len(), "level {level} frame {f}");
            app.validate(mesh.positions.len(), &mesh.triangles).expect("a valid appearance");
            assert_eq!(app.materials.len(), 2);
            for (t, tri) in mesh.triangles.iter().enumerate() {
                let m = app.triangle_material[t];
                let (lo, hi) = u_range(m);
                for &v in tri {
                    let u = app.uv0[v as usize][0];
                    // A coarse value is a weighted mean of its chart's wedges: inside the chart's
                    // texture region (a triangle never straddles two materials), within a quantum.
                    assert!(
                        u >= lo - 1e-3 && u <= hi + 1e-3,
                        "level {level} frame {f} triangle {t}: u {u} outside material {m}'s {lo}..{hi}"
                    );
                    let n = app.normals[v as usize];
                    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                    assert!((len - 1.0).abs() < 1e-5, "normal {n:?}");
                }
            }
            if level == 0 {
                // Level 0 is the input: every corner's UV within half a quantum, materials exact.
                assert_eq!(app.triangle_material, input.triangle_material);
                let step = info.uv_step;
                for (t, tri) in mesh.triangles.iter().enumerate() {
                    for i in 0..3 {
                        let (got, want) = (app.uv0[tri[i] as usize], input.uv0[input.corner_wedges[t][i] as usize]);
                        for a in 0..2 {
                            assert!((got[a] - want[a]).abs() <= step[a] * 0.5 + 1e-6, "triangle {t} corner {i}: {got:?} vs {want:?}");
                        }
                        let (gc, wc) = (app.colors[tri[i] as usize], input.colors[input.corner_wedges[t][i] as usize]);
                        assert!(gc.iter().zip(wc).all(|(a, b)| (a - b).abs() <= 0.5 / 255.0 + 1e-6), "colour {gc:?} vs {wc:?}");
                    }
                }
            }
        }
    }
    // Band 0's entries are derived from the triangles (its chunk starts 0, 1): the level-0
    // checks above read that coding.
    let band0 = reader.read_chunk(reader.find(ChunkKind::Attributes, 0, 0).expect("band 0 attributes")).expect("read");
    assert_eq!((band0[0], band0[1] & 7), (0, 1));

    let images = Decoder::new(reader.borrowed(), 0).unwrap().images().expect("images");
    assert_eq!(images.len(), 1);
    assert_eq!(images[0].bytes, input.images[0].bytes);
}

#[test]
fn budget_cuts_carry_appearance_and_seams_split_vertices() {
    let (_, bytes) = encoded(5);
    let reader = Reader::open(bytes.as_slice()).expect("open");
    let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
    for f in 0..5 {
        d.seek(f).expect("seek");
        for budget in [40, 150, 400, 10_000] {
            let plain = d.mesh(CutTarget::Triangles(budget)).expect("mesh");
            let (mesh, app) = d.textured_mesh(CutTarget::Triangles(budget)).expect("textured");
            assert_eq!(mesh.triangles.len(), plain.triangles.len(), "budget {budget}");
            // The material seam doubles the vertices along it: more vertices than cut nodes.
            assert!(mesh.positions.len() > plain.positions.len(), "budget {budget}: {} vs {}", mesh.positions.len(), plain.positions.len());
            for (t, tri) in mesh.triangles.iter().enumerate() {
                let (lo, hi) = u_range(app.triangle_material[t]);
                assert!(tri.iter().all(|&v| (lo - 1e-3..=hi + 1e-3).contains(&app.uv0[v as usize][0])), "budget {budget} triangle {t}");
            }
        }
    }
}

#[test]
fn a_coarse_client_reads_a_small_share_of_the_appearance() {
    let (_, bytes) = encoded(4);
    let reader = Reader::open(bytes.as_slice()).expect("open");
    let s = summary(&reader);
    let all: u64 = s.attributes_bytes.iter().sum();
    let coarse: u64 = s.attributes_bytes[2..].iter().sum();
    assert!(all > 0 && s.charts_bytes > 0 && s.materials_bytes > 0 && s.image_bytes > 0);
    // Level 2 holds about a tenth of the vertices: its client reads part of the tables only.
    // Since coarse values are their representatives' input values (sent once, coarse first),
    // the finer bands send only the rest and the coarse bands' share grew (about a half here,
    // where it was under one); a coarse client reads no more bytes than before.
    assert!(coarse * 3 < all * 2, "bands 2.. hold {coarse} of {all} attribute bytes");
    let entries = reader.index().chunks.iter().filter(|e| e.kind == ChunkKind::Attributes).count();
    assert_eq!(entries, reader.header().levels());
}

#[test]
fn a_bare_surface_has_no_appearance() {
    let seq = pmcodec_mesh::samples::waving_cloth(8, 6, 3);
    let bytes = encode(&seq, &EncodeOptions::default(), |_| {}).expect("encode");
    let reader = Reader::open(bytes.as_slice()).expect("open");
    assert!(reader.header().appearance.is_none());
    let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
    d.seek(0).expect("seek");
    assert!(d.textured_mesh(CutTarget::Level(0)).is_err());
    assert!(d.images().expect("none").is_empty());
}

/// A tube whose triangles fall into many small UV islands (a chart per triangle band, as in a
/// low-poly character's atlas): budget cuts that mix levels put a coarse corner beside fine
/// ones of another chart. Every budget of every frame must find its (node, chart) entries.
#[test]
fn budget_cuts_mixing_levels_find_every_chart_entry() {
    let mut seq = pmcodec_mesh::samples::twisting_tube(24, 20, 6);
    let mut app = pmcodec_mesh::Appearance::default();
    let mut wedge: std::collections::HashMap<(u32, u32), u32> = Default::default();
    for (t, tri) in seq.triangles.iter().enumerate() {
        // A chart per 7 triangles, scattered: charts meet along many short seams.
        let chart = ((t as u32).wrapping_mul(2_654_435_761) >> 7) % 37;
        let mut cw = [0u32; 3];
        for i in 0..3 {
            let next = app.wedge_vertex.len() as u32;
            cw[i] = *wedge.entry((tri[i], chart)).or_insert(next);
            if cw[i] == next {
                app.wedge_vertex.push(tri[i]);
                let p = seq.frames[0][tri[i] as usize];
                app.uv0.push([chart as f32 + 0.5 * p.x.fract().abs(), 0.5 * p.z.fract().abs()]);
            }
        }
        app.corner_wedges.push(cw);
    }
    app.validate(seq.frames[0].len(), &seq.triangles).expect("a valid appearance");
    seq.appearance = Some(app);
    let opts = EncodeOptions { keyframe_interval: 3, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let bytes = encode(&seq, &opts, |_| {}).expect("encode");
    let reader = Reader::open(bytes.as_slice()).expect("open");
    // Which coding each band's table took (0 listed, else the mode after a first byte 0).
    let modes: Vec<u8> = (0..reader.header().levels() as u32)
        .map(|j| {
            let raw = reader.read_chunk(reader.find(ChunkKind::Attributes, 0, j).expect("attributes")).expect("read");
            if raw.len() > 1 && raw[0] == 0 { raw[1] } else { 0 }
        })
        .collect();
    // The cuts below read band 0 with derived entries and bands predicted from the band above
    // (either with its residuals entropy-coded: the mode's bit 8).
    assert!(modes[0] & 7 == 1 && modes.iter().any(|m| m & 7 == 3), "table codings by band: {modes:?}");
    // A band above 0 predicts its values across its faces (mode 3 | 64) and band 0 takes its
    // representatives' values from above (| 16): level 0 is then the input only if that band
    // decodes exactly as it was written.
    assert!(modes[0] & 16 != 0 && modes[1..].iter().any(|m| m & 64 != 0), "table codings by band: {modes:?}");
    let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
    d.seek(0).expect("seek");
    let (mesh, app) = d.textured_mesh(CutTarget::Level(0)).expect("level 0");
    let (input, step) = (seq.appearance.as_ref().expect("appearance"), reader.header().appearance.as_ref().expect("info").uv_step);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for i in 0..3 {
            let (got, want) = (app.uv0[tri[i] as usize], input.uv0[input.corner_wedges[t][i] as usize]);
            assert!((0..2).all(|a| (got[a] - want[a]).abs() <= step[a] * 0.5 + 1e-6), "triangle {t} corner {i}: {got:?} vs {want:?}");
        }
    }
    let n = seq.triangles.len() as u32;
    let mut mixed = 0;
    for f in 0..6 {
        d.seek(f).expect("seek");
        for budget in (1..=n).step_by(7) {
            let (mesh, app) = d.textured_mesh(CutTarget::Triangles(budget)).unwrap_or_else(|e| panic!("frame {f} budget {budget}: {e}"));
            assert_eq!(mesh.triangles.len(), d.mesh(CutTarget::Triangles(budget)).expect("mesh").triangles.len());
            // Every corner's u lies in its chart's strip [chart, chart + 0.5], within the
            // quantization step (37 units over the texture-coordinate bits).
            let tol = 0.02;
            assert!(app.uv0.iter().all(|uv| uv[0].fract() <= 0.5 + tol || uv[0].fract() >= 1.0 - tol), "frame {f} budget {budget}");
            mixed += 1;
        }
    }
    assert!(mixed > 100);
}

/// Materials without texture coordinates or colours (a RobotExpressive-like input: several
/// materials in scattered, disconnected patches): one chart per material, no Attributes chunks
/// at all, and every level and budget cut still draws, each triangle in its input material.
#[test]
fn materials_without_values_need_no_tables() {
    let mut seq = pmcodec_mesh::samples::twisting_tube(24, 20, 6);
    let n = seq.triangles.len();
    let mut app = pmcodec_mesh::Appearance {
        wedge_vertex: (0..seq.frames[0].len() as u32).collect(),
        corner_wedges: seq.triangles.clone(),
        // Five materials in scattered runs of triangles: each is many disconnected patches.
        triangle_material: (0..n as u32).map(|t| (t.wrapping_mul(2_654_435_761) >> 9) % 5).collect(),
        ..Default::default()
    };
    app.materials = (0..5).map(|m| pmcodec_mesh::appearance::Material { name: Some(format!("m{m}")), ..Default::default() }).collect();
    app.validate(seq.frames[0].len(), &seq.triangles).expect("a valid appearance");
    let input_materials = app.triangle_material.clone();
    seq.appearance = Some(app);
    let opts = EncodeOptions { keyframe_interval: 3, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let bytes = encode(&seq, &opts, |_| {}).expect("encode");
    let reader = Reader::open(bytes.as_slice()).expect("open");
    verify(&reader).expect("verify");
    let info = reader.header().appearance.clone().expect("appearance");
    assert_eq!((info.channels(), info.charts, info.materials), (0, 5, 5));
    assert!(!reader.index().chunks.iter().any(|e| e.kind == ChunkKind::Attributes), "value-less tables were written");
    let s = summary(&reader);
    // A chart per material: the charts chunk is the material runs, a byte or two per run.
    assert!(s.charts_bytes < 3 * n as u64, "{} bytes of charts for {n} triangles", s.charts_bytes);
    let levels = reader.header().levels();
    for level in 0..levels {
        let mut d = Decoder::new(reader.borrowed(), level).expect("decoder");
        for f in [0, 4] {
            d.seek(f).expect("seek");
            let (mesh, app) = d.textured_mesh(CutTarget::Level(level)).expect("textured");
            assert_eq!(mesh.triangles.len(), d.mesh(CutTarget::Level(level)).expect("mesh").triangles.len());
            assert!(app.uv0.is_empty() && app.colors.is_empty());
            assert_eq!(app.normals.len(), mesh.positions.len());
            if level == 0 {
                assert_eq!(app.triangle_material, input_materials, "frame {f}");
            }
            if level == 0 {
                for budget in (1..=n as u32).step_by(41) {
                    let (mesh, app) =
                        d.textured_mesh(CutTarget::Triangles(budget)).unwrap_or_else(|e| panic!("frame {f} budget {budget}: {e}"));
                    assert_eq!(mesh.triangles.len(), app.triangle_material.len());
                    assert!(app.triangle_material.iter().all(|&m| m < 5));
                }
            }
        }
    }
}

/// A UV-mapped cylinder (issue 16's represented values): the tube's side unrolled with a seam
/// where u wraps from 1 back to 0, its caps a second chart each, and colours from a palette of
/// four (repeated values) beside all-distinct texture coordinates. Every coarse value is one
/// of the input's own (each band sends only the values the band above does not hold), the
/// tables take the represented codings (mode | 16), and level 0 reads back the input.
#[test]
fn coarse_values_of_a_seamed_cylinder_are_input_values() {
    let (segments, rings) = (24u32, 20u32);
    let mut seq = pmcodec_mesh::samples::twisting_tube(segments, rings, 5);
    let mut app = pmcodec_mesh::Appearance::default();
    let side = rings * segments;
    let mut wedge: std::collections::HashMap<(u32, bool), u32> = Default::default();
    let palette = [[255u8, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [255, 255, 0, 255]];
    for tri in &seq.triangles {
        let cap = tri.iter().any(|&v| v >= side);
        // A side triangle spanning the last column takes the seam's wedges (u = 1) there.
        let wraps = !cap && tri.iter().any(|&v| v % segments == segments - 1) && tri.iter().any(|&v| v % segments == 0);
        let mut cw = [0u32; 3];
        for i in 0..3 {
            let v = tri[i];
            let seam = wraps && v % segments == 0;
            let next = app.wedge_vertex.len() as u32;
            cw[i] = *wedge.entry((v, seam || cap)).or_insert(next);
            if cw[i] == next {
                app.wedge_vertex.push(v);
                let uv = if v >= side {
                    [1.25, if v == side { 0.25 } else { 0.75 }]
                } else if cap {
                    let a = std::f32::consts::TAU * (v % segments) as f32 / segments as f32;
                    [1.25 + 0.2 * a.cos(), if v / segments == 0 { 0.25 } else { 0.75 } + 0.2 * a.sin()]
                } else {
                    [if seam { 1.0 } else { (v % segments) as f32 / segments as f32 }, (v / segments) as f32 / (rings - 1) as f32]
                };
                app.uv0.push(uv);
                app.colors.push(palette[(v / 5 % 4) as usize].map(|c| c as f32 / 255.0));
            }
        }
        app.corner_wedges.push(cw);
    }
    app.validate(seq.frames[0].len(), &seq.triangles).expect("a valid appearance");
    seq.appearance = Some(app.clone());
    let opts = EncodeOptions { keyframe_interval: 3, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let bytes = encode(&seq, &opts, |_| {}).expect("encode");
    let reader = Reader::open(bytes.as_slice()).expect("open");
    verify(&reader).expect("verify");
    let info = reader.header().appearance.clone().expect("appearance");
    assert_eq!((info.uv_sets, info.colors), (1, true));
    assert!(info.charts >= 3, "{} charts", info.charts);
    let modes: Vec<u8> = (0..reader.header().levels() as u32)
        .map(|j| {
            let raw = reader.read_chunk(reader.find(ChunkKind::Attributes, 0, j).expect("attributes")).expect("read");
            if raw.len() > 1 && raw[0] == 0 { raw[1] } else { 0 }
        })
        .collect();
    // (Band 0 may list its entries: a regular grid's chart-wise differences compress well.)
    assert!(modes.iter().any(|m| m & 16 != 0), "no band with represented values: {modes:?}");
    // The input's values as a decoder draws them: quantized on the header's grid, dequantized.
    let q = |a: usize, x: f32| ((x - info.uv_min[a]) / info.uv_step[a]).round() as i32;
    let drawn = |uv: [f32; 2], c: [f32; 4]| {
        let uv = [0, 1].map(|a| ((info.uv_min[a] as f64 + q(a, uv[a]) as f64 * info.uv_step[a] as f64) as f32).to_bits());
        let c = c.map(|x| (((x.clamp(0.0, 1.0) * 255.0).round() as f64) / 255.0) as f32);
        (uv, c.map(f32::to_bits))
    };
    let input: std::collections::HashSet<_> = app.uv0.iter().zip(&app.colors).map(|(&uv, &c)| drawn(uv, c)).collect();
    for level in 0..reader.header().levels() {
        let mut d = Decoder::new(reader.borrowed(), level).expect("decoder");
        d.seek(0).expect("seek");
        let (mesh, got) = d.textured_mesh(CutTarget::Level(level)).expect("textured");
        assert!(!mesh.triangles.is_empty());
        for (v, (&uv, &c)) in got.uv0.iter().zip(&got.colors).enumerate() {
            let key = (uv.map(f32::to_bits), c.map(f32::to_bits));
            assert!(input.contains(&key), "level {level} vertex {v}: {uv:?} {c:?} is no input value");
        }
    }
}
