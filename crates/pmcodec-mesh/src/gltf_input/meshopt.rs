//! `EXT_meshopt_compression` (and `KHR_meshopt_compression`) bufferViews, decoded into the
//! bytes the view stands for.
//!
//! A compressed view keeps its `buffer`, `byteLength` and `byteStride`, but its bytes are
//! produced by decoding the extension's own range of another buffer with meshoptimizer's
//! codecs (Kapoulkine, meshoptimizer: vertex and index buffer compression, 2019-2024): the
//! vertex codec for ATTRIBUTES, the index codec for TRIANGLES, the index sequence codec for
//! INDICES, followed by an optional filter (octahedral normals, quaternions, exponent/mantissa
//! floats, and for the KHR version YCoCg colours). The view's own buffer is then usually a
//! *fallback* buffer with no data at all, which is never loaded.
//!
//! We decode every compressed view once, when the file is parsed, with the decoders of the
//! `meshopt` crate (meshoptimizer's C decoders, documented safe on untrusted input). Accessors,
//! sparse accessors and Draco streams then read the decoded bytes as they read any view.
//!
//! Hostile input: the decoded size is `count * byteStride`; it must equal the view's
//! `byteLength` and stay within [`MAX_DECODED_BYTES`] summed over the file, both checked before
//! anything is allocated. Truncated or corrupt data fails in the decoder, which says so.

use super::*;
use serde::Deserialize;

/// Most bytes the compressed views of one file may decode to, summed (1 GiB: far above any
/// real asset, far below what a few bytes of hostile JSON could otherwise ask for).
pub(super) const MAX_DECODED_BYTES: usize = 1 << 30;

#[derive(Deserialize)]
struct RawDocument {
    #[serde(default, rename = "bufferViews")]
    buffer_views: Vec<RawView>,
}

#[derive(Deserialize)]
struct RawView {
    extensions: Option<RawViewExtensions>,
}

#[derive(Deserialize)]
struct RawViewExtensions {
    #[serde(rename = "EXT_meshopt_compression")]
    ext: Option<MeshoptView>,
    #[serde(rename = "KHR_meshopt_compression")]
    khr: Option<MeshoptView>,
}

/// A compressed view: where its compressed bytes are and how to decode them.
#[derive(Clone, Debug, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct MeshoptView {
    pub(super) buffer: usize,
    #[serde(default)]
    byte_offset: u64,
    byte_length: u64,
    byte_stride: u64,
    count: u64,
    mode: String,
    #[serde(default)]
    filter: Option<String>,
    /// Set for the KHR version, which also allows the COLOR filter.
    #[serde(skip)]
    khr: bool,
}

/// Per bufferView of the document, its compression (`None` for a plain view).
pub(super) fn meshopt_views(json_bytes: &[u8]) -> Result<Vec<Option<MeshoptView>>, MeshError> {
    let raw: RawDocument = serde_json::from_slice(json_bytes)
        .map_err(|e| gltf_error(format!("a bufferView's EXT_meshopt_compression extension is malformed: {e}")))?;
    Ok(raw
        .buffer_views
        .into_iter()
        .map(|v| {
            v.extensions.and_then(|e| match (e.khr, e.ext) {
                (Some(khr), _) => Some(MeshoptView { khr: true, ..khr }),
                (None, ext) => ext,
            })
        })
        .collect())
}

/// Decodes every compressed view of `file`, keyed by bufferView index.
pub(super) fn decode_meshopt(file: &GltfFile, views: &[Option<MeshoptView>]) -> Result<HashMap<usize, Vec<u8>>, MeshError> {
    let mut out = HashMap::new();
    let mut budget = MAX_DECODED_BYTES;
    for (index, view) in views.iter().enumerate() {
        let Some(view) = view else { continue };
        let what = format!("bufferView {index} ({})", if view.khr { "KHR_meshopt_compression" } else { "EXT_meshopt_compression" });
        let decoded = decode_view(file, index, view, &mut budget, &what)?;
        out.insert(index, decoded);
    }
    Ok(out)
}

