//! Oriented shells: an entity from a cluster's second moments alone, turned to its principal
//! axes.
//!
//! The paper fits axis-aligned semi-axes to eq. 12, whose algebraic residual and volume term
//! reward a shell passing sideways through the points, and whose axes cannot follow a tilted
//! surface. Measured both ways against the points (README, "Fidelity"), a shell on the
//! cluster's principal axes with semi-axes proportional to the standard deviations is closer
//! to the points and leaves less phantom surface, costs no search, and needs only the mean and
//! covariance, which the streaming mapper keeps anyway.

use crate::geometry::{Degeneration, Entity, Point3};
use crate::rotation::Rotation;

/// Cyclic Jacobi sweeps: a 3 x 3 symmetric matrix converges to f64 precision in 4 to 6; the cap
/// only bounds the work on hostile input.
const MAX_SWEEPS: usize = 32;

/// Semi-axes `r_j = scale_j sqrt(lambda_j)` along the principal axes, largest variance first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellParams {
    /// Scale of the two largest standard deviations: the extent of a surface patch. A uniform
    /// disc of radius R has sigma = R / 2, a uniform square of half side a has sigma = a / sqrt 3.
    pub tangent_scale: f64,
    /// Scale of the smallest one: a patch's thickness (noise, curvature), where the best shell
    /// sits at about the mean absolute offset, 0.8 sigma for Gaussian noise.
    pub normal_scale: f64,
    /// No semi-axis shorter than this fraction of the longest (coplanar points have zero
    /// variance, and a zero semi-axis has no weight).
    pub min_ratio: f64,
    pub degeneration: Degeneration,
}

impl ShellParams {
    /// [`ShellParams::default`] as a constant, for a firmware's `static` initialiser (its
    /// degeneration is `Degeneration::default()`'s values).
    pub const DEFAULT: Self = Self {
        tangent_scale: 2.0,
        normal_scale: 0.7,
        min_ratio: 1e-3,
        degeneration: Degeneration {
            threshold: 4.0,
            sphere_tolerance: 0.01,
        },
    };
}

