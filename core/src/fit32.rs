//! Eq. 12 in single precision without cancellation, and the DE that searches it.
//!
//! Why: a Cortex-M4F has an FPU for f32 only, so every f64 operation of a fit is a software
//! routine of tens of instructions, and a DE fit evaluates eq. 12 510 times. The raw moment form
//! `1 - 2 w.E[q] + w^T E[q q^T] w` cannot simply be narrowed: its terms are O(1) and a good fit
//! makes their sum small, so f32 loses the 1e-4 agreement with a direct sum.
//!
//! The form evaluated here has no such difference. With `m = E[q]` and `C = Cov(q)`,
//! `E[g^2] = ((1 - w.m)^2 + w^T C w) / 4`, and `C` is positive semi-definite, so `w^T C w =
//! |L^T w|^2` with `C = L L^T`. `C` and its Cholesky factor are computed once per fit in f64,
//! from the central moments; each evaluation is then a sum of four squares of short f32 dot
//! products, whose rounding error is relative to the square root of each term, not to the
//! O(1) terms the raw form subtracts. Near a perfect fit the residual then carries about 1e-8
//! absolute error, as the f64 raw form already did.
//!
//! Everything is expressed in units of the cluster's RMS radius `s` (`r' = r / s`), so the
//! numbers a fit sees are O(1) whatever the cloud's unit and f32's range is never a concern.

use crate::de::{DeParams, OutOfBounds};
use crate::fitness::FitnessTerms;
use rand_core::Rng;

/// The square root in f32 arithmetic alone: a bit-pattern guess, then three Newton steps.
///
/// Why not `libm::sqrtf`: on thumbv7em it is a software routine of a few hundred instructions
/// (libm has no ARM32 path, and core has no stable `f32::sqrt`), where this is three hardware
/// divisions and six other operations. Its result is within an ulp or two rather than
/// correctly rounded, but it is made of IEEE operations only, so it is the same bits on every
/// target, which is what the map needs. Below f32's normal range it returns 0 (the error is
/// under 1.1e-19, far below any fitness eq. 12 can resolve).
#[inline]
pub fn sqrt32(x: f32) -> f32 {
    if !(x >= f32::MIN_POSITIVE) {
        return if x >= 0.0 { 0.0 } else { f32::NAN };
    }
    if x == f32::INFINITY {
        return x;
    }
    // Halving the exponent bits guesses within 3.5%; each step squares the relative error.
    let mut y = f32::from_bits(0x1fbd_1df5 + (x.to_bits() >> 1));
    y = 0.5 * (y + x / y);
    y = 0.5 * (y + x / y);
    0.5 * (y + x / y)
}

/// Eq. 12 for semi-axes in units of `s`, ready for f32 evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fitness32 {
    /// `alpha / 2`: eq. 12's residual is `sqrt(E[g^2]) = sqrt(4 E[g^2]) / 2`.
    half_alpha: f32,
    /// `E[q'] = E[d^2] / s^2`.
    mean_q: [f32; 3],
    /// Lower-triangular `L` of `Cov(q') = L L^T`, by rows: `l00, l10, l11, l20, l21, l22`.
    chol: [f32; 6],
    /// Multiplies `r'_x r'_y r'_z` (the volume term is in the cloud's units: `s^3` folded in).
    volume_scale: f32,
    /// The sphere's problem in f64: `sum_j E[q'_j]`, `1^T Cov(q') 1`, the volume scale and
    /// `alpha / 2` ([`Fitness32::optimal_sphere`]).
    sphere: [f64; 4],
}

