//! One entity's record in each layout of the `.mema` file, and the quantization grid.
//!
//! Quantized records (14 bytes) exist because the map is judged per byte: at the same file size
//! they hold almost three times the entities of the full-precision oriented record (41 bytes),
//! and the grid's error (below a micrometre to a few millimetres, see [`Quantization`]) is far
//! under what the extra entities gain.

use crate::geometry::{Entity, EntityKind, Point3, Rotation};

/// Version 1: centre and weights (f32), kind; the paper's 24 bytes plus the kind.
pub const AXIS_ALIGNED_LEN: usize = 25;
/// Version 2, full precision: centre, weights, quaternion `(x, y, z, w)` (f32), kind.
pub const ORIENTED_LEN: usize = 41;
/// Version 2, quantized: centre (3 x i16), quaternion (u32), semi-axes and kind (u32).
pub const QUANTIZED_LEN: usize = 14;

/// The largest code of a finite semi-axis; one more marks a degenerated (infinite) one.
const AXIS_CODE_MAX: u32 = 1022;
const AXIS_CODE_INFINITE: u32 = 1023;
/// Bits per quaternion component in the smallest-three code.
const QUATERNION_BITS: u32 = 10;
const QUATERNION_MAX: f64 = ((1 << QUATERNION_BITS) - 1) as f64;

/// The shortest semi-axis a grid may hold: its weight, `1e38`, is finite in f32 (a shorter one's
/// overflowed, decoded as `f32::MAX`, and re-encoded one code off).
pub const AXIS_MIN_FLOOR: f32 = 1e-19;

/// The longest finite semi-axis a grid may hold: its weight, `1e-36`, is a normal f32 (a longer
/// one's lost its precision or became 0, which reads as an infinite semi-axis).
pub const AXIS_MAX_CEILING: f64 = 1e18;

/// The finest positive step of the semi-axes' logarithm a grid may have: at it, f32's rounding
/// of a decoded weight moves its re-encoded code by 3e-4 of a step, so every code is its own
/// again (at 1e-10 it moved hundreds of codes).
pub const AXIS_LOG_STEP_MIN: f32 = 1e-4;

/// The grid a quantized map lives on, stored in its header.
///
/// - Centres: `c = step * i` with `i` an i16 per axis, relative to the map's origin. With the
///   origin at the cloud's centre the step is the half extent over 32,767: 2.4 um on a bunny,
///   2.6 mm on an Ouster sweep 168 m across (docs/map-format.md).
/// - Semi-axes: `r = axis_min * exp(axis_log_step * code)`, code 0..=1022 (1023 = infinite), so
///   every semi-axis is within half a step (0.5% over a range of 10^4) of its fitted length.
/// - Rotations: the smallest-three code, three components of 10 bits in `[-1/sqrt 2, 1/sqrt 2]`
///   and the index of the largest: within a quarter of a degree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quantization {
    pub centre_step: f32,
    pub axis_min: f32,
    pub axis_log_step: f32,
}

impl Quantization {
    /// The finest grid that holds every entity: centres up to the farthest one, semi-axes from
    /// the shortest finite one (at least 10^-12 of the longest) to the longest.
    pub fn for_entities(entities: impl Iterator<Item = MapEntity>) -> Self {
        let mut far = 0.0f64;
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for e in entities {
            for v in e.entity.center.to_f64() {
                if v.is_finite() {
                    far = far.max(v.abs());
                }
            }
            for r in e.entity.semi_axes_f64() {
                if r.is_finite() && r > 0.0 {
                    lo = lo.min(r);
                    hi = hi.max(r);
                }
            }
        }
        Self::for_extent(far, lo, hi)
    }

