//! A small deterministic random source (xorshift64*, seeded through splitmix64) and the
//! "interesting values" every mutator draws from. Case `i` of a campaign with seed `s` always
//! draws the same numbers ([`Rng::for_case`]), so a failure is reproduced from `(s, i)` alone.

/// xorshift64* — fast, tiny, good enough to pick mutations (not for cryptography).
#[derive(Clone, Debug)]
pub struct Rng(u64);

fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    /// A generator seeded with `seed` (any value, zero included).
    pub fn new(seed: u64) -> Rng {
        Rng(splitmix64(seed) | 1)
    }

    /// The generator of case `case` of the campaign seeded `seed`.
    pub fn for_case(seed: u64, case: u64) -> Rng {
        Rng::new(splitmix64(seed) ^ splitmix64(case.wrapping_mul(0xA24B_AED4_963E_E407)))
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next_u64() % n as u64) as usize }
    }

    /// True with probability `num / den`.
    pub fn chance(&mut self, num: u32, den: u32) -> bool {
        self.below(den as usize) < num as usize
    }

    /// One element of `items` (which must not be empty).
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }

    /// An interesting `u32`: boundaries, small numbers, powers of two, near-overflow values.
    pub fn interesting_u32(&mut self, near: u32) -> u32 {
        match self.below(10) {
            0 => *self.pick(&[0, 1, 2, 3, 7, 15, 16, 255, 256, 4096, 8191, 65_535, 65_536, 1 << 20, 1 << 24]),
            1 => *self.pick(&[u32::MAX, u32::MAX - 1, i32::MAX as u32, 0x8000_0000, 0x4000_0000]),
            2 => near.wrapping_add(1),
            3 => near.wrapping_sub(1),
            4 => near.wrapping_mul(2),
            5 => near / 2,
            6 => near.wrapping_add(self.below(64) as u32),
            7 => 1 << self.below(32),
            8 => self.next_u64() as u32,
            _ => near.wrapping_mul(1000).max(1),
        }
    }

    /// An interesting `u64` (the `u32` ones, and values that overflow offset arithmetic).
    pub fn interesting_u64(&mut self, near: u64) -> u64 {
        match self.below(6) {
            0 => *self.pick(&[u64::MAX, u64::MAX - 15, 1 << 63, 1 << 40, (1 << 32) + 16]),
            1 => near.wrapping_add(16),
            2 => near.wrapping_sub(16),
            3 => near.wrapping_mul(3),
            _ => self.interesting_u32(near as u32) as u64,
        }
    }

    /// An interesting `f32`: non-finite, extreme, negative, zero, subnormal, or a nudge of `near`.
    pub fn interesting_f32(&mut self, near: f32) -> f32 {
        match self.below(8) {
            0 => *self.pick(&[f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -f32::NAN]),
            1 => *self.pick(&[
                f32::MAX,
                f32::MIN,
                3e38,
                1e20,
                1e7,
                1.0000001e7,
                1e6,
                1e-6,
                1e-13,
                1e-45,
                f32::MIN_POSITIVE,
            ]),
            2 => *self.pick(&[0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 1.01, 0.99]),
            3 => -near,
            4 => near * 1e6,
            5 => near * 1e-6,
            6 => near + (self.below(1000) as f32 - 500.0) * 1e-3 * near.abs().max(1.0),
            _ => f32::from_bits(self.next_u64() as u32),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_are_reproducible_and_distinct() {
        let a: Vec<u64> = (0..4).map(|_| Rng::for_case(7, 3).next_u64()).collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        assert_ne!(Rng::for_case(7, 3).next_u64(), Rng::for_case(7, 4).next_u64());
        assert_ne!(Rng::for_case(7, 3).next_u64(), Rng::for_case(8, 3).next_u64());
        let mut r = Rng::new(0);
        assert!((0..1000).all(|_| r.below(10) < 10));
    }
}
