//! The four solvers' kernels (fur thesis §3.3.2, §3.4.1): one step of size `h` from `(x, v)` to
//! `(x_out, v_out)` for the free masses; anchored masses never move.
//!
//! - **Explicit** (eq. 3.20–3.25): forces at `t` (Hooke eq. 3.23, viscosity eq. 3.24, external),
//!   `v(t+h) = v + h M⁻¹F`, `p(t+h) = p + h v(t+h)`. Stable only below the step of
//!   [`stable_step`]; the simulator substeps.
//! - **Implicit** (eq. 3.26–3.34): the linearised backward-Euler system
//!   `(M − h ∂F/∂v − h² ∂F/∂x) Δv = h (F + h ∂F/∂x v)` solved by `iterations` Jacobi sweeps from
//!   `Δv = 0`; one sweep is the thesis's first iterate of eq. 3.34. Two deliberate changes, both
//!   needed for stability at large steps: the full 3×3 spring Jacobian of eq. 3.29 is used with the
//!   transverse term clamped at zero under compression, and the mass's own Jacobian blocks are
//!   moved to the left-hand side (eq. 3.34 as printed keeps only `M` there and diverges once
//!   `h²k/m > 1`) — a link between two free masses counts twice on the diagonal, which makes the
//!   diagonal dominate the system matrix so every sweep count is stable. Where the free masses
//!   fall into small independent clusters (separable prisms: three tips each) the system is
//!   solved exactly per cluster instead (`clusters.rs`): truncated sweeps there pump energy into
//!   a spinning stiff cluster.
//! - **Stick** (§3.4.1, "orientation only"): every link from an anchored root is a rigid stick;
//!   external and remaining spring forces move the mass explicitly, the parent link's damping is
//!   implicit, then the mass is put back at the stick's length from its parent (level by level
//!   from the skin) and its velocity along the stick is removed.
//! - **Reference** (Baraff & Witkin 1998): the same linearised backward-Euler system without the
//!   diagonal trick, in f64, solved by block-Jacobi-preconditioned conjugate gradient to a tight
//!   relative residual. Used to measure everyone else's error.
//!
//! Sticks in the mass–spring solvers are projected after the step the same way.
//!
//! Layout for speed: the explicit, stick and one-sweep implicit kernels run per free mass, eight
//! masses at a time in the lanes of one register ([`crate::model::GroupData`]: eight consecutive
//! free masses per group, their links slot by slot, the link constants of one slot in two cache
//! lines). Each mass evaluates each of its links from its own side — a link between two free
//! masses is evaluated at both ends, and the other end's result is the exact negation (IEEE
//! negation commutes with every operation used), so both ends see the same magnitude bit for
//! bit — then adds the external and restoring forces and advances. One parallel pass per step
//! does it all: the stick projection when every stick ends at an anchored mass, the finiteness
//! check, the wrong-side guard of §3.4.3 when every tip's root is anchored (last substep), and
//! for the implicit solver the next step's rotation limit; anything else falls back to a separate
//! pass. The lanes are AVX2 + FMA registers when the CPU has them (runtime detection), plain
//! arrays otherwise. No atomics, no scatter: every mass sums its own links in a fixed order and
//! every sum (guard energy, CG dot products) uses fixed-size chunks combined in order, so the
//! result is bit-identical for any thread count. The reference solver assembles in parallel per
//! mass (links to anchored masses folded into the mass's own block), and runs CG with two
//! passes per iteration: `p = z + βp`, `Ap = Az + βAp` and `p·Ap` in one; the vector updates, the
//! preconditioner and the two dot products in the other.

use std::ops::{Add, Div, Mul, Sub};

use glam::{DMat3, DVec3, Vec3A};
use rayon::prelude::*;

use crate::clusters::{Clusters, MAX_CLUSTER, solve_cluster};
use crate::forces::{ForceEval, restoring_force};
use crate::model::{GROUP, NONE, SimModel};
use crate::shell::{GuardOutcome, GuardParams, GuardState};

/// Masses per parallel work item; also the fixed chunk of deterministic sums.
pub(crate) const CHUNK: usize = 1024;
/// Below this many free masses the kernels run on the calling thread.
pub(crate) const PARALLEL_MIN: usize = 4096;

/// Runs `f(k)` for every free mass `k`, writing the returned `(x, v)` to `x_out[k]`, `v_out[k]`.
fn for_free<F>(n_free: usize, x_out: &mut [Vec3A], v_out: &mut [Vec3A], f: F)
where
    F: Fn(usize) -> (Vec3A, Vec3A) + Sync,
{
    let (xs, vs) = (&mut x_out[..n_free], &mut v_out[..n_free]);
    if n_free < PARALLEL_MIN {
        for (k, (xo, vo)) in xs.iter_mut().zip(vs.iter_mut()).enumerate() {
            (*xo, *vo) = f(k);
        }
        return;
    }
    xs.par_chunks_mut(CHUNK).zip(vs.par_chunks_mut(CHUNK)).enumerate().for_each(|(c, (xc, vc))| {
        for (o, (xo, vo)) in xc.iter_mut().zip(vc.iter_mut()).enumerate() {
            (*xo, *vo) = f(c * CHUNK + o);
        }
    });
}

/// Deterministic parallel sum of `f(k)` over `0..n` (fixed chunks, summed in order).
pub(crate) fn sum_over<F: Fn(usize) -> f64 + Sync>(n: usize, f: F) -> f64 {
    let chunks = n.div_ceil(CHUNK);
    let partial: Vec<f64> = if n < PARALLEL_MIN {
        (0..chunks).map(|c| (c * CHUNK..((c + 1) * CHUNK).min(n)).map(&f).sum()).collect()
    } else {
        (0..chunks).into_par_iter().map(|c| (c * CHUNK..((c + 1) * CHUNK).min(n)).map(&f).sum()).collect()
    };
    partial.iter().sum()
}

#[inline(always)]
fn external(model: &SimModel, fe: &ForceEval, k: usize, xi: Vec3A, vi: Vec3A) -> Vec3A {
    if fe.uniform_only() { fe.accel * model.mass[k] } else { fe.external(model.mass[k], xi, vi, model.rest[k]) }
}

#[inline(always)]
fn restoring(model: &SimModel, fe: &ForceEval, x: &[Vec3A], k: usize, xi: Vec3A) -> Vec3A {
    let r = model.rest_parent[k];
    if r == NONE || fe.restoring_w == 0.0 {
        Vec3A::ZERO
    } else {
        restoring_force(x[r as usize], xi, model.rest_n[k], fe.restoring_w)
    }
}

/// The largest stable explicit step (with safety factor `safety`) for the links in the model's
/// adjacency: a Gershgorin bound `λ` on the eigenvalues of `M^{-1/2} K M^{-1/2}` and `γ` on the
/// damping, and the symplectic-Euler stability condition `λh² + 2γh < 4`. Infinity when nothing
/// constrains the step.
pub(crate) fn stable_step(model: &SimModel, restoring_w: f32, include_parent_damping: bool, safety: f32) -> f64 {
    let mut best = f64::INFINITY;
    for k in 0..model.n_free {
        let mi = model.mass[k] as f64;
        let (mut lam, mut gam) = (model.restoring_stiffness(k, restoring_w) as f64 / mi, 0.0f64);
        for a in model.adj_of(k) {
            let j = a.other as usize;
            let coupling = if j < model.n_free { 1.0 / (mi * model.mass[j] as f64).sqrt() } else { 0.0 };
            lam += a.k as f64 * (1.0 / mi + coupling);
            gam += a.c as f64 * (1.0 / mi + coupling);
        }
        if include_parent_damping && model.parent[k] != NONE {
            gam += model.parent_c[k] as f64 / mi;
        }
        let h = if lam > 0.0 {
            (-gam + (gam * gam + 4.0 * lam).sqrt()) / lam
        } else if gam > 0.0 {
            2.0 / gam
        } else {
            f64::INFINITY
        };
        best = best.min(h);
    }
    best * safety as f64
}