    /// The finest grid for centres within `far` of the origin on every axis and finite
    /// semi-axes from `shortest` (at least 10^-12 of `longest`) to `longest`: a grid fixed before
    /// the entities are known, so that each can be judged as it will be stored.
    pub fn for_extent(far: f64, shortest: f64, longest: f64) -> Self {
        let (lo, hi) = (shortest, longest);
        let centre_step = if far > 0.0 {
            // A hair over far / 32767 so the farthest centre rounds inside the i16 range.
            ((far * (1.0 + 1e-6) / 32767.0) as f32).max(f32::MIN_POSITIVE)
        } else {
            1.0
        };
        if !(hi > 0.0) || !hi.is_finite() {
            return Self {
                centre_step,
                axis_min: 1.0,
                axis_log_step: 0.0,
            };
        }
        let hi = hi.clamp(AXIS_MIN_FLOOR as f64, AXIS_MAX_CEILING);
        // 10^-12, not the 10^-6 it was: one huge entity (a glitch's 3,712 km ellipsoid) then
        // started the grid at 3.7 m and every millimetre shell came back metres wide; over 12
        // decades each semi-axis is still within 1.4% of its length.
        let lo = lo.max(hi * 1e-12).max(AXIS_MIN_FLOOR as f64).min(hi);
        let mut axis_log_step = (libm::log(hi / lo) / AXIS_CODE_MAX as f64) as f32;
        if axis_log_step > 0.0 {
            axis_log_step = axis_log_step.max(AXIS_LOG_STEP_MIN);
        }
        Self {
            centre_step,
            axis_min: lo as f32,
            axis_log_step,
        }
    }

    /// A grid every code of which decodes to a finite entity that encodes to the same code
    /// again: a normal centre step whose farthest centre is finite, semi-axes from
    /// [`AXIS_MIN_FLOOR`] to about [`AXIS_MAX_CEILING`], and a log step of 0 (one length) or at least
    /// [`AXIS_LOG_STEP_MIN`].
    pub fn is_valid(&self) -> bool {
        let longest =
            self.axis_min as f64 * libm::exp(self.axis_log_step as f64 * AXIS_CODE_MAX as f64);
        let farthest = self.centre_step as f64 * -(i16::MIN as f64);
        self.centre_step.is_normal()
            && self.centre_step > 0.0
            && farthest < f32::MAX as f64
            && self.axis_min.is_finite()
            && self.axis_min >= AXIS_MIN_FLOOR
            && (self.axis_log_step == 0.0 || self.axis_log_step >= AXIS_LOG_STEP_MIN)
            && self.axis_log_step.is_finite()
            // Room for the log step raised to its least over a range near the ceiling.
            && longest <= AXIS_MAX_CEILING * 1.2
    }

    /// The entity as its record stores it: what the file will read back.
    pub fn quantize(&self, e: MapEntity) -> MapEntity {
        let mut record = [0u8; QUANTIZED_LEN];
        write_quantized(self, &e, &mut record);
        read_quantized(self, &record)
    }

    fn axis_code(&self, weight: f32) -> u32 {
        if !(weight > 0.0) {
            return AXIS_CODE_INFINITE;
        }
        let r = 1.0 / libm::sqrt(weight as f64);
        if !(self.axis_log_step > 0.0) {
            return 0;
        }
        let code = libm::round(libm::log(r / self.axis_min as f64) / self.axis_log_step as f64);
        crate::num::clamp(code, 0.0, AXIS_CODE_MAX as f64) as u32
    }

    fn axis_weight(&self, code: u32) -> f32 {
        if code >= AXIS_CODE_INFINITE {
            return 0.0;
        }
        let r = self.axis_min as f64 * libm::exp(self.axis_log_step as f64 * code as f64);
        let w = (1.0 / (r * r)) as f32;
        if w.is_finite() { w } else { f32::MAX }
    }
}

use super::MapEntity;

