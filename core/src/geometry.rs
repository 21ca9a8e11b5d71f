//! Points and entities in the G(6,3) parametrisation of the paper (eqs. 4, 5, 10, 11).
//!
//! An entity is stored as its centre and its weights `w_j = 1 / r_j^2` rather than its semi-axes:
//! a semi-axis that passed the degeneration threshold is infinite, and `w_j = 0` carries that
//! limit (Table 1) as an ordinary finite number, so no inf or NaN is ever stored.

pub use crate::rotation::Rotation;

/// A point in R^3, in the map's local frame (metres or the cloud's own unit).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct Point3 {
    pub x: f32,
    pub y: f32,
    pub z: f32,
}

/// The box of `points`' finite coordinates, (lowest, highest) on each axis; an axis with none
/// has lowest > highest.
pub(crate) fn finite_box(points: impl IntoIterator<Item = Point3>) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in points {
        for ((l, h), v) in lo.iter_mut().zip(hi.iter_mut()).zip(p.to_array()) {
            if v.is_finite() {
                *l = l.min(v);
                *h = h.max(v);
            }
        }
    }
    (lo, hi)
}

/// The axis (0, 1, 2 for x, y, z) along which `points` spread widest: sorted along it, a sweep
/// for close pairs meets the fewest that are not.
pub(crate) fn longest_axis(points: impl IntoIterator<Item = Point3>) -> usize {
    let (lo, hi) = finite_box(points);
    let side = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    if side[0] >= side[1] && side[0] >= side[2] {
        0
    } else if side[1] >= side[2] {
        1
    } else {
        2
    }
}

impl Point3 {
    pub const fn new(x: f32, y: f32, z: f32) -> Self {
        Self { x, y, z }
    }

    pub const fn to_array(self) -> [f32; 3] {
        [self.x, self.y, self.z]
    }

    /// The coordinate on axis 0, 1 or 2 (x, y, z; z for any other).
    pub(crate) const fn coordinate(self, axis: usize) -> f32 {
        match axis {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }

    pub fn to_f64(self) -> [f64; 3] {
        [self.x as f64, self.y as f64, self.z as f64]
    }

    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }

    pub fn distance_squared(self, other: Point3) -> f32 {
        let dx = self.x - other.x;
        let dy = self.y - other.y;
        let dz = self.z - other.z;
        dx * dx + dy * dy + dz * dz
    }
}

impl From<[f32; 3]> for Point3 {
    fn from(p: [f32; 3]) -> Self {
        Self::new(p[0], p[1], p[2])
    }
}

/// The entities of Table 1. A degenerated axis is one whose fitted semi-axis reached the
/// degeneration threshold; its weight is stored as zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum EntityKind {
    Ellipsoid = 0,
    /// An ellipsoid whose three semi-axes agree within the sphere tolerance.
    Sphere = 1,
    /// One infinite semi-axis: an elliptic cylinder along that axis.
    Pseudocylinder = 2,
    /// Two infinite semi-axes: two parallel planes normal to the remaining axis.
    PlanePair = 3,
}

impl EntityKind {
    pub const ALL: [EntityKind; 4] = [
        EntityKind::Ellipsoid,
        EntityKind::Sphere,
        EntityKind::Pseudocylinder,
        EntityKind::PlanePair,
    ];

    pub const fn from_u8(code: u8) -> Option<Self> {
        match code {
            0 => Some(Self::Ellipsoid),
            1 => Some(Self::Sphere),
            2 => Some(Self::Pseudocylinder),
            3 => Some(Self::PlanePair),
            _ => None,
        }
    }

    pub const fn name(self) -> &'static str {
        match self {
            Self::Ellipsoid => "ellipsoid",
            Self::Sphere => "sphere",
            Self::Pseudocylinder => "pseudocylinder",
            Self::PlanePair => "plane_pair",
        }
    }

    /// Inverse of [`EntityKind::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|kind| kind.name() == name)
    }
}

/// Parameters that turn fitted semi-axes into a stored entity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Degeneration {
    /// A semi-axis at or above this length becomes infinite (`w_j = 0`); the paper uses 4 m.
    pub threshold: f64,
    /// Semi-axes whose largest/smallest ratio is within `1 + sphere_tolerance` form a sphere.
    pub sphere_tolerance: f64,
}

impl Default for Degeneration {
    fn default() -> Self {
        Self {
            threshold: 4.0,
            sphere_tolerance: 0.01,
        }
    }
}

