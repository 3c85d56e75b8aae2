//! `KHR_draco_mesh_compression` primitives, decoded into the accessors they stand for.
//!
//! A Draco primitive keeps its `attributes` and `indices` accessors, but they have no
//! bufferView: the extension's bufferView holds one Draco stream (Galligan et al., "Google Draco
//! 3D data compression", 2017, edgebreaker connectivity after Rossignac, "Edgebreaker:
//! connectivity compression for triangle meshes", 1999), and its `attributes` map names the
//! Draco attribute (by unique id) each accessor is decoded from. We decode every such stream
//! once, when the file is parsed, and write each accessor's elements in the accessor's own
//! component type, tightly packed. [`GltfFile`]'s accessor reader then reads them as it reads
//! a bufferView, so every caller (positions, indices, skins, UVs, normals, colours) sees the
//! same data as from an uncompressed file without knowing Draco was there.
//!
//! Morph targets are not covered by the extension: they stay plain accessors, indexed like the
//! decoded vertices. That only holds when the encoder kept the vertex order, which Draco's
//! sequential method does and edgebreaker does not (exporters such as glTF Transform switch to
//! sequential for meshes with targets), so a primitive with targets over an edgebreaker stream
//! is refused rather than read with every morph delta on the wrong vertex.
//!
//! Hostile input: the decoder ([`draco_core`], pure Rust, no `unsafe`) is given ceilings taken
//! from the accessors' declared counts, which are first checked against the [`InputLimits`], so
//! a stream that claims more points or faces fails before anything that size is allocated.

use super::*;
use draco_core::{DataType, DecodeLimits, DecoderBuffer, MeshDecoder, PointAttribute, PointIndex};
use serde::Deserialize;
use std::collections::BTreeMap;

/// The parts of the document this module reads, deserialised apart from `gltf`'s types, which
/// drop extensions they do not know.
#[derive(Deserialize)]
struct RawDocument {
    #[serde(default)]
    meshes: Vec<RawMesh>,
}

#[derive(Deserialize)]
struct RawMesh {
    #[serde(default)]
    primitives: Vec<RawPrimitive>,
}

#[derive(Deserialize)]
struct RawPrimitive {
    #[serde(default)]
    attributes: BTreeMap<String, usize>,
    indices: Option<usize>,
    mode: Option<u32>,
    #[serde(default)]
    targets: Vec<serde_json::Value>,
    extensions: Option<RawPrimitiveExtensions>,
}

#[derive(Deserialize)]
struct RawPrimitiveExtensions {
    #[serde(rename = "KHR_draco_mesh_compression")]
    draco: Option<RawDraco>,
}

#[derive(Deserialize)]
struct RawDraco {
    #[serde(rename = "bufferView")]
    buffer_view: usize,
    attributes: BTreeMap<String, u32>,
}

/// One Draco primitive of the document: where it is and what it maps.
pub(super) struct DracoPrimitive {
    mesh: usize,
    primitive: usize,
    /// The bufferView holding the Draco stream.
    pub(super) buffer_view: usize,
    /// Per glTF attribute name: its accessor and the Draco attribute's unique id.
    attributes: Vec<(String, usize, u32)>,
    indices: Option<usize>,
    mode: u32,
    has_targets: bool,
}

impl DracoPrimitive {
    fn what(&self) -> String {
        format!("mesh {} primitive {} (KHR_draco_mesh_compression)", self.mesh, self.primitive)
    }
}

/// Every Draco primitive of a document (empty when none uses the extension).
pub(super) fn draco_primitives(json_bytes: &[u8]) -> Result<Vec<DracoPrimitive>, MeshError> {
    let raw: RawDocument = serde_json::from_slice(json_bytes)
        .map_err(|e| gltf_error(format!("a mesh primitive's KHR_draco_mesh_compression extension is malformed: {e}")))?;
    let mut out = Vec::new();
    for (m, mesh) in raw.meshes.into_iter().enumerate() {
        for (p, prim) in mesh.primitives.into_iter().enumerate() {
            let Some(draco) = prim.extensions.and_then(|e| e.draco) else { continue };
            let mut attributes = Vec::with_capacity(draco.attributes.len());
            for (name, id) in draco.attributes {
                let accessor = prim.attributes.get(&name).copied().ok_or_else(|| {
                    gltf_error(format!(
                        "mesh {m} primitive {p} (KHR_draco_mesh_compression) maps attribute {name}, which the primitive does not have"
                    ))
                })?;
                attributes.push((name, accessor, id));
            }
            out.push(DracoPrimitive {
                mesh: m,
                primitive: p,
                buffer_view: draco.buffer_view,
                attributes,
                indices: prim.indices,
                mode: prim.mode.unwrap_or(4),
                has_targets: !prim.targets.is_empty(),
            });
        }
    }
    Ok(out)
}

/// What the Draco primitives of one file may still decode to (vertices and triangles summed
/// over the primitives, against the input limits).
struct DracoBudget {
    vertices: usize,
    triangles: usize,
}