fn decode_view(file: &GltfFile, index: usize, view: &MeshoptView, budget: &mut usize, what: &str) -> Result<Vec<u8>, MeshError> {
    let stride = usize::try_from(view.byte_stride).unwrap_or(usize::MAX);
    let count = usize::try_from(view.count).unwrap_or(usize::MAX);
    let size = count.checked_mul(stride).filter(|&s| s <= *budget).ok_or_else(|| MeshError::TooLarge {
        what: format!("{what}: {count} elements of {stride} bytes, past {MAX_DECODED_BYTES} decoded bytes for the file"),
    })?;
    *budget -= size;
    let declared = file.root.buffer_views.get(index).map_or(0, |v| v.byte_length.0);
    if declared != size as u64 {
        return Err(gltf_error(format!("{what}: {count} elements of {stride} bytes do not fill its byteLength {declared}")));
    }
    let source = compressed_bytes(file, view, what)?;
    let filter = view.filter.as_deref().unwrap_or("NONE");
    let mut data = match view.mode.as_str() {
        "ATTRIBUTES" => {
            if stride == 0 || stride > 256 || !stride.is_multiple_of(4) {
                return Err(gltf_error(format!("{what}: byteStride {stride} is not a multiple of 4 up to 256")));
            }
            decode_vertices(source, count, stride)
        }
        "TRIANGLES" | "INDICES" => {
            if filter != "NONE" {
                return Err(gltf_error(format!("{what}: mode {} takes no filter, but has {filter}", view.mode)));
            }
            if view.mode == "TRIANGLES" && !count.is_multiple_of(3) {
                return Err(gltf_error(format!("{what}: {count} indices is not a whole number of triangles")));
            }
            decode_indices(source, count, stride, view.mode == "TRIANGLES")
                .ok_or_else(|| gltf_error(format!("{what}: byteStride {stride} for indices (2 or 4 expected)")))?
        }
        other => return Err(gltf_error(format!("{what}: unknown mode {other:?}"))),
    }
    .map_err(|e| gltf_error(format!("{what}: the compressed data does not decode ({e}): truncated or corrupt")))?;
    apply_filter(&mut data, filter, stride, view.khr).map_err(|m| gltf_error(format!("{what}: {m}")))?;
    Ok(data)
}

/// The extension's range of its buffer.
fn compressed_bytes<'a>(file: &'a GltfFile, view: &MeshoptView, what: &str) -> Result<&'a [u8], MeshError> {
    let buffer = view.buffer;
    let data = file
        .buffers
        .get(buffer)
        .and_then(Option::as_deref)
        .ok_or_else(|| gltf_error(format!("{what}: its compressed data is in buffer {buffer}, which does not exist")))?;
    let start = usize::try_from(view.byte_offset).ok();
    let end = start.zip(usize::try_from(view.byte_length).ok()).and_then(|(s, l)| s.checked_add(l));
    start.zip(end).and_then(|(s, e)| data.get(s..e)).ok_or_else(|| {
        gltf_error(format!(
            "{what}: compressed bytes {}..+{} lie outside buffer {buffer} ({} bytes)",
            view.byte_offset,
            view.byte_length,
            data.len()
        ))
    })
}

/// One vertex of `N` bytes: the element type the vertex codec decodes into.
#[derive(Clone, Copy)]
struct Vertex<const N: usize>([u8; N]);

impl<const N: usize> Default for Vertex<N> {
    fn default() -> Self {
        Vertex([0; N])
    }
}

fn decode_sized<const N: usize>(source: &[u8], count: usize) -> ::meshopt::Result<Vec<u8>> {
    let vertices: Vec<Vertex<N>> = ::meshopt::decode_vertex_buffer(source, count)?;
    Ok(vertices.iter().flat_map(|v| v.0).collect())
}

/// The vertex codec decodes whole vertices, so its element size is a type: one instance per
/// stride glTF allows (multiples of 4 up to 256).
fn decode_vertices(source: &[u8], count: usize, stride: usize) -> ::meshopt::Result<Vec<u8>> {
    macro_rules! by_stride {
        ($($n:literal)*) => {
            match stride {
                $($n => decode_sized::<$n>(source, count),)*
                _ => Err(::meshopt::Error::Native(-2)),
            }
        };
    }
    by_stride!(4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64 68 72 76 80 84 88 92 96 100 104 108 112 116 120 124 128
        132 136 140 144 148 152 156 160 164 168 172 176 180 184 188 192 196 200 204 208 212 216 220 224 228 232 236 240
        244 248 252 256)
}

