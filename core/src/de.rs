//! Differential Evolution, DE/rand/1/bin (Section 2.4, eqs. 7-9), over a bounded box.
//!
//! The population lives on the stack (`POP` candidates of `D` coordinates, twice for the
//! synchronous generation), so a fit needs no allocator and its memory is known at compile time.

use crate::num::clamp;
use crate::rng::{index_below, uniform};
use rand_core::Rng;

/// The paper's settings: F = 1.2, CR = 0.7, 50 generations (population 10 is the const generic).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeParams {
    /// Mutation factor F of eq. 7.
    pub mutation: f64,
    /// Crossover rate CR of eq. 8.
    pub crossover: f64,
    pub generations: u32,
}

impl Default for DeParams {
    fn default() -> Self {
        Self {
            mutation: 1.2,
            crossover: 0.7,
            generations: 50,
        }
    }
}

/// The paper's population size.
pub const PAPER_POPULATION: usize = 10;

/// What happens to a trial coordinate that eq. 7 pushed outside the bounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum OutOfBounds {
    /// Put it on the bound it crossed: lets the search rest on a bound (e.g. a degenerating axis).
    #[default]
    Clamp,
    /// Mirror it back inside, as if the bound were a wall.
    Reflect,
    /// Draw it again uniformly inside the bounds (Storn and Price's suggestion).
    Resample,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeResult<const D: usize> {
    pub best: [f64; D],
    pub fitness: f64,
    pub evaluations: u32,
}

/// A NaN fitness never wins, so a broken objective cannot take over the population.
fn no_worse(candidate: f64, incumbent: f64) -> bool {
    candidate <= incumbent || (incumbent.is_nan() && !candidate.is_nan())
}

fn repair<R: Rng + ?Sized>(value: f64, lo: f64, hi: f64, rule: OutOfBounds, rng: &mut R) -> f64 {
    if value >= lo && value <= hi {
        return value;
    }
    match rule {
        OutOfBounds::Clamp => clamp(value, lo, hi),
        OutOfBounds::Reflect => {
            let width = hi - lo;
            let mirrored = if value < lo {
                2.0 * lo - value
            } else {
                2.0 * hi - value
            };
            // A step larger than the box still lands inside after one mirror and a clamp.
            if width > 0.0 {
                clamp(mirrored, lo, hi)
            } else {
                lo
            }
        }
        OutOfBounds::Resample => lo + uniform(rng) * (hi - lo),
    }
}

/// Minimises `objective` over the box `[lower, upper]` with DE/rand/1/bin.
///
/// `seed_candidate`, when given, replaces the first random member of the initial population
/// (clamped into the box). Selection is eq. 9 (`<=`), so the best fitness never gets worse.
pub fn minimize<const D: usize, const POP: usize, R, F>(
    mut objective: F,
    lower: [f64; D],
    upper: [f64; D],
    params: &DeParams,
    out_of_bounds: OutOfBounds,
    seed_candidate: Option<[f64; D]>,
    rng: &mut R,
) -> DeResult<D>
where
    R: Rng + ?Sized,
    F: FnMut(&[f64; D]) -> f64,
{
    const {
        assert!(
            POP >= 4,
            "DE/rand/1 needs the target and three distinct others"
        )
    };
    const { assert!(D >= 1) };
    let mut population = [[0.0f64; D]; POP];
    let mut scores = [f64::INFINITY; POP];
    let mut evaluations = 0u32;
    for (member, score) in population.iter_mut().zip(scores.iter_mut()) {
        for (x, (&lo, &hi)) in member.iter_mut().zip(lower.iter().zip(upper.iter())) {
            *x = lo + uniform(rng) * (hi - lo);
        }
        *score = objective(member);
        evaluations += 1;
    }
    if let (Some(seed), Some(first), Some(first_score)) =
        (seed_candidate, population.first_mut(), scores.first_mut())
    {
        for (x, (&s, (&lo, &hi))) in first
            .iter_mut()
            .zip(seed.iter().zip(lower.iter().zip(upper.iter())))
        {
            *x = if s.is_nan() { lo } else { clamp(s, lo, hi) };
        }
        *first_score = objective(first);
        evaluations += 1;
    }

    let mut next = population;
    let mut next_scores = scores;
    for _ in 0..params.generations {
        for i in 0..POP {
            let [r1, r2, r3] = distinct_three::<POP, R>(i, rng);
            let forced = index_below(rng, D);
            let mut trial = population[i];
            // r1, r2, r3 < POP by construction; `get` keeps a bounds-check panic out of the build.
            let [x1, x2, x3] = [r1, r2, r3].map(|r| population.get(r).copied().unwrap_or(trial));
            for j in 0..D {
                if j == forced || uniform(rng) <= params.crossover {
                    let donor = x1[j] + params.mutation * (x2[j] - x3[j]);
                    trial[j] = repair(donor, lower[j], upper[j], out_of_bounds, rng);
                }
            }
            let score = objective(&trial);
            evaluations += 1;
            if no_worse(score, scores[i]) {
                next[i] = trial;
                next_scores[i] = score;
            } else {
                next[i] = population[i];
                next_scores[i] = scores[i];
            }
        }
        population = next;
        scores = next_scores;
    }

    // Strictly better only, so ties keep the lowest index and the result is order-stable.
    let mut best = 0;
    for i in 1..POP {
        if no_worse(scores[i], scores[best]) && scores[i] != scores[best] {
            best = i;
        }
    }
    DeResult {
        best: population[best],
        fitness: scores[best],
        evaluations,
    }
}