/// Decodes every Draco primitive of `file` into the bytes of the accessors it stands for, keyed
/// by accessor index.
pub(super) fn decode_draco(
    file: &GltfFile,
    primitives: &[DracoPrimitive],
    limits: &InputLimits,
) -> Result<HashMap<usize, Vec<u8>>, MeshError> {
    let mut out = HashMap::new();
    let mut budget = DracoBudget { vertices: limits.max_vertices, triangles: limits.max_triangles };
    for prim in primitives {
        decode_primitive(file, prim, limits, &mut budget, &mut out)?;
    }
    Ok(out)
}

fn decode_primitive(
    file: &GltfFile,
    prim: &DracoPrimitive,
    limits: &InputLimits,
    budget: &mut DracoBudget,
    out: &mut HashMap<usize, Vec<u8>>,
) -> Result<(), MeshError> {
    let what = prim.what();
    // The extension defines TRIANGLES (and POINTS, which make no surface).
    if prim.mode != 4 {
        return Err(MeshError::Unsupported(format!("{what} has mode {}; Draco primitives are read as TRIANGLES only", prim.mode)));
    }
    let indices_at = prim.indices.ok_or_else(|| gltf_error(format!("{what} has no indices accessor")))?;
    let (_, positions_at, _) = prim
        .attributes
        .iter()
        .find(|(name, _, _)| name == "POSITION")
        .ok_or_else(|| gltf_error(format!("{what} does not map POSITION")))?;
    // The accessors say what the stream must decode to; check that against the limits first,
    // then hold the decoder to it.
    let points = file.accessor_count(*positions_at);
    let index_count = file.accessor_count(indices_at);
    if points > budget.vertices {
        return Err(limits.too_many_vertices(1, limits.max_vertices, &format!("{what} POSITION")));
    }
    if index_count / 3 > budget.triangles {
        return Err(limits.too_many_triangles(&format!("{what} indices")));
    }
    budget.vertices -= points;
    budget.triangles -= index_count / 3;
    // Most bytes the decoded attributes can honestly take: four 8-byte components per
    // attribute value, plus Draco's own per-attribute bookkeeping.
    let bytes_per_point = 32 * prim.attributes.len().max(1) as u64 + 64;

    let (stream, _) = file.view(prim.buffer_view, &what)?;
    check_order(stream, prim, &what)?;
    let draco_limits = DecodeLimits::default()
        .with_max_points(points as u64)
        .with_max_faces((index_count / 3) as u64)
        .with_max_decoded_bytes((points as u64).saturating_mul(bytes_per_point));
    let mut buffer = DecoderBuffer::new(stream).with_limits(draco_limits);
    let mut mesh = draco_core::Mesh::new();
    MeshDecoder::new()
        .decode(&mut buffer, &mut mesh)
        .map_err(|e| gltf_error(format!("{what}: the Draco stream in bufferView {} does not decode: {e}", prim.buffer_view)))?;

    if mesh.num_points() != points {
        return Err(gltf_error(format!(
            "{what}: the Draco stream decodes to {} vertices but accessor {positions_at} (POSITION) declares {points}",
            mesh.num_points()
        )));
    }
    for (name, accessor, id) in &prim.attributes {
        let attribute = mesh
            .attribute_by_unique_id(*id)
            .ok_or_else(|| gltf_error(format!("{what}: {name} maps to Draco attribute {id}, which the stream does not have")))?;
        let bytes = attribute_bytes(file, attribute, *accessor, points, &format!("{what} {name} (accessor {accessor})"))?;
        out.insert(*accessor, bytes);
    }
    let faces = mesh.faces();
    if faces.len().saturating_mul(3) != index_count {
        return Err(gltf_error(format!(
            "{what}: the Draco stream decodes to {} triangles but accessor {indices_at} (indices) declares {index_count} indices",
            faces.len()
        )));
    }
    let flat: Vec<f64> = faces.iter().flat_map(|f| f.iter().map(|p| f64::from(p.0))).collect();
    out.insert(indices_at, write_components(file, indices_at, 1, &flat, &format!("{what} indices (accessor {indices_at})"))?);
    Ok(())
}

/// Refuses morph targets over a stream whose connectivity method reorders vertices. The
/// header is "DRACO", version major and minor, encoder type, then the method (0 sequential,
/// 1 edgebreaker).
fn check_order(stream: &[u8], prim: &DracoPrimitive, what: &str) -> Result<(), MeshError> {
    const EDGEBREAKER: u8 = 1;
    if prim.has_targets && stream.starts_with(b"DRACO") && stream.get(8) == Some(&EDGEBREAKER) {
        return Err(MeshError::Unsupported(format!(
            "{what} has morph targets but its Draco stream uses edgebreaker, which reorders the vertices the targets \
             are indexed by (Draco's sequential method keeps them)"
        )));
    }
    Ok(())
}

