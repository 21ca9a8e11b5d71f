//! Two shells' sums (orders 1 and 2) merged in integers. Why: a device's merge pass merges
//! five pairs, and through f64 each converted 18 sums to soft f64 and back on the Cortex-M4F
//! (16,500 instructions a merge on the image, with four a pass a fifth of a shells' pass).
//!
//! About this anchor, on the merged grids, the other cluster's offsets are its own plus `d`,
//! the anchors' difference in steps, exact (both anchors are f32; rounding it to the grid
//! moved every point of the other cluster by up to half a step, and a cluster's mean by as
//! much at each merge): `sum (n + d) = S1 + N d`, `sum (n_j + d_j)^2 = S2 + 2 d_j S1_j +
//! N d_j^2`, `sum (n_j + d_j)(n_k + d_k) = S_jk + d_k S1_j + d_j S1_k + N d_j d_k`. Each term
//! is an integer times a power of two, summed in 128 bits (exactly, unless two terms' exponents
//! are over a hundred bits apart) and rounded into its slot.

use super::{
    FixedMoments, MAX_QUANTUM, MIN_QUANTUM, NO_PITCH, PAIRS, PITCH_BITS, POWERS, SLOTS,
    exact_difference, exponent32, pow2_64,
};

/// `m 2^e`, in a slot's units on the merged grids.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Scaled {
    m: i128,
    e: i32,
}

/// Headroom kept above a term aligned for a sum: two terms of it add without overflow.
const TOP_BITS: u32 = 125;

impl Scaled {
    const ZERO: Self = Self { m: 0, e: 0 };

    fn of(m: i64, e: i32) -> Self {
        Self {
            m: i128::from(m),
            e,
        }
    }

    /// `x 2^e`, exactly (an f32's significand is 24 bits; non-finite values are 0).
    fn of_f32(x: f32, e: i32) -> Self {
        if !x.is_finite() || x == 0.0 {
            return Self::ZERO;
        }
        let bits = x.to_bits();
        let biased = ((bits >> 23) & 0xff) as i32;
        let fraction = i128::from(bits & 0x7f_ffff);
        // Subnormals have no implicit bit and the smallest exponent.
        let (significand, exponent) = if biased == 0 {
            (fraction, -149)
        } else {
            (fraction | 0x80_0000, biased - 150)
        };
        let m = if x < 0.0 { -significand } else { significand };
        Self { m, e: exponent + e }
    }

    /// The same value with its mantissa under 2^`bits`, rounded if it was not.
    fn normalized(self, bits: u32) -> Self {
        let have = 128 - self.m.unsigned_abs().leading_zeros();
        let drop = have.saturating_sub(bits);
        Self {
            m: rounded_shift(self.m, drop),
            e: self.e + drop as i32,
        }
    }

    /// The product, each factor first rounded to 62 bits (exact for a slot's mantissa, a
    /// count or an anchors' difference), so it stays within 124.
    fn times(self, other: Self) -> Self {
        let (a, b) = (self.normalized(62), other.normalized(62));
        Self {
            m: a.m.saturating_mul(b.m),
            e: a.e + b.e,
        }
    }

    /// The sum, exact while the terms' exponents are within the headroom of each other, else
    /// the smaller rounded to the larger's last kept bit.
    fn plus(self, other: Self) -> Self {
        if other.m == 0 {
            return self;
        }
        if self.m == 0 {
            return other;
        }
        let (high, low) = if self.e >= other.e {
            (self, other)
        } else {
            (other, self)
        };
        let gap = high.e.abs_diff(low.e);
        let bits = 128 - high.m.unsigned_abs().leading_zeros();
        let up = gap.min(TOP_BITS.saturating_sub(bits));
        Self {
            m: (high.m << up).saturating_add(rounded_shift(low.m, gap - up)),
            e: high.e - up as i32,
        }
    }

    /// The slot's mantissa and exponent: the smallest exponent in `0..=63` that keeps the
    /// mantissa under 2^61, as `from_moments` chooses it, rounded half up (ties toward +inf,
    /// where `from_moments` rounds them away from zero: the same on every target either way).
    fn into_slot(self) -> (i64, u8) {
        const LIMIT: i128 = 1 << 61;
        if self.m == 0 {
            return (0, 0);
        }
        let bits = (128 - self.m.unsigned_abs().leading_zeros()) as i32;
        let shift = (bits + self.e - 61).clamp(0, 63);
        let down = shift - self.e;
        let m = if down > 0 {
            rounded_shift(self.m, down as u32)
        } else if bits - down <= 126 {
            // Below 2^61 after the move unless the shift was clamped at 63.
            self.m << (-down) as u32
        } else {
            // Past 2^124 in the slot's units: no sum of a cluster's points gets there.
            self.m.signum() * LIMIT
        };
        (m.clamp(-LIMIT, LIMIT) as i64, shift as u8)
    }
}