/// The Cholesky factor of a symmetric positive semi-definite 3x3 matrix, by rows. A pivot that
/// rounding made zero or negative leaves its column zero, the factor of the nearest PSD matrix
/// with that column's variance gone (a coplanar cluster, two points).
fn cholesky_psd(c: [[f64; 3]; 3]) -> [f64; 6] {
    let root = |v: f64| if v > 0.0 { libm::sqrt(v) } else { 0.0 };
    let over = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
    let l00 = root(c[0][0]);
    let l10 = over(c[1][0], l00);
    let l20 = over(c[2][0], l00);
    let l11 = root(c[1][1] - l10 * l10);
    let l21 = over(c[2][1] - l20 * l10, l11);
    let l22 = root(c[2][2] - l20 * l20 - l21 * l21);
    [l00, l10, l11, l20, l21, l22]
}

impl Fitness32 {
    /// From the f64 terms of one cluster whose RMS radius is `s > 0`.
    pub fn new(terms: &FitnessTerms, s: f64) -> Self {
        let s2 = s * s;
        let mean = terms.second.map(|v| v / s2);
        // Cov(q') = E[q' q'^T] - E[q'] E[q']^T, once per fit in f64.
        let mut cov = [[0.0; 3]; 3];
        for j in 0..3 {
            for k in 0..3 {
                cov[j][k] = terms.fourth[j][k] / (s2 * s2) - mean[j] * mean[k];
            }
        }
        let volume_scale = terms.volume_scale * s2 * s;
        let spread: f64 = cov.iter().flatten().sum();
        Self {
            sphere: [
                mean[0] + mean[1] + mean[2],
                spread,
                volume_scale,
                0.5 * terms.alpha,
            ],
            half_alpha: (0.5 * terms.alpha) as f32,
            mean_q: mean.map(|v| v as f32),
            chol: cholesky_psd(cov).map(|v| v as f32),
            volume_scale: volume_scale as f32,
        }
    }

    /// The radius, in units of `s` and within `[lo, hi]`, of the sphere minimising eq. 12.
    ///
    /// In `w = 1/r'^2` eq. 12 is convex (the root of a convex quadratic plus `V w^(-3/2)`), so
    /// its minimum is the root of its derivative, found by Newton's method inside a bracket,
    /// from `start`. Why a root and not a search for the minimum: a minimum's position is only
    /// determined to the square root of the arithmetic's precision (1e-8 in f64, 2e-4 in f32),
    /// a root of the derivative to the precision itself, so this radius is the same number,
    /// to f32's rounding, that an independent computation finds (the DE starts from it).
    pub fn optimal_sphere(&self, lo: f64, hi: f64, start: f64) -> f64 {
        let [m, q, v, half_alpha] = self.sphere;
        // Eq. 12's first and second derivatives in w.
        let derivatives = |w: f64| {
            let a = 1.0 - w * m;
            let e4 = a * a + w * w * q;
            let root = libm::sqrt(e4);
            let slope = w * q - m * a;
            let w_root = w * libm::sqrt(w);
            let (d1, d2) = if root > 0.0 {
                (
                    half_alpha * slope / root,
                    half_alpha * ((m * m + q) * e4 - slope * slope) / (e4 * root),
                )
            } else {
                (0.0, 0.0)
            };
            (
                d1 - 1.5 * v / (w * w_root),
                d2 + 3.75 * v / (w * w * w_root),
            )
        };
        let (mut a, mut b) = (1.0 / (hi * hi), 1.0 / (lo * lo));
        if !(derivatives(a).0 < 0.0) {
            return hi;
        }
        if !(derivatives(b).0 > 0.0) {
            return lo;
        }
        let mut w = 1.0 / (start * start);
        if !(w > a && w < b) {
            w = 0.5 * (a + b);
        }
        // Newton converges in about 3 steps from the f32 search's start; bisection guards it.
        for _ in 0..100 {
            let (d1, d2) = derivatives(w);
            if d1 < 0.0 {
                a = w;
            } else if d1 > 0.0 {
                b = w;
            } else {
                break;
            }
            let newton = w - d1 / d2;
            // Converged: the step no longer moves w (to 1e-13, far below f32's 6e-8, so the
            // DE's start is the root's f32 rounding). Checked before the bracket, which the
            // converged step may sit on.
            if (newton - w).abs() <= 1e-13 * w {
                w = newton;
                break;
            }
            w = if newton > a && newton < b {
                newton
            } else {
                0.5 * (a + b)
            };
            if !(b - a > 1e-13 * w) {
                break;
            }
        }
        1.0 / libm::sqrt(w)
    }