/// Three indices, distinct from each other and from `target`; POP >= 4 guarantees they exist.
pub(crate) fn distinct_three<const POP: usize, R: Rng + ?Sized>(
    target: usize,
    rng: &mut R,
) -> [usize; 3] {
    // Draw from the POP-1 others, then from the remaining ones, skipping taken slots: three
    // draws, never a rejection loop, so the cost is bounded.
    let pick = |rng: &mut R, taken: &[usize]| {
        let mut k = index_below(rng, POP - taken.len());
        let mut sorted = [usize::MAX; 3];
        for (slot, &t) in sorted.iter_mut().zip(taken.iter()) {
            *slot = t;
        }
        let sorted = sorted.get_mut(..taken.len()).unwrap_or(&mut []);
        crate::num::insertion_sort_by(sorted, |a, b| a < b);
        for &t in sorted.iter() {
            if k >= t {
                k += 1;
            }
        }
        // k < POP already; the min lets the compiler drop the population's bounds checks.
        k.min(POP - 1)
    };
    let r1 = pick(rng, &[target]);
    let r2 = pick(rng, &[target, r1]);
    let r3 = pick(rng, &[target, r1, r2]);
    [r1, r2, r3]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream_rng;

    #[test]
    fn finds_the_minimum_of_a_shifted_bowl() {
        let mut rng = stream_rng(3, 0);
        let target = [0.3, -1.2, 2.5];
        let result = minimize::<3, 20, _, _>(
            |x| {
                x.iter()
                    .zip(target.iter())
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum()
            },
            [-5.0; 3],
            [5.0; 3],
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
    }

    #[test]
    fn seed_candidate_is_never_lost_and_bounds_hold() {
        for rule in [
            OutOfBounds::Clamp,
            OutOfBounds::Reflect,
            OutOfBounds::Resample,
        ] {
            let mut rng = stream_rng(9, 1);
            let mut outside = 0;
            let result = minimize::<2, 10, _, _>(
                |x| {
                    if !(0.5..=2.0).contains(&x[0]) || !(0.5..=2.0).contains(&x[1]) {
                        outside += 1;
                    }
                    (x[0] - 1.7).abs() + (x[1] - 0.6).abs()
                },
                [0.5; 2],
                [2.0; 2],
                &DeParams {
                    generations: 5,
                    ..DeParams::default()
                },
                rule,
                Some([1.7, 0.6]),
                &mut rng,
            );
            assert_eq!(outside, 0, "{rule:?}");
            assert_eq!(result.best, [1.7, 0.6], "{rule:?}");
            assert_eq!(result.fitness, 0.0);
        }
    }

    #[test]
    fn nan_objective_never_wins() {
        let mut rng = stream_rng(1, 1);
        let result = minimize::<1, 4, _, _>(
            |x| if x[0] > 0.5 { f64::NAN } else { x[0] },
            [0.0],
            [1.0],
            &DeParams::default(),
            OutOfBounds::Clamp,
            None,
            &mut rng,
        );
        assert!(result.fitness.is_finite() && result.best[0] <= 0.5);
    }

    #[test]
    fn three_distinct_others() {
        let mut rng = stream_rng(5, 5);
        for target in 0..4 {
            for _ in 0..1000 {
                let [a, b, c] = distinct_three::<4, _>(target, &mut rng);
                let all = [target, a, b, c];
                for i in 0..4 {
                    assert!(all[i] < 4);
                    for j in 0..i {
                        assert_ne!(all[i], all[j], "{all:?}");
                    }
                }
            }
        }
    }
}
