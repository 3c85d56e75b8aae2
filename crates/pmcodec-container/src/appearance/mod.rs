//! Appearance in the container (format version 6): texture coordinates, colours and
//! materials stored once for the sequence, per level, coarse first; normals computed by
//! decoders from decoded positions. See proto/container.md, "Appearance".
//!
//! - `charts`: the charts and smoothing groups of the input triangles.
//! - `tables`: the encoder's per-level (node, chart) attribute tables.
//! - `payload`: the Attributes chunk payloads (and the Charts chunk's, from `chart_runs`);
//!   `entries`: a table's entries, listed or from the band above; `grown_charts`: the charts
//!   grown over the triangles' edges (Charts mode 4); `codes`: residual sections (rANS or
//!   adaptive Rice).
//! - `cut`: a decoded cut's per-corner attributes and normals.
//! - [`mod@format`]: the raw serialized types (header field, Materials chunk).

pub mod across;
mod chart_runs;
pub(crate) mod charts;
mod codes;
pub(crate) mod cut;
mod entries;
pub mod export;
pub mod format;
mod grown_charts;
pub mod payload;
pub mod project;
pub(crate) mod tables;

pub use charts::Charts;
pub use cut::DecodedAppearance;
pub use format::{AppearanceInfo, MaterialsChunk};

use pmcodec_mesh::Appearance;

/// Texture coordinates are quantized to this many bits over their bounding box by default
/// (Draco's default for texture coordinates is 10 to 12 bits; 12 keeps a 4096-pixel texture's
/// texel).
pub const DEFAULT_UV_BITS: u8 = 12;

/// The header field for an appearance with `charts`: texture coordinate grid from the
/// coordinates' bounding box at `uv_bits` bits.
pub fn info_for(app: &Appearance, charts: &Charts, uv_bits: u8) -> AppearanceInfo {
    let uv_sets = if app.uv0.is_empty() {
        0
    } else if app.uv1.is_empty() {
        1
    } else {
        2
    };
    let mut lo = [f32::INFINITY; 2];
    let mut hi = [f32::NEG_INFINITY; 2];
    for uv in app.uv0.iter().chain(&app.uv1) {
        for a in 0..2 {
            lo[a] = lo[a].min(uv[a]);
            hi[a] = hi[a].max(uv[a]);
        }
    }
    let levels = ((1u32 << uv_bits.clamp(4, 24)) - 1) as f32;
    let (uv_min, uv_step) =
        if uv_sets == 0 { ([0.0; 2], [1.0; 2]) } else { (lo, [0, 1].map(|a| ((hi[a] - lo[a]) / levels).max(f32::MIN_POSITIVE * 1e6))) };
    AppearanceInfo {
        charts: charts.count() as u32,
        groups: charts.triangle_group.iter().max().map_or(0, |&g| g + 1),
        materials: app.materials.len() as u32,
        images: app.images.len() as u32,
        uv_sets,
        uv_min,
        uv_step,
        colors: !app.colors.is_empty(),
        normals: !app.normals.is_empty(),
    }
}

/// The encoder's appearance state for `seq` (which has appearance `app`) with a hierarchy of
/// `levels` levels: charts and header field now, tables as frames are observed.
pub fn builder<'a>(seq: &'a pmcodec_mesh::Sequence, app: &'a Appearance, levels: usize) -> tables::TableBuilder<'a> {
    let charts = charts::build(&seq.triangles, seq.vertex_count(), app);
    let info = info_for(app, &charts, DEFAULT_UV_BITS);
    tables::TableBuilder::new(&seq.triangles, &seq.frames[0], app, charts, info, levels)
}

