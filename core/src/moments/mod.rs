//! Cluster moments: count, mean and the central moments of order 2 and 4 that eq. 12 needs.
//!
//! Scheme: shifted power sums in f64. Each cluster keeps the sums of `u^a v^b` over its points,
//! `u = x - shift`, for the monomials `u, u^2, u^3, u^4` of each axis and `uv, u^2 v, u v^2,
//! u^2 v^2` of each axis pair. That set is closed under a change of shift, so two clusters merge
//! exactly (re-shift one, add) and a point is one O(1) update.
//!
//! Why f64 sums and not Pébay's f32 updates: eq. 12's residual is a difference of fourth-order
//! sums, and a well-fitted cluster makes that difference small, so f32's 24-bit mantissa (about
//! 6e-8) is used up before the 1e-4 agreement with a direct f64 sum is reached. IEEE-754 addition and multiplication are
//! exactly rounded on every target, soft-float on a Cortex-M4F included, so f64 keeps the bits
//! identical across builds. The shift is the cluster's first point (or a caller's guess at the
//! mean), which keeps the raw-to-central conversion free of large cancellations.

use crate::geometry::Point3;

pub mod fixed;
pub use fixed::FixedMoments;

/// Number of pairs (x,y), (x,z), (y,z).
const PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// Central moments a fitness evaluation needs, all about the cluster mean.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CentralMoments {
    pub count: u64,
    pub mean: [f64; 3],
    /// `E[d_j^2]`, `d = x - mean`.
    pub second: [f64; 3],
    /// `E[d_j^2 d_k^2]` as a symmetric 3x3 matrix (diagonal: `E[d_j^4]`).
    pub fourth: [[f64; 3]; 3],
}

/// Mergeable, incrementally updated power sums of a cluster.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moments {
    shift: [f64; 3],
    /// False until a shift is chosen, by the caller or by the first point.
    shift_fixed: bool,
    count: u64,
    /// `sum u_j^p` for p = 1..=4, per axis j.
    axis: [[f64; 4]; 3],
    /// Per pair (j,k): `sum u v, sum u^2 v, sum u v^2, sum u^2 v^2`.
    pair: [[f64; 4]; 3],
}

impl Default for Moments {
    fn default() -> Self {
        Self::new()
    }
}

impl Moments {
    /// Empty moments; the first point added becomes the shift.
    pub const fn new() -> Self {
        Self {
            shift: [0.0; 3],
            shift_fixed: false,
            count: 0,
            axis: [[0.0; 4]; 3],
            pair: [[0.0; 4]; 3],
        }
    }

    /// Empty moments with a chosen shift (e.g. a centroid known in advance).
    pub const fn with_shift(shift: [f64; 3]) -> Self {
        Self {
            shift,
            shift_fixed: true,
            count: 0,
            axis: [[0.0; 4]; 3],
            pair: [[0.0; 4]; 3],
        }
    }

    pub const fn count(&self) -> u64 {
        self.count
    }

    pub const fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Adds one point. Non-finite points are the caller's to reject; see `kmeans` and the stream.
    pub fn add(&mut self, point: Point3) {
        self.add_f64(point.to_f64());
    }

    pub fn add_f64(&mut self, p: [f64; 3]) {
        if !self.shift_fixed {
            self.shift = p;
            self.shift_fixed = true;
        }
        let u = [
            p[0] - self.shift[0],
            p[1] - self.shift[1],
            p[2] - self.shift[2],
        ];
        for (sums, &uj) in self.axis.iter_mut().zip(u.iter()) {
            let u2 = uj * uj;
            sums[0] += uj;
            sums[1] += u2;
            sums[2] += u2 * uj;
            sums[3] += u2 * u2;
        }
        for (sums, &(j, k)) in self.pair.iter_mut().zip(PAIRS.iter()) {
            let (a, b) = (u[j], u[k]);
            let ab = a * b;
            sums[0] += ab;
            sums[1] += ab * a;
            sums[2] += ab * b;
            sums[3] += ab * ab;
        }
        self.count += 1;
    }

