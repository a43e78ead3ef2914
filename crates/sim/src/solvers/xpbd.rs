//! Extended position-based dynamics (XPBD; Macklin, Müller & Chentanez, "XPBD: Position-Based
//! Simulation of Compliant Constrained Dynamics", MIG 2016), the method NVIDIA Warp and Newton
//! ship, on the fur's links:
//!
//! 1. **Predict** with the external forces (gravity, wind, object motion, local forces) and the
//!    restoring force of eq. 3.37, all evaluated at the start of the step. The restoring force
//!    keeps the implicit solver's diagonal linearisation (mass `m + h²·2w/L`, `implicit.rs`):
//!    taken fully explicitly its stiffness `2w/L` over a hair mass of 1 µg gives `hω ≈ 16` at
//!    1/60 s, and since XPBD never substeps for stability, that would throw the tips around.
//! 2. **Project** `iterations` symmetric Gauss–Seidel sweeps over the links (colours out along the
//!    hairs, then back), one colour at a time. A spring
//!    is a distance constraint `C = |xᵢ − xⱼ| − l₀` with compliance `α = 1/k` (`α̃ = α/h²`); a
//!    stick one with zero compliance. A link's viscosity (eq. 3.24, `c (vⱼ − vᵢ)`: the *full*
//!    relative velocity, not only along the link) is XPBD's damping term (the paper's eq. 25,
//!    `β̃ = h² c`) on the vector constraint `C = xᵢ − xⱼ` with zero stiffness: in the limit
//!    `α → ∞` the update becomes `Δλ = −(λ + h c (Δxᵢ − Δxⱼ)) / (1 + h c (wᵢ + wⱼ))`, which
//!    converges to backward Euler's `h² c (vⱼ − vᵢ)`. An anchored end has zero inverse mass and
//!    moves, for the damper, with the skin's velocity.
//! 3. **Velocities** from the position change, `v = Δx/h`. The iterate is the displacement `Δx`
//!    itself (in f32), not the position, so `Δx/h` carries no `1/h`-amplified rounding of the
//!    positions' magnitude.
//!
//! Then the shared end of step (`fused.rs`'s `finish_step`): stick projection (which XPBD's
//! zero-compliance sticks already nearly satisfy), finiteness check and guard.
//!
//! **Parallel and deterministic.** The links are edge-coloured once, in link order, so that no
//! free mass has two links of one colour and the colours of a hair's links increase outwards. One colour's pass then runs per free mass in
//! fixed chunks: each mass finds its (at most one) link of that colour, both ends compute that
//! link's update from the same inputs in the same orientation, and each keeps its own half and
//! its own copy of the multipliers (stored per colour and mass). Reads come from one buffer,
//! writes go to another, so nothing is shared, nothing is atomic and the result is bit-identical
//! for any thread count (and to the sequential Gauss–Seidel sweep in colour order).
//!
//! Substeps: XPBD is unconditionally stable, so the simulator never splits its step. The
//! "small steps" variant (Macklin et al. 2019: many substeps, one iteration each) is
//! `xpbd_iterations = 1` with the caller stepping `n` times by `dt/n`.

use glam::Vec3A;
use rayon::prelude::*;

use super::chunks::{CHUNK, PARALLEL_MIN};
use super::fused::finish_step;
use super::{Step, StepOutcome, external, restoring};
use crate::model::{NONE, SimModel};

/// One link as XPBD sees it: `a` is free and `a < b` when both are free (the orientation both
/// ends compute in); `b` may be anchored.
#[derive(Clone, Copy, Debug)]
struct Link {
    a: u32,
    b: u32,
    rest: f32,
    /// Compliance `1/k` (zero for a stick; infinite for a link without stiffness).
    compliance: f32,
    c: f32,
}

/// XPBD's links, their colouring and its per-step buffers (kept between steps).
#[derive(Debug, Default)]
pub(crate) struct XpbdScratch {
    links: Vec<Link>,
    colours: usize,
    /// Colour-major: `slot[c · n_free + i]` is free mass `i`'s link of colour `c`, or NONE.
    slot: Vec<u32>,
    /// Per colour and mass (as `slot`): that link's distance and damping multipliers.
    lambda: Vec<f32>,
    lambda_damp: Vec<Vec3A>,
    inv_mass: Vec<f32>,
    /// The displacement iterate `Δx` (read) and the next one (written).
    dx: Vec<Vec3A>,
    dx_next: Vec<Vec3A>,
}

