//! The fused lane-group pass: the explicit (eq. 3.20–3.25), stick (§3.4.1) and one-sweep implicit
//! (eq. 3.26–3.34, one 3×3 solve per mass) updates of the fur thesis, run per free mass eight
//! masses at a time in the lanes of one register (`lanes.rs`; [`crate::groups::GroupData`]: eight
//! consecutive free masses per group, their links slot by slot, the link constants of one slot in
//! two cache lines).
//!
//! Each mass evaluates each of its links from its own side — a link between two free masses is
//! evaluated at both ends, and the other end's result is the exact negation (IEEE negation
//! commutes with every operation used), so both ends see the same magnitude bit for bit — then
//! adds the external and restoring (eq. 3.37) forces and advances. One parallel pass per step
//! does it all: the stick projection when every stick ends at an anchored mass, the finiteness
//! check, the wrong-side guard of §3.4.3 (eq. 3.35) when every tip's root is anchored (last
//! substep), and for the implicit solvers the next step's rotation limit; anything else falls
//! back to a separate pass. The reference and multi-sweep implicit solvers use the same pass with
//! no update ([`Mode::Finish`]) to end their step. Chunks are fixed and their outcomes combined
//! in chunk order, so the result is bit-identical for any thread count.

use glam::{DVec3, Vec3A};
use rayon::prelude::*;

use super::chunks::PARALLEL_MIN;
use super::lanes::{Avx, Lanes, Sc, V3, at, dot3, map3, present};
use super::projection::{place_on_stick, project_sticks};
use super::{Step, StepOutcome};
use crate::forces::ForceEval;
use crate::groups::GROUP;
use crate::model::SimModel;
use crate::sentinel::NONE;
use crate::shell::{GuardOutcome, GuardState};

/// Which update the lane-group kernel applies.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Mode {
    Explicit = 0,
    Stick = 1,
    Implicit = 2,
    /// No update: the new state is already in the outputs (projection, check, guard only).
    Finish = 3,
}

impl Mode {
    /// The mode of a kernel's const parameter (the kernel is compiled once per mode).
    #[inline(always)]
    const fn from_const(m: u8) -> Mode {
        match m {
            0 => Mode::Explicit,
            1 => Mode::Stick,
            2 => Mode::Implicit,
            _ => Mode::Finish,
        }
    }
}

/// Per free mass an f64 state: position and velocity (the reference solver's state, `reference.rs`,
/// which [`Mode::Finish`] rounds into the outputs).
#[derive(Clone, Copy, Default)]
pub(super) struct CgRow {
    pub x: DVec3,
    pub v: DVec3,
}

impl CgRow {
    /// True when `(x, v)` is this state's f32 rounding.
    #[inline]
    pub(super) fn rounds_to(&self, x: Vec3A, v: Vec3A) -> bool {
        self.x.as_vec3a() == x && self.v.as_vec3a() == v
    }
}

/// Everything the lane-group kernel reads.
struct GroupCtx<'a> {
    model: &'a SimModel,
    fe: &'a ForceEval<'a>,
    h: f32,
    x: &'a [Vec3A],
    v: &'a [Vec3A],
    mode: Mode,
    /// Put masses back on their sticks (parents all anchored) in the same pass.
    project: bool,
    /// Run the wrong-side guard on the tips in the same pass (roots all anchored, last substep).
    guard: Option<GuardCtx>,
    /// With `Some(θ)`: compute the next step's rotation limit from the new state (uniform forces).
    rotation: Option<f64>,
    /// The guard's current scale vectors and frozen flags (all tips; empty without the guard).
    old_scale: &'a [Vec3A],
    old_frozen: &'a [bool],
    /// Finish mode with the reference solver's new f64 state per free mass: the new state is
    /// its f32 rounding, written here rather than in a pass of its own.
    cg: &'a [CgRow],
}

/// The guard's parameters as the kernel uses them.
#[derive(Clone, Copy)]
struct GuardCtx {
    cos_a: f32,
    enabled: bool,
    impulse: f32,
}

/// What one chunk of the lane-group kernel found: whether its output is finite, and the guard's
/// triggers, frozen tips and added kinetic energy (summed in tip order within the chunk).
#[derive(Clone, Copy)]
struct ChunkOutcome {
    finite: bool,
    guard: GuardOutcome,
    /// The smallest rotation-limited step of the new state (infinity when not computed).
    rotation: f64,
}

