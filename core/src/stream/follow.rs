//! Surface following in the stream: a point joins the nearby cluster whose Gaussian explains it
//! best, not merely the nearest centre.
//!
//! The batch map moves each point, after k-means, to the neighbouring cluster whose Gaussian
//! explains it best (Mahalanobis distance plus the covariance's log-determinant), so clusters
//! stretch along the surfaces they sample and thin across them. The stream sees each point once,
//! so it makes the same choice as the point arrives, among the clusters within the join radius,
//! from a Gaussian cached per cluster and refreshed as the cluster grows.

use crate::moments::FixedMoments;
use crate::shell::symmetric_eigen;

/// A cluster's Gaussian is trusted from this many points: fewer have no covariance worth the
/// name, and the point joins the nearest centre.
pub const MIN_POINTS: u64 = 8;

/// No variance below this fraction of the cluster's largest: coplanar points have a zero one,
/// and its inverse would pull every point of the plane's neighbours into it (the batch's floor).
const VARIANCE_FLOOR: f64 = 1e-4;

/// A cluster's Gaussian as the assignment reads it: the inverse covariance (upper triangle:
/// xx, xy, xz, yy, yz, zz) and the log-determinant, in f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gaussian {
    precision: [f32; 6],
    log_det: f32,
    /// The cluster's count when it was computed: refreshed once the count doubles, so a
    /// cluster of n points pays for log2(n) refreshes in all.
    count: u64,
}

impl Gaussian {
    /// None yet: the cluster joins by distance.
    pub const NONE: Self = Self {
        precision: [0.0; 6],
        log_det: 0.0,
        count: 0,
    };

    /// Whether the assignment may use it.
    pub fn is_some(&self) -> bool {
        self.count > 0
    }

    /// Whether `moments` have grown enough since this was computed to compute it again.
    pub fn due(&self, moments: &FixedMoments) -> bool {
        let n = moments.count();
        n >= MIN_POINTS && n >= 2 * self.count
    }

    /// The Gaussian of `moments`, or [`Gaussian::NONE`] for too few points or a degenerate
    /// covariance.
    pub fn of(moments: &FixedMoments) -> Self {
        let n = moments.count();
        if n < MIN_POINTS {
            return Self::NONE;
        }
        let Some((_, covariance)) = moments.covariance() else {
            return Self::NONE;
        };
        let (values, vectors) = symmetric_eigen(covariance);
        let floor = values[0] * VARIANCE_FLOOR;
        if !(floor.is_finite() && floor > 0.0) {
            return Self::NONE;
        }
        let values = values.map(|v| v.max(floor));
        let inverse = |a: usize, b: usize| -> f32 {
            let mut s = 0.0;
            for (j, v) in values.iter().enumerate() {
                s += vectors[a][j] * vectors[b][j] / v;
            }
            s as f32
        };
        let log_det = values.iter().map(|v| libm::log(*v)).sum::<f64>();
        Self {
            precision: [
                inverse(0, 0),
                inverse(0, 1),
                inverse(0, 2),
                inverse(1, 1),
                inverse(1, 2),
                inverse(2, 2),
            ],
            log_det: log_det as f32,
            count: n,
        }
    }

    /// Twice the negative log-likelihood of offset `d` from the cluster's centre, constants
    /// aside.
    #[inline]
    pub fn cost(&self, d: [f32; 3]) -> f32 {
        let [xx, xy, xz, yy, yz, zz] = self.precision;
        let [x, y, z] = d;
        x * (xx * x + 2.0 * (xy * y + xz * z)) + y * (yy * y + 2.0 * yz * z) + zz * z * z
            + self.log_det
    }
}
