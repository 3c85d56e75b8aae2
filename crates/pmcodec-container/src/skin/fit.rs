//! The encoder's side of skinning: the palette quantized frame by frame, and every node's skin.
//! Input vertices keep their own; a coarser node takes the four strongest of its cluster's
//! summed influences and a bind position, either the cluster's rest centroid or its frame-0
//! position carried back to bind space through its blended transform (Houle and Poulin's
//! bone-space placement, "Simplification and real-time smooth transitions of articulated
//! meshes", 2001, which `pmcodec-lod` applies per collapse).

use super::joints::{JointsFrame, fit_rig, rig_matrix};
use super::{ENTRY, LINEAR_BITS, MAX_BIND, MAX_MATRIX, NodeSkin, SkinHeader, SkinState, TRANSLATION_BITS, WEIGHT_ONE};
use crate::ContainerError;
use crate::encode::SkinPlacement;
use glam::{DMat3, DVec3, Vec3};
use pmcodec_hierarchy::Hierarchy;
use pmcodec_mesh::SequenceSkin;

/// Added to every translation before it is rounded, in its units (2^-2 quanta): the integer
/// skinning floors each influence's linear part (`>> 13`, proto/container.md "Skinning"), which
/// moves every skinned point by half a unit on average; translations half a unit up centre that
/// error on zero (the generated character of [`bind_step`]: 3.6% of a keyframe's vertices
/// outside the stored positions' slack, 4.1% without). Decoders are unchanged.
const FLOOR_CENTRE: f64 = 0.5;

/// What the encoder knows of a sequence's skin.
pub struct SkinFit<'a> {
    pub header: SkinHeader,
    skin: &'a SequenceSkin,
    /// Every node's skin (global ids).
    pub nodes: Vec<NodeSkin>,
    /// Per palette entry, the largest norm of a bind position of a node it influences, in bind
    /// quanta: how far a rotation error of the entry moves a point.
    radius: Vec<f64>,
    lo: Vec3,
    step: f64,
}

/// Influences as (entry, weight) quantized to weights in 1/65536 that sum to 65536 exactly, the
/// strongest first, the weakest dropped when they round to nothing.
fn quantize_weights(mut pairs: Vec<(u32, f64)>) -> ([u32; 4], [i64; 4]) {
    pairs.retain(|p| p.1 > 0.0 && p.1.is_finite());
    pairs.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    pairs.truncate(4);
    let sum: f64 = pairs.iter().map(|p| p.1).sum();
    let (mut joints, mut weights) = ([0u32; 4], [0i64; 4]);
    if sum <= 0.0 {
        return (joints, weights);
    }
    let mut q: Vec<(u32, i64)> =
        pairs.iter().map(|&(j, w)| (j, (w / sum * WEIGHT_ONE as f64).round() as i64)).filter(|p| p.1 > 0).collect();
    if q.is_empty() {
        q.push((pairs[0].0, WEIGHT_ONE));
    }
    // The strongest takes the rounding, so the sum is exact and every weight positive.
    let rest: i64 = q[1..].iter().map(|p| p.1).sum();
    q[0].1 = WEIGHT_ONE - rest;
    for (slot, (j, w)) in q.into_iter().enumerate() {
        joints[slot] = j;
        weights[slot] = w;
    }
    (joints, weights)
}

/// The bind quantum: a fraction `u` of the position quantum pulled back through the palette's
/// typical scale in frame 0 (the median cube root of its linear parts' determinants).
///
/// The integer skinning of a vertex errs by its bind position's rounding (uniform in `u / 2`
/// position quanta per axis) plus its linear parts' rounding (half a unit of 2^-15 quanta per
/// bind quantum, times the bind coordinates, about `|x| / u` quanta for a vertex `|x|` quanta
/// from the bind-space origin): variances `u^2 / 12` and `(|x| / (2^15 u))^2 / 12` (three
/// products of that spread), least in sum at `u = sqrt(|x| / 2^15)`, here at the rest
/// positions' RMS distance. A glTF whose motion is exactly linear blend skinning is predicted to
/// within the slack of the stored positions (`crate::grid`) when the sum is small: on a generated
/// character (`make_character --parts 12 --seconds 4`, 6,936 vertices) the fixed `u = 1/2` of
/// before left 7.9% of a keyframe's vertices outside it, this `u` 4.1% (3.6% with
/// [`FLOOR_CENTRE`]).
fn bind_step(skin: &SequenceSkin, step: f64) -> f64 {
    let mut scales: Vec<f64> = skin
        .matrices
        .first()
        .map(|ms| ms.iter().map(|m| linear(m).determinant().abs().cbrt()).filter(|s| s.is_finite() && *s > 1e-12).collect())
        .unwrap_or_default();
    scales.sort_by(f64::total_cmp);
    let s = scales.get(scales.len() / 2).copied().unwrap_or(1.0);
    let n = skin.rest.len().max(1) as f64;
    let x = (skin.rest.iter().map(|r| r.as_dvec3().length_squared()).sum::<f64>() / n).sqrt() * s / step;
    // Between 1/16 (a finer bind grid costs pose bytes: the linear parts shrink, so the rotation
    // takes more bits to stay as close) and 1/2, the quantum of before.
    let u = if x.is_finite() && x > 0.0 { (x / (1u64 << LINEAR_BITS) as f64).sqrt().clamp(1.0 / 16.0, 0.5) } else { 0.5 };
    step * u / s
}

