//! The implicit mass–spring solver (fur thesis §3.3.2, eq. 3.26–3.34): the linearised
//! backward-Euler system `A Δv = b`, `A = M − h ∂F/∂v − h² ∂F/∂x`, `b = h (F + h ∂F/∂x v)`.
//! One iteration is the thesis's first iterate of eq. 3.34: one sweep `Δv = P⁻¹ b` with the
//! splitting `P` below. Two or more run preconditioned conjugate gradient on the same system
//! with `P` as preconditioner, started from that sweep: `A` and `P` are symmetric positive
//! definite, so every iteration lowers the `A`-norm of the error (from at most the sweep's) and
//! 32 iterations reach backward Euler with this Jacobian (`tests/convergence.rs`). Each CG
//! iteration costs what a sweep costs (one product with `A`, one solve with `P`) plus two dot
//! products; Jacobi-like sweeps (`Δv += P⁻¹ (b − A Δv)`) also converge, but only as fast as
//! `P⁻¹A`'s smallest eigenvalue allows (on the stiff net at 1/30 s eight sweeps are still
//! 9e-4 m from backward Euler after one second; eight CG iterations 9e-5 m).
//!
//! Two deliberate changes, both needed for stability at large steps: the full 3×3 spring Jacobian
//! of eq. 3.29 is used with the transverse term clamped at zero under compression (so `A` stays
//! positive definite; on the stiff net this moves the one-second trajectory by 1e-4 m at 1/30 s
//! and 3e-6 m at 1/3000 s from backward Euler with the exact Jacobian), and the mass's
//! own Jacobian blocks are moved to the left-hand side (eq. 3.34 as printed keeps only `M` there
//! and diverges once `h²k/m > 1`) — a link between two free masses counts twice on the diagonal
//! of `P`, so `P ≥ A` and the sweep is stable. The restoring force of eq. 3.37 enters the one
//! sweep as the isotropic stiffness `2w/L` (`SimModel::restoring_stiffness`), which damps fur
//! that the exact Jacobian (zero at rest) leaves free: two or more iterations take the exact
//! Jacobian's symmetric positive part instead ([`exact_restoring`]; with `2w/L`, 64 iterations
//! stayed 3.6e-3 m from the reference on the grass patch after 30 steps of 1/60 s, now 32 are
//! within 2.3e-7 m of it after one second at 1/30 s). Where the free masses fall into small
//! independent clusters (separable prisms: three tips each) the system (with `2w/L`) is solved
//! exactly per cluster instead (`clusters.rs`): truncated sweeps there pump energy into a
//! spinning stiff cluster. One sweep without hair trees or clusters runs in the fused lane-group pass
//! (`fused.rs`).

use glam::{DMat3, DVec3, Vec3A};
use rayon::prelude::*;

use super::chunks::{CHUNK, PARALLEL_MIN, chunk_sum, for_free};
use super::fused::{Mode, finish_step, group_step};
use super::{Step, StepOutcome};
use super::{external, restoring};
use crate::clusters::{ClusterSystem, Clusters, MAX_CLUSTER};
use crate::forces::{restoring_force_f64, restoring_stiffness_spd};
use crate::model::SimModel;
use crate::sentinel::NONE;

/// Symmetric 3×3 matrix `[xx, yy, zz, xy, xz, yz]`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Sym3(pub [f32; 6]);

