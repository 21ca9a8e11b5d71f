//! k-means++ draw weights as integers, so partial sums can be kept and reused exactly.
//!
//! A float running sum of `n` distances per draw makes seeding O(nk) however cleverly the
//! distances are updated, and a float sum regrouped into blocks rounds differently. So each
//! squared distance `d` becomes the integer `floor(d * 2^s)`, with `s` chosen once per run so
//! that `n` weights cannot overflow a `u128`; sums are then exact in any grouping, and the draw
//! picks the first point whose prefix sum exceeds a uniform integer target.
//!
//! Resolution: the largest weight has at least `127 - log2(n)` bits, so a distance below
//! `2^-95` of the largest one (for n < 2^32) weighs nothing and is never drawn. In a cloud that
//! is far below the f32 resolution of its coordinates, so no real cloud can notice.

use crate::rng::Pcg32;
use rand_core::Rng;

/// Points per partial sum in the accelerated draw.
pub const BLOCK: usize = 256;

/// Number of block sums for `n` points.
pub const fn blocks_for(n: usize) -> usize {
    n.div_ceil(BLOCK)
}

/// The largest squared distance to the first centre seeding accepts (`2^120`): two points of
/// the cloud are then at most `4 * 2^120` apart squared, far from f32 overflow, so no distance
/// the seeding or Lloyd computes is infinite.
pub const MAX_SQUARED: f32 = f32::from_bits((127 + 120) << 23);

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WeightScale {
    /// `2^s`, exact.
    factor: f64,
}

impl WeightScale {
    /// The scale for `n` points whose squared distances never exceed `max_squared` (finite,
    /// positive, at most `MAX_SQUARED`).
    pub fn new(max_squared: f32, n: usize) -> Self {
        // max_squared < 2^e_max.
        let bits = max_squared.to_bits();
        let biased = ((bits >> 23) & 0xff) as i32;
        let e_max = if biased == 0 {
            // Subnormal: m * 2^-149 with m < 2^23.
            (u32::BITS - (bits & 0x7f_ffff).leading_zeros()) as i32 - 149
        } else {
            biased - 126
        };
        let n_bits = (usize::BITS - n.leading_zeros()) as i32;
        // n weights below 2^(127 - n_bits) each sum below 2^127.
        let s = 127 - n_bits - e_max;
        // s lies in [-65, 275], well inside f64's normal exponents.
        let factor = f64::from_bits(((s + 1023) as u64) << 52);
        Self { factor }
    }

    #[inline]
    pub fn weight(&self, squared: f32) -> u128 {
        // Exact product (power of two), truncated toward zero: floor for d >= 0.
        (squared as f64 * self.factor) as u128
    }
}

/// A uniform integer in `[0, total)` for `total > 0`: `floor(m * total / 2^53)` with `m` the 53
/// random bits that `rng::uniform` also uses, computed exactly in two 64-bit halves.
pub fn draw_target(rng: &mut Pcg32, total: u128) -> u128 {
    let m = (rng.next_u64() >> 11) as u128;
    let high = total >> 64;
    let low = total & u64::MAX as u128;
    // (m * high * 2^64 + m * low) >> 53, each product below 2^117.
    ((m * high) << 11) + ((m * low) >> 53)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream_rng;

    #[test]
    fn weights_of_n_points_cannot_overflow() {
        for &(max, n) in &[
            (1.0f32, 1usize),
            (3.7e2, 239_000),
            (MAX_SQUARED, usize::MAX >> 1),
            (1e-40, 5),
            (f32::MIN_POSITIVE, 1 << 20),
        ] {
            let scale = WeightScale::new(max, n);
            let w = scale.weight(max);
            assert!(w > 0, "{max} {n}");
            let total = w.checked_mul(n as u128);
            assert!(total.is_some_and(|t| t < 1u128 << 127), "{max} {n}");
            // The largest weight keeps at least 127 - log2(n) - 1 bits.
            let n_bits = usize::BITS - n.leading_zeros();
            assert!(w >= 1u128 << (126 - n_bits), "{max} {n}");
        }
        assert_eq!(MAX_SQUARED, 2f32.powi(120));
    }

    #[test]
    fn targets_stay_below_the_total_and_match_the_float_draw() {
        let mut a = stream_rng(3, 9);
        let mut b = stream_rng(3, 9);
        for total in [1u128, 2, 1000, u64::MAX as u128 + 7, (1u128 << 127) - 1] {
            for _ in 0..1000 {
                let t = draw_target(&mut a, total);
                assert!(t < total);
                // Same draw as rng::uniform(rng) * total, up to the f64 rounding of the latter.
                let u = crate::rng::uniform(&mut b);
                let f = u * total as f64;
                assert!((t as f64 - f).abs() <= 1.0 + f * 1e-15, "{t} vs {f}");
            }
        }
    }
}