/// What a mass–spring step reports: whether the kernel verified that the new state is finite
/// (false: not verified, or not finite), and the guard's outcome when it ran in the same pass.
pub(crate) struct StepOutcome {
    pub finite: bool,
    pub guard: Option<GuardOutcome>,
    /// The rotation-limited step of the new state, when the kernel computed it.
    pub rotation: Option<f64>,
}

/// Runs the lane-group kernel in `mode` and the stick projection: fused into the kernel when
/// every stick ends at an anchored mass, else level by level afterwards. With `guard` (the last
/// substep), the wrong-side guard runs in the same pass when every tip's root is anchored.
#[allow(clippy::too_many_arguments)]
fn group_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    x: &[Vec3A],
    v: &[Vec3A],
    mode: Mode,
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
    guard: Option<(&GuardParams, &mut GuardState)>,
    rotation: Option<f64>,
    cg: &[CgRow],
) -> StepOutcome {
    let fused = !model.has_sticks || model.sticks_to_anchors;
    let guard = guard.filter(|_| fused && model.guard_fusable);
    let (params, mut state) = match guard {
        Some((p, g)) => (Some(p), Some(g)),
        None => (None, None),
    };
    let gctx = params.map(|p| GuardCtx {
        cos_a: p.threshold_angle_deg.to_radians().cos(),
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

/// The end of a step whose new state the solver already wrote into `x_out`, `v_out` (the
/// reference and multi-sweep implicit solvers): the stick projection, the finiteness check, the
/// guard (with `guard`) and the next rotation limit (with `rotation`), in one lane-group pass
/// where the topology allows, else the level-by-level projection alone.
pub(crate) fn finish_step(
    model: &SimModel,
    fe: &ForceEval,
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
    guard: Option<(&GuardParams, &mut GuardState)>,
    rotation: Option<f64>,
) -> StepOutcome {
    if model.has_sticks && !model.sticks_to_anchors {
        project_sticks(model, x_out, v_out);
        return StepOutcome { finite: false, guard: None, rotation: None };
    }
    group_step(model, fe, 0.0, &[], &[], Mode::Finish, x_out, v_out, guard, rotation, &[])
}

/// One explicit Euler step (eq. 3.20–3.25). With `guard`, runs the guard in the same pass where it can.
#[allow(clippy::too_many_arguments)]
pub(crate) fn explicit_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    x: &[Vec3A],
    v: &[Vec3A],
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
    guard: Option<(&GuardParams, &mut GuardState)>,
) -> StepOutcome {
    group_step(model, fe, h, x, v, Mode::Explicit, x_out, v_out, guard, None, &[])
}

/// One stick-solver step: explicit forces, implicit parent damping
/// `v' = (v + h F/m + a v_parent)/(1 + a)`, `a = h c/m`, then projection. With `guard`, runs the
/// guard in the same pass where it can.
#[allow(clippy::too_many_arguments)]
pub(crate) fn stick_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    x: &[Vec3A],
    v: &[Vec3A],
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
    guard: Option<(&GuardParams, &mut GuardState)>,
) -> StepOutcome {
    group_step(model, fe, h, x, v, Mode::Stick, x_out, v_out, guard, None, &[])
}

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
fn place_on_stick(model: &SimModel, k: usize, xp: Vec3A, vp: Vec3A, xo: &mut Vec3A, vo: &mut Vec3A) {
    let p = model.parent[k] as usize;
    let dir = (*xo - xp).try_normalize().unwrap_or_else(|| (model.rest[k] - model.rest[p]).normalize_or(Vec3A::Y));
    *xo = xp + dir * model.parent_len[k];
    let rel = *vo - vp;
    *vo -= dir * rel.dot(dir);
}

/// Symmetric 3×3 matrix `[xx, yy, zz, xy, xz, yz]`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Sym3(pub [f32; 6]);

impl Sym3 {
    #[inline(always)]
    fn scaled_identity(s: f32) -> Sym3 {
        Sym3([s, s, s, 0.0, 0.0, 0.0])
    }
    #[inline(always)]
    fn add_scaled(&mut self, o: &Sym3, s: f32) {
        for i in 0..6 {
            self.0[i] += o.0[i] * s;
        }
    }
    #[inline(always)]
    fn mul(&self, v: Vec3A) -> Vec3A {
        let m = &self.0;
        Vec3A::new(
            m[0] * v.x + m[3] * v.y + m[4] * v.z,
            m[3] * v.x + m[1] * v.y + m[5] * v.z,
            m[4] * v.x + m[5] * v.y + m[2] * v.z,
        )
    }
    /// Solves `self · x = b` by the adjugate (the matrix is symmetric positive definite by
    /// construction); NaN when it is singular, which the simulator's finiteness check reports.
    #[inline(always)]
    fn solve(&self, b: Vec3A) -> Vec3A {
        let [a, e, i, bb, c, f] = self.0;
        let (c00, c01, c02) = (e * i - f * f, c * f - bb * i, bb * f - c * e);
        let (c11, c12, c22) = (a * i - c * c, bb * c - a * f, a * e - bb * bb);
        let det = a * c00 + bb * c01 + c * c02;
        if !(det.is_finite() && det > 0.0) {
            return Vec3A::splat(f32::NAN);
        }
        let r = 1.0 / det;
        Vec3A::new(
            (c00 * b.x + c01 * b.y + c02 * b.z) * r,
            (c01 * b.x + c11 * b.y + c12 * b.z) * r,
            (c02 * b.x + c12 * b.y + c22 * b.z) * r,
        )
    }
}

/// Hooke + viscosity force on mass i from a link (as [`link_force`]) and the link's stiffness
/// block `Kp = k (β I + (1 − β) d̂d̂ᵀ)` (eq. 3.29 with the transverse term `β = 1 − rest/l`
/// clamped to [0, 1], so the block is positive semi-definite); `∂F_i/∂x_j = Kp`,
/// `∂F_i/∂x_i = −Kp`. One square root and one division.
#[inline(always)]
fn force_and_block(d: Vec3A, dv: Vec3A, rest: f32, k: f32, c: f32) -> (Vec3A, Sym3) {
    let l = d.length();
    let inv_l = 1.0 / l.max(1e-20);
    let force = d * (k * (1.0 - rest * inv_l)) + dv * c;
    if k == 0.0 {
        return (force, Sym3::default());
    }
    if l <= 1e-12 {
        return (force, Sym3::scaled_identity(if rest == 0.0 { k } else { 0.0 }));
    }
    let beta = (1.0 - rest * inv_l).clamp(0.0, 1.0);
    let u = d * inv_l;
    let g = k * (1.0 - beta);
    let kb = k * beta;
    (
        force,
        Sym3([kb + g * u.x * u.x, kb + g * u.y * u.y, kb + g * u.z * u.z, g * u.x * u.y, g * u.x * u.z, g * u.y * u.z]),
    )
}

/// Per-step scratch of the mass–spring solvers (kept between steps to avoid reallocating).
#[derive(Default)]
pub(crate) struct ImplicitScratch {
    b: Vec<Vec3A>,
    diag: Vec<Sym3>,
    blocks: Vec<Sym3>,
    dv: Vec<Vec3A>,
    res: Vec<Vec3A>,
    dinv: Vec<DMat3>,
    rp: Vec<DVec3>,
    z: Vec<DVec3>,
    /// Per small cluster, its masses' `Δv` by slot (see `clusters`).
    cluster_dv: Vec<[Vec3A; MAX_CLUSTER]>,
}

fn sym_to_dmat(m: &Sym3) -> DMat3 {
    let q = m.0.map(|c| c as f64);
    DMat3::from_cols_array(&[q[0], q[3], q[4], q[3], q[1], q[5], q[4], q[5], q[2]])
}

/// One implicit Euler step (eq. 3.26–3.34) with `iterations` sweeps. With `guard`, runs the
/// guard in the same pass where it can.
///
/// Each sweep solves `P z = b − A Δv` and adds `z` to `Δv`, where `P` keeps the exact couplings
/// along each hair (a free mass and its free parent, solved by elimination from the tips down
/// to the roots and back) and replaces every other link between free masses by twice its block
/// on the diagonal (`P ≥ A`, so the sweeps converge and the step stays stable). For the two-mass
/// topologies there is nothing to eliminate and one sweep is one 3×3 solve per mass.
#[allow(clippy::too_many_arguments)]
pub(crate) fn implicit_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    iterations: u32,
    clusters: Option<&Clusters>,
    scratch: &mut ImplicitScratch,
    x: &[Vec3A],
    v: &[Vec3A],
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
    guard: Option<(&GuardParams, &mut GuardState)>,
    rotation: Option<f64>,
) -> StepOutcome {
    let nf = model.n_free;
    let h2 = h * h;
    // Assembles b_i, the diagonal block of P and (when `blocks` is given) every link's
    // h c I + h² Kp block for free mass k.
    let assemble = |k: usize, blocks: Option<&mut [Sym3]>| -> (Vec3A, Sym3) {
        let (xi, vi) = (x[k], v[k]);
        let mut f = external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi);
        let mut kv = Vec3A::ZERO;
        let kr = model.restoring_stiffness(k, fe.restoring_w);
        let mut diag = Sym3::scaled_identity(model.mass[k] + h2 * kr);
        if kr > 0.0 {
            kv -= (vi - v[model.rest_parent[k] as usize]) * kr;
        }
        let base = model.adj_start[k] as usize;
        let adj = model.adj_of(k);
        let mut blocks = blocks;
        for (e, a) in adj.iter().enumerate() {
            let j = a.other as usize;
            let dv = v[j] - vi;
            let (fl, kp) = force_and_block(x[j] - xi, dv, a.rest, a.k, a.c);
            f += fl;
            kv += kp.mul(dv);
            let mut hb = Sym3::scaled_identity(h * a.c);
            hb.add_scaled(&kp, h2);
            diag.add_scaled(&hb, model.adj_weight[base + e]);
            if let Some(bl) = blocks.as_deref_mut() {
                bl[e] = hb;
            }
        }
        ((f + kv * h) * h, diag)
    };
    if iterations <= 1 && !model.has_tree() && clusters.is_none() {
        // One sweep without trees: per mass its links' forces and blocks, one 3×3 solve.
        return group_step(model, fe, h, x, v, Mode::Implicit, x_out, v_out, guard, rotation, &[]);
    }
    let s = scratch;
    s.b.resize(nf, Vec3A::ZERO);
    s.diag.resize(nf, Sym3::default());
    s.blocks.resize(model.adj.len(), Sym3::default());
    s.dv.clear();
    s.dv.resize(nf, Vec3A::ZERO);
    s.res.resize(nf, Vec3A::ZERO);
    {
        let mut block_slices: Vec<&mut [Sym3]> = Vec::with_capacity(nf);
        let mut rest = s.blocks.as_mut_slice();
        for k in 0..nf {
            let len = (model.adj_start[k + 1] - model.adj_start[k]) as usize;
            let (head, tail) = rest.split_at_mut(len);
            block_slices.push(head);
            rest = tail;
        }
        let work = |(k, ((b, d), bl)): (usize, ((&mut Vec3A, &mut Sym3), &mut &mut [Sym3]))| {
            let (bb, dd) = assemble(k, Some(&mut **bl));
            *b = bb;
            *d = dd;
        };
        if nf < PARALLEL_MIN {
            s.b.iter_mut().zip(s.diag.iter_mut()).zip(block_slices.iter_mut()).enumerate().for_each(work);
        } else {
            s.b.par_iter_mut()
                .zip(s.diag.par_iter_mut())
                .zip(block_slices.par_iter_mut())
                .enumerate()
                .with_min_len(CHUNK)
                .for_each(work);
        }
    }
    if let Some(cl) = clusters {
        // Small independent clusters: the exact solve (see `clusters`), whatever the sweep count.
        s.cluster_dv.resize(cl.len(), [Vec3A::ZERO; MAX_CLUSTER]);
        let (out, blocks, b) = (&mut s.cluster_dv, &s.blocks, &s.b);
        let solve =
            |(c, o): (usize, &mut [Vec3A; MAX_CLUSTER])| solve_cluster(model, cl, c, h, fe.restoring_w, blocks, b, o);
        if nf < PARALLEL_MIN {
            out.iter_mut().enumerate().for_each(solve);
        } else {
            out.par_iter_mut().enumerate().with_min_len(CHUNK / 4).for_each(solve);
        }
        for k in 0..nf {
            s.dv[k] = out[cl.index_of(k)][cl.slot[k] as usize];
        }
        let dv = &s.dv;
        for_free(nf, x_out, v_out, |k| {
            let vn = v[k] + dv[k];
            (x[k] + vn * h, vn)
        });
        return finish_step(model, fe, x_out, v_out, guard, rotation);
    }
    let tree = model.has_tree();
    if tree {
        // Factor P along the hair trees, deepest level first: D'_k = D_k − Σ_c H_c D'_c⁻¹ H_c.
        s.dinv.resize(nf, DMat3::ZERO);
        for &(ls, le) in model.levels.iter().rev() {
            for k in ls..le {
                let mut d = sym_to_dmat(&s.diag[k]);
                let (cs, ce) = (model.tree_children_start[k] as usize, model.tree_children_start[k + 1] as usize);
                for &c in &model.tree_children[cs..ce] {
                    let hc = sym_to_dmat(&s.blocks[model.tree_parent_adj[c as usize] as usize]);
                    d -= hc * s.dinv[c as usize] * hc;
                }
                s.dinv[k] = if d.determinant() > 0.0 { d.inverse() } else { DMat3::NAN };
            }
        }
        s.rp.resize(nf, DVec3::ZERO);
        s.z.resize(nf, DVec3::ZERO);
    }
    for it in 0..iterations {
        // Residual b − A Δv (Δv = 0 on the first sweep).
        if it == 0 {
            s.res.copy_from_slice(&s.b);
        } else {
            let (b, blocks, dv) = (&s.b, &s.blocks, &s.dv);
            let residual = |k: usize| -> Vec3A {
                let kr = model.restoring_stiffness(k, fe.restoring_w);
                let mut ax = dv[k] * (model.mass[k] + h2 * kr);
                let base = model.adj_start[k] as usize;
                for (e, a) in model.adj_of(k).iter().enumerate() {
                    let j = a.other as usize;
                    let dvj = if j < nf { dv[j] } else { Vec3A::ZERO };
                    ax += blocks[base + e].mul(dv[k] - dvj);
                }
                b[k] - ax
            };
            if nf < PARALLEL_MIN {
                for (k, o) in s.res.iter_mut().enumerate() {
                    *o = residual(k);
                }
            } else {
                s.res.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(k, o)| *o = residual(k));
            }
        }
        // Δv += P⁻¹ res.
        if !tree {
            let (diag, res) = (&s.diag, &s.res);
            if nf < PARALLEL_MIN {
                for (k, o) in s.dv.iter_mut().enumerate() {
                    *o += diag[k].solve(res[k]);
                }
            } else {
                s.dv.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(k, o)| *o += diag[k].solve(res[k]));
            }
        } else {
            for k in 0..nf {
                s.rp[k] = s.res[k].as_dvec3();
            }
            for &(ls, le) in model.levels.iter().rev() {
                for k in ls..le {
                    let (cs, ce) = (model.tree_children_start[k] as usize, model.tree_children_start[k + 1] as usize);
                    for &c in &model.tree_children[cs..ce] {
                        let c = c as usize;
                        let hc = sym_to_dmat(&s.blocks[model.tree_parent_adj[c] as usize]);
                        let add = hc * (s.dinv[c] * s.rp[c]);
                        s.rp[k] += add;
                    }
                }
            }
            for &(ls, le) in &model.levels {
                for k in ls..le {
                    let mut t = s.rp[k];
                    let p = model.tree_parent[k];
                    if p != NONE {
                        t += sym_to_dmat(&s.blocks[model.tree_parent_adj[k] as usize]) * s.z[p as usize];
                    }
                    s.z[k] = s.dinv[k] * t;
                }
            }
            for k in 0..nf {
                s.dv[k] += s.z[k].as_vec3a();
            }
        }
    }
    let dv = &s.dv;
    for_free(nf, x_out, v_out, |k| {
        let vn = v[k] + dv[k];
        (x[k] + vn * h, vn)
    });
    finish_step(model, fe, x_out, v_out, guard, rotation)
}

