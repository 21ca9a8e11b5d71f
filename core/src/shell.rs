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

/// The float a Jacobi sweep runs in: f64 where precision decides, f32 where a single-precision
/// FPU (a Cortex-M4F's) makes it a tenth of the work ([`symmetric_eigen_single`]).
trait Real:
    Copy
    + PartialEq
    + PartialOrd
    + core::ops::Add<Output = Self>
    + core::ops::Sub<Output = Self>
    + core::ops::Mul<Output = Self>
    + core::ops::Div<Output = Self>
{
    const ZERO: Self;
    const ONE: Self;
    const TWO: Self;
    /// Off-diagonal weight, as a share of the diagonal's, under which the sweeps stop: well
    /// above the type's rounding squared, so a converged matrix is not rotated again.
    const CONVERGED: Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn copysign(self, sign: Self) -> Self;
}

/// `Real` for a float type by its libm routines.
macro_rules! real {
    ($t:ty, $converged:expr, $sqrt:path, $abs:path, $copysign:path) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const TWO: Self = 2.0;
            const CONVERGED: Self = $converged;
            fn sqrt(self) -> Self {
                $sqrt(self)
            }
            fn abs(self) -> Self {
                $abs(self)
            }
            fn copysign(self, sign: Self) -> Self {
                $copysign(self, sign)
            }
        }
    };
}

real!(f64, 1e-30, libm::sqrt, libm::fabs, libm::copysign);
real!(f32, 1e-13, libm::sqrtf, libm::fabsf, libm::copysignf);

