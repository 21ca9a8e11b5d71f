//! Where a frame's points go: sensor frame to world (the pose), world to the map's frame (the
//! origin), in the frame's unit.

use crate::geometry::Point3;
use crate::rotation::quaternion_matrix;
use crate::wire::{Frame, WirePose};

/// A sensor pose the receiver holds, sensor to world: `x_world = R x_sensor + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// The number the points frames name it by; 0 is the identity a session starts at.
    pub number: u32,
    /// `R` in f32 (`None`: the identity, which takes no arithmetic). A sensor-frame point is
    /// within the sensor's range, so f32 rotates it to a few micrometres at 100 m, and f32 on a
    /// Cortex-M4F is the FPU's, not soft float.
    pub rotation: Option<[[f32; 3]; 3]>,
    /// `t`, metres.
    pub translation: [f64; 3],
}

impl Pose {
    /// The identity: where a session starts, and what a version 1 frame's points are at.
    pub const START: Self = Self {
        number: 0,
        rotation: None,
        translation: [0.0; 3],
    };

    /// A pose frame's pose: number `number`, translation in units of `scale` metres.
    pub fn of_wire(number: u32, wire: &WirePose, scale: f64) -> Self {
        let [x, y, z, w] = wire.rotation;
        // q and -q are the same rotation: a zero vector part is the identity whatever w's sign.
        let rotation = (x != 0 || y != 0 || z != 0).then(|| {
            let m = quaternion_matrix([x as f64, y as f64, z as f64, w as f64]);
            m.map(|row| row.map(|v| v as f32))
        });
        Self {
            number,
            rotation,
            translation: wire.translation.map(|v| v as f64 * scale),
        }
    }
}

/// Where a frame's points go, worked out once per frame: the pose, the map's origin and the
/// frame's unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    origin: [f64; 3],
    /// Metres per unit of the frame.
    scale: f64,
    rotation: Option<[[f32; 3]; 3]>,
    /// Added to a (rotated) point in metres: the pose's translation minus the origin.
    offset: [f64; 3],
    /// No rotation and nothing to add: a point reaches the mapper as `(v * 10^e) as f32`, the
    /// bits it had before there were an origin and poses, without three soft-float additions
    /// on a device.
    plain: bool,
}

impl Placement {
    pub(super) fn new(origin: [f64; 3], exponent: i8, pose: &Pose) -> Self {
        let [tx, ty, tz] = pose.translation;
        let [ox, oy, oz] = origin;
        let offset = [tx - ox, ty - oy, tz - oz];
        Self {
            origin,
            scale: crate::wire::unit_scale(exponent).unwrap_or(f64::NAN),
            rotation: pose.rotation,
            offset,
            plain: pose.rotation.is_none() && offset == [0.0; 3],
        }
    }

    /// The map's origin, in the world frame (metres).
    pub const fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// Raw point `[x, y, z]` in metres, rotated into the world's axes, in f64.
    fn turned(&self, [x, y, z]: [i32; 3]) -> [f64; 3] {
        let s = self.scale;
        let p = [x as f64 * s, y as f64 * s, z as f64 * s];
        let Some(r) = self.rotation else {
            return p;
        };
        let [px, py, pz] = p.map(|v| v as f32);
        let row = |[a, b, c]: [f32; 3]| (a * px + b * py + c * pz) as f64;
        let [r0, r1, r2] = r;
        [row(r0), row(r1), row(r2)]
    }

    /// Point `i` of `frame` in the map's frame (metres from the origin), or `None` past its
    /// points. `frame` is the frame this placement was made for.
    pub fn point<T: AsRef<[u8]>>(&self, frame: &Frame<T>, i: usize) -> Option<Point3> {
        let raw = frame.point(i)?;
        if self.plain {
            let [x, y, z] = raw;
            let s = self.scale;
            return Some(Point3::new(
                (x as f64 * s) as f32,
                (y as f64 * s) as f32,
                (z as f64 * s) as f32,
            ));
        }
        let [x, y, z] = self.turned(raw);
        let [ox, oy, oz] = self.offset;
        Some(Point3::new(
            (x + ox) as f32,
            (y + oy) as f32,
            (z + oz) as f32,
        ))
    }

    /// Every point of `frame`, as [`Placement::point`] gives them.
    pub fn points<'a, T: AsRef<[u8]>>(
        &'a self,
        frame: &'a Frame<T>,
    ) -> impl Iterator<Item = Point3> + 'a {
        (0..usize::from(frame.point_count())).filter_map(move |i| self.point(frame, i))
    }

    /// Raw point `raw` in the world frame (metres, f64): where the map's origin comes from.
    pub(super) fn world(&self, raw: [i32; 3]) -> [f64; 3] {
        let [x, y, z] = self.turned(raw);
        let [ox, oy, oz] = self.offset;
        let [gx, gy, gz] = self.origin;
        [x + ox + gx, y + oy + gy, z + oz + gz]
    }
}
