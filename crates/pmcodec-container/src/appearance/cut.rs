//! A cut's appearance: per shown triangle corner the texture coordinates and colour of its
//! (cut node, chart) entry, and a normal computed from the decoded positions, area weighted
//! per (cut node, smoothing group) (proto/container.md, "Drawing a cut's appearance"; the
//! TypeScript decoder computes the same bits).

use super::charts::Charts;
use super::format::{AppearanceInfo, MaterialsChunk};
use super::payload::Table;
use crate::ContainerError;
use glam::Vec3;
use pmcodec_mesh::{Appearance, TriMesh};

/// Everything of a file's appearance but the images, as a decoder holds it.
#[derive(Clone, Debug, Default)]
pub struct DecodedAppearance {
    /// The header's appearance field; `None` for a bare surface (then everything here is empty).
    pub info: Option<AppearanceInfo>,
    /// Every input triangle's chart, and every chart's material and smoothing group.
    pub charts: Charts,
    /// Per level; `None` below the decoder's finest level.
    pub tables: Vec<Option<Table>>,
    /// The Materials chunk: materials, textures, samplers, image descriptions.
    pub materials: MaterialsChunk,
    /// The images, read on first use and shared by clones of the decoder.
    pub images: Option<std::sync::Arc<Vec<pmcodec_mesh::appearance::Image>>>,
}

/// Texture coordinate `q` of axis `a` (binary64, rounded once to binary32).
pub fn dequantize_uv(info: &AppearanceInfo, a: usize, q: i32) -> f32 {
    (info.uv_min[a] as f64 + q as f64 * info.uv_step[a] as f64) as f32
}

