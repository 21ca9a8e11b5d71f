//! DE/rand/1/bin (eqs. 7-9) in f32: the search every fit of the core runs.
//!
//! The algorithm is [`crate::de::minimize`]'s, the paper's: synchronous generations, selection by
//! `<=`, the moment candidate replacing the first random member, F and CR as given. What differs
//! is how it is paid for on a 32-bit core with an f32-only FPU (README, "Firmware"): the
//! population is f32, the two generations are two buffers whose roles swap (no copy of the
//! population per generation), and the random numbers come from a 32-bit generator seeded once
//! per run from the fit's own stream ([`DeRng`]).
//!
//! The draws, in order, so that an independent implementation can replay them (the firmware
//! simulator's f64 reference does): one draw of the caller's stream seeds the [`DeRng`]; then,
//! from it, `D` per initial member (24-bit uniforms); then per trial one draw split into the
//! three donors and the forced coordinate, then one per coordinate deciding its crossover
//! (taken even for the forced coordinate, so every trial draws the same count), then, under
//! [`OutOfBounds::Resample`] only, one per crossing coordinate whose donor left the box.

use crate::de::{DeParams, OutOfBounds};
use crate::rng::DeRng;
use rand_core::Rng;

/// `x.clamp(lo, hi)` without the standard one's panicking assertion; NaN passes through.
#[inline]
pub(crate) fn clamp32(x: f32, lo: f32, hi: f32) -> f32 {
    let mut x = x;
    if x < lo {
        x = lo;
    }
    if x > hi {
        x = hi;
    }
    x
}

