//! The stream's power sums: integers, so a point costs a Cortex-M4F integer multiply-adds
//! instead of 45 soft-float operations, each a software routine.
//!
//! Scheme: each coordinate of a point's offset from the cluster's anchor (its first point) is
//! rounded to a grid of pitch `2^quantum[j]` per axis, chosen so every offset seen on that axis is
//! at most [`OFFSET_LIMIT`] = 2^24 steps, as fine as f32 holds the offset. The products of those
//! integers up to order 4 are exact (orders 3 and 4 in two words), and each of the 24 sums is an i64 mantissa under 2^62 with its own
//! binary exponent: an exact integer until it outgrows 62 bits, then rounded once per halving,
//! 9 bits finer than f64. A farther point coarsens its axis's grid, which for each sum is an
//! exponent change.
//!
//! Why rounding to a grid is harmless: the pitch is at most `2^-23` of the largest offset on its
//! axis, so it moves a point by at most 6e-8 of the cluster's extent on that axis (the f32
//! rounding of the offset itself), far below any scanner's noise; the comparison with the f64 reference on every shared cloud bounds its effect on the
//! fits (`mema-firmware-sim reference`).
//!
//! Central moments, covariance and the merge of sums with orders 3 and 4 go through the f64
//! [`Moments`] the sums convert to, once per fit or merge rather than once per point; two
//! shells' sums (orders 1 and 2) merge in integers (`merge.rs`).

use super::{CentralMoments, Moments};
use crate::geometry::Point3;

/// The largest offset, in grid steps, as fine as an f32 offset itself: squares fit 48 bits,
/// cubes 72 and fourth powers 96 (their products are formed in two words).
pub const OFFSET_LIMIT: i32 = 1 << 24;

/// Grid pitch below the largest offset: `2^-PITCH_BITS` of its binade.
const PITCH_BITS: i32 = 23;

/// Mantissas stay below this in magnitude, and a term is added only once it is below half of
/// it, so no addition can overflow.
pub const MANTISSA_LIMIT: i64 = 1 << 62;

/// The three axis pairs, in the order of the mixed sums.
const PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// An axis's pitch exponent before any non-zero offset on it has been seen.
const NO_PITCH: i8 = i8::MIN;
/// Pitches from 2^-110 (offsets below 1e-27 round to zero: no scanner resolves them) to 2^104
/// (the largest f32 offset, 2^128, in 2^24 steps): every unit f32 and f64 need stays normal.
const MIN_QUANTUM: i32 = -110;
const MAX_QUANTUM: i32 = 104;

/// The 24 sums: per axis j, `n_j^p` for p = 1..=4 (slots `4 j + p - 1`), then per pair (j, k)
/// `n_j n_k`, `n_j^2 n_k`, `n_j n_k^2`, `n_j^2 n_k^2` (slots `12 + 4 pair + i`).
pub const SLOTS: usize = 24;

/// The slots of orders 3 and 4 as products of two factors of `accumulate`'s bank (0-2:
/// `|n_j|`, 3-5: `n_j^2`, 6-8: `|n_j n_k|` of pairs xy, xz, yz), negative when axis `sign`'s
/// offset is (3: never).
const WIDE: [(u8, u8, u8, u8); 15] = [
    (2, 3, 0, 0),
    (3, 3, 3, 3),
    (6, 4, 1, 1),
    (7, 4, 4, 3),
    (10, 5, 2, 2),
    (11, 5, 5, 3),
    (13, 3, 1, 1),
    (14, 0, 4, 0),
    (15, 6, 6, 3),
    (17, 3, 2, 2),
    (18, 0, 5, 0),
    (19, 7, 7, 3),
    (21, 4, 2, 2),
    (22, 1, 5, 1),
    (23, 8, 8, 3),
];

