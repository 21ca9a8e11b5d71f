//! The sphere minimising eq. 12: one of the two start candidates of the f32 search.
//!
//! In `w = 1/r'^2` eq. 12 over spheres is `f(w) = h sqrt(e(w)) + v w^(-3/2)`, where
//! `e(w) = (1 - w m)^2 + w^2 q`, `m = sum_j E[q'_j]`, `q = 1^T Cov(q') 1`, `h = alpha / 2` and
//! `v` the volume term's factor. Both terms are convex, so the minimum is where `f'` changes
//! sign. With `slope = w q - m (1 - w m)` (half of `e'`; written so, not as `w (m^2 + q) - m`,
//! so that for `q = 0` it is exactly `-m (1 - w m)` and `slope / sqrt(e)` is `-m` or `m` even
//! at the kink of a perfect fit, where both are rounding noise), `k(w) = w^(5/2) f'(w) =
//! h slope w^(5/2) / sqrt(e) - 1.5 v`, and since `(m^2 + q) e - slope^2 = q` identically,
//! `k'(w) = h w^(3/2) (w q / e + 2.5 slope) / sqrt(e)`: positive wherever `slope > 0`, which
//! it is at the root, so Newton's method on `k` has no cancellation in its step.
//!
//! Why a root and not a search for the minimum: a minimum's position is only determined to the
//! square root of the arithmetic's precision, a root to the precision itself. The DE starts
//! from this radius rounded to f32, and an independent computation (the firmware simulator's
//! f64 reference) must find the same f32, or the two DE runs part. Newton's method on `k` runs
//! in f32 (a few steps of about twenty FPU operations on the Cortex-M4F), then one step with `k`
//! in f64 takes the root from f32's precision to about its square (the step's size needs
//! only f32's `k'`): one software f64 step, where a search in f64 would take a software square
//! root and division at every step.

/// Eq. 12 restricted to spheres (module doc), in f64 and rounded to f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereTerms {
    m: f64,
    q: f64,
    v: f64,
    h: f64,
    /// `m`, `q`, `m^2 + q`, `h`, `v` in f32, for the f32 steps.
    f32s: [f32; 5],
}

/// `2^-21`: a Newton step this small, relative to `w`, leaves an error of about its square.
const CONVERGED: f32 = 1.0 / 2_097_152.0;

/// The sphere's radius to f32's precision ([`SphereTerms::estimate`]), ready to be made exact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereEstimate {
    /// A bound of the box where the minimum lies on it (exact already).
    bound: Option<f64>,
    /// Else the f32 root of `k` and the bracket around it.
    w: f32,
    left: f32,
    right: f32,
    lo: f64,
    hi: f64,
}

impl SphereEstimate {
    /// The radius in f32: within a few f32 ulps of the exact one.
    pub fn radius32(&self) -> f32 {
        match self.bound {
            Some(r) => r as f32,
            None => 1.0 / crate::fit32::sqrt32(self.w),
        }
    }
}

impl SphereTerms {
    /// `m = sum_j E[q'_j]`, `q = 1^T Cov(q') 1` (a rounding below zero is taken as zero), `v`
    /// the volume term's factor and `h = alpha / 2`.
    pub fn new(m: f64, q: f64, v: f64, h: f64) -> Self {
        let q = if q > 0.0 { q } else { 0.0 };
        Self {
            m,
            q,
            v,
            h,
            f32s: [m as f32, q as f32, (m * m + q) as f32, h as f32, v as f32],
        }
    }

    /// `k` in f64 (module doc), with one square root: `w^(5/2) / sqrt(e) = w^3 / sqrt(w e)`.
    fn k64(&self, w: f64) -> f64 {
        let Self { m, q, v, h, .. } = *self;
        let a = 1.0 - w * m;
        let slope = w * q - m * a;
        let we = w * (a * a + w * w * q);
        if !(we > 0.0) {
            // The kink of a perfect fit (q = 0, w = 1/m), as from its right (`k32`).
            return -1.5 * v;
        }
        h * slope * (w * w * w) / libm::sqrt(we) - 1.5 * v
    }