/// Runs the lane-group kernel in `mode` over `step` and the stick projection: fused into the
/// kernel when every stick ends at an anchored mass, else level by level afterwards. The step's
/// guard (the last substep) runs in the same pass when every tip's root is anchored. `cg`: the
/// reference solver's CG rows in [`Mode::Finish`] (see [`GroupCtx::cg`]), else empty.
pub(super) fn group_step(step: Step, mode: Mode, cg: &[CgRow]) -> StepOutcome {
    let Step { model, fe, h, x, v, x_out, v_out, guard, rotation } = step;
    let fused = !model.has_sticks || model.sticks_to_anchors;
    let guard = guard.filter(|_| fused && model.guard_fusable);
    let (params, mut state) = match guard {
        Some((p, g)) => (Some(p), Some(g)),
        None => (None, None),
    };
    let gctx = params.map(|p| GuardCtx {
        cos_a: p.max_angle_deg.to_radians().cos(),
        enabled: p.enabled,
        impulse: p.impulse_m_per_s,
    });
    // The implicit kernel computes the next step's rotation limit when it sees the final state
    // (the guard ran in the pass) and the forces are uniform (independent of time and state).
    let rotation = rotation
        .filter(|&t| t > 0.0 && gctx.is_some() && fe.uniform_only() && matches!(mode, Mode::Implicit | Mode::Finish));
    let fused_guard = state.is_some();
    let out = {
        // The pass reads the guard's current state and writes the next one.
        let (tips, old_scale, old_frozen) = match state.as_deref_mut() {
            Some(GuardState { scale, frozen, scale_next, frozen_next, .. }) => {
                (Some((&mut scale_next[..], &mut frozen_next[..])), &scale[..], &frozen[..])
            }
            None => (None, &[][..], &[][..]),
        };
        let project = model.has_sticks && fused;
        let ctx = GroupCtx { model, fe, h, x, v, mode, project, guard: gctx, rotation, old_scale, old_frozen, cg };
        run_groups(&ctx, x_out, v_out, tips)
    };
    // A rejected (non-finite) step leaves the guard as it was.
    if let Some(g) = state
        && out.finite
    {
        g.commit();
    }
    if !fused {
        project_sticks(model, x_out, v_out);
    }
    StepOutcome {
        finite: out.finite && fused,
        guard: fused_guard.then_some(out.guard),
        rotation: rotation.map(|_| out.rotation),
    }
}

/// The end of a step whose new state the solver already wrote into `step.x_out`, `step.v_out`
/// (the reference and multi-sweep implicit solvers): the stick projection, the finiteness check,
/// the guard and the next rotation limit, in one lane-group pass where the topology allows, else
/// the level-by-level projection alone. Reads neither `step.x`, `step.v` nor `step.h`.
pub(super) fn finish_step(step: Step) -> StepOutcome {
    let model = step.model;
    if model.has_sticks && !model.sticks_to_anchors {
        project_sticks(model, step.x_out, step.v_out);
        return StepOutcome { finite: false, guard: None, rotation: None };
    }
    group_step(Step { h: 0.0, x: &[], v: &[], ..step }, Mode::Finish, &[])
}

/// One lane group as the kernel's stages see it.
#[derive(Clone, Copy)]
struct Group<'a> {
    /// Group index.
    g: usize,
    /// Its first free mass (`g · GROUP`).
    base: usize,
    /// Lanes that hold a real mass of this chunk (fewer than `GROUP` only in the last group).
    real: usize,
    /// Per lane the free mass it computes.
    lanes: &'a [u32; GROUP],
}

/// The forces on one lane group's masses and what the velocity update needs besides.
struct GroupForces<V> {
    /// External + restoring + link forces, N.
    total: V3<V>,
    /// Implicit only: `Σ w (h c I + h² Kp)` over the links, `[xx, yy, zz, xy, xz, yz]`.
    diag: [V; 6],
    mass: V,
    /// Implicit only: the restoring link's stiffness `2w/L` (0 without one) and its parent's velocity.
    restoring_k: V,
    restoring_parent_v: V3<V>,
}