/// One chunk of the reference assembly's outputs: right-hand sides, preconditioner blocks,
/// own blocks and the chunk's link blocks.
type AssemblyChunk<'a> = (((&'a mut [DVec3], &'a mut [[f64; 6]]), &'a mut [[f64; 6]]), &'a mut [[f64; 6]]);

/// Scratch of the converged reference solver (f64).
#[derive(Default)]
pub(crate) struct ReferenceScratch {
    b: Vec<DVec3>,
    /// Inverse diagonal blocks (symmetric, `[xx, yy, zz, xy, xz, yz]`).
    pinv: Vec<[f64; 6]>,
    blocks: Vec<[f64; 6]>,
    dself: Vec<[f64; 6]>,
    cg: Vec<CgRow>,
    /// Preconditioned residual.
    z: Vec<DVec3>,
    /// Search direction `p` and `A p`.
    pap: Vec<[DVec3; 2]>,
}

/// Per free mass: CG solution and residual.
#[derive(Clone, Copy, Default)]
struct CgRow {
    x: DVec3,
    r: DVec3,
}

#[inline(always)]
fn sym_mul64(m: &[f64; 6], v: DVec3) -> DVec3 {
    DVec3::new(
        m[0] * v.x + m[3] * v.y + m[4] * v.z,
        m[3] * v.x + m[1] * v.y + m[5] * v.z,
        m[4] * v.x + m[5] * v.y + m[2] * v.z,
    )
}