    /// The same sums expressed about `new_shift` (exact algebra, binomial expansion).
    pub fn reshifted(&self, new_shift: [f64; 3]) -> Self {
        // u' = u - t with t = new_shift - shift.
        let n = self.count as f64;
        let t = [
            new_shift[0] - self.shift[0],
            new_shift[1] - self.shift[1],
            new_shift[2] - self.shift[2],
        ];
        let mut out = Self::with_shift(new_shift);
        out.count = self.count;
        for j in 0..3 {
            let [s1, s2, s3, s4] = self.axis[j];
            let a = t[j];
            let (a2, a3, a4) = (a * a, a * a * a, a * a * a * a);
            out.axis[j] = [
                s1 - n * a,
                s2 - 2.0 * a * s1 + n * a2,
                s3 - 3.0 * a * s2 + 3.0 * a2 * s1 - n * a3,
                s4 - 4.0 * a * s3 + 6.0 * a2 * s2 - 4.0 * a3 * s1 + n * a4,
            ];
        }
        for (p, &(j, k)) in PAIRS.iter().enumerate() {
            // `min(2)` leaves the pair as it is; it only lets the compiler drop the bounds check
            // when the loop is not unrolled (opt-level "s").
            let (j, k) = (j.min(2), k.min(2));
            let [uv, u2v, uv2, u2v2] = self.pair[p];
            let (u1, u2) = (self.axis[j][0], self.axis[j][1]);
            let (v1, v2) = (self.axis[k][0], self.axis[k][1]);
            let (a, b) = (t[j], t[k]);
            // (u-a)(v-b), (u-a)^2 (v-b), (u-a)(v-b)^2, (u-a)^2 (v-b)^2 expanded.
            let new_uv = uv - b * u1 - a * v1 + n * a * b;
            let new_u2v =
                u2v - b * u2 - 2.0 * a * uv + 2.0 * a * b * u1 + a * a * v1 - n * a * a * b;
            let new_uv2 =
                uv2 - a * v2 - 2.0 * b * uv + 2.0 * a * b * v1 + b * b * u1 - n * a * b * b;
            let new_u2v2 =
                u2v2 - 2.0 * b * u2v - 2.0 * a * uv2 + b * b * u2 + a * a * v2 + 4.0 * a * b * uv
                    - 2.0 * a * b * b * u1
                    - 2.0 * a * a * b * v1
                    + n * a * a * b * b;
            out.pair[p] = [new_uv, new_u2v, new_uv2, new_u2v2];
        }
        out
    }

    /// The sums each kept to `bits` significant bits (clamped to 1..=53), rounded to nearest:
    /// what a store narrower than f64 would hold. Applied after every update, it prices a
    /// compact cluster in agreement with direct sums before anyone builds one.
    pub fn with_significand_bits(mut self, bits: u32) -> Self {
        let dropped = 53 - bits.clamp(1, 53);
        if dropped == 0 {
            return self;
        }
        // On the bit pattern: the carry of the rounding runs into the exponent, as it should.
        let half = 1u64 << (dropped - 1);
        let round = |v: &mut f64| {
            if v.is_finite() {
                *v = f64::from_bits(((v.to_bits() + half) >> dropped) << dropped);
            }
        };
        self.axis.iter_mut().flatten().for_each(round);
        self.pair.iter_mut().flatten().for_each(round);
        self
    }

    /// Merges another cluster's moments into this one; exact up to rounding.
    pub fn merge(&mut self, other: &Moments) {
        if other.count == 0 {
            return;
        }
        if self.count == 0 {
            *self = *other;
            return;
        }
        let other = other.reshifted(self.shift);
        self.count += other.count;
        for (mine, theirs) in self.axis.iter_mut().zip(other.axis.iter()) {
            for (a, b) in mine.iter_mut().zip(theirs.iter()) {
                *a += b;
            }
        }
        for (mine, theirs) in self.pair.iter_mut().zip(other.pair.iter()) {
            for (a, b) in mine.iter_mut().zip(theirs.iter()) {
                *a += b;
            }
        }
    }

    /// [`Moments::merge`] of the sums of orders 1 and 2 only (the mean and covariance), the
    /// others left as they were: a shell's merge, a tenth of the work in software f64.
    pub fn merge_second_order(&mut self, other: &Moments) {
        if other.count == 0 {
            return;
        }
        if self.count == 0 {
            *self = *other;
            return;
        }
        let n = other.count as f64;
        let t = [
            self.shift[0] - other.shift[0],
            self.shift[1] - other.shift[1],
            self.shift[2] - other.shift[2],
        ];
        // About this shift, u' = u - t: sum u' = sum u - n t, sum u'^2 = sum u^2 - 2 t sum u + n t^2.
        for ((mine, theirs), &a) in self.axis.iter_mut().zip(other.axis.iter()).zip(t.iter()) {
            mine[0] += theirs[0] - n * a;
            mine[1] += theirs[1] - 2.0 * a * theirs[0] + n * (a * a);
        }
        for ((mine, theirs), &(j, k)) in self
            .pair
            .iter_mut()
            .zip(other.pair.iter())
            .zip(PAIRS.iter())
        {
            // `min(2)` leaves the pair as it is; it only lets the compiler drop the bounds check.
            let (j, k) = (j.min(2), k.min(2));
            let (a, b) = (t[j], t[k]);
            let (u1, v1) = (other.axis[j][0], other.axis[k][0]);
            mine[0] += theirs[0] - b * u1 - a * v1 + n * a * b;
        }
        self.count += other.count;
    }

