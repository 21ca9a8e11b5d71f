//! Central moments by direct two-pass sums over the points.

use nalgebra::{Matrix3, Vector3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectMoments {
    pub count: usize,
    pub mean: Vector3<f64>,
    /// `E[d_j^2]`.
    pub second: Vector3<f64>,
    /// `E[d_j^2 d_k^2]`.
    pub fourth: Matrix3<f64>,
}

/// `None` for no points.
pub fn direct_moments(points: &[Vector3<f64>]) -> Option<DirectMoments> {
    if points.is_empty() {
        return None;
    }
    let n = points.len() as f64;
    let mean = points.iter().sum::<Vector3<f64>>() / n;
    let mut second = Vector3::zeros();
    let mut fourth = Matrix3::zeros();
    for p in points {
        let q = (p - mean).component_mul(&(p - mean));
        second += q;
        fourth += q * q.transpose();
    }
    Some(DirectMoments {
        count: points.len(),
        mean,
        second: second / n,
        fourth: fourth / n,
    })
}
