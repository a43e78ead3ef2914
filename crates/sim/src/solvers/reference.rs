//! The reference solver: backward Euler linearised once per step (Baraff & Witkin 1998),
//! `(M − h ∂F/∂v − h² ∂F/∂x) Δv = h (F + h ∂F/∂x v)`, with the exact Jacobian of every force it
//! applies — springs with the full `k ((1 − L/l) I + (L/l) d̂d̂ᵀ)` (not clamped, so indefinite
//! under compression; only a compression so strong that `h² k (L/l − 1)` exceeds half the
//! lighter end's mass is floored there, [`COMPRESSION_FLOOR`]), their damping, the restoring force of eq. 3.37 (not symmetric: its
//! Jacobian couples the tip to its root one way only), the inertial forces of a rotating frame and
//! the local forces. The system is not symmetric, so it is solved by BiCGSTAB with a block-Jacobi
//! preconditioner (the inverse of each mass's 3×3 diagonal block) to the relative residual
//! `reference_tolerance`, all in f64.
//!
//! The state is f64 too: the solver keeps an f64 copy of the free masses' positions and velocities
//! between steps and publishes their f32 rounding. At the start of a step every free mass whose
//! f32 state is no longer the rounding of its copy (the host, a stick projection or the guard
//! moved it) is reseeded from f32. So the reference's own error is not held at the f32 floor
//! (`Simulator::positions_f64` reads the copy).
//!
//! The system is assembled in parallel per fixed chunk of masses (per mass its own row: every
//! block of that row, nothing shared), and every dot product of BiCGSTAB sums fixed chunks in
//! order (`chunks.rs`), so results are bit-identical for any thread count. The new state, stick
//! projection, guard and rotation limit then run in the fused lane-group pass (`fused.rs`).

use glam::{DMat3, DVec3, Vec3A};
use rayon::prelude::*;

use super::chunks::{CHUNK, PARALLEL_MIN, chunk_sum, for_free};
use super::fused::{CgRow, Mode, finish_step, group_step};
use super::projection::project_sticks;
use super::{Step, StepOutcome};
use crate::forces::{outer, restoring_force_f64};
use crate::model::SimModel;
use crate::sentinel::NONE;

/// The most negative transverse stiffness of a compressed link, as a fraction of its lighter
/// end's mass over `h²`: below it linearised backward Euler with the exact Jacobian is unstable
/// (a strongly compressed link buckles within the step and the linear solve turns that into
/// energy), so the Jacobian is floored there. Mild compression (`h² k (L/l − 1) ≤ m/2`) keeps
/// the exact Jacobian.
pub(crate) const COMPRESSION_FLOOR: f64 = 0.5;

/// Per free mass its row of the system: right-hand side, diagonal block and its inverse.
#[derive(Clone, Copy, Default)]
struct RowSys {
    b: DVec3,
    diag: DMat3,
    pinv: DMat3,
}

/// Per free mass the BiCGSTAB vectors (`ph`, `sh`: the preconditioned `p` and `s`).
#[derive(Clone, Copy, Default)]
struct BiRow {
    x: DVec3,
    r: DVec3,
    rh: DVec3,
    p: DVec3,
    v: DVec3,
    s: DVec3,
    ph: DVec3,
    sh: DVec3,
}

/// Scratch of the reference solver (f64), kept between steps.
#[derive(Default)]
pub(crate) struct ReferenceScratch {
    /// The f64 state of the free masses at the start of the next step, and the new state of the
    /// step being taken.
    state: Vec<CgRow>,
    next: Vec<CgRow>,
    rows: Vec<RowSys>,
    /// Per adjacency entry `e` of free mass `k` (other end `j` free) the block `A_kj`.
    off: Vec<DMat3>,
    bi: Vec<BiRow>,
    /// A matrix product's output.
    av: Vec<DVec3>,
    sums1: Vec<[f64; 1]>,
    sums2: Vec<[f64; 2]>,
}