    /// Eq. 12 at semi-axes `r' = r / s`.
    #[inline]
    pub fn fitness(&self, r: &[f32; 3]) -> f32 {
        let w = r.map(|v| 1.0 / (v * v));
        let [l00, l10, l11, l20, l21, l22] = self.chol;
        let a = 1.0 - (w[0] * self.mean_q[0] + w[1] * self.mean_q[1] + w[2] * self.mean_q[2]);
        let b0 = l00 * w[0] + l10 * w[1] + l20 * w[2];
        let b1 = l11 * w[1] + l21 * w[2];
        let b2 = l22 * w[2];
        let four_mean_square = a * a + b0 * b0 + b1 * b1 + b2 * b2;
        self.half_alpha * sqrt32(four_mean_square) + self.volume_scale * (r[0] * r[1] * r[2])
    }
}

/// `x.clamp(lo, hi)` without the standard one's panicking assertion; NaN passes through.
#[inline]
fn clamp32(x: f32, lo: f32, hi: f32) -> f32 {
    let mut x = x;
    if x < lo {
        x = lo;
    }
    if x > hi {
        x = hi;
    }
    x
}

/// Uniform in [0, 1) from one 32-bit draw, with the 24 bits an f32 holds (exact conversion).
#[inline]
fn unit<R: Rng + ?Sized>(rng: &mut R) -> f32 {
    (rng.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Crossover decisions are 10-bit slices of one 32-bit draw: this many bits each, so up to three
/// coordinates share a draw.
const CROSS_BITS: u32 = 10;

/// The largest 10-bit slice that counts as "at most `rate`" (`u / 2^10 <= rate`), so a crossover
/// decision is one integer comparison: for CR = 0.7, 716, a rate of 717/1024 = 0.70020. A
/// slice is taken even when every slice passes (rate 1), so the stream stays in step with the
/// reference's.
fn rate_threshold(rate: f64) -> u32 {
    let top = (1u32 << CROSS_BITS) as f64;
    let scaled = rate * top;
    if scaled >= top - 1.0 {
        (1 << CROSS_BITS) - 1
    } else if scaled >= 0.0 {
        libm::floor(scaled) as u32
    } else {
        // No slice is at most a negative bound; 0 is the nearest an integer threshold gets.
        0
    }
}

/// `n` uniform outcomes from the high bits of `x` by Lemire's multiply-shift, leaving the low
/// 32 bits of the product in `x` for the next split (each split's bias is at most the product
/// of the earlier `n`s over 2^32: 1,512 / 2^32 = 3.5e-7 for a population of 10).
#[inline]
fn split(x: &mut u32, n: usize) -> usize {
    let t = u64::from(*x) * n as u64;
    *x = t as u32;
    (t >> 32) as usize
}

/// One trial's random choices from two 32-bit draws: the three donors, distinct from each other
/// and from `target` (uniform among the `POP - 1`, `POP - 2`, `POP - 3` left), and the forced
/// coordinate, all split from the first draw; the crossover slices are the second draw's bits
/// from the top, 10 per coordinate. Before, each of these was a draw of its own (7 a trial, each
/// a 64-bit multiply-add on a 32-bit core); two save about 20,000 instructions a fit on the
/// Cortex-M4F image (README, "Firmware").
#[inline]
fn trial_draws<const POP: usize, const D: usize, R: Rng + ?Sized>(
    target: usize,
    rng: &mut R,
) -> ([usize; 3], usize, u32) {
    let mut x = rng.next_u32();
    let k1 = split(&mut x, POP - 1);
    let k2 = split(&mut x, POP - 2);
    let k3 = split(&mut x, POP - 3);
    let forced = split(&mut x, D);
    // The k-th index not yet taken: step over the taken ones in increasing order.
    let r1 = k1 + usize::from(k1 >= target);
    let (a, b) = if r1 < target {
        (r1, target)
    } else {
        (target, r1)
    };
    let mut r2 = k2;
    r2 += usize::from(r2 >= a);
    r2 += usize::from(r2 >= b);
    let (a, b, c) = if r2 < a {
        (r2, a, b)
    } else if r2 < b {
        (a, r2, b)
    } else {
        (a, b, r2)
    };
    let mut r3 = k3;
    r3 += usize::from(r3 >= a);
    r3 += usize::from(r3 >= b);
    r3 += usize::from(r3 >= c);
    // All < POP already; the min lets the compiler drop the population's bounds checks.
    (
        [r1.min(POP - 1), r2.min(POP - 1), r3.min(POP - 1)],
        forced,
        rng.next_u32(),
    )
}

fn repair<R: Rng + ?Sized>(value: f32, lo: f32, hi: f32, rule: OutOfBounds, rng: &mut R) -> f32 {
    if value >= lo && value <= hi {
        return value;
    }
    match rule {
        OutOfBounds::Clamp => clamp32(value, lo, hi),
        OutOfBounds::Reflect => {
            let mirrored = if value < lo {
                2.0 * lo - value
            } else {
                2.0 * hi - value
            };
            if hi > lo {
                clamp32(mirrored, lo, hi)
            } else {
                lo
            }
        }
        OutOfBounds::Resample => lo + unit(rng) * (hi - lo),
    }
}

/// A NaN fitness never wins, so a broken objective cannot take over the population.
#[inline]
fn no_worse(candidate: f32, incumbent: f32) -> bool {
    candidate <= incumbent || (incumbent.is_nan() && !candidate.is_nan())
}

/// What a DE run found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct De32Result<const D: usize> {
    pub best: [f32; D],
    pub fitness: f32,
    pub evaluations: u32,
}

/// DE/rand/1/bin (eqs. 7-9) over the box `[lo, hi]^D` in f32, the paper's algorithm as
/// [`crate::de::minimize`] runs it: synchronous generations, selection by `<=`, the seed
/// candidate replacing the first random member. The draws, in order: `D` per initial member
/// (24-bit uniforms), then two per trial (`trial_draws`): one split into the three donors and
/// the forced coordinate, one whose 10-bit slices decide the crossovers (`D <= 3`).
pub fn minimize32<const D: usize, const POP: usize, R, F>(
    objective: F,
    lo: f32,
    hi: f32,
    params: &DeParams,
    out_of_bounds: OutOfBounds,
    seed_candidate: Option<[f32; D]>,
    rng: &mut R,
) -> De32Result<D>
where
    R: Rng + ?Sized,
    F: Fn(&[f32; D]) -> f32,
{
    const {
        assert!(
            POP >= 4,
            "DE/rand/1 needs the target and three distinct others"
        )
    };
    let mutation = params.mutation as f32;
    let crossover = rate_threshold(params.crossover);
    const { assert!(D >= 1 && D <= 3, "one draw holds three crossover slices") };
    let mut population = [[0.0f32; D]; POP];
    let mut scores = [f32::INFINITY; POP];
    let mut evaluations = 0u32;
    for (member, score) in population.iter_mut().zip(scores.iter_mut()) {
        for x in member.iter_mut() {
            *x = lo + unit(rng) * (hi - lo);
        }
        *score = objective(member);
        evaluations += 1;
    }
    if let (Some(seed), Some(first), Some(first_score)) =
        (seed_candidate, population.first_mut(), scores.first_mut())
    {
        *first = seed.map(|s| if s.is_nan() { lo } else { clamp32(s, lo, hi) });
        *first_score = objective(first);
        evaluations += 1;
    }

    let mut next = population;
    let mut next_scores = scores;
    for _ in 0..params.generations {
        for (i, (slot, slot_score)) in next.iter_mut().zip(next_scores.iter_mut()).enumerate() {
            let ([r1, r2, r3], forced, mut slices) = trial_draws::<POP, D, R>(i, rng);
            let current = population.get(i).copied().unwrap_or([lo; D]);
            let current_score = scores.get(i).copied().unwrap_or(f32::NAN);
            // r1, r2, r3 < POP by construction; `get` keeps a bounds-check panic out of the build.
            let [x1, x2, x3] = [r1, r2, r3].map(|r| population.get(r).copied().unwrap_or(current));
            let mut trial = current;
            for j in 0..D {
                let slice = slices >> (32 - CROSS_BITS);
                slices <<= CROSS_BITS;
                let cross = j == forced || slice <= crossover;
                if cross {
                    let donor = x1[j] + mutation * (x2[j] - x3[j]);
                    trial[j] = repair(donor, lo, hi, out_of_bounds, rng);
                }
            }
            let score = objective(&trial);
            evaluations += 1;
            if no_worse(score, current_score) {
                *slot = trial;
                *slot_score = score;
            } else {
                *slot = current;
                *slot_score = current_score;
            }
        }
        population = next;
        scores = next_scores;
    }

    // Strictly better only, so ties keep the lowest index and the result is order-stable.
    let mut best = 0;
    let mut best_score = scores.first().copied().unwrap_or(f32::NAN);
    for (i, &s) in scores.iter().enumerate().skip(1) {
        if no_worse(s, best_score) && s != best_score {
            best = i;
            best_score = s;
        }
    }
    De32Result {
        best: population.get(best).copied().unwrap_or([lo; D]),
        fitness: best_score,
        evaluations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fitness::VolumeTerm;
    use crate::moments::Moments;
    use crate::rng::stream_rng;
    use crate::test_support::{OrFail, TestResult};

    #[test]
    fn f32_fitness_agrees_with_the_f64_form_on_a_near_perfect_fit() -> TestResult {
        // A thin noisy shell, far from the origin: the raw form's hard case.
        let mut m = Moments::new();
        let mut state = 5u64;
        for i in 0..500 {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            let noise = ((state >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 1e-3;
            let (t, u) = (i as f64 * 0.37, i as f64 * 0.11);
            m.add_f64([
                100.0 + 0.3 * (1.0 + noise) * libm::cos(t) * libm::sin(u),
                -40.0 + 0.2 * libm::sin(t) * libm::sin(u),
                7.0 + 0.1 * libm::cos(u),
            ]);
        }
        let central = m.central().or_fail("points")?;
        let terms = FitnessTerms::new(&central, 0.8, VolumeTerm::Exact);
        let s = central.rms_radius();
        let fast = Fitness32::new(&terms, s);
        for r in [
            [0.3, 0.2, 0.1],
            [0.31, 0.19, 0.1],
            [0.5, 0.5, 0.5],
            [0.05, 2.0, 0.01],
        ] {
            let want = terms.fitness(&r);
            let got = f64::from(fast.fitness(&r.map(|v| (v / s) as f32)));
            // The semi-axes themselves are rounded to f32 (6e-8), which moves eq. 12 by a few
            // times that; the evaluation adds its own rounding on top, at the same level.
            if (got - want).abs() > 1e-5 * want + 1e-8 {
                return Err("f32 fitness differs from the f64 form");
            }
        }
        Ok(())
    }

    #[test]
    fn sqrt32_is_within_two_ulps_of_the_correctly_rounded_root() {
        let mut x = 1e-37f32;
        while x < 1e37 {
            for m in [1.0f32, 1.3, 2.0, 2.9, 3.7] {
                let v = x * m;
                let exact = libm::sqrtf(v);
                let got = sqrt32(v);
                let ulps = (got.to_bits() as i64 - exact.to_bits() as i64).abs();
                assert!(ulps <= 2, "{v}: {got} vs {exact}");
            }
            x *= 3.1;
        }
        assert_eq!(sqrt32(0.0), 0.0);
        assert_eq!(sqrt32(f32::INFINITY), f32::INFINITY);
        assert!(sqrt32(-1.0).is_nan() && sqrt32(f32::NAN).is_nan());
    }

    #[test]
    fn cholesky_of_a_singular_matrix_reproduces_it() {
        // Rank one: the second and third pivots vanish.
        let v = [1.0, 2.0, -0.5];
        let c = [0, 1, 2].map(|j| [0, 1, 2].map(|k| v[j] * v[k]));
        let [l00, l10, l11, l20, l21, l22] = cholesky_psd(c);
        let l = [[l00, 0.0, 0.0], [l10, l11, 0.0], [l20, l21, l22]];
        for j in 0..3 {
            for k in 0..3 {
                let back: f64 = (0..3).map(|i| l[j][i] * l[k][i]).sum();
                assert!((back - c[j][k]).abs() < 1e-12, "{j} {k}");
            }
        }
        assert_eq!(cholesky_psd([[0.0; 3]; 3]), [0.0; 6]);
    }

    #[test]
    fn de_finds_a_bowl_and_keeps_the_bounds() {
        let mut rng = stream_rng(3, 0);
        let target = [0.3f32, 1.2, 2.5];
        let result = minimize32::<3, 20, _, _>(
            |x| {
                (0..3)
                    .map(|j| (x[j] - target[j]) * (x[j] - target[j]))
                    .sum()
            },
            0.0,
            5.0,
            &DeParams {
                generations: 200,
                ..DeParams::default()
            },
            OutOfBounds::Clamp,
            None,
            &mut rng,
        );
        for (x, t) in result.best.iter().zip(target.iter()) {
            assert!((x - t).abs() < 1e-3, "{:?}", result.best);
        }
        assert_eq!(result.evaluations, 20 + 200 * 20);
        for rule in [OutOfBounds::Reflect, OutOfBounds::Resample] {
            let r = minimize32::<3, 10, _, _>(
                |x| {
                    assert!(x.iter().all(|v| (0.5..=2.0).contains(v)), "{rule:?}");
                    x[0]
                },
                0.5,
                2.0,
                &DeParams::default(),
                rule,
                Some([1.7, 0.6, 9.0]),
                &mut rng,
            );
            assert!(r.fitness >= 0.5);
        }
    }

    #[test]
    fn crossover_threshold_is_the_rate() {
        assert_eq!(rate_threshold(1.0), 1023);
        assert_eq!(rate_threshold(0.5), 512);
        assert_eq!(rate_threshold(0.0), 0);
        assert_eq!(rate_threshold(0.7), 716);
    }

    #[test]
    fn trial_draws_are_distinct_and_uniform() {
        let mut rng = stream_rng(5, 5);
        let mut seen = [[0u32; 10]; 3];
        let mut forced_seen = [0u32; 3];
        for n in 0..90_000 {
            let target = n % 10;
            let ([a, b, c], forced, _) = trial_draws::<10, 3, _>(target, &mut rng);
            let all = [target, a, b, c];
            for i in 0..4 {
                assert!(all[i] < 10);
                for j in 0..i {
                    assert_ne!(all[i], all[j], "{all:?}");
                }
            }
            for (count, r) in seen.iter_mut().zip([a, b, c]) {
                count[r] += 1;
            }
            forced_seen[forced] += 1;
        }
        // Each donor slot is uniform over the 9 indices other than the target: 9,000 each.
        for count in seen.iter().flatten() {
            assert!((8_500..9_500).contains(count), "{seen:?}");
        }
        for count in forced_seen {
            assert!((29_000..31_000).contains(&count), "{forced_seen:?}");
        }
        // POP = 4 leaves exactly one choice for the third donor.
        for target in 0..4 {
            let ([a, b, c], _, _) = trial_draws::<4, 1, _>(target, &mut rng);
            let mut all = [target, a, b, c];
            all.sort_unstable();
            assert_eq!(all, [0, 1, 2, 3]);
        }
    }
}
