//! Eq. 12 as written: `alpha sqrt(mean_i (psi1(X_i) . psi2(E))^2) + (1 - alpha) (4/3) pi r_x r_y
//! r_z / n`, with `psi1(X) . psi2(E) = (1 - sum_j (x_j - c_j)^2 / r_j^2) / 2`, summed point by point.

use nalgebra::Vector3;

use super::moments::DirectMoments;

#[derive(Debug)]
pub struct DirectFitness {
    /// `(x - c)^2` per point, componentwise.
    squared_offsets: Vec<Vector3<f64>>,
    alpha: f64,
}

impl DirectFitness {
    pub fn new(points: &[Vector3<f64>], m: &DirectMoments, alpha: f64) -> Self {
        Self {
            squared_offsets: points
                .iter()
                .map(|p| (p - m.mean).component_mul(&(p - m.mean)))
                .collect(),
            alpha,
        }
    }

    /// Eq. 12 for semi-axes `r` (finite, positive).
    pub fn eval(&self, r: &Vector3<f64>) -> f64 {
        let w = r.map(|v| 1.0 / (v * v));
        let n = self.squared_offsets.len() as f64;
        let sum: f64 = self
            .squared_offsets
            .iter()
            .map(|q| {
                let g = 0.5 * (1.0 - q.dot(&w));
                g * g
            })
            .sum();
        self.alpha * (sum / n).sqrt()
            + (1.0 - self.alpha) * 4.0 / 3.0 * std::f64::consts::PI * r.x * r.y * r.z / n
    }

    /// The derivative of eq. 12 over spheres (`r_x = r_y = r_z = 1/sqrt(w)`) in `w`.
    pub fn sphere_slope(&self, w: f64) -> f64 {
        let n = self.squared_offsets.len() as f64;
        let (mut g2, mut g_dg) = (0.0, 0.0);
        for q in &self.squared_offsets {
            let sum = q.x + q.y + q.z;
            let g = 0.5 * (1.0 - w * sum);
            g2 += g * g;
            g_dg += g * (-0.5 * sum);
        }
        let rms = (g2 / n).sqrt();
        let residual = if rms > 0.0 {
            self.alpha * (g_dg / n) / rms
        } else {
            0.0
        };
        residual
            - 1.5 * (1.0 - self.alpha) * 4.0 / 3.0 * std::f64::consts::PI / n / (w * w * w.sqrt())
    }
}