#[inline(always)]
fn precond(pinv: &[f64; 6], r: DVec3) -> DVec3 {
    sym_mul64(pinv, r)
}

/// Runs `f(chunk, out_chunk)` over the fixed `CHUNK`-mass chunks of `out` (parallel above the
/// cut-off) and returns the results in chunk order, so sums over them are thread-count independent.
fn chunk_map<T: Send, R: Send, F: Fn(usize, &mut [T]) -> R + Sync>(out: &mut [T], f: F) -> Vec<R> {
    if out.len() < PARALLEL_MIN {
        out.chunks_mut(CHUNK).enumerate().map(|(c, o)| f(c, o)).collect()
    } else {
        out.par_chunks_mut(CHUNK).enumerate().map(|(c, o)| f(c, o)).collect()
    }
}

/// [`chunk_map`] over two slices of the same length, chunked alike.
fn chunk_map2<T: Send, U: Send, R: Send, F: Fn(usize, &mut [T], &mut [U]) -> R + Sync>(
    a: &mut [T],
    b: &mut [U],
    f: F,
) -> Vec<R> {
    if a.len() < PARALLEL_MIN {
        a.chunks_mut(CHUNK).zip(b.chunks_mut(CHUNK)).enumerate().map(|(c, (x, y))| f(c, x, y)).collect()
    } else {
        a.par_chunks_mut(CHUNK).zip(b.par_chunks_mut(CHUNK)).enumerate().map(|(c, (x, y))| f(c, x, y)).collect()
    }
}

/// One converged backward-Euler step: PCG on the linearised system to relative residual `tol`.
/// Returns the CG iterations used, the relative residual reached and what [`finish_step`] did.
#[allow(clippy::too_many_arguments)]
pub(crate) fn reference_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    tol: f64,
    max_iterations: u32,
    s: &mut ReferenceScratch,
    x: &[Vec3A],
    v: &[Vec3A],
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
    guard: Option<(&GuardParams, &mut GuardState)>,
    rotation: Option<f64>,
) -> (u32, f64, StepOutcome) {
    let nf = model.n_free;
    let hd = h as f64;
    let h2 = hd * hd;
    s.blocks.resize(model.ref_first[nf] as usize, [0.0; 6]);
    s.b.resize(nf, DVec3::ZERO);
    s.pinv.resize(nf, [0.0; 6]);
    s.dself.resize(nf, [0.0; 6]);
    // Assembly, per mass over its own links, in parallel over fixed chunks of masses (each chunk
    // writes the blocks of the links between free masses that its masses list first — the other
    // end computes the same block bit for bit and only adds it to its diagonal).
    {
        let mut block_chunks: Vec<&mut [[f64; 6]]> = Vec::with_capacity(nf.div_ceil(CHUNK));
        let mut rest = s.blocks.as_mut_slice();
        let mut prev = 0usize;
        for c in 0..nf.div_ceil(CHUNK) {
            let end = model.ref_first[((c + 1) * CHUNK).min(nf)] as usize;
            let (head, tail) = rest.split_at_mut(end - prev);
            block_chunks.push(head);
            rest = tail;
            prev = end;
        }
        let assemble = |k: usize, blocks: &mut [[f64; 6]], base: usize| -> (DVec3, [f64; 6], [f64; 6]) {
            let kr = model.restoring_stiffness(k, fe.restoring_w) as f64;
            let (xi, vi) = (x[k], v[k]);
            let mut f = (external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi)).as_dvec3();
            let mut kv = DVec3::ZERO;
            if kr > 0.0 {
                kv -= (vi - v[model.rest_parent[k] as usize]).as_dvec3() * kr;
            }
            let md = model.mass[k] as f64 + h2 * kr;
            let mut diag = [md, md, md, 0.0, 0.0, 0.0];
            let mut dself = diag;
            for (e, a) in model.adj_of(k).iter().enumerate() {
                let j = a.other as usize;
                let (xj, vj) = (x[j].as_dvec3(), v[j].as_dvec3());
                let d = xj - xi.as_dvec3();
                let l = d.length();
                let (rest, kk, c) = (a.rest as f64, a.k as f64, a.c as f64);
                f += d * (kk * (1.0 - rest / l.max(1e-300))) + (vj - vi.as_dvec3()) * c;
                let kp: [f64; 6] = if kk == 0.0 {
                    [0.0; 6]
                } else if l <= 1e-12 {
                    let s = if rest == 0.0 { kk } else { 0.0 };
                    [s, s, s, 0.0, 0.0, 0.0]
                } else {
                    let beta = (1.0 - rest / l).clamp(0.0, 1.0);
                    let u = d / l;
                    let g = kk * (1.0 - beta);
                    let kb = kk * beta;
                    [
                        kb + g * u.x * u.x,
                        kb + g * u.y * u.y,
                        kb + g * u.z * u.z,
                        g * u.x * u.y,
                        g * u.x * u.z,
                        g * u.y * u.z,
                    ]
                };
                kv += sym_mul64(&kp, vj - vi.as_dvec3());
                let mut hb = kp.map(|q| q * h2);
                for q in &mut hb[..3] {
                    *q += hd * c;
                }
                for q in 0..6 {
                    diag[q] += hb[q];
                }
                let ae = model.adj_start[k] as usize + e;
                if j >= model.n_free {
                    for q in 0..6 {
                        dself[q] += hb[q];
                    }
                } else if model.ref_owner[ae] {
                    blocks[model.ref_slot[ae] as usize - base] = hb;
                }
            }
            // Block-Jacobi preconditioner: the inverse of the diagonal block.
            let (a, ee, i, bb, c, ff) = (diag[0], diag[1], diag[2], diag[3], diag[4], diag[5]);
            let (c00, c01, c02) = (ee * i - ff * ff, c * ff - bb * i, bb * ff - c * ee);
            let (c11, c12, c22) = (a * i - c * c, bb * c - a * ff, a * ee - bb * bb);
            let det = a * c00 + bb * c01 + c * c02;
            let r = if det > 0.0 && det.is_finite() { 1.0 / det } else { 0.0 };
            let pinv = [c00 * r, c11 * r, c22 * r, c01 * r, c02 * r, c12 * r];
            ((f + kv * hd) * hd, pinv, dself)
        };
        let work = |(c, (((bc, pc), kc), blc)): (usize, AssemblyChunk)| {
            let base = model.ref_first[c * CHUNK] as usize;
            for o in 0..bc.len() {
                let k = c * CHUNK + o;
                (bc[o], pc[o], kc[o]) = assemble(k, blc, base);
            }
        };
        if nf < PARALLEL_MIN {
            s.b.chunks_mut(CHUNK)
                .zip(s.pinv.chunks_mut(CHUNK))
                .zip(s.dself.chunks_mut(CHUNK))
                .zip(block_chunks)
                .enumerate()
                .for_each(work);
        } else {
            s.b.par_chunks_mut(CHUNK)
                .zip(s.pinv.par_chunks_mut(CHUNK))
                .zip(s.dself.par_chunks_mut(CHUNK))
                .zip(block_chunks.into_par_iter())
                .enumerate()
                .for_each(work);
        }
    }
    let (blocks, dself, pinv, b) = (&s.blocks, &s.dself, &s.pinv, &s.b);
    // Row k of A y: the mass's own block (mass, restoring stiffness and its links to anchored
    // masses) times y_k, plus every link to a free mass times (y_k − y_j).
    let apply_a = |ys: &[DVec3], k: usize| -> DVec3 {
        let yk = ys[k];
        let mut y = sym_mul64(&dself[k], yk);
        let (s0, s1) = (model.adj_start[k] as usize, model.adj_start[k + 1] as usize);
        for (&j, &slot) in model.adj_other[s0..s1].iter().zip(&model.ref_slot[s0..s1]) {
            let j = j as usize;
            if j < nf {
                y += sym_mul64(&blocks[slot as usize], yk - ys[j]);
            }
        }
        y
    };
    s.cg.resize(nf, CgRow::default());
    s.z.resize(nf, DVec3::ZERO);
    s.pap.resize(nf, [DVec3::ZERO; 2]);
    // Initial state x = 0, r = b, z = P⁻¹ r; sums of b·b and r·z per chunk.
    let sums = chunk_map2(&mut s.cg, &mut s.z, |c, rows, zs| {
        let mut acc = [0.0f64; 2];
        for (o, (row, zo)) in rows.iter_mut().zip(zs.iter_mut()).enumerate() {
            let k = c * CHUNK + o;
            let r = b[k];
            let z = precond(&pinv[k], r);
            (*row, *zo) = (CgRow { x: DVec3::ZERO, r }, z);
            acc[0] += r.length_squared();
            acc[1] += r.dot(z);
        }
        acc
    });
    let sum = |v: &[[f64; 2]], i: usize| v.iter().fold(0.0, |a, s| a + s[i]);
    let bnorm = sum(&sums, 0).sqrt();
    let mut rz = sum(&sums, 1);
    let mut iterations = 0;
    let mut rel = 0.0;
    if bnorm > 0.0 {
        rel = 1.0;
        let mut beta = None;
        loop {
            if rel <= tol || iterations >= max_iterations {
                break;
            }
            iterations += 1;
            // p = z + β p and A p = A z + β A p (so the product needs only z, final everywhere
            // after the last pass), with p·Ap; p = z on the first iteration.
            let pap: f64 = {
                let z = &s.z;
                chunk_map(&mut s.pap, |c, out| {
                    let mut acc = 0.0f64;
                    for (o, pa) in out.iter_mut().enumerate() {
                        let k = c * CHUNK + o;
                        let az = apply_a(z, k);
                        *pa = match beta {
                            None => [z[k], az],
                            Some(beta) => [z[k] + pa[0] * beta, az + pa[1] * beta],
                        };
                        acc += pa[0].dot(pa[1]);
                    }
                    acc
                })
                .iter()
                .fold(0.0, |a, s| a + s)
            };
            if pap.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                break;
            }
            let alpha = rz / pap;
            // x += α p, r −= α ap, z = P⁻¹ r, with r·r and r·z.
            let sums = {
                let pa = &s.pap;
                chunk_map2(&mut s.cg, &mut s.z, |c, rows, zs| {
                    let mut acc = [0.0f64; 2];
                    for (o, (row, zo)) in rows.iter_mut().zip(zs.iter_mut()).enumerate() {
                        let k = c * CHUNK + o;
                        row.x += pa[k][0] * alpha;
                        row.r -= pa[k][1] * alpha;
                        *zo = precond(&pinv[k], row.r);
                        acc[0] += row.r.length_squared();
                        acc[1] += row.r.dot(*zo);
                    }
                    acc
                })
            };
            rel = sum(&sums, 0).sqrt() / bnorm;
            let rz_new = sum(&sums, 1);
            beta = Some(rz_new / rz);
            rz = rz_new;
        }
    }
    let cg = &s.cg;
    // A step that did not converge is rejected: leave the guard alone.
    let converged = !(rel > tol && rel.is_finite());
    let out = if converged && (!model.has_sticks || model.sticks_to_anchors) {
        // The new state, projection, check, guard and rotation limit in one lane-group pass.
        group_step(model, fe, h, x, v, Mode::Finish, x_out, v_out, guard, rotation, cg)
    } else {
        for_free(nf, x_out, v_out, |k| {
            let vn = (v[k].as_dvec3() + cg[k].x).as_vec3a();
            ((x[k].as_dvec3() + vn.as_dvec3() * hd).as_vec3a(), vn)
        });
        if converged {
            finish_step(model, fe, x_out, v_out, guard, rotation)
        } else {
            project_sticks(model, x_out, v_out);
            StepOutcome { finite: false, guard: None, rotation: None }
        }
    };
    (iterations, rel, out)
}

