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
use std::collections::HashMap;

/// Everything of a file's appearance but the images, as a decoder holds it.
#[derive(Clone, Debug, Default)]
pub struct DecodedAppearance {
    pub info: Option<AppearanceInfo>,
    pub charts: Charts,
    /// Per level; `None` below the decoder's finest level.
    pub tables: Vec<Option<Table>>,
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
    let mut vertex: HashMap<(u32, u32, u32), u32> = HashMap::with_capacity(shown.len());
    // Per vertex: its cut node and group, to look its normal up at the end.
    let mut vertex_key: Vec<u64> = Vec::with_capacity(shown.len());
    let mut normal_sum: HashMap<u64, [f64; 3]> = HashMap::with_capacity(shown.len());
    let level_of = |g: u32| offsets.partition_point(|&o| o <= g).saturating_sub(1);
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
            let next = mesh.positions.len() as u32;
            let v = *vertex.entry((g, chart, group)).or_insert(next);
            if v == next {
                let level = level_of(g);
                let local = g - offsets[level];
                let values =
                    d.tables.get(level).and_then(Option::as_ref).and_then(|tb| tb.get(local, chart, channels)).ok_or_else(|| {
                        ContainerError::Corrupt {
                            what: format!("band {level} attributes"),
                            detail: format!("no entry for node {local}, chart {chart}"),
                        }
                    })?;
                mesh.positions.push(positions.get(g as usize).copied().unwrap_or(Vec3::ZERO));
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
                vertex_key.push(((g as u64) << 32) | group as u64);
            }
            tri[i] = v;
            let s = normal_sum.entry(((g as u64) << 32) | group as u64).or_insert([0.0; 3]);
            for a in 0..3 {
                s[a] += n[a];
            }
        }
        mesh.triangles.push(tri);
        app.corner_wedges.push(tri);
        app.triangle_material.push(d.charts.chart_material[chart as usize]);
    }
    app.normals = vertex_key
        .iter()
        .map(|key| {
            let [x, y, z] = normal_sum.get(key).copied().unwrap_or([0.0; 3]);
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