impl Sym3 {
    #[inline(always)]
    pub(super) fn scaled_identity(s: f32) -> Sym3 {
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

/// Hooke + viscosity force on mass i from a link (as the fused pass computes it) and the link's
/// stiffness block `Kp = k (β I + (1 − β) d̂d̂ᵀ)` (eq. 3.29 with the transverse term `β = 1 − rest/l`
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
    /// Per free mass the right-hand side `h (F + h ∂F/∂x v)`.
    b: Vec<Vec3A>,
    /// Per free mass the diagonal block of the sweeps' matrix `P`.
    diag: Vec<Sym3>,
    /// Per adjacency entry the link's `h c I + h² Kp` block.
    blocks: Vec<Sym3>,
    /// The solution `Δv` so far.
    dv: Vec<Vec3A>,
    /// The one sweep's right-hand side (`b`: the sweep starts from `Δv = 0`).
    res: Vec<Vec3A>,
    /// Per free mass the inverse of its block of `P` factored along the hair trees.
    dinv: Vec<DMat3>,
    /// The tree solve's forward (`rp`) and backward (`z`) vectors.
    rp: Vec<DVec3>,
    z: Vec<DVec3>,
    /// Per small cluster, its masses' `Δv` by slot (see `clusters`).
    cluster_dv: Vec<[Vec3A; MAX_CLUSTER]>,
    /// Preconditioned CG (two or more iterations): per free mass the solution and residual,
    /// the preconditioned residual, the search direction and `A p`; per chunk partial sums.
    xr: Vec<[DVec3; 2]>,
    zc: Vec<DVec3>,
    pq: Vec<[DVec3; 2]>,
    sums: Vec<[f64; 1]>,
    /// Per free mass `h²` times the restoring stiffness of [`exact_restoring`].
    rself: Vec<Sym3>,
    /// The previous iteration's `r·z`.
    rz_prev: f64,
}

fn sym_to_dmat(m: &Sym3) -> DMat3 {
    let q = m.0.map(|c| c as f64);
    DMat3::from_cols_array(&[q[0], q[3], q[4], q[3], q[1], q[5], q[4], q[5], q[2]])
}

/// One implicit Euler step (eq. 3.26–3.34) with `iterations` sweeps, or the exact per-cluster
/// solve when `clusters` is given. Runs the step's guard in the same pass where it can.
///
/// Each sweep solves `P z = b − A Δv` and adds `z` to `Δv`, where `P` keeps the exact couplings
/// along each hair (a free mass and its free parent, solved by elimination from the tips down
/// to the roots and back) and replaces every other link between free masses by twice its block
/// on the diagonal (`P ≥ A`, so the sweeps converge and the step stays stable). For the two-mass
/// topologies there is nothing to eliminate and one sweep is one 3×3 solve per mass.
pub(crate) fn implicit_step(
    mut step: Step,
    iterations: u32,
    clusters: Option<&Clusters>,
    scratch: &mut ImplicitScratch,
) -> StepOutcome {
    let model = step.model;
    if iterations <= 1 && !model.has_tree() && clusters.is_none() {
        // One sweep without trees: per mass its links' forces and blocks, one 3×3 solve.
        return group_step(step, Mode::Implicit, &[]);
    }
    assemble_system(&step, scratch);
    match clusters {
        // Small independent clusters: the exact solve (see `clusters`), whatever the sweep count.
        Some(cl) => solve_clusters(&step, cl, scratch),
        // Two or more iterations: preconditioned CG from the one-sweep result.
        None if iterations >= 2 => {
            exact_restoring(&step, scratch);
            if model.has_tree() {
                factor_trees(model, scratch);
            } else {
                invert_diagonal(model, scratch);
            }
            solve_pcg(&step, iterations, scratch);
        }
        // One sweep from Δv = 0: the residual is b.
        None if model.has_tree() => {
            factor_trees(model, scratch);
            scratch.res.copy_from_slice(&scratch.b);
            sweep_trees(model, scratch);
        }
        None => {
            scratch.res.copy_from_slice(&scratch.b);
            sweep_diagonal(model, scratch);
        }
    }
    advance(&mut step, &scratch.dv);
    finish_step(step)
}

/// Free mass `k`'s right-hand side `b_k`, its diagonal block of `P` and (into `blocks`, its
/// adjacency's slice) every link's `h c I + h² Kp` block.
#[inline]
fn assemble_mass(step: &Step, k: usize, blocks: &mut [Sym3]) -> (Vec3A, Sym3) {
    let (model, fe, h, x, v) = (step.model, step.fe, step.h, step.x, step.v);
    let h2 = h * h;
    let (xi, vi) = (x[k], v[k]);
    let mut f = external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi);
    let mut kv = Vec3A::ZERO;
    let kr = model.restoring_stiffness(k, fe.restoring_w);
    let mut diag = Sym3::scaled_identity(model.mass[k] + h2 * kr);
    if kr > 0.0 {
        kv -= (vi - v[model.rest_parent[k] as usize]) * kr;
    }
    let base = model.adj_start[k] as usize;
    for (e, a) in model.adj_of(k).iter().enumerate() {
        let j = a.other as usize;
        let dv = v[j] - vi;
        let (fl, kp) = force_and_block(x[j] - xi, dv, a.rest, a.k, a.c);
        f += fl;
        kv += kp.mul(dv);
        let mut hb = Sym3::scaled_identity(h * a.c);
        hb.add_scaled(&kp, h2);
        diag.add_scaled(&hb, model.adj_weight[base + e]);
        blocks[e] = hb;
    }
    ((f + kv * h) * h, diag)
}