// ------------------------------------------------------------------------------------------------
// Lane groups: the explicit, stick and one-sweep implicit kernels, eight free masses per register.

/// Eight `f32` lanes and the operations the per-mass kernels need. [`Sc`] is portable (plain
/// arrays, which the compiler vectorises as it can); [`Avx`] is an AVX register, used only after
/// runtime detection of AVX2 and FMA. Both perform the same IEEE operations in the same order,
/// except that [`Lanes::mul_add`] is fused on AVX (results may differ in the last bit between
/// the two; each is deterministic). Masks are lanes with every bit set (true) or clear (false).
trait Lanes: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> {
    fn splat(v: f32) -> Self;
    fn load(a: &[f32; GROUP]) -> Self;
    fn sqrt(self) -> Self;
    /// `self · b + c`: fused (one rounding) with AVX2+FMA, two roundings on the portable lanes.
    fn mul_add(self, b: Self, c: Self) -> Self;
    /// `self > o ? self : o` (the second operand when either is NaN, as `maxps`).
    fn max(self, o: Self) -> Self;
    /// `self < o ? self : o` (the second operand when either is NaN, as `minps`).
    fn min(self, o: Self) -> Self;
    /// Ordered `<=`, `==`, `>` and unordered `!=`, as masks.
    fn le(self, o: Self) -> Self;
    fn eq(self, o: Self) -> Self;
    fn gt(self, o: Self) -> Self;
    fn ne(self, o: Self) -> Self;
    /// Bitwise and (mask & value).
    fn and(self, o: Self) -> Self;
    /// `m ? a : b` lane by lane.
    fn select(m: Self, a: Self, b: Self) -> Self;
    /// Bit `l` set when lane `l`'s mask is true.
    fn bits(self) -> u32;
    /// Lowers `best` to the smallest rotation-limited step of eight masses (see
    /// [`rotation_limit_of`]) from their speeds `vl`, force magnitudes plus `4w` `fa`, masses `m`
    /// and shortest links `sl` (f32 lanes), with the f64 arithmetic of [`rotation_limit_of`].
    fn rot_min(vl: Self, fa: Self, m: Self, sl: Self, theta: f64, best: &mut f64);
    /// The eight vectors `src[idx[l]]`, by component.
    fn gather3(src: &[Vec3A], idx: &[u32; GROUP]) -> [Self; 3];
    /// The eight vectors of three component lanes.
    fn rows3(c: [Self; 3]) -> [Vec3A; GROUP];
    /// True lanes where the value is finite (`x − x` is 0 for finite `x`, NaN otherwise).
    #[inline(always)]
    #[allow(clippy::eq_op)]
    fn finite(self) -> Self {
        (self - self).eq(Self::splat(0.0))
    }
}

/// Portable lanes.
#[derive(Clone, Copy)]
struct Sc([f32; GROUP]);

macro_rules! sc_binop {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for Sc {
            type Output = Sc;
            #[inline(always)]
            fn $f(self, o: Sc) -> Sc {
                Sc(std::array::from_fn(|l| self.0[l] $op o.0[l]))
            }
        }
    };
}
sc_binop!(Add, add, +);
sc_binop!(Sub, sub, -);
sc_binop!(Mul, mul, *);
sc_binop!(Div, div, /);

