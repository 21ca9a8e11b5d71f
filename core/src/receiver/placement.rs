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
    /// `t` as the wire sent it, in units of `10^exponent` m: a placement adds it to points in
    /// integers when their units allow ([`Placement`]).
    pub wire_translation: [i32; 3],
    pub exponent: i8,
}

impl Pose {
    /// The identity: where a session starts, and what a version 1 frame's points are at.
    pub const START: Self = Self {
        number: 0,
        rotation: None,
        translation: [0.0; 3],
        wire_translation: [0; 3],
        exponent: 0,
    };

    /// A pose frame's pose: number `number`, translation in units of `10^exponent` m.
    pub fn of_wire(number: u32, wire: &WirePose, exponent: i8) -> Self {
        let scale = crate::wire::unit_scale(exponent).unwrap_or(f64::NAN);
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
            wire_translation: wire.translation,
            exponent,
        }
    }
}

/// `10^n` for `n` in `0..=9`: as f32 each is exact (`5^9 < 2^24`).
const POWERS: [i32; 10] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
    1_000_000_000,
];

/// Points are placed in f32 on the FPU while their units stay below this: `n` units are then
/// exact in f32, and so is `10^|e|`, so one multiplication or division rounds `n 10^e` once.
const EXACT32: u64 = 1 << 24;

/// Where a frame's points go, worked out once per frame: the pose, the map's origin and the
/// frame's unit.
///
/// A device has no f64 unit, so a point is placed in f32 (a few FPU instructions where soft
/// f64 took about 800 a point), with the bits the f64 computation gives:
/// - No rotation, and an offset (pose translation minus origin) of whole units, which is what
///   senders give (poses in the points' unit or a coarser one, the origin whole metres): the
///   point plus the offset is an integer `n`, placed at `n 10^e` rounded once to f32. Below 2^24
///   units that is one f32 operation and the same bits as `(n as f64 * 10^e) as f32` (tested for
///   every such `n` and `e`); beyond, f64.
/// - Otherwise the point in metres is rounded to f32 (as the rotation always took it), turned
///   in f32, and the offset added as two f32 with the sum's exact error (TwoSum) before the
///   last rounding: `(r as f64 + offset) as f32` unless that sum lies within about 2^-24 of an
///   f32 ulp from a rounding boundary.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    origin: [f64; 3],
    /// Metres per unit of the frame.
    scale: f64,
    /// `10^|e|` in f32, exact; points are divided by it when `e < 0`.
    power: f32,
    divide: bool,
    rotation: Option<[[f32; 3]; 3]>,
    /// Added to a (rotated) point in metres: the pose's translation minus the origin.
    offset: [f64; 3],
    /// `offset` in whole units of the frame, when it is whole and the pose does not turn.
    shift: Option<[i32; 3]>,
    /// `offset` as f32 high and low parts.
    offset32: [[f32; 2]; 3],
}

/// The pose's translation minus the origin in whole units of `10^exponent` m, if it is whole
/// and an i32: the pose in the points' unit or a coarser one, the origin whole metres (a
/// multiple of ORIGIN_CELL) within 2,147 km, metres no finer than the unit.
fn whole_offset(origin: [f64; 3], exponent: i8, pose: &Pose) -> Option<[i32; 3]> {
    let power = |k: i16| usize::try_from(k).ok().and_then(|k| POWERS.get(k).copied());
    let coarser = power(i16::from(pose.exponent) - i16::from(exponent))?;
    let per_metre = power(-i16::from(exponent))?;
    let mut out = [0i32; 3];
    for ((slot, &t), &o) in out.iter_mut().zip(&pose.wire_translation).zip(&origin) {
        // `as` saturates and takes NaN to 0: the comparison refuses both.
        let metres = o as i32;
        if f64::from(metres) != o {
            return None;
        }
        let units = i64::from(t) * i64::from(coarser) - i64::from(metres) * i64::from(per_metre);
        *slot = i32::try_from(units).ok()?;
    }
    Some(out)
}