/// `m / 2^s` rounded half up (0 past the width).
fn rounded_shift(m: i128, s: u32) -> i128 {
    match s {
        0 => m,
        1..=126 => (m >> s) + ((m >> (s - 1)) & 1),
        _ => 0,
    }
}

impl FixedMoments {
    /// Slot `i`'s value on the grids `quantum` (each at least as coarse as this one's).
    fn scaled_to(&self, i: usize, quantum: [i8; 3]) -> Scaled {
        let (Some(&m), Some(&shift), Some(powers)) =
            (self.sums.get(i), self.shift.get(i), POWERS.get(i))
        else {
            return Scaled::ZERO;
        };
        let mut e = i32::from(shift);
        for ((&p, &mine), &merged) in powers.iter().zip(&self.quantum).zip(&quantum) {
            // An axis without a pitch has only zero offsets: its slots hold zeros.
            if p > 0 && mine != NO_PITCH && merged != NO_PITCH {
                e += i32::from(p) * (i32::from(mine) - i32::from(merged));
            }
        }
        Scaled::of(m, e)
    }

    /// The grids of a merge: each axis's holds every merged offset within the limit (this
    /// cluster's offsets reach 2^24 steps of its pitch, the other's as far again from its own
    /// anchor).
    pub(super) fn merged_quantum(&self, other: &FixedMoments) -> [i8; 3] {
        let reach = |q: i8| {
            if q == NO_PITCH {
                0.0
            } else {
                pow2_64(i32::from(q) + 24)
            }
        };
        let mut quantum = self.quantum;
        for (j, q) in quantum.iter_mut().enumerate() {
            let theirs = other.quantum.get(j).copied().unwrap_or(NO_PITCH);
            let apart = match (self.anchor.get(j), other.anchor.get(j)) {
                (Some(&a), Some(&b)) => libm::fabs(f64::from(b) - f64::from(a)),
                _ => 0.0,
            };
            let bound = reach(*q).max(apart + reach(theirs));
            *q = (*q).max(theirs);
            if *q == NO_PITCH && bound > 0.0 {
                *q = (exponent32(bound as f32) - PITCH_BITS).clamp(MIN_QUANTUM, MAX_QUANTUM) as i8;
            }
            while bound > reach(*q) && i32::from(*q) < MAX_QUANTUM {
                *q += 1;
            }
        }
        quantum
    }

    /// Merges `other`'s sums (both of orders 1 and 2 only, both non-empty) into these, about
    /// this anchor, on the grids `quantum` (`FixedMoments::merged_quantum`). Out of line: the
    /// paper's merges, through f64, need none of its frame.
    #[inline(never)]
    pub(super) fn merge_second_order(&mut self, other: &FixedMoments, quantum: [i8; 3]) {
        // The anchors' difference in steps of each merged grid, exactly: `b - a` is the f32
        // sum `s + err` (TwoSum), each term an integer times a power of two.
        let mut d = [Scaled::ZERO; 3];
        for (j, slot) in d.iter_mut().enumerate() {
            let (Some(&a), Some(&b), Some(&q)) =
                (self.anchor.get(j), other.anchor.get(j), quantum.get(j))
            else {
                continue;
            };
            if a != b && q != NO_PITCH {
                let (s, err) = exact_difference(b, a);
                let q = -i32::from(q);
                *slot = Scaled::of_f32(s, q).plus(Scaled::of_f32(err, q));
            }
        }
        let n = Scaled {
            m: i128::from(other.count),
            e: 0,
        };
        let first = |j: usize| other.scaled_to(4 * j, quantum);
        let offset = |j: usize| d.get(j).copied().unwrap_or(Scaled::ZERO);
        // Each slot's merged value needs only its own two sums and the other's first orders,
        // so it is written in place (an array of the 24 would be 768 bytes of the image's stack).
        for i in 0..SLOTS {
            if !self.kept(i) {
                continue;
            }
            let both = self.scaled_to(i, quantum).plus(other.scaled_to(i, quantum));
            let moved = if i < 12 {
                let j = i / 4;
                let dj = offset(j);
                if i % 4 == 0 {
                    n.times(dj)
                } else {
                    let twice = Scaled { e: dj.e + 1, ..dj };
                    first(j).times(twice).plus(n.times(dj.times(dj)))
                }
            } else {
                let (j, k) = PAIRS.get((i - 12) / 4).copied().unwrap_or((0, 0));
                let (dj, dk) = (offset(j), offset(k));
                first(j)
                    .times(dk)
                    .plus(first(k).times(dj))
                    .plus(n.times(dj.times(dk)))
            };
            if let (Some(sum), Some(shift)) = (self.sums.get_mut(i), self.shift.get_mut(i)) {
                (*sum, *shift) = both.plus(moved).into_slot();
            }
        }
        self.count = self.count.saturating_add(other.count);
        self.quantum = quantum;
    }
}