    /// `k` and `k'` in f32 (module doc).
    fn k32(&self, w: f32) -> (f32, f32) {
        let [m, q, _, h, v] = self.f32s;
        let sqrt32 = crate::fit32::sqrt32;
        let a = 1.0 - w * m;
        let slope = w * q - m * a;
        let e = a * a + w * w * q;
        let w_root = w * sqrt32(w);
        if !(e > 0.0) {
            // The kink of a perfect fit (q = 0, w = 1/m): as if from its right, where the
            // residual term's slope is zero; bisection then closes in on it.
            return (-1.5 * v, h * w_root * 2.5 * slope);
        }
        let inverse_root_e = 1.0 / sqrt32(e);
        let k = h * slope * (w * w_root) * inverse_root_e - 1.5 * v;
        let dk =
            h * w_root * (w * q * (inverse_root_e * inverse_root_e) + 2.5 * slope) * inverse_root_e;
        (k, dk)
    }

    /// The radius in `[lo, hi]` (units of `s`) of the sphere minimising eq. 12, to f64's
    /// precision: [`SphereTerms::estimate`] then [`SphereTerms::exact`].
    pub fn optimal_radius(&self, lo: f64, hi: f64) -> f64 {
        self.exact(&self.estimate(lo, hi))
    }

    /// The minimum to f32's precision, by Newton's method on `k` in f32 kept inside a bracket.
    pub fn estimate(&self, lo: f64, hi: f64) -> SphereEstimate {
        let [m, q, mq, h, v] = self.f32s;
        let sqrt32 = crate::fit32::sqrt32;
        let (lo32, hi32) = (lo as f32, hi as f32);
        let (mut left, mut right) = (1.0 / (hi32 * hi32), 1.0 / (lo32 * lo32));
        let at = |bound: f64| SphereEstimate {
            bound: Some(bound),
            w: 0.0,
            left,
            right,
            lo,
            hi,
        };
        // Without a residual term (or without points) the smallest volume wins.
        if !(self.h > 0.0) || !(self.m * self.m + self.q > 0.0) {
            return at(lo);
        }
        if !(self.k32(right).0 > 0.0) {
            return at(lo);
        }
        if !(self.k32(left).0 < 0.0) {
            return at(hi);
        }
        // Start where the residual's minimum, w_ls = m / (m^2 + q), moves under the volume
        // term (k linearised about w_ls, where slope = 0 and e = q / (m^2 + q)).
        let w_ls = m / mq;
        let mut w = w_ls + 1.5 * v * sqrt32(q / mq) / (h * mq * (w_ls * w_ls * sqrt32(w_ls)));
        if !(w > left && w < right) {
            w = 0.5 * (left + right);
        }
        for _ in 0..64 {
            let (k, dk) = self.k32(w);
            if k < 0.0 {
                left = w;
            } else if k > 0.0 {
                right = w;
            } else {
                break;
            }
            let newton = w - k / dk;
            let next = if newton > left && newton < right {
                newton
            } else {
                0.5 * (left + right)
            };
            let moved = (next - w).abs();
            w = next;
            if !(moved > CONVERGED * w) {
                break;
            }
        }
        SphereEstimate {
            bound: None,
            w,
            left,
            right,
            lo,
            hi,
        }
    }