/// The lane-group kernel over groups `g0..`, writing masses `g0 · GROUP ..` into `xo`, `vo`
/// (whose length says how many masses). Per group: the links of its eight masses slot by slot
/// ([`link_forces`]), the external and restoring forces ([`external_forces`],
/// [`restoring_forces`]), the update ([`new_velocity`]), the stick projection when `project`
/// ([`project_onto_anchors`]), a finiteness check of the result, and with the guard on, the
/// guard on the tips among these masses ([`guard_tips`]; `scale`, `frozen`: their tips' slots)
/// and the next rotation limit. Returns whether every written value is finite, the guard's
/// outcome and the rotation limit.
#[inline(always)]
fn groups_kernel<V: Lanes, const MODE: u8>(
    c: &GroupCtx,
    g0: usize,
    xo: &mut [Vec3A],
    vo: &mut [Vec3A],
    scale: &mut [Vec3A],
    frozen: &mut [bool],
) -> ChunkOutcome {
    let mode = Mode::from_const(MODE);
    let m = c.model;
    let gd = &m.groups;
    let hv = V::splat(c.h);
    let mut finite = true;
    let mut go = GuardOutcome::default();
    let mut rot = f64::INFINITY;
    let tip0 = m.tip_first[g0 * GROUP];
    for (gi, (xg, vg)) in xo.chunks_mut(GROUP).zip(vo.chunks_mut(GROUP)).enumerate() {
        let g = g0 + gi;
        let base = g * GROUP;
        let lanes: &[u32; GROUP] = gd.lane[base..base + GROUP].try_into().expect("whole groups");
        let grp = Group { g, base, real: xg.len().min(GROUP), lanes };
        let real = grp.real;
        if mode == Mode::Finish && !c.cg.is_empty() {
            write_cg_state(c, grp, xg, vg);
        }
        let (xi, vi) = if mode == Mode::Finish {
            let local = [0, 1, 2, 3, 4, 5, 6, 7].map(|l: u32| l.min(real as u32 - 1));
            (V::gather3(xg, &local), V::gather3(vg, &local))
        } else {
            (V::gather3(c.x, lanes), V::gather3(c.v, lanes))
        };
        let forces = group_forces::<V>(c, mode, grp, &xi, &vi);
        let mut vn = new_velocity(c, mode, grp, &vi, &forces);
        let mut xn: V3<V> = if mode == Mode::Finish { xi } else { map3!(a => xi[a] + vn[a] * hv) };
        // Stick projection onto anchored parents (as `project_sticks`); a mass sitting exactly on
        // its parent takes the scalar fallback below.
        let (pre_x, pre_v) = (xn, vn);
        let fallback = if c.project { project_onto_anchors(c, grp, &mut xn, &mut vn) } else { 0 };
        let one = V::splat(1.0);
        let mut ok = one.eq(one);
        for a in 0..3 {
            ok = ok.and(xn[a].finite()).and(vn[a].finite());
        }
        let want = (1u32 << real) - 1;
        finite &= ok.bits() & want == want;
        let (mut xr, mut vr) = (V::rows3(xn), V::rows3(vn));
        if fallback & want != 0 {
            let (px, pv) = (V::rows3(pre_x), V::rows3(pre_v));
            for l in (0..real).filter(|l| fallback >> l & 1 != 0) {
                (xr[l], vr[l]) = (px[l], pv[l]);
                let xp = m.rest[m.parent[base + l] as usize];
                place_on_stick(m, base + l, xp, Vec3A::ZERO, &mut xr[l], &mut vr[l]);
                finite &= xr[l].is_finite() && vr[l].is_finite();
            }
        }
        if let Some(gc) = c.guard {
            let rows = GroupRows { xn: &xn, xr: &xr, vr: &mut vr, fallback };
            guard_tips(c, gc, grp, rows, TipSlots { scale: &mut *scale, frozen: &mut *frozen, tip0 }, &mut go);
        }
        xg.copy_from_slice(&xr[..real]);
        vg.copy_from_slice(&vr[..real]);
        if let Some(theta) = c.rotation {
            // The next step's rotation limit (as `rotation_limit_of`, on the final velocities).
            let vf = V::gather3(vg, &[0, 1, 2, 3, 4, 5, 6, 7].map(|l: u32| l.min(real as u32 - 1)));
            let vl = dot3(&vf, &vf).sqrt();
            let f = map3!(a => V::splat(c.fe.accel[a]) * forces.mass);
            let fa = dot3(&f, &f).sqrt() + V::splat(4.0 * c.fe.restoring_w);
            V::rot_min(vl, fa, forces.mass, at::<V>(&gd.shortest_link, base), theta, &mut rot);
        }
    }
    if c.guard.is_some() {
        go.frozen = frozen.iter().filter(|&&f| f).count() as u32;
    }
    ChunkOutcome { finite, guard: go, rotation: rot }
}

