//! Rigid transforms of entities and maps.
//!
//! A translation moves the centre: in G(6,3) `psi1(X + t) . psi2(E + t) = psi1(X) . psi2(E)`
//! for every point, exactly. A signed axis permutation (a rotation that maps axes onto axes)
//! permutes the centre and the weights: exact too. A general rotation turns an axis-aligned
//! ellipsoid into an oriented one, which the 24-byte entity cannot hold; mema then stores the
//! axis-aligned ellipsoid inscribed in the rotated ellipsoid's bounding box, semi-axes
//! `r'_j = sqrt(sum_k R_jk^2 r_k^2)`. It has the same per-axis second moments as the rotated
//! ellipsoid and touches all six faces of its box; it is exact for axis permutations. Keeping
//! the orientation instead would cost a unit quaternion, 16 more bytes per entity (24 -> 40).

use crate::geometry::{Entity, Point3};

/// `x' = rotation x + translation`, in the map's world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidTransform {
    pub rotation: [[f64; 3]; 3],
    pub translation: [f64; 3],
}

impl RigidTransform {
    pub const IDENTITY: Self = Self {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0; 3],
    };

    pub fn translation(t: [f64; 3]) -> Self {
        Self {
            translation: t,
            ..Self::IDENTITY
        }
    }

    /// Rotation by `angle` radians about axis `axis` (0 = x, 1 = y, 2 = z), right-handed.
    pub fn rotation_about(axis: usize, angle: f64) -> Self {
        let (s, c) = (libm::sin(angle), libm::cos(angle));
        let rotation = match axis {
            0 => [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
            1 => [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
            _ => [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
        };
        Self {
            rotation,
            translation: [0.0; 3],
        }
    }

    /// `self` after `first`.
    pub fn after(&self, first: &RigidTransform) -> Self {
        let mut rotation = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                rotation[i][j] = (0..3)
                    .map(|k| self.rotation[i][k] * first.rotation[k][j])
                    .sum();
            }
        }
        Self {
            rotation,
            translation: self.apply_point(first.translation),
        }
    }

    pub fn apply_point(&self, p: [f64; 3]) -> [f64; 3] {
        let mut out = self.translation;
        for (i, o) in out.iter_mut().enumerate() {
            *o += (0..3).map(|k| self.rotation[i][k] * p[k]).sum::<f64>();
        }
        out
    }

    pub fn rotate_vector(&self, v: [f64; 3]) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (i, o) in out.iter_mut().enumerate() {
            *o = (0..3).map(|k| self.rotation[i][k] * v[k]).sum();
        }
        out
    }

    /// True if the rotation maps each axis onto an axis (entries 0 or +-1): transforms are exact.
    pub fn is_axis_permutation(&self) -> bool {
        self.rotation.iter().all(|row| {
            row.iter().filter(|v| **v != 0.0).count() == 1
                && row.iter().all(|v| *v == 0.0 || v.abs() == 1.0)
        })
    }

    /// The entity's shape rotated (its centre is moved by the caller, in its own frame).
    pub fn rotate_shape(&self, e: &Entity) -> [f32; 3] {
        let mut weights = [0.0f32; 3];
        for (j, w) in weights.iter_mut().enumerate() {
            let mut r2 = 0.0f64;
            let mut infinite = false;
            for k in 0..3 {
                let m = self.rotation[j][k] * self.rotation[j][k];
                if m == 0.0 {
                    continue;
                }
                let wk = e.weights[k] as f64;
                if wk == 0.0 {
                    infinite = true;
                } else {
                    r2 += m / wk;
                }
            }
            *w = if infinite || !(r2 > 0.0) {
                0.0
            } else if self.is_axis_permutation() {
                // Exact: the permuted weight itself, never a round trip through r.
                (0..3)
                    .find(|&k| self.rotation[j][k] != 0.0)
                    .and_then(|k| e.weights.get(k).copied())
                    .unwrap_or(0.0)
            } else {
                (1.0 / r2) as f32
            };
        }
        weights
    }

    /// The entity in a frame whose origin is unchanged: centre rotated and translated.
    pub fn apply_entity(&self, e: &Entity) -> Entity {
        let c = self.apply_point(e.center.to_f64());
        Entity {
            center: Point3::new(c[0] as f32, c[1] as f32, c[2] as f32),
            weights: self.rotate_shape(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Degeneration, psi_inner_product, psi1};

    #[test]
    fn translation_keeps_every_g63_inner_product() {
        let e = Entity::from_semi_axes(
            Point3::new(0.5, -0.25, 2.0),
            [0.5, 1.0, 0.25],
            &Degeneration::default(),
        );
        let t = RigidTransform::translation([1.5, -3.0, 0.75]);
        let moved = t.apply_entity(&e);
        for p in [[0.0, 0.0, 0.0], [1.0, -0.25, 2.0], [3.0, 2.0, -1.0]] {
            let x = Point3::new(p[0] as f32, p[1] as f32, p[2] as f32);
            let q = t.apply_point(p);
            let xq = Point3::new(q[0] as f32, q[1] as f32, q[2] as f32);
            let before = psi_inner_product(&psi1(x), &e.psi2());
            let after = psi_inner_product(&psi1(xq), &moved.psi2());
            assert!((before - after).abs() < 1e-5, "{p:?}: {before} vs {after}");
        }
    }

    #[test]
    fn axis_permutations_are_exact_and_rotations_inscribe_the_box() {
        let e = Entity::from_semi_axes(
            Point3::new(1.0, 2.0, 3.0),
            [0.5, 1.0, 0.25],
            &Degeneration::default(),
        );
        let quarter = RigidTransform::rotation_about(2, core::f64::consts::FRAC_PI_2);
        // sin(pi/2) is 1, cos(pi/2) is 6e-17: snap to the exact permutation first.
        let snapped = RigidTransform {
            rotation: quarter.rotation.map(|r| r.map(libm::round)),
            ..quarter
        };
        assert!(snapped.is_axis_permutation());
        let p = snapped.apply_entity(&e);
        assert_eq!(p.weights, [e.weights[1], e.weights[0], e.weights[2]]);
        assert_eq!(p.center, Point3::new(-2.0, 1.0, 3.0));
        // 45 degrees about z: the x and y semi-axes both become sqrt((0.5^2 + 1^2) / 2).
        let r = RigidTransform::rotation_about(2, core::f64::consts::FRAC_PI_4).apply_entity(&e);
        let want = libm::sqrt((0.25 + 1.0) / 2.0);
        let axes = r.semi_axes();
        assert!((axes[0] as f64 - want).abs() < 1e-6 && (axes[1] as f64 - want).abs() < 1e-6);
        assert!((axes[2] - 0.25).abs() < 1e-7);
    }
}
