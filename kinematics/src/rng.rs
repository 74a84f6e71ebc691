//! A small deterministic PRNG (SplitMix64) for IK restarts and test-target sampling: the same seed
//! always gives the same restarts, so a solve is reproducible on the host and on the board.

use crate::Real;

/// SplitMix64 (Steele, Lea, Flood 2014): 64-bit state, passes BigCrush, no tables.
#[derive(Clone, Copy, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn unit_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lower, upper].
    pub fn uniform<T: Real>(&mut self, lower: T, upper: T) -> T {
        // `unit_f64` rounded to T, computed in T: the 53 bits rounded once to T, then scaled by
        // 2^-53 (exact), the same value bit for bit, without f64 arithmetic when T is f32 (the
        // M4F runs f64 in software).
        let unit = T::of_i64((self.next_u64() >> 11) as i64) * T::of(1.0 / (1u64 << 53) as f64);
        lower + (upper - lower) * unit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `uniform` in f32 is the f64 draw rounded to f32, bit for bit, and in f64 the f64 draw.
    #[test]
    fn a_draw_in_f32_is_the_f64_draw_rounded() {
        let (mut f64s, mut f32s, mut reference) = (SplitMix64::new(7), SplitMix64::new(7), SplitMix64::new(7));
        for _ in 0..100_000 {
            let unit = reference.unit_f64();
            assert_eq!(f64s.uniform(-2.0f64, 3.0), -2.0 + 5.0 * unit);
            assert_eq!(f32s.uniform(0.0f32, 1.0).to_bits(), (unit as f32).to_bits(), "{unit}");
        }
    }
}