fn put_f32s(out: &mut [u8], values: &[f32]) {
    for (chunk, v) in out.chunks_exact_mut(4).zip(values.iter()) {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
}

fn f32s<const N: usize>(record: &[u8]) -> [f32; N] {
    let mut values = [0f32; N];
    for (v, chunk) in values.iter_mut().zip(record.chunks_exact(4)) {
        let mut b = [0u8; 4];
        b.copy_from_slice(chunk);
        *v = f32::from_le_bytes(b);
    }
    values
}

fn u32_at(record: &[u8], at: usize) -> u32 {
    let mut b = [0u8; 4];
    if let Some(src) = record.get(at..at + 4) {
        b.copy_from_slice(src);
    }
    u32::from_le_bytes(b)
}

/// Writes a version-1 record (`out` is [`AXIS_ALIGNED_LEN`] bytes).
pub fn write_axis_aligned(e: &MapEntity, out: &mut [u8]) {
    let c = e.entity.center.to_array();
    let w = e.entity.weights;
    put_f32s(out, &[c[0], c[1], c[2], w[0], w[1], w[2]]);
    if let Some(kind) = out.get_mut(AXIS_ALIGNED_LEN - 1) {
        *kind = e.kind as u8;
    }
}

/// The entity of a version-1 record and its raw kind code.
pub fn read_axis_aligned(record: &[u8]) -> (Entity, u8) {
    let v: [f32; 6] = f32s(record);
    let kind = record.get(AXIS_ALIGNED_LEN - 1).copied().unwrap_or(u8::MAX);
    (
        Entity::axis_aligned(Point3::new(v[0], v[1], v[2]), [v[3], v[4], v[5]]),
        kind,
    )
}

/// Writes a full-precision version-2 record (`out` is [`ORIENTED_LEN`] bytes).
pub fn write_oriented(e: &MapEntity, out: &mut [u8]) {
    let c = e.entity.center.to_array();
    let w = e.entity.weights;
    let q = e.entity.rotation.to_array();
    put_f32s(
        out,
        &[c[0], c[1], c[2], w[0], w[1], w[2], q[0], q[1], q[2], q[3]],
    );
    if let Some(kind) = out.get_mut(ORIENTED_LEN - 1) {
        *kind = e.kind as u8;
    }
}

/// The entity of a full-precision version-2 record, its raw kind code, and whether its
/// quaternion is a unit one (within 1e-5, checked by the file's validation).
pub fn read_oriented(record: &[u8]) -> (Entity, u8, bool) {
    let v: [f32; 10] = f32s(record);
    let kind = record.get(ORIENTED_LEN - 1).copied().unwrap_or(u8::MAX);
    let q = [v[6], v[7], v[8], v[9]];
    let norm2: f64 = q.iter().map(|&x| x as f64 * x as f64).sum();
    let unit = (norm2 - 1.0).abs() <= 1e-5;
    let rotation = Rotation {
        x: q[0],
        y: q[1],
        z: q[2],
        w: q[3],
    };
    let entity = Entity {
        center: Point3::new(v[0], v[1], v[2]),
        weights: [v[3], v[4], v[5]],
        rotation: if rotation.x == 0.0 && rotation.y == 0.0 && rotation.z == 0.0 {
            Rotation::IDENTITY
        } else {
            rotation
        },
    };
    (entity, kind, unit)
}

fn quantize_centre(step: f32, v: f32) -> i16 {
    let code = libm::round(v as f64 / step as f64);
    crate::num::clamp(code, i16::MIN as f64, i16::MAX as f64) as i16
}

/// Smallest three: the largest component is implied (made positive, as q and -q are one
/// rotation); the others lie in `[-1/sqrt 2, 1/sqrt 2]`.
/// The smallest-three code of `r`. It is a fixed point of decoding and encoding again, so a map
/// read back from its file re-encodes to the same bytes: where two components are within the
/// code's step of each other (a turn of about 90 degrees about one axis), a stored component
/// could round above the largest one as decoded, and encoding the decoded rotation would then
/// drop the other (a car6 shell map read back 0.03 degrees off the map in memory). So a stored
/// component that would come within 1e-6 of the decoded largest is moved a step toward zero.
fn encode_rotation(r: &Rotation) -> u32 {
    let q = r.to_array().map(|v| v as f64);
    let mut largest = 3;
    for i in 0..4 {
        if q[i].abs() > q[largest].abs() {
            largest = i;
        }
    }
    let sign = if q.get(largest).is_some_and(|&v| v < 0.0) {
        -1.0
    } else {
        1.0
    };
    let mut bits = [0u32; 3];
    let others = q.iter().enumerate().filter(|&(i, _)| i != largest);
    for (b, (_, &v)) in bits.iter_mut().zip(others) {
        let unit = (sign * v * core::f64::consts::SQRT_2 + 1.0) * 0.5;
        *b = libm::round(crate::num::clamp(unit, 0.0, 1.0) * QUATERNION_MAX) as u32;
    }
    let middle = QUATERNION_MAX as u32 / 2;
    for _ in 0..8 {
        let values = bits.map(stored_component);
        let decoded_largest =
            libm::sqrt((1.0 - values.iter().map(|v| v * v).sum::<f64>()).max(0.0));
        let Some(i) = (0..3).find(|&i| values[i].abs() >= decoded_largest - 1e-6) else {
            break;
        };
        bits[i] = if bits[i] > middle {
            bits[i] - 1
        } else {
            bits[i] + 1
        };
    }
    let mut code = largest as u32;
    for (j, b) in bits.iter().enumerate() {
        code |= b << (2 + QUATERNION_BITS * j as u32);
    }
    code
}

/// A stored component's value from its bits.
fn stored_component(bits: u32) -> f64 {
    (bits as f64 / QUATERNION_MAX * 2.0 - 1.0) * core::f64::consts::FRAC_1_SQRT_2
}

/// A smallest-three code's parts: the index of the largest component, and each other
/// component's stored bits, in order.
fn code_parts(code: u32) -> (usize, [u32; 3]) {
    let field = |j: u32| (code >> (2 + QUATERNION_BITS * j)) & ((1 << QUATERNION_BITS) - 1);
    ((code & 3) as usize, [field(0), field(1), field(2)])
}

fn decode_rotation(code: u32) -> Rotation {
    let (largest, bits) = code_parts(code);
    let mut q = [0.0f64; 4];
    let mut sum = 0.0;
    let others = q.iter_mut().enumerate().filter(|&(i, _)| i != largest);
    for ((_, v), &b) in others.zip(bits.iter()) {
        *v = stored_component(b);
        sum += *v * *v;
    }
    if let Some(v) = q.get_mut(largest) {
        *v = libm::sqrt((1.0 - sum).max(0.0));
    }
    Rotation::from_quaternion(q).unwrap_or(Rotation::IDENTITY)
}

/// The rotation's u32 code in a quantized record: 0 for the identity, else smallest three
/// (within a quarter of a degree). A streaming mapper keeps frozen entities' rotations in it.
pub fn rotation_code(r: &Rotation) -> u32 {
    if r.is_identity() {
        0
    } else {
        encode_rotation(r)
    }
}

/// The rotation of a [`rotation_code`]; every code is a valid rotation.
pub fn rotation_of_code(code: u32) -> Rotation {
    match code {
        0 => Rotation::IDENTITY,
        code => decode_rotation(code),
    }
}

/// Column `j` of the rotation matrix of a [`rotation_code`], in single precision: the world
/// direction of an entity's axis `j`, for a device ranking pairs of frozen shells by it
/// (`rotation_of_code` decodes in f64, a software routine on the M4F).
pub fn rotation_column32(code: u32, j: usize) -> [f32; 3] {
    let mut unit = [0.0f32; 3];
    if let Some(v) = unit.get_mut(j) {
        *v = 1.0;
    }
    if code == 0 {
        return unit;
    }
    let (largest, bits) = code_parts(code);
    let mut q = [0.0f32; 4];
    let mut sum = 0.0f32;
    let others = q.iter_mut().enumerate().filter(|&(i, _)| i != largest);
    for ((_, v), &b) in others.zip(bits.iter()) {
        *v = (b as f32 / QUATERNION_MAX as f32 * 2.0 - 1.0) * core::f32::consts::FRAC_1_SQRT_2;
        sum += *v * *v;
    }
    if let Some(v) = q.get_mut(largest) {
        *v = crate::num::square_root((1.0 - sum).max(0.0));
    }
    let n2: f32 = q.iter().map(|v| v * v).sum();
    if !(n2 > 0.0) {
        return unit;
    }
    let s = 2.0 / n2;
    let [x, y, z, w] = q;
    match j {
        0 => [
            1.0 - s * (y * y + z * z),
            s * (x * y + z * w),
            s * (x * z - y * w),
        ],
        1 => [
            s * (x * y - z * w),
            1.0 - s * (x * x + z * z),
            s * (y * z + x * w),
        ],
        _ => [
            s * (x * z + y * w),
            s * (y * z - x * w),
            1.0 - s * (x * x + y * y),
        ],
    }
}

/// Writes a quantized version-2 record (`out` is [`QUANTIZED_LEN`] bytes).
pub fn write_quantized(grid: &Quantization, e: &MapEntity, out: &mut [u8]) {
    let c = e.entity.center.to_array();
    for (chunk, v) in out.chunks_exact_mut(2).take(3).zip(c.iter()) {
        chunk.copy_from_slice(&quantize_centre(grid.centre_step, *v).to_le_bytes());
    }
    let rotation = rotation_code(&e.entity.rotation);
    let mut axes = e.kind as u32 & 3;
    for (j, w) in e.entity.weights.iter().enumerate() {
        axes |= grid.axis_code(*w) << (2 + 10 * j);
    }
    if let Some(dst) = out.get_mut(6..10) {
        dst.copy_from_slice(&rotation.to_le_bytes());
    }
    if let Some(dst) = out.get_mut(10..14) {
        dst.copy_from_slice(&axes.to_le_bytes());
    }
}

/// The entity of a quantized record. Every code decodes to a valid entity on a valid grid, so
/// the file's validation checks only the grid and that some axis is finite.
pub fn read_quantized(grid: &Quantization, record: &[u8]) -> MapEntity {
    let mut centre = [0f32; 3];
    for (v, chunk) in centre.iter_mut().zip(record.chunks_exact(2).take(3)) {
        *v = i16::from_le_bytes([chunk[0], chunk[1]]) as f32 * grid.centre_step;
    }
    let rotation = rotation_of_code(u32_at(record, 6));
    let axes = u32_at(record, 10);
    let weights = [0, 1, 2].map(|j| grid.axis_weight((axes >> (2 + 10 * j)) & 0x3ff));
    let kind = EntityKind::from_u8((axes & 3) as u8).unwrap_or(EntityKind::Ellipsoid);
    MapEntity {
        entity: Entity {
            center: Point3::new(centre[0], centre[1], centre[2]),
            weights,
            rotation,
        },
        kind,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_survive_the_smallest_three_code_within_a_quarter_degree() {
        let mut state = 12345u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f64 / u32::MAX as f64 * 2.0 - 1.0
        };
        for _ in 0..2000 {
            let q = [next(), next(), next(), next()];
            let Some(r) = Rotation::from_quaternion(q) else {
                continue;
            };
            let back = decode_rotation(encode_rotation(&r));
            let dot: f64 = r
                .to_array()
                .iter()
                .zip(back.to_array().iter())
                .map(|(a, b)| *a as f64 * *b as f64)
                .sum();
            // The angle between two rotations is 2 acos |q1 . q2|.
            let angle = 2.0 * libm::acos(dot.abs().min(1.0));
            assert!(angle.to_degrees() < 0.25, "{q:?}: {angle}");
        }
    }

    #[test]
    fn a_quantized_entity_is_a_fixed_point_of_quantization() {
        let entities = [
            MapEntity {
                entity: Entity::from_semi_axes(
                    Point3::new(0.5, -1.25, 3.0),
                    [0.01, 0.2, 0.004],
                    &crate::Degeneration::default(),
                )
                .with_rotation(
                    Rotation::from_quaternion([0.3, -0.2, 0.1, 0.9]).unwrap_or_default(),
                ),
                kind: EntityKind::Ellipsoid,
            },
            MapEntity {
                entity: Entity::axis_aligned(Point3::new(-2.0, 0.0, 0.1), [0.0, 25.0, 0.0]),
                kind: EntityKind::PlanePair,
            },
        ];
        let grid = Quantization::for_entities(entities.iter().copied());
        assert!(grid.is_valid());
        for e in entities {
            let once = grid.quantize(e);
            assert_eq!(grid.quantize(once), once);
            assert_eq!(once.kind, e.kind);
            for j in 0..3 {
                let (a, b) = (e.entity.semi_axes_f64()[j], once.entity.semi_axes_f64()[j]);
                assert!(a == b || ((a - b) / a).abs() < 0.01, "{a} vs {b}");
                let (a, b) = (e.entity.center.to_f64()[j], once.entity.center.to_f64()[j]);
                assert!((a - b).abs() <= grid.centre_step as f64, "{a} vs {b}");
            }
        }
    }

    /// Every axis code and the extreme centre codes of a valid grid decode to what encodes to
    /// them again, at the grid's limits too (a fuzz campaign's map had a 3.9e-20 shortest axis,
    /// whose weight overflowed); and the grids the encoder makes are valid at those limits.
    #[test]
    fn every_code_of_a_valid_grid_is_its_own_again() {
        let grids = [
            Quantization::for_extent(1.0, 1e-3, 1.0),
            Quantization::for_extent(1e-30, 1e-25, 1e-20),
            Quantization::for_extent(1e30, 1e17, 1e30),
            Quantization::for_extent(5.0, 0.5, 0.5 * (1.0 + 1e-7)),
            Quantization::for_extent(5.0, 2.0, 2.0),
            Quantization {
                centre_step: f32::MIN_POSITIVE,
                axis_min: AXIS_MIN_FLOOR,
                axis_log_step: AXIS_LOG_STEP_MIN,
            },
        ];
        for grid in grids {
            assert!(grid.is_valid(), "{grid:?}");
            for code in 0..=AXIS_CODE_INFINITE {
                let w = grid.axis_weight(code);
                assert!(w.is_finite() && (w > 0.0 || code == AXIS_CODE_INFINITE));
                let again = grid.axis_weight(grid.axis_code(w));
                assert_eq!(again.to_bits(), w.to_bits(), "{grid:?}, code {code}");
            }
            for i in [i16::MIN, -1, 0, 1, 12345, i16::MAX] {
                let c = i as f32 * grid.centre_step;
                assert!(c.is_finite());
                assert_eq!(quantize_centre(grid.centre_step, c), i, "{grid:?}");
            }
        }
        for (step, min, log_step) in [
            (1e-39f32, 1.0f32, 0.01f32),
            (1e35, 1.0, 0.01),
            (1.0, 3.9e-20, 0.01),
            (1.0, 1.0, 1e-7),
            (1.0, 1e17, 0.1),
        ] {
            let grid = Quantization {
                centre_step: step,
                axis_min: min,
                axis_log_step: log_step,
            };
            assert!(!grid.is_valid(), "{grid:?}");
        }
    }

    /// One entity a thousand kilometres across does not coarsen a millimetre shell beside it.
    #[test]
    fn a_huge_entity_leaves_the_small_ones_their_semi_axes() {
        let small = MapEntity {
            entity: Entity::axis_aligned(Point3::new(0.5, 0.0, 0.0), [1e6, 4e4, 1e2]),
            kind: EntityKind::Ellipsoid,
        };
        let huge = MapEntity {
            entity: Entity::axis_aligned(Point3::new(-0.5, 0.0, 0.0), [1e-12, 1e-12, 1e-12]),
            kind: EntityKind::Ellipsoid,
        };
        let grid = Quantization::for_entities([small, huge].into_iter());
        let back = grid.quantize(small);
        for j in 0..3 {
            let (a, b) = (
                small.entity.semi_axes_f64()[j],
                back.entity.semi_axes_f64()[j],
            );
            assert!(((a - b) / a).abs() < 0.014, "{a} vs {b}");
        }
    }
}