/// The paper's 24-byte entity, axis-aligned: where entities are counted against a device's
/// memory (the streaming mapper's working fits and frozen entities), the 16 bytes of an identity
/// quaternion are not stored.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct AxisEntity {
    pub center: Point3,
    pub weights: [f32; 3],
}

impl AxisEntity {
    /// The centre and weights of an entity fitted axis-aligned (its rotation, the identity,
    /// is dropped).
    pub const fn of_axis_aligned(e: &Entity) -> Self {
        Self {
            center: e.center,
            weights: e.weights,
        }
    }
}

impl From<AxisEntity> for Entity {
    fn from(e: AxisEntity) -> Self {
        Entity::axis_aligned(e.center, e.weights)
    }
}

/// One map entity: the six floats of the paper's memory count (Table 2), and an orientation.
/// An axis-aligned entity (the paper's) has [`Rotation::IDENTITY`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Entity {
    pub center: Point3,
    /// `w_j = 1 / r_j^2`; zero for a degenerated (infinite) semi-axis, never negative, inf or NaN.
    pub weights: [f32; 3],
    /// Local axes to world: `x_world = center + R(rotation) x_local`.
    pub rotation: Rotation,
}

impl Entity {
    /// Builds an entity from fitted semi-axes. Axes at or over the threshold degenerate, except
    /// that at least one axis always stays finite: with all three infinite eq. 5 has no surface.
    pub fn from_semi_axes(
        center: Point3,
        semi_axes: [f64; 3],
        degeneration: &Degeneration,
    ) -> Self {
        let mut weights = [0.0f32; 3];
        let mut thinnest = 0;
        let mut smallest = semi_axes[0];
        for (j, &r) in semi_axes.iter().enumerate() {
            if r < smallest {
                thinnest = j;
                smallest = r;
            }
        }
        for (j, (w, &r)) in weights.iter_mut().zip(semi_axes.iter()).enumerate() {
            let degenerated = !(r < degeneration.threshold) && j != thinnest;
            *w = if degenerated || !(r > 0.0) {
                0.0
            } else {
                weight_of(r)
            };
        }
        if weights.iter().all(|&w| w == 0.0) {
            // Every axis was non-positive or the thinnest is itself over the threshold: keep
            // the thinnest one as a finite surface rather than store an entity with none.
            let r = smallest;
            let r = if r > 0.0 && r.is_finite() {
                r
            } else {
                degeneration.threshold
            };
            if let Some(w) = weights.get_mut(thinnest) {
                *w = weight_of(r);
            }
        }
        Self {
            center,
            weights,
            rotation: Rotation::IDENTITY,
        }
    }

    /// [`Entity::from_semi_axes`] from f32 semi-axes, by the same rules in f32 arithmetic: the f32
    /// search's fits (`fit`) end here, and on the Cortex-M4F the f64 form's divisions and
    /// comparisons are software routines, at every fit.
    pub fn from_semi_axes32(
        center: Point3,
        semi_axes: [f32; 3],
        degeneration: &Degeneration,
    ) -> Self {
        let threshold = degeneration.threshold as f32;
        let weight = |r: f32| {
            let w = 1.0 / (r * r);
            if w.is_finite() { w } else { f32::MAX }
        };
        let mut weights = [0.0f32; 3];
        let mut thinnest = 0;
        let mut smallest = semi_axes[0];
        for (j, &r) in semi_axes.iter().enumerate() {
            if r < smallest {
                thinnest = j;
                smallest = r;
            }
        }
        for (j, (w, &r)) in weights.iter_mut().zip(semi_axes.iter()).enumerate() {
            let degenerated = !(r < threshold) && j != thinnest;
            *w = if degenerated || !(r > 0.0) {
                0.0
            } else {
                weight(r)
            };
        }
        if weights.iter().all(|&w| w == 0.0) {
            let r = if smallest > 0.0 && smallest.is_finite() {
                smallest
            } else {
                threshold
            };
            if let Some(w) = weights.get_mut(thinnest) {
                *w = weight(r);
            }
        }
        Self::axis_aligned(center, weights)
    }

    /// An axis-aligned entity of these weights (the paper's, and the stored form of version 1).
    pub const fn axis_aligned(center: Point3, weights: [f32; 3]) -> Self {
        Self {
            center,
            weights,
            rotation: Rotation::IDENTITY,
        }
    }

    /// The same shape turned to `rotation`.
    pub const fn with_rotation(self, rotation: Rotation) -> Self {
        Self { rotation, ..self }
    }