/// Index buffers (TRIANGLES) and index sequences (INDICES) of 2- or 4-byte indices; `None` for
/// another stride.
fn decode_indices(source: &[u8], count: usize, stride: usize, triangles: bool) -> Option<::meshopt::Result<Vec<u8>>> {
    Some(match (stride, triangles) {
        (2, true) => ::meshopt::decode_index_buffer::<u16>(source, count).map(|v| v.iter().flat_map(|i| i.to_le_bytes()).collect()),
        (4, true) => ::meshopt::decode_index_buffer::<u32>(source, count).map(|v| v.iter().flat_map(|i| i.to_le_bytes()).collect()),
        (2, false) => ::meshopt::decode_index_sequence::<u16>(source, count).map(|v| v.iter().flat_map(|i| i.to_le_bytes()).collect()),
        (4, false) => ::meshopt::decode_index_sequence::<u32>(source, count).map(|v| v.iter().flat_map(|i| i.to_le_bytes()).collect()),
        _ => return None,
    })
}

/// Undoes the filter in place. The filters work on whole elements of fixed shapes, so the
/// bytes are regrouped into those shapes and back.
fn apply_filter(data: &mut [u8], filter: &str, stride: usize, khr: bool) -> Result<(), String> {
    match (filter, stride) {
        ("NONE", _) => {}
        ("OCTAHEDRAL", 4) => {
            let mut v: Vec<[i8; 4]> = data.chunks_exact(4).map(|c| [c[0] as i8, c[1] as i8, c[2] as i8, c[3] as i8]).collect();
            ::meshopt::decode_filter_oct(&mut v);
            copy_back(data, v.iter().flat_map(|e| e.map(|x| x as u8)));
        }
        ("OCTAHEDRAL", 8) => {
            let mut v = to_i16x4(data);
            ::meshopt::decode_filter_oct(&mut v);
            copy_back(data, v.iter().flat_map(|e| e.iter().flat_map(|x| x.to_le_bytes())));
        }
        ("QUATERNION", 8) => {
            let mut v = to_i16x4(data);
            ::meshopt::decode_filter_quat(&mut v);
            copy_back(data, v.iter().flat_map(|e| e.iter().flat_map(|x| x.to_le_bytes())));
        }
        // Every 32-bit word is decoded on its own, so the element size does not matter.
        ("EXPONENTIAL", s) if s.is_multiple_of(4) => {
            let mut v: Vec<[u32; 1]> = data.chunks_exact(4).map(|c| [u32::from_le_bytes([c[0], c[1], c[2], c[3]])]).collect();
            ::meshopt::decode_filter_exp(&mut v);
            copy_back(data, v.iter().flat_map(|e| e[0].to_le_bytes()));
        }
        ("COLOR", 4) if khr => {
            let mut v: Vec<[u8; 4]> = data.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
            ::meshopt::decode_filter_color(&mut v);
            copy_back(data, v.iter().flat_map(|e| *e));
        }
        ("COLOR", 8) if khr => {
            let mut v: Vec<[u16; 4]> =
                data.chunks_exact(8).map(|c| std::array::from_fn(|i| u16::from_le_bytes([c[2 * i], c[2 * i + 1]]))).collect();
            ::meshopt::decode_filter_color(&mut v);
            copy_back(data, v.iter().flat_map(|e| e.iter().flat_map(|x| x.to_le_bytes())));
        }
        (filter, stride) => return Err(format!("filter {filter} does not apply to {stride}-byte elements")),
    }
    Ok(())
}

fn to_i16x4(data: &[u8]) -> Vec<[i16; 4]> {
    data.chunks_exact(8).map(|c| std::array::from_fn(|i| i16::from_le_bytes([c[2 * i], c[2 * i + 1]]))).collect()
}

