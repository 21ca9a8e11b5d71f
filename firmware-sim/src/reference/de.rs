//! DE/rand/1/bin on the direct fitness, drawing the same random numbers as the core's f32 DE
//! (`mema_core::de32`, module doc): one PCG32 draw seeds a 32-bit xorshift generator with a
//! multiplicative output, which then gives the initial members, and per target one draw read
//! as a binary fraction that yields the three distinct donors and the forced coordinate, then
//! one draw per coordinate that crosses with probability CR. Everything else is computed here, in f64 and in the
//! cloud's unit where the core searches in f32 and in units of the cluster's spread: vectors,
//! box, start candidate.

use mema_core::de::DeParams;
use mema_core::rng::Pcg32;
use nalgebra::Vector3;
use rand_core::Rng;

use super::fitness::DirectFitness;
use super::moments::DirectMoments;

const POP: usize = mema_core::de::PAPER_POPULATION;

/// Marsaglia's xorshift32 (shifts 13, 17, 5) whose output is the new state times Knuth's
/// 2654435761, in 64-bit arithmetic reduced mod 2^32.
struct XorShift32Star {
    state: u64,
}

impl XorShift32Star {
    /// The state from the next draw of the fit's PCG32, made odd (never zero).
    fn seeded(rng: &mut Pcg32) -> Self {
        Self {
            state: u64::from(rng.next_u32() | 1),
        }
    }

    fn next_u32(&mut self) -> u32 {
        const MOD: u64 = 1 << 32;
        let mut x = self.state;
        x ^= (x << 13) % MOD;
        x ^= x >> 17;
        x ^= (x << 5) % MOD;
        self.state = x;
        ((x * 2_654_435_761) % MOD) as u32
    }
}

fn uniform(rng: &mut XorShift32Star) -> f64 {
    // The top 24 bits of one draw, scaled into [0, 1).
    f64::from(rng.next_u32() >> 8) / 16_777_216.0
}

/// A crossover: the draw's top 31 bits below CR 2^31 rounded, probability CR within 2^-32.
fn crosses(draw: u32, rate: f64) -> bool {
    f64::from(draw >> 1) < (rate * 2f64.powi(31)).round()
}

/// The integer part of `fraction * n`, `fraction` the draw read as a 32-bit binary fraction;
/// the fractional part of the product is left as the next fraction (one draw, several choices).
fn take(fraction: &mut u32, n: usize) -> usize {
    let product = u64::from(*fraction) * n as u64;
    *fraction = (product & 0xffff_ffff) as u32;
    (product >> 32) as usize
}

/// The k-th index not in `taken`.
fn pick(k: usize, taken: &[usize]) -> usize {
    let mut k = k;
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
///
/// The search space is the core's: coordinates `r / s` held in f32 (`s` the cluster's RMS
/// radius), the donor `x1 + F (x2 - x3)` rounded as f32 arithmetic rounds it. That is the
/// algorithm's specification, not its evaluation: which member wins is decided here by the
/// direct f64 sum, so a comparison the core's f32 form decides differently shows as a
/// different trajectory.
pub fn minimize(
    f: impl Fn(&Vector3<f64>) -> f64,
    lo: f64,
    hi: f64,
    s: f64,
    seed: Option<Vector3<f64>>,
    de: &DeParams,
    rng: &mut Pcg32,
) -> (Vector3<f64>, f64) {
    let rng = &mut XorShift32Star::seeded(rng);
    let (lo32, hi32) = ((lo / s) as f32, (hi / s) as f32);
    let clamp32 = |v: f32| v.max(lo32).min(hi32);
    let axes = |x: &[f32; 3]| Vector3::from_fn(|j, _| (f64::from(x[j]) * s).max(lo).min(hi));
    let mut pop: Vec<[f32; 3]> = (0..POP)
        .map(|_| [0; 3].map(|_| lo32 + uniform(rng) as f32 * (hi32 - lo32)))
        .collect();
    let mut score: Vec<f64> = pop.iter().map(|x| f(&axes(x))).collect();
    if let Some(seed) = seed {
        pop[0] = [0, 1, 2].map(|j| {
            let v = seed[j];
            if v.is_nan() {
                lo32
            } else {
                clamp32((v / s) as f32)
            }
        });
        score[0] = f(&axes(&pop[0]));
    }
    let mutation = de.mutation as f32;
    let wins = |new: f64, old: f64| new <= old || (old.is_nan() && !new.is_nan());
    for _ in 0..de.generations {
        let mut next = pop.clone();
        let mut next_score = score.clone();
        for i in 0..POP {
            let mut fraction = rng.next_u32();
            let r1 = pick(take(&mut fraction, POP - 1), &[i]);
            let r2 = pick(take(&mut fraction, POP - 2), &[i, r1]);
            let r3 = pick(take(&mut fraction, POP - 3), &[i, r1, r2]);
            let forced = take(&mut fraction, 3);
            let mut trial = pop[i];
            for j in 0..3 {
                if crosses(rng.next_u32(), de.crossover) || j == forced {
                    trial[j] = clamp32(pop[r1][j] + mutation * (pop[r2][j] - pop[r3][j]));
                }
            }
            let s = f(&axes(&trial));
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
    (axes(&pop[best]), score[best])
}

/// The start candidate: the better (by direct fitness) of the least-squares ellipsoid, solved
/// by LU, and the best sphere (`best_sphere`: bisection on the derivative in `w = 1/r^2`).
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

/// The best sphere: eq. 12 over spheres is convex in `w = 1/r^2`, so its minimum is where the
/// derivative in `w`, summed point by point, changes sign; bisection finds it to the last bit
/// (a root is determined to the arithmetic's precision, a minimum only to its square root).
fn best_sphere(f: &DirectFitness, lo: f64, hi: f64) -> f64 {
    let slope = |w: f64| f.sphere_slope(w);
    let (mut a, mut b) = (1.0 / (hi * hi), 1.0 / (lo * lo));
    if slope(a) >= 0.0 {
        return hi;
    }
    if slope(b) <= 0.0 {
        return lo;
    }
    loop {
        let mid = 0.5 * (a + b);
        if mid <= a || mid >= b {
            break;
        }
        if slope(mid) < 0.0 {
            a = mid;
        } else {
            b = mid;
        }
    }
    1.0 / (0.5 * (a + b)).sqrt()
}