impl ReferenceScratch {
    /// Free mass `k`'s position in f64: its f64 state when `x` (its f32 position) is still that
    /// state's rounding, else `x`.
    pub(crate) fn position_f64(&self, k: usize, x: Vec3A) -> DVec3 {
        match self.state.get(k) {
            Some(s) if s.x.as_vec3a() == x => s.x,
            _ => x.as_dvec3(),
        }
    }
}

/// What a reference step did: the BiCGSTAB iterations used, the relative residual reached and
/// what the end of the step did.
pub(crate) struct ReferenceOutcome {
    pub iterations: u32,
    pub residual: f64,
    pub step: StepOutcome,
}

/// One backward-Euler step: BiCGSTAB on the linearised system to relative residual `tol`, at most
/// `max_iterations` iterations. A step that does not converge is rejected: the guard is left
/// alone and the caller reports [`ReferenceOutcome::residual`].
pub(crate) fn reference_step(step: Step, tol: f64, max_iterations: u32, s: &mut ReferenceScratch) -> ReferenceOutcome {
    sync_state(&step, s);
    assemble_system(&step, s);
    let (iterations, residual) = solve_bicgstab(step.model, tol, max_iterations, s);
    let converged = !(residual > tol && residual.is_finite());
    let hd = step.h as f64;
    let (state, bi) = (&s.state, &s.bi);
    s.next.resize(step.model.n_free, CgRow::default());
    for (k, o) in s.next.iter_mut().enumerate() {
        let v = state[k].v + bi[k].x;
        *o = CgRow { x: state[k].x + v * hd, v };
    }
    let out = finish_reference_step(step, &s.next, converged);
    std::mem::swap(&mut s.state, &mut s.next);
    ReferenceOutcome { iterations, residual, step: out }
}

/// Keeps the f64 state of every free mass whose f32 state is still its rounding; reseeds the
/// others from f32.
fn sync_state(step: &Step, s: &mut ReferenceScratch) {
    let nf = step.model.n_free;
    let (x, v) = (step.x, step.v);
    s.state.resize(nf, CgRow { x: DVec3::NAN, v: DVec3::NAN });
    for (k, st) in s.state.iter_mut().enumerate() {
        if !st.rounds_to(x[k], v[k]) {
            *st = CgRow { x: x[k].as_dvec3(), v: v[k].as_dvec3() };
        }
    }
}