/// The powers of each axis in each slot: what a change of that axis's pitch scales it by.
const POWERS: [[u8; 3]; SLOTS] = {
    let mut out = [[0u8; 3]; SLOTS];
    let mut j = 0;
    while j < 3 {
        let mut p = 0;
        while p < 4 {
            out[4 * j + p][j] = p as u8 + 1;
            p += 1;
        }
        j += 1;
    }
    let mixed = [(1u8, 1u8), (2, 1), (1, 2), (2, 2)];
    let mut pair = 0;
    while pair < 3 {
        let (j, k) = PAIRS[pair];
        let mut i = 0;
        while i < 4 {
            out[12 + 4 * pair + i][j] = mixed[i].0;
            out[12 + 4 * pair + i][k] = mixed[i].1;
            i += 1;
        }
        pair += 1;
    }
    out
};

/// Mergeable, incrementally updated power sums of a cluster in integer arithmetic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixedMoments {
    anchor: [f32; 3],
    count: u64,
    /// Slot `i` holds `sums[i] * 2^shift[i]` in units of its axes' pitches.
    sums: [i64; SLOTS],
    shift: [u8; SLOTS],
    /// Offsets on axis j are counted in steps of `2^quantum[j]`; [`NO_PITCH`] while all are 0.
    quantum: [i8; 3],
    /// Only the sums of orders 1 and 2 are kept ([`FixedMoments::second_order`]).
    second_order: bool,
}

/// `2^e` as an f32, for `e` within f32's normal exponents (clamped to them).
fn pow2_32(e: i32) -> f32 {
    f32::from_bits(((e.clamp(-126, 127) + 127) as u32) << 23)
}

/// `2^e` as an f64, for `e` within f64's normal exponents (clamped to them).
fn pow2_64(e: i32) -> f64 {
    f64::from_bits(((e.clamp(-1022, 1023) + 1023) as u64) << 52)
}

/// `x 2^e` for `e` within f64's normal exponents: the product `x * pow2_64(e)`, the same bits,
/// by moving the exponent when the result stays normal (a soft-f64 multiplication on the M4F
/// would be a software routine, once per sum at every fit).
fn scaled_by_pow2(x: f64, e: i32) -> f64 {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let moved = biased + e;
    if biased != 0 && biased != 0x7ff && (1..0x7ff).contains(&moved) {
        f64::from_bits((bits & !(0x7ff << 52)) | ((moved as u64) << 52))
    } else {
        x * pow2_64(e)
    }
}

/// The smallest shift `s <= 63` with `|x| < 2^(61 + s)` (63 for infinities, 0 for NaN), from
/// the exponent bits, where a loop of soft-f64 comparisons would call a routine at every step.
fn shift_below_2_61(x: f64) -> u8 {
    if x.is_nan() {
        return 0;
    }
    let exponent = ((x.to_bits() >> 52) & 0x7ff) as i32 - 1023;
    (exponent - 60).clamp(0, 63) as u8
}

/// The exponent `e` with `2^e <= x < 2^(e + 1)` of a positive normal f32 (bit pattern, exact).
fn exponent32(x: f32) -> i32 {
    ((x.to_bits() >> 23) & 0xff) as i32 - 127
}

/// `a - b` as an f32 and the error of that rounding, `(s, e)` with `s + e = a - b` exactly
/// (Knuth's TwoSum): a point and its cluster's anchor straddling a power of two or zero
/// differ by more bits than f32 holds, and the grid should see the offset, not its rounding.
#[inline]
fn exact_difference(a: f32, b: f32) -> (f32, f32) {
    let s = a - b;
    let b_virtual = s - a;
    let a_virtual = s - b_virtual;
    let e = (a - a_virtual) + (-b - b_virtual);
    (s, e)
}

/// Offset `d` (a pair summing to it exactly) in steps of `2^q`, rounded to the nearest and
/// within [`OFFSET_LIMIT`].
#[inline]
fn steps_of(q: i32, (d, error): (f32, f32)) -> i32 {
    // Both scalings by a power of two are exact.
    let scale = pow2_32(-q);
    let (x, below) = (d * scale, error * scale);
    // Round half away from zero; `as` saturates, so an offset near f32's range stays bounded.
    let n = (x + if x < 0.0 { -0.5 } else { 0.5 }) as i32;
    // What rounding `x` alone left out, plus the subtraction's error: exact but for the
    // last addition, which matters only at a tie.
    let rest = (x - n as f32) + below;
    let n = n + i32::from(rest > 0.5) - i32::from(rest < -0.5);
    n.clamp(-OFFSET_LIMIT, OFFSET_LIMIT)
}

