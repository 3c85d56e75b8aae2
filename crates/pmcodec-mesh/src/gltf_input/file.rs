//! Files, buffers and accessors: GLB chunks, URIs, `data:` buffers, checked accessor reads.

use super::*;

/// A parsed document and the bytes of every buffer an accessor uses (others stay `None`: a
/// buffer that only holds images is never loaded, nor a meshopt fallback buffer).
pub(super) struct GltfFile {
    pub(super) root: json::Root,
    pub(super) buffers: Vec<Option<Vec<u8>>>,
    /// The decoded bytes of every meshopt-compressed bufferView (see [`super::meshopt`]),
    /// read in place of the view's own.
    decoded_views: HashMap<usize, Vec<u8>>,
    /// The elements of every accessor a Draco primitive stands for (see [`super::draco`]),
    /// tightly packed in the accessor's component type, read in place of a bufferView.
    decoded_accessors: HashMap<usize, Vec<u8>>,
    /// Materials, textures, samplers and images as serialized (see `looks`).
    pub(super) looks: looks_raw::RawLooks,
    /// The folder external images are read from (`None` for bytes in memory).
    pub(super) base: Option<PathBuf>,
}

pub(super) const ANY_NUMBER: &[ComponentType] =
    &[ComponentType::F32, ComponentType::I8, ComponentType::U8, ComponentType::I16, ComponentType::U16, ComponentType::U32];

/// Extensions that do not change how positions, skins, morphs or animations are stored, and
/// KHR_mesh_quantization, whose integer attributes the accessor reader decodes, and the
/// geometry compressions decoded when the file is parsed (Draco, meshopt). Any other required
/// extension changes the data and is refused by name.
pub(super) fn extension_is_supported(name: &str) -> bool {
    const SUPPORTED: &[&str] = &[
        "KHR_mesh_quantization",
        "KHR_draco_mesh_compression",
        "EXT_meshopt_compression",
        "KHR_meshopt_compression",
        "KHR_texture_transform",
        "KHR_texture_basisu",
        "EXT_texture_webp",
        "EXT_texture_avif",
        "KHR_lights_punctual",
    ];
    SUPPORTED.contains(&name) || name.starts_with("KHR_materials_")
}

impl GltfFile {
    /// The element count an accessor declares (0 for an accessor that does not exist: reading
    /// it says so).
    pub(super) fn accessor_count(&self, index: usize) -> usize {
        self.root.accessors.get(index).map_or(0, |a| usize::try_from(a.count.0).unwrap_or(usize::MAX))
    }

    pub(super) fn open(path: &Path, limits: &InputLimits) -> Result<Self, MeshError> {
        let bytes = std::fs::read(path).map_err(|error| MeshError::Io { path: path.to_path_buf(), error })?;
        let base = path.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
        Self::parse(&bytes, base, limits).map_err(|e| at_path(path, e))
    }