impl Sc {
    #[inline(always)]
    fn mask(f: impl Fn(usize) -> bool) -> Sc {
        Sc(std::array::from_fn(|l| f32::from_bits(if f(l) { u32::MAX } else { 0 })))
    }
}

impl Lanes for Sc {
    #[inline(always)]
    fn splat(v: f32) -> Sc {
        Sc([v; GROUP])
    }
    #[inline(always)]
    fn load(a: &[f32; GROUP]) -> Sc {
        Sc(*a)
    }
    #[inline(always)]
    fn sqrt(self) -> Sc {
        Sc(self.0.map(f32::sqrt))
    }
    #[inline(always)]
    fn mul_add(self, b: Sc, c: Sc) -> Sc {
        self * b + c
    }
    #[inline(always)]
    fn max(self, o: Sc) -> Sc {
        Sc(std::array::from_fn(|l| if self.0[l] > o.0[l] { self.0[l] } else { o.0[l] }))
    }
    #[inline(always)]
    fn min(self, o: Sc) -> Sc {
        Sc(std::array::from_fn(|l| if self.0[l] < o.0[l] { self.0[l] } else { o.0[l] }))
    }
    #[inline(always)]
    fn le(self, o: Sc) -> Sc {
        Sc::mask(|l| self.0[l] <= o.0[l])
    }
    #[inline(always)]
    fn eq(self, o: Sc) -> Sc {
        Sc::mask(|l| self.0[l] == o.0[l])
    }
    #[inline(always)]
    fn gt(self, o: Sc) -> Sc {
        Sc::mask(|l| self.0[l] > o.0[l])
    }
    #[inline(always)]
    fn ne(self, o: Sc) -> Sc {
        Sc::mask(|l| self.0[l] != o.0[l])
    }
    #[inline(always)]
    fn and(self, o: Sc) -> Sc {
        Sc(std::array::from_fn(|l| f32::from_bits(self.0[l].to_bits() & o.0[l].to_bits())))
    }
    #[inline(always)]
    fn select(m: Sc, a: Sc, b: Sc) -> Sc {
        Sc(std::array::from_fn(|l| if m.0[l].to_bits() != 0 { a.0[l] } else { b.0[l] }))
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        (0..GROUP).fold(0, |b, l| b | (((self.0[l].to_bits() >> 31) & 1) << l))
    }
    #[inline(always)]
    fn rot_min(vl: Sc, fa: Sc, m: Sc, sl: Sc, theta: f64, best: &mut f64) {
        for l in 0..GROUP {
            *best = best.min(rotation_step(vl.0[l] as f64, fa.0[l] as f64 / m.0[l] as f64, theta * sl.0[l] as f64));
        }
    }
    #[inline(always)]
    fn gather3(src: &[Vec3A], idx: &[u32; GROUP]) -> [Sc; 3] {
        let r: [Vec3A; GROUP] = std::array::from_fn(|l| src[idx[l] as usize]);
        [Sc(r.map(|p| p.x)), Sc(r.map(|p| p.y)), Sc(r.map(|p| p.z))]
    }
    #[inline(always)]
    fn rows3(c: [Sc; 3]) -> [Vec3A; GROUP] {
        std::array::from_fn(|l| Vec3A::new(c[0].0[l], c[1].0[l], c[2].0[l]))
    }
}

/// AVX lanes. Values of this type are only created inside [`groups_avx2`], which runs only after
/// `is_x86_feature_detected!` confirmed AVX2 and FMA, so every intrinsic below is supported.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx(std::arch::x86_64::__m256);

#[cfg(target_arch = "x86_64")]
macro_rules! avx_binop {
    ($tr:ident, $f:ident, $intr:ident) => {
        impl $tr for Avx {
            type Output = Avx;
            #[inline(always)]
            fn $f(self, o: Avx) -> Avx {
                // SAFETY: AVX is present (see `Avx`); register-only operation.
                Avx(unsafe { std::arch::x86_64::$intr(self.0, o.0) })
            }
        }
    };
}
#[cfg(target_arch = "x86_64")]
avx_binop!(Add, add, _mm256_add_ps);
#[cfg(target_arch = "x86_64")]
avx_binop!(Sub, sub, _mm256_sub_ps);
#[cfg(target_arch = "x86_64")]
avx_binop!(Mul, mul, _mm256_mul_ps);
#[cfg(target_arch = "x86_64")]
avx_binop!(Div, div, _mm256_div_ps);

#[cfg(target_arch = "x86_64")]
impl Lanes for Avx {
    #[inline(always)]
    fn splat(v: f32) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_set1_ps(v) })
    }
    #[inline(always)]
    fn load(a: &[f32; GROUP]) -> Avx {
        // SAFETY: AVX is present (see `Avx`); `a` is eight readable floats (unaligned load).
        Avx(unsafe { std::arch::x86_64::_mm256_loadu_ps(a.as_ptr()) })
    }
    #[inline(always)]
    fn sqrt(self) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_sqrt_ps(self.0) })
    }
    #[inline(always)]
    fn mul_add(self, b: Avx, c: Avx) -> Avx {
        // SAFETY: AVX2 and FMA are present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_fmadd_ps(self.0, b.0, c.0) })
    }
    #[inline(always)]
    fn max(self, o: Avx) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_max_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn min(self, o: Avx) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_min_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn le(self, o: Avx) -> Avx {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn eq(self, o: Avx) -> Avx {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn gt(self, o: Avx) -> Avx {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn ne(self, o: Avx) -> Avx {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { _mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn and(self, o: Avx) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_and_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn select(m: Avx, a: Avx, b: Avx) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_blendv_ps(b.0, a.0, m.0) })
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        unsafe { std::arch::x86_64::_mm256_movemask_ps(self.0) as u32 }
    }
    #[inline(always)]
    fn rot_min(vl: Avx, fa: Avx, m: Avx, sl: Avx, theta: f64, best: &mut f64) {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operations, plus one store into a
        // local array of four doubles.
        unsafe {
            let (t64, two, four, zero, inf) = (
                _mm256_set1_pd(theta),
                _mm256_set1_pd(2.0),
                _mm256_set1_pd(4.0),
                _mm256_setzero_pd(),
                _mm256_set1_pd(f64::INFINITY),
            );
            let lo = |q: Avx| _mm256_cvtps_pd(_mm256_castps256_ps128(q.0));
            let hi = |q: Avx| _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(q.0));
            let mut acc = inf;
            for (v, f, mm, s) in [(lo(vl), lo(fa), lo(m), lo(sl)), (hi(vl), hi(fa), hi(m), hi(sl))] {
                let reach = _mm256_mul_pd(t64, s);
                let a = _mm256_div_pd(f, mm);
                let root =
                    _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(v, v), _mm256_mul_pd(_mm256_mul_pd(four, a), reach)));
                let h1 = _mm256_div_pd(_mm256_mul_pd(two, reach), _mm256_add_pd(v, root));
                let h2 = _mm256_blendv_pd(inf, _mm256_div_pd(reach, v), _mm256_cmp_pd::<_CMP_GT_OQ>(v, zero));
                let h = _mm256_blendv_pd(h2, h1, _mm256_cmp_pd::<_CMP_GT_OQ>(a, zero));
                let finite = _mm256_cmp_pd::<_CMP_EQ_OQ>(_mm256_sub_pd(reach, reach), zero);
                // minpd keeps the second operand when the first is NaN: NaN is ignored, as f64::min.
                acc = _mm256_min_pd(_mm256_blendv_pd(inf, h, finite), acc);
            }
            let mut lanes = [0.0f64; 4];
            _mm256_storeu_pd(lanes.as_mut_ptr(), acc);
            for q in lanes {
                *best = best.min(q);
            }
        }
    }
    #[inline(always)]
    fn gather3(src: &[Vec3A], idx: &[u32; GROUP]) -> [Avx; 3] {
        use std::arch::x86_64::*;
        let r = |l: usize| -> __m128 { src[idx[l] as usize].into() };
        let (a0, a1, a2, a3, a4, a5, a6, a7) = (r(0), r(1), r(2), r(3), r(4), r(5), r(6), r(7));
        // SAFETY: AVX is present (see `Avx`); register-only operations (a 4×4 transpose in each
        // 128-bit half: rows 0–3 low, 4–7 high).
        unsafe {
            let r0 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(a0), a4);
            let r1 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(a1), a5);
            let r2 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(a2), a6);
            let r3 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(a3), a7);
            let t0 = _mm256_unpacklo_ps(r0, r1);
            let t1 = _mm256_unpacklo_ps(r2, r3);
            let t2 = _mm256_unpackhi_ps(r0, r1);
            let t3 = _mm256_unpackhi_ps(r2, r3);
            [
                Avx(_mm256_shuffle_ps::<0x44>(t0, t1)),
                Avx(_mm256_shuffle_ps::<0xEE>(t0, t1)),
                Avx(_mm256_shuffle_ps::<0x44>(t2, t3)),
            ]
        }
    }
    #[inline(always)]
    fn rows3(c: [Avx; 3]) -> [Vec3A; GROUP] {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operations (the inverse transpose,
        // the fourth component zero).
        unsafe {
            let z = _mm256_setzero_ps();
            let t0 = _mm256_unpacklo_ps(c[0].0, c[1].0);
            let t1 = _mm256_unpackhi_ps(c[0].0, c[1].0);
            let u0 = _mm256_unpacklo_ps(c[2].0, z);
            let u1 = _mm256_unpackhi_ps(c[2].0, z);
            let (r0, r1, r2, r3) = (
                _mm256_shuffle_ps::<0x44>(t0, u0),
                _mm256_shuffle_ps::<0xEE>(t0, u0),
                _mm256_shuffle_ps::<0x44>(t1, u1),
                _mm256_shuffle_ps::<0xEE>(t1, u1),
            );
            [
                Vec3A::from(_mm256_castps256_ps128(r0)),
                Vec3A::from(_mm256_castps256_ps128(r1)),
                Vec3A::from(_mm256_castps256_ps128(r2)),
                Vec3A::from(_mm256_castps256_ps128(r3)),
                Vec3A::from(_mm256_extractf128_ps::<1>(r0)),
                Vec3A::from(_mm256_extractf128_ps::<1>(r1)),
                Vec3A::from(_mm256_extractf128_ps::<1>(r2)),
                Vec3A::from(_mm256_extractf128_ps::<1>(r3)),
            ]
        }
    }
}