/// Free mass `k`'s row: right-hand side `h (F + h ∂F/∂x v)`, diagonal block
/// `M − h ∂F_k/∂v_k − h² ∂F_k/∂x_k` and its inverse (the preconditioner), and into `off` (the
/// mass's adjacency slice) the blocks `A_kj = −h ∂F_k/∂v_j − h² ∂F_k/∂x_j` of its links to free
/// masses (zero for anchored ones, whose `Δv` is zero).
#[inline]
fn assemble_mass(step: &Step, state: &[CgRow], k: usize, off: &mut [DMat3]) -> RowSys {
    let (model, fe) = (step.model, step.fe);
    let nf = model.n_free;
    let (h, id) = (step.h as f64, DMat3::IDENTITY);
    let h2 = h * h;
    let pos = |j: usize| if j < nf { state[j].x } else { step.x[j].as_dvec3() };
    let vel = |j: usize| if j < nf { state[j].v } else { step.v[j].as_dvec3() };
    let (xi, vi) = (state[k].x, state[k].v);
    let m = model.mass[k] as f64;
    let (mut f, jx, jv) = fe.external_f64(m, xi, vi, model.rest[k]);
    let mut diag = DMat3::from_diagonal(DVec3::splat(m)) - jv * h - jx * h2;
    // Σ_j ∂F_k/∂x_j v_j.
    let mut kv = jx * vi;
    for (e, a) in model.adj_of(k).iter().enumerate() {
        let j = a.other as usize;
        let (d, dv) = (pos(j) - xi, vel(j) - vi);
        let l = d.length();
        let (rest, kk, c) = (a.rest as f64, a.k as f64, a.c as f64);
        f += d * (kk * (1.0 - rest / l.max(1e-300))) + dv * c;
        // ∂F_k/∂x_j = K = k ((1 − L/l) I + (L/l) d̂d̂ᵀ); ∂F_k/∂x_k = −K; ∂F_k/∂v_j = c I.
        let kj = if kk == 0.0 {
            DMat3::ZERO
        } else if l <= 1e-12 {
            id * if rest == 0.0 { kk } else { 0.0 }
        } else {
            // The transverse stiffness k (1 − L/l) is negative under compression; floored at
            // −μ/h² (μ half the lighter end's mass) so that one link's compression cannot make
            // the step's matrix indefinite (see `COMPRESSION_FLOOR`).
            let mj = if j < nf { model.mass[j] as f64 } else { m };
            let floor = -COMPRESSION_FLOOR * m.min(mj) / h2;
            id * (kk * (1.0 - rest / l)).max(floor) + outer(d, d) * (kk * rest / (l * l * l))
        };
        kv += kj * dv;
        let blk = id * (h * c) + kj * h2;
        diag += blk;
        off[e] = if j < nf { -blk } else { DMat3::ZERO };
    }
    let p = model.rest_parent[k];
    if p != NONE && fe.restoring_w != 0.0 {
        let p = p as usize;
        let (fr, jr) = restoring_force_f64(pos(p), xi, model.rest_n[k].as_dvec3(), fe.restoring_w as f64);
        f += fr;
        // ∂F_k/∂x_k = J, ∂F_k/∂x_p = −J (the root feels no reaction).
        kv += jr * (vi - vel(p));
        diag -= jr * h2;
        if p < nf {
            if let Some(e) = model.adj_of(k).iter().position(|a| a.other as usize == p) {
                off[e] += jr * h2;
            }
        }
    }
    let det = diag.determinant();
    let pinv = if det != 0.0 && det.is_finite() { diag.inverse() } else { DMat3::ZERO };
    RowSys { b: (f + kv * h) * h, diag, pinv }
}

/// Sizes the scratch and assembles every free mass's row ([`assemble_mass`]) over fixed chunks of
/// masses, in parallel above the cut-off.
fn assemble_system(step: &Step, s: &mut ReferenceScratch) {
    let model = step.model;
    let nf = model.n_free;
    s.rows.resize(nf, RowSys::default());
    s.off.resize(model.adj.len(), DMat3::ZERO);
    let state = &s.state;
    let work = |(c, (rows, off)): (usize, (&mut [RowSys], &mut [DMat3]))| {
        let (k0, base) = (c * CHUNK, model.adj_start[c * CHUNK] as usize);
        for (o, row) in rows.iter_mut().enumerate() {
            let k = k0 + o;
            let (a0, a1) = (model.adj_start[k] as usize - base, model.adj_start[k + 1] as usize - base);
            *row = assemble_mass(step, state, k, &mut off[a0..a1]);
        }
    };
    // Each chunk of masses with its adjacency's blocks (split in order, no allocation).
    let mut rest = s.off.as_mut_slice();
    let chunks = s.rows.chunks_mut(CHUNK).enumerate().map(move |(c, rows)| {
        let (a0, a1) = (model.adj_start[c * CHUNK], model.adj_start[c * CHUNK + rows.len()]);
        let (head, tail) = std::mem::take(&mut rest).split_at_mut((a1 - a0) as usize);
        rest = tail;
        (c, (rows, head))
    });
    if nf < PARALLEL_MIN {
        chunks.for_each(work);
    } else {
        chunks.par_bridge().for_each(work);
    }
}