    /// A world point in the entity's frame, `R^T (p - c)`; exactly `p - c` when axis-aligned.
    pub fn to_local(&self, p: [f64; 3]) -> [f64; 3] {
        let c = self.center.to_f64();
        self.rotation
            .inverse_rotate([p[0] - c[0], p[1] - c[1], p[2] - c[2]])
    }

    /// A point of the entity's frame in the world, `c + R local`.
    pub fn to_world(&self, local: [f64; 3]) -> [f64; 3] {
        let c = self.center.to_f64();
        let v = self.rotation.rotate(local);
        [c[0] + v[0], c[1] + v[1], c[2] + v[2]]
    }

    /// A sphere of radius `radius` (kept finite whatever the threshold).
    pub fn sphere(center: Point3, radius: f64) -> Self {
        let w = if radius > 0.0 && radius.is_finite() {
            weight_of(radius)
        } else {
            0.0
        };
        Self::axis_aligned(center, [w; 3])
    }

    /// Semi-axes `r_j = 1 / sqrt(w_j)`, with `f32::INFINITY` for a degenerated axis.
    /// Display only: the stored form is [`Entity::weights`].
    pub fn semi_axes(&self) -> [f32; 3] {
        self.weights.map(|w| {
            if w > 0.0 {
                1.0 / libm::sqrtf(w)
            } else {
                f32::INFINITY
            }
        })
    }

    /// Semi-axes in f64, `f64::INFINITY` for a degenerated axis: what eq. 13 and the queries use.
    pub fn semi_axes_f64(&self) -> [f64; 3] {
        self.weights.map(|w| {
            if w > 0.0 {
                1.0 / libm::sqrt(w as f64)
            } else {
                f64::INFINITY
            }
        })
    }

    /// Number of degenerated (infinite) semi-axes.
    pub fn degenerated_axes(&self) -> usize {
        self.weights.iter().filter(|&&w| w == 0.0).count()
    }

    pub fn kind(&self, sphere_tolerance: f64) -> EntityKind {
        match self.degenerated_axes() {
            0 => {
                let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
                for &w in &self.weights {
                    // Comparisons, not `min`/`max`: those are calls on a Cortex-M4F.
                    if w < lo {
                        lo = w;
                    }
                    if w > hi {
                        hi = w;
                    }
                }
                // Weights go as 1/r^2, so the axis ratio is sqrt(hi/lo), compared squared and
                // without the division, in f32: on a Cortex-M4F the square root and division
                // in soft f64 are software routines, for every entity a map encodes.
                let bound = 1.0 + sphere_tolerance as f32;
                if hi <= lo * (bound * bound) {
                    EntityKind::Sphere
                } else {
                    EntityKind::Ellipsoid
                }
            }
            1 => EntityKind::Pseudocylinder,
            _ => EntityKind::PlanePair,
        }
    }

    /// `psi2(E)` of eq. 11, of the entity's axis-aligned shape at its centre: for an oriented
    /// entity it pairs with `psi1` of the point's world position only when the rotation is the
    /// identity; [`Entity::inner_product`] holds for every entity.
    pub fn psi2(&self) -> [f64; 7] {
        let c = self.center.to_f64();
        let w = self.weights.map(|w| w as f64);
        let shift = c[0] * c[0] * w[0] + c[1] * c[1] * w[1] + c[2] * c[2] * w[2];
        [
            c[0] * w[0],
            c[1] * w[1],
            c[2] * w[2],
            -0.5 * (shift - 1.0),
            w[0],
            w[1],
            w[2],
        ]
    }

    /// `psi1(X)^T psi2(E)` in its closed form `(1 - sum_j w_j (x_j - c_j)^2) / 2`: zero on the
    /// surface, positive inside, negative outside.
    pub fn inner_product(&self, point: Point3) -> f64 {
        let d = self.to_local(point.to_f64());
        let mut sum = 0.0;
        for j in 0..3 {
            sum += self.weights[j] as f64 * d[j] * d[j];
        }
        0.5 * (1.0 - sum)
    }
}

fn weight_of(semi_axis: f64) -> f32 {
    let w = (1.0 / (semi_axis * semi_axis)) as f32;
    // A semi-axis so small that 1/r^2 overflows f32 is kept as the largest finite weight.
    if w.is_finite() { w } else { f32::MAX }
}