    /// Mean of the points, or `None` for an empty cluster.
    pub fn mean(&self) -> Option<[f64; 3]> {
        if self.count == 0 {
            return None;
        }
        let n = self.count as f64;
        Some([
            self.shift[0] + self.axis[0][0] / n,
            self.shift[1] + self.axis[1][0] / n,
            self.shift[2] + self.axis[2][0] / n,
        ])
    }

    /// The mean in single precision: `shift + (sum u) / n`, each term rounded to f32 first, so
    /// the division is the FPU's and not a software f64 routine (on a Cortex-M4F three f64
    /// divisions cost about as much as the rest of a point's clustering). Within an ulp or two
    /// of [`Moments::mean`] rounded to f32, and the same bits on every target.
    pub fn mean32(&self) -> Option<[f32; 3]> {
        if self.count == 0 {
            return None;
        }
        // Counts past 2^32 saturate; the mean's rounding is then far below an f32 ulp anyway.
        let n = u32::try_from(self.count).unwrap_or(u32::MAX) as f32;
        Some([0, 1, 2].map(|j| {
            let (shift, sum) = match (self.shift.get(j), self.axis.get(j)) {
                (Some(&shift), Some(sums)) => (shift, sums[0]),
                _ => (0.0, 0.0),
            };
            shift as f32 + sum as f32 / n
        }))
    }

    /// Mean and covariance `E[d_j d_k]` (`d = x - mean`, divided by n), or `None` for an empty
    /// cluster: all an oriented shell needs. The diagonal is [`CentralMoments::second`] to the
    /// bit, from the same expression.
    pub fn covariance(&self) -> Option<([f64; 3], [[f64; 3]; 3])> {
        if self.count == 0 {
            return None;
        }
        let n = self.count as f64;
        let e = |s: f64| s / n;
        let a = self.axis.map(|sums| e(sums[0]));
        let mut cov = [[0.0; 3]; 3];
        for j in 0..3 {
            cov[j][j] = (e(self.axis[j][1]) - a[j] * a[j]).max(0.0);
        }
        for (p, &(j, k)) in PAIRS.iter().enumerate() {
            let (j, k) = (j.min(2), k.min(2));
            let value = e(self.pair[p][0]) - a[j] * a[k];
            cov[j][k] = value;
            cov[k][j] = value;
        }
        let mean = [
            self.shift[0] + a[0],
            self.shift[1] + a[1],
            self.shift[2] + a[2],
        ];
        Some((mean, cov))
    }

    /// Central moments about the mean, or `None` for an empty cluster.
    pub fn central(&self) -> Option<CentralMoments> {
        let n = self.count as f64;
        self.central_by(|s| s / n)
    }

    /// [`Moments::central`] with each mean formed as a product by `1/n`, within an ulp of the
    /// quotient: the stream's fits take this one, where each soft-f64 division costs a
    /// Cortex-M4F several multiplications' worth, and a fit has one for every mean. The batch
    /// pipeline keeps the quotients, and with them the paper tables' bits.
    pub fn central_by_reciprocal(&self) -> Option<CentralMoments> {
        let inverse = 1.0 / self.count as f64;
        self.central_by(|s| s * inverse)
    }