    /// The estimate made exact: Newton's steps on `k` in f64, from f32's precision to about its
    /// square, within the f32 bracket widened by f32's evaluation error (a step out of it is not
    /// converging: at the kink of a perfect fit, k jumps and the bracket is the answer).
    pub fn exact(&self, estimate: &SphereEstimate) -> f64 {
        let SphereEstimate {
            bound,
            w,
            left,
            right,
            lo,
            hi,
        } = *estimate;
        if let Some(r) = bound {
            return r;
        }
        let slack = 1.0 / 1_048_576.0;
        let (left, right) = (
            f64::from(left) * (1.0 - slack),
            f64::from(right) * (1.0 + slack),
        );
        let mut w64 = f64::from(w);
        for _ in 0..4 {
            // k in f64 decides where the root is; its slope, in f32, only scales the step.
            let step = (self.k64(w64) as f32) / self.k32(w64 as f32).1;
            let next = w64 - f64::from(step);
            if !(next >= left && next <= right) {
                // k jumps: the kink of e at w = 1/m, where a perfect fit's residual is zero.
                let kink = 1.0 / self.m;
                if kink >= left && kink <= right {
                    w64 = kink;
                }
                break;
            }
            w64 = next;
            if !(step.abs() > CONVERGED * (w64 as f32)) {
                break;
            }
        }
        let r = 1.0 / libm::sqrt(w64);
        if r < lo {
            lo
        } else if r > hi {
            hi
        } else {
            r
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq. 12 over spheres in f64, written from the formula: the independent computation.
    fn f(t: &SphereTerms, w: f64) -> f64 {
        let e = (1.0 - w * t.m) * (1.0 - w * t.m) + w * w * t.q;
        t.h * libm::sqrt(e) + t.v * libm::pow(w, -1.5)
    }

    /// Its minimum by bisection on the sign of a central difference of `f`, then refined by
    /// bisection on the exact derivative `h slope / sqrt(e) - 1.5 v w^-2.5` (not `g`).
    fn reference_radius(t: &SphereTerms, lo: f64, hi: f64) -> f64 {
        let slope = |w: f64| {
            let e = (1.0 - w * t.m) * (1.0 - w * t.m) + w * w * t.q;
            let s = w * (t.m * t.m + t.q) - t.m;
            t.h * s / libm::sqrt(e) - 1.5 * t.v * libm::pow(w, -2.5)
        };
        let (mut a, mut b) = (1.0 / (hi * hi), 1.0 / (lo * lo));
        if slope(a) >= 0.0 {
            return hi;
        }
        if slope(b) <= 0.0 {
            return lo;
        }
        loop {
            let mid = 0.5 * (a + b);
            if mid <= a || mid >= b {
                break;
            }
            if slope(mid) < 0.0 {
                a = mid;
            } else {
                b = mid;
            }
        }
        1.0 / libm::sqrt(0.5 * (a + b))
    }

    #[test]
    fn the_radius_is_the_minimum_to_f64_precision() {
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (lo, hi) = (0.05, 3.0);
        let mut interior = 0;
        for i in 0..2000 {
            // m near 1 (q' are in units of the RMS radius), q from a perfect sphere (0) to
            // a spread-out blob, v over six decades, alpha the paper's and others.
            let m = 0.8 + 0.4 * next();
            let q = if i % 10 == 0 {
                0.0
            } else {
                2.0 * next() * next()
            };
            let v = libm::pow(10.0, -6.0 + 6.0 * next());
            let h = 0.5 * [0.8, 0.5, 0.95][i % 3];
            let t = SphereTerms::new(m, q, v, h);
            let got = t.optimal_radius(lo, hi);
            let want = reference_radius(&t, lo, hi);
            assert!(
                (got - want).abs() <= 1e-12 * want,
                "{i}: {got} vs {want} ({m} {q} {v} {h})"
            );
            // A minimum indeed: no better radius nearby (the reference's own check).
            let w = 1.0 / (got * got);
            assert!(f(&t, w) <= f(&t, w * (1.0 + 1e-6)) && f(&t, w) <= f(&t, w * (1.0 - 1e-6)));
            interior += usize::from(got > lo && got < hi);
        }
        assert!(interior > 1500, "{interior}");
    }

    #[test]
    fn degenerate_terms_give_a_bound_or_the_residual_minimum() {
        // No residual term: the smallest sphere.
        assert_eq!(
            SphereTerms::new(1.0, 0.5, 1e-3, 0.0).optimal_radius(0.05, 3.0),
            0.05
        );
        // No points' spread at all: the same.
        assert_eq!(
            SphereTerms::new(0.0, 0.0, 1e-3, 0.4).optimal_radius(0.05, 3.0),
            0.05
        );
        // No volume term: w = m / (m^2 + q).
        let r = SphereTerms::new(1.0, 0.25, 0.0, 0.4).optimal_radius(0.05, 3.0);
        assert!((r - libm::sqrt(1.25)).abs() < 1e-12 * r, "{r}");
        // A huge volume term pushes to the smallest radius; a negligible one and a box that
        // excludes the residual's minimum, to the largest.
        assert_eq!(
            SphereTerms::new(1.0, 0.5, 1e9, 0.4).optimal_radius(0.05, 3.0),
            0.05
        );
        assert_eq!(
            SphereTerms::new(1.0, 0.5, 1e-9, 0.4).optimal_radius(0.05, 0.5),
            0.5
        );
    }
}