/// `psi1(X)` of eq. 10.
pub fn psi1(point: Point3) -> [f64; 7] {
    let p = point.to_f64();
    [
        p[0],
        p[1],
        p[2],
        1.0,
        -0.5 * p[0] * p[0],
        -0.5 * p[1] * p[1],
        -0.5 * p[2] * p[2],
    ]
}

/// `psi1(X)^T psi2(E)`, the G(6,3) inner product of a point and an entity, as the dot product
/// of eqs. 10 and 11. Prefer [`Entity::inner_product`] numerically; this is the paper's form.
pub fn psi_inner_product(psi1: &[f64; 7], psi2: &[f64; 7]) -> f64 {
    psi1.iter().zip(psi2.iter()).map(|(a, b)| a * b).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_f32_entity_follows_the_f64_rules() {
        let degeneration = Degeneration::default();
        let center = Point3::new(1.0, 2.0, 3.0);
        let mut state = 3u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            // Semi-axes from 1e-18 to 100, under and over the threshold. (Below, r^2 is
            // subnormal in f32 and the weight, near f32's largest, loses bits.)
            libm::powf(10.0, (state >> 8) as f32 / 16_777_216.0 * 20.0 - 18.0)
        };
        for i in 0..20_000 {
            let mut r = [next(), next(), next()];
            if i % 7 == 0 {
                r[i % 3] = 0.0;
            }
            let a = Entity::from_semi_axes32(center, r, &degeneration);
            let b = Entity::from_semi_axes(center, r.map(f64::from), &degeneration);
            for (x, y) in a.weights.iter().zip(b.weights.iter()) {
                // One rounding more in f32 (the square) than in f64: within two ulps.
                let ulps = (i64::from(x.to_bits()) - i64::from(y.to_bits())).abs();
                assert!(ulps <= 2, "{r:?}: {:?} vs {:?}", a.weights, b.weights);
            }
        }
    }

    #[test]
    fn psi_product_equals_closed_form() {
        let entity = Entity::from_semi_axes(
            Point3::new(0.3, -1.2, 2.0),
            [0.5, 1.5, 0.25],
            &Degeneration::default(),
        );
        for p in [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.8, -1.2, 2.0),
            Point3::new(-3.0, 4.0, 1.0),
        ] {
            let paper = psi_inner_product(&psi1(p), &entity.psi2());
            let closed = entity.inner_product(p);
            assert!(
                (paper - closed).abs() < 1e-9 * (1.0 + closed.abs()),
                "{paper} vs {closed}"
            );
        }
        // (0.8, -1.2, 2.0) is r_x away from the centre along x: on the surface.
        assert!(entity.inner_product(Point3::new(0.8, -1.2, 2.0)).abs() < 1e-6);
    }

    #[test]
    fn degeneration_stores_zero_weights_and_names_the_kind() {
        let d = Degeneration::default();
        let c = Point3::default();
        let cases = [
            ([0.5, 0.6, 0.7], EntityKind::Ellipsoid, 0),
            ([0.5, 0.502, 0.501], EntityKind::Sphere, 0),
            ([0.5, 9.0, 0.7], EntityKind::Pseudocylinder, 1),
            ([5.0, 9.0, 0.7], EntityKind::PlanePair, 2),
            ([5.0, 9.0, 7.0], EntityKind::PlanePair, 2),
        ];
        for (axes, kind, degenerated) in cases {
            let e = Entity::from_semi_axes(c, axes, &d);
            assert_eq!(e.kind(d.sphere_tolerance), kind, "{axes:?}");
            assert_eq!(e.degenerated_axes(), degenerated, "{axes:?}");
            assert!(e.weights.iter().all(|w| w.is_finite() && *w >= 0.0));
        }
    }

    #[test]
    fn hostile_semi_axes_never_store_inf_or_nan() {
        let d = Degeneration::default();
        for axes in [
            [f64::NAN, 1.0, 1.0],
            [0.0, 0.0, 0.0],
            [-1.0, f64::INFINITY, 1e-30],
            [f64::INFINITY; 3],
        ] {
            let e = Entity::from_semi_axes(Point3::default(), axes, &d);
            assert!(
                e.weights.iter().all(|w| w.is_finite() && *w >= 0.0),
                "{axes:?}"
            );
            assert!(e.degenerated_axes() < 3, "{axes:?}");
        }
    }

    #[test]
    fn kind_names_round_trip() {
        for kind in EntityKind::ALL {
            assert_eq!(EntityKind::from_name(kind.name()), Some(kind));
            assert_eq!(EntityKind::from_u8(kind as u8), Some(kind));
        }
    }
}
