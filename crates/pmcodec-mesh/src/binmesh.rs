//! The compact binary mesh of proto/http.md (`format=bin` LOD responses): little-endian
//! `"PMCM"`, u32 version, u32 vertex count V, u32 triangle count T, V x 3 f32 positions,
//! T x 3 indices, u16 when V <= 65,536 and u32 otherwise (version 2; version 1, still read, had
//! u32 indices always). Written by the server, read by clients and tests.
//!
//! Version 3 (opt-in, `format=bin&layout=3`) adds the appearance of the cut: per vertex
//! normals, texture coordinates and 8-bit colours, and the triangles grouped by material (one
//! run per material, as a renderer draws them: three.js's `geometry.addGroup`, one glTF
//! primitive each). See [`encode_bin_v3`] and proto/http.md.

use crate::{Appearance, TriMesh};

/// Magic of the compact binary mesh.
pub const MAGIC: &[u8; 4] = b"PMCM";
/// Version of the layout written.
pub const VERSION: u32 = 2;
/// Bytes before the positions: magic, version, vertex count, triangle count.
pub const HEADER_LEN: usize = 16;
/// Meshes with at most this many vertices get 16-bit indices (version 2).
pub const MAX_U16_VERTICES: usize = 1 << 16;

/// What is wrong with a compact binary mesh.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("binary mesh: {0}")]
pub struct BinMeshError(pub &'static str);

/// The opt-in layout with appearance.
pub const VERSION_APPEARANCE: u32 = 3;
/// Version 3's attribute flags: which per-vertex arrays follow the positions, in this order.
pub const HAS_NORMALS: u32 = 1;
/// Version 3 flag: per-vertex texture coordinates 0 follow (2 x f32 each).
pub const HAS_UV0: u32 = 2;
/// Version 3 flag: per-vertex texture coordinates 1 follow (2 x f32 each).
pub const HAS_UV1: u32 = 4;
/// Version 3 flag: per-vertex RGBA colours follow (4 x u8 each).
pub const HAS_COLORS: u32 = 8;
/// Bytes before version 3's material runs: the version 2 header, the flags and the run count.
pub const HEADER_LEN_V3: usize = 24;

/// One run of version 3: triangles `first..first + count` (in the body's order) use `material`,
/// an index into the asset's `appearance.materials` (proto/http.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaterialRun {
    /// Index into the asset's materials.
    pub material: u32,
    /// First triangle of the run.
    pub first: u32,
    /// Triangles in the run.
    pub count: u32,
}

/// Bytes per index for a mesh of `vertices` vertices in layout `version`.
fn index_bytes(version: u32, vertices: usize) -> usize {
    if version >= 2 && vertices <= MAX_U16_VERTICES { 2 } else { 4 }
}

/// Writes `mesh` in the version 2 layout (16-bit indices when it has at most
/// [`MAX_U16_VERTICES`] vertices). Infallible: the layout holds any mesh whose counts fit a u32.
pub fn encode_bin(mesh: &TriMesh) -> Vec<u8> {
    let (v, t) = (mesh.positions.len(), mesh.triangles.len());
    let width = index_bytes(VERSION, v);
    let mut b = vec![0u8; HEADER_LEN + v * 12 + t * 3 * width];
    let (header, body) = b.split_at_mut(HEADER_LEN);
    header[..4].copy_from_slice(MAGIC);
    header[4..8].copy_from_slice(&VERSION.to_le_bytes());
    header[8..12].copy_from_slice(&(v as u32).to_le_bytes());
    header[12..16].copy_from_slice(&(t as u32).to_le_bytes());
    // Sized slots filled in place (no per-value capacity checks, so the loops vectorize: an
    // answer of 100 KB is written in a few microseconds).
    let (positions, indices) = body.split_at_mut(v * 12);
    for (out, p) in positions.chunks_exact_mut(12).zip(&mesh.positions) {
        out[0..4].copy_from_slice(&p.x.to_le_bytes());
        out[4..8].copy_from_slice(&p.y.to_le_bytes());
        out[8..12].copy_from_slice(&p.z.to_le_bytes());
    }
    if width == 2 {
        // Indices are below V <= 65,536, so they fit 16 bits.
        for (out, t) in indices.chunks_exact_mut(6).zip(&mesh.triangles) {
            out[0..2].copy_from_slice(&(t[0] as u16).to_le_bytes());
            out[2..4].copy_from_slice(&(t[1] as u16).to_le_bytes());
            out[4..6].copy_from_slice(&(t[2] as u16).to_le_bytes());
        }
    } else {
        for (out, &i) in indices.chunks_exact_mut(4).zip(mesh.triangles.iter().flatten()) {
            out.copy_from_slice(&i.to_le_bytes());
        }
    }
    b
}

