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
//!   diagonal dominate the system matrix so every sweep count is stable.
//! - **Stick** (§3.4.1, "orientation only"): every link from an anchored root is a rigid stick;
//!   external and remaining spring forces move the mass explicitly, the parent link's damping is
//!   implicit, then the mass is put back at the stick's length from its parent (level by level
//!   from the skin) and its velocity along the stick is removed.
//! - **Reference** (Baraff & Witkin 1998): the same linearised backward-Euler system without the
//!   diagonal trick, in f64, solved by block-Jacobi-preconditioned conjugate gradient to a tight
//!   relative residual. Used to measure everyone else's error.
//!
//! Sticks in the mass–spring solvers are projected after the step the same way.
//! Every kernel computes each free mass from a gather over its own links, in a fixed order, so the
//! result is identical for any thread count; sums (CG dot products) use fixed-size chunks.

use glam::{DMat3, DVec3, Vec3A};
use rayon::prelude::*;

use crate::forces::{ForceEval, restoring_force};
use crate::model::{NONE, SimModel};

/// Masses per parallel work item; also the fixed chunk of deterministic sums.
pub(crate) const CHUNK: usize = 1024;
/// Below this many free masses the kernels run on the calling thread.
const PARALLEL_MIN: usize = 4096;

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

/// Hooke + viscosity force on the mass at `xi` (velocity `vi`) from a link to `xj`, `vj`.
#[inline(always)]
fn link_force(xi: Vec3A, vi: Vec3A, xj: Vec3A, vj: Vec3A, rest: f32, k: f32, c: f32) -> Vec3A {
    let d = xj - xi;
    let l = d.length();
    // |d · (1 − rest/l)| = |l − rest| stays bounded as l → 0, and d = 0 gives 0: no NaN.
    d * (k * (1.0 - rest / l.max(1e-20))) + (vj - vi) * c
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

/// Total force on free mass `k` at state `(x, v)`: external, links, restoring.
#[inline(always)]
pub(crate) fn total_force(model: &SimModel, fe: &ForceEval, x: &[Vec3A], v: &[Vec3A], k: usize) -> Vec3A {
    let (xi, vi) = (x[k], v[k]);
    let mut f = external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi);
    for a in model.adj_of(k) {
        let j = a.other as usize;
        f += link_force(xi, vi, x[j], v[j], a.rest, a.k, a.c);
    }
    f
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

/// One explicit Euler step (eq. 3.20–3.25).
pub(crate) fn explicit_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    x: &[Vec3A],
    v: &[Vec3A],
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
) {
    for_free(model.n_free, x_out, v_out, |k| {
        let f = total_force(model, fe, x, v, k);
        let vn = v[k] + f * (h * model.inv_mass[k]);
        (x[k] + vn * h, vn)
    });
    project_sticks(model, x_out, v_out);
}

/// One stick-solver step: explicit forces, implicit parent damping, then projection.
pub(crate) fn stick_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    x: &[Vec3A],
    v: &[Vec3A],
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
) {
    for_free(model.n_free, x_out, v_out, |k| {
        let f = total_force(model, fe, x, v, k);
        let a = h * model.inv_mass[k];
        let p = model.parent[k];
        let vn = if p == NONE {
            v[k] + f * a
        } else {
            let ac = a * model.parent_c[k];
            (v[k] + f * a + v[p as usize] * ac) / (1.0 + ac)
        };
        (x[k] + vn * h, vn)
    });
    project_sticks(model, x_out, v_out);
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
            let dir =
                (*xo - xp).try_normalize().unwrap_or_else(|| (model.rest[k] - model.rest[p]).normalize_or(Vec3A::Y));
            *xo = xp + dir * model.parent_len[k];
            let rel = *vo - vp;
            *vo -= dir * rel.dot(dir);
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

/// Per-step scratch of the implicit solver (kept between steps to avoid reallocating).
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
}

fn sym_to_dmat(m: &Sym3) -> DMat3 {
    let q = m.0.map(|c| c as f64);
    DMat3::from_cols_array(&[q[0], q[3], q[4], q[3], q[1], q[5], q[4], q[5], q[2]])
}

/// One implicit Euler step (eq. 3.26–3.34) with `iterations` sweeps.
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
    scratch: &mut ImplicitScratch,
    x: &[Vec3A],
    v: &[Vec3A],
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
) {
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
    if iterations <= 1 && !model.has_tree() {
        for_free(nf, x_out, v_out, |k| {
            let (b, diag) = assemble(k, None);
            let vn = v[k] + diag.solve(b);
            (x[k] + vn * h, vn)
        });
        project_sticks(model, x_out, v_out);
        return;
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
    project_sticks(model, x_out, v_out);
}

/// Scratch of the converged reference solver (f64).
#[derive(Default)]
pub(crate) struct ReferenceScratch {
    b: Vec<DVec3>,
    pinv: Vec<[f64; 9]>,
    blocks: Vec<[f64; 6]>,
    kr: Vec<f64>,
    xs: Vec<DVec3>,
    r: Vec<DVec3>,
    z: Vec<DVec3>,
    p: Vec<DVec3>,
    ap: Vec<DVec3>,
}

fn sym_mul64(m: &[f64; 6], v: DVec3) -> DVec3 {
    DVec3::new(
        m[0] * v.x + m[3] * v.y + m[4] * v.z,
        m[3] * v.x + m[1] * v.y + m[5] * v.z,
        m[4] * v.x + m[5] * v.y + m[2] * v.z,
    )
}

fn par_fill<T: Send, F: Fn(usize) -> T + Sync>(out: &mut [T], f: F) {
    if out.len() < PARALLEL_MIN {
        for (k, o) in out.iter_mut().enumerate() {
            *o = f(k);
        }
    } else {
        out.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(k, o)| *o = f(k));
    }
}

