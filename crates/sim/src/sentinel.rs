//! The sentinel of the per-mass `u32` tables (the link graph's, the model's, the lane groups'
//! and the solvers'), below every module that reads them.

/// Marks "none" in the per-mass `u32` tables.
pub(crate) const NONE: u32 = u32::MAX;