/// Sizes the scratch for the step and assembles every free mass's right-hand side, diagonal block
/// and link blocks ([`assemble_mass`]); `Δv = 0`.
fn assemble_system(step: &Step, s: &mut ImplicitScratch) {
    let model = step.model;
    let nf = model.n_free;
    s.b.resize(nf, Vec3A::ZERO);
    s.diag.resize(nf, Sym3::default());
    s.blocks.resize(model.adj.len(), Sym3::default());
    s.dv.clear();
    s.dv.resize(nf, Vec3A::ZERO);
    s.res.resize(nf, Vec3A::ZERO);
    let mut block_slices: Vec<&mut [Sym3]> = Vec::with_capacity(nf);
    let mut rest = s.blocks.as_mut_slice();
    for k in 0..nf {
        let len = (model.adj_start[k + 1] - model.adj_start[k]) as usize;
        let (head, tail) = rest.split_at_mut(len);
        block_slices.push(head);
        rest = tail;
    }
    let work = |(k, ((b, d), bl)): (usize, ((&mut Vec3A, &mut Sym3), &mut &mut [Sym3]))| {
        let (bb, dd) = assemble_mass(step, k, bl);
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

/// `Δv` by the exact solve of every small independent cluster (see `clusters`).
fn solve_clusters(step: &Step, cl: &Clusters, s: &mut ImplicitScratch) {
    let (model, h, restoring_w) = (step.model, step.h, step.fe.restoring_w);
    let nf = model.n_free;
    s.cluster_dv.resize(cl.len(), [Vec3A::ZERO; MAX_CLUSTER]);
    let system = ClusterSystem { model, clusters: cl, h, restoring_w, blocks: &s.blocks, b: &s.b };
    let out = &mut s.cluster_dv;
    let solve = |(c, o): (usize, &mut [Vec3A; MAX_CLUSTER])| *o = system.solve(c);
    if nf < PARALLEL_MIN {
        out.iter_mut().enumerate().for_each(solve);
    } else {
        out.par_iter_mut().enumerate().with_min_len(CHUNK / 4).for_each(solve);
    }
    for k in 0..nf {
        s.dv[k] = out[cl.index_of(k)][cl.slot[k] as usize];
    }
}

/// Factors `P` along the hair trees, deepest level first: `D'_k = D_k − Σ_c H_c D'_c⁻¹ H_c`
/// (into `dinv`, the inverses), and sizes the tree solve's vectors.
fn factor_trees(model: &SimModel, s: &mut ImplicitScratch) {
    let nf = model.n_free;
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

/// `dinv` = the inverses of `P`'s diagonal blocks (no hair trees: `P` is block diagonal), for
/// the preconditioned CG.
fn invert_diagonal(model: &SimModel, s: &mut ImplicitScratch) {
    s.dinv.resize(model.n_free, DMat3::ZERO);
    let invert = |(k, o): (usize, &mut DMat3)| {
        let d = sym_to_dmat(&s.diag[k]);
        *o = if d.determinant() > 0.0 { d.inverse() } else { DMat3::NAN };
    };
    if model.n_free < PARALLEL_MIN {
        s.dinv.iter_mut().enumerate().for_each(invert);
    } else {
        s.dinv.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(invert);
    }
}

/// For two or more iterations: the restoring force's stiffness from its exact Jacobian `J`
/// instead of the isotropic `2w/L` of the sweep — its symmetric positive semi-definite part
/// (`forces::restoring_stiffness_spd`, all but a term of third order in the deflection) on the
/// diagonal (into `rself` and `P`'s diagonal), and the exact `J (v_k − v_root)` in the right-hand
/// side. The coupling to the root (`J` is one-sided: the root feels no reaction) is left out of
/// `A`, which keeps it symmetric.
fn exact_restoring(step: &Step, s: &mut ImplicitScratch) {
    let (model, fe, x, v) = (step.model, step.fe, step.x, step.v);
    let (nf, w) = (model.n_free, fe.restoring_w);
    let h2 = (step.h as f64).powi(2);
    s.rself.resize(nf, Sym3::default());
    let work = |(k, ((b, d), r)): (usize, ((&mut Vec3A, &mut Sym3), &mut Sym3))| {
        let p = model.rest_parent[k];
        if p == NONE || w == 0.0 {
            *r = Sym3::default();
            return;
        }
        let p = p as usize;
        let (xp, xk, n) = (x[p].as_dvec3(), x[k].as_dvec3(), model.rest_n[k].as_dvec3());
        let (_, j) = restoring_force_f64(xp, xk, n, w as f64);
        let kspd = restoring_stiffness_spd(xp, xk, n, w as f64);
        let kr = model.restoring_stiffness(k, w) as f64;
        let dv = (v[k] - v[p]).as_dvec3();
        // b = h (F + h ∂F/∂x v): swap the sweep's −kr (v_k − v_root) for J (v_k − v_root).
        *b += ((j * dv + dv * kr) * h2).as_vec3a();
        let hk = kspd * h2;
        *r = Sym3([hk.x_axis.x, hk.y_axis.y, hk.z_axis.z, hk.y_axis.x, hk.z_axis.x, hk.z_axis.y].map(|c| c as f32));
        d.add_scaled(r, 1.0);
        d.add_scaled(&Sym3::scaled_identity((h2 * kr) as f32), -1.0);
    };
    if nf < PARALLEL_MIN {
        s.b.iter_mut().zip(s.diag.iter_mut()).zip(s.rself.iter_mut()).enumerate().for_each(work);
    } else {
        s.b.par_iter_mut()
            .zip(s.diag.par_iter_mut())
            .zip(s.rself.par_iter_mut())
            .enumerate()
            .with_min_len(CHUNK)
            .for_each(work);
    }
}

/// Row `k` of `A y` in f64 (two or more iterations): the mass's own block (mass and the
/// restoring stiffness of [`exact_restoring`]) times `y_k` plus every link's block times
/// `y_k − y_j` (`y_j = 0` for anchored masses).
#[inline]
fn apply_a(step: &Step, blocks: &[Sym3], rself: &[Sym3], y: impl Fn(usize) -> DVec3, k: usize) -> DVec3 {
    let model = step.model;
    let nf = model.n_free;
    let yk = y(k);
    let mut ay = yk * model.mass[k] as f64 + sym_to_dmat(&rself[k]) * yk;
    let base = model.adj_start[k] as usize;
    for (e, a) in model.adj_of(k).iter().enumerate() {
        let j = a.other as usize;
        let yj = if j < nf { y(j) } else { DVec3::ZERO };
        ay += sym_to_dmat(&blocks[base + e]) * (yk - yj);
    }
    ay
}

/// `z = P⁻¹ r` (`r` = the residual column of `xr`) with `P` factored along the hair trees
/// ([`factor_trees`]) or block diagonal ([`invert_diagonal`]); returns `r·z` (summed in a fixed
/// order: chunk partial sums, or serially along the trees).
fn precondition(model: &SimModel, s: &mut ImplicitScratch) -> f64 {
    let (dinv, xr) = (&s.dinv, &s.xr);
    if !model.has_tree() {
        return chunk_sum(&mut s.zc, &mut s.sums, |c, zs| {
            let mut acc = 0.0;
            for (o, z) in zs.iter_mut().enumerate() {
                let k = c * CHUNK + o;
                *z = dinv[k] * xr[k][1];
                acc += xr[k][1].dot(*z);
            }
            [acc]
        })[0];
    }
    for (rp, row) in s.rp.iter_mut().zip(xr) {
        *rp = row[1];
    }
    tree_solve(model, dinv, &s.blocks, &mut s.rp, &mut s.zc);
    xr.iter().zip(&s.zc).map(|(row, z)| row[1].dot(*z)).sum()
}

/// `z = P⁻¹ r` with `P` factored along the hair trees ([`factor_trees`], inverses `dinv`): `rp`
/// holds `r` and is overwritten by the elimination from the tips down to the roots; `z` gets the
/// substitution back up.
// The levels are index ranges over several per-mass arrays at once.
#[allow(clippy::needless_range_loop)]
fn tree_solve(model: &SimModel, dinv: &[DMat3], blocks: &[Sym3], rp: &mut [DVec3], z: &mut [DVec3]) {
    for &(ls, le) in model.levels.iter().rev() {
        for k in ls..le {
            let (cs, ce) = (model.tree_children_start[k] as usize, model.tree_children_start[k + 1] as usize);
            for &c in &model.tree_children[cs..ce] {
                let c = c as usize;
                let hc = sym_to_dmat(&blocks[model.tree_parent_adj[c] as usize]);
                let add = hc * (dinv[c] * rp[c]);
                rp[k] += add;
            }
        }
    }
    for &(ls, le) in &model.levels {
        for k in ls..le {
            let mut t = rp[k];
            let p = model.tree_parent[k];
            if p != NONE {
                t += sym_to_dmat(&blocks[model.tree_parent_adj[k] as usize]) * z[p as usize];
            }
            z[k] = dinv[k] * t;
        }
    }
}

/// Preconditioned conjugate gradient on `A Δv = b` (the sweeps' system) with the sweeps' `P`
/// as preconditioner, from the one-sweep result `Δv₀ = P⁻¹ b`, for `iterations − 1` iterations
/// (so `iterations` products with `P⁻¹` and with `A`, as many as `iterations` sweeps plus one
/// product with `A`). `A` and `P` are symmetric positive definite, so the `A`-norm of the
/// error falls monotonically with every iteration, from at most the one sweep's; CG stops
/// early at a zero residual or when `p·Ap` is not positive (a non-finite system). The result
/// goes to `dv` (f32).
fn solve_pcg(step: &Step, iterations: u32, s: &mut ImplicitScratch) {
    let model = step.model;
    let nf = model.n_free;
    s.xr.resize(nf, [DVec3::ZERO; 2]);
    s.zc.resize(nf, DVec3::ZERO);
    s.pq.resize(nf, [DVec3::ZERO; 2]);
    // Δv₀ = P⁻¹ b: precondition b, then move it to the solution column.
    for k in 0..nf {
        s.xr[k][1] = s.b[k].as_dvec3();
    }
    precondition(model, s);
    for k in 0..nf {
        s.xr[k][0] = s.zc[k];
    }
    // r₀ = b − A Δv₀.
    {
        let (b, blocks, rself, zc) = (&s.b, &s.blocks, &s.rself, &s.zc);
        chunk_sum(&mut s.xr, &mut s.sums, |c, rows| {
            for (o, row) in rows.iter_mut().enumerate() {
                let k = c * CHUNK + o;
                row[1] = b[k].as_dvec3() - apply_a(step, blocks, rself, |j| zc[j], k);
            }
            [0.0]
        });
    }
    let mut rz = precondition(model, s);
    for it in 1..iterations {
        if !(rz > 0.0 && rz.is_finite()) {
            break;
        }
        // p = z + β p and A p = A z + β A p (p = z on the first iteration), with p·Ap.
        let beta = if it == 1 { None } else { Some(rz / s.rz_prev) };
        let [pap] = {
            let (blocks, rself, zc) = (&s.blocks, &s.rself, &s.zc);
            chunk_sum(&mut s.pq, &mut s.sums, |c, rows| {
                let mut acc = 0.0;
                for (o, pq) in rows.iter_mut().enumerate() {
                    let k = c * CHUNK + o;
                    let az = apply_a(step, blocks, rself, |j| zc[j], k);
                    *pq = match beta {
                        None => [zc[k], az],
                        Some(beta) => [zc[k] + pq[0] * beta, az + pq[1] * beta],
                    };
                    acc += pq[0].dot(pq[1]);
                }
                [acc]
            })
        };
        if !(pap > 0.0 && pap.is_finite()) {
            break;
        }
        let alpha = rz / pap;
        {
            let pq = &s.pq;
            chunk_sum(&mut s.xr, &mut s.sums, |c, rows| {
                for (o, row) in rows.iter_mut().enumerate() {
                    let k = c * CHUNK + o;
                    row[0] += pq[k][0] * alpha;
                    row[1] -= pq[k][1] * alpha;
                }
                [0.0]
            });
        }
        if it + 1 == iterations {
            break;
        }
        s.rz_prev = rz;
        rz = precondition(model, s);
    }
    for k in 0..nf {
        s.dv[k] = s.xr[k][0].as_vec3a();
    }
}

/// `Δv += P⁻¹ res` with `P` block diagonal (no hair trees): one 3×3 solve per mass.
fn sweep_diagonal(model: &SimModel, s: &mut ImplicitScratch) {
    let (diag, res) = (&s.diag, &s.res);
    if model.n_free < PARALLEL_MIN {
        for (k, o) in s.dv.iter_mut().enumerate() {
            *o += diag[k].solve(res[k]);
        }
    } else {
        s.dv.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(k, o)| *o += diag[k].solve(res[k]));
    }
}

/// `Δv += P⁻¹ res` with `P` factored along the hair trees ([`factor_trees`], [`tree_solve`]).
fn sweep_trees(model: &SimModel, s: &mut ImplicitScratch) {
    for (rp, r) in s.rp.iter_mut().zip(&s.res) {
        *rp = r.as_dvec3();
    }
    tree_solve(model, &s.dinv, &s.blocks, &mut s.rp, &mut s.z);
    for (dv, z) in s.dv.iter_mut().zip(&s.z) {
        *dv += z.as_vec3a();
    }
}

/// The new state from `Δv`: `v + Δv` and `x + h (v + Δv)` (eq. 3.26, 3.20).
fn advance(step: &mut Step, dv: &[Vec3A]) {
    let (x, v, h) = (step.x, step.v, step.h);
    for_free(step.model.n_free, step.x_out, step.v_out, |k| {
        let vn = v[k] + dv[k];
        (x[k] + vn * h, vn)
    });
}
