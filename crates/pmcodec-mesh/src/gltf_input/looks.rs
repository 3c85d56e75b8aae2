//! Appearance input: each primitive's `TEXCOORD_0`/`_1`, `NORMAL` and `COLOR_0`, its material,
//! and the document's materials, textures, samplers and images, into an [`Appearance`].
//!
//! While a file is read, wedge `i` is authored vertex `i` (one wedge per vertex of every
//! primitive). Welding then moves positions together across seams while the wedges keep their
//! attributes, which is what makes a seam: one vertex, several wedges (Hoppe, "New quadric metric
//! for simplifying meshes with appearance attributes", 1999).

use super::looks_raw::{RawImage, RawLooks, RawTextureInfo};
use super::*;
use crate::Appearance;
use crate::appearance::{AlphaMode, Image, Material, Sampler, Texture, TextureRef, TextureTransform, image_mime_type};

/// The attributes of one primitive, each `None` when the primitive does not have it.
pub(super) struct PrimitiveLooks {
    uv0: Option<Vec<[f32; 2]>>,
    uv1: Option<Vec<[f32; 2]>>,
    normals: Option<Vec<[f32; 3]>>,
    colors: Option<Vec<[f32; 4]>>,
    /// Index into the file's materials, `None` for glTF's default material.
    material: Option<usize>,
}

const UV_TYPES: &[ComponentType] = &[ComponentType::F32, ComponentType::U8, ComponentType::U16, ComponentType::I8, ComponentType::I16];
const NORMAL_TYPES: &[ComponentType] = &[ComponentType::F32, ComponentType::I8, ComponentType::I16];
const COLOR_TYPES: &[ComponentType] = &[ComponentType::F32, ComponentType::U8, ComponentType::U16];

/// Reads the appearance attributes of a primitive of `n` vertices; `what` names it.
pub(super) fn read_primitive_looks(
    file: &GltfFile,
    prim: &json::mesh::Primitive,
    n: usize,
    what: &str,
) -> Result<PrimitiveLooks, MeshError> {
    use json::mesh::Semantic;
    let attribute = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|a| a.value());
    let material = prim.material.map(|m| m.value());
    if let Some(m) = material.filter(|&m| m >= file.looks.materials.len()) {
        return Err(gltf_error(format!("{what}: material {m} does not exist (the file has {})", file.looks.materials.len())));
    }
    let mut uvs = [None, None];
    for (set, slot) in uvs.iter_mut().enumerate() {
        let Some(at) = attribute(Semantic::TexCoords(set as u32)) else { continue };
        let name = format!("{what} TEXCOORD_{set}");
        let flat = file.read_floats(at, 2, UV_TYPES, &name)?;
        *slot = Some(per_vertex::<2>(&flat, n, &name)?);
    }
    let [uv0, uv1] = uvs;
    let normals = match attribute(Semantic::Normals) {
        Some(at) => {
            let name = format!("{what} NORMAL");
            let mut normals = per_vertex::<3>(&file.read_floats(at, 3, NORMAL_TYPES, &name)?, n, &name)?;
            for v in &mut normals {
                // Quantized normals are only nearly unit; a zero normal stays zero and is
                // replaced by the surface's own normal when the rig is finished.
                *v = Vec3::from_array(*v).normalize_or_zero().to_array();
            }
            Some(normals)
        }
        None => None,
    };
    let colors = match attribute(Semantic::Colors(0)) {
        Some(at) => {
            let name = format!("{what} COLOR_0");
            let dims = match file.root.accessors.get(at).map(|a| a.type_) {
                Some(Checked::Valid(Type::Vec3)) => 3,
                _ => 4,
            };
            let flat = file.read_floats(at, dims, COLOR_TYPES, &name)?;
            let colors = if dims == 3 {
                per_vertex::<3>(&flat, n, &name)?.into_iter().map(|[r, g, b]| [r, g, b, 1.0]).collect()
            } else {
                per_vertex::<4>(&flat, n, &name)?
            };
            Some(colors)
        }
        None => None,
    };
    Ok(PrimitiveLooks { uv0, uv1, normals, colors, material })
}