/// Uniform in [0, 1) with the 24 bits an f32 holds (exact conversion).
#[inline]
fn unit(draw: u32) -> f32 {
    (draw >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The crossover rate CR as a 31-bit threshold `t`: a coordinate crosses when its draw `u`
/// has `u >> 1 < t`, which `t` of the 2^31 values of `u >> 1` do. With `t = round(CR 2^31)` the
/// probability is CR to within 2^-32 for every CR in [0, 1]; CR = 0 never crosses, CR = 1
/// always. (Before, the rate was a 10-bit slice: 717/1024 = 0.70020 for CR = 0.7.)
pub(crate) fn crossover_threshold(rate: f64) -> u32 {
    const SCALE: f64 = (1u64 << 31) as f64;
    if !(rate > 0.0) {
        // NaN and negative rates never cross; the forced coordinate still does.
        0
    } else if rate >= 1.0 {
        1 << 31
    } else {
        // rate * 2^31 is exact (a power of two); + 0.5 then truncation rounds it.
        (rate * SCALE + 0.5) as u32
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

/// The three distinct ranks among the `n` members other than a target, from a number
/// `k < n (n - 1) (n - 2)` read in mixed radix: `a` the first digit, `b` the second digit's rank
/// among those left, and so on (what three successive Lemire splits give).
const fn ranks(k: usize, n: usize) -> [usize; 3] {
    let a = k / ((n - 1) * (n - 2));
    let mut b = k / (n - 2) % (n - 1);
    if b >= a {
        b += 1;
    }
    let (low, high) = if a < b { (a, b) } else { (b, a) };
    let mut c = k % (n - 2);
    if c >= low {
        c += 1;
    }
    if c >= high {
        c += 1;
    }
    [a, b, c]
}

/// [`ranks`] for the paper's population, packed `a | b << 4 | c << 8`: one load a trial instead
/// of a chain of comparisons, for 504 entries of two bytes of flash.
const PAPER_RANKS: [u16; 504] = {
    let mut table = [0u16; 504];
    let mut k = 0;
    while k < 504 {
        let [a, b, c] = ranks(k, 9);
        table[k] = (a | b << 4 | c << 8) as u16;
        k += 1;
    }
    table
};

/// One trial's donors, distinct from each other and from `target` (uniform among the
/// `POP - 1`, `POP - 2`, `POP - 3` left), and its forced coordinate, all split from one draw.
/// The donors are drawn as distinct ranks among the `POP - 1` members other than the target
/// ([`ranks`]), and a rank `a` is member `a + (a >= target)`.
#[inline]
fn donors<const POP: usize, const D: usize>(target: usize, draw: u32) -> ([usize; 3], usize) {
    let mut x = draw;
    let n = POP - 1;
    // One split into n (n - 1) (n - 2) outcomes is the three successive splits: the same
    // number in mixed radix, and the same fraction left over.
    let k = split(&mut x, n * (n - 1) * (n - 2));
    let [a, b, c] = if POP == crate::de::PAPER_POPULATION {
        let packed = usize::from(PAPER_RANKS.get(k).copied().unwrap_or(0));
        [packed & 15, packed >> 4 & 15, packed >> 8 & 15]
    } else {
        ranks(k, n)
    };
    let forced = split(&mut x, D);
    // Ranks are < POP - 1, so members are < POP <= SLOTS; the mask changes nothing but lets
    // the compiler drop the population's bounds checks in one instruction.
    let member = |rank: usize| (rank + usize::from(rank >= target)) & (SLOTS - 1);
    ([member(a), member(b), member(c)], forced)
}

/// A donor coordinate outside `[lo, hi]` brought back in by `rule`.
#[cold]
fn repair(value: f32, lo: f32, hi: f32, rule: OutOfBounds, draws: &mut DeRng) -> f32 {
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
        OutOfBounds::Resample => lo + unit(draws.next_u32()) * (hi - lo),
    }
}

/// A NaN fitness never wins, so a broken objective cannot take over the population: `candidate
/// <= incumbent`, or the incumbent is NaN and the candidate not. (Written so that a worse
/// candidate, the common case, is decided by one comparison.)
#[inline]
fn no_worse(candidate: f32, incumbent: f32) -> bool {
    !(candidate > incumbent) && !candidate.is_nan()
}

/// The population's storage: `POP <= SLOTS` members, in arrays of a power of two so that a
/// member index is bounded by a mask (see `donors`).
pub const SLOTS: usize = 16;

/// One member of the population: its coordinates and their fitness, side by side so that a
/// trial's winner is stored (and its target loaded) as one block.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct Member<const D: usize> {
    x: [f32; D],
    score: f32,
}

/// What a DE run found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct De32Result<const D: usize> {
    pub best: [f32; D],
    pub fitness: f32,
    pub evaluations: u32,
}

/// DE/rand/1/bin over the box `[lo, hi]^D` in f32 (the draws: module doc).
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
            POP >= 4 && POP <= SLOTS,
            "DE/rand/1 needs the target and three distinct others, in SLOTS"
        )
    };
    const { assert!(D >= 1) };
    let mut draws = DeRng::from_stream(rng);
    let mutation = params.mutation as f32;
    let crossover = crossover_threshold(params.crossover);
    let clamps = out_of_bounds == OutOfBounds::Clamp;
    let mut first = [Member {
        x: [0.0f32; D],
        score: f32::INFINITY,
    }; SLOTS];
    let mut evaluations = 0u32;
    for member in first.iter_mut().take(POP) {
        for x in member.x.iter_mut() {
            *x = lo + unit(draws.next_u32()) * (hi - lo);
        }
        member.score = objective(&member.x);
        evaluations += 1;
    }
    if let (Some(seed), Some(member)) = (seed_candidate, first.first_mut()) {
        member.x = seed.map(|s| if s.is_nan() { lo } else { clamp32(s, lo, hi) });
        member.score = objective(&member.x);
        evaluations += 1;
    }

    // Generation g reads `population` and writes `next`; then they trade places.
    let mut second = first;
    let (mut population, mut next) = (&mut first, &mut second);
    for _ in 0..params.generations {
        for i in 0..POP {
            let ([r1, r2, r3], forced) = donors::<POP, D>(i, draws.next_u32());
            // The target goes to the next generation unless its trial wins: copied now, as one
            // block, and overwritten by a winner.
            next[i] = population[i];
            let current_score = population[i].score;
            let (x1, x2, x3) = (population[r1].x, population[r2].x, population[r3].x);
            let current = population[i].x;
            // Built coordinate by coordinate, so that the trial stays in FPU registers.
            let mut trial = [0.0f32; D];
            for j in 0..D {
                trial[j] = if (draws.next_u32() >> 1) < crossover || j == forced {
                    let donor = x1[j] + mutation * (x2[j] - x3[j]);
                    if donor >= lo && donor <= hi {
                        donor
                    } else if clamps {
                        // F = 1.2 sends about one donor in six out of the box on real
                        // clusters: the default rule inline. (`repair` stays out of line at
                        // the image's low inline thresholds, and a call a trial costs a fit.)
                        clamp32(donor, lo, hi)
                    } else {
                        repair(donor, lo, hi, out_of_bounds, &mut draws)
                    }
                } else {
                    current[j]
                };
            }
            let score = objective(&trial);
            evaluations += 1;
            if no_worse(score, current_score) {
                next[i] = Member { x: trial, score };
            }
        }
        core::mem::swap(&mut population, &mut next);
    }

    // Strictly better only, so ties keep the lowest index and the result is order-stable.
    let mut best = population[0];
    for member in population.iter().take(POP).skip(1) {
        if no_worse(member.score, best.score) && member.score != best.score {
            best = *member;
        }
    }
    De32Result {
        best: best.x,
        fitness: best.score,
        evaluations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream_rng;

    #[test]
    fn de_finds_a_bowl_and_keeps_the_bounds() {
        let mut rng = stream_rng(3, 0);
        let target = [0.3f32, 1.2, 2.5];
        let result = minimize32::<3, 16, _, _>(
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
        assert_eq!(result.evaluations, 16 + 200 * 16);
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
        let scale = (1u64 << 31) as f64;
        assert_eq!(crossover_threshold(1.0), 1 << 31);
        assert_eq!(crossover_threshold(2.0), 1 << 31);
        assert_eq!(crossover_threshold(0.0), 0);
        assert_eq!(crossover_threshold(-0.5), 0);
        assert_eq!(crossover_threshold(f64::NAN), 0);
        // The probability of a pass is t / 2^31: within 2^-32 of the rate, for every rate.
        for i in 0..=10_000 {
            let rate = i as f64 / 10_000.0;
            let p = f64::from(crossover_threshold(rate)) / scale;
            assert!((p - rate).abs() <= 0.5 / scale, "{rate}: {p}");
        }
    }

    /// The fraction of trial coordinates that differ from the member they replace, over
    /// `runs` runs on a constant objective (every trial wins, so each generation is the
    /// previous one's trials). A coordinate crosses if it is the forced one (1/3) or else
    /// with probability CR: 1/3 + 2/3 CR in all.
    fn crossed_fraction(rate: f64, runs: u64) -> f64 {
        // A small F keeps donors inside the box and apart from their targets (a donor clamped
        // to a bound can equal a target already there).
        let params = DeParams {
            crossover: rate,
            mutation: 0.05,
            ..DeParams::default()
        };
        let (mut changed, mut total) = (0u64, 0u64);
        for run in 0..runs {
            // Previous generation, this one, evaluations so far, changed, compared.
            let log = core::cell::RefCell::new(([[0f32; 3]; 10], [[0f32; 3]; 10], 0, 0, 0));
            minimize32::<3, 10, _, _>(
                |x| {
                    let mut guard = log.borrow_mut();
                    let (previous, current, n, changed, total) = &mut *guard;
                    if *n < 10 {
                        previous[*n] = *x;
                    } else {
                        let i = (*n - 10) % 10;
                        for j in 0..3 {
                            *total += 1;
                            *changed += u64::from(x[j] != previous[i][j]);
                        }
                        current[i] = *x;
                        if i == 9 {
                            *previous = *current;
                        }
                    }
                    *n += 1;
                    1.0
                },
                -1.0,
                1.0,
                &params,
                OutOfBounds::Clamp,
                None,
                &mut stream_rng(run, 17),
            );
            let (_, _, _, c, t) = log.into_inner();
            changed += c;
            total += t;
        }
        changed as f64 / total as f64
    }

    #[test]
    fn coordinates_cross_at_the_rate() {
        // 100 runs of 500 trials of 3 coordinates: the standard error of the fraction is at
        // most 0.0017; 5 of them bound it.
        for rate in [0.0, 0.1, 0.7, 1.0] {
            let f = crossed_fraction(rate, 100);
            let want = (1.0 + 2.0 * rate) / 3.0;
            assert!((f - want).abs() <= 0.0085, "{rate}: {f} vs {want}");
        }
    }

    #[test]
    fn the_rank_table_is_the_successive_splits() {
        // Three Lemire splits by 9, 8 and 7, then the k-th rank not yet taken, against the
        // table's single split by 504.
        let mut g = DeRng::from_stream(&mut stream_rng(8, 8));
        for _ in 0..100_000 {
            let draw = g.next_u32();
            let mut x = draw;
            let a = split(&mut x, 9);
            let mut b = split(&mut x, 8);
            let mut c = split(&mut x, 7);
            let rest = x;
            b += usize::from(b >= a);
            for taken in [a.min(b), a.max(b)] {
                c += usize::from(c >= taken);
            }
            let mut y = draw;
            let k = split(&mut y, 504);
            assert_eq!(y, rest);
            let packed = usize::from(PAPER_RANKS[k]);
            assert_eq!([packed & 15, packed >> 4 & 15, packed >> 8], [a, b, c]);
        }
    }

    #[test]
    fn donors_are_distinct_and_uniform() {
        let mut g = DeRng::from_stream(&mut stream_rng(5, 5));
        let mut seen = [[0u32; 10]; 3];
        let mut forced_seen = [0u32; 3];
        for n in 0..90_000 {
            let target = n % 10;
            let ([a, b, c], forced) = donors::<10, 3>(target, g.next_u32());
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
            let ([a, b, c], _) = donors::<4, 1>(target, g.next_u32());
            let mut all = [target, a, b, c];
            all.sort_unstable();
            assert_eq!(all, [0, 1, 2, 3]);
        }
    }
}