/// Writes version 3: `mesh` with `app`'s per-vertex attributes. `app` is per vertex, as a
/// decoded cut's appearance is (`wedge_vertex[v] == v`, `corner_wedges` empty or equal to the
/// triangles); every per-wedge array it has must have one entry per vertex, and
/// `triangle_material` none or one per triangle. Triangles are written grouped by material
/// (ascending, in mesh order within a material) so a renderer draws each run in one call.
/// Colours are written as 8-bit RGBA (what the container stores, so a decoded cut's colours
/// round-trip exactly).
pub fn encode_bin_v3(mesh: &TriMesh, app: &Appearance) -> Result<Vec<u8>, BinMeshError> {
    let (v, t) = (mesh.positions.len(), mesh.triangles.len());
    let per_vertex = |n: usize| n == 0 || n == v;
    if !(per_vertex(app.normals.len()) && per_vertex(app.uv0.len()) && per_vertex(app.uv1.len()) && per_vertex(app.colors.len())) {
        return Err(BinMeshError("an attribute array does not have one entry per vertex"));
    }
    if !app.corner_wedges.is_empty() && app.corner_wedges != mesh.triangles {
        return Err(BinMeshError("attributes are not per vertex (corners name other wedges)"));
    }
    if !(app.triangle_material.is_empty() || app.triangle_material.len() == t) {
        return Err(BinMeshError("triangle materials do not match the triangles"));
    }
    if v > u32::MAX as usize || t > u32::MAX as usize {
        return Err(BinMeshError("counts overflow"));
    }
    // Triangle order: by material, stable (a counting sort over the materials used).
    let (order, runs): (Vec<u32>, Vec<MaterialRun>) = if app.triangle_material.is_empty() {
        let runs =
            if app.materials.is_empty() || t == 0 { Vec::new() } else { vec![MaterialRun { material: 0, first: 0, count: t as u32 }] };
        ((0..t as u32).collect(), runs)
    } else {
        let mut order: Vec<u32> = (0..t as u32).collect();
        order.sort_by_key(|&i| app.triangle_material[i as usize]);
        let mut runs: Vec<MaterialRun> = Vec::new();
        for (k, &i) in order.iter().enumerate() {
            let m = app.triangle_material[i as usize];
            match runs.last_mut() {
                Some(r) if r.material == m => r.count += 1,
                _ => runs.push(MaterialRun { material: m, first: k as u32, count: 1 }),
            }
        }
        (order, runs)
    };
    let flags = [
        (HAS_NORMALS, !app.normals.is_empty()),
        (HAS_UV0, !app.uv0.is_empty()),
        (HAS_UV1, !app.uv1.is_empty()),
        (HAS_COLORS, !app.colors.is_empty()),
    ]
    .iter()
    .filter(|f| f.1)
    .fold(0, |a, f| a | f.0);
    let width = index_bytes(VERSION_APPEARANCE, v);
    let mut b = Vec::with_capacity(v3_len(v, t, runs.len(), flags, width).unwrap_or(0));
    b.extend_from_slice(MAGIC);
    for w in [VERSION_APPEARANCE, v as u32, t as u32, flags, runs.len() as u32] {
        b.extend_from_slice(&w.to_le_bytes());
    }
    for r in &runs {
        for w in [r.material, r.first, r.count] {
            b.extend_from_slice(&w.to_le_bytes());
        }
    }
    let floats = |b: &mut Vec<u8>, xs: &mut dyn Iterator<Item = f32>| xs.for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
    floats(&mut b, &mut mesh.positions.iter().flat_map(|p| p.to_array()));
    floats(&mut b, &mut app.normals.iter().flatten().copied());
    floats(&mut b, &mut app.uv0.iter().flatten().copied());
    floats(&mut b, &mut app.uv1.iter().flatten().copied());
    // NaN clamps to 0; linear [0, 1] to the nearest of 256 levels.
    b.extend(app.colors.iter().flatten().map(|&c| (c.clamp(0.0, 1.0) * 255.0).round() as u8));
    for &i in &order {
        for &x in &mesh.triangles[i as usize] {
            if width == 2 {
                b.extend_from_slice(&(x as u16).to_le_bytes());
            } else {
                b.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    Ok(b)
}

/// Version 3's exact length, `None` on overflow.
fn v3_len(v: usize, t: usize, runs: usize, flags: u32, width: usize) -> Option<usize> {
    let mut per_vertex = 12;
    for (f, n) in [(HAS_NORMALS, 12), (HAS_UV0, 8), (HAS_UV1, 8), (HAS_COLORS, 4)] {
        if flags & f != 0 {
            per_vertex += n;
        }
    }
    HEADER_LEN_V3.checked_add(runs.checked_mul(12)?)?.checked_add(v.checked_mul(per_vertex)?)?.checked_add(t.checked_mul(3 * width)?)
}

/// Reads exactly one well-formed mesh (version 1, 2 or 3; version 3's appearance is dropped,
/// see [`decode_bin_appearance`]); counts are checked against the length before anything is
/// allocated, so hostile counts cannot overflow or allocate without bound.
pub fn decode_bin(b: &[u8]) -> Result<TriMesh, BinMeshError> {
    decode_bin_appearance(b).map(|(mesh, _)| mesh)
}

/// Reads a mesh of any version with its appearance: for version 3 per vertex (`wedge_vertex`
/// the identity, `corner_wedges` the triangles) with `triangle_material` from the material runs;
/// for versions 1 and 2 an empty appearance.
pub fn decode_bin_appearance(b: &[u8]) -> Result<(TriMesh, Appearance), BinMeshError> {
    let word = |i: usize| b.get(i..i + 4).and_then(|s| s.try_into().ok()).map(u32::from_le_bytes);
    if b.get(..4) != Some(&MAGIC[..]) {
        return Err(BinMeshError("bad magic"));
    }
    let version = match word(4) {
        Some(x @ (1..=3)) => x,
        _ => return Err(BinMeshError("unknown version")),
    };
    let (v, t) = match (word(8), word(12)) {
        (Some(v), Some(t)) => (v as usize, t as usize),
        _ => return Err(BinMeshError("short header")),
    };
    let width = index_bytes(version, v);
    let (flags, run_count) = if version >= VERSION_APPEARANCE {
        match (word(16), word(20)) {
            (Some(f), Some(r)) => (f, r as usize),
            _ => return Err(BinMeshError("short header")),
        }
    } else {
        (0, 0)
    };
    if flags & !(HAS_NORMALS | HAS_UV0 | HAS_UV1 | HAS_COLORS) != 0 {
        return Err(BinMeshError("unknown attribute flags"));
    }
    let (head, end) = if version >= VERSION_APPEARANCE {
        (HEADER_LEN_V3 + 12 * run_count, v3_len(v, t, run_count, flags, width))
    } else {
        let end =
            v.checked_mul(12).and_then(|n| n.checked_add(HEADER_LEN)).zip(t.checked_mul(3 * width)).and_then(|(p, n)| p.checked_add(n));
        (HEADER_LEN, end)
    };
    let Some(end) = end else { return Err(BinMeshError("counts overflow")) };
    if b.len() != end {
        return Err(BinMeshError("length does not match its counts"));
    }
    // In bounds from here on: the length was checked against the counts above.
    let f = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    let mut at = head;
    let mut floats = |n: usize| {
        let o = at;
        at += 4 * n * v;
        (0..v).map(move |k| o + 4 * n * k)
    };
    let positions = floats(3).map(|o| glam::Vec3::new(f(o), f(o + 4), f(o + 8))).collect();
    let mut app = Appearance::default();
    if flags & HAS_NORMALS != 0 {
        app.normals = floats(3).map(|o| [f(o), f(o + 4), f(o + 8)]).collect();
    }
    if flags & HAS_UV0 != 0 {
        app.uv0 = floats(2).map(|o| [f(o), f(o + 4)]).collect();
    }
    if flags & HAS_UV1 != 0 {
        app.uv1 = floats(2).map(|o| [f(o), f(o + 4)]).collect();
    }
    if flags & HAS_COLORS != 0 {
        let o = at;
        at += 4 * v;
        // As the container dequantizes its 8-bit colours (binary64, rounded once).
        app.colors = (0..v).map(|k| [0, 1, 2, 3].map(|c| (b[o + 4 * k + c] as f64 / 255.0) as f32)).collect();
    }
    let index = |i: usize| {
        if width == 2 { u16::from_le_bytes([b[i], b[i + 1]]) as u32 } else { u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]) }
    };
    let triangles: Vec<[u32; 3]> = (0..t).map(|k| at + 3 * width * k).map(|o| [index(o), index(o + width), index(o + 2 * width)]).collect();
    if triangles.iter().flatten().any(|&i| i as usize >= v) {
        return Err(BinMeshError("index out of range"));
    }
    if run_count > 0 {
        let mut next = 0usize;
        app.triangle_material.reserve(t);
        for r in 0..run_count {
            let o = HEADER_LEN_V3 + 12 * r;
            let (material, first, count) = (word(o), word(o + 4), word(o + 8));
            let (Some(material), Some(first), Some(count)) = (material, first, count) else {
                return Err(BinMeshError("short material runs"));
            };
            if first as usize != next || next + count as usize > t {
                return Err(BinMeshError("material runs do not cover the triangles in order"));
            }
            next += count as usize;
            app.triangle_material.extend(std::iter::repeat_n(material, count as usize));
        }
        if next != t {
            return Err(BinMeshError("material runs do not cover the triangles in order"));
        }
    }
    if version >= VERSION_APPEARANCE {
        app.wedge_vertex = (0..v as u32).collect();
        app.corner_wedges = triangles.clone();
    }
    Ok((TriMesh { positions, triangles }, app))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_hostile_headers() {
        let mesh = TriMesh { positions: vec![glam::Vec3::X, glam::Vec3::Y, glam::Vec3::Z], triangles: vec![[0, 1, 2]] };
        let b = encode_bin(&mesh);
        assert_eq!(decode_bin(&b), Ok(mesh));
        let mut huge = b.clone();
        huge[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
        huge[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode_bin(&huge).is_err());
        assert_eq!(decode_bin(&b[..b.len() - 1]), Err(BinMeshError("length does not match its counts")));
        assert_eq!(decode_bin(b"PMC"), Err(BinMeshError("bad magic")));
    }

    /// A fan of `n` triangles over `n + 2` vertices.
    fn fan(n: u32) -> TriMesh {
        TriMesh {
            positions: (0..n + 2).map(|i| glam::Vec3::new(i as f32, (i * 7 % 13) as f32, -(i as f32))).collect(),
            triangles: (0..n).map(|i| [0, i + 1, i + 2]).collect(),
        }
    }

    #[test]
    fn sixteen_bit_indices_up_to_65536_vertices() {
        for (n, width) in [(1u32, 2usize), (65_534, 2), (65_535, 4)] {
            let mesh = fan(n);
            let b = encode_bin(&mesh);
            assert_eq!(b.len(), HEADER_LEN + 12 * mesh.positions.len() + 3 * width * mesh.triangles.len(), "{n} triangles");
            assert_eq!(decode_bin(&b), Ok(mesh));
        }
    }

    #[test]
    fn reads_version_1() {
        let mesh = fan(3);
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        for w in [1u32, 5, 3] {
            b.extend_from_slice(&w.to_le_bytes());
        }
        b.extend(mesh.positions.iter().flat_map(|p| p.to_array()).flat_map(f32::to_le_bytes));
        b.extend(mesh.triangles.iter().flatten().flat_map(|i| i.to_le_bytes()));
        assert_eq!(decode_bin(&b), Ok(mesh));
        b[4] = 4;
        assert_eq!(decode_bin(&b), Err(BinMeshError("unknown version")));
    }

    #[test]
    fn index_out_of_range_is_an_error() {
        let mut b = encode_bin(&fan(2));
        let last = b.len() - 2;
        b[last..].copy_from_slice(&9u16.to_le_bytes());
        assert_eq!(decode_bin(&b), Err(BinMeshError("index out of range")));
    }

    /// A fan with per-vertex appearance: normals, both UV sets, colours on the 8-bit grid, and
    /// materials interleaved so the writer must regroup them.
    fn textured_fan(n: u32, materials: u32) -> (TriMesh, Appearance) {
        let mesh = fan(n);
        let v = mesh.positions.len();
        let app = Appearance {
            corner_wedges: mesh.triangles.clone(),
            wedge_vertex: (0..v as u32).collect(),
            uv0: (0..v).map(|i| [i as f32 / 7.0, 1.0 - i as f32 / 11.0]).collect(),
            uv1: (0..v).map(|i| [(i % 5) as f32, -(i as f32)]).collect(),
            normals: (0..v).map(|i| [0.0, (i as f32).sin(), (i as f32).cos()]).collect(),
            colors: (0..v).map(|i| [0, 1, 2, 3].map(|c| ((i * 37 + c * 91) % 256) as f32 / 255.0)).collect(),
            triangle_material: (0..n).map(|t| (t * 7 + 3) % materials.max(1)).collect(),
            materials: vec![crate::appearance::Material::default(); materials as usize],
            ..Default::default()
        };
        (mesh, app)
    }

    #[test]
    fn version_3_round_trips_attributes_grouped_by_material() {
        for (n, materials) in [(1u32, 1u32), (40, 3), (70_000, 5)] {
            let (mesh, app) = textured_fan(n, materials);
            let b = encode_bin_v3(&mesh, &app).unwrap();
            assert_eq!(&b[4..8], &3u32.to_le_bytes());
            let (got, got_app) = decode_bin_appearance(&b).unwrap();
            assert_eq!(got.positions, mesh.positions);
            assert_eq!(
                (got_app.normals.clone(), got_app.uv0.clone(), got_app.uv1.clone()),
                (app.normals.clone(), app.uv0.clone(), app.uv1.clone())
            );
            // Colours on the 8-bit grid come back bit for bit.
            assert_eq!(got_app.colors, app.colors);
            // Same triangles with the same materials, now sorted by material (stable).
            let mut want: Vec<(u32, [u32; 3])> = app.triangle_material.iter().copied().zip(mesh.triangles.iter().copied()).collect();
            want.sort_by_key(|x| x.0);
            let have: Vec<(u32, [u32; 3])> = got_app.triangle_material.iter().copied().zip(got.triangles.iter().copied()).collect();
            assert_eq!(have, want, "{n} triangles");
            assert_eq!(got_app.corner_wedges, got.triangles);
            // A version 3 body is still a mesh to an older-style reader.
            assert_eq!(decode_bin(&b).unwrap().triangles, got.triangles);
        }
    }

    #[test]
    fn version_3_without_attributes_or_materials() {
        let mesh = fan(5);
        let b = encode_bin_v3(&mesh, &Appearance::default()).unwrap();
        assert_eq!(b.len(), HEADER_LEN_V3 + 12 * mesh.positions.len() + 6 * mesh.triangles.len());
        let (got, app) = decode_bin_appearance(&b).unwrap();
        assert_eq!(got, mesh);
        assert!(app.triangle_material.is_empty() && app.uv0.is_empty() && app.normals.is_empty());
        // Versions 1 and 2 read with an empty appearance.
        assert_eq!(decode_bin_appearance(&encode_bin(&mesh)).unwrap(), (mesh, Appearance::default()));
    }

    #[test]
    fn version_3_rejects_bad_input() {
        let (mesh, app) = textured_fan(6, 2);
        let mut short = app.clone();
        short.uv0.pop();
        assert!(encode_bin_v3(&mesh, &short).is_err());
        let mut wedged = app.clone();
        wedged.corner_wedges[0] = [1, 2, 3];
        assert!(encode_bin_v3(&mesh, &wedged).is_err());
        let b = encode_bin_v3(&mesh, &app).unwrap();
        let mut flags = b.clone();
        flags[16] |= 0x40;
        assert_eq!(decode_bin_appearance(&flags), Err(BinMeshError("unknown attribute flags")));
        // A run that does not start where the last one ended.
        let mut runs = b.clone();
        runs[HEADER_LEN_V3 + 4..HEADER_LEN_V3 + 8].copy_from_slice(&1u32.to_le_bytes());
        assert_eq!(decode_bin_appearance(&runs), Err(BinMeshError("material runs do not cover the triangles in order")));
        let mut count = b.clone();
        count[HEADER_LEN_V3 + 8..HEADER_LEN_V3 + 12].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode_bin_appearance(&count).is_err());
        let mut huge = b.clone();
        huge[20..24].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode_bin_appearance(&huge).is_err());
        for cut in [1, 13, b.len() - 1] {
            assert!(decode_bin_appearance(&b[..cut]).is_err(), "cut at {cut}");
        }
    }
}