/// Finish mode with the reference solver's new f64 state rows: their f32 rounding into `xg`, `vg`.
#[inline(always)]
fn write_cg_state(c: &GroupCtx, grp: Group, xg: &mut [Vec3A], vg: &mut [Vec3A]) {
    for l in 0..grp.real {
        let row = &c.cg[grp.base + l];
        (xg[l], vg[l]) = (row.x.as_vec3a(), row.v.as_vec3a());
    }
}

/// The forces on the group's masses at `xi`, `vi`: its links ([`link_forces`]), the external
/// forces ([`external_forces`]) and the restoring force ([`restoring_forces`]); none in
/// [`Mode::Finish`].
#[inline(always)]
fn group_forces<V: Lanes>(c: &GroupCtx, mode: Mode, grp: Group, xi: &V3<V>, vi: &V3<V>) -> GroupForces<V> {
    let (fl, diag) = link_forces::<V>(c, mode, grp, xi, vi);
    let mass = at::<V>(&c.model.groups.mass, grp.base);
    let fext = external_forces::<V>(c, mode, grp, mass);
    let (fr, restoring_k, restoring_parent_v) = restoring_forces::<V>(c, mode, grp, xi);
    let total: V3<V> = map3!(a => (fext[a] + fr[a]) + fl[a]);
    GroupForces { total, diag, mass, restoring_k, restoring_parent_v }
}

/// The group's link forces (Hooke eq. 3.23 + viscosity eq. 3.24), slot by slot in adjacency
/// order, each evaluated from the mass's own side (the other end computes the exact negation);
/// for the implicit solver also `h ∂F/∂x v` and the diagonal `Σ w (h c I + h² Kp)` (eq. 3.29).
#[inline(always)]
#[allow(clippy::needless_range_loop)]
fn link_forces<V: Lanes>(c: &GroupCtx, mode: Mode, grp: Group, xi: &V3<V>, vi: &V3<V>) -> (V3<V>, [V; 6]) {
    let gd = &c.model.groups;
    let (x, v, h) = (c.x, c.v, c.h);
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let (hv, h2v) = (V::splat(h), V::splat(h * h));
    let mut fl = [zero; 3];
    let mut diag = [zero; 6];
    let slots = if mode == Mode::Finish { 0..0 } else { gd.start[grp.g] as usize..gd.start[grp.g + 1] as usize };
    for s in slots {
        let sl = &gd.slots[s];
        let xj = V::gather3(x, &sl.other);
        let vj = V::gather3(v, &sl.other);
        let d = map3!(a => xj[a] - xi[a]);
        let dv = map3!(a => vj[a] - vi[a]);
        let (rest, k, cc) = (V::load(&sl.rest), V::load(&sl.k), V::load(&sl.c));
        let len = dot3(&d, &d).sqrt();
        if mode != Mode::Implicit {
            // |d · (1 − rest/l)| = |l − rest| stays bounded as l → 0, and d = 0 gives 0.
            let t = k * (one - rest / len.max(V::splat(1e-20)));
            for a in 0..3 {
                fl[a] = fl[a] + d[a].mul_add(t, dv[a] * cc);
            }
            continue;
        }
        // Force and stiffness block Kp = k (β I + (1 − β) d̂d̂ᵀ) (see `force_and_block`).
        let inv_l = one / len.max(V::splat(1e-20));
        let t = one - rest * inv_l;
        let kt = k * t;
        let beta = t.max(zero).min(one);
        let u = map3!(a => d[a] * inv_l);
        let kb = k * beta;
        let gg = k - kb;
        let gu = map3!(a => gg * u[a]);
        let mut kp = [
            gu[0].mul_add(u[0], kb),
            gu[1].mul_add(u[1], kb),
            gu[2].mul_add(u[2], kb),
            gu[0] * u[1],
            gu[0] * u[2],
            gu[1] * u[2],
        ];
        // Zero length: an isotropic block (k for a zero-rest link, else 0); k = 0 (padding,
        // sticks): no block. Rare, so only groups that have such a lane pay for the masks.
        let small = len.le(V::splat(1e-12));
        let keep = k.ne(zero);
        if (small.bits() | !keep.bits()) & 0xFF != 0 {
            let iso = rest.eq(zero).and(k);
            for (q, kq) in kp.iter_mut().enumerate() {
                *kq = keep.and(V::select(small, if q < 3 { iso } else { zero }, *kq));
            }
        }
        let kd = [
            kp[4].mul_add(dv[2], kp[3].mul_add(dv[1], kp[0] * dv[0])),
            kp[5].mul_add(dv[2], kp[1].mul_add(dv[1], kp[3] * dv[0])),
            kp[2].mul_add(dv[2], kp[5].mul_add(dv[1], kp[4] * dv[0])),
        ];
        let wl = V::load(&gd.slot_w[s]);
        let hc = hv * cc;
        for q in 0..6 {
            let hb = if q < 3 { kp[q].mul_add(h2v, hc) } else { kp[q] * h2v };
            diag[q] = hb.mul_add(wl, diag[q]);
        }
        for a in 0..3 {
            fl[a] = fl[a] + kd[a].mul_add(hv, d[a].mul_add(kt, dv[a] * cc));
        }
    }
    (fl, diag)
}