fn linear(m: &[f32; 12]) -> DMat3 {
    DMat3::from_cols_array(&[m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6], m[10]].map(|x| x as f64))
}

fn translation(m: &[f32; 12]) -> DVec3 {
    DVec3::new(m[3] as f64, m[7] as f64, m[11] as f64)
}

/// Fits the skin of every node of `h` (the hierarchy of frame 0, whose node positions are
/// `positions0`) for positions quantized at `step` from `lo`.
pub fn fit_skin<'a>(
    skin: &'a SequenceSkin,
    h: &Hierarchy,
    positions0: &[Vec3],
    (lo, step): (Vec3, f32),
    (placement, keep): (SkinPlacement, f64),
) -> Result<SkinFit<'a>, ContainerError> {
    let step = step as f64;
    let bstep = bind_step(skin, step);
    if !(bstep.is_finite() && bstep > 0.0) {
        return Err(ContainerError::Options(format!("skin: bind quantum {bstep} from a position quantum {step}")));
    }
    let header = SkinHeader { palette_len: skin.palette_len, bind_step: bstep as f32 };
    let bstep = header.bind_step as f64;
    let quantize_bind = |b: DVec3, what: &dyn Fn() -> String| -> Result<[i64; 3], ContainerError> {
        let q = (b / bstep).round();
        if !q.is_finite() || q.abs().max_element() > MAX_BIND as f64 {
            return Err(ContainerError::Options(format!("skin: {} has a bind position {b} beyond the bind grid", what())));
        }
        Ok([q.x as i64, q.y as i64, q.z as i64])
    };
    let n0 = h.level_sizes[0] as usize;
    let total = h.offsets.last().copied().unwrap_or(0) as usize;
    let mut nodes = vec![NodeSkin::default(); total];
    for v in 0..n0 {
        let (joints, weights) = quantize_weights(skin.joints[v].iter().zip(&skin.weights[v]).map(|(&j, &w)| (j, w as f64)).collect());
        let bind = quantize_bind(skin.rest[v].as_dvec3(), &|| format!("vertex {v}"))?;
        nodes[v] = NodeSkin { bind, joints, weights };
    }
    let frame0 = skin.matrices.first().map(Vec::as_slice).unwrap_or_default();
    let ancestors = h.all_ancestors();
    // The entries each level keeps (a coarse node's dropped influences go to the kept entry
    // that replaces them: `super::skeleton`).
    let skeleton = super::skeleton::skeleton_levels(skin, &ancestors, &h.level_sizes, &positions0[..n0.min(positions0.len())], keep);
    let frames = super::skeleton::sampled_frames(skin);
    for (j, anc) in ancestors.iter().enumerate().skip(1) {
        let size = h.level_sizes[j] as usize;
        // Per node, its cluster's summed weight on each entry and the second moment of the
        // points each entry moves.
        let mut own: Vec<Vec<(u32, f64, [f64; 16])>> = vec![Vec::new(); size];
        let mut centroid = vec![(DVec3::ZERO, 0u32); size];
        for v in 0..n0 {
            let node = anc[v] as usize;
            for (&k, &w) in skin.joints[v].iter().zip(&skin.weights[v]) {
                if w <= 0.0 {
                    continue;
                }
                let at = match own[node].iter().position(|p| p.0 == k) {
                    Some(i) => i,
                    None => {
                        own[node].push((k, 0.0, [0.0; 16]));
                        own[node].len() - 1
                    }
                };
                own[node][at].1 += w as f64;
                super::skeleton::add_moment(&mut own[node][at].2, skin.rest[v], w as f64);
            }
            centroid[node].0 += skin.rest[v].as_dvec3();
            centroid[node].1 += 1;
        }
        // A merged entry's weight goes to whichever of the entries the level keeps for it or
        // for the node's other influences carries its points nearest.
        let level = &skeleton[j];
        let target = |k: u32| level.get(k as usize).copied().unwrap_or(k);
        let sums: Vec<Vec<(u32, f64)>> = own
            .iter()
            .map(|entries| {
                let mut candidates: Vec<u32> = entries.iter().map(|p| target(p.0)).collect();
                candidates.sort_unstable();
                candidates.dedup();
                let mut pairs: Vec<(u32, f64)> = Vec::new();
                for (k, w, s) in entries {
                    let to =
                        if target(*k) == *k { *k } else { super::skeleton::nearest(&frames, *k, s, &candidates).unwrap_or(target(*k)) };
                    match pairs.iter_mut().find(|p| p.0 == to) {
                        Some(p) => p.1 += w,
                        None => pairs.push((to, *w)),
                    }
                }
                pairs
            })
            .collect();
        for (local, pairs) in sums.into_iter().enumerate() {
            let g = h.offsets[j] as usize + local;
            let (joints, weights) = quantize_weights(pairs);
            let rest = centroid[local].0 / centroid[local].1.max(1) as f64;
            let bind = match placement {
                SkinPlacement::Centroid => rest,
                SkinPlacement::BackPropagated => back_propagate(&joints, &weights, frame0, positions0[g].as_dvec3()).unwrap_or(rest),
            };
            nodes[g] = NodeSkin { bind: quantize_bind(bind, &|| format!("level {j} node {local}"))?, joints, weights };
        }
    }
    let mut radius = vec![0.0f64; skin.palette_len as usize];
    for n in &nodes {
        let norm = n.bind.iter().map(|&b| (b as f64).powi(2)).sum::<f64>().sqrt();
        for (&j, &w) in n.joints.iter().zip(&n.weights) {
            if let Some(r) = radius.get_mut(j as usize).filter(|_| w > 0) {
                *r = r.max(norm);
            }
        }
    }
    Ok(SkinFit { header, skin, nodes, radius, lo, step })
}