impl XpbdScratch {
    /// The links of `model` (springs and the sticks among its force links) and their colouring.
    pub fn new(model: &SimModel) -> XpbdScratch {
        let nf = model.n_free;
        let mut links = Vec::new();
        for k in 0..nf {
            for a in model.adj_of(k) {
                let j = a.other as usize;
                if j < nf && j <= k {
                    continue; // listed from its lower end
                }
                // Sticks are the rigid parent links; they carry `k = 0` in the adjacency.
                let stick = model.parent[k] == a.other || (j < nf && model.parent[j] == k as u32);
                let compliance = if stick {
                    0.0
                } else if a.k > 0.0 {
                    1.0 / a.k
                } else {
                    f32::INFINITY
                };
                links.push(Link { a: k as u32, b: a.other, rest: a.rest, compliance, c: a.c });
            }
        }
        // Edge colouring in link order (masses by depth from the skin): a hair-tree link takes
        // the first colour free at both ends *above* every colour already used at its upper
        // end, so the colours run from the skin outwards along every hair and a sweep in colour
        // order carries a correction down a whole hair, as a sequential root-to-tip sweep would
        // (red–black alternation along a chain needs O(n²) sweeps); other links (prism edges)
        // take the first colour free at both ends.
        let mut slot: Vec<u32> = Vec::new();
        let mut colours = 0;
        let mut above = vec![0usize; nf];
        // Links to the skin first, whatever a mass's adjacency order.
        let skin_first = (0..links.len())
            .filter(|&l| links[l].b as usize >= nf)
            .chain((0..links.len()).filter(|&l| (links[l].b as usize) < nf));
        for l in skin_first {
            let link = links[l];
            let (a, b) = (link.a as usize, link.b as usize);
            let tree = b < nf && model.tree_parent[b] == a as u32;
            let mut c = if tree { above[a] } else { 0 };
            loop {
                if c == colours {
                    slot.resize((colours + 1) * nf, NONE);
                    colours += 1;
                }
                let free_a = slot[c * nf + a] == NONE;
                let free_b = b >= nf || slot[c * nf + b] == NONE;
                if free_a && free_b {
                    break;
                }
                c += 1;
            }
            slot[c * nf + a] = l as u32;
            above[a] = above[a].max(c + 1);
            if b < nf {
                slot[c * nf + b] = l as u32;
                above[b] = above[b].max(c + 1);
            }
        }
        XpbdScratch {
            links,
            colours,
            lambda: vec![0.0; slot.len()],
            lambda_damp: vec![Vec3A::ZERO; slot.len()],
            slot,
            inv_mass: model.mass[..nf].iter().map(|&m| 1.0 / m).collect(),
            dx: vec![Vec3A::ZERO; nf],
            dx_next: vec![Vec3A::ZERO; nf],
        }
    }
}

/// One XPBD step with `iterations` symmetric Gauss–Seidel sweeps over the coloured links.
pub(crate) fn xpbd_step(step: Step, iterations: u32, s: &mut XpbdScratch) -> StepOutcome {
    let (model, fe, h, x, v) = (step.model, step.fe, step.h, step.x, step.v);
    let nf = model.n_free;
    // 1. Predict: external and restoring forces at the start, restoring linearised on the diagonal.
    predict(model, fe, h, x, v, &mut s.dx);
    s.lambda.fill(0.0);
    s.lambda_damp.fill(Vec3A::ZERO);
    // 2. Project, colour by colour.
    if nf > 0 {
        // Symmetric Gauss–Seidel: every iteration sweeps the colours out along the hairs and back.
        let sweep = (0..s.colours).chain((0..s.colours.saturating_sub(1)).rev());
        for _ in 0..iterations {
            for c in sweep.clone() {
                let range = c * nf..(c + 1) * nf;
                let pass = Pass {
                    links: &s.links,
                    slot: &s.slot[range.clone()],
                    inv_mass: &s.inv_mass,
                    x,
                    v,
                    h,
                    nf,
                    dx: &s.dx,
                };
                pass.run(&mut s.dx_next, &mut s.lambda[range.clone()], &mut s.lambda_damp[range]);
                std::mem::swap(&mut s.dx, &mut s.dx_next);
            }
        }
    }
    // 3. New state and velocities from the displacement.
    let inv_h = 1.0 / h;
    for ((xo, vo), (&x0, &d)) in step.x_out[..nf].iter_mut().zip(&mut step.v_out[..nf]).zip(x[..nf].iter().zip(&s.dx)) {
        *xo = x0 + d;
        *vo = d * inv_h;
    }
    finish_step(Step { rotation: None, ..step })
}