    /// Raw moments about the shift, then central ones by expanding (u - a)^p with a = E[u];
    /// `e` takes a sum to its mean.
    fn central_by(&self, e: impl Fn(f64) -> f64) -> Option<CentralMoments> {
        if self.count == 0 {
            return None;
        }
        let mut a = [0.0; 3];
        let mut second = [0.0; 3];
        let mut fourth = [[0.0; 3]; 3];
        for j in 0..3 {
            let [s1, s2, s3, s4] = self.axis[j];
            let m = e(s1);
            a[j] = m;
            second[j] = (e(s2) - m * m).max(0.0);
            fourth[j][j] =
                (e(s4) - 4.0 * m * e(s3) + 6.0 * m * m * e(s2) - 3.0 * m * m * m * m).max(0.0);
        }
        for (p, &(j, k)) in PAIRS.iter().enumerate() {
            let (j, k) = (j.min(2), k.min(2));
            let [uv, u2v, uv2, u2v2] = self.pair[p].map(&e);
            let (ma, mb) = (a[j], a[k]);
            let (u2, v2) = (e(self.axis[j][1]), e(self.axis[k][1]));
            let value = u2v2 - 2.0 * mb * u2v - 2.0 * ma * uv2
                + mb * mb * u2
                + ma * ma * v2
                + 4.0 * ma * mb * uv
                - 3.0 * ma * ma * mb * mb;
            fourth[j][k] = value.max(0.0);
            fourth[k][j] = value.max(0.0);
        }
        let mean = [
            self.shift[0] + a[0],
            self.shift[1] + a[1],
            self.shift[2] + a[2],
        ];
        Some(CentralMoments {
            count: self.count,
            mean,
            second,
            fourth,
        })
    }
}