/// Which update the lane-group kernel applies.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
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

/// Everything the lane-group kernel reads.
struct GroupCtx<'a> {
    model: &'a SimModel,
    fe: &'a ForceEval,
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
    /// Finish mode with the reference solver's CG rows: the new state is `v + Δv`,
    /// `x + h (v + Δv)` (in f64), computed here rather than in a pass of its own.
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

/// Three component lanes.
type V3<V> = [V; 3];

/// `[f(0), f(1), f(2)]` without a closure (closures would not inherit the kernel's target
/// features, and the intrinsics in them would not be inlined).
macro_rules! map3 {
    ($a:ident => $e:expr) => {
        [
            {
                let $a = 0;
                $e
            },
            {
                let $a = 1;
                $e
            },
            {
                let $a = 2;
                $e
            },
        ]
    };
}

/// Eight lanes of `a` from group base `base`.
#[inline(always)]
fn at<V: Lanes>(a: &[f32], base: usize) -> V {
    V::load(a[base..base + GROUP].try_into().expect("whole groups"))
}

/// A mask of the lanes whose index is not `NONE`, and the indices with `NONE` replaced by the
/// lane's own mass.
#[inline(always)]
fn present<V: Lanes>(idx: &[u32; GROUP], lanes: &[u32; GROUP]) -> (V, [u32; GROUP]) {
    let mut m = [0.0f32; GROUP];
    let mut o = *idx;
    for l in 0..GROUP {
        if idx[l] != NONE {
            m[l] = f32::from_bits(u32::MAX);
        } else {
            o[l] = lanes[l];
        }
    }
    (V::load(&m), o)
}

