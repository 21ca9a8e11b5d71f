//! Eq. 12 evaluated from a cluster's central moments in O(1).
//!
//! With `q_j = (x_j - c_j)^2` and `g = psi1(X)^T psi2(E) = (1 - w . q) / 2`, the mean square is a
//! quadratic in the weights: `E[g^2] = (1 - 2 w . E[q] + w^T E[q q^T] w) / 4`. `E[q]` are the
//! second central moments and `E[q q^T]` the fourth-order ones, so no pass over the points is
//! needed per evaluation.

use crate::moments::CentralMoments;

/// The paper's alpha (Section 4).
pub const PAPER_ALPHA: f64 = 0.8;

const FOUR_THIRDS_PI: f64 = 4.0 / 3.0 * core::f64::consts::PI;

/// How eq. 12's second term measures volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum VolumeTerm {
    /// `(1 - alpha) (4/3) pi r_x r_y r_z / |S_i|`, exactly as printed. Its size depends on the
    /// cloud's unit: negligible for metre-scale objects, dominant for clouds in feet or mm.
    #[default]
    Exact,
    /// `(1 - alpha) r_x r_y r_z / s^3`: the entity's volume over that of the sphere of the
    /// cluster's RMS radius `s`. Unit-free, so alpha means the same on any cloud.
    SpreadRelative,
}

/// The cluster-dependent constants of eq. 12, computed once per fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitnessTerms {
    pub alpha: f64,
    /// `E[d_j^2]`.
    pub second: [f64; 3],
    /// `E[d_j^2 d_k^2]`.
    pub fourth: [[f64; 3]; 3],
    /// Multiplies `r_x r_y r_z` in the volume term.
    pub volume_scale: f64,
}

impl FitnessTerms {
    pub fn new(moments: &CentralMoments, alpha: f64, volume: VolumeTerm) -> Self {
        let n = (moments.count.max(1)) as f64;
        let volume_scale = match volume {
            VolumeTerm::Exact => (1.0 - alpha) * FOUR_THIRDS_PI / n,
            VolumeTerm::SpreadRelative => {
                let s = moments.rms_radius();
                if s > 0.0 {
                    (1.0 - alpha) / (s * s * s)
                } else {
                    (1.0 - alpha) * FOUR_THIRDS_PI / n
                }
            }
        };
        Self {
            alpha,
            second: moments.second,
            fourth: moments.fourth,
            volume_scale,
        }
    }

    /// `sqrt(mean (psi1(X)^T psi2(E))^2)` for weights `w_j = 1 / r_j^2` (zero: degenerated axis).
    pub fn residual_rms(&self, weights: &[f64; 3]) -> f64 {
        let mut linear = 0.0;
        let mut quadratic = 0.0;
        for j in 0..3 {
            linear += weights[j] * self.second[j];
            for k in 0..3 {
                quadratic += weights[j] * weights[k] * self.fourth[j][k];
            }
        }
        // Rounding can take an (exactly) zero mean square a hair below zero.
        let mean_square = ((1.0 - 2.0 * linear + quadratic) * 0.25).max(0.0);
        libm::sqrt(mean_square)
    }

    /// The volume term for finite semi-axes.
    pub fn volume_term(&self, semi_axes: &[f64; 3]) -> f64 {
        self.volume_scale * semi_axes[0] * semi_axes[1] * semi_axes[2]
    }

    /// Eq. 12 for an ellipsoid with semi-axes `(r_x, r_y, r_z)`.
    pub fn fitness(&self, semi_axes: &[f64; 3]) -> f64 {
        let weights = semi_axes.map(|r| 1.0 / (r * r));
        self.alpha * self.residual_rms(&weights) + self.volume_term(semi_axes)
    }

    /// Eq. 12 for a sphere of radius `r` (one-radius fit, volume `(4/3) pi r^3`).
    pub fn sphere_fitness(&self, radius: f64) -> f64 {
        self.fitness(&[radius; 3])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::moments::Moments;
    use crate::test_support::{OrFail, TestResult};

    /// Direct per-point eq. 12 in f64, the independent computation.
    fn direct(points: &[[f64; 3]], alpha: f64, r: [f64; 3]) -> f64 {
        let n = points.len() as f64;
        let mut c = [0.0; 3];
        for p in points {
            for j in 0..3 {
                c[j] += p[j] / n;
            }
        }
        let mut sum = 0.0;
        for p in points {
            let mut s = 0.0;
            for j in 0..3 {
                s += (p[j] - c[j]) * (p[j] - c[j]) / (r[j] * r[j]);
            }
            let g = 0.5 * (1.0 - s);
            sum += g * g;
        }
        alpha * (sum / n).sqrt() + (1.0 - alpha) * FOUR_THIRDS_PI * r[0] * r[1] * r[2] / n
    }

    #[test]
    fn moments_fitness_equals_direct_sum() -> TestResult {
        // Points on a noisy ellipsoid shell: the residual is small, the hard case for moments.
        let mut pts = [[0.0; 3]; 200];
        let mut s = 11u64;
        for (i, p) in pts.iter_mut().enumerate() {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
            let noise = ((s >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 0.002;
            let t = i as f64 * 0.37;
            let u = i as f64 * 0.11;
            *p = [
                5.0 + 0.3 * (1.0 + noise) * t.cos() * u.sin(),
                -2.0 + 0.2 * t.sin() * u.sin(),
                0.1 * u.cos(),
            ];
        }
        let mut m = Moments::new();
        for p in &pts {
            m.add_f64(*p);
        }
        let terms = FitnessTerms::new(&m.central().or_fail("points")?, 0.8, VolumeTerm::Exact);
        for r in [[0.3, 0.2, 0.1], [0.5, 0.5, 0.5], [0.05, 2.0, 0.01]] {
            let want = direct(&pts, 0.8, r);
            let got = terms.fitness(&r);
            assert!((got - want).abs() <= 1e-9 * want, "{r:?}: {got} vs {want}");
        }
        Ok(())
    }
}
