//! The stick projection (fur thesis §3.4.1, "orientation only"): every free mass with a rigid
//! parent link is put back at the link's length from its parent, level by level from the skin,
//! and its velocity along the link is removed. Run by the stick solver (`stick.rs`) and after the
//! mass–spring solvers' steps ([`project_sticks`]); the fused pass (`fused.rs`) does it in-line
//! ([`place_on_stick`]) when every stick ends at an anchored mass.

use glam::Vec3A;
use rayon::prelude::*;

use super::chunks::{CHUNK, PARALLEL_MIN};
use crate::model::SimModel;
use crate::sentinel::NONE;

/// Puts every mass with a rigid parent link back at the link's length from its (already placed)
/// parent, level by level from the skin, and removes the velocity component along the link
/// (relative to the parent). The position correction adds no velocity: a teleported stick snaps
/// back without being flung, and velocities are not computed as `(x_new − x_old)/h`, which in
/// f32 amplifies rounding by `1/h` and stops small steps from converging.
pub(crate) fn project_sticks(model: &SimModel, x_out: &mut [Vec3A], v_out: &mut [Vec3A]) {
    if !model.has_sticks {
        return;
    }
    let nf = model.n_free;
    for &(s, e) in &model.levels {
        let (placed_x, rest_x) = x_out.split_at_mut(s);
        let (placed_v, rest_v) = v_out.split_at_mut(s);
        let level_x = &mut rest_x[..e - s];
        let level_v = &mut rest_v[..e - s];
        let anchored = &model.rest[nf..];
        let place = |k: usize, xo: &mut Vec3A, vo: &mut Vec3A| {
            let p = model.parent[k];
            if p == NONE {
                return;
            }
            let p = p as usize;
            // Parents lie on a lower level (already placed) or are anchored (at rest, still).
            let (xp, vp) = if p < nf { (placed_x[p], placed_v[p]) } else { (anchored[p - nf], Vec3A::ZERO) };
            place_on_stick(model, k, xp, vp, xo, vo);
        };
        if e - s < PARALLEL_MIN {
            for (o, (xo, vo)) in level_x.iter_mut().zip(level_v.iter_mut()).enumerate() {
                place(s + o, xo, vo);
            }
        } else {
            level_x.par_chunks_mut(CHUNK).zip(level_v.par_chunks_mut(CHUNK)).enumerate().for_each(|(c, (xc, vc))| {
                for (o, (xo, vo)) in xc.iter_mut().zip(vc.iter_mut()).enumerate() {
                    place(s + c * CHUNK + o, xo, vo);
                }
            });
        }
    }
}

/// Puts free mass `k` (at `xo`, moving at `vo`) at its stick's length from its parent (at `xp`,
/// moving at `vp`) and removes its velocity along the stick relative to the parent.
#[inline]
pub(super) fn place_on_stick(model: &SimModel, k: usize, xp: Vec3A, vp: Vec3A, xo: &mut Vec3A, vo: &mut Vec3A) {
    let p = model.parent[k] as usize;
    let dir = (*xo - xp).try_normalize().unwrap_or_else(|| (model.rest[k] - model.rest[p]).normalize_or(Vec3A::Y));
    *xo = xp + dir * model.parent_len[k];
    let rel = *vo - vp;
    *vo -= dir * rel.dot(dir);
}