/// The external forces on the group's masses (uniform: `m a` in lanes; else per mass).
#[inline(always)]
#[allow(clippy::needless_range_loop)]
fn external_forces<V: Lanes>(c: &GroupCtx, mode: Mode, grp: Group, mass: V) -> V3<V> {
    let (fe, m) = (c.fe, c.model);
    if mode == Mode::Finish {
        [V::splat(0.0); 3]
    } else if fe.uniform_only() {
        [V::splat(fe.accel.x) * mass, V::splat(fe.accel.y) * mass, V::splat(fe.accel.z) * mass]
    } else {
        let mut a = [[0.0f32; GROUP]; 3];
        for l in 0..grp.real {
            let k = grp.base + l;
            let f = fe.external(m.mass[k], c.x[k], c.v[k], m.rest[k]);
            (a[0][l], a[1][l], a[2][l]) = (f.x, f.y, f.z);
        }
        map3!(c => V::load(&a[c]))
    }
}

/// The restoring force (eq. 3.37) on the group's masses at `xi`, and for the implicit solver its
/// stiffness `2w/L` and the rest parent's velocity (zero lanes without a restoring link).
#[inline(always)]
fn restoring_forces<V: Lanes>(c: &GroupCtx, mode: Mode, grp: Group, xi: &V3<V>) -> (V3<V>, V, V3<V>) {
    let gd = &c.model.groups;
    let (base, w) = (grp.base, c.fe.restoring_w);
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let rp: &[u32; GROUP] = gd.rest_parent[base..base + GROUP].try_into().expect("whole groups");
    let (mut fr, mut kr) = ([zero; 3], zero);
    let mut vrp = [zero; 3];
    if mode != Mode::Finish && w != 0.0 && rp.iter().any(|&p| p != NONE) {
        let (has, rpi) = present::<V>(rp, grp.lanes);
        let xr = V::gather3(c.x, &rpi);
        let s = map3!(a => xi[a] - xr[a]);
        let rcp = one / dot3(&s, &s).sqrt();
        let ok = has.and(rcp.finite()).and(rcp.gt(zero));
        let sn = map3!(a => s[a] * rcp);
        let n = map3!(a => at::<V>(&gd.rest_n[a], base));
        let q = (one - dot3(&n, &sn)) * V::splat(w);
        for a in 0..3 {
            fr[a] = ok.and((n[a] - sn[a]) * q);
        }
        if mode == Mode::Implicit {
            kr = has.and(V::splat(2.0 * w) / at::<V>(&gd.rest_len, base).max(V::splat(1e-3)));
            vrp = V::gather3(c.v, &rpi);
        }
    }
    (fr, kr, vrp)
}