/// `r + hi + lo` rounded to f32 as nearly as once: TwoSum (Knuth) gives the exact error of
/// `r + hi`, which joins the low part before the last rounding.
#[inline]
fn add_offset(r: f32, [hi, lo]: [f32; 2]) -> f32 {
    let s = r + hi;
    let b = s - r;
    let error = (r - (s - b)) + (hi - b);
    s + (error + lo)
}

impl Placement {
    /// Where nothing has arrived: the identity at origin 0, in metres.
    pub(super) const NONE: Self = Self {
        origin: [0.0; 3],
        scale: 1.0,
        power: 1.0,
        divide: false,
        rotation: None,
        offset: [0.0; 3],
        shift: Some([0; 3]),
        offset32: [[0.0; 2]; 3],
    };

    pub(super) fn new(origin: [f64; 3], exponent: i8, pose: &Pose) -> Self {
        let [tx, ty, tz] = pose.translation;
        let [ox, oy, oz] = origin;
        let offset = [tx - ox, ty - oy, tz - oz];
        let split = |v: f64| {
            let hi = v as f32;
            [hi, (v - hi as f64) as f32]
        };
        let power = POWERS.get(usize::from(exponent.unsigned_abs()));
        Self {
            origin,
            scale: crate::wire::unit_scale(exponent).unwrap_or(f64::NAN),
            power: power.map_or(f32::NAN, |&p| p as f32),
            divide: exponent < 0,
            rotation: pose.rotation,
            offset,
            shift: pose
                .rotation
                .is_none()
                .then(|| whole_offset(origin, exponent, pose))
                .flatten(),
            offset32: offset.map(split),
        }
    }

    /// The map's origin, in the world frame (metres).
    pub const fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// `v + shift` units in metres, rounded once to f32 below [`EXACT32`] units.
    #[inline]
    fn metres(&self, v: i32, shift: i32) -> f32 {
        let n = i64::from(v) + i64::from(shift);
        if n.unsigned_abs() < EXACT32 {
            let v = n as i32 as f32;
            if self.divide {
                v / self.power
            } else {
                v * self.power
            }
        } else {
            ((f64::from(v) + f64::from(shift)) * self.scale) as f32
        }
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
    #[inline]
    pub fn point<T: AsRef<[u8]>>(&self, frame: &Frame<T>, i: usize) -> Option<Point3> {
        frame.point(i).map(|raw| self.place(raw))
    }

    /// Raw point `[x, y, z]` of the frame this placement was made for, in the map's frame.
    #[inline]
    pub fn place(&self, [x, y, z]: [i32; 3]) -> Point3 {
        if let Some([sx, sy, sz]) = self.shift {
            return Point3::new(self.metres(x, sx), self.metres(y, sy), self.metres(z, sz));
        }
        let p = [x, y, z].map(|v| self.metres(v, 0));
        let [px, py, pz] = p;
        let r = match self.rotation {
            Some(rows) => rows.map(|[a, b, c]| a * px + b * py + c * pz),
            None => p,
        };
        let [ox, oy, oz] = self.offset32;
        let [rx, ry, rz] = r;
        Point3::new(add_offset(rx, ox), add_offset(ry, oy), add_offset(rz, oz))
    }

    /// Every point of `frame`, as [`Placement::point`] gives them.
    pub fn points<'a, T: AsRef<[u8]>>(
        &'a self,
        frame: &'a Frame<T>,
    ) -> impl Iterator<Item = Point3> + 'a {
        frame.points_from(0).map(|raw| self.place(raw))
    }

    /// Raw point `raw` in the world frame (metres, f64): where the map's origin comes from.
    pub(super) fn world(&self, raw: [i32; 3]) -> [f64; 3] {
        let [x, y, z] = self.turned(raw);
        let [ox, oy, oz] = self.offset;
        let [gx, gy, gz] = self.origin;
        [x + ox + gx, y + oy + gy, z + oz + gz]
    }
}

#[cfg(test)]
mod tests;
