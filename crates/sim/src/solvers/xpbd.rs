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
//! free mass has two links of one colour and the colours of a hair's links increase outwards,
//! then stored colour-major (each colour's links contiguous, in link order, with their
//! multipliers beside them). One colour's pass visits only that colour's links: each computes
//! its update from its two ends' current displacements and writes both ends in place. Within a
//! colour no free mass is shared, so the links are independent: the pass runs in fixed chunks
//! of links (in parallel above a size cut-off), nothing is atomic, and the result is
//! bit-identical for any thread count (and to the sequential Gauss–Seidel sweep in colour
//! order). A sweep costs O(links), not O(colours × masses).
//!
//! Substeps: XPBD is unconditionally stable, so the simulator never splits its step. The
//! "small steps" variant (Macklin et al. 2019: many substeps, one iteration each) is
//! `xpbd_iterations = 1` with the caller stepping `n` times by `dt/n`.

use glam::Vec3A;
use rayon::prelude::*;

use super::chunks::{CHUNK, PARALLEL_MIN};
use super::fused::finish_step;
use super::{Step, StepOutcome, external, restoring};
use crate::model::SimModel;
use crate::sentinel::NONE;

/// One link as XPBD sees it: `a` is free and `a < b` when both are free (the orientation it is
/// projected in); `b` may be anchored.
#[derive(Clone, Copy, Debug)]
struct Link {
    a: u32,
    b: u32,
    /// The adjacency entry of `a` it was made from (its rest length follows that entry's).
    e: u32,
    rest: f32,
    /// Compliance `1/k` (zero for a stick; infinite for a link without stiffness).
    compliance: f32,
    c: f32,
    /// The ends' inverse masses (`wb` zero when `b` is anchored).
    wa: f32,
    wb: f32,
    /// Per step (for the step `XpbdScratch::h`): `α̃ = α/h²`, the distance update's denominator
    /// `wa + wb + α̃`, `h c` and the damper's denominator `1 + h c (wa + wb)`.
    at: f32,
    den: f32,
    hc: f32,
    den_damp: f32,
}

impl Link {
    /// The per-step coefficients for step `h` (the same expressions, in the same order, as
    /// the projection would evaluate them).
    fn set_step(&mut self, h: f32) {
        self.at = self.compliance / (h * h);
        self.den = self.wa + self.wb + self.at;
        self.hc = h * self.c;
        self.den_damp = 1.0 + self.hc * (self.wa + self.wb);
    }
}

/// XPBD's links, their colouring and its per-step buffers (kept between steps).
#[derive(Debug, Default)]
pub(crate) struct XpbdScratch {
    /// Colour-major: colour `c`'s links are `links[colour_start[c]..colour_start[c + 1]]`, each
    /// colour's in link order.
    links: Vec<Link>,
    colour_start: Vec<usize>,
    /// Per link (as `links`): its distance and damping multipliers.
    lambda: Vec<f32>,
    lambda_damp: Vec<Vec3A>,
    /// The step the links' per-step coefficients are for (NaN before the first).
    h: f32,
    /// The model's `rest_version` the links' rest lengths were copied at.
    rest_version: u64,
    /// The displacement iterate `Δx`, updated in place colour by colour.
    dx: Vec<Vec3A>,
}