/// Groups `flat` into `n` finite elements, or says what is wrong with the attribute.
fn per_vertex<const D: usize>(flat: &[f32], n: usize, name: &str) -> Result<Vec<[f32; D]>, MeshError> {
    if flat.len() != n * D {
        return Err(gltf_error(format!("{name} has {} elements but POSITION has {n}", flat.len() / D)));
    }
    if let Some(i) = flat.iter().position(|x| !x.is_finite()) {
        return Err(gltf_error(format!("{name}: element {} is not a finite number", i / D)));
    }
    Ok(flat.chunks_exact(D).map(|c| std::array::from_fn(|k| c[k])).collect())
}

impl RiggedMesh {
    /// Appends the wedges of a primitive whose `n` vertices start at `base` and whose triangles
    /// are `self.triangles[first_triangle..]`. A per-wedge array that this primitive lacks but
    /// others have gets glTF's defaults (UV 0, white, the surface normal); one that only this
    /// primitive has is filled in for the wedges before it.
    pub(super) fn add_primitive_looks(&mut self, looks: PrimitiveLooks, base: usize, first_triangle: usize) {
        let n = self.positions.len() - base;
        let normals_before = match (&looks.normals, self.appearance.as_ref().is_some_and(|a| a.normals.is_empty())) {
            (Some(_), true) if base > 0 => Some(area_normals(&self.positions, &self.triangles[..first_triangle], 0..base)),
            _ => None,
        };
        let own_normals = match &looks.normals {
            Some(normals) => {
                let fallback = area_normals(&self.positions, &self.triangles[first_triangle..], base..base + n);
                normals.iter().zip(fallback).map(|(v, f)| if *v == [0.0; 3] { f } else { *v }).collect()
            }
            None => area_normals(&self.positions, &self.triangles[first_triangle..], base..base + n),
        };
        let triangles = self.triangles.len() - first_triangle;
        let app = self.appearance.get_or_insert_with(Appearance::default);
        let material = match looks.material {
            Some(m) => m as u32,
            None => default_material(app),
        };
        app.triangle_material.resize(app.triangle_material.len() + triangles, material);
        append(&mut app.uv0, looks.uv0, base, n, [0.0; 2]);
        append(&mut app.uv1, looks.uv1, base, n, [0.0; 2]);
        append(&mut app.colors, looks.colors, base, n, [1.0; 4]);
        if looks.normals.is_some() || !app.normals.is_empty() {
            if let Some(before) = normals_before {
                app.normals = before;
            }
            app.normals.extend(own_normals);
        }
    }

    /// Makes the wedges explicit once every primitive is read: wedge `i` on vertex `i`, the
    /// corners naming their vertex's wedge.
    pub(super) fn finish_looks(&mut self) {
        let n = self.positions.len();
        if let Some(app) = &mut self.appearance {
            app.wedge_vertex = (0..n as u32).collect();
            app.corner_wedges = self.triangles.clone();
        }
    }
}

/// Appends a primitive's values (or defaults) to a per-wedge array, filling in the wedges
/// before `base` with defaults when this is the first primitive with the attribute.
fn append<T: Copy>(out: &mut Vec<T>, values: Option<Vec<T>>, base: usize, n: usize, default: T) {
    match values {
        Some(values) => {
            out.resize(base, default);
            out.extend(values);
        }
        None if !out.is_empty() => out.resize(base + n, default),
        None => {}
    }
}

/// The index of glTF's default material, added after the file's own on first use.
fn default_material(app: &mut Appearance) -> u32 {
    if let Some(i) = app.materials.iter().position(|m| *m == Material::default() && m.name.as_deref() == Some(DEFAULT_NAME)) {
        return i as u32;
    }
    app.materials.push(Material { name: Some(DEFAULT_NAME.to_string()), ..Material::default() });
    app.materials.len() as u32 - 1
}

const DEFAULT_NAME: &str = "default";

/// Area-weighted vertex normals of `vertices` from `triangles` (glTF asks clients to compute
/// normals when a primitive has none); a vertex no triangle touches gets +Z.
fn area_normals(positions: &[Vec3], triangles: &[[u32; 3]], vertices: Range<usize>) -> Vec<[f32; 3]> {
    let mut sum = vec![Vec3::ZERO; vertices.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| positions.get(i as usize).copied().unwrap_or(Vec3::ZERO));
        let n = (b - a).cross(c - a);
        for &i in t {
            if let Some(s) = (i as usize).checked_sub(vertices.start).and_then(|k| sum.get_mut(k)) {
                *s += n;
            }
        }
    }
    sum.into_iter().map(|s| s.try_normalize().unwrap_or(Vec3::Z).to_array()).collect()
}

