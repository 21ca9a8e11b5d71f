//! A full-precision f64 reference on `nalgebra`, written apart from the core's code paths:
//! - [`moments`]: mean, second and fourth central moments by direct two-pass sums, not the
//!   core's shifted power sums;
//! - [`fitness`]: eq. 12 as a per-point sum over the cluster, not the core's O(1) quadratic form;
//! - [`de`]: DE/rand/1/bin driven by the same random numbers as the core (the cluster's PCG32
//!   stream seeds the DE's 32-bit generator, written here apart from the core: the same draws in
//!   the same order, which is what "the same random sequence" means), on that direct fitness;
//!   its moment-derived start solves the least-squares system with nalgebra's LU and finds the
//!   best sphere by bisection on the direct sum's derivative in `w = 1/r^2` (the core: Newton's
//!   method on the moment form);
//! - [`closest_point`]: eq. 13 by Newton's method on the Lagrange condition, safeguarded by a
//!   bracket, not Eberly's bisection.

pub mod closest_point;
pub mod de;
pub mod fitness;
pub mod moments;

use mema_core::fit::{FitParams, SemiAxisBounds};
use mema_core::rng::Pcg32;
use nalgebra::Vector3;

/// The reference's fit of one cluster.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceFit {
    /// DE's semi-axes (finite, before degeneration).
    pub semi_axes: [f64; 3],
    /// Eq. 12 at `semi_axes`, by direct sum.
    pub fitness: f64,
    /// Semi-axes after degeneration: infinite where the threshold was reached.
    pub stored_axes: [f64; 3],
}

impl ReferenceFit {
    pub fn degenerated_axes(&self) -> usize {
        self.stored_axes.iter().filter(|r| r.is_infinite()).count()
    }
}

/// Fits one cluster's points as the core's `fit_ellipsoid_paper` does, by independent means.
pub fn fit_cluster(
    points: &[Vector3<f64>],
    params: &FitParams,
    rng: &mut Pcg32,
) -> Option<ReferenceFit> {
    let m = moments::direct_moments(points)?;
    let f = fitness::DirectFitness::new(points, &m, params.alpha);
    let s = m.second.sum().sqrt();
    let s = if s > 0.0 && s.is_finite() { s } else { 1e-6 };
    let (lo, hi) = match params.bounds {
        SemiAxisBounds::Spread { lower, upper } => ((lower * s).max(f64::MIN_POSITIVE), upper * s),
        // The threshold box searches ln r; the reference covers the default (spread) box only.
        SemiAxisBounds::Threshold { .. } => return None,
    };
    let hi = hi.max(lo);
    let seed = de::moment_candidate(&m, &f, lo, hi);
    let (best, fitness) = de::minimize(|r| f.eval(r), lo, hi, s, Some(seed), &params.de, rng);
    let semi_axes = [best.x, best.y, best.z];
    Some(ReferenceFit {
        semi_axes,
        fitness,
        stored_axes: degenerate(semi_axes, params.degeneration.threshold),
    })
}

/// Table 1: axes at or over the threshold become infinite, except the thinnest.
pub fn degenerate(r: [f64; 3], threshold: f64) -> [f64; 3] {
    let thinnest = (0..3).fold(0, |t, j| if r[j] < r[t] { j } else { t });
    let mut out = r;
    for j in 0..3 {
        if r[j] >= threshold && j != thinnest {
            out[j] = f64::INFINITY;
        }
    }
    out
}
