//! Rigid transforms of entities and maps.
//!
//! A translation moves the centre: in G(6,3) `psi1(X + t) . psi2(E + t) = psi1(X) . psi2(E)`
//! for every point, exactly. A signed axis permutation (a rotation that maps axes onto axes)
//! permutes the centre and the weights of an axis-aligned entity, so it stays axis-aligned (and
//! in the paper's 24-byte form) bit for bit. Any other rotation turns the entity: its rotation
//! becomes `R q` and its shape is kept, so `psi1(R^T (x - c))` and every distance move with the
//! map, to the f32 rounding of the stored quaternion.

use crate::geometry::{Entity, Point3};
use crate::rotation::Rotation;

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

    /// The permuted weights of an axis-aligned entity under an axis permutation: exact, never a
    /// round trip through r.
    fn permute_weights(&self, e: &Entity) -> [f32; 3] {
        [0, 1, 2].map(|j| {
            (0..3)
                .find(|&k| self.rotation[j][k] != 0.0)
                .and_then(|k| e.weights.get(k).copied())
                .unwrap_or(0.0)
        })
    }

    /// The entity in a frame whose origin is unchanged: centre rotated and translated, and the
    /// shape turned with it (`None` if `rotation` is not a rotation).
    pub fn apply_entity(&self, e: &Entity) -> Option<Entity> {
        let c = self.apply_point(e.center.to_f64());
        let center = Point3::new(c[0] as f32, c[1] as f32, c[2] as f32);
        if e.rotation.is_identity() && self.is_axis_permutation() {
            return Some(Entity::axis_aligned(center, self.permute_weights(e)));
        }
        let turn = Rotation::from_matrix(self.rotation)?;
        Some(Entity {
            center,
            weights: e.weights,
            rotation: turn.after(&e.rotation),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Degeneration, psi_inner_product, psi1};

    #[test]
    fn translation_keeps_every_g63_inner_product() -> Result<(), &'static str> {
        let e = Entity::from_semi_axes(
            Point3::new(0.5, -0.25, 2.0),
            [0.5, 1.0, 0.25],
            &Degeneration::default(),
        );
        let t = RigidTransform::translation([1.5, -3.0, 0.75]);
        let moved = t.apply_entity(&e).ok_or("a rotation")?;
        for p in [[0.0, 0.0, 0.0], [1.0, -0.25, 2.0], [3.0, 2.0, -1.0]] {
            let x = Point3::new(p[0] as f32, p[1] as f32, p[2] as f32);
            let q = t.apply_point(p);
            let xq = Point3::new(q[0] as f32, q[1] as f32, q[2] as f32);
            let before = psi_inner_product(&psi1(x), &e.psi2());
            let after = psi_inner_product(&psi1(xq), &moved.psi2());
            assert!((before - after).abs() < 1e-5, "{p:?}: {before} vs {after}");
        }
        Ok(())
    }

    #[test]
    fn axis_permutations_stay_axis_aligned_and_rotations_turn_the_entity()
    -> Result<(), &'static str> {
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
        let p = snapped.apply_entity(&e).ok_or("a rotation")?;
        assert_eq!(p.weights, [e.weights[1], e.weights[0], e.weights[2]]);
        assert_eq!(p.center, Point3::new(-2.0, 1.0, 3.0));
        assert!(p.rotation.is_identity());
        // 0.4 rad about x: the entity's surface points move with the map.
        let t = RigidTransform::rotation_about(0, 0.4);
        let r = t.apply_entity(&e).ok_or("a rotation")?;
        assert_eq!(r.weights, e.weights);
        for local in [[0.5, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -0.25]] {
            let before = e.to_world(local);
            let after = t.apply_point(before);
            let d = crate::closest_point::surface_distance(&r, after);
            assert!(d < 1e-6, "{local:?}: {d}");
        }
        Ok(())
    }
}