    /// Parses a GLB or a JSON document; `base` is the folder external buffers are read from
    /// (`None` for bytes in memory, where they cannot be). Draco primitives and meshopt views
    /// are decoded here, Draco ones within `limits`.
    pub(super) fn parse(bytes: &[u8], base: Option<&Path>, limits: &InputLimits) -> Result<Self, MeshError> {
        let (json_bytes, bin) = if bytes.starts_with(b"glTF") {
            split_glb(bytes)?
        } else {
            // A UTF-8 byte order mark is not allowed (§3.2) but harmless; skip it.
            (bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes), None)
        };
        let root: json::Root = serde_json::from_slice(json_bytes).map_err(|e| gltf_error(format!("not a glTF 2.0 document: {e}")))?;
        let major = root.asset.version.split('.').next().unwrap_or_default();
        if major != "2" {
            return Err(MeshError::Unsupported(format!("glTF version {} (only 2.x is read)", root.asset.version)));
        }
        let unsupported: Vec<&str> = root.extensions_required.iter().map(String::as_str).filter(|e| !extension_is_supported(e)).collect();
        if !unsupported.is_empty() {
            return Err(MeshError::Unsupported(format!("required extension {}", unsupported.join(", "))));
        }
        let meshopt = meshopt_views(json_bytes)?;
        let draco = draco_primitives(json_bytes)?;
        let looks: looks_raw::RawLooks = serde_json::from_slice(json_bytes).map_err(|e| gltf_error(format!("materials or images: {e}")))?;
        let mut needed = vec![false; root.buffers.len()];
        let mut need_view = |view: usize| {
            // A compressed view needs the buffer of its compressed bytes, not its own.
            let buffer = match meshopt.get(view) {
                Some(Some(m)) => Some(m.buffer),
                _ => root.buffer_views.get(view).map(|v| v.buffer.value()),
            };
            if let Some(b) = buffer.and_then(|b| needed.get_mut(b)) {
                *b = true;
            }
        };
        for prim in &draco {
            need_view(prim.buffer_view);
        }
        for acc in &root.accessors {
            if let Some(v) = acc.buffer_view {
                need_view(v.value());
            }
            if let Some(sparse) = &acc.sparse {
                need_view(sparse.indices.buffer_view.value());
                need_view(sparse.values.buffer_view.value());
            }
        }
        for view in looks.images.iter().filter_map(|i| i.buffer_view) {
            need_view(view as usize);
        }
        let mut buffers = Vec::with_capacity(root.buffers.len());
        for (i, buffer) in root.buffers.iter().enumerate() {
            if !needed.get(i).copied().unwrap_or(false) {
                buffers.push(None);
                continue;
            }
            let mut data = match buffer.uri.as_deref() {
                // The GLB BIN chunk is the first buffer, the one without a URI (§4.4.3.3).
                None if i == 0 => bin.ok_or_else(|| gltf_error("buffer 0 has no URI and there is no GLB BIN chunk"))?.to_vec(),
                None => return Err(gltf_error(format!("buffer {i} has no URI"))),
                Some(uri) => read_uri(uri, base, i)?,
            };
            let declared = usize::try_from(buffer.byte_length.0).unwrap_or(usize::MAX);
            if data.len() < declared {
                return Err(gltf_error(format!("buffer {i} declares {declared} bytes but has {}", data.len())));
            }
            // Views may only reach the declared bytes, not the GLB padding.
            data.truncate(declared);
            buffers.push(Some(data));
        }
        let mut file = GltfFile {
            root,
            buffers,
            looks,
            base: base.map(Path::to_path_buf),
            decoded_views: HashMap::new(),
            decoded_accessors: HashMap::new(),
        };
        file.decoded_views = decode_meshopt(&file, &meshopt)?;
        file.decoded_accessors = decode_draco(&file, &draco, limits)?;
        Ok(file)
    }

    /// The bytes of a buffer view and its stride (if it declares one).
    pub(super) fn view(&self, index: usize, what: &str) -> Result<(&[u8], Option<usize>), MeshError> {
        let view = self.root.buffer_views.get(index).ok_or_else(|| gltf_error(format!("{what}: bufferView {index} does not exist")))?;
        if let Some(decoded) = self.decoded_views.get(&index) {
            return Ok((decoded, view.byte_stride.map(|s| s.0)));
        }
        let buffer = view.buffer.value();
        let data = self
            .buffers
            .get(buffer)
            .and_then(Option::as_deref)
            .ok_or_else(|| gltf_error(format!("{what}: bufferView {index} uses buffer {buffer}, which does not exist")))?;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let end = start.checked_add(view.byte_length.0);
        let slice = end.and_then(|end| data.get(usize::try_from(start).ok()?..usize::try_from(end).ok()?)).ok_or_else(|| {
            gltf_error(format!(
                "{what}: bufferView {index} (bytes {start}..{}) lies outside buffer {buffer} ({} bytes)",
                start.saturating_add(view.byte_length.0),
                data.len()
            ))
        })?;
        Ok((slice, view.byte_stride.map(|s| s.0)))
    }

    /// Decodes accessor `index` with `dims` components per element (§3.6.2), base view and
    /// sparse substitution (§3.6.2.3) included, calling `convert` on each component's bytes.
    fn decode<T: Copy + Default>(
        &self,
        index: usize,
        dims: usize,
        allowed: &[ComponentType],
        what: &str,
        convert: impl Fn(ComponentType, bool, &[u8]) -> T,
    ) -> Result<Vec<T>, MeshError> {
        let what = format!("{what} (accessor {index})");
        let acc = self.root.accessors.get(index).ok_or_else(|| gltf_error(format!("{what} does not exist")))?;
        let ty = match acc.type_ {
            Checked::Valid(t) => t,
            Checked::Invalid => return Err(gltf_error(format!("{what}: unknown type"))),
        };
        let actual_dims = match ty {
            Type::Scalar => 1,
            Type::Vec2 => 2,
            Type::Vec3 => 3,
            Type::Vec4 | Type::Mat2 => 4,
            Type::Mat3 => 9,
            Type::Mat4 => 16,
        };
        let ct = match acc.component_type {
            Checked::Valid(GenericComponentType(c)) => c,
            Checked::Invalid => return Err(gltf_error(format!("{what}: unknown component type"))),
        };
        if actual_dims != dims || !allowed.contains(&ct) {
            return Err(gltf_error(format!("{what} is {ty:?} of {ct:?}; expected {dims} components of one of {allowed:?}")));
        }
        let size = component_size(ct);
        let element = size * dims;
        let count = usize::try_from(acc.count.0).unwrap_or(usize::MAX);
        let total = count.checked_mul(dims).filter(|&t| t <= MAX_ELEMENTS);
        let Some(total) = total else {
            return Err(MeshError::TooLarge { what: format!("{what}: {count} elements") });
        };
        let mut out = vec![T::default(); total];
        let read_element = |slot: &mut [T], bytes: &[u8], at: usize| -> Option<()> {
            for (c, s) in slot.iter_mut().enumerate() {
                let from = at.checked_add(c * size)?;
                *s = convert(ct, acc.normalized, bytes.get(from..from.checked_add(size)?)?);
            }
            Some(())
        };
        let outside = || gltf_error(format!("{what}: {count} elements run past the end of their bufferView"));
        // A Draco-decoded accessor reads its decoded elements; without a bufferView the
        // elements are zeros (before sparse substitution).
        let source = match (self.decoded_accessors.get(&index), acc.buffer_view) {
            (Some(decoded), _) => Some((decoded.as_slice(), None, true)),
            (None, Some(view)) => Some(self.view(view.value(), &what).map(|(b, s)| (b, s, false))?),
            (None, None) => None,
        };
        if let Some((bytes, stride, decoded)) = source {
            let stride = stride.unwrap_or(element);
            if stride < element {
                return Err(gltf_error(format!("{what}: byteStride {stride} is less than its {element}-byte elements")));
            }
            let offset = if decoded { 0 } else { usize::try_from(acc.byte_offset.map_or(0, |o| o.0)).map_err(|_| outside())? };
            if count > 0 {
                let end = (count - 1).checked_mul(stride).and_then(|x| x.checked_add(offset)).and_then(|x| x.checked_add(element));
                if end.is_none_or(|end| end > bytes.len()) {
                    return Err(outside());
                }
            }
            for (e, slot) in out.chunks_exact_mut(dims).enumerate() {
                read_element(slot, bytes, offset + e * stride).ok_or_else(outside)?;
            }
        }
        if let Some(sparse) = &acc.sparse {
            let n = usize::try_from(sparse.count.0).unwrap_or(usize::MAX);
            if n > count {
                return Err(gltf_error(format!("{what}: {n} sparse values for {count} elements")));
            }
            let index_type = match sparse.indices.component_type {
                Checked::Valid(IndexComponentType(c @ (ComponentType::U8 | ComponentType::U16 | ComponentType::U32))) => c,
                _ => return Err(gltf_error(format!("{what}: sparse indices are not unsigned integers"))),
            };
            let (index_bytes, _) = self.view(sparse.indices.buffer_view.value(), &what)?;
            let (value_bytes, _) = self.view(sparse.values.buffer_view.value(), &what)?;
            let index_offset = usize::try_from(sparse.indices.byte_offset.0).unwrap_or(usize::MAX);
            let value_offset = usize::try_from(sparse.values.byte_offset.0).unwrap_or(usize::MAX);
            let sparse_outside = || gltf_error(format!("{what}: sparse data runs past the end of its bufferView"));
            let index_size = component_size(index_type);
            for s in 0..n {
                let at = s.checked_mul(index_size).and_then(|x| x.checked_add(index_offset)).ok_or_else(sparse_outside)?;
                let target =
                    index_bytes.get(at..at.saturating_add(index_size)).map(|b| component_u32(index_type, b)).ok_or_else(sparse_outside)?
                        as usize;
                let slot = out
                    .get_mut(target.saturating_mul(dims)..target.saturating_mul(dims).saturating_add(dims))
                    .ok_or_else(|| gltf_error(format!("{what}: sparse index {target} is beyond its {count} elements")))?;
                // Sparse values are tightly packed (§3.6.2.3).
                let at = s.checked_mul(element).and_then(|x| x.checked_add(value_offset)).ok_or_else(sparse_outside)?;
                read_element(slot, value_bytes, at).ok_or_else(sparse_outside)?;
            }
        }
        Ok(out)
    }

    /// Components as floats; normalised integers map to [0, 1] or [-1, 1] (§3.11).
    pub(super) fn read_floats(&self, index: usize, dims: usize, allowed: &[ComponentType], what: &str) -> Result<Vec<f32>, MeshError> {
        self.decode(index, dims, allowed, what, component_f32)
    }

    /// Components as unsigned integers (indices, joints).
    pub(super) fn read_uints(&self, index: usize, dims: usize, allowed: &[ComponentType], what: &str) -> Result<Vec<u32>, MeshError> {
        self.decode(index, dims, allowed, what, |ct, _, b| component_u32(ct, b))
    }
}

