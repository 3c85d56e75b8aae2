//! SSDR's transform step (Le and Deng, "Smooth Skinning Decomposition with Rigid Bones", 2012,
//! section 4.4): with the weights fixed, each bone's transform in each frame is refitted in
//! turn to what the other bones leave of every vertex it influences, a weighted Procrustes
//! problem solved in closed form (Horn's quaternion method here). Frame 0 is the rest pose and
//! keeps the identity.

use super::horn::{Rigid, outer, rotation_from_covariance};
use super::sample::Data;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// The vertices each bone influences, with their weights.
pub fn members(joints: &[Vec<(u32, f64)>], bones: usize) -> Vec<Vec<(u32, f64)>> {
    let mut out = vec![Vec::new(); bones];
    for (v, infl) in joints.iter().enumerate() {
        for &(b, w) in infl {
            if w > 0.0 {
                out[b as usize].push((v as u32, w));
            }
        }
    }
    out
}

/// Refits `transforms[fi * bones + b]` for every frame of `data` but the rest pose, one bone
/// after another (block coordinate descent: each step can only lower the reconstruction
/// error). Frames are independent of each other.
pub fn update(data: &Data, influences: &[Vec<(u32, f64)>], transforms: &mut [Rigid], bones: usize) {
    let by_bone = members(influences, bones);
    let rest = &data.rest;
    // Frames in parallel, each with its own reconstruction: the same result on any number of
    // threads.
    transforms.par_chunks_mut(bones).enumerate().filter(|(fi, _)| !data.is_rest(*fi)).for_each(|(fi, row)| {
        let mut recon = vec![DVec3::ZERO; rest.len()];
        for (v, infl) in influences.iter().enumerate() {
            recon[v] = infl.iter().map(|&(b, w)| w * row[b as usize].apply(rest[v])).sum();
        }
        for (b, list) in by_bone.iter().enumerate() {
            if list.is_empty() {
                continue;
            }
            let old = row[b];
            // What vertex v asks of bone b: q_v = x_v - (the other bones' part), fitted by
            // w_v (R p_v + t). Then t = qbar - R pbar with pbar = sum w^2 p / sum w^2 and
            // qbar = sum w q / sum w^2, and R maximises tr(R^T sum w (q - w qbar)(p - pbar)^T).
            let (mut sw2, mut pbar, mut qbar) = (0.0, DVec3::ZERO, DVec3::ZERO);
            for &(v, w) in list {
                let v = v as usize;
                let q = data.at(fi, v) - recon[v] + w * old.apply(rest[v]);
                sw2 += w * w;
                pbar += w * w * rest[v];
                qbar += w * q;
            }
            if !(sw2 > 1e-300) {
                continue;
            }
            pbar /= sw2;
            qbar /= sw2;
            let mut s = DMat3::ZERO;
            for &(v, w) in list {
                let v = v as usize;
                let q = data.at(fi, v) - recon[v] + w * old.apply(rest[v]);
                s += outer(w * (rest[v] - pbar), q - w * qbar);
            }
            let r = rotation_from_covariance(s);
            let new = Rigid { r, t: qbar - r * pbar };
            for &(v, w) in list {
                let v = v as usize;
                recon[v] += w * (new.apply(rest[v]) - old.apply(rest[v]));
            }
            row[b] = new;
        }
    });
}