/// The appearance chunks, in file order: Charts, Materials, the Attributes of every band top
/// first (none when the entries carry no channels), then each Image. (kind, band, raw payload).
///
/// `triangles_read` says whether every client of the file reads the Triangles chunk and the
/// frame 0 Key chunks of the bands below its level (true where every band above 0 derives its
/// faces somewhere: proto/container.md, "Who reads what"). Only then may the Charts chunk use
/// neighbour charts and a coarse band's values be predicted across its faces, which read them:
/// otherwise a coarse client would have to fetch chunks the file says it does not read.
///
/// `bind` is a skinned file's bind positions of the level-0 nodes (its Bind chunk of band 0,
/// which every level-0 client reads): band 0 may then predict texture coordinates from them.
pub fn chunks(
    mut builder: tables::TableBuilder<'_>,
    triangles_read: bool,
    bind: Option<&[[i64; 3]]>,
) -> Result<Vec<(crate::ChunkKind, u32, Vec<u8>)>, crate::ContainerError> {
    use crate::ChunkKind;
    let tables = builder.finish();
    let channels = builder.info().channels();
    let app = builder.appearance();
    let materials = postcard::to_stdvec(&MaterialsChunk::from_appearance(app))
        .map_err(|e| crate::ContainerError::Io(format!("materials chunk: {e}")))?;
    let size = |b: &Vec<u8>| zstd::bulk::compress(b, crate::format::ZSTD_LEVEL).map_or(usize::MAX, |z| z.len());
    // The charts as plain, new-chart or recent-chart runs, whichever zstd makes shortest.
    let charts = [payload::write_charts(builder.charts()), payload::write_charts_new_runs(builder.charts())]
        .into_iter()
        .chain(payload::write_charts_recent(builder.charts()))
        .chain(triangles_read.then(|| payload::write_charts_neighbours(builder.charts(), builder.triangles())).flatten())
        .chain(triangles_read.then(|| payload::write_charts_grown(builder.charts(), builder.triangles())).flatten())
        .min_by_key(size)
        .unwrap_or_default();
    let mut out = vec![(ChunkKind::Charts, 0, charts), (ChunkKind::Materials, 0, materials)];
    // Entries without values name nothing a decoder draws: a file whose entries carry no
    // channels has no Attributes chunks (proto/container.md, "Attributes, band j").
    if channels > 0 {
        for (j, t) in tables.iter().enumerate().rev() {
            // Entries listed, values as differences from the previous entry's, from the
            // previous one of the same chart or from the band above's value of the node's
            // parent in frame 0 (bands below the top); band 0's entries may instead follow from the
            // Triangles and Charts chunks a level-0 client reads anyway, its values predicted
            // across the triangles. Whichever zstd makes shortest is written (all read the
            // same table).
            // Each also with its value residuals entropy-coded (rANS over their bit lengths),
            // which pays once a band has a few hundred values.
            // With the band above, its representatives' values need no residual at all
            // (`tables` made every coarse value one of its children's).
            let mut codings = vec![payload::write_table(t, channels), payload::write_table_rans(t, channels)];
            let chart_of = &builder.charts().triangle_chart;
            // Band j's faces in frame 0 (band 0's are the triangles, which mode 1 uses).
            let faces = (j > 0 && triangles_read)
                .then(|| (0..j).map(|i| builder.first_parent(i)).collect::<Option<Vec<_>>>())
                .flatten()
                .and_then(|parents| across::band_faces(builder.triangles(), chart_of, &parents));
            for rans in [false, true] {
                codings.push(payload::write_table_chartwise(t, channels, rans));
                if j == 0 {
                    codings.push(payload::write_table_derived(t, channels, builder.triangles(), chart_of, rans));
                    // Texture coordinates placed by the bind pose, the mesh their unwrap was
                    // made on (Fox's band 0: 695 -> 540 B).
                    if let Some(bind) = bind {
                        let tris = (builder.triangles(), &chart_of[..]);
                        codings.extend(payload::write_table_derived_bind(t, channels, tris, None, bind, rans));
                        let above = builder.first_parent(0).zip(tables.get(1).map(|a| a.to_table()));
                        if let Some((parent, above)) = &above {
                            codings.extend(payload::write_table_derived_bind(t, channels, tris, Some((parent, above)), bind, rans));
                        }
                    }
                }
                if let (Some(parent), Some(above)) = (builder.first_parent(j), tables.get(j + 1)) {
                    let above = above.to_table();
                    codings.push(payload::write_table_from_above(t, channels, parent, &above, rans));
                    codings.extend(payload::write_table_represented(t, channels, parent, &above, rans));
                    // And the entries themselves as bits over their parents' charts.
                    for represented in [false, true] {
                        codings.extend(payload::write_table_entries_above(t, channels, parent, &above, rans, represented));
                    }
                    // Or the values predicted across the band's own faces in frame 0.
                    if let Some(faces) = &faces {
                        for (represented, entries_above) in [(false, false), (true, false), (false, true), (true, true)] {
                            let f = (&faces.0[..], &faces.1[..]);
                            codings.extend(across::write_table_across(t, channels, parent, &above, f, rans, represented, entries_above));
                        }
                    }
                    if j == 0 {
                        let tris = builder.triangles();
                        codings.extend(across::write_table_derived_across(t, channels, tris, chart_of, parent, &above, rans));
                        codings.extend(payload::write_table_derived_represented(
                            t,
                            channels,
                            builder.triangles(),
                            chart_of,
                            parent,
                            &above,
                            rans,
                        ));
                    }
                }
            }
            let raw = codings.into_iter().min_by_key(size).unwrap_or_default();
            out.push((ChunkKind::Attributes, j as u32, raw));
        }
    }
    for (i, image) in app.images.iter().enumerate() {
        out.push((ChunkKind::Image, i as u32, image.bytes.clone()));
    }
    Ok(out)
}

/// The Materials chunk of a file with an appearance, parsed and checked against its header.
pub fn read_materials<S: crate::ByteSource>(reader: &crate::Reader<S>) -> Result<MaterialsChunk, crate::ContainerError> {
    let corrupt = |detail: String| crate::ContainerError::Corrupt { what: "materials chunk".into(), detail };
    let info = reader.header().appearance.as_ref().ok_or_else(|| crate::ContainerError::Options("the file has no appearance".into()))?;
    let entry = reader.find(crate::ChunkKind::Materials, 0, 0).ok_or_else(|| corrupt("missing from the index".into()))?;
    let raw = reader.read_chunk(entry)?;
    let m: MaterialsChunk = postcard::from_bytes(&raw).map_err(|e| corrupt(e.to_string()))?;
    m.check(info).map_err(corrupt)?;
    Ok(m)
}
