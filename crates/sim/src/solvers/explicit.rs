//! The explicit mass–spring solver (fur thesis §3.3.2, eq. 3.20–3.25): forces at `t` (Hooke
//! eq. 3.23, viscosity eq. 3.24, external forces), `v(t+h) = v + h M⁻¹F` (eq. 3.21–3.22),
//! `p(t+h) = p + h v(t+h)` (eq. 3.20). The update itself runs in the fused lane-group pass
//! (`fused.rs`); this file holds its entry point and its stable step, below which the simulator
//! substeps.

use super::fused::{Mode, group_step};
use super::{Step, StepOutcome};
use crate::model::SimModel;
use crate::sentinel::NONE;

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

/// One explicit Euler step (eq. 3.20–3.25). Runs the step's guard in the same pass where it can.
pub(crate) fn explicit_step(step: Step) -> StepOutcome {
    group_step(step, Mode::Explicit, &[])
}
