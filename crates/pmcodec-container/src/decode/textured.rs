//! The decoder's appearance (version 6): the Charts, Materials and Attributes chunks loaded
//! with the first keyframe, images on demand, and a cut's mesh with its appearance.

use super::Decoder;
use crate::appearance::across::{band_faces, needs_faces};
use crate::appearance::cut::{DecodedAppearance, textured_mesh};
use crate::appearance::format::{AppearanceInfo, MaterialsChunk};
use crate::appearance::payload::{
    Table, charts_need_triangles, needs_above, needs_bind, read_band_bind, read_charts, read_charts_with, read_table_above,
    read_table_across,
};
use crate::format::ChunkKind;
use crate::payload::{read_key, read_triangles};
use crate::skin::read_binds;
use crate::{ByteSource, ContainerError};
use pmcodec_hierarchy::CutTarget;
use pmcodec_mesh::appearance::Image;
use pmcodec_mesh::{Appearance, TriMesh};

impl<S: ByteSource> Decoder<S> {
    /// Reads the appearance chunks this decoder's levels need, once (a file without
    /// appearance has none).
    pub(super) fn load_appearance(&mut self) -> Result<(), ContainerError> {
        if self.looks.is_some() {
            return Ok(());
        }
        let h = self.reader.header();
        let Some(info) = h.appearance.clone() else {
            self.looks = Some(DecodedAppearance::default());
            return Ok(());
        };
        // The triangles: a Charts chunk with neighbour charts and band 0's derived entries are
        // read from them, and a band's faces in frame 0 are walked up from them.
        let triangles = |this: &Self| -> Result<Vec<[u32; 3]>, ContainerError> {
            match &this.triangles {
                Some(t) => Ok(t.clone()),
                None => {
                    let e = this.reader.index().chunks.iter().find(|e| e.kind == ChunkKind::Triangles);
                    let e = e.ok_or_else(|| ContainerError::Corrupt { what: "index".into(), detail: "no triangles chunk".into() })?;
                    read_triangles(&this.reader.read_chunk(e)?, "triangles chunk", h.triangle_count, h.vertex_count, this.reader.version())
                }
            }
        };
        let raw = self.chunk(ChunkKind::Charts, 0, 0)?;
        let charts = if charts_need_triangles(&raw) {
            read_charts_with(&raw, &info, h.triangle_count, Some(&triangles(self)?))?
        } else {
            read_charts(&raw, &info, h.triangle_count)?
        };
        let raw = self.chunk(ChunkKind::Materials, 0, 0)?;
        let materials: MaterialsChunk =
            postcard::from_bytes(&raw).map_err(|e| ContainerError::Corrupt { what: "materials chunk".into(), detail: e.to_string() })?;
        materials.check(&info).map_err(|detail| ContainerError::Corrupt { what: "materials chunk".into(), detail })?;
        if let Some(c) = charts.chart_material.iter().position(|&m| m >= info.materials.max(1)) {
            return Err(ContainerError::Corrupt { what: "charts chunk".into(), detail: format!("chart {c} uses a material out of range") });
        }
        let mut tables = vec![None; h.levels()];
        // Without channels there is nothing to look up: files since 2026-11-26 have no
        // Attributes chunks then, and older ones' value-less tables are not read.
        let bands = if info.channels() == 0 { h.levels() } else { self.min_level };
        // Bands top down: a band's values may be predicted from the band above's.
        let mut above: Option<Table> = None;
        for (j, slot) in tables.iter_mut().enumerate().skip(bands).rev() {
            let raw = self.chunk(ChunkKind::Attributes, 0, j)?;
            let what = format!("band {j} attributes");
            // Through the parents of frame 0's hierarchy (its Key chunk of band j).
            let parent = if needs_above(&raw) {
                let key = self.chunk(ChunkKind::Key, 0, j)?;
                Some(read_key(&key, &format!("frame 0 band {j} keyframe"), &h.level_sizes, j, self.reader.version())?)
            } else {
                None
            };
            let above_of = parent.as_ref().and_then(|p| above.as_ref().map(|t| (&p[..], t)));
            let table = if j > 0 && needs_faces(&raw) {
                // Values across band j's faces in frame 0: the triangles walked up frame 0's
                // parents of levels 0..j (their Key chunks), as a derived Faces chunk does.
                let mut parents = Vec::with_capacity(j);
                for i in 0..j {
                    let key = self.chunk(ChunkKind::Key, 0, i)?;
                    parents.push(read_key(&key, &format!("frame 0 band {i} keyframe"), &h.level_sizes, i, self.reader.version())?);
                }
                let refs: Vec<&[u32]> = parents.iter().map(Vec::as_slice).collect();
                let faces = band_faces(&triangles(self)?, &charts.triangle_chart, &refs)
                    .ok_or_else(|| ContainerError::Corrupt { what: what.clone(), detail: "a frame 0 parent map misses a node".into() })?;
                read_table_across(&raw, &what, h.level_sizes[j], &info, h.triangle_count, above_of, Some((&faces.0, &faces.1)))?
            } else if j > 0 {
                read_table_above(&raw, &what, h.level_sizes[j], &info, h.triangle_count, above_of)?
            } else {
                let triangles = triangles(self)?;
                // Texture coordinates placed by the bind pose: the Bind chunk of band 0, which a
                // level-0 client of a skinned file reads anyway.
                // (The skin's when the decoder holds it already, else read here.)
                let n = h.level_sizes[0] as usize;
                let bind = match (needs_bind(&raw), &self.skin, &h.skin) {
                    (false, _, _) => None,
                    (true, Some(s), _) if s.nodes.len() >= n => Some(s.nodes[..n].iter().map(|s| s.bind).collect::<Vec<_>>()),
                    (true, _, Some(skin)) => {
                        let raw = self.chunk(ChunkKind::Bind, 0, 0)?;
                        Some(read_binds(&raw, "band 0 bind", h.level_sizes[0], skin.palette_len)?.iter().map(|n| n.bind).collect())
                    }
                    (true, _, None) => {
                        return Err(ContainerError::Corrupt { what, detail: "bind positions in a file without a skin".into() });
                    }
                };
                let band0 = (h.triangle_count, Some((&triangles[..], &charts.triangle_chart[..])));
                read_band_bind(&raw, &what, h.level_sizes[j], &info, band0, above_of, bind.as_deref())?
            };
            above = Some(table.clone());
            *slot = Some(table);
        }
        self.looks = Some(DecodedAppearance { info: Some(info), charts, tables, materials, images: None });
        Ok(())
    }