impl Default for ShellParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Eigenvalues (descending) and unit eigenvectors (the columns of the matrix, right-handed) of
/// a symmetric 3 x 3 matrix, by cyclic Jacobi rotations.
pub fn symmetric_eigen(a: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut a = a;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..MAX_SWEEPS {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if !(off > 1e-30 * diag) {
            break;
        }
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            // The same p and q, in a form whose indexing cannot panic (the loop is not unrolled).
            let (p, q) = (p.min(2), q.min(2));
            if a[p][q] == 0.0 {
                continue;
            }
            // The rotation that zeroes a[p][q] (Golub and Van Loan, Algorithm 8.4.1).
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t =
                libm::copysign(1.0, theta) / (libm::fabs(theta) + libm::sqrt(theta * theta + 1.0));
            let c = 1.0 / libm::sqrt(t * t + 1.0);
            let s = t * c;
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    // `i.min(2)` is `i` (an index of `order`): written so, no bounds check survives to panic.
    let diagonal = [a[0][0], a[1][1], a[2][2]];
    let mut order = [0usize, 1, 2];
    crate::num::insertion_sort_by(&mut order, |&i, &j| diagonal[i.min(2)] > diagonal[j.min(2)]);
    let values = order.map(|i| diagonal[i.min(2)]);
    let mut vectors = [[0.0; 3]; 3];
    for (col, &i) in order.iter().enumerate() {
        for row in 0..3 {
            vectors[row][col] = v[row][i.min(2)];
        }
    }
    // Right-handed, so the columns are a rotation: the third axis is the cross product.
    // Spelled out, not `[0, 1, 2].map(..)`: at opt-level "s" that map stays a loop whose
    // indexing keeps a bounds check.
    let [r0, r1, r2] = vectors;
    let (x, y) = ([r0[0], r1[0], r2[0]], [r0[1], r1[1], r2[1]]);
    let z = [
        x[1] * y[2] - x[2] * y[1],
        x[2] * y[0] - x[0] * y[2],
        x[0] * y[1] - x[1] * y[0],
    ];
    for r in 0..3 {
        vectors[r][2] = z[r];
    }
    (values, vectors)
}

/// The shell of a cluster of mean `mean` and covariance `covariance` (local frame), or `None`
/// if the covariance is not finite.
pub fn shell(mean: [f64; 3], covariance: [[f64; 3]; 3], params: &ShellParams) -> Option<Entity> {
    if !covariance.iter().flatten().all(|v| v.is_finite()) || !mean.iter().all(|v| v.is_finite()) {
        return None;
    }
    let (values, vectors) = symmetric_eigen(covariance);
    let scales = [
        params.tangent_scale,
        params.tangent_scale,
        params.normal_scale,
    ];
    let mut semi_axes = [0.0; 3];
    for j in 0..3 {
        semi_axes[j] = scales[j] * libm::sqrt(values[j].max(0.0));
    }
    let floor = semi_axes[0] * params.min_ratio;
    let floor = if floor > 0.0 {
        floor
    } else {
        f64::MIN_POSITIVE
    };
    for r in semi_axes.iter_mut() {
        *r = r.max(floor);
    }
    let rotation = Rotation::from_matrix(vectors).unwrap_or(Rotation::IDENTITY);
    let center = Point3::new(mean[0] as f32, mean[1] as f32, mean[2] as f32);
    Some(Entity::from_semi_axes(center, semi_axes, &params.degeneration).with_rotation(rotation))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{OrFail, TestResult};

    #[test]
    fn the_constant_defaults_are_the_defaults() {
        assert_eq!(ShellParams::DEFAULT.degeneration, Degeneration::default());
    }

    #[test]
    fn eigenpairs_reconstruct_the_matrix() {
        let a = [[4.0, 1.0, -2.0], [1.0, 3.0, 0.5], [-2.0, 0.5, 1.0]];
        let (values, v) = symmetric_eigen(a);
        assert!(values[0] >= values[1] && values[1] >= values[2]);
        for i in 0..3 {
            for j in 0..3 {
                let back: f64 = (0..3).map(|k| v[i][k] * values[k] * v[j][k]).sum();
                assert!((back - a[i][j]).abs() < 1e-12, "{i}{j}: {back}");
            }
        }
        assert!(crate::rotation::is_rotation(&v));
    }

    #[test]
    fn a_tilted_flat_cluster_gets_a_tilted_flat_shell() -> TestResult {
        // Variance 1 along (1, 1, 0)/sqrt 2, 0.25 along z, 0.0001 along (1, -1, 0)/sqrt 2.
        let (u, w) = (
            [
                core::f64::consts::FRAC_1_SQRT_2,
                core::f64::consts::FRAC_1_SQRT_2,
                0.0,
            ],
            [
                core::f64::consts::FRAC_1_SQRT_2,
                -core::f64::consts::FRAC_1_SQRT_2,
                0.0,
            ],
        );
        let z = [0.0, 0.0, 1.0];
        let mut cov = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] = u[i] * u[j] + 0.25 * z[i] * z[j] + 1e-4 * w[i] * w[j];
            }
        }
        let params = ShellParams {
            tangent_scale: 1.9,
            normal_scale: 1.0,
            ..ShellParams::default()
        };
        let e = shell([1.0, 2.0, 3.0], cov, &params).or_fail("finite")?;
        let r = e.semi_axes_f64();
        assert!(
            (r[0] - 1.9).abs() < 1e-5 && (r[1] - 0.95).abs() < 1e-5 && (r[2] - 0.01).abs() < 1e-5
        );
        // Its thin axis is w: a point 0.01 along w from the centre is on the surface.
        let p = [1.0 + 0.01 * w[0], 2.0 + 0.01 * w[1], 3.0];
        assert!(crate::closest_point::surface_distance(&e, p) < 1e-6);
        Ok(())
    }
}
