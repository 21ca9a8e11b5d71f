//! Fitting one cluster's semi-axes by DE on eq. 12 (Section 3), ellipsoid or one-radius sphere.

use crate::de::{DeParams, OutOfBounds, PAPER_POPULATION, minimize};
use crate::de32::minimize32;
use crate::fit32::{Fitness32, UnitMoments};
use crate::fitness::{FitnessTerms, PAPER_ALPHA, VolumeTerm};
use crate::geometry::{Degeneration, Entity, Point3};
use crate::moments::CentralMoments;
use crate::num::clamp;
use rand_core::Rng;

/// The DE search box for the semi-axes. The paper gives none; both rules scale with the
/// cluster's RMS radius `s`, so a fit means the same for a bunny in metres and a field in feet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SemiAxisBounds {
    /// `r_j` in `[lower * s, upper * s]`, searched linearly as in the paper. An axis cannot
    /// degenerate unless `upper * s` reaches the threshold.
    Spread { lower: f64, upper: f64 },
    /// `r_j` in `[lower * s, threshold]`, searched in `ln r` because the box spans several
    /// decades: an axis the fit wants infinite can reach the threshold and degenerate (Table 1).
    Threshold { lower: f64 },
}

impl Default for SemiAxisBounds {
    /// Chosen by measurement (README): on the shared clouds every box gives the same eq. 13
    /// error within 0.7%, but the threshold box lets 3-8% of small clusters degenerate into
    /// infinite cylinders and planes, which then block rays across the whole map (`mema
    /// query-bench`: 22,319 of 49,500 demo rays hit such a phantom at k = 1000). With the spread
    /// box an axis degenerates only when the cluster is large enough (RMS radius >= threshold / 3)
    /// for an axis at the threshold to be within its reach, as in the paper's Experiment 7.
    fn default() -> Self {
        Self::Spread {
            lower: 0.05,
            upper: 3.0,
        }
    }
}

/// Whether the initial population is all random (the paper) or holds one candidate derived
/// from the moments: the better of the least-squares ellipsoid and the optimal sphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Initialisation {
    Random,
    #[default]
    MomentSeeded,
}

/// Everything that shapes one fit; `Default` is the paper's settings plus mema's measured choices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitParams {
    pub alpha: f64,
    pub volume: VolumeTerm,
    pub de: DeParams,
    pub bounds: SemiAxisBounds,
    pub out_of_bounds: OutOfBounds,
    pub initialisation: Initialisation,
    pub degeneration: Degeneration,
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            alpha: PAPER_ALPHA,
            volume: VolumeTerm::Exact,
            de: DeParams::default(),
            bounds: SemiAxisBounds::default(),
            out_of_bounds: OutOfBounds::Clamp,
            initialisation: Initialisation::MomentSeeded,
            degeneration: Degeneration::default(),
        }
    }
}

/// One fitted entity and what the fit saw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fit {
    pub entity: Entity,
    /// The DE's semi-axes before degeneration (finite).
    pub semi_axes: [f64; 3],
    /// Eq. 12 at `semi_axes`.
    pub fitness: f64,
    /// Eq. 12's first term without alpha: `sqrt(mean (psi1 . psi2)^2)`.
    pub residual_rms: f64,
    /// Eq. 12's second term.
    pub volume_term: f64,
    /// Axes that ended on the upper bound of the search box.
    pub on_upper_bound: u8,
    /// Axes that ended on its lower bound. Most axes of a map on either bound mean the box,
    /// not eq. 12, chose them: typically a cloud read in the wrong unit.
    pub on_lower_bound: u8,
    pub evaluations: u32,
}

/// The box `[lo, hi]` for every semi-axis, and whether DE searches it in `ln r`.
#[derive(Clone, Copy, Debug)]
struct SearchBox {
    lo: f64,
    hi: f64,
    log_space: bool,
    /// The cluster's RMS radius (or a positive stand-in): the f32 search's unit of length.
    scale: f64,
    /// `lo` and `hi` in units of `scale`.
    unit_lo: f64,
    unit_hi: f64,
}