    /// The file's appearance header field (`None` for a bare surface or a file before version 6).
    pub fn appearance_info(&self) -> Option<&AppearanceInfo> {
        self.reader.header().appearance.as_ref()
    }

    /// The images, in order, read from their chunks (each call reads them again: a caller that
    /// draws many frames keeps them).
    pub fn images(&self) -> Result<Vec<Image>, ContainerError> {
        let Some(info) = self.appearance_info() else { return Ok(Vec::new()) };
        let raw = self.chunk(ChunkKind::Materials, 0, 0)?;
        let materials: MaterialsChunk =
            postcard::from_bytes(&raw).map_err(|e| ContainerError::Corrupt { what: "materials chunk".into(), detail: e.to_string() })?;
        materials.check(info).map_err(|detail| ContainerError::Corrupt { what: "materials chunk".into(), detail })?;
        let mut out = Vec::with_capacity(materials.images.len());
        for (i, desc) in materials.images.iter().enumerate() {
            let bytes = self.chunk(ChunkKind::Image, 0, i)?;
            if bytes.len() != desc.byte_length as usize {
                return Err(ContainerError::Corrupt {
                    what: format!("image {i} chunk"),
                    detail: format!("{} bytes where the materials chunk says {}", bytes.len(), desc.byte_length),
                });
            }
            out.push(Image { name: desc.name.clone(), mime_type: desc.mime_type.clone(), bytes });
        }
        Ok(out)
    }

    /// The cut `target` selects on the current frame, with its appearance: one vertex per
    /// (cut node, chart), texture coordinates and colours from the attribute tables, normals
    /// from the decoded positions, a material per triangle, and the materials, textures and
    /// samplers and images (read once, kept). Triangles come in the order
    /// [`Decoder::mesh`] lists them for budgets and errors, by input id for levels.
    pub fn textured_mesh(&mut self, target: CutTarget) -> Result<(TriMesh, Appearance), ContainerError> {
        self.load_appearance()?;
        if self.looks.as_ref().is_some_and(|l| l.info.is_some() && l.images.is_none()) {
            let images = std::sync::Arc::new(self.images()?);
            if let Some(l) = self.looks.as_mut() {
                l.images = Some(images);
            }
        }
        let diagonal = self.diagonal();
        let mut d = self.take_derived(target)?;
        let replay = self.replay.as_mut().ok_or_else(|| ContainerError::Options("seek to a frame first".into()))?;
        let size = replay.h.level_sizes[replay.min_level];
        let corners_of = |c: [u32; 3]| {
            if c.iter().all(|&v| v < size) { Ok(c) } else { Err(ContainerError::Options("a shown triangle without corners".into())) }
        };
        let mut shown: Vec<(u32, [u32; 3])> = Vec::new();
        let (priorities, order) = super::cut::Ordered::pick(&mut d.by_error, &mut d.by_budget, target);
        match order.prefix(replay, priorities, target, diagonal) {
            Ok(k) => {
                for &t in order.shown(k) {
                    let c = corners_of(replay.corners()[t as usize])?;
                    shown.push((t, c.map(|v| order.cut_node_of(replay, v, k))));
                }
            }
            Err(l) => {
                replay.select_level(l);
                // Mesh order: a small cut sorts its shown triangles, a large one (a player at
                // full resolution, every frame) marks them and passes over the triangles once.
                let count = replay.corners().len();
                let ts: Vec<u32> = if replay.shown().len() * 16 < count {
                    let mut ts = replay.shown().to_vec();
                    ts.sort_unstable();
                    ts
                } else {
                    let mut mark = vec![false; count];
                    for &t in replay.shown() {
                        if let Some(m) = mark.get_mut(t as usize) {
                            *m = true;
                        }
                    }
                    (0..count as u32).filter(|&t| mark[t as usize]).collect()
                };
                for t in ts {
                    let c = corners_of(replay.corners()[t as usize])?;
                    shown.push((t, c.map(|v| replay.cut_node_of(v))));
                }
            }
        }
        let offsets = replay.h.offsets.clone();
        let result = match &self.looks {
            Some(looks) => textured_mesh(looks, &offsets, &d.positions, &shown),
            None => Err(ContainerError::Options("appearance not loaded".into())),
        };
        self.derived = Some(d);
        result
    }
}
