//! An entity's orientation: a unit quaternion, scalar last, `x_world = c + R(q) x_local`.
//!
//! The paper's entities are axis-aligned, and a tilted surface then needs many of them or one
//! too large. An oriented entity keeps the G(6,3) product of the paper in its own frame,
//! `psi1(R^T (x - c)) . psi2(E)`, so every formula of the axis-aligned entity holds after one
//! change of frame. The identity takes no arithmetic at all ([`Rotation::is_identity`]), so an
//! axis-aligned map gives the same bits as before orientations existed.

/// A unit quaternion `(x, y, z, w)`, `w` the scalar, stored with `w >= 0` (q and -q are the
/// same rotation; one sign makes equal rotations equal bits).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Rotation {
    pub x: f32,
    pub y: f32,
    pub z: f32,
    pub w: f32,
}

impl Default for Rotation {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Rotation {
    pub const IDENTITY: Self = Self {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 1.0,
    };

    /// The rotation of quaternion `[x, y, z, w]`, normalised; `None` for a zero or non-finite one.
    /// One already unit to f32 precision is kept as it is: a stored rotation read back from a
    /// CSV or JSON map is then the same bits (renormalising moves an f32 by an ulp), and
    /// [`Rotation::matrix`] renormalises in f64 anyway.
    pub fn from_quaternion(q: [f64; 4]) -> Option<Self> {
        let n = libm::sqrt(q.iter().map(|v| v * v).sum::<f64>());
        if !(n > 0.0) || !n.is_finite() {
            return None;
        }
        let n = if libm::fabs(n - 1.0) <= 4.0 * f32::EPSILON as f64 {
            1.0
        } else {
            n
        };
        let sign = if q[3] < 0.0 { -1.0 } else { 1.0 };
        let [x, y, z, w] = q.map(|v| (sign * v / n) as f32);
        let r = Self { x, y, z, w };
        Some(if r.is_identity_rotation() {
            Self::IDENTITY
        } else {
            r
        })
    }

    /// `[x, y, z, w]`.
    pub const fn to_array(self) -> [f32; 4] {
        [self.x, self.y, self.z, self.w]
    }

    /// True for the stored identity: the fast, exact path of every frame change.
    pub fn is_identity(&self) -> bool {
        *self == Self::IDENTITY
    }

    /// After rounding to f32, a quaternion whose vector part is zero is the identity.
    fn is_identity_rotation(&self) -> bool {
        self.x == 0.0 && self.y == 0.0 && self.z == 0.0
    }

    /// The rotation matrix, from the quaternion renormalised in f64 so that f32 storage does not
    /// scale lengths.
    pub fn matrix(&self) -> [[f64; 3]; 3] {
        quaternion_matrix(self.to_array().map(|v| v as f64))
    }

    /// `R v`.
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        if self.is_identity() {
            return v;
        }
        let [r0, r1, r2] = self.matrix();
        // Written out, not `[0, 1, 2].map(|i| ...)`: built for size, that leaves a bounds
        // check (a panicking branch) in the firmware.
        [r0, r1, r2].map(|r| r[0] * v[0] + r[1] * v[1] + r[2] * v[2])
    }

    /// `R^T v`: a world direction in the entity's frame.
    pub fn inverse_rotate(&self, v: [f64; 3]) -> [f64; 3] {
        if self.is_identity() {
            return v;
        }
        let [a, b, c] = self.matrix();
        [
            a[0] * v[0] + b[0] * v[1] + c[0] * v[2],
            a[1] * v[0] + b[1] * v[1] + c[1] * v[2],
            a[2] * v[0] + b[2] * v[1] + c[2] * v[2],
        ]
    }

