//! The fast mass–spring method of Liu, Bargteil, O'Brien & Kavan, "Fast Simulation of
//! Mass-Spring Systems" (ACM TOG 32(6), 2013): backward Euler of the *nonlinear* spring forces,
//! written as the minimisation of `½ (x − y)ᵀ M (x − y) + h² E(x)` and solved by alternating a
//! local step (per spring the optimal direction `d = l₀ (xᵢ − xⱼ)/|xᵢ − xⱼ|`) and a global step
//! (one solve with the constant matrix `M + h² L`, `L` the stiffness-weighted spring Laplacian).
//!
//! The unknown is the step's displacement `u = x(t+h) − x(t)` of the free masses (f64); anchored
//! masses are eliminated (their links add to the diagonal and, through their known positions and
//! skin velocities, to the right-hand side). Per free mass `i`:
//!
//! `(mᵢ + h² k_r + Σ (h² k + h c)) uᵢ − Σ_free (h² k + h c) uⱼ =
//!     mᵢ h vᵢ + h² (F_ext + F_rest + k_r h v_p) + h² Σ_anchored c v_a + h² Σ k (d − (xᵢ − xⱼ))`
//!
//! - **Damping**: a link's viscosity `c (vⱼ − vᵢ)` (eq. 3.24) is taken implicitly with
//!   `v = u/h`: `h c` joins the constant matrix as a second, damping-weighted Laplacian (exactly,
//!   not Rayleigh-approximated), so converged iterations are backward Euler of Hooke + viscosity.
//! - **External and restoring forces** are explicit, at the start of the step; the restoring
//!   force keeps the implicit solver's diagonal linearisation `k_r = 2w/L` (mass `m + h² k_r`,
//!   parent velocity `v_p` explicit), without which a 1 µg hair would see `hω ≈ 16`.
//! - **Sticks** carry no stiffness (only their damping enters the matrix); they are projected
//!   after the step like every solver's (`stick.rs`, through `fused.rs`'s `finish_step`).
//!
//! **Prefactoring.** The matrix depends only on `h`, the links' `k` and `c`, the masses, the
//! restoring weight and which masses are anchored — not on where anything is. Its pattern is
//! ordered (minimum degree) and analysed once at construction; the numeric `LDLᵀ` factor
//! (`ldlt.rs`, f64) is computed on the first step and again only when the step size or the
//! restoring weight changes (the cache key is their bit patterns), so a fixed frame rate factors
//! once. Skinning moves anchors but not the matrix. The three coordinates share the factor: three
//! right-hand sides, solved side by side on three threads (each solve is sequential, so the
//! result does not depend on the thread count).
//!
//! **Precision: f64.** `h² k/m` spans ten orders of magnitude across the hard cases (1 µg hairs
//! on 10⁴ N/m springs, 1 t hairs on soft ones); the factor of such a matrix in f32 would lose the
//! displacement of the soft modes, and `v = u/h` needs the displacement to full precision.

use glam::{DVec3, Vec3A};

use super::chunks::{CHUNK, PARALLEL_MIN, chunk_for_each};
use super::fused::finish_step;
use super::ldlt::Ldlt;
use super::{Step, StepOutcome, external, restoring};
use crate::SimError;
use crate::model::SimModel;
use crate::sentinel::NONE;

/// The local/global solver's matrix pattern, factor and per-step buffers (kept between steps).
#[derive(Debug, Default)]
pub(crate) struct LocalGlobalScratch {
    /// The matrix per free mass (CSR): its diagonal first, then one entry per adjacency entry
    /// to a free mass (the pattern itself lives in the factor).
    row_start: Vec<u32>,
    val: Vec<f64>,
    ldlt: Ldlt,
    /// `(h, restoring weight)` bits of the current factor.
    key: Option<(u32, u32)>,
    /// Per free mass: the constant part of the right-hand side, and the displacement iterate.
    base: Vec<DVec3>,
    u: Vec<DVec3>,
    /// Per free mass the right-hand side; per coordinate the solution and the solver's scratch
    /// (models above the parallel cut-off solve the coordinates side by side), or the scratch of
    /// the three solved together (`work3`, below it).
    rhs: Vec<DVec3>,
    sol: [Vec<f64>; 3],
    work: [Vec<f64>; 3],
    work3: Vec<DVec3>,
}

impl LocalGlobalScratch {
    /// Analyses the matrix pattern of `model` (ordering and symbolic factorisation).
    pub fn new(model: &SimModel) -> LocalGlobalScratch {
        let nf = model.n_free;
        let mut row_start = vec![0u32; nf + 1];
        let mut col = Vec::new();
        for k in 0..nf {
            col.push(k as u32);
            col.extend(model.adj_of(k).iter().map(|a| a.other).filter(|&j| (j as usize) < nf));
            row_start[k + 1] = col.len() as u32;
        }
        let ldlt = Ldlt::analyse(&row_start, &col);
        LocalGlobalScratch {
            val: vec![0.0; col.len()],
            row_start,
            ldlt,
            key: None,
            base: vec![DVec3::ZERO; nf],
            u: vec![DVec3::ZERO; nf],
            rhs: vec![DVec3::ZERO; nf],
            sol: std::array::from_fn(|_| vec![0.0; nf]),
            work: std::array::from_fn(|_| vec![0.0; nf]),
            work3: vec![DVec3::ZERO; nf],
        }
    }