#[inline(always)]
fn dot3<V: Lanes>(a: &V3<V>, b: &V3<V>) -> V {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The lane-group kernel over groups `g0..`, writing masses `g0 · GROUP ..` into `xo`, `vo`
/// (whose length says how many masses). Per group: the links of its eight masses slot by slot
/// (each link's force, and for the implicit solver its Jacobian block, evaluated from the
/// mass's own side — the other end computes the exact negation), the external and restoring
/// forces, the update, the stick projection when `project`, and a finiteness check of the result.
/// With the guard on, the tips among these masses are tested (`scale`, `frozen`: their tips'
/// slots) and kicked. Returns whether every written value is finite, and the guard's outcome.
#[inline(always)]
#[allow(clippy::needless_range_loop)]
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
    let fe = c.fe;
    let (x, v, h) = (c.x, c.v, c.h);
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let (hv, h2v) = (V::splat(h), V::splat(h * h));
    let w = fe.restoring_w;
    let mut finite = true;
    let mut go = GuardOutcome::default();
    let mut rot = f64::INFINITY;
    let tip0 = m.tip_first[g0 * GROUP];
    for (gi, (xg, vg)) in xo.chunks_mut(GROUP).zip(vo.chunks_mut(GROUP)).enumerate() {
        let g = g0 + gi;
        let base = g * GROUP;
        let lanes: &[u32; GROUP] = gd.lane[base..base + GROUP].try_into().expect("whole groups");
        let real = xg.len().min(GROUP);
        if mode == Mode::Finish && !c.cg.is_empty() {
            let hd = h as f64;
            for l in 0..real {
                let k = base + l;
                let vn = (v[k].as_dvec3() + c.cg[k].x).as_vec3a();
                (xg[l], vg[l]) = ((x[k].as_dvec3() + vn.as_dvec3() * hd).as_vec3a(), vn);
            }
        }
        let (xi, vi) = if mode == Mode::Finish {
            let local = [0, 1, 2, 3, 4, 5, 6, 7].map(|l: u32| l.min(real as u32 - 1));
            (V::gather3(xg, &local), V::gather3(vg, &local))
        } else {
            (V::gather3(x, lanes), V::gather3(v, lanes))
        };
        // Links, slot by slot (adjacency order per mass).
        let mut fl = [zero; 3];
        let mut diag = [zero; 6];
        let slots = if mode == Mode::Finish { 0..0 } else { gd.start[g] as usize..gd.start[g + 1] as usize };
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
        let mass = at::<V>(&gd.mass, base);
        // External force.
        let fext: V3<V> = if mode == Mode::Finish {
            [zero; 3]
        } else if fe.uniform_only() {
            [V::splat(fe.accel.x) * mass, V::splat(fe.accel.y) * mass, V::splat(fe.accel.z) * mass]
        } else {
            let mut a = [[0.0f32; GROUP]; 3];
            for l in 0..real {
                let k = base + l;
                let f = fe.external(m.mass[k], x[k], v[k], m.rest[k]);
                (a[0][l], a[1][l], a[2][l]) = (f.x, f.y, f.z);
            }
            map3!(c => V::load(&a[c]))
        };
        // Restoring force (eq. 3.37) and its stiffness 2w/L.
        let rp: &[u32; GROUP] = gd.rest_parent[base..base + GROUP].try_into().expect("whole groups");
        let (mut fr, mut kr) = ([zero; 3], zero);
        let mut vrp = [zero; 3];
        if mode != Mode::Finish && w != 0.0 && rp.iter().any(|&p| p != NONE) {
            let (has, rpi) = present::<V>(rp, lanes);
            let xr = V::gather3(x, &rpi);
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
                vrp = V::gather3(v, &rpi);
            }
        }
        let f: V3<V> = map3!(a => (fext[a] + fr[a]) + fl[a]);
        let mut vn: V3<V> = match mode {
            Mode::Finish => vi,
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
                    let (has, pi) = present::<V>(pa, lanes);
                    let vp = V::gather3(v, &pi);
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
                let md = mass + h2v * kr;
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
        };
        let mut xn: V3<V> = if mode == Mode::Finish { xi } else { map3!(a => xi[a] + vn[a] * hv) };
        // Stick projection onto anchored parents (as `project_sticks`); a mass sitting exactly on
        // its parent takes the scalar fallback below.
        let mut fallback = 0u32;
        let (pre_x, pre_v) = (xn, vn);
        if c.project {
            let pa: &[u32; GROUP] = gd.parent[base..base + GROUP].try_into().expect("whole groups");
            if pa.iter().any(|&p| p != NONE) {
                let (has, pi) = present::<V>(pa, lanes);
                let xp = V::gather3(&m.rest, &pi);
                let e = map3!(a => xn[a] - xp[a]);
                let rcp = one / dot3(&e, &e).sqrt();
                let ok = rcp.finite().and(rcp.gt(zero));
                fallback = has.bits() & !ok.bits();
                let dir = map3!(a => e[a] * rcp);
                let pl = at::<V>(&gd.parent_len, base);
                let rel = map3!(a => vn[a] - zero);
                let along = dot3(&rel, &dir);
                for a in 0..3 {
                    xn[a] = V::select(has, xp[a] + dir[a] * pl, xn[a]);
                    vn[a] = V::select(has, vn[a] - dir[a] * along, vn[a]);
                }
            }
        }
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
        // The wrong-side guard (as `GuardState::apply`): n·s ≥ cos α with s the unit root→tip
        // direction (eq. 3.35); a fresh failure freezes the scale vector and kicks the tip.
        let tr: &[u32; GROUP] = gd.tip_root[base..base + GROUP].try_into().expect("whole groups");
        if let Some(gc) = c.guard
            && tr[..real].iter().any(|&r| r != NONE)
        {
            let (_, ri) = present::<V>(tr, lanes);
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
        xg.copy_from_slice(&xr[..real]);
        vg.copy_from_slice(&vr[..real]);
        if let Some(theta) = c.rotation {
            // The next step's rotation limit (as `rotation_limit_of`, on the final velocities).
            let vf = V::gather3(vg, &[0, 1, 2, 3, 4, 5, 6, 7].map(|l: u32| l.min(real as u32 - 1)));
            let vl = dot3(&vf, &vf).sqrt();
            let f = map3!(a => V::splat(fe.accel[a]) * mass);
            let fa = dot3(&f, &f).sqrt() + V::splat(4.0 * w);
            V::rot_min(vl, fa, mass, at::<V>(&gd.shortest_link, base), theta, &mut rot);
        }
    }
    if c.guard.is_some() {
        go.frozen = frozen.iter().filter(|&&f| f).count() as u32;
    }
    ChunkOutcome { finite, guard: go, rotation: rot }
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

/// One free mass's rotation-limited step (see `Simulator::rotation_limited_step_s`): the `h` with
/// `|v| h + |a| h² = θ · shortest link`, `a` the external and restoring acceleration, in f64.
#[inline]
fn rotation_limit_of(model: &SimModel, fe: &ForceEval, theta: f64, x: &[Vec3A], v: &[Vec3A], k: usize) -> f64 {
    let reach = theta * model.shortest_link[k] as f64;
    if !reach.is_finite() {
        return f64::INFINITY;
    }
    let f = external(model, fe, k, x[k], v[k]);
    let a = (f.length() + 4.0 * fe.restoring_w) as f64 / model.mass[k] as f64;
    rotation_step(v[k].length() as f64, a, reach)
}

/// The `h` with `v h + a h² = reach` (speed `v`, acceleration `a`, finite `reach`).
#[inline(always)]
fn rotation_step(v: f64, a: f64, reach: f64) -> f64 {
    if !reach.is_finite() {
        f64::INFINITY
    } else if a > 0.0 {
        2.0 * reach / (v + (v * v + 4.0 * a * reach).sqrt())
    } else if v > 0.0 {
        reach / v
    } else {
        f64::INFINITY
    }
}

/// The smallest [`rotation_limit_of`] over the masses `k0..k1` with only uniform forces, eight
/// masses at a time: the f32 parts (speeds, force magnitudes) in AVX lanes, the f64 parts four
/// lanes at a time — the same IEEE operations as [`rotation_limit_of`], so the same result.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn rotation_chunk_avx2(
    model: &SimModel,
    fe: &ForceEval,
    theta: f64,
    x: &[Vec3A],
    v: &[Vec3A],
    k0: usize,
    k1: usize,
) -> f64 {
    use std::arch::x86_64::*;
    let wv = Avx::splat(4.0 * fe.restoring_w);
    let acc = [Avx::splat(fe.accel.x), Avx::splat(fe.accel.y), Avx::splat(fe.accel.z)];
    let (t64, two, four, zero, inf) = (
        _mm256_set1_pd(theta),
        _mm256_set1_pd(2.0),
        _mm256_set1_pd(4.0),
        _mm256_setzero_pd(),
        _mm256_set1_pd(f64::INFINITY),
    );
    let mut best = inf;
    let mut k = k0;
    while k + GROUP <= k1 {
        let idx: [u32; GROUP] = std::array::from_fn(|l| (k + l) as u32);
        let vv = Avx::gather3(v, &idx);
        let vl = dot3(&vv, &vv).sqrt();
        let m32 = Avx::load(model.mass[k..k + GROUP].try_into().expect("eight masses"));
        let sl = Avx::load(model.shortest_link[k..k + GROUP].try_into().expect("eight masses"));
        let f = map3!(a => acc[a] * m32);
        let fa = dot3(&f, &f).sqrt() + wv;
        let halves =
            |q: Avx| [_mm256_cvtps_pd(_mm256_castps256_ps128(q.0)), _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(q.0))];
        let (vh, fh, mh, sh) = (halves(vl), halves(fa), halves(m32), halves(sl));
        for i in 0..2 {
            let (v, reach) = (vh[i], _mm256_mul_pd(t64, sh[i]));
            let a = _mm256_div_pd(fh[i], mh[i]);
            let root = _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(v, v), _mm256_mul_pd(_mm256_mul_pd(four, a), reach)));
            let h1 = _mm256_div_pd(_mm256_mul_pd(two, reach), _mm256_add_pd(v, root));
            let h2 = _mm256_div_pd(reach, v);
            let h2 = _mm256_blendv_pd(inf, h2, _mm256_cmp_pd::<_CMP_GT_OQ>(v, zero));
            let h = _mm256_blendv_pd(h2, h1, _mm256_cmp_pd::<_CMP_GT_OQ>(a, zero));
            let finite = _mm256_cmp_pd::<_CMP_EQ_OQ>(_mm256_sub_pd(reach, reach), zero);
            let h = _mm256_blendv_pd(inf, h, finite);
            // minpd keeps the second operand when the first is NaN: NaN is ignored, as f64::min.
            best = _mm256_min_pd(h, best);
        }
        k += GROUP;
    }
    let mut lanes = [0.0f64; 4];
    // SAFETY: `lanes` is four writable doubles (unaligned store); AVX is enabled here.
    unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), best) };
    let mut out = lanes.iter().fold(f64::INFINITY, |a, &b| a.min(b));
    for kk in k..k1 {
        out = out.min(rotation_limit_of(model, fe, theta, x, v, kk));
    }
    out
}

/// The implicit solvers' rotation-limited step: the smallest [`rotation_limit_of`] over the free
/// masses (f64::min, so NaN is ignored), in fixed chunks.
pub(crate) fn rotation_limit(model: &SimModel, fe: &ForceEval, theta: f64, x: &[Vec3A], v: &[Vec3A]) -> f64 {
    let nf = model.n_free;
    let chunk = |c: usize| -> f64 {
        let (k0, k1) = (c * CHUNK, ((c + 1) * CHUNK).min(nf));
        #[cfg(target_arch = "x86_64")]
        if fe.uniform_only() && std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports AVX2 and FMA (detected just above).
            return unsafe { rotation_chunk_avx2(model, fe, theta, x, v, k0, k1) };
        }
        (k0..k1).map(|k| rotation_limit_of(model, fe, theta, x, v, k)).fold(f64::INFINITY, f64::min)
    };
    let chunks = nf.div_ceil(CHUNK);
    if nf < PARALLEL_MIN {
        (0..chunks).map(chunk).fold(f64::INFINITY, f64::min)
    } else {
        (0..chunks).into_par_iter().map(chunk).reduce(|| f64::INFINITY, f64::min)
    }
}