pub(super) fn component_size(ct: ComponentType) -> usize {
    match ct {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

pub(super) fn component_f32(ct: ComponentType, normalized: bool, b: &[u8]) -> f32 {
    match (ct, b) {
        (ComponentType::F32, &[a, b, c, d]) => f32::from_le_bytes([a, b, c, d]),
        (ComponentType::I8, &[a]) => {
            let v = f32::from(a as i8);
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        (ComponentType::U8, &[a]) => {
            let v = f32::from(a);
            if normalized { v / 255.0 } else { v }
        }
        (ComponentType::I16, &[a, b]) => {
            let v = f32::from(i16::from_le_bytes([a, b]));
            if normalized { (v / 32767.0).max(-1.0) } else { v }
        }
        (ComponentType::U16, &[a, b]) => {
            let v = f32::from(u16::from_le_bytes([a, b]));
            if normalized { v / 65535.0 } else { v }
        }
        (ComponentType::U32, &[a, b, c, d]) => {
            let v = u32::from_le_bytes([a, b, c, d]) as f32;
            if normalized { v / u32::MAX as f32 } else { v }
        }
        _ => 0.0,
    }
}

pub(super) fn component_u32(ct: ComponentType, b: &[u8]) -> u32 {
    match (ct, b) {
        (ComponentType::U8, &[a]) => u32::from(a),
        (ComponentType::U16, &[a, b]) => u32::from(u16::from_le_bytes([a, b])),
        (ComponentType::U32, &[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => 0,
    }
}

/// Splits a GLB (§4.4) into its JSON chunk and optional BIN chunk. Unknown chunk types are
/// skipped, as the specification asks.
pub(super) fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), MeshError> {
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    let word = |at: usize| bytes.get(at..at + 4).and_then(|b| b.try_into().ok()).map(u32::from_le_bytes);
    let version = word(4).ok_or_else(|| gltf_error("GLB header is truncated"))?;
    if version != 2 {
        return Err(MeshError::Unsupported(format!("GLB container version {version}")));
    }
    let length = word(8).ok_or_else(|| gltf_error("GLB header is truncated"))? as usize;
    if length < 12 || length > bytes.len() {
        return Err(gltf_error(format!("GLB header says {length} bytes but there are {}: truncated or corrupt", bytes.len())));
    }
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    while at < length {
        let (Some(chunk_length), Some(kind)) = (word(at), word(at + 4)) else {
            return Err(gltf_error(format!("GLB chunk header at byte {at} is truncated")));
        };
        let start = at + 8;
        let end = start.checked_add(chunk_length as usize).filter(|&e| e <= length);
        let data = end
            .and_then(|end| bytes.get(start..end))
            .ok_or_else(|| gltf_error(format!("GLB chunk at byte {at} runs past the end of the file")))?;
        match kind {
            JSON if json.is_none() && at == 12 => json = Some(data),
            BIN if bin.is_none() && json.is_some() => bin = Some(data),
            _ if at == 12 => return Err(gltf_error("the first GLB chunk is not JSON")),
            _ => {}
        }
        at = start + data.len();
    }
    Ok((json.ok_or_else(|| gltf_error("GLB has no JSON chunk"))?, bin))
}

/// Bytes of a buffer URI: a base64 `data:` URI, or with a base folder a relative path inside it.
pub(super) fn read_uri(uri: &str, base: Option<&Path>, index: usize) -> Result<Vec<u8>, MeshError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) =
            rest.split_once(";base64,").ok_or_else(|| MeshError::Unsupported(format!("buffer {index}: a data URI that is not base64")))?;
        return decode_base64(payload).ok_or_else(|| gltf_error(format!("buffer {index}: invalid base64 in its data URI")));
    }
    let Some(base) = base else {
        return Err(gltf_error(format!(
            "buffer {index} refers to the external file {uri:?}; a .gltf that references external files can only \
             be read from a path (or convert it to GLB)"
        )));
    };
    // Relative references only (§3.3.1 resolves URIs against the file), and never outside its
    // folder: a file from elsewhere must not make us read arbitrary local files.
    let decoded = percent_decode(uri).ok_or_else(|| gltf_error(format!("buffer {index}: URI {uri:?} is not valid")))?;
    let relative = PathBuf::from(&decoded);
    let inside = !uri.contains(':') && relative.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir));
    if !inside {
        return Err(MeshError::Unsupported(format!("buffer {index}: URI {uri:?} (only relative paths inside the file's folder are read)")));
    }
    let path = base.join(relative);
    std::fs::read(&path).map_err(|error| MeshError::Io { path, error })
}

pub(super) fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&b) = bytes.get(i) {
        if b == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Standard (and URL-safe) base64; stops at padding, skips whitespace.
pub(super) fn decode_base64(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let mut bits: u32 = 0;
    let mut held = 0u32;
    for c in text.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b' ' | b'\t' | b'\r' | b'\n' => continue,
            _ => return None,
        };
        bits = (bits << 6) | u32::from(v);
        held += 6;
        if held >= 8 {
            held -= 8;
            out.push((bits >> held) as u8);
            bits &= (1 << held) - 1;
        }
    }
    Some(out)
}