impl SearchBox {
    fn new(moments: &CentralMoments, params: &FitParams) -> Self {
        // A cluster of coincident points has s = 0; any positive scale keeps the box non-empty.
        let s = {
            let s = moments.rms_radius();
            if s > 0.0 && s.is_finite() { s } else { 1e-6 }
        };
        let (lower, upper, log_space) = match params.bounds {
            SemiAxisBounds::Spread { lower, upper } => (lower, upper * s, false),
            SemiAxisBounds::Threshold { lower } => (lower, params.degeneration.threshold, true),
        };
        let lo = (lower * s).max(f64::MIN_POSITIVE);
        let hi = upper.max(lo);
        Self {
            lo,
            hi,
            log_space,
            scale: s,
            unit_lo: lo / s,
            unit_hi: hi / s,
        }
    }

    /// The f32 search coordinate of a semi-axis `u` in units of `s`: `u`, or its log.
    fn coordinate32(&self, u: f64) -> f32 {
        (if self.log_space { libm::log(u) } else { u }) as f32
    }

    /// The semi-axis, in units of `s`, at f32 search coordinate `x`.
    fn unit_axis32(&self, x: f32) -> f32 {
        if self.log_space { libm::expf(x) } else { x }
    }

    /// The entity at f32 search coordinates `x`, its semi-axes in f32 ([`Entity::from_semi_axes32`]).
    fn entity32(&self, center: Point3, x: [f32; 3], degeneration: &Degeneration) -> Entity {
        let (s, lo, hi) = (self.scale as f32, self.lo as f32, self.hi as f32);
        let axes = x.map(|x| crate::de32::clamp32(self.unit_axis32(x) * s, lo, hi));
        Entity::from_semi_axes32(center, axes, degeneration)
    }

    /// The semi-axis in the cloud's unit at f32 search coordinate `x`.
    fn semi_axis_of32(&self, x: f32) -> f64 {
        clamp(
            f64::from(self.unit_axis32(x)) * self.scale,
            self.lo,
            self.hi,
        )
    }

    /// [`SearchBox::minimize`] in f32 on [`Fitness32`]: the fit the core runs. The seed's
    /// semi-axes are in units of `s`, as the objective's; the result is the best member's
    /// search coordinates.
    fn minimize32<const D: usize, const POP: usize, R: Rng + ?Sized>(
        &self,
        objective: impl Fn(&[f32; D]) -> f32,
        seed: Option<[f64; D]>,
        params: &FitParams,
        rng: &mut R,
    ) -> ([f32; D], u32) {
        let (lo, hi) = (
            self.coordinate32(self.unit_lo),
            self.coordinate32(self.unit_hi),
        );
        let seed = seed.map(|r| r.map(|v| self.coordinate32(v)));
        let (de, rule) = (&params.de, params.out_of_bounds);
        let result = minimize32::<D, POP, R, _>(
            |x| {
                if self.log_space {
                    objective(&exp_axes(x))
                } else {
                    objective(x)
                }
            },
            lo,
            hi,
            de,
            rule,
            seed,
            rng,
        );
        (result.best, result.evaluations)
    }

    fn search_coordinate(&self, r: f64) -> f64 {
        if self.log_space { libm::log(r) } else { r }
    }

    fn semi_axis(&self, x: f64) -> f64 {
        if self.log_space { libm::exp(x) } else { x }
    }

    /// Runs DE over `D` semi-axes in this box; `objective` sees semi-axes, not search coordinates.
    fn minimize<const D: usize, const POP: usize, R: Rng + ?Sized>(
        &self,
        objective: impl Fn(&[f64; D]) -> f64,
        seed: Option<[f64; D]>,
        params: &FitParams,
        rng: &mut R,
    ) -> ([f64; D], u32) {
        let result = minimize::<D, POP, R, _>(
            |x| objective(&x.map(|v| self.semi_axis(v))),
            [self.search_coordinate(self.lo); D],
            [self.search_coordinate(self.hi); D],
            &params.de,
            params.out_of_bounds,
            seed.map(|r| r.map(|v| self.search_coordinate(v))),
            rng,
        );
        (result.best.map(|v| self.semi_axis(v)), result.evaluations)
    }
}

/// The semi-axes at log-box coordinates `x`. Out of line and cold: the log box is not the
/// default, and a call the register allocator sees as cold leaves the DE loop's registers
/// alone on the linear path (inlined, it costs the default fit instructions at every trial).
#[cold]
#[inline(never)]
fn exp_axes<const D: usize>(x: &[f32; D]) -> [f32; D] {
    x.map(libm::expf)
}