impl XpbdScratch {
    /// The links of `model` (springs and the sticks among its force links) and their colouring.
    pub fn new(model: &SimModel) -> XpbdScratch {
        let nf = model.n_free;
        let mut links = Vec::new();
        for k in 0..nf {
            for (i, a) in model.adj_of(k).iter().enumerate() {
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
                let wa = 1.0 / model.mass[k];
                let wb = if j < nf { 1.0 / model.mass[j] } else { 0.0 };
                links.push(Link {
                    a: k as u32,
                    b: a.other,
                    e: model.adj_start[k] + i as u32,
                    rest: a.rest,
                    compliance,
                    c: a.c,
                    wa,
                    wb,
                    at: 0.0,
                    den: 0.0,
                    hc: 0.0,
                    den_damp: 0.0,
                });
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
        let mut colour_of = vec![0usize; links.len()];
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
            colour_of[l] = c;
            slot[c * nf + a] = l as u32;
            above[a] = above[a].max(c + 1);
            if b < nf {
                slot[c * nf + b] = l as u32;
                above[b] = above[b].max(c + 1);
            }
        }
        // Colour-major order, link order within a colour.
        let mut colour_start = vec![0usize; colours + 1];
        for &c in &colour_of {
            colour_start[c + 1] += 1;
        }
        for c in 0..colours {
            colour_start[c + 1] += colour_start[c];
        }
        let mut order: Vec<usize> = (0..links.len()).collect();
        order.sort_by_key(|&l| colour_of[l]); // stable: link order within a colour
        let ordered: Vec<Link> = order.iter().map(|&l| links[l]).collect();
        XpbdScratch {
            lambda: vec![0.0; ordered.len()],
            lambda_damp: vec![Vec3A::ZERO; ordered.len()],
            links: ordered,
            colour_start,
            h: f32::NAN,
            rest_version: model.rest_version,
            dx: vec![Vec3A::ZERO; nf],
        }
    }
}

impl XpbdScratch {
    /// The coloured links as a compute solver reads them (`crate::compute`): per link, colour-major,
    /// its ends, rest length (the model's current one), compliance, viscosity and the ends'
    /// inverse masses; and where each colour starts (`colours + 1` entries).
    pub(crate) fn compute_links(&self, model: &SimModel) -> (Vec<crate::ComputeXpbdLink>, Vec<u32>) {
        let links = self
            .links
            .iter()
            .map(|l| crate::ComputeXpbdLink {
                ends: [l.a, l.b],
                rest: model.adj[l.e as usize].rest,
                compliance: l.compliance,
                c: l.c,
                inv_mass: [l.wa, l.wb],
                entry: l.e,
            })
            .collect();
        (links, self.colour_start.iter().map(|&c| c as u32).collect())
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
    if s.h.to_bits() != h.to_bits() {
        s.links.iter_mut().for_each(|l| l.set_step(h));
        s.h = h;
    }
    if s.rest_version != model.rest_version {
        s.links.iter_mut().for_each(|l| l.rest = model.adj[l.e as usize].rest);
        s.rest_version = model.rest_version;
    }
    // 2. Project, colour by colour, in place.
    let colours = s.colour_start.len().saturating_sub(1);
    if nf > 0 {
        // Symmetric Gauss–Seidel: every iteration sweeps the colours out along the hairs and back.
        let sweep = (0..colours).chain((0..colours.saturating_sub(1)).rev());
        for _ in 0..iterations {
            for c in sweep.clone() {
                let range = s.colour_start[c]..s.colour_start[c + 1];
                let pass = Pass { x, v, h, nf };
                pass.run(&s.links[range.clone()], &mut s.dx, &mut s.lambda[range.clone()], &mut s.lambda_damp[range]);
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
    x: &'a [Vec3A],
    v: &'a [Vec3A],
    h: f32,
    nf: usize,
}

/// The displacement buffer shared by one colour's parallel chunks. Within a colour no free mass
/// has two links, so the chunks read and write disjoint masses.
struct SharedDx {
    ptr: *mut Vec3A,
    len: usize,
}

// SAFETY: only used by `Pass::run`, whose concurrent chunks touch disjoint elements.
unsafe impl Sync for SharedDx {}

impl Pass<'_> {
    /// Projects this colour's `links` (with their multipliers), updating `dx` in place.
    fn run(&self, links: &[Link], dx: &mut [Vec3A], lambda: &mut [f32], lambda_damp: &mut [Vec3A]) {
        if links.len() < PARALLEL_MIN {
            for ((l, lam), ld) in links.iter().zip(lambda.iter_mut()).zip(lambda_damp.iter_mut()) {
                let (a, b) = (l.a as usize, l.b as usize);
                let free_b = b < self.nf;
                let db = if free_b { dx[b] } else { Vec3A::ZERO };
                let (na, nb) = self.link(l, dx[a], db, lam, ld);
                dx[a] = na;
                if free_b {
                    dx[b] = nb;
                }
            }
            return;
        }
        let shared = SharedDx { ptr: dx.as_mut_ptr(), len: dx.len() };
        let shared = &shared;
        links.par_chunks(CHUNK).zip(lambda.par_chunks_mut(CHUNK)).zip(lambda_damp.par_chunks_mut(CHUNK)).for_each(
            |((lc, lamc), ldc)| {
                for ((l, lam), ld) in lc.iter().zip(lamc.iter_mut()).zip(ldc.iter_mut()) {
                    let (a, b) = (l.a as usize, l.b as usize);
                    let free_b = b < self.nf;
                    assert!(a < shared.len && (!free_b || b < shared.len));
                    // SAFETY: `a` and `b` are in bounds (checked above) and belong to this link
                    // only among the colour's links (edge colouring), so no other chunk reads or
                    // writes them during this pass.
                    unsafe {
                        let pa = shared.ptr.add(a);
                        let db = if free_b { *shared.ptr.add(b) } else { Vec3A::ZERO };
                        let (na, nb) = self.link(l, *pa, db, lam, ld);
                        *pa = na;
                        if free_b {
                            *shared.ptr.add(b) = nb;
                        }
                    }
                }
            },
        );
    }

    /// One link projected (distance, then damper) from its ends' displacements `da`, `db` (`db`
    /// zero for an anchored end); returns both ends' next displacements.
    #[inline(always)]
    fn link(
        &self,
        l: &Link,
        mut da: Vec3A,
        mut db: Vec3A,
        lambda: &mut f32,
        lambda_damp: &mut Vec3A,
    ) -> (Vec3A, Vec3A) {
        let (a, b) = (l.a as usize, l.b as usize);
        let free_b = b < self.nf;
        let (wa, wb) = (l.wa, l.wb);
        if l.compliance.is_finite() {
            let d = (self.x[a] - self.x[b]) + (da - db);
            let len = d.length();
            if len > 1e-12 {
                let n = d / len;
                let dl = (-(len - l.rest) - l.at * *lambda) / l.den;
                *lambda += dl;
                da += n * (wa * dl);
                db -= n * (wb * dl);
            }
        }
        if l.c > 0.0 {
            // An anchored end moves, for the damper, with the skin's velocity over the step.
            let moved_b = if free_b { db } else { self.v[b] * self.h };
            let dl = (-*lambda_damp - (da - moved_b) * l.hc) / l.den_damp;
            *lambda_damp += dl;
            da += dl * wa;
            db -= dl * wb;
        }
        (da, db)
    }
}
