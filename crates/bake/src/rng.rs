//! Seeds of the bake stages: every stochastic stage draws from a stream derived from the master
//! seed and a stage tag, so stages never share random numbers and the output does not depend on
//! thread count or scheduling. The generator (SplitMix64) and the derivation are the grass
//! crate's, shared rather than copied.

pub use furbake_grass::rng::{SplitMix64, derive_seed};

/// Stage tags for [`derive_seed`].
pub mod stage {
    /// The hair volume.
    pub const VOLUME: u64 = 1;
    /// The per-triangle UV offsets.
    pub const UV_OFFSETS: u64 = 2;
    /// Grass blade scattering.
    pub const BLADES: u64 = 3;
}
