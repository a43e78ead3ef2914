//! The stick solver (fur thesis §3.4.1, "orientation only") and the stick projection. Every link
//! from an anchored root is a rigid stick: external and remaining spring forces move the mass
//! explicitly (eq. 3.20–3.25), the parent link's damping (eq. 3.24) is implicit, then the mass is
//! put back at the stick's length from its parent, level by level from the skin, and its velocity
//! along the stick is removed (the stick projection, `projection.rs`, which the mass–spring
//! solvers also run after their step; the fused pass, `fused.rs`, does it in-line when every
//! stick ends at an anchored mass).

use super::fused::{Mode, group_step};
use super::{Step, StepOutcome};

/// One stick-solver step: explicit forces, implicit parent damping
/// `v' = (v + h F/m + a v_parent)/(1 + a)`, `a = h c/m`, then projection. Runs the step's guard
/// in the same pass where it can.
pub(crate) fn stick_step(step: Step) -> StepOutcome {
    group_step(step, Mode::Stick, &[])
}