/// The values of a decoded Draco attribute, per point, as components of `accessor`'s type.
fn attribute_bytes(file: &GltfFile, attribute: &PointAttribute, accessor: usize, points: usize, what: &str) -> Result<Vec<u8>, MeshError> {
    let dims = accessor_dims(file, accessor, what)?;
    if file.accessor_count(accessor) != points {
        return Err(gltf_error(format!(
            "{what} declares {} elements for the {points} vertices of the Draco stream",
            file.accessor_count(accessor)
        )));
    }
    if usize::from(attribute.num_components()) != dims {
        return Err(gltf_error(format!("{what}: the Draco attribute has {} components, the accessor {dims}", attribute.num_components())));
    }
    let data_type = attribute.data_type();
    let size = data_type.byte_length();
    if size == 0 || data_type == DataType::Bool {
        return Err(gltf_error(format!("{what}: the Draco attribute has data type {data_type:?}")));
    }
    let stride = usize::try_from(attribute.byte_stride()).unwrap_or(0);
    let data = attribute.buffer().data();
    let mut values = Vec::with_capacity(points * dims);
    for point in 0..points {
        let value = attribute.mapped_index(PointIndex(point as u32)).0 as usize;
        let at = value.checked_mul(stride);
        for c in 0..dims {
            let bytes = at.and_then(|at| at.checked_add(c * size)).and_then(|from| data.get(from..from + size));
            let bytes = bytes.ok_or_else(|| gltf_error(format!("{what}: the Draco attribute has no value for vertex {point}")))?;
            values.push(scalar(data_type, bytes));
        }
    }
    write_components(file, accessor, dims, &values, what)
}

fn accessor_dims(file: &GltfFile, accessor: usize, what: &str) -> Result<usize, MeshError> {
    let acc = file.root.accessors.get(accessor).ok_or_else(|| gltf_error(format!("{what} does not exist")))?;
    match acc.type_ {
        Checked::Valid(Type::Scalar) => Ok(1),
        Checked::Valid(Type::Vec2) => Ok(2),
        Checked::Valid(Type::Vec3) => Ok(3),
        Checked::Valid(Type::Vec4) => Ok(4),
        _ => Err(gltf_error(format!("{what}: a Draco-decoded accessor must be SCALAR or VEC2-4"))),
    }
}

/// One decoded component, widened to `f64` (exact for every Draco type up to 32 bits).
fn scalar(data_type: DataType, b: &[u8]) -> f64 {
    let word = |n: usize| -> u64 { b.iter().take(n).rev().fold(0u64, |acc, &x| (acc << 8) | u64::from(x)) };
    match data_type {
        DataType::Int8 => f64::from(word(1) as u8 as i8),
        DataType::Uint8 => word(1) as f64,
        DataType::Int16 => f64::from(word(2) as u16 as i16),
        DataType::Uint16 => word(2) as f64,
        DataType::Int32 => f64::from(word(4) as u32 as i32),
        DataType::Uint32 => word(4) as f64,
        DataType::Int64 => word(8) as i64 as f64,
        DataType::Uint64 => word(8) as f64,
        DataType::Float32 => f64::from(f32::from_bits(word(4) as u32)),
        DataType::Float64 => f64::from_bits(word(8)),
        _ => 0.0,
    }
}

/// `values` (`dims` per element) written as `accessor`'s component type, little-endian and
/// tightly packed: what a bufferView would hold. An integer accessor only takes integers in
/// its range (Draco keeps normalised attributes as integers, so nothing is rounded here).
fn write_components(file: &GltfFile, accessor: usize, dims: usize, values: &[f64], what: &str) -> Result<Vec<u8>, MeshError> {
    if accessor_dims(file, accessor, what)? != dims {
        return Err(gltf_error(format!("{what} does not have {dims} components")));
    }
    let acc = file.root.accessors.get(accessor).ok_or_else(|| gltf_error(format!("{what} does not exist")))?;
    let ct = match acc.component_type {
        Checked::Valid(GenericComponentType(c)) => c,
        Checked::Invalid => return Err(gltf_error(format!("{what}: unknown component type"))),
    };
    let (low, high) = match ct {
        ComponentType::F32 => (f64::NEG_INFINITY, f64::INFINITY),
        ComponentType::I8 => (-128.0, 127.0),
        ComponentType::U8 => (0.0, 255.0),
        ComponentType::I16 => (-32768.0, 32767.0),
        ComponentType::U16 => (0.0, 65535.0),
        ComponentType::U32 => (0.0, f64::from(u32::MAX)),
    };
    let mut out = Vec::with_capacity(values.len() * component_size(ct));
    for (i, &v) in values.iter().enumerate() {
        if ct != ComponentType::F32 && !(v.fract() == 0.0 && (low..=high).contains(&v)) {
            return Err(gltf_error(format!("{what}: decoded value {v} (element {}) does not fit its {ct:?} accessor", i / dims)));
        }
        match ct {
            ComponentType::F32 => out.extend((v as f32).to_le_bytes()),
            ComponentType::I8 => out.push(v as i8 as u8),
            ComponentType::U8 => out.push(v as u8),
            ComponentType::I16 => out.extend((v as i16).to_le_bytes()),
            ComponentType::U16 => out.extend((v as u16).to_le_bytes()),
            ComponentType::U32 => out.extend((v as u32).to_le_bytes()),
        }
    }
    Ok(out)
}