/// `m / 2^s`, rounded half up.
#[inline]
fn shifted(m: i64, s: u32) -> i64 {
    match s {
        0 => m,
        1..=63 => (m >> s) + ((m >> (s - 1)) & 1),
        _ => 0,
    }
}

/// `a b` for `a, b < 2^48`, exactly, as two 64-bit words `(high, low)` formed from 32-bit
/// halves: on a 32-bit core four multiplies, where a u128 product calls a routine.
#[inline]
fn wide_product(a: u64, b: u64) -> (u64, u64) {
    let (ah, al) = (a >> 32, a & 0xffff_ffff);
    let (bh, bl) = (b >> 32, b & 0xffff_ffff);
    let low = al * bl;
    // Each cross product is below 2^48, their sum below 2^49.
    let cross = ah * bl + al * bh;
    let lo = low.wrapping_add(cross << 32);
    (ah * bh + (cross >> 32) + u64::from(lo < low), lo)
}

/// The shift that brings `(high, low)` under 2^60: its bit length minus 60, or 0.
#[inline]
fn shift_for(high: u64, low: u64) -> u32 {
    let bits = if high != 0 {
        128 - high.leading_zeros()
    } else {
        64 - low.leading_zeros()
    };
    bits.saturating_sub(60)
}

/// `(high, low) / 2^s` rounded half up, for `s` at least [`shift_for`] (so below 2^61) and
/// `high < 2^32` (a product below 2^96). In 32-bit words: a variable shift of a u64 is about
/// eight instructions on a 32-bit core, and this runs for 15 sums a point.
#[inline]
fn wide_shifted(high: u64, low: u64, s: u32) -> u64 {
    let (w0, w1, w2) = (low as u32, (low >> 32) as u32, high as u32);
    let join = |hi: u32, lo: u32| (u64::from(hi) << 32) | u64::from(lo);
    match s {
        0 => low,
        1..=31 => {
            let r0 = (w0 >> s) | (w1 << (32 - s));
            let r1 = (w1 >> s) | (w2 << (32 - s));
            join(r1, r0) + u64::from((w0 >> (s - 1)) & 1)
        }
        32 => join(w2, w1) + u64::from(w0 >> 31),
        33..=63 => {
            let r = s - 32;
            let r0 = (w1 >> r) | (w2 << (32 - r));
            join(w2 >> r, r0) + u64::from((w1 >> (r - 1)) & 1)
        }
        _ => 0,
    }
}

/// Halves a sum's mantissa and doubles its unit. Rare (once per doubling of a sum), so out of
/// line: flash, not time, is what the image runs short of.
#[cold]
#[inline(never)]
fn halve(sum: &mut i64, shift: &mut u8) {
    *sum = shifted(*sum, 1);
    *shift = shift.saturating_add(1);
}

/// Raises a sum's exponent to `to` (at most 63), rounding its mantissa once: what a large term
/// arriving at a small sum needs (typically the second point of a cluster), so out of line.
#[cold]
#[inline(never)]
fn raise(sum: &mut i64, shift: &mut u8, to: u32) {
    let to = to.min(63);
    *sum = shifted(*sum, to.saturating_sub(u32::from(*shift)));
    *shift = to as u8;
}

impl Default for FixedMoments {
    fn default() -> Self {
        Self::new()
    }
}

impl FixedMoments {
    pub const fn new() -> Self {
        Self {
            anchor: [0.0; 3],
            count: 0,
            sums: [0; SLOTS],
            shift: [0; SLOTS],
            quantum: [NO_PITCH; 3],
            second_order: false,
        }
    }

