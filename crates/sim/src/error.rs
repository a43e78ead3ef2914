//! Typed errors of the simulation crate, split by blame: the input mesh or topology (bad input),
//! the caller's settings (parameter), a limit the caller asked us to respect (step too large for
//! the explicit solver without substeps), and numerical failure (non-finite state).

/// What went wrong while building a topology or simulating it.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The skin mesh or the topology is malformed (index out of range, mismatched array lengths,
    /// unsupported structure). Blame: the input.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A setting or force parameter is out of range (negative step, NaN weight, ...). Blame: the caller.
    #[error("invalid parameter {name}: {what}")]
    Parameter {
        /// The parameter's name.
        name: &'static str,
        /// What is wrong with it.
        what: String,
    },
    /// The step exceeds the solver's stable step (explicit and stick: the stiffest spring/mass
    /// ratio; implicit and reference: the link-rotation limit) and substepping was refused or
    /// would need more substeps than allowed. The state is unchanged.
    #[error(
        "step of {dt_s} s exceeds the solver's stable step of {stable_dt_s} s and would need {needed} substeps (allowed: {allowed})"
    )]
    StepTooLarge {
        /// The step asked for, seconds.
        dt_s: f64,
        /// The stable step, seconds.
        stable_dt_s: f64,
        /// Substeps needed.
        needed: u64,
        /// Substeps allowed (1 when substepping is off).
        allowed: u32,
    },
    /// The state became non-finite (NaN or infinite). The state is left as it was at the start of
    /// the failing substep.
    #[error("non-finite state after step {step} at t = {time_s} s: {what}")]
    NonFinite {
        /// Index of the step that failed.
        step: u64,
        /// Simulated time at the start of the failed step, seconds.
        time_s: f64,
        /// Which quantity became non-finite.
        what: String,
    },
    /// The converged reference's BiCGSTAB solve did not reach its tolerance.
    #[error("the reference solver's BiCGSTAB stopped after {iterations} iterations at relative residual {residual:e}")]
    NotConverged {
        /// Iterations run.
        iterations: u32,
        /// Relative residual reached.
        residual: f64,
    },
}