    /// The quaternion of a rotation matrix (Shepperd's method: the largest of the four
    /// candidate pivots, so no division by a small number). `None` unless `m` is a rotation
    /// within 1e-6.
    pub fn from_matrix(m: [[f64; 3]; 3]) -> Option<Self> {
        if !is_rotation(&m) {
            return None;
        }
        let trace = m[0][0] + m[1][1] + m[2][2];
        let q = if trace > 0.0 {
            let s = 2.0 * libm::sqrt(1.0 + trace);
            [
                (m[2][1] - m[1][2]) / s,
                (m[0][2] - m[2][0]) / s,
                (m[1][0] - m[0][1]) / s,
                0.25 * s,
            ]
        } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
            let s = 2.0 * libm::sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]);
            [
                0.25 * s,
                (m[0][1] + m[1][0]) / s,
                (m[0][2] + m[2][0]) / s,
                (m[2][1] - m[1][2]) / s,
            ]
        } else if m[1][1] > m[2][2] {
            let s = 2.0 * libm::sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]);
            [
                (m[0][1] + m[1][0]) / s,
                0.25 * s,
                (m[1][2] + m[2][1]) / s,
                (m[0][2] - m[2][0]) / s,
            ]
        } else {
            let s = 2.0 * libm::sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]);
            [
                (m[0][2] + m[2][0]) / s,
                (m[1][2] + m[2][1]) / s,
                0.25 * s,
                (m[1][0] - m[0][1]) / s,
            ]
        };
        Self::from_quaternion(q)
    }

    /// `self` after `first`: the Hamilton product `self * first`, in f64 then stored.
    pub fn after(&self, first: &Rotation) -> Rotation {
        let [ax, ay, az, aw] = self.to_array().map(|v| v as f64);
        let [bx, by, bz, bw] = first.to_array().map(|v| v as f64);
        let q = [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ];
        Self::from_quaternion(q).unwrap_or(Self::IDENTITY)
    }
}

/// The rotation matrix of quaternion `q = [x, y, z, w]` of any non-zero length: the scale
/// `2 / |q|^2` normalises it, so no square root is needed (the identity for a zero or
/// non-finite `q`).
pub fn quaternion_matrix(q: [f64; 4]) -> [[f64; 3]; 3] {
    let n2: f64 = q.iter().map(|v| v * v).sum();
    if !(n2 > 0.0) || !n2.is_finite() {
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    }
    let s = 2.0 / n2;
    let [x, y, z, w] = q;
    [
        [
            1.0 - s * (y * y + z * z),
            s * (x * y - z * w),
            s * (x * z + y * w),
        ],
        [
            s * (x * y + z * w),
            1.0 - s * (x * x + z * z),
            s * (y * z - x * w),
        ],
        [
            s * (x * z - y * w),
            s * (y * z + x * w),
            1.0 - s * (x * x + y * y),
        ],
    ]
}

/// Orthonormal with determinant +1, within 1e-6 per entry.
pub fn is_rotation(m: &[[f64; 3]; 3]) -> bool {
    if !m.iter().flatten().all(|v| v.is_finite()) {
        return false;
    }
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| m[i][k] * m[j][k]).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            if (dot - want).abs() > 1e-6 {
                return false;
            }
        }
    }
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    det > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{OrFail, TestResult};

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
    }

    #[test]
    fn matrix_and_quaternion_round_trip() -> TestResult {
        // 90 degrees about z takes x to y.
        let h = core::f64::consts::FRAC_1_SQRT_2;
        let q = Rotation::from_quaternion([0.0, 0.0, h, h]).or_fail("unit")?;
        assert!(close(q.rotate([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], 1e-7));
        assert!(close(
            q.inverse_rotate([0.0, 1.0, 0.0]),
            [1.0, 0.0, 0.0],
            1e-7
        ));
        let back = Rotation::from_matrix(q.matrix()).or_fail("rotation")?;
        for (a, b) in back.to_array().iter().zip(q.to_array().iter()) {
            assert!((a - b).abs() < 1e-7);
        }
        // Every branch of Shepperd's method: rotations by near-pi about each axis.
        for axis in [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.6, 0.0, 0.8],
        ] {
            let q = Rotation::from_quaternion([axis[0], axis[1], axis[2], 0.01]).or_fail("q")?;
            let back = Rotation::from_matrix(q.matrix()).or_fail("rotation")?;
            let v = [0.3, -1.2, 2.5];
            assert!(close(back.rotate(v), q.rotate(v), 1e-6));
        }
        Ok(())
    }

    #[test]
    fn composition_and_identity() -> TestResult {
        let a = Rotation::from_quaternion([0.1, 0.2, 0.3, 0.9]).or_fail("a")?;
        let b = Rotation::from_quaternion([-0.4, 0.1, 0.0, 0.5]).or_fail("b")?;
        let v = [1.0, 2.0, 3.0];
        assert!(close(a.after(&b).rotate(v), a.rotate(b.rotate(v)), 1e-6));
        assert!(Rotation::IDENTITY.is_identity());
        assert_eq!(Rotation::IDENTITY.rotate(v), v);
        assert_eq!(
            Rotation::from_quaternion([0.0, 0.0, 0.0, -2.0]),
            Some(Rotation::IDENTITY)
        );
        assert_eq!(Rotation::from_quaternion([0.0; 4]), None);
        assert_eq!(
            Rotation::from_matrix([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]),
            None
        );
        Ok(())
    }
}