    /// Sums that keep the mean and covariance only, all a shell needs: the sums of orders 3
    /// and 4 (eq. 12's fitness) stay 0, and [`FixedMoments::central`] is `None`. Why: those 15
    /// sums are two-word products, most of what adding a point costs a Cortex-M4F (about 1,300
    /// of its 1,900 instructions on car6), and a stream of shells never reads them.
    pub const fn second_order() -> Self {
        Self {
            second_order: true,
            ..Self::new()
        }
    }

    pub const fn count(&self) -> u64 {
        self.count
    }

    pub const fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Adds one finite point (non-finite points are the caller's to reject).
    pub fn add(&mut self, p: Point3) {
        if self.count == 0 {
            self.anchor = [p.x, p.y, p.z];
        }
        self.count = self.count.saturating_add(1);
        let [ax, ay, az] = self.anchor;
        let d = [
            exact_difference(p.x, ax),
            exact_difference(p.y, ay),
            exact_difference(p.z, az),
        ];
        let mut n = [0i32; 3];
        for (j, (n, d)) in n.iter_mut().zip(d).enumerate() {
            *n = self.steps(j, d);
        }
        if n != [0; 3] {
            self.accumulate(n);
        }
    }

    /// Offset `d` (a pair summing to it exactly) on axis `j` in grid steps, coarsening that
    /// axis's grid first if it must.
    fn steps(&mut self, j: usize, (d, error): (f32, f32)) -> i32 {
        let size = libm::fabsf(d);
        if !(size > 0.0) {
            return 0;
        }
        // The pitch that puts this offset within the limit: 2^-23 of its binade, or finer.
        let needed = (exponent32(size) - PITCH_BITS).clamp(MIN_QUANTUM, MAX_QUANTUM);
        let Some(q) = self.quantum.get_mut(j) else {
            return 0;
        };
        if *q == NO_PITCH {
            *q = needed as i8;
        } else if needed > i32::from(*q) {
            let levels = needed - i32::from(*q);
            self.coarsen(j, levels);
        }
        let q = self.quantum.get(j).copied().map_or(0, i32::from);
        steps_of(q, (d, error))
    }

    // Rare (a cluster's grid coarsens a few times in its life): out of line, to keep the image
    // under its 64 KiB of flash.
    #[cold]
    #[inline(never)]
    /// Makes axis `j`'s pitch `2^levels` times coarser: a sum with `n_j^a` in it becomes
    /// `2^(-a levels)` of itself in the new steps, an exponent change while the exponent allows.
    fn coarsen(&mut self, j: usize, levels: i32) {
        let levels = levels.clamp(0, 64) as u32;
        if let Some(q) = self.quantum.get_mut(j) {
            *q = (i32::from(*q) + levels as i32).clamp(MIN_QUANTUM, MAX_QUANTUM) as i8;
        }
        for ((sum, shift), powers) in self.sums.iter_mut().zip(self.shift.iter_mut()).zip(POWERS) {
            let wanted = u32::from(powers.get(j).copied().unwrap_or(0)) * levels;
            let have = u32::from(*shift);
            if have >= wanted {
                *shift = (have - wanted) as u8;
            } else {
                *sum = shifted(*sum, wanted - have);
                *shift = 0;
            }
        }
    }

    /// Adds term `t` (below 2^61 after its shift) to slot `i`, halving the slot past 2^62.
    #[inline]
    fn add_term(&mut self, i: usize, t: i64) {
        if let (Some(sum), Some(shift)) = (self.sums.get_mut(i), self.shift.get_mut(i)) {
            *sum += shifted(t, u32::from(*shift));
            if !(-MANTISSA_LIMIT..MANTISSA_LIMIT).contains(sum) {
                halve(sum, shift);
            }
        }
    }

    /// Adds `a b` (`a, b < 2^48`, negated if `negative`) to slot `i`, first raising the slot's
    /// exponent if the shifted product would not stay under 2^61.
    fn add_product(&mut self, i: usize, a: u64, b: u64, negative: bool) {
        let (Some(sum), Some(shift)) = (self.sums.get_mut(i), self.shift.get_mut(i)) else {
            return;
        };
        let (high, low) = wide_product(a, b);
        let needed = shift_for(high, low);
        if needed > u32::from(*shift) {
            raise(sum, shift, needed);
        }
        // Below 2^61: the conversion and the negation are exact.
        let t = wide_shifted(high, low, u32::from(*shift)) as i64;
        *sum += if negative { -t } else { t };
        if !(-MANTISSA_LIMIT..MANTISSA_LIMIT).contains(sum) {
            halve(sum, shift);
        }
    }

    /// Adds the products of one offset `n` (each within [`OFFSET_LIMIT`]).
    #[inline]
    fn accumulate(&mut self, n: [i32; 3]) {
        let [x, y, z] = n.map(i64::from);
        let size = n.map(|v| u64::from(v.unsigned_abs()));
        let [sx, sy, sz] = size;
        // The factors the wide slots multiply: |n_j|, n_j^2, |n_j n_k|.
        let bank = [
            sx,
            sy,
            sz,
            sx * sx,
            sy * sy,
            sz * sz,
            sx * sy,
            sx * sz,
            sy * sz,
        ];
        let narrow = [
            (0, x),
            (1, (sx * sx) as i64),
            (4, y),
            (5, (sy * sy) as i64),
            (8, z),
            (9, (sz * sz) as i64),
            (12, x * y),
            (16, x * z),
            (20, y * z),
        ];
        for (slot, term) in narrow {
            self.add_term(slot, term);
        }
        if self.second_order {
            return;
        }
        // Orders 3 and 4 (15 slots) in one loop, so the two-word arithmetic is in the image once.
        for &(slot, a, b, sign) in WIDE.iter() {
            let factor = |f: u8| bank.get(usize::from(f)).copied().unwrap_or(0);
            let negative = n.get(usize::from(sign)).is_some_and(|&v| v < 0);
            self.add_product(usize::from(slot), factor(a), factor(b), negative);
        }
    }

    /// The exponent of slot `i`'s unit (a power of two: its axes' pitches to their powers,
    /// times `2^shift`), clamped to f64's normal exponents.
    fn unit_exponent(&self, i: usize) -> i32 {
        let [px, py, pz] = POWERS.get(i).copied().unwrap_or([0; 3]).map(i32::from);
        // An axis without a pitch has only zero offsets: its power's slots hold zeros.
        let [qx, qy, qz] = self
            .quantum
            .map(|q| if q == NO_PITCH { 0 } else { i32::from(q) });
        let shift = self.shift.get(i).copied().map_or(0, i32::from);
        (shift + px * qx + py * qy + pz * qz).clamp(-1022, 1023)
    }

    /// Whether slot `i` is kept: every slot, or those of orders 1 and 2 ([`FixedMoments::second_order`]).
    fn kept(&self, i: usize) -> bool {
        !self.second_order
            || if i < 12 {
                i % 4 < 2
            } else {
                i.is_multiple_of(4)
            }
    }

    /// The same sums as f64 power sums about the anchor: each mantissa rounded once to 53 bits.
    pub fn to_moments(&self) -> Moments {
        let mut out = Moments::with_shift(self.anchor.map(f64::from));
        out.count = self.count;
        for (i, &m) in self.sums.iter().enumerate() {
            if !self.kept(i) {
                continue;
            }
            let value = scaled_by_pow2(m as f64, self.unit_exponent(i));
            let (row, col) = ((i % 12) / 4, i % 4);
            let target = if i < 12 { &mut out.axis } else { &mut out.pair };
            if let Some(slot) = target.get_mut(row).and_then(|r| r.get_mut(col)) {
                *slot = value;
            }
        }
        out
    }

    /// f64 power sums about `anchor` (their shift) as integers on the grids `quantum`: each
    /// slot's exponent is the smallest that keeps its mantissa under 2^62.
    fn from_moments(m: &Moments, anchor: [f32; 3], quantum: [i8; 3], second_order: bool) -> Self {
        let mut out = Self {
            anchor,
            count: m.count,
            quantum,
            second_order,
            ..Self::new()
        };
        for i in 0..SLOTS {
            if !out.kept(i) {
                continue;
            }
            let (row, col) = ((i % 12) / 4, i % 4);
            let source = if i < 12 { &m.axis } else { &m.pair };
            let value = source
                .get(row)
                .and_then(|r| r.get(col))
                .copied()
                .unwrap_or(0.0);
            // Slots of an axis without a pitch hold only zeros (`unit_exponent` leaves it out).
            // Scalings by powers of two as exponent moves (`scaled_by_pow2`): the quotients'
            // bits, without a soft-f64 division or multiplication on the M4F.
            let steps = scaled_by_pow2(value, -out.unit_exponent(i));
            let shift = shift_below_2_61(steps);
            if let (Some(sum), Some(s)) = (out.sums.get_mut(i), out.shift.get_mut(i)) {
                let x = scaled_by_pow2(steps, -i32::from(shift));
                *sum = (x + if x < 0.0 { -0.5 } else { 0.5 }) as i64;
                *s = shift;
            }
        }
        out
    }

    /// Merges another cluster's sums into these (about this anchor, each axis on the coarser
    /// of the two grids). Two shells' sums (orders 1 and 2) merge in integers, rounded once to
    /// the merged grid (`merge.rs`); sums with orders 3 and 4 through f64, exact up to its
    /// rounding.
    pub fn merge(&mut self, other: &FixedMoments) {
        if other.count == 0 {
            return;
        }
        if self.count == 0 {
            *self = *other;
            return;
        }
        let quantum = self.merged_quantum(other);
        if self.second_order && other.second_order {
            self.merge_second_order(other, quantum);
            return;
        }
        // `Moments::merge` keeps the first one's shift: this anchor.
        let second_order = self.second_order || other.second_order;
        let mut sum = self.to_moments();
        if second_order {
            sum.merge_second_order(&other.to_moments());
        } else {
            sum.merge(&other.to_moments());
        }
        *self = Self::from_moments(&sum, self.anchor, quantum, second_order);
    }

    /// The mean in single precision: the anchor plus the mean offset, all in f32 operations
    /// (the centre the clustering uses, once per point).
    pub fn mean32(&self) -> Option<[f32; 3]> {
        if self.count == 0 {
            return None;
        }
        let n = u32::try_from(self.count).unwrap_or(u32::MAX) as f32;
        Some([0, 1, 2].map(|j| {
            let anchor = self.anchor.get(j).copied().unwrap_or(0.0);
            let q = self.quantum.get(j).copied().unwrap_or(NO_PITCH);
            if q == NO_PITCH {
                return anchor;
            }
            let slot = 4 * j;
            let sum = self.sums.get(slot).copied().unwrap_or(0);
            let unit = pow2_32(i32::from(q) + self.shift.get(slot).copied().map_or(0, i32::from));
            // Below 2^31 (a cluster of up to 2^7 points at the largest offsets) the FPU converts
            // it; above, its two halves are (the i64 routine is a software call at every sum;
            // the result may differ from it in the last bit, the same on every target).
            let sum = match i32::try_from(sum) {
                Ok(v) => v as f32,
                Err(_) => ((sum >> 32) as i32 as f32) * pow2_32(32) + (sum as u32) as f32,
            };
            anchor + sum * unit / n
        }))
    }

    /// Central moments about the mean (through the f64 sums), or `None` for an empty cluster
    /// or one that keeps the second order only.
    pub fn central(&self) -> Option<CentralMoments> {
        if self.second_order {
            return None;
        }
        self.to_moments().central_by_reciprocal()
    }

    /// Mean and covariance (through the f64 sums), or `None` for an empty cluster.
    pub fn covariance(&self) -> Option<([f64; 3], [[f64; 3]; 3])> {
        self.to_moments().covariance()
    }
}

mod merge;
#[cfg(test)]
mod tests;