/// Cyclic Jacobi rotations of a symmetric 3 x 3 matrix: its diagonal once converged and the
/// accumulated rotation (eigenvectors in its columns), in no order.
fn jacobi<T: Real>(a: [[T; 3]; 3]) -> ([T; 3], [[T; 3]; 3]) {
    let mut a = a;
    let (o, l) = (T::ZERO, T::ONE);
    let mut v = [[l, o, o], [o, l, o], [o, o, l]];
    for _ in 0..MAX_SWEEPS {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if !(off > T::CONVERGED * diag) {
            break;
        }
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            // The same p and q, in a form whose indexing cannot panic (the loop is not unrolled).
            let (p, q) = (p.min(2), q.min(2));
            if a[p][q] == T::ZERO {
                continue;
            }
            // The rotation that zeroes a[p][q] (Golub and Van Loan, Algorithm 8.4.1).
            let theta = (a[q][q] - a[p][p]) / (T::TWO * a[p][q]);
            let t = l.copysign(theta) / (theta.abs() + (theta * theta + l).sqrt());
            let c = l / (t * t + l).sqrt();
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
    ([a[0][0], a[1][1], a[2][2]], v)
}

/// Eigenvalues (descending) and unit eigenvectors (the columns of the matrix, right-handed) of
/// a symmetric 3 x 3 matrix, by cyclic Jacobi rotations.
pub fn symmetric_eigen(a: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let (diagonal, v) = jacobi(a);
    descending(diagonal, v)
}

/// [`symmetric_eigen`] for a device whose FPU has no f64: the rotations in f32, then each
/// eigenvalue the f64 Rayleigh quotient of its vector against the f64 matrix.
///
/// Why: in software f64 the eigen-solve was most of a shell's freeze on a Cortex-M4F (the 64 KiB
/// image's freezes cost 88,000 instructions with it, 37,000 with this one), and the price of a
/// freeze decides how often a stream could make room (docs/design.md, "A device's layout").
/// An f32
/// vector is within about 1e-7 rad of the true one, and a Rayleigh quotient's error is the
/// square of that times the spread of the eigenvalues: the thinnest shell the floor allows
/// (a variance 1e-6 of the largest) keeps its semi-axis to 1e-7 of itself, as f64 rotations
/// do. Every step is IEEE-rounded in a fixed order, so host and device agree bit for bit.
pub fn symmetric_eigen_single(a: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let (_, v) = jacobi(a.map(|row| row.map(|x| x as f32)));
    let v = orthonormal_columns(v.map(|row| row.map(f64::from)));
    let rayleigh = |k: usize| {
        let u = [0, 1, 2].map(|i| v.get(i).and_then(|r| r.get(k)).copied().unwrap_or(0.0));
        let mut quotient = 0.0;
        let mut norm = 0.0;
        for (row, &ui) in a.iter().zip(u.iter()) {
            let au = row[0] * u[0] + row[1] * u[1] + row[2] * u[2];
            quotient += ui * au;
            norm += ui * ui;
        }
        if norm > 0.0 { quotient / norm } else { 0.0 }
    };
    descending([rayleigh(0), rayleigh(1), rayleigh(2)], v)
}

/// `v`'s columns made orthonormal in f64 (Gram-Schmidt, in column order). Why: f32 rotations
/// leave them orthonormal to a few times 1e-7, and after many rotations past the 1e-6 that
/// [`Rotation::from_matrix`] allows: the shell then lost its rotation for the identity, a
/// stream's thin shell turned to the axes (bun000's stream at k = 400 had one).
fn orthonormal_columns(v: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let column = |j: usize| [v[0][j], v[1][j], v[2][j]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let unit = |a: [f64; 3]| {
        let n = libm::sqrt(dot(a, a));
        if n > 0.0 { a.map(|x| x / n) } else { a }
    };
    let minus =
        |a: [f64; 3], b: [f64; 3], k: f64| [a[0] - k * b[0], a[1] - k * b[1], a[2] - k * b[2]];
    let x = unit(column(0));
    let y = unit(minus(column(1), x, dot(x, column(1))));
    let z = minus(column(2), x, dot(x, column(2)));
    let z = unit(minus(z, y, dot(y, z)));
    [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]]
}

/// Eigenpairs ordered by value, largest first, the third vector the cross product of the first
/// two so the columns are a rotation.
fn descending(diagonal: [f64; 3], v: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    // `i.min(2)` is `i` (an index of `order`): written so, no bounds check survives to panic.
    let mut order = [0usize, 1, 2];
    crate::num::insertion_sort_by(&mut order, |&i, &j| diagonal[i.min(2)] > diagonal[j.min(2)]);
    let values = order.map(|i| diagonal[i.min(2)]);
    let mut vectors = [[0.0; 3]; 3];
    for (col, &i) in order.iter().enumerate() {
        for row in 0..3 {
            vectors[row][col] = v[row][i.min(2)];
        }
    }
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
    shell_by(mean, covariance, params, symmetric_eigen)
}

/// [`shell`] by [`symmetric_eigen_single`]: the streaming mapper's, whose shells a device makes.
pub fn shell_single(
    mean: [f64; 3],
    covariance: [[f64; 3]; 3],
    params: &ShellParams,
) -> Option<Entity> {
    shell_by(mean, covariance, params, symmetric_eigen_single)
}

type Eigen = fn([[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]);

fn shell_by(
    mean: [f64; 3],
    covariance: [[f64; 3]; 3],
    params: &ShellParams,
    eigen: Eigen,
) -> Option<Entity> {
    if !covariance.iter().flatten().all(|v| v.is_finite()) || !mean.iter().all(|v| v.is_finite()) {
        return None;
    }
    let (values, vectors) = eigen(covariance);
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

    /// A patch as thin as the shells' floor allows (variance 1e-6 of the largest), tilted so
    /// every entry is non-zero: the f32 rotations' eigenvalues, refined in f64, are the f64
    /// solver's to a millionth of each (the thin one too), and its axes within 1e-6 rad.
    #[test]
    fn single_precision_rotations_keep_the_thin_axis() {
        let (c, s) = (libm::cos(0.3), libm::sin(0.3));
        let (c2, s2) = (libm::cos(-1.1), libm::sin(-1.1));
        // A rotation about z then about x.
        let r = [[c, -s * c2, s * s2], [s, c * c2, -c * s2], [0.0, s2, c2]];
        for variances in [[4.0, 1.0, 4e-6], [2.0, 1.9, 1e-3], [1.0, 1e-6, 1e-6]] {
            let mut a = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    a[i][j] = (0..3).map(|k| r[i][k] * variances[k] * r[j][k]).sum();
                }
            }
            let (want, want_v) = symmetric_eigen(a);
            let (got, got_v) = symmetric_eigen_single(a);
            for k in 0..3 {
                assert!(
                    (got[k] - want[k]).abs() <= 1e-6 * want[k],
                    "{variances:?}: eigenvalue {k} {} against {}",
                    got[k],
                    want[k]
                );
            }
            assert!(crate::rotation::is_rotation(&got_v));
            // Axes with distinct variances: the same line either way.
            for k in 0..3 {
                let distinct = (0..3).all(|j| j == k || (want[j] - want[k]).abs() > 1e-3 * want[0]);
                if distinct {
                    // Cosine of the angle: the f32 columns are unit to f32's rounding only.
                    let dot: f64 = (0..3).map(|i| got_v[i][k] * want_v[i][k]).sum();
                    let norm: f64 = (0..3).map(|i| got_v[i][k] * got_v[i][k]).sum();
                    let cosine = dot.abs() / libm::sqrt(norm);
                    assert!(1.0 - cosine < 1e-12, "{variances:?}: axis {k} at {cosine}");
                }
            }
        }
    }

    /// Over many turned, thin covariances, the f32 rotations' vectors are a rotation (the
    /// shell keeps its turn: before they were made orthonormal in f64, some were off by more
    /// than `is_rotation` allows and their shells fell back to the axes), with the f64
    /// solver's thin axis where it is ten times thinner than the next.
    #[test]
    fn single_precision_vectors_are_always_a_rotation() {
        let mut rng = crate::rng::stream_rng(7, 0);
        let mut next = || crate::rng::uniform(&mut rng);
        for case in 0..20_000 {
            let q = [next() - 0.5, next() - 0.5, next() - 0.5, next() - 0.5];
            let Some(r) = Rotation::from_quaternion(q) else {
                continue;
            };
            let r = r.matrix();
            let variances = [
                1.0,
                10f64.powf(-3.0 * next()),
                10f64.powf(-6.0 * next() - 1.0),
            ];
            let mut a = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    a[i][j] = (0..3).map(|k| r[i][k] * variances[k] * r[j][k]).sum();
                }
            }
            let (_, got_v) = symmetric_eigen_single(a);
            assert!(
                crate::rotation::is_rotation(&got_v),
                "case {case}: {got_v:?}"
            );
            if variances[2] < 0.1 * variances[1] {
                let (_, want_v) = symmetric_eigen(a);
                let thin: f64 = (0..3).map(|i| got_v[i][2] * want_v[i][2]).sum();
                assert!(1.0 - thin.abs() < 1e-6, "case {case}: thin axis at {thin}");
            }
        }
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
