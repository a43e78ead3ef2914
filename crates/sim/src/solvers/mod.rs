//! The solvers' kernels (fur thesis §3.3.2, §3.4.1, and two peers' methods): one step of size `h` from `(x, v)` to
//! `(x_out, v_out)` for the free masses; anchored masses never move. One file per job:
//!
//! - [`explicit`]: explicit Euler, eq. 3.20–3.25, and its stable step (the simulator substeps).
//! - [`implicit`]: the linearised backward-Euler system of eq. 3.26–3.34 with the full 3×3 spring
//!   Jacobian of eq. 3.29: one sweep (the thesis's first iterate of eq. 3.34) or, for two or more
//!   iterations, preconditioned conjugate gradient from that sweep with the sweep's matrix as
//!   preconditioner (monotone convergence to the system's solution).
//! - [`stick`]: the stick solver of §3.4.1 ("orientation only").
//! - [`projection`]: the stick projection every solver applies after its step.
//! - [`reference`]: backward Euler linearised per step with the exact Jacobian of every force,
//!   solved by BiCGSTAB in f64 with an f64 state kept between steps (Baraff & Witkin 1998): the
//!   accuracy report measures everyone else against it.
//! - [`xpbd`]: extended position-based dynamics (Macklin, Müller & Chentanez 2016), the method
//!   NVIDIA Warp and Newton ship: compliant distance constraints and dampers, Gauss–Seidel over
//!   a colouring of the links.
//! - [`local_global`]: the fast mass–spring method of Liu, Bargteil, O'Brien & Kavan 2013:
//!   local/global iterations towards backward Euler of the nonlinear springs, with a prefactored
//!   constant matrix.
//! - [`ldlt`]: the local/global solver's sparse `LDLᵀ` (minimum-degree ordering, f64).
//! - [`fused`]: the one parallel pass per step that runs the explicit, stick and one-sweep
//!   implicit updates eight masses at a time, with the stick projection, the finiteness check,
//!   the wrong-side guard of §3.4.3 and the next rotation limit fused in.
//! - [`lanes`]: the eight-lane SIMD layer the fused pass is written in (AVX2 + FMA after runtime
//!   detection, portable arrays otherwise).
//! - [`rotation`]: the implicit solvers' rotation-limited step (its per-mass formula,
//!   `rotation_step`, sits in [`lanes`] with the lane operations that evaluate it).
//! - [`chunks`]: fixed-chunk parallel loops and sums, so every result is bit-identical for any
//!   rayon thread count.
//!
//! This file holds what they share: the [`Step`] every solver step works on, the
//! [`StepOutcome`] it returns and the per-mass external and restoring forces (eq. 3.37).
//!
//! Determinism: no atomics, no scatter: every mass sums its own links in a fixed order and every
//! sum (guard energy, CG and BiCGSTAB dot products) uses fixed-size chunks combined in order.

mod chunks;
mod explicit;
mod fused;
mod implicit;
mod lanes;
mod ldlt;
mod local_global;
mod projection;
mod reference;
mod rotation;
mod stick;
mod xpbd;

use glam::Vec3A;

use crate::forces::{ForceEval, restoring_force};
use crate::model::SimModel;
use crate::sentinel::NONE;
use crate::shell::{GuardOutcome, GuardSettings, GuardState};

pub(crate) use chunks::{CHUNK, PARALLEL_MIN, sum_over};
pub(crate) use explicit::{explicit_step, stable_step};
pub(crate) use implicit::{ImplicitScratch, Sym3, implicit_step};
pub(crate) use local_global::{LocalGlobalScratch, local_global_step};
pub(crate) use projection::project_sticks;
pub(crate) use reference::{ReferenceScratch, reference_step};
pub(crate) use rotation::rotation_limit;
pub(crate) use stick::stick_step;
pub(crate) use xpbd::{XpbdScratch, xpbd_step};

/// One step of size `h` from `(x, v)` to `(x_out, v_out)`: what every solver step reads, where
/// it writes, and what its end also does. Built by the simulator once per substep.
pub(crate) struct Step<'a> {
    pub model: &'a SimModel,
    /// The forces at the start of the step.
    pub fe: &'a ForceEval<'a>,
    /// Step length, seconds.
    pub h: f32,
    /// Positions (m) and velocities (m/s) at the start, in the model's internal order.
    pub x: &'a [Vec3A],
    pub v: &'a [Vec3A],
    /// Positions and velocities after the step; the free masses are written, anchored ones kept.
    pub x_out: &'a mut [Vec3A],
    pub v_out: &'a mut [Vec3A],
    /// The wrong-side guard (§3.4.3), on a frame step's last substep: run in the step's own pass
    /// where the topology allows (see [`StepOutcome::guard`]), else left to the caller.
    pub guard: Option<(&'a GuardSettings, &'a mut GuardState)>,
    /// `Some(θ)` (implicit and reference solvers): compute the next step's rotation-limited step
    /// for the link-rotation limit `θ` (radians) in the step's own pass where possible.
    pub rotation: Option<f64>,
}

/// What a mass–spring step reports: whether the kernel verified that the new state is finite
/// (false: not verified, or not finite), and the guard's outcome when it ran in the same pass.
pub(crate) struct StepOutcome {
    pub finite: bool,
    pub guard: Option<GuardOutcome>,
    /// The rotation-limited step of the new state, when the kernel computed it.
    pub rotation: Option<f64>,
}

/// The external force on free mass `k` at `xi` moving at `vi` (gravity, wind, object motion,
/// local interaction).
#[inline(always)]
fn external(model: &SimModel, fe: &ForceEval, k: usize, xi: Vec3A, vi: Vec3A) -> Vec3A {
    if fe.uniform_only() { fe.accel * model.mass[k] } else { fe.external(model.mass[k], xi, vi, model.rest[k]) }
}

/// The restoring force (eq. 3.37) on free mass `k` at `xi`, pulling its rest-parent link back
/// towards the rest direction; zero without a restoring link or weight.
#[inline(always)]
fn restoring(model: &SimModel, fe: &ForceEval, x: &[Vec3A], k: usize, xi: Vec3A) -> Vec3A {
    let r = model.rest_parent[k];
    if r == NONE || fe.restoring_w == 0.0 {
        Vec3A::ZERO
    } else {
        restoring_force(x[r as usize], xi, model.rest_n[k], fe.restoring_w)
    }
}