// ------------------------------------------------------------------------------------------------
// Materials, textures, samplers, images
// ------------------------------------------------------------------------------------------------

/// The document's materials, textures and samplers, and the images its textures use (others,
/// for example WebP alternatives behind an extension, are not loaded). Every index is checked.
pub(super) fn read_document_looks(file: &GltfFile) -> Result<Appearance, MeshError> {
    let raw = &file.looks;
    let mut app = Appearance::default();
    for (i, s) in raw.samplers.iter().enumerate() {
        let wrap = |w: Option<u32>, axis: &str| match w.unwrap_or(10497) {
            w @ (33071 | 33648 | 10497) => Ok(w),
            w => Err(gltf_error(format!("sampler {i}: wrap{axis} {w} is not a glTF wrapping mode"))),
        };
        app.samplers.push(Sampler {
            mag_filter: s.mag_filter,
            min_filter: s.min_filter,
            wrap_s: wrap(s.wrap_s, "S")?,
            wrap_t: wrap(s.wrap_t, "T")?,
        });
    }
    let mut image_slot: HashMap<usize, u32> = HashMap::new();
    for (i, t) in raw.textures.iter().enumerate() {
        let source = t.source.ok_or_else(|| gltf_error(format!("texture {i} has no PNG or JPEG source image")))? as usize;
        if source >= raw.images.len() {
            return Err(gltf_error(format!("texture {i}: image {source} does not exist (the file has {})", raw.images.len())));
        }
        if let Some(s) = t.sampler.filter(|&s| s as usize >= raw.samplers.len()) {
            return Err(gltf_error(format!("texture {i}: sampler {s} does not exist (the file has {})", raw.samplers.len())));
        }
        let next = app.images.len() as u32;
        let image = match image_slot.get(&source) {
            Some(&slot) => slot,
            None => {
                app.images.push(read_image(file, source, &raw.images[source])?);
                image_slot.insert(source, next);
                next
            }
        };
        app.textures.push(Texture { image, sampler: t.sampler.map(|s| s as u32) });
    }
    for (m, raw_material) in raw.materials.iter().enumerate() {
        app.materials.push(read_material(raw, m, raw_material)?);
    }
    Ok(app)
}