fn copy_back(data: &mut [u8], bytes: impl Iterator<Item = u8>) {
    for (slot, b) in data.iter_mut().zip(bytes) {
        *slot = b;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paths gltfpack's Fox does not take: index sequences (INDICES), 32-bit indices,
    /// 16-bit octahedral normals, colour filters, and vertex strides up to 256.
    #[test]
    fn every_mode_stride_and_filter_decodes_what_was_encoded() {
        let sequence: Vec<u32> = (0..300u32).map(|i| (i * 7919) % 1000).collect();
        let encoded = ::meshopt::encode_index_sequence(&sequence, 1000).unwrap();
        let as_u32 = |b: Vec<u8>| b.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect::<Vec<_>>();
        assert_eq!(as_u32(decode_indices(&encoded, 300, 4, false).unwrap().unwrap()), sequence);
        let triangles: Vec<u32> = (0..99u32).map(|i| i / 3 + i % 3).collect();
        let encoded = ::meshopt::encode_index_buffer(&triangles, 40).unwrap();
        // The index codec keeps each triangle but may start it at another corner.
        let canonical = |t: &[u32]| {
            let r = (0..3).min_by_key(|&r| t[r]).unwrap_or(0);
            [t[r], t[(r + 1) % 3], t[(r + 2) % 3]]
        };
        let decoded = as_u32(decode_indices(&encoded, 99, 4, true).unwrap().unwrap());
        let got: Vec<[u32; 3]> = decoded.chunks_exact(3).map(canonical).collect();
        assert_eq!(got, triangles.chunks_exact(3).map(canonical).collect::<Vec<_>>());
        assert!(decode_indices(&encoded, 99, 3, true).is_none());

        // A 256-byte vertex round trips through the largest stride.
        let vertices: Vec<[u32; 64]> = (0..50u32).map(|v| std::array::from_fn(|c| v * 64 + c as u32)).collect();
        let encoded = ::meshopt::encode_vertex_buffer(&vertices).unwrap();
        let want: Vec<u8> = vertices.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        assert_eq!(decode_vertices(&encoded, 50, 256).unwrap(), want);
        assert!(decode_vertices(&encoded[..encoded.len() / 2], 50, 256).is_err(), "truncated data decodes");

        let normals: Vec<[f32; 4]> = (0..64).map(|i| (i as f32 * 0.37).sin_cos()).map(|(s, c)| [s * 0.6, c * 0.6, 0.8, 0.0]).collect();
        let oct: Vec<[i16; 4]> = ::meshopt::encode_filter_oct(&normals, 16);
        let mut bytes: Vec<u8> = oct.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        apply_filter(&mut bytes, "OCTAHEDRAL", 8, false).unwrap();
        for (n, c) in normals.iter().zip(bytes.chunks_exact(8)) {
            let x = |k: usize| f32::from(i16::from_le_bytes([c[2 * k], c[2 * k + 1]])) / 32767.0;
            assert!((x(0) - n[0]).abs() < 1e-3 && (x(1) - n[1]).abs() < 1e-3 && (x(2) - n[2]).abs() < 1e-3, "{n:?}");
        }

        let colors: Vec<[f32; 4]> = (0..64).map(|i| [i as f32 / 63.0, 1.0 - i as f32 / 63.0, 0.5, 1.0]).collect();
        let ycocg: Vec<[u8; 4]> = ::meshopt::encode_filter_color(&colors, 8);
        let mut bytes: Vec<u8> = ycocg.iter().flatten().copied().collect();
        assert!(apply_filter(&mut bytes.clone(), "COLOR", 4, false).is_err(), "COLOR is KHR_meshopt_compression only");
        apply_filter(&mut bytes, "COLOR", 4, true).unwrap();
        for (c, got) in colors.iter().zip(bytes.chunks_exact(4)) {
            for k in 0..4 {
                assert!((f32::from(got[k]) / 255.0 - c[k]).abs() <= 2.0 / 255.0, "{c:?} -> {got:?}");
            }
        }
        assert!(apply_filter(&mut [0; 12], "QUATERNION", 12, false).is_err());
    }
}