/// Row `k` of `A y`: the diagonal block times `y_k` plus every link to a free mass's block times
/// `y_j`.
#[inline]
fn apply_a(model: &SimModel, rows: &[RowSys], off: &[DMat3], y: impl Fn(usize) -> DVec3, k: usize) -> DVec3 {
    let nf = model.n_free;
    let mut out = rows[k].diag * y(k);
    let (s0, s1) = (model.adj_start[k] as usize, model.adj_start[k + 1] as usize);
    for (&j, blk) in model.adj_other[s0..s1].iter().zip(&off[s0..s1]) {
        if (j as usize) < nf {
            out += *blk * y(j as usize);
        }
    }
    out
}

/// Block-Jacobi-preconditioned BiCGSTAB (van der Vorst 1992) on the assembled system from
/// `Δv = 0` until the relative residual is at most `tol` or `max_iterations` are used; the
/// solution in `s.bi[k].x`. A breakdown (`r̂·r`, `r̂·v` or `ω` zero or not finite) restarts from
/// the current solution with the true residual as the new shadow. Returns the iterations used
/// and the relative residual reached (0 for a zero right-hand side, NaN for a non-finite system).
fn solve_bicgstab(model: &SimModel, tol: f64, max_iterations: u32, s: &mut ReferenceScratch) -> (u32, f64) {
    let nf = model.n_free;
    s.bi.resize(nf, BiRow::default());
    s.av.resize(nf, DVec3::ZERO);
    let rows = &s.rows;
    let off = &s.off;
    let [bb] = chunk_sum(&mut s.bi, &mut s.sums1, |c, bi| {
        let mut acc = 0.0;
        for (o, row) in bi.iter_mut().enumerate() {
            let b = rows[c * CHUNK + o].b;
            *row = BiRow { r: b, rh: b, ..BiRow::default() };
            acc += b.length_squared();
        }
        [acc]
    });
    let bnorm = bb.sqrt();
    if bnorm == 0.0 {
        return (0, 0.0);
    }
    if !bnorm.is_finite() {
        return (0, f64::NAN);
    }
    let (mut rho, mut alpha, mut omega) = (1.0f64, 1.0f64, 1.0f64);
    let mut rho_new = bb;
    let mut rel = 1.0;
    let mut iterations = 0;
    let usable = |q: f64| q != 0.0 && q.is_finite();
    while rel > tol && iterations < max_iterations {
        iterations += 1;
        if !(usable(rho_new) && usable(omega) && usable(rho)) {
            // Restart: r = b − A x, r̂ = r, p = v = 0.
            {
                let bi = &s.bi;
                chunk_sum(&mut s.av, &mut s.sums1, |c, av| {
                    for (o, a) in av.iter_mut().enumerate() {
                        *a = apply_a(model, rows, off, |j| bi[j].x, c * CHUNK + o);
                    }
                    [0.0]
                });
            }
            let av = &s.av;
            let [rr] = chunk_sum(&mut s.bi, &mut s.sums1, |c, bi| {
                let mut acc = 0.0;
                for (o, row) in bi.iter_mut().enumerate() {
                    let k = c * CHUNK + o;
                    row.r = rows[k].b - av[k];
                    (row.rh, row.p, row.v) = (row.r, DVec3::ZERO, DVec3::ZERO);
                    acc += row.r.length_squared();
                }
                [acc]
            });
            rel = rr.sqrt() / bnorm;
            (rho, alpha, omega, rho_new) = (1.0, 1.0, 1.0, rr);
            if rel <= tol || !usable(rr) {
                break;
            }
        }
        let beta = (rho_new / rho) * (alpha / omega);
        rho = rho_new;
        // p = r + β (p − ω v), p̂ = P⁻¹ p.
        chunk_sum(&mut s.bi, &mut s.sums1, |c, bi| {
            for (o, row) in bi.iter_mut().enumerate() {
                row.p = row.r + (row.p - row.v * omega) * beta;
                row.ph = rows[c * CHUNK + o].pinv * row.p;
            }
            [0.0]
        });
        // v = A p̂, α = ρ / r̂·v.
        let [rhv] = {
            let bi = &s.bi;
            chunk_sum(&mut s.av, &mut s.sums1, |c, av| {
                let mut acc = 0.0;
                for (o, a) in av.iter_mut().enumerate() {
                    let k = c * CHUNK + o;
                    *a = apply_a(model, rows, off, |j| bi[j].ph, k);
                    acc += bi[k].rh.dot(*a);
                }
                [acc]
            })
        };
        if !usable(rhv) {
            rho_new = 0.0;
            continue;
        }
        alpha = rho / rhv;
        // s = r − α v, ŝ = P⁻¹ s.
        let [ss] = {
            let av = &s.av;
            chunk_sum(&mut s.bi, &mut s.sums1, |c, bi| {
                let mut acc = 0.0;
                for (o, row) in bi.iter_mut().enumerate() {
                    let k = c * CHUNK + o;
                    row.v = av[k];
                    row.s = row.r - row.v * alpha;
                    row.sh = rows[k].pinv * row.s;
                    acc += row.s.length_squared();
                }
                [acc]
            })
        };
        if ss.sqrt() / bnorm <= tol {
            let [rr] = chunk_sum(&mut s.bi, &mut s.sums1, |_, bi| {
                let mut acc = 0.0;
                for row in bi.iter_mut() {
                    row.x += row.ph * alpha;
                    row.r = row.s;
                    acc += row.r.length_squared();
                }
                [acc]
            });
            rel = rr.sqrt() / bnorm;
            break;
        }
        // t = A ŝ, ω = t·s / t·t.
        let [ts, tt] = {
            let bi = &s.bi;
            chunk_sum(&mut s.av, &mut s.sums2, |c, av| {
                let mut acc = [0.0; 2];
                for (o, a) in av.iter_mut().enumerate() {
                    let k = c * CHUNK + o;
                    *a = apply_a(model, rows, off, |j| bi[j].sh, k);
                    acc[0] += a.dot(bi[k].s);
                    acc[1] += a.length_squared();
                }
                acc
            })
        };
        omega = if tt > 0.0 { ts / tt } else { 0.0 };
        // x += α p̂ + ω ŝ, r = s − ω t, with r·r and r̂·r.
        let [rr, rhr] = {
            let av = &s.av;
            chunk_sum(&mut s.bi, &mut s.sums2, |c, bi| {
                let mut acc = [0.0; 2];
                for (o, row) in bi.iter_mut().enumerate() {
                    let k = c * CHUNK + o;
                    row.x += row.ph * alpha + row.sh * omega;
                    row.r = row.s - av[k] * omega;
                    acc[0] += row.r.length_squared();
                    acc[1] += row.rh.dot(row.r);
                }
                acc
            })
        };
        rel = rr.sqrt() / bnorm;
        rho_new = rhr;
        if !rel.is_finite() {
            break;
        }
    }
    (iterations, rel)
}

/// The end of a reference step from the new f64 state `next`: when it `converged`, its f32
/// rounding, projection, check, guard and rotation limit in one lane-group pass where the topology
/// allows, else the rounding and [`finish_step`]; when it did not, the rounding and the projection
/// only (the guard left alone).
fn finish_reference_step(step: Step, next: &[CgRow], converged: bool) -> StepOutcome {
    let model = step.model;
    if converged && (!model.has_sticks || model.sticks_to_anchors) {
        return group_step(step, Mode::Finish, next);
    }
    for_free(model.n_free, step.x_out, step.v_out, |k| (next[k].x.as_vec3a(), next[k].v.as_vec3a()));
    if converged {
        finish_step(step)
    } else {
        project_sticks(model, step.x_out, step.v_out);
        StepOutcome { finite: false, guard: None, rotation: None }
    }
}