/// One converged backward-Euler step: PCG on the linearised system to relative residual `tol`.
/// Returns the CG iterations used and the relative residual reached.
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
) -> (u32, f64) {
    let nf = model.n_free;
    let hd = h as f64;
    let h2 = hd * hd;
    s.blocks.resize(model.adj.len(), [0.0; 6]);
    s.b.resize(nf, DVec3::ZERO);
    s.pinv.resize(nf, [0.0; 9]);
    s.kr.resize(nf, 0.0);
    for k in 0..nf {
        s.kr[k] = model.restoring_stiffness(k, fe.restoring_w) as f64;
    }
    // Assembly (sequential over links is cheap next to the CG iterations; keeps it simple).
    for k in 0..nf {
        let (xi, vi) = (x[k], v[k]);
        let mut f = (external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi)).as_dvec3();
        let mut kv = DVec3::ZERO;
        if s.kr[k] > 0.0 {
            kv -= (vi - v[model.rest_parent[k] as usize]).as_dvec3() * s.kr[k];
        }
        let md = model.mass[k] as f64 + h2 * s.kr[k];
        let mut diag = [md, md, md, 0.0, 0.0, 0.0];
        let base = model.adj_start[k] as usize;
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
            s.blocks[base + e] = hb;
        }
        s.b[k] = (f + kv * hd) * hd;
        // Block-Jacobi preconditioner: the inverse of the diagonal block.
        let (a, ee, i, bb, c, ff) = (diag[0], diag[1], diag[2], diag[3], diag[4], diag[5]);
        let (c00, c01, c02) = (ee * i - ff * ff, c * ff - bb * i, bb * ff - c * ee);
        let (c11, c12, c22) = (a * i - c * c, bb * c - a * ff, a * ee - bb * bb);
        let det = a * c00 + bb * c01 + c * c02;
        let r = if det > 0.0 && det.is_finite() { 1.0 / det } else { 0.0 };
        s.pinv[k] = [c00 * r, c01 * r, c02 * r, c01 * r, c11 * r, c12 * r, c02 * r, c12 * r, c22 * r];
    }
    let apply_a = |xs: &[DVec3], k: usize| -> DVec3 {
        let mut y = xs[k] * (model.mass[k] as f64 + h2 * s.kr[k]);
        let base = model.adj_start[k] as usize;
        for (e, a) in model.adj_of(k).iter().enumerate() {
            let j = a.other as usize;
            let xj = if j < nf { xs[j] } else { DVec3::ZERO };
            y += sym_mul64(&s.blocks[base + e], xs[k] - xj);
        }
        y
    };
    let precond = |pinv: &[f64; 9], r: DVec3| {
        DVec3::new(
            pinv[0] * r.x + pinv[1] * r.y + pinv[2] * r.z,
            pinv[3] * r.x + pinv[4] * r.y + pinv[5] * r.z,
            pinv[6] * r.x + pinv[7] * r.y + pinv[8] * r.z,
        )
    };
    s.xs.clear();
    s.xs.resize(nf, DVec3::ZERO);
    s.r.clone_from(&s.b);
    s.z.resize(nf, DVec3::ZERO);
    s.p.resize(nf, DVec3::ZERO);
    s.ap.resize(nf, DVec3::ZERO);
    let bnorm = sum_over(nf, |k| s.b[k].length_squared()).sqrt();
    let mut iterations = 0;
    let mut rel = 0.0;
    if bnorm > 0.0 {
        {
            let (r, pinv) = (&s.r, &s.pinv);
            par_fill(&mut s.z, |k| precond(&pinv[k], r[k]));
        }
        s.p.clone_from(&s.z);
        let mut rz = sum_over(nf, |k| s.r[k].dot(s.z[k]));
        loop {
            rel = sum_over(nf, |k| s.r[k].length_squared()).sqrt() / bnorm;
            if rel <= tol || iterations >= max_iterations {
                break;
            }
            iterations += 1;
            {
                let p = &s.p;
                par_fill(&mut s.ap, |k| apply_a(p, k));
            }
            let pap = sum_over(nf, |k| s.p[k].dot(s.ap[k]));
            if pap.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                break;
            }
            let alpha = rz / pap;
            for k in 0..nf {
                s.xs[k] += s.p[k] * alpha;
                s.r[k] -= s.ap[k] * alpha;
            }
            {
                let (r, pinv) = (&s.r, &s.pinv);
                par_fill(&mut s.z, |k| precond(&pinv[k], r[k]));
            }
            let rz_new = sum_over(nf, |k| s.r[k].dot(s.z[k]));
            let beta = rz_new / rz;
            rz = rz_new;
            for k in 0..nf {
                s.p[k] = s.z[k] + s.p[k] * beta;
            }
        }
    }
    let dv = &s.xs;
    for_free(nf, x_out, v_out, |k| {
        let vn = (v[k].as_dvec3() + dv[k]).as_vec3a();
        ((x[k].as_dvec3() + vn.as_dvec3() * hd).as_vec3a(), vn)
    });
    project_sticks(model, x_out, v_out);
    (iterations, rel)
}