/// The group's new velocities from `vi` and `forces`: explicit `v + h F/m` (eq. 3.21–3.22); stick
/// with implicit parent damping; implicit by one 3×3 solve of the mass's diagonal block
/// (eq. 3.26–3.34); unchanged in [`Mode::Finish`].
#[inline(always)]
fn new_velocity<V: Lanes>(c: &GroupCtx, mode: Mode, grp: Group, vi: &V3<V>, forces: &GroupForces<V>) -> V3<V> {
    let gd = &c.model.groups;
    let base = grp.base;
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let (hv, h2v) = (V::splat(c.h), V::splat(c.h * c.h));
    let f = &forces.total;
    match mode {
        Mode::Finish => *vi,
        Mode::Explicit => {
            let s = hv * at::<V>(&gd.inv_mass, base);
            map3!(a => vi[a] + f[a] * s)
        }
        Mode::Stick => {
            let s = hv * at::<V>(&gd.inv_mass, base);
            let pa: &[u32; GROUP] = gd.parent[base..base + GROUP].try_into().expect("whole groups");
            if pa.iter().all(|&p| p == NONE) {
                map3!(a => vi[a] + f[a] * s)
            } else {
                let (has, pi) = present::<V>(pa, grp.lanes);
                let vp = V::gather3(c.v, &pi);
                let ac = s * at::<V>(&gd.parent_c, base);
                map3!(a => {
                    let free = vi[a] + f[a] * s;
                    V::select(has, (free + vp[a] * ac) / (one + ac), free)
                })
            }
        }
        Mode::Implicit => {
            // Diagonal block: (m + h² kr) I + Σ w (h c I + h² Kp); right-hand side
            // h (F + h ∂F/∂x v) with the restoring link's −kr (v − v_parent).
            let (diag, kr, vrp) = (&forces.diag, forces.restoring_k, &forces.restoring_parent_v);
            let md = forces.mass + h2v * kr;
            let [a, e, i, bb, cq, ff] = [diag[0] + md, diag[1] + md, diag[2] + md, diag[3], diag[4], diag[5]];
            let kpos = kr.gt(zero);
            let b: V3<V> = map3!(q => (f[q] + kpos.and(zero - (vi[q] - vrp[q]) * kr) * hv) * hv);
            let (c00, c01, c02) = (e * i - ff * ff, cq * ff - bb * i, bb * ff - cq * e);
            let (c11, c12, c22) = (a * i - cq * cq, bb * cq - a * ff, a * e - bb * bb);
            let det = a * c00 + bb * c01 + cq * c02;
            // Singular (not positive definite) blocks give NaN, which the finiteness check reports.
            let good = det.finite().and(det.gt(zero));
            let r = V::select(good, one / det, V::splat(f32::NAN));
            let dvv = [
                (c00 * b[0] + c01 * b[1] + c02 * b[2]) * r,
                (c01 * b[0] + c11 * b[1] + c12 * b[2]) * r,
                (c02 * b[0] + c12 * b[1] + c22 * b[2]) * r,
            ];
            map3!(q => vi[q] + dvv[q])
        }
    }
}

/// Puts the group's masses whose parent is anchored back at the stick's length from it and removes
/// their velocity along the stick (as `project_sticks`, parents at rest). Returns the lanes whose
/// mass sits exactly on its parent (no direction): the caller projects those in scalar code.
#[inline(always)]
fn project_onto_anchors<V: Lanes>(c: &GroupCtx, grp: Group, xn: &mut V3<V>, vn: &mut V3<V>) -> u32 {
    let (m, base) = (c.model, grp.base);
    let gd = &m.groups;
    let pa: &[u32; GROUP] = gd.parent[base..base + GROUP].try_into().expect("whole groups");
    if pa.iter().all(|&p| p == NONE) {
        return 0;
    }
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let (has, pi) = present::<V>(pa, grp.lanes);
    let xp = V::gather3(&m.rest, &pi);
    let e = map3!(a => xn[a] - xp[a]);
    let rcp = one / dot3(&e, &e).sqrt();
    let ok = rcp.finite().and(rcp.gt(zero));
    let fallback = has.bits() & !ok.bits();
    let dir = map3!(a => e[a] * rcp);
    let pl = at::<V>(&gd.parent_len, base);
    let rel = map3!(a => vn[a] - zero);
    let along = dot3(&rel, &dir);
    for a in 0..3 {
        xn[a] = V::select(has, xp[a] + dir[a] * pl, xn[a]);
        vn[a] = V::select(has, vn[a] - dir[a] * along, vn[a]);
    }
    fallback
}