/// The predicted displacement `h v*` of every free mass: `v* = v + h (F − h k_r (v − v_p)) / (m + h² k_r)`,
/// `F` the external and restoring forces at the start, `k_r = 2w/L` the restoring link's
/// stiffness bound and `v_p` its parent's velocity (the implicit solver's linearisation).
fn predict(model: &SimModel, fe: &crate::forces::ForceEval, h: f32, x: &[Vec3A], v: &[Vec3A], dx: &mut [Vec3A]) {
    let one = |k: usize| {
        let (xi, vi) = (x[k], v[k]);
        let f = external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi);
        let kr = model.restoring_stiffness(k, fe.restoring_w);
        let rp = model.rest_parent[k];
        let vp = if kr > 0.0 && rp != NONE { v[rp as usize] } else { Vec3A::ZERO };
        let dv = (f - (vi - vp) * (h * kr)) * (h / (model.mass[k] + h * h * kr));
        (vi + dv) * h
    };
    let nf = model.n_free;
    if nf < PARALLEL_MIN {
        for (k, d) in dx[..nf].iter_mut().enumerate() {
            *d = one(k);
        }
    } else {
        dx[..nf].par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            for (o, d) in out.iter_mut().enumerate() {
                *d = one(c * CHUNK + o);
            }
        });
    }
}

/// One colour's Gauss–Seidel pass (see the file docs).
struct Pass<'a> {
    links: &'a [Link],
    /// This colour's slots, per free mass.
    slot: &'a [u32],
    inv_mass: &'a [f32],
    x: &'a [Vec3A],
    v: &'a [Vec3A],
    h: f32,
    nf: usize,
    dx: &'a [Vec3A],
}

impl Pass<'_> {
    fn run(&self, dx_next: &mut [Vec3A], lambda: &mut [f32], lambda_damp: &mut [Vec3A]) {
        let nf = self.nf;
        let out = &mut dx_next[..nf];
        if nf < PARALLEL_MIN {
            for (i, ((d, l), ld)) in out.iter_mut().zip(lambda.iter_mut()).zip(lambda_damp.iter_mut()).enumerate() {
                *d = self.mass(i, l, ld);
            }
            return;
        }
        out.par_chunks_mut(CHUNK)
            .zip(lambda.par_chunks_mut(CHUNK))
            .zip(lambda_damp.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(c, ((dc, lc), ldc))| {
                for (o, ((d, l), ld)) in dc.iter_mut().zip(lc.iter_mut()).zip(ldc.iter_mut()).enumerate() {
                    *d = self.mass(c * CHUNK + o, l, ld);
                }
            });
    }

    /// Free mass `i`'s next displacement: its link of this colour projected (distance, then
    /// damper), from the link's own orientation, so both ends compute the same update.
    #[inline]
    fn mass(&self, i: usize, lambda: &mut f32, lambda_damp: &mut Vec3A) -> Vec3A {
        let s = self.slot[i];
        if s == NONE {
            return self.dx[i];
        }
        let l = self.links[s as usize];
        let (a, b) = (l.a as usize, l.b as usize);
        let free_b = b < self.nf;
        let wa = self.inv_mass[a];
        let wb = if free_b { self.inv_mass[b] } else { 0.0 };
        let mut da = self.dx[a];
        let mut db = if free_b { self.dx[b] } else { Vec3A::ZERO };
        let h = self.h;
        if l.compliance.is_finite() {
            let d = (self.x[a] - self.x[b]) + (da - db);
            let len = d.length();
            if len > 1e-12 {
                let n = d / len;
                let at = l.compliance / (h * h);
                let dl = (-(len - l.rest) - at * *lambda) / (wa + wb + at);
                *lambda += dl;
                da += n * (wa * dl);
                db -= n * (wb * dl);
            }
        }
        if l.c > 0.0 {
            let hc = h * l.c;
            // An anchored end moves, for the damper, with the skin's velocity over the step.
            let moved_b = if free_b { db } else { self.v[b] * h };
            let dl = (-*lambda_damp - (da - moved_b) * hc) / (1.0 + hc * (wa + wb));
            *lambda_damp += dl;
            da += dl * wa;
            db -= dl * wb;
        }
        if i == a { da } else { db }
    }
}