/// The bind position that the blended transform of `joints`/`weights` in `frame` carries to
/// `x`, or `None` when that transform is singular.
fn back_propagate(joints: &[u32; 4], weights: &[i64; 4], frame: &[[f32; 12]], x: DVec3) -> Option<DVec3> {
    let (mut a, mut t) = (DMat3::ZERO, DVec3::ZERO);
    for (&j, &w) in joints.iter().zip(weights) {
        if w == 0 {
            continue;
        }
        let m = frame.get(j as usize)?;
        let w = w as f64 / WEIGHT_ONE as f64;
        a += linear(m) * w;
        t += translation(m) * w;
    }
    let det = a.determinant();
    (det.is_finite() && det.abs() > 1e-12).then(|| a.inverse() * (x - t)).filter(|b| b.is_finite())
}

impl SkinFit<'_> {
    /// Frame `f`'s palette as the Joints chunks code it, given what the decoder holds: entries
    /// whose input matrix is the previous frame's are held; the others are rigid where a
    /// rotation and uniform scale rebuild them to within a quarter quantum more than rounding
    /// their twelve values would (`fit_rig`), else their twelve values rounded.
    pub fn joints(&self, f: usize, held: &SkinState, intra: bool) -> Result<JointsFrame, ContainerError> {
        let fixed = self.fixed(f)?;
        let n = fixed.len() / ENTRY;
        let prediction = held.joint_prediction(intra);
        let mut out = JointsFrame { palette: vec![0; n * ENTRY], rig: vec![None; n], held: vec![false; n], links: Vec::new() };
        let (now, before) = (self.skin.matrices.get(f), f.checked_sub(1).and_then(|b| self.skin.matrices.get(b)));
        for e in 0..n {
            let r = e * ENTRY..(e + 1) * ENTRY;
            let same = matches!((now.and_then(|m| m.get(e)), before.and_then(|m| m.get(e))), (Some(a), Some(b)) if a == b);
            if let (false, true, Some(p)) = (intra, same, held.palette.get(r.clone())) {
                out.palette[r].copy_from_slice(p);
                out.rig[e] = held.rig.get(e).copied().flatten();
                out.held[e] = true;
                continue;
            }
            let m = &fixed[r.clone()];
            let radius = self.radius.get(e).copied().unwrap_or(0.0).max(1.0);
            let tolerance = 0.25 + 1.5 * radius / (1u64 << LINEAR_BITS) as f64;
            let rig = fit_rig(m, radius, prediction.rig_at(e), tolerance);
            let linear = rig.as_ref().and_then(rig_matrix);
            for (i, slot) in out.palette[r].iter_mut().enumerate() {
                *slot = match linear {
                    Some(l) if i % 4 != 3 => l[3 * (i / 4) + i % 4],
                    _ => m[i].round() as i64,
                };
            }
            out.rig[e] = rig;
        }
        Ok(out)
    }

    /// Frame `f`'s palette for the linked Joints coding ([`super::hierarchy::fit_frame`]), the
    /// entries fitted in reading order (`bands`: the entries each band carries); a keyframe
    /// chooses every entry's reference over its frames, up to `until` (the next keyframe).
    pub fn joints_linked(
        &self,
        f: usize,
        held: &SkinState,
        intra: bool,
        bands: &[Vec<u32>],
        until: usize,
    ) -> Result<JointsFrame, ContainerError> {
        let fixed = self.fixed(f)?;
        let n = fixed.len() / ENTRY;
        let order: Vec<u32> = bands.iter().rev().flatten().copied().collect();
        let radius = |e: usize| self.radius.get(e).copied().unwrap_or(0.0);
        let links = if intra {
            let frames = (f..until.max(f + 1)).map(|g| self.fixed(g)).collect::<Result<Vec<_>, _>>()?;
            super::choose_links(&frames, n, &order, radius, |p, e| super::read_before(bands, p as u32, e as u32))
        } else {
            let mut r = held.links.clone();
            r.resize(n, super::Link::NONE);
            r
        };
        // How far each linked entry's points lie from its pivot.
        let mut local = vec![0.0f64; n];
        for node in &self.nodes {
            for (&j, &w) in node.joints.iter().zip(&node.weights) {
                let Some(l) = links.get(j as usize).filter(|l| w > 0 && l.reference != super::NO_REF) else { continue };
                let d = (0..3).map(|a| (node.bind[a] - l.pivot[a]) as f64).map(|v| v * v).sum::<f64>().sqrt();
                local[j as usize] = local[j as usize].max(d);
            }
        }
        let radii = |e: usize| (radius(e), local.get(e).copied().unwrap_or(0.0));
        let (now, before) = (self.skin.matrices.get(f), f.checked_sub(1).and_then(|b| self.skin.matrices.get(b)));
        let same = |e: usize| matches!((now.and_then(|m| m.get(e)), before.and_then(|m| m.get(e))), (Some(a), Some(b)) if a == b);
        Ok(super::fit_frame(&fixed, radii, same, &order, links, (&held.joint_prediction(intra), &held.palette, intra)))
    }

    /// Frame `f`'s palette in the file's fixed point, before rounding.
    fn fixed(&self, f: usize) -> Result<Vec<f64>, ContainerError> {
        let scale = self.header.bind_step as f64 / self.step * (1u64 << LINEAR_BITS) as f64;
        let tscale = (1u64 << TRANSLATION_BITS) as f64 / self.step;
        let lo = self.lo.as_dvec3().to_array();
        let frame = self.skin.matrices.get(f).map(Vec::as_slice).unwrap_or_default();
        let mut out = Vec::with_capacity(frame.len() * ENTRY);
        for (k, m) in frame.iter().enumerate() {
            for a in 0..3 {
                for c in 0..4 {
                    let x = m[4 * a + c] as f64;
                    let q = if c < 3 { x * scale } else { (x - lo[a]) * tscale + FLOOR_CENTRE };
                    if !(q.is_finite() && q.abs() <= MAX_MATRIX as f64 - 1.0) {
                        return Err(ContainerError::Options(format!(
                            "skin: frame {f}: the matrix of {} does not fit the file's fixed point",
                            self.skin.name(k)
                        )));
                    }
                    out.push(q);
                }
            }
        }
        Ok(out)
    }
}