    /// Assembles `M + h² (L_k + k_r) + h L_c` and factors it.
    fn refactor(&mut self, model: &SimModel, h: f64, w: f32) -> Result<(), SimError> {
        let h2 = h * h;
        for k in 0..model.n_free {
            let s = self.row_start[k] as usize;
            let mut diag = model.mass[k] as f64 + h2 * model.restoring_stiffness(k, w) as f64;
            let mut e = s + 1;
            for a in model.adj_of(k) {
                let coupling = h2 * a.k as f64 + h * a.c as f64;
                diag += coupling;
                if (a.other as usize) < model.n_free {
                    self.val[e] = -coupling;
                    e += 1;
                }
            }
            self.val[s] = diag;
        }
        self.ldlt.factor(&self.val).map_err(|column| {
            SimError::InvalidInput(format!(
                "the local/global matrix is not positive definite (pivot {column}): masses must be positive, \
                 stiffness and damping non-negative"
            ))
        })
    }
}

/// One local/global step with `iterations` local and global steps.
pub(crate) fn local_global_step(
    step: Step,
    iterations: u32,
    s: &mut LocalGlobalScratch,
) -> Result<StepOutcome, SimError> {
    let (model, fe, x, v) = (step.model, step.fe, step.x, step.v);
    let nf = model.n_free;
    let h = step.h as f64;
    let key = (step.h.to_bits(), fe.restoring_w.to_bits());
    if s.key != Some(key) {
        s.key = None;
        s.refactor(model, h, fe.restoring_w)?;
        s.key = Some(key);
    }
    let h2 = h * h;
    // The constant part of the right-hand side; the first iterate is the inertial guess `h v`.
    chunk_for_each(&mut s.base[..nf], |c, out| {
        for (o, b) in out.iter_mut().enumerate() {
            let k = c * CHUNK + o;
            let (xi, vi) = (x[k], v[k]);
            let mut f = (external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi)).as_dvec3();
            let kr = model.restoring_stiffness(k, fe.restoring_w) as f64;
            let rp = model.rest_parent[k];
            if kr > 0.0 && rp != NONE {
                f += v[rp as usize].as_dvec3() * (kr * h);
            }
            for a in model.adj_of(k).iter().filter(|a| a.other as usize >= nf) {
                f += v[a.other as usize].as_dvec3() * a.c as f64;
            }
            *b = vi.as_dvec3() * (model.mass[k] as f64 * h) + f * h2;
        }
    });
    for (u, vi) in s.u[..nf].iter_mut().zip(&v[..nf]) {
        *u = vi.as_dvec3() * h;
    }
    for _ in 0..iterations {
        local_step(model, x, h2, s);
        if nf < PARALLEL_MIN {
            // A small model: the three coordinates in one pass over the factor (handing three
            // short solves to the pool cost more than they do: on the walking Fox, 290 free
            // masses, most of the step was the caller sleeping and waking).
            s.ldlt.solve3(&s.rhs, &mut s.u[..nf], &mut s.work3);
            continue;
        }
        let LocalGlobalScratch { ldlt, rhs, sol: [s0, s1, s2], work: [w0, w1, w2], .. } = &mut *s;
        let (ldlt, rhs) = (&*ldlt, &*rhs);
        rayon::join(
            || ldlt.solve(|i| rhs[i].x, s0, w0),
            || rayon::join(|| ldlt.solve(|i| rhs[i].y, s1, w1), || ldlt.solve(|i| rhs[i].z, s2, w2)),
        );
        for (k, u) in s.u[..nf].iter_mut().enumerate() {
            *u = DVec3::new(s.sol[0][k], s.sol[1][k], s.sol[2][k]);
        }
    }
    for ((xo, vo), (&x0, &u)) in step.x_out[..nf].iter_mut().zip(&mut step.v_out[..nf]).zip(x[..nf].iter().zip(&s.u)) {
        *xo = (x0.as_dvec3() + u).as_vec3a();
        *vo = (u / h).as_vec3a();
    }
    Ok(finish_step(Step { rotation: None, ..step }))
}

/// The local step and the right-hand side it gives: per free mass, the constant part plus
/// `h² Σ k (d − (xᵢ − xⱼ))` with `d = l₀ e/|e|`, `e` the link's current vector (gathered per
/// mass over its own links in adjacency order; each link's `d` is computed from both ends with
/// opposite signs).
fn local_step(model: &SimModel, x: &[Vec3A], h2: f64, s: &mut LocalGlobalScratch) {
    let nf = model.n_free;
    let (u, base) = (&s.u, &s.base);
    let one = |k: usize| {
        let xi = x[k].as_dvec3();
        let mut f = DVec3::ZERO;
        for a in model.adj_of(k) {
            if a.k == 0.0 {
                continue;
            }
            let j = a.other as usize;
            let e0 = xi - x[j].as_dvec3();
            let e = if j < nf { e0 + u[k] - u[j] } else { e0 + u[k] };
            let len = e.length();
            let dir = if len > 1e-12 {
                e / len
            } else {
                (model.rest[k] - model.rest[j]).as_dvec3().try_normalize().unwrap_or(DVec3::Y)
            };
            f += (dir * a.rest as f64 - e0) * a.k as f64;
        }
        base[k] + f * h2
    };
    chunk_for_each(&mut s.rhs[..nf], |c, out| {
        for (o, r) in out.iter_mut().enumerate() {
            *r = one(c * CHUNK + o);
        }
    });
}