impl CentralMoments {
    /// Root-mean-square distance of the points from their mean: the cluster's spread `s`.
    pub fn rms_radius(&self) -> f64 {
        libm::sqrt(self.second[0] + self.second[1] + self.second[2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{OrFail, TestResult};

    fn lcg_points(n: usize, seed: u64, offset: [f64; 3]) -> ([[f64; 3]; 64], usize) {
        let mut out = [[0.0; 3]; 64];
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        for p in out.iter_mut().take(n) {
            *p = [
                offset[0] + next() * 0.3,
                offset[1] + next() * 0.1,
                offset[2] + next() * 0.02,
            ];
        }
        (out, n)
    }

    /// The moments of `a` merged with those of `b`, and the points of both in one array
    /// (together at most 64).
    fn merged(a: &[[f64; 3]], b: &[[f64; 3]]) -> (Moments, [[f64; 3]; 64]) {
        let (mut ma, mut mb) = (Moments::new(), Moments::new());
        let mut all = [[0.0; 3]; 64];
        for (slot, p) in all.iter_mut().zip(a.iter().chain(b)) {
            *slot = *p;
        }
        a.iter().for_each(|p| ma.add_f64(*p));
        b.iter().for_each(|p| mb.add_f64(*p));
        ma.merge(&mb);
        (ma, all)
    }

    /// Direct two-pass central moments, the independent check.
    fn direct(points: &[[f64; 3]]) -> CentralMoments {
        direct_of(points.iter().copied())
    }

    /// [`direct`] of any points (the integer sums' tests feed theirs as f32).
    pub(super) fn direct_of(points: impl Iterator<Item = [f64; 3]> + Clone) -> CentralMoments {
        let n = points.clone().count() as f64;
        let mut mean = [0.0; 3];
        for p in points.clone() {
            for j in 0..3 {
                mean[j] += p[j] / n;
            }
        }
        let mut second = [0.0; 3];
        let mut fourth = [[0.0; 3]; 3];
        for p in points {
            let d = [p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]];
            for j in 0..3 {
                second[j] += d[j] * d[j] / n;
                for k in 0..3 {
                    fourth[j][k] += d[j] * d[j] * d[k] * d[k] / n;
                }
            }
        }
        CentralMoments {
            count: n as u64,
            mean,
            second,
            fourth,
        }
    }

    fn assert_close(a: &CentralMoments, b: &CentralMoments, tol: f64) {
        assert_eq!(a.count, b.count);
        for j in 0..3 {
            assert!((a.mean[j] - b.mean[j]).abs() <= tol * (1.0 + b.mean[j].abs()));
            assert!((a.second[j] - b.second[j]).abs() <= tol * b.second[j]);
            for k in 0..3 {
                let (x, y) = (a.fourth[j][k], b.fourth[j][k]);
                assert!((x - y).abs() <= tol * y, "fourth[{j}][{k}] {x} vs {y}");
            }
        }
    }

    #[test]
    fn incremental_matches_two_pass_far_from_origin() -> TestResult {
        // A cluster 1 km from the origin: raw sums about zero would lose everything here.
        let (pts, n) = lcg_points(64, 7, [1000.0, -250.0, 30.0]);
        let mut m = Moments::new();
        for p in &pts[..n] {
            m.add_f64(*p);
        }
        let got = m.central().or_fail("non-empty")?;
        assert_close(&got, &direct(&pts[..n]), 1e-9);
        Ok(())
    }

    #[test]
    fn significand_bits_round_to_nearest_and_53_keeps_every_bit() -> TestResult {
        let mut m = Moments::with_shift([0.0; 3]);
        m.add_f64([1.0 + 5.0 / 1024.0, -0.1, 1e-3]);
        if m.with_significand_bits(53) != m || m.with_significand_bits(99) != m {
            return Err("53 bits or more must keep the f64 sums as they are");
        }
        let narrow = m.with_significand_bits(8);
        let x = narrow.central().or_fail("one point")?.mean[0];
        // 1 + 5/1024 has 11 significant bits; to 8 (steps of 8/1024) the nearest is 1 + 8/1024.
        if x != 1.0 + 8.0 / 1024.0 {
            return Err("1 + 5/1024 to 8 bits must round to the nearest, 1 + 8/1024");
        }
        Ok(())
    }

    #[test]
    fn merge_equals_one_pass_and_reshift_is_exact() -> TestResult {
        let (a, na) = lcg_points(40, 1, [1.0, 2.0, 3.0]);
        let (b, nb) = lcg_points(24, 2, [1.5, 1.8, 3.1]);
        let (ma, all) = merged(&a[..na], &b[..nb]);
        let expected = direct(&all[..na + nb]);
        assert_close(&ma.central().or_fail("non-empty")?, &expected, 1e-9);
        // A shift 50 spreads away costs (50)^4 in cancellation: 6e6 * 1e-16, hence 1e-8.
        let moved = ma.reshifted([-3.0, 7.0, 0.5]);
        assert_close(&moved.central().or_fail("non-empty")?, &expected, 1e-8);
        Ok(())
    }

    /// Direct two-pass covariance, the independent check of [`Moments::covariance`].
    fn direct_covariance(points: &[[f64; 3]]) -> ([f64; 3], [[f64; 3]; 3]) {
        let n = points.len() as f64;
        let mut mean = [0.0; 3];
        for p in points {
            for j in 0..3 {
                mean[j] += p[j] / n;
            }
        }
        let mut cov = [[0.0; 3]; 3];
        for p in points {
            for j in 0..3 {
                for k in 0..3 {
                    cov[j][k] += (p[j] - mean[j]) * (p[k] - mean[k]) / n;
                }
            }
        }
        (mean, cov)
    }

    #[test]
    fn covariance_matches_two_pass_after_merges_and_far_from_origin() -> TestResult {
        // Tilted so every off-diagonal term is non-zero: the shell's rotation comes from them.
        let tilt = |mut pts: [[f64; 3]; 64]| {
            for p in pts.iter_mut() {
                let (x, y, z) = (p[0], p[1], p[2]);
                *p = [x + 0.5 * y, y - 0.3 * z + 0.2 * x, z + 0.1 * x];
            }
            pts
        };
        let (a, na) = lcg_points(40, 3, [1000.0, -250.0, 30.0]);
        let (b, nb) = lcg_points(24, 4, [1000.2, -250.1, 30.05]);
        let (a, b) = (tilt(a), tilt(b));
        let (ma, all) = merged(&a[..na], &b[..nb]);
        let (mean, cov) = ma.covariance().or_fail("non-empty")?;
        let (want_mean, want) = direct_covariance(&all[..na + nb]);
        let scale = want[0][0] + want[1][1] + want[2][2];
        for j in 0..3 {
            if (mean[j] - want_mean[j]).abs() > 1e-12 * want_mean[j].abs() {
                return Err("mean differs from the two-pass mean");
            }
            for k in 0..3 {
                // Relative to the trace: a small off-diagonal term is judged at the matrix's scale.
                if (cov[j][k] - want[j][k]).abs() > 1e-9 * scale || cov[j][k] != cov[k][j] {
                    return Err("covariance differs from the two-pass covariance");
                }
            }
        }
        if want[0][1].abs() < 1e-3 * scale {
            return Err("the test cloud must be tilted");
        }
        let second = ma.central().or_fail("non-empty")?.second;
        if (0..3).any(|j| second[j].to_bits() != cov[j][j].to_bits()) {
            return Err("the diagonal must be `second` to the bit");
        }
        Ok(())
    }

    #[test]
    fn empty_moments_have_no_mean() {
        let m = Moments::new();
        assert!(m.mean().is_none() && m.central().is_none() && m.covariance().is_none());
        let mut merged = Moments::new();
        merged.merge(&m);
        assert!(merged.is_empty());
    }
}