fn read_material(raw: &RawLooks, m: usize, mat: &looks_raw::RawMaterial) -> Result<Material, MeshError> {
    let reference = |info: &Option<RawTextureInfo>, slot: &str| -> Result<Option<TextureRef>, MeshError> {
        let Some(info) = info else { return Ok(None) };
        if info.index as usize >= raw.textures.len() {
            return Err(gltf_error(format!(
                "material {m} {slot}: texture {} does not exist (the file has {})",
                info.index,
                raw.textures.len()
            )));
        }
        let transform = info.extensions.texture_transform.as_ref().map(|t| TextureTransform {
            offset: t.offset.unwrap_or([0.0; 2]),
            rotation: t.rotation.unwrap_or(0.0),
            scale: t.scale.unwrap_or([1.0; 2]),
            tex_coord: t.tex_coord,
        });
        let set = transform.and_then(|t| t.tex_coord).unwrap_or(info.tex_coord);
        if set > 1 {
            return Err(MeshError::Unsupported(format!(
                "material {m} {slot} uses TEXCOORD_{set} (only TEXCOORD_0 and TEXCOORD_1 are read)"
            )));
        }
        Ok(Some(TextureRef { texture: info.index as u32, tex_coord: info.tex_coord, transform }))
    };
    let pbr = &mat.pbr_metallic_roughness;
    let alpha_mode = match mat.alpha_mode.as_deref() {
        None | Some("OPAQUE") => AlphaMode::Opaque,
        Some("MASK") => AlphaMode::Mask,
        Some("BLEND") => AlphaMode::Blend,
        Some(other) => return Err(gltf_error(format!("material {m}: alphaMode {other:?} is not OPAQUE, MASK or BLEND"))),
    };
    let d = Material::default();
    let out = Material {
        name: mat.name.clone(),
        base_color_factor: pbr.base_color_factor.unwrap_or(d.base_color_factor),
        base_color_texture: reference(&pbr.base_color_texture, "baseColorTexture")?,
        metallic_factor: pbr.metallic_factor.unwrap_or(d.metallic_factor),
        roughness_factor: pbr.roughness_factor.unwrap_or(d.roughness_factor),
        metallic_roughness_texture: reference(&pbr.metallic_roughness_texture, "metallicRoughnessTexture")?,
        normal_texture: reference(&mat.normal_texture, "normalTexture")?,
        normal_scale: mat.normal_texture.as_ref().and_then(|t| t.scale).unwrap_or(1.0),
        occlusion_texture: reference(&mat.occlusion_texture, "occlusionTexture")?,
        occlusion_strength: mat.occlusion_texture.as_ref().and_then(|t| t.strength).unwrap_or(1.0),
        emissive_texture: reference(&mat.emissive_texture, "emissiveTexture")?,
        emissive_factor: mat.emissive_factor.unwrap_or(d.emissive_factor),
        alpha_mode,
        alpha_cutoff: mat.alpha_cutoff.unwrap_or(d.alpha_cutoff),
        double_sided: mat.double_sided,
    };
    let numbers = out.base_color_factor.iter().chain(&out.emissive_factor).chain([
        &out.metallic_factor,
        &out.roughness_factor,
        &out.normal_scale,
        &out.occlusion_strength,
        &out.alpha_cutoff,
    ]);
    let finite = numbers.into_iter().all(|x| x.is_finite());
    if !finite {
        return Err(gltf_error(format!("material {m}: a factor is not a finite number")));
    }
    Ok(out)
}

/// The encoded bytes of image `i`: from a bufferView, a `data:` URI, or a file beside the glTF
/// (only when it was read from a path, and never outside its folder).
fn read_image(file: &GltfFile, i: usize, raw: &RawImage) -> Result<Image, MeshError> {
    let what = format!("image {i}");
    let bytes = match (&raw.buffer_view, &raw.uri) {
        (Some(view), _) => file.view(*view as usize, &what)?.0.to_vec(),
        (None, Some(uri)) if uri.starts_with("data:") => {
            let payload = uri.split_once(";base64,").map(|(_, p)| p);
            payload.and_then(decode_base64).ok_or_else(|| gltf_error(format!("{what}: its data URI is not valid base64")))?
        }
        (None, Some(uri)) => {
            let Some(base) = &file.base else {
                return Err(gltf_error(format!(
                    "{what} refers to the external file {uri:?}; a glTF whose images are external files can only be read from \
                     a path (or embed the images in a GLB)"
                )));
            };
            let decoded = percent_decode(uri).ok_or_else(|| gltf_error(format!("{what}: URI {uri:?} is not valid")))?;
            let relative = PathBuf::from(&decoded);
            let inside = !uri.contains(':') && relative.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir));
            if !inside {
                return Err(MeshError::Unsupported(format!("{what}: URI {uri:?} (only relative paths inside the file's folder are read)")));
            }
            let path = base.join(relative);
            std::fs::read(&path).map_err(|e| gltf_error(format!("{what}: cannot read {}: {e}", path.display())))?
        }
        (None, None) => return Err(gltf_error(format!("{what} has neither a bufferView nor a URI"))),
    };
    let mime_type = image_mime_type(&bytes).ok_or_else(|| {
        gltf_error(format!(
            "{what} ({}) is neither PNG nor JPEG (its first bytes are {:02x?})",
            raw_name(raw),
            &bytes[..bytes.len().min(8)]
        ))
    })?;
    Ok(Image { name: raw.name.clone(), mime_type: mime_type.to_string(), bytes })
}

fn raw_name(raw: &RawImage) -> String {
    match (&raw.name, &raw.uri) {
        (Some(n), _) => format!("{n:?}"),
        (None, Some(u)) if !u.starts_with("data:") => format!("{u:?}"),
        _ => "unnamed".to_string(),
    }
}
