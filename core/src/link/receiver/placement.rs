//! Where a frame's points go: sensor frame to world (the pose), world to the map's frame (the
//! origin), in the frame's unit.

use crate::geometry::Point3;
use crate::link::wire::{Frame, WirePose};
use crate::rotation::quaternion_matrix;

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
    /// `t` as the wire sent it, in units of `10^exponent` m.
    pub wire_translation: [i64; 3],
    pub exponent: i8,
    /// `t` in whole nanometres, the unit every wire unit is a whole number of: a placement
    /// subtracts the map's origin from it exactly ([`Placement`]). `None` past the i64 range
    /// (9.2 million km), far beyond any world frame's.
    pub translation_nm: Option<[i64; 3]>,
}

impl Pose {
    /// The identity: where a session starts, and what a version 1 frame's points are at.
    pub const START: Self = Self {
        number: 0,
        rotation: None,
        translation: [0.0; 3],
        wire_translation: [0; 3],
        exponent: 0,
        translation_nm: Some([0; 3]),
    };

    /// A pose frame's pose: number `number`, translation in units of `10^exponent` m.
    pub fn of_wire(number: u32, wire: &WirePose, exponent: i8) -> Self {
        let scale = crate::link::wire::unit_scale(exponent).unwrap_or(f64::NAN);
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
            translation_nm: nanometres3(wire.translation, exponent),
        }
    }
}

/// Nanometres in one unit of `10^exponent` m, for the wire's exponents (-9..=3).
fn nanometres_per_unit(exponent: i8) -> Option<i64> {
    let k = usize::try_from(i16::from(exponent) + 9).ok()?;
    let mut per = 1i64;
    for _ in 0..k.min(13) {
        per = per.checked_mul(10)?;
    }
    (k <= 12).then_some(per)
}

/// `units` of `10^exponent` m in nanometres, exactly, if within i64.
pub(super) fn nanometres(units: i64, exponent: i8) -> Option<i64> {
    units.checked_mul(nanometres_per_unit(exponent)?)
}

fn nanometres3(units: [i64; 3], exponent: i8) -> Option<[i64; 3]> {
    let [x, y, z] = units;
    Some([
        nanometres(x, exponent)?,
        nanometres(y, exponent)?,
        nanometres(z, exponent)?,
    ])
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

/// Whether raw point `raw` is a no-return: at the sensor itself, where lidar drivers put a
/// beam that returned nothing. It is never surface (a map would put an obstacle inside the
/// robot).
#[inline]
pub const fn is_no_return(raw: [i32; 3]) -> bool {
    raw[0] == 0 && raw[1] == 0 && raw[2] == 0
}

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
    /// The map's origin in the world frame, whole nanometres.
    origin: [i64; 3],
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
    /// Points farther than this from the origin on any axis (metres) are out of reach.
    reach: f32,
}

/// The pose's translation minus the origin (nanometres) in whole units of `10^exponent` m, if
/// it is whole and an i32.
fn whole_offset(offset_nm: [i64; 3], exponent: i8) -> Option<[i32; 3]> {
    let per_unit = nanometres_per_unit(exponent)?;
    let mut out = [0i32; 3];
    for (slot, &o) in out.iter_mut().zip(&offset_nm) {
        // Checked: the divisor is never 0 or -1, but the image admits no panicking branch.
        if o.checked_rem(per_unit)? != 0 {
            return None;
        }
        *slot = i32::try_from(o.checked_div(per_unit)?).ok()?;
    }
    Some(out)
}

