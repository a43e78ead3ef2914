//! Seed derivation and a small deterministic PRNG (SplitMix64): every stochastic stage draws from
//! a stream derived from the master seed and a stage tag, so stages never share random numbers and
//! the output does not depend on thread count or scheduling.

/// Derives an independent seed for `stage` (and optionally an element index) from `master`.
pub fn derive_seed(master: u64, stage: u64, index: u64) -> u64 {
    let mut s = SplitMix64::new(master ^ stage.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let a = s.next_u64();
    SplitMix64::new(a ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03)).next_u64()
}

/// SplitMix64 (Steele, Lea, Flood 2014): tiny, fast, and good enough for placing hairs.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator starting at `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform `f32` in `[0, 1)`.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
}

/// Stage tags for [`derive_seed`].
pub mod stage {
    /// The hair volume.
    pub const VOLUME: u64 = 1;
    /// The per-triangle UV offsets.
    pub const UV_OFFSETS: u64 = 2;
    /// Grass blade scattering.
    pub const BLADES: u64 = 3;
}