/// Solves the 3x3 system `a x = b` by Gaussian elimination with partial pivoting.
fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    for col in 0..3 {
        let mut pivot = col;
        for row in col + 1..3 {
            if a[row][col].abs() > a[pivot][col].abs() {
                pivot = row;
            }
        }
        if !(a[pivot][col].abs() > 0.0) {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..3 {
            let factor = a[row][col] / a[col][col];
            // Column `col` below the pivot is never read again: only the columns right of it.
            for k in col + 1..3 {
                a[row][k] -= factor * a[col][k];
            }
            b[row] -= factor * b[col];
        }
    }
    let mut x = [0.0; 3];
    for row in (0..3).rev() {
        let mut sum = b[row];
        for k in row + 1..3 {
            sum -= a[row][k] * x[k];
        }
        x[row] = sum / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The radius minimising the whole of eq. 12 for a sphere, within `[lo, hi]`.
///
/// In `w = 1/r^2` the residual term is the square root of a convex quadratic and the volume
/// term is `c w^(-3/2)`, both convex, so a golden-section search in `w` finds the one minimum.
fn optimal_sphere_radius(terms: &FitnessTerms, lo: f64, hi: f64) -> f64 {
    let fitness_of_weight = |w: f64| terms.sphere_fitness(1.0 / libm::sqrt(w));
    let (mut a, mut b) = (1.0 / (hi * hi), 1.0 / (lo * lo));
    const INV_PHI: f64 = 0.618_033_988_749_894_8;
    let mut c = b - INV_PHI * (b - a);
    let mut d = a + INV_PHI * (b - a);
    let (mut fc, mut fd) = (fitness_of_weight(c), fitness_of_weight(d));
    // 80 steps shrink the bracket by 0.618^80 ~ 2e-17: to the last bit of f64.
    for _ in 0..80 {
        if fc <= fd {
            b = d;
            d = c;
            fd = fc;
            c = b - INV_PHI * (b - a);
            fc = fitness_of_weight(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + INV_PHI * (b - a);
            fd = fitness_of_weight(d);
        }
    }
    clamp(1.0 / libm::sqrt(0.5 * (a + b)), lo, hi)
}

/// The optimal sphere's radius in units of `s`, to f64's precision (`fit32::sphere`).
fn exact_sphere(fast: &Fitness32, search: &SearchBox) -> f64 {
    fast.optimal_sphere(search.unit_lo, search.unit_hi)
}

/// The f32 search's start candidate: the better, by the f32 form, of the least-squares
/// ellipsoid and the optimal sphere, as semi-axes in units of `s`.
fn moment_candidate32(unit: &UnitMoments, fast: &Fitness32, search: &SearchBox) -> [f64; 3] {
    let sphere = fast.sphere();
    let estimate = sphere.estimate(search.unit_lo, search.unit_hi);
    match least_squares_axes(unit.raw, unit.mean, search.unit_lo, search.unit_hi) {
        // The comparison is in f32, where the sphere's f32 estimate serves; its exact radius
        // (a step in soft f64 on the M4F) only when the sphere wins.
        Some(e)
            if fast.fitness(&e.map(|r| r as f32)) <= fast.fitness(&[estimate.radius32(); 3]) =>
        {
            e
        }
        _ => [sphere.exact(&estimate); 3],
    }
}

/// Semi-axes minimising eq. 12's residual, `w = E[q q^T]^-1 E[q]`, each clamped into the box.
fn least_squares_semi_axes(moments: &CentralMoments, lo: f64, hi: f64) -> Option<[f64; 3]> {
    least_squares_axes(moments.fourth, moments.second, lo, hi)
}

/// [`least_squares_semi_axes`] from `E[q q^T]` and `E[q]` in any unit of length.
fn least_squares_axes(
    fourth: [[f64; 3]; 3],
    second: [f64; 3],
    lo: f64,
    hi: f64,
) -> Option<[f64; 3]> {
    let w = solve3(fourth, second)?;
    Some(w.map(|w| {
        if w > 0.0 {
            clamp(1.0 / libm::sqrt(w), lo, hi)
        } else {
            hi
        }
    }))
}

/// The better of the least-squares ellipsoid and the optimal sphere, inside the search box.
fn moment_candidate(
    moments: &CentralMoments,
    terms: &FitnessTerms,
    search: &SearchBox,
) -> [f64; 3] {
    let (lo, hi) = (search.lo, search.hi);
    let sphere = [optimal_sphere_radius(terms, lo, hi); 3];
    match least_squares_semi_axes(moments, lo, hi) {
        Some(e) if terms.fitness(&e) <= terms.fitness(&sphere) => e,
        _ => sphere,
    }
}

/// A cheap estimate of a cluster's eq. 13 error from its moments alone, for decisions that
/// cannot see the points (the streaming mapper's tolerance mode): the least-squares fit's
/// algebraic residual over the mean gradient norm, `sqrt(E[g^2] / sum_j w_j^2 E[d_j^2])`, which
/// is the first-order distance to the surface (exact for points near a sphere).
pub fn surface_error_estimate(moments: &CentralMoments, params: &FitParams) -> f64 {
    let terms = FitnessTerms::new(moments, params.alpha, params.volume);
    let search = SearchBox::new(moments, params);
    // Closed forms only (it runs for every merge candidate): the least-squares ellipsoid, or
    // the least-squares sphere `r^2 = E[|d|^4] / E[|d|^2]` where the 3x3 system is singular.
    let r = least_squares_semi_axes(moments, search.lo, search.hi).unwrap_or_else(|| {
        let first: f64 = moments.second.iter().sum();
        let second: f64 = moments.fourth.iter().flatten().sum();
        [clamp(libm::sqrt(second / first), search.lo, search.hi); 3]
    });
    let w = r.map(|r| 1.0 / (r * r));
    let residual = terms.residual_rms(&w);
    let gradient: f64 = (0..3).map(|j| w[j] * w[j] * moments.second[j]).sum();
    if gradient > 0.0 {
        residual / libm::sqrt(gradient)
    } else {
        0.0
    }
}

/// Fits the ellipsoid semi-axes of one cluster (eq. 12 by DE) with a `POP`-member population:
/// the search runs in f32 on [`Fitness32`], the reported fitness is eq. 12 in f64.
pub fn fit_ellipsoid<const POP: usize, R: Rng + ?Sized>(
    moments: &CentralMoments,
    params: &FitParams,
    rng: &mut R,
) -> Fit {
    let (terms, search, best, evaluations) = search_ellipsoid::<POP, R>(moments, params, rng);
    finish(
        &terms,
        search.entity32(center_of(moments), best, &params.degeneration),
        best.map(|x| search.semi_axis_of32(x)),
        (search.lo, search.hi),
        evaluations,
        false,
    )
}

/// The DE search of [`fit_ellipsoid`]: its terms, box, best search coordinates and evaluation
/// count.
fn search_ellipsoid<const POP: usize, R: Rng + ?Sized>(
    moments: &CentralMoments,
    params: &FitParams,
    rng: &mut R,
) -> (FitnessTerms, SearchBox, [f32; 3], u32) {
    let terms = FitnessTerms::new(moments, params.alpha, params.volume);
    let search = SearchBox::new(moments, params);
    let unit = UnitMoments::new(&terms, search.scale);
    let fast = Fitness32::of_unit(&unit, &terms, search.scale);
    let seed = match params.initialisation {
        Initialisation::Random => None,
        Initialisation::MomentSeeded => Some(moment_candidate32(&unit, &fast, &search)),
    };
    let (best, evaluations) =
        search.minimize32::<3, POP, R>(|r| fast.fitness(r), seed, params, rng);
    (terms, search, best, evaluations)
}

/// The entity of [`fit_ellipsoid_paper`], the same bits, without the fit's statistics (eq. 12
/// in f64, its residual and volume term, the bound counts): the streaming mapper keeps only
/// the entity, and on a Cortex-M4F those sums are soft-float routines at every fit.
pub fn fit_entity_paper<R: Rng + ?Sized>(
    moments: &CentralMoments,
    params: &FitParams,
    rng: &mut R,
) -> Entity {
    let (_, search, best, _) = search_ellipsoid::<PAPER_POPULATION, R>(moments, params, rng);
    search.entity32(center_of(moments), best, &params.degeneration)
}

/// Fits one radius (the spherical map of Section 4.5), by the same DE on eq. 12.
pub fn fit_sphere<const POP: usize, R: Rng + ?Sized>(
    moments: &CentralMoments,
    params: &FitParams,
    rng: &mut R,
) -> Fit {
    let terms = FitnessTerms::new(moments, params.alpha, params.volume);
    let search = SearchBox::new(moments, params);
    let fast = Fitness32::new(&terms, search.scale);
    let seed = match params.initialisation {
        Initialisation::Random => None,
        Initialisation::MomentSeeded => Some([exact_sphere(&fast, &search)]),
    };
    let ([best], evaluations) =
        search.minimize32::<1, POP, R>(|r| fast.fitness(&[r[0]; 3]), seed, params, rng);
    let radius = search.semi_axis_of32(best);
    finish(
        &terms,
        Entity::sphere(center_of(moments), radius),
        [radius; 3],
        (search.lo, search.hi),
        evaluations,
        true,
    )
}

/// [`fit_ellipsoid`] as it was before the f32 search: DE in f64 on the raw moment form. Kept
/// as the baseline `mema bench` measures the f32 fit against.
pub fn fit_ellipsoid_f64<const POP: usize, R: Rng + ?Sized>(
    moments: &CentralMoments,
    params: &FitParams,
    rng: &mut R,
) -> Fit {
    let terms = FitnessTerms::new(moments, params.alpha, params.volume);
    let search = SearchBox::new(moments, params);
    let bounds = (search.lo, search.hi);
    let seed = match params.initialisation {
        Initialisation::Random => None,
        Initialisation::MomentSeeded => Some(moment_candidate(moments, &terms, &search)),
    };
    let (semi_axes, evaluations) =
        search.minimize::<3, POP, R>(|r| terms.fitness(r), seed, params, rng);
    finish(
        &terms,
        Entity::from_semi_axes(center_of(moments), semi_axes, &params.degeneration),
        semi_axes,
        bounds,
        evaluations,
        false,
    )
}

/// [`fit_sphere`] before the f32 search (see [`fit_ellipsoid_f64`]).
pub fn fit_sphere_f64<const POP: usize, R: Rng + ?Sized>(
    moments: &CentralMoments,
    params: &FitParams,
    rng: &mut R,
) -> Fit {
    let terms = FitnessTerms::new(moments, params.alpha, params.volume);
    let search = SearchBox::new(moments, params);
    let seed = match params.initialisation {
        Initialisation::Random => None,
        Initialisation::MomentSeeded => Some([optimal_sphere_radius(&terms, search.lo, search.hi)]),
    };
    let ([radius], evaluations) =
        search.minimize::<1, POP, R>(|r| terms.sphere_fitness(r[0]), seed, params, rng);
    finish(
        &terms,
        Entity::sphere(center_of(moments), radius),
        [radius; 3],
        (search.lo, search.hi),
        evaluations,
        true,
    )
}

/// A semi-axis this close to a bound of the box rests on it: the f32 search holds the bound
/// to f32's precision (6e-8), the f64 one exactly.
const ON_BOUND: f64 = 1e-6;

/// The entity's centre: the cluster's mean.
fn center_of(moments: &CentralMoments) -> Point3 {
    Point3::new(
        moments.mean[0] as f32,
        moments.mean[1] as f32,
        moments.mean[2] as f32,
    )
}

/// A fit's report: `entity` and the f64 statistics of eq. 12 at `semi_axes`.
fn finish(
    terms: &FitnessTerms,
    entity: Entity,
    semi_axes: [f64; 3],
    (lo, hi): (f64, f64),
    evaluations: u32,
    sphere: bool,
) -> Fit {
    let weights = semi_axes.map(|r| 1.0 / (r * r));
    // A sphere's three semi-axes are one radius: it counts once.
    let axes = semi_axes.iter().take(if sphere { 1 } else { 3 });
    let on_upper_bound = axes
        .clone()
        .filter(|&&r| r >= hi * (1.0 - ON_BOUND))
        .count() as u8;
    let on_lower_bound = axes.filter(|&&r| r <= lo * (1.0 + ON_BOUND)).count() as u8;
    Fit {
        entity,
        semi_axes,
        fitness: terms.fitness(&semi_axes),
        residual_rms: terms.residual_rms(&weights),
        volume_term: terms.volume_term(&semi_axes),
        on_upper_bound,
        on_lower_bound,
        evaluations,
    }
}

/// [`fit_ellipsoid`] with the paper's population of 10.
pub fn fit_ellipsoid_paper<R: Rng + ?Sized>(
    moments: &CentralMoments,
    params: &FitParams,
    rng: &mut R,
) -> Fit {
    fit_ellipsoid::<PAPER_POPULATION, R>(moments, params, rng)
}

/// [`fit_sphere`] with the paper's population of 10.
pub fn fit_sphere_paper<R: Rng + ?Sized>(
    moments: &CentralMoments,
    params: &FitParams,
    rng: &mut R,
) -> Fit {
    fit_sphere::<PAPER_POPULATION, R>(moments, params, rng)
}

#[cfg(test)]
mod tests;