/// Raw point `[x, y, z]` in units of `scale` metres, rotated by `rotation` (f32 rows, on the
/// point rounded to f32 in metres), in f64.
fn turn([x, y, z]: [i32; 3], scale: f64, rotation: Option<[[f32; 3]; 3]>) -> [f64; 3] {
    let p = [x as f64 * scale, y as f64 * scale, z as f64 * scale];
    let Some(r) = rotation else {
        return p;
    };
    let [px, py, pz] = p.map(|v| v as f32);
    let row = |[a, b, c]: [f32; 3]| (a * px + b * py + c * pz) as f64;
    let [r0, r1, r2] = r;
    [row(r0), row(r1), row(r2)]
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
    /// Where nothing has arrived, or nothing can go: the identity at origin 0, in metres, with
    /// every point out of reach.
    pub(super) const NONE: Self = Self {
        origin: [0; 3],
        scale: 1.0,
        power: 1.0,
        divide: false,
        rotation: None,
        offset: [0.0; 3],
        shift: Some([0; 3]),
        offset32: [[0.0; 2]; 3],
        // Refuses every point: nothing has a place yet.
        reach: -1.0,
    };

    /// Where the points of a frame in units of `10^exponent` m, measured at `pose`, go in a map
    /// whose origin is `origin` (nanometres): `None` when the pose's offset from the origin is
    /// past i64 nanometres. The offset is worked out in integers, so it is the same wherever
    /// the world frame puts the map (the origin and the pose move together), and the points
    /// reach the mapper with the same bits.
    pub(super) fn new(origin: [i64; 3], exponent: i8, pose: &Pose, reach: f32) -> Option<Self> {
        let t = pose.translation_nm?;
        let offset_nm = [
            t[0].checked_sub(origin[0])?,
            t[1].checked_sub(origin[1])?,
            t[2].checked_sub(origin[2])?,
        ];
        let offset = offset_nm.map(|v| v as f64 / 1e9);
        let split = |v: f64| {
            let hi = v as f32;
            [hi, (v - hi as f64) as f32]
        };
        let power = POWERS.get(usize::from(exponent.unsigned_abs()));
        Some(Self {
            origin,
            scale: crate::link::wire::unit_scale(exponent).unwrap_or(f64::NAN),
            power: power.map_or(f32::NAN, |&p| p as f32),
            divide: exponent < 0,
            rotation: pose.rotation,
            offset,
            shift: pose
                .rotation
                .is_none()
                .then(|| whole_offset(offset_nm, exponent))
                .flatten(),
            offset32: offset.map(split),
            reach,
        })
    }

    /// The map's origin, in the world frame (metres).
    pub fn origin(&self) -> [f64; 3] {
        super::metres_of_nm(self.origin)
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

    /// Point `i` of `frame` in the map's frame (metres from the origin), or `None` past its
    /// points or out of reach. `frame` is the frame this placement was made for.
    #[inline]
    pub fn point<T: AsRef<[u8]>>(&self, frame: &Frame<T>, i: usize) -> Option<Point3> {
        frame.point(i).and_then(|raw| self.placed(raw))
    }

    /// Raw point `raw` in the map's frame, or `None` when it is a no-return ([`is_no_return`])
    /// or out of reach (farther from the origin than the receiver's reach on some axis, or not
    /// finite): the points a receiver maps.
    #[inline]
    pub fn placed(&self, raw: [i32; 3]) -> Option<Point3> {
        if is_no_return(raw) {
            return None;
        }
        let p = self.place(raw);
        let r = self.reach;
        // `!(a <= r)` refuses NaN as well.
        (p.x.abs() <= r && p.y.abs() <= r && p.z.abs() <= r).then_some(p)
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

    /// Every point of `frame` within reach, as [`Placement::point`] gives them.
    pub fn points<'a, T: AsRef<[u8]>>(
        &'a self,
        frame: &'a Frame<T>,
    ) -> impl Iterator<Item = Point3> + 'a {
        frame.points_from(0).filter_map(|raw| self.placed(raw))
    }

    /// Raw point `raw` of a frame at `pose` in the world frame, whole nanometres: where the
    /// map's origin comes from. The turned part is rounded on its own, before the pose's
    /// translation is added in integers, so the origin moves exactly with the world frame.
    pub(super) fn world_nm(raw: [i32; 3], exponent: i8, pose: &Pose) -> Option<[i64; 3]> {
        let t = pose.translation_nm?;
        let local = match pose.rotation {
            None => nanometres3(raw.map(i64::from), exponent)?,
            Some(rows) => {
                let scale = crate::link::wire::unit_scale(exponent)?;
                let turned = turn(raw, scale, Some(rows));
                let mut out = [0i64; 3];
                for (slot, v) in out.iter_mut().zip(turned) {
                    let nm = libm::round(v * 1e9);
                    // Within i64 (9.2 million km), or refused.
                    if !(nm.abs() < 9.0e18) {
                        return None;
                    }
                    *slot = nm as i64;
                }
                out
            }
        };
        Some([
            t[0].checked_add(local[0])?,
            t[1].checked_add(local[1])?,
            t[2].checked_add(local[2])?,
        ])
    }
}

#[cfg(test)]
mod tests;