/// The mesh of a cut with its appearance. `shown` lists the shown triangles in mesh order,
/// each with the global ids of its corners' cut nodes; `offsets` are the levels' first global
/// ids (one more entry than levels). Output vertices are the distinct (cut node, chart,
/// smoothing group) triples in order of first use; the appearance has one wedge per vertex.
pub fn textured_mesh(
    d: &DecodedAppearance,
    offsets: &[u32],
    positions: &[Vec3],
    shown: &[(u32, [u32; 3])],
) -> Result<(TriMesh, Appearance), ContainerError> {
    let Some(info) = d.info.as_ref() else {
        return Err(ContainerError::Options("the file has no appearance".into()));
    };
    let channels = info.channels();
    let mut mesh = TriMesh::default();
    let mut app = Appearance::default();
    mesh.positions.reserve(shown.len());
    mesh.triangles.reserve(shown.len());
    // Flat arrays instead of hash maps (this runs every frame): per cut node, the head of a
    // list of its drawn vertices (distinct (chart, group)) and of its normal sums (distinct
    // group); almost every node has one of each, so the lists are a slot or two long.
    const NONE: u32 = u32::MAX;
    let mut vertex_head = vec![NONE; positions.len()];
    let mut vertex_next: Vec<u32> = Vec::with_capacity(shown.len());
    let mut vertex_tag: Vec<(u32, u32)> = Vec::with_capacity(shown.len());
    let mut sum_head = vec![NONE; positions.len()];
    let mut sum_next: Vec<u32> = Vec::with_capacity(shown.len());
    let mut sum_group: Vec<u32> = Vec::with_capacity(shown.len());
    let mut sums: Vec<[f64; 3]> = Vec::with_capacity(shown.len());
    // Per vertex: its normal sum.
    let mut vertex_sum: Vec<u32> = Vec::with_capacity(shown.len());
    let level_of = |g: u32| offsets.partition_point(|&o| o <= g).saturating_sub(1);
    let beyond = |g: u32| ContainerError::Corrupt { what: "cut".into(), detail: format!("node {g} beyond the decoded nodes") };
    for &(t, cut) in shown {
        let chart =
            *d.charts.triangle_chart.get(t as usize).ok_or_else(|| ContainerError::Options(format!("triangle {t} beyond the charts")))?;
        let group = d.charts.triangle_group[t as usize];
        let p = cut.map(|g| positions.get(g as usize).copied().unwrap_or(Vec3::ZERO).as_dvec3());
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let n = [e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x];
        let mut tri = [0u32; 3];
        for i in 0..3 {
            let g = cut[i];
            let gi = g as usize;
            // The normal sum of (g, group), accumulated in triangle order (the spec's order).
            let mut s = *sum_head.get(gi).ok_or_else(|| beyond(g))?;
            while s != NONE && sum_group[s as usize] != group {
                s = sum_next[s as usize];
            }
            if s == NONE {
                s = sums.len() as u32;
                sums.push([0.0; 3]);
                sum_group.push(group);
                sum_next.push(sum_head[gi]);
                sum_head[gi] = s;
            }
            let sum = &mut sums[s as usize];
            for a in 0..3 {
                sum[a] += n[a];
            }
            // The drawn vertex of (g, chart, group), numbered in order of first use.
            let mut v = vertex_head[gi];
            while v != NONE && vertex_tag[v as usize] != (chart, group) {
                v = vertex_next[v as usize];
            }
            if v == NONE {
                v = mesh.positions.len() as u32;
                let level = level_of(g);
                let local = g - offsets[level];
                let values =
                    d.tables.get(level).and_then(Option::as_ref).and_then(|tb| tb.get(local, chart, channels)).ok_or_else(|| {
                        ContainerError::Corrupt {
                            what: format!("band {level} attributes"),
                            detail: format!("no entry for node {local}, chart {chart}"),
                        }
                    })?;
                vertex_tag.push((chart, group));
                vertex_next.push(vertex_head[gi]);
                vertex_head[gi] = v;
                vertex_sum.push(s);
                mesh.positions.push(positions[gi]);
                app.wedge_vertex.push(v);
                let mut k = 0;
                if info.uv_sets >= 1 {
                    app.uv0.push([dequantize_uv(info, 0, values[0]), dequantize_uv(info, 1, values[1])]);
                    k = 2;
                }
                if info.uv_sets >= 2 {
                    app.uv1.push([dequantize_uv(info, 0, values[2]), dequantize_uv(info, 1, values[3])]);
                    k = 4;
                }
                if info.colors {
                    app.colors.push([0, 1, 2, 3].map(|c| (values[k + c] as f64 / 255.0) as f32));
                }
            }
            tri[i] = v;
        }
        mesh.triangles.push(tri);
        app.corner_wedges.push(tri);
        app.triangle_material.push(d.charts.chart_material[chart as usize]);
    }
    app.normals = vertex_sum
        .iter()
        .map(|&s| {
            let [x, y, z] = sums[s as usize];
            let len = (x * x + y * y + z * z).sqrt();
            if len > 0.0 && len.is_finite() { [(x / len) as f32, (y / len) as f32, (z / len) as f32] } else { [0.0, 0.0, 1.0] }
        })
        .collect();
    let shared = d.materials.to_appearance(Vec::new());
    app.materials = shared.materials;
    app.textures = shared.textures;
    app.samplers = shared.samplers;
    app.images = d.images.as_ref().map(|i| i.as_ref().clone()).unwrap_or_default();
    if app.materials.is_empty() {
        app.triangle_material.clear();
    }
    Ok((mesh, app))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::appearance::payload::Table;
    use std::collections::HashMap;

    /// Triangles, vertices as (node, chart, group), normals.
    type Drawn = (Vec<[u32; 3]>, Vec<(u32, u32, u32)>, Vec<[f32; 3]>);

    /// proto/container.md, "Drawing a cut's appearance", transcribed with hash maps: vertices
    /// (g, k, s) in order of first use, N[(g, s)] summed in triangle order.
    fn reference(d: &DecodedAppearance, positions: &[Vec3], shown: &[(u32, [u32; 3])]) -> Drawn {
        let mut ids: HashMap<(u32, u32, u32), u32> = HashMap::new();
        let mut order = Vec::new();
        let mut n_sum: HashMap<(u32, u32), [f64; 3]> = HashMap::new();
        let mut tris = Vec::new();
        for &(t, cut) in shown {
            let (k, s) = (d.charts.triangle_chart[t as usize], d.charts.triangle_group[t as usize]);
            let p = cut.map(|g| positions[g as usize].as_dvec3());
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            let n = [e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x];
            tris.push(cut.map(|g| {
                let e = n_sum.entry((g, s)).or_default();
                for a in 0..3 {
                    e[a] += n[a];
                }
                let next = ids.len() as u32;
                *ids.entry((g, k, s)).or_insert_with(|| {
                    order.push((g, k, s));
                    next
                })
            }));
        }
        let normals = order
            .iter()
            .map(|&(g, _, s)| {
                let [x, y, z] = n_sum[&(g, s)];
                let len = (x * x + y * y + z * z).sqrt();
                if len > 0.0 && len.is_finite() { [(x / len) as f32, (y / len) as f32, (z / len) as f32] } else { [0.0, 0.0, 1.0] }
            })
            .collect();
        (tris, order, normals)
    }

    #[test]
    fn flat_arrays_draw_what_the_spec_says() {
        // Two levels of 40 and 12 nodes; 4 charts, 3 groups; every (node, chart) has an entry
        // whose texture coordinates encode it, so a wrong lookup shows.
        let offsets = [0u32, 40, 52];
        let mut seed = 0x9E37_79B9u32;
        let mut rnd = |m: u32| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed % m
        };
        let positions: Vec<Vec3> = (0..52).map(|_| Vec3::new(rnd(1000) as f32, rnd(1000) as f32, rnd(1000) as f32) / 37.0).collect();
        let table = |nodes: u32| Table {
            first: (0..=nodes).map(|n| 4 * n).collect(),
            charts: (0..nodes).flat_map(|_| 0..4).collect(),
            values: (0..nodes).flat_map(|n| (0..4).flat_map(move |k| [n as i32, k])).collect(),
        };
        let triangles = 300u32;
        let d = DecodedAppearance {
            info: Some(AppearanceInfo {
                charts: 4,
                groups: 3,
                materials: 2,
                images: 0,
                uv_sets: 1,
                uv_min: [0.0; 2],
                uv_step: [1.0; 2],
                colors: false,
                normals: true,
            }),
            charts: Charts {
                triangle_chart: (0..triangles).map(|_| rnd(4)).collect(),
                chart_material: vec![0, 1, 1, 0],
                triangle_group: (0..triangles).map(|_| rnd(3)).collect(),
            },
            tables: vec![Some(table(40)), Some(table(12))],
            ..Default::default()
        };
        // Shown triangles over nodes of both levels, some degenerate (a repeated corner: zero
        // area) and some sharing nodes many times.
        let mut shown: Vec<(u32, [u32; 3])> = Vec::new();
        for t in 0..triangles {
            if rnd(5) == 0 {
                continue;
            }
            let a = rnd(52);
            let b = if rnd(10) == 0 { a } else { rnd(52) };
            shown.push((t, [a, b, rnd(52)]));
        }
        let (mesh, app) = textured_mesh(&d, &offsets, &positions, &shown).unwrap();
        let (tris, order, normals) = reference(&d, &positions, &shown);
        assert_eq!(mesh.triangles, tris);
        assert_eq!(app.normals, normals);
        let level_of = |g: u32| if g < 40 { (0, g) } else { (1, g - 40) };
        for (v, &(g, k, _)) in order.iter().enumerate() {
            assert_eq!(mesh.positions[v], positions[g as usize]);
            assert_eq!(app.uv0[v], [level_of(g).1 as f32, k as f32], "vertex {v}");
        }
        // The Materials chunk is empty here: every triangle draws with the default material.
        assert!(app.triangle_material.is_empty());
        // A cut naming a node beyond the decoded ones is an error, not a panic.
        assert!(textured_mesh(&d, &offsets, &positions, &[(0, [0, 1, 60])]).is_err());
    }
}