/// A lane group's new state as the guard sees it: positions in lanes (`xn`) and as rows (`xr`),
/// velocity rows (`vr`, kicked by the guard), and the lanes the scalar stick fallback placed.
struct GroupRows<'a, V> {
    xn: &'a V3<V>,
    xr: &'a [Vec3A; GROUP],
    vr: &'a mut [Vec3A; GROUP],
    fallback: u32,
}

/// The guard's slots of one chunk: its tips' next scale vectors and frozen flags, the first at
/// global tip slot `tip0`.
struct TipSlots<'a> {
    scale: &'a mut [Vec3A],
    frozen: &'a mut [bool],
    tip0: u32,
}

/// The wrong-side guard (as `GuardState::apply`) on the group's tips: `n·s ≥ cos α` with `s` the
/// unit root→tip direction (eq. 3.35); a fresh failure freezes the scale vector and kicks the tip
/// (its velocity in `rows.vr`; triggers and added kinetic energy into `go`).
#[inline(always)]
fn guard_tips<V: Lanes>(
    c: &GroupCtx,
    gc: GuardCtx,
    grp: Group,
    rows: GroupRows<V>,
    tips: TipSlots,
    go: &mut GuardOutcome,
) {
    let (m, base, real) = (c.model, grp.base, grp.real);
    let gd = &m.groups;
    let GroupRows { xn, xr, vr, fallback } = rows;
    let TipSlots { scale, frozen, tip0 } = tips;
    let tr: &[u32; GROUP] = gd.tip_root[base..base + GROUP].try_into().expect("whole groups");
    if !tr[..real].iter().any(|&r| r != NONE) {
        return;
    }
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let (_, ri) = present::<V>(tr, grp.lanes);
    let xroot = V::gather3(&m.rest, &ri);
    let e = map3!(a => xn[a] - xroot[a]);
    let rcp = one / dot3(&e, &e).sqrt();
    let okn = rcp.finite().and(rcp.gt(zero));
    let sv = map3!(a => e[a] * rcp);
    let n = map3!(a => at::<V>(&gd.tip_n[a], base));
    let pass = V::splat(gc.cos_a).le(dot3(&n, &sv)).and(okn);
    let (okb, passb) = (okn.bits(), pass.bits());
    let srows = V::rows3(sv);
    let slot0 = (m.tip_first[base] - tip0) as usize;
    // Fast path: eight tips in a row, all passing (consecutive tip slots).
    let all = real == GROUP && gc.enabled && fallback == 0 && passb == 0xFF && tr.iter().all(|&r| r != NONE);
    if all {
        scale[slot0..slot0 + GROUP].copy_from_slice(&srows);
        frozen[slot0..slot0 + GROUP].fill(false);
    }
    for l in (0..real).filter(|&l| !all && tr[l] != NONE) {
        let k = base + l;
        let slot = (m.tip_first[k] - tip0) as usize;
        let gslot = m.tip_first[k] as usize;
        (scale[slot], frozen[slot]) = (c.old_scale[gslot], c.old_frozen[gslot]);
        let tn = m.tips[gslot].n;
        let (sn, pass) = if fallback >> l & 1 != 0 {
            let s = (xr[l] - m.rest[tr[l] as usize]).try_normalize();
            (s, s.is_some_and(|s| tn.dot(s) >= gc.cos_a))
        } else {
            (if okb >> l & 1 != 0 { Some(srows[l]) } else { None }, passb >> l & 1 != 0)
        };
        if !gc.enabled {
            scale[slot] = sn.unwrap_or(tn);
        } else if pass {
            scale[slot] = sn.expect("a passing tip has a direction");
            frozen[slot] = false;
        } else if !frozen[slot] {
            // Frozen tips wait for the restoring force; a fresh failure freezes and kicks.
            frozen[slot] = true;
            go.triggers += 1;
            let vi = vr[l];
            let nv = vi + gc.impulse * tn;
            let mk = m.mass[k] as f64;
            go.kinetic_added_j += 0.5 * mk * (nv.length_squared() as f64 - vi.length_squared() as f64);
            vr[l] = nv;
        }
    }
}

