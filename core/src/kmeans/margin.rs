//! Rigorous bounds on distances despite f32 rounding, so pruning never changes an answer.
//!
//! The plain search compares `fl(D^2)`, the f32 value of `dx*dx + dy*dy + dz*dz` with
//! `dx = fl(x - c_x)` (no fused multiply-add: Rust never contracts). Each of its five roundings
//! is relative (`u = 2^-24`) except where a square underflows, so for the true distance `d`:
//!
//! `(1 - EPS) d^2 - ETA <= fl(D^2) <= (1 + EPS) d^2 + ETA`, with `EPS = 6u` and `ETA = 2^-140`.
//!
//! The accelerated searches keep bounds on *true* distances (the triangle inequality holds for
//! those, not for rounded values) and convert with the helpers below, each of which leaves a
//! margin of `2^-20`, sixteen times the rounding it must cover. A pruning decision is taken only
//! when it holds with that margin; anything closer falls back to the exact scan.

use crate::geometry::Point3;

/// `1 + 2^-20` and `1 - 2^-20`, exact in f32.
const UP: f32 = 1.0 + 1.0 / 1_048_576.0;
const DOWN: f32 = 1.0 - 1.0 / 1_048_576.0;
/// Absolute slack for distances so small that the squares underflow (`2^-60`, `2^-50`).
const TINY: f32 = f32::from_bits((127 - 60) << 23);
const SEPARABLE: f32 = f32::from_bits((127 - 50) << 23);

/// The squared distance exactly as the plain search computes it.
#[inline]
pub fn squared(p: Point3, c: Point3) -> f32 {
    p.distance_squared(c)
}

/// An upper bound on the true distance of a pair whose computed `fl(D^2)` is `sq`.
#[inline]
pub fn upper(sq: f32) -> f32 {
    libm::sqrtf(sq) * UP + TINY
}

/// A lower bound on the true distance of a pair whose computed `fl(D^2)` is `sq` (0 at worst).
#[inline]
pub fn lower(sq: f32) -> f32 {
    (libm::sqrtf(sq) * DOWN - TINY).max(0.0)
}

/// A lower bound on `a - b`, clamped at 0 (a distance is never negative).
#[inline]
pub fn sub_down(a: f32, b: f32) -> f32 {
    ((a - b) * DOWN).max(0.0)
}

/// True when any pair no farther than `near` (true distance) is sure to get a strictly smaller
/// `fl(D^2)` than any pair at least `far` away, so the plain search could not have preferred
/// the far one, even on a tie.
#[inline]
pub fn surely_nearer(near: f32, far: f32) -> bool {
    near * UP < far * DOWN && far > SEPARABLE
}

/// A squared centre distance from which a cluster of true radius `radius` is surely out of
/// reach: for `fl(D^2(c_j, c)) >= skip_squared(r_j)`, every point within `r_j` of `c_j` is surely
/// nearer to `c_j` than to `c` (`surely_nearer(r, lower(sq) - r)`, checked at the returned value;
/// it is monotone in `sq`, so it holds above). Saves a square root per centre pair in seeding.
pub fn skip_squared(radius: f32) -> f32 {
    let holds = |sq: f32| surely_nearer(radius, sub_down(lower(sq), radius));
    let guess = 2.0001 * radius;
    let mut sq = (guess * guess).max(16.0 * SEPARABLE * SEPARABLE);
    for _ in 0..8 {
        if holds(sq) {
            return sq;
        }
        sq *= 2.0;
    }
    f32::INFINITY
}

/// True when every centre whose true squared distance is at least that of a box with computed
/// squared distance `box_sq` gets a computed `fl(D^2)` strictly above `sq`.
#[inline]
pub fn box_beyond(box_sq: f32, sq: f32) -> bool {
    box_sq * (DOWN * DOWN) > sq * (UP * UP) + SEPARABLE * SEPARABLE
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_are_the_powers_of_two_they_claim() {
        assert_eq!(UP, 1.0 + 2f32.powi(-20));
        assert_eq!(DOWN, 1.0 - 2f32.powi(-20));
        assert_eq!(TINY, 2f32.powi(-60));
        assert_eq!(SEPARABLE, 2f32.powi(-50));
    }

    /// An f64 check of the error model: the bounds must enclose the exact distance of many
    /// f32 pairs, including nearly equal and subnormal-scale ones.
    #[test]
    fn bounds_enclose_the_exact_distance() {
        let mut s = 7u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        for scale in [1e-30f64, 1e-12, 1e-3, 1.0, 1e4, 1e12] {
            for _ in 0..20_000 {
                let p = Point3::new(
                    (next() * scale) as f32,
                    (next() * scale) as f32,
                    (next() * scale) as f32,
                );
                let q = Point3::new(
                    p.x + (next() * scale * 1e-3) as f32,
                    (next() * scale) as f32,
                    p.z,
                );
                let exact = {
                    let (a, b) = (p.to_f64(), q.to_f64());
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
                };
                let sq = squared(p, q);
                assert!(upper(sq) as f64 >= exact, "{p:?} {q:?}");
                assert!(lower(sq) as f64 <= exact, "{p:?} {q:?}");
            }
        }
    }

    #[test]
    fn skip_thresholds_are_proved_and_tight() {
        for r in [0.0f32, TINY, 1e-20, 1e-6, 0.01, 1.0, 37.5, 1e15] {
            let t = skip_squared(r);
            for sq in [t, t * 1.5, t * 1e6] {
                assert!(surely_nearer(r, sub_down(lower(sq), r)), "r {r}, sq {sq}");
            }
            // Within 1% of the exact (2r)^2 beyond the underflow range.
            if r >= 1e-6 {
                assert!(t <= 4.0 * r * r * 1.01, "r {r}: {t}");
            }
        }
    }

    #[test]
    fn decisions_need_a_margin() {
        assert!(surely_nearer(1.0, 1.001));
        assert!(!surely_nearer(1.0, 1.0));
        assert!(!surely_nearer(1.0, 1.0 + 1e-7));
        assert!(!surely_nearer(0.0, 0.0));
        assert!(surely_nearer(1.0, f32::INFINITY));
        assert!(!surely_nearer(f32::INFINITY, f32::INFINITY));
        assert!(box_beyond(1.001, 1.0));
        assert!(!box_beyond(1.0, 1.0));
        assert!(!box_beyond(0.0, 0.0));
        assert!(sub_down(3.0, 1.0) < 2.0);
        assert_eq!(sub_down(1.0, 3.0), 0.0);
    }
}
