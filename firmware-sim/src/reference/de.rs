//! DE/rand/1/bin on the direct fitness, drawing from the PCG32 stream exactly as the paper's
//! algorithm is specified in the core (init draws, seed member, then per target: three distinct
//! donors, the forced coordinate, one crossover draw per other coordinate), so both runs see the
//! same random numbers. Everything else is computed here: vectors, box, start candidate.

use mema_core::de::DeParams;
use mema_core::rng::Pcg32;
use nalgebra::Vector3;
use rand_core::Rng;

use super::fitness::DirectFitness;
use super::moments::DirectMoments;

const POP: usize = mema_core::de::PAPER_POPULATION;

fn uniform(rng: &mut Pcg32) -> f64 {
    // 53 random bits scaled into [0, 1).
    (rng.next_u64() >> 11) as f64 / 9_007_199_254_740_992.0
}

fn index_below(rng: &mut Pcg32, n: usize) -> usize {
    ((u64::from(rng.next_u32()) * n as u64) >> 32) as usize
}

/// The k-th index not in `taken`, k uniform.
fn pick(rng: &mut Pcg32, taken: &[usize]) -> usize {
    let mut k = index_below(rng, POP - taken.len());
    let mut sorted = taken.to_vec();
    sorted.sort();
    for t in sorted {
        if k >= t {
            k += 1;
        }
    }
    k
}

/// Minimises `f` over `[lo, hi]^3`; returns the best member and its fitness.
pub fn minimize(
    f: impl Fn(&Vector3<f64>) -> f64,
    lo: f64,
    hi: f64,
    seed: Option<Vector3<f64>>,
    de: &DeParams,
    rng: &mut Pcg32,
) -> (Vector3<f64>, f64) {
    let mut pop: Vec<Vector3<f64>> = (0..POP)
        .map(|_| Vector3::from_fn(|_, _| lo + uniform(rng) * (hi - lo)))
        .collect();
    let mut score: Vec<f64> = pop.iter().map(&f).collect();
    if let Some(s) = seed {
        pop[0] = s.map(|v| if v.is_nan() { lo } else { v.max(lo).min(hi) });
        score[0] = f(&pop[0]);
    }
    let wins = |new: f64, old: f64| new <= old || (old.is_nan() && !new.is_nan());
    for _ in 0..de.generations {
        let mut next = pop.clone();
        let mut next_score = score.clone();
        for i in 0..POP {
            let r1 = pick(rng, &[i]);
            let r2 = pick(rng, &[i, r1]);
            let r3 = pick(rng, &[i, r1, r2]);
            let forced = index_below(rng, 3);
            let mut trial = pop[i];
            for j in 0..3 {
                if j == forced || uniform(rng) <= de.crossover {
                    let v = pop[r1][j] + de.mutation * (pop[r2][j] - pop[r3][j]);
                    trial[j] = v.max(lo).min(hi);
                }
            }
            let s = f(&trial);
            if wins(s, score[i]) {
                next[i] = trial;
                next_score[i] = s;
            }
        }
        pop = next;
        score = next_score;
    }
    let best = (1..POP).fold(0, |b, i| {
        if wins(score[i], score[b]) && score[i] != score[b] {
            i
        } else {
            b
        }
    });
    (pop[best], score[best])
}

/// The start candidate: the better (by direct fitness) of the least-squares ellipsoid, solved
/// by LU, and the best sphere, found by golden section over `r`.
pub fn moment_candidate(m: &DirectMoments, f: &DirectFitness, lo: f64, hi: f64) -> Vector3<f64> {
    let sphere = Vector3::repeat(best_sphere(f, lo, hi));
    let least_squares = m
        .fourth
        .lu()
        .solve(&m.second)
        .filter(|w| w.iter().all(|v| v.is_finite()));
    match least_squares {
        Some(w) => {
            let e = w.map(|w| {
                if w > 0.0 {
                    (1.0 / w.sqrt()).max(lo).min(hi)
                } else {
                    hi
                }
            });
            if f.eval(&e) <= f.eval(&sphere) {
                e
            } else {
                sphere
            }
        }
        None => sphere,
    }
}

/// Eq. 12 over spheres is unimodal in `r` (it is convex in `1/r^2`, a monotone map of `r`).
fn best_sphere(f: &DirectFitness, lo: f64, hi: f64) -> f64 {
    let g = |r: f64| f.eval(&Vector3::repeat(r));
    let inv_phi = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (lo, hi);
    for _ in 0..200 {
        let c = b - inv_phi * (b - a);
        let d = a + inv_phi * (b - a);
        if g(c) <= g(d) {
            b = d;
        } else {
            a = c;
        }
        if b - a <= 1e-15 * b {
            break;
        }
    }
    0.5 * (a + b)
}