/// [`groups_kernel`] with AVX lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn groups_avx2(
    c: &GroupCtx,
    g0: usize,
    xo: &mut [Vec3A],
    vo: &mut [Vec3A],
    scale: &mut [Vec3A],
    frozen: &mut [bool],
) -> ChunkOutcome {
    match c.mode {
        Mode::Explicit => groups_kernel::<Avx, 0>(c, g0, xo, vo, scale, frozen),
        Mode::Stick => groups_kernel::<Avx, 1>(c, g0, xo, vo, scale, frozen),
        Mode::Implicit => groups_kernel::<Avx, 2>(c, g0, xo, vo, scale, frozen),
        Mode::Finish => groups_kernel::<Avx, 3>(c, g0, xo, vo, scale, frozen),
    }
}

/// [`groups_kernel`] on the best lanes this CPU has.
fn groups_dispatch(
    c: &GroupCtx,
    g0: usize,
    xo: &mut [Vec3A],
    vo: &mut [Vec3A],
    scale: &mut [Vec3A],
    frozen: &mut [bool],
) -> ChunkOutcome {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA (detected just above).
        return unsafe { groups_avx2(c, g0, xo, vo, scale, frozen) };
    }
    match c.mode {
        Mode::Explicit => groups_kernel::<Sc, 0>(c, g0, xo, vo, scale, frozen),
        Mode::Stick => groups_kernel::<Sc, 1>(c, g0, xo, vo, scale, frozen),
        Mode::Implicit => groups_kernel::<Sc, 2>(c, g0, xo, vo, scale, frozen),
        Mode::Finish => groups_kernel::<Sc, 3>(c, g0, xo, vo, scale, frozen),
    }
}

/// Masses per parallel work item of the lane-group kernel (a multiple of `GROUP`).
const GROUP_CHUNK: usize = 512;

/// Runs the lane-group kernel over every free mass: one parallel pass (above the cut-off), fixed
/// chunks; every mass's result depends on its own links only, so chunking never changes a
/// result, and the guard's sums are per chunk, combined in chunk order. `tips`: the guard's
/// scale vectors and frozen flags when it runs in the pass.
fn run_groups(
    c: &GroupCtx,
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
    tips: Option<(&mut [Vec3A], &mut [bool])>,
) -> ChunkOutcome {
    let nf = c.model.n_free;
    let (xs, vs) = (&mut x_out[..nf], &mut v_out[..nf]);
    let (mut scale, mut frozen) = tips.unwrap_or_default();
    if nf < PARALLEL_MIN {
        return groups_dispatch(c, 0, xs, vs, scale, frozen);
    }
    let tf = &c.model.tip_first;
    let mut tip_chunks = Vec::with_capacity(nf.div_ceil(GROUP_CHUNK));
    for i in 0..nf.div_ceil(GROUP_CHUNK) {
        let (a, b) = (i * GROUP_CHUNK, ((i + 1) * GROUP_CHUNK).min(nf));
        let len = if c.guard.is_some() { (tf[b] - tf[a]) as usize } else { 0 };
        let (sh, st) = std::mem::take(&mut scale).split_at_mut(len);
        let (fh, ft) = std::mem::take(&mut frozen).split_at_mut(len);
        tip_chunks.push((sh, fh));
        (scale, frozen) = (st, ft);
    }
    xs.par_chunks_mut(GROUP_CHUNK)
        .zip(vs.par_chunks_mut(GROUP_CHUNK))
        .zip(tip_chunks.into_par_iter())
        .enumerate()
        .map(|(i, ((xc, vc), (sc, fc)))| groups_dispatch(c, i * GROUP_CHUNK / GROUP, xc, vc, sc, fc))
        .collect::<Vec<_>>()
        .into_iter()
        // Combined in chunk order (rayon's `reduce` groups by how the work was split, which
        // would make the guard's f64 energy sum depend on the thread count).
        .fold(ChunkOutcome { finite: true, guard: GuardOutcome::default(), rotation: f64::INFINITY }, |a, b| {
            ChunkOutcome {
                finite: a.finite && b.finite,
                rotation: a.rotation.min(b.rotation),
                guard: GuardOutcome {
                    triggers: a.guard.triggers + b.guard.triggers,
                    frozen: a.guard.frozen + b.guard.frozen,
                    kinetic_added_j: a.guard.kinetic_added_j + b.guard.kinetic_added_j,
                },
            }
        })
}
