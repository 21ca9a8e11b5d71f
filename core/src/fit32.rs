//! Eq. 12 in single precision without cancellation (the DE that searches it: [`crate::de32`]).
//!
//! Why: a Cortex-M4F has an FPU for f32 only, so every f64 operation of a fit is a software
//! routine of tens of instructions, and a DE fit evaluates eq. 12 510 times. The raw moment form
//! `1 - 2 w.E[q] + w^T E[q q^T] w` cannot simply be narrowed: its terms are O(1) and a good fit
//! makes their sum small, so f32 loses the 1e-4 agreement with a direct sum.
//!
//! The form evaluated here has no such difference. With `m = E[q]` and `C = Cov(q)`,
//! `E[g^2] = ((1 - w.m)^2 + w^T C w) / 4`, and `C` is positive semi-definite, so `w^T C w =
//! |L^T w|^2` with `C = L L^T`. `C` and its Cholesky factor are computed once per fit in f64,
//! from the central moments; each evaluation is then a sum of four squares of short f32 dot
//! products, whose rounding error is relative to the square root of each term, not to the
//! O(1) terms the raw form subtracts. Near a perfect fit the residual then carries about 1e-8
//! absolute error, as the f64 raw form already did.
//!
//! Everything is expressed in units of the cluster's RMS radius `s` (`r' = r / s`), so the
//! numbers a fit sees are O(1) whatever the cloud's unit and f32's range is never a concern.

mod sphere;

use crate::fitness::FitnessTerms;
pub use sphere::{SphereEstimate, SphereTerms};

/// The correctly rounded square root of an f32: the FPU's VSQRT on a hard-float ARM core,
/// `libm::sqrtf` elsewhere (SSE's `sqrtss` on x86-64, or libm's own exact routine). Both are
/// IEEE-754's square root, correctly rounded, so every target computes the same bits.
///
/// Why not `libm::sqrtf` on the Cortex-M4F too: libm has no ARM32 path, so it is a software
/// routine of a few hundred instructions, where the FPU has the instruction (and `core` has no
/// stable `f32::sqrt`). Before, a bit-pattern guess and three Newton steps (three divisions)
/// stood in for it, within two ulps.
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[allow(unsafe_code)]
#[inline(always)]
pub fn sqrt32(x: f32) -> f32 {
    let root: u32;
    // SAFETY: VSQRT.F32 exists on every hard-float ARM FPU (the eabihf ABI implies one) and
    // reads and writes only the registers named here. Rust's asm cannot take an S register as
    // an operand on a single-precision FPU (its `sreg` class requires `vfp2`, which includes
    // double precision), so the value travels through a core register and s15 is saved in a
    // core register and restored before the block ends: no register but the operands
    // changes, and no memory or stack is touched. The FPSCR's cumulative exception flags may
    // change, as after any float operation, hence no `preserves_flags`.
    unsafe {
        core::arch::asm!(
            "vmov {saved}, s15",
            "vmov s15, {v}",
            "vsqrt.f32 s15, s15",
            "vmov {v}, s15",
            "vmov s15, {saved}",
            v = inout(reg) x.to_bits() => root,
            saved = out(reg) _,
            options(pure, nomem, nostack),
        );
    }
    f32::from_bits(root)
}

/// The correctly rounded square root of an f32 (see the hard-float ARM version above).
#[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
#[inline(always)]
pub fn sqrt32(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// Eq. 12 for semi-axes in units of `s`, ready for f32 evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fitness32 {
    /// `alpha / 2`: eq. 12's residual is `sqrt(E[g^2]) = sqrt(4 E[g^2]) / 2`.
    half_alpha: f32,
    /// `E[q'] = E[d^2] / s^2`.
    mean_q: [f32; 3],
    /// Lower-triangular `L` of `Cov(q') = L L^T`, by rows: `l00, l10, l11, l20, l21, l22`.
    chol: [f32; 6],
    /// Multiplies `r'_x r'_y r'_z` (the volume term is in the cloud's units: `s^3` folded in).
    volume_scale: f32,
    /// Eq. 12 restricted to spheres, in f64 ([`Fitness32::optimal_sphere`]).
    sphere: SphereTerms,
}

/// The Cholesky factor of a symmetric positive semi-definite 3x3 matrix given by its lower
/// triangle (`c00, c10, c11, c20, c21, c22`), by rows. A pivot that rounding made zero or
/// negative leaves its column zero, the factor of the nearest PSD matrix with that column's
/// variance gone (a coplanar cluster, two points).
fn cholesky_psd([c00, c10, c11, c20, c21, c22]: [f64; 6]) -> [f64; 6] {
    let root = |v: f64| if v > 0.0 { libm::sqrt(v) } else { 0.0 };
    let over = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
    let l00 = root(c00);
    let l10 = over(c10, l00);
    let l20 = over(c20, l00);
    let l11 = root(c11 - l10 * l10);
    let l21 = over(c21 - l20 * l10, l11);
    let l22 = root(c22 - l20 * l20 - l21 * l21);
    [l00, l10, l11, l20, l21, l22]
}

/// `E[q']` and `E[q' q'^T]` of `q'_j = d_j^2 / s^2`, in f64: what a fit in units of `s` needs
/// of the cluster's moments (eq. 12's terms, and the least-squares candidate's system).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnitMoments {
    pub mean: [f64; 3],
    pub raw: [[f64; 3]; 3],
}

impl UnitMoments {
    /// From the f64 terms of one cluster whose RMS radius is `s > 0`.
    pub fn new(terms: &FitnessTerms, s: f64) -> Self {
        // Products by 1/s^2 and 1/s^4 rather than quotients: a division is about twice a
        // multiplication in the M4F's software f64, and this runs once per fit.
        let inv_s2 = 1.0 / (s * s);
        let inv_s4 = inv_s2 * inv_s2;
        let f = &terms.fourth;
        let (r10, r20, r21) = (f[1][0] * inv_s4, f[2][0] * inv_s4, f[2][1] * inv_s4);
        Self {
            mean: terms.second.map(|v| v * inv_s2),
            raw: [
                [f[0][0] * inv_s4, r10, r20],
                [r10, f[1][1] * inv_s4, r21],
                [r20, r21, f[2][2] * inv_s4],
            ],
        }
    }
}

impl Fitness32 {
    /// From the f64 terms of one cluster whose RMS radius is `s > 0`.
    pub fn new(terms: &FitnessTerms, s: f64) -> Self {
        Self::of_unit(&UnitMoments::new(terms, s), terms, s)
    }

    /// From the cluster's moments in units of `s` ([`UnitMoments::new`] of the same terms).
    pub fn of_unit(unit: &UnitMoments, terms: &FitnessTerms, s: f64) -> Self {
        let (mean, raw) = (unit.mean, &unit.raw);
        // Cov(q') = E[q' q'^T] - E[q'] E[q']^T, symmetric: its lower triangle, once per fit in f64.
        let cov = |j: usize, k: usize| raw[j][k] - mean[j] * mean[k];
        let lower = [
            cov(0, 0),
            cov(1, 0),
            cov(1, 1),
            cov(2, 0),
            cov(2, 1),
            cov(2, 2),
        ];
        let [c00, c10, c11, c20, c21, c22] = lower;
        let volume_scale = terms.volume_scale * (s * s * s);
        Self {
            sphere: SphereTerms::new(
                mean[0] + mean[1] + mean[2],
                // 1^T Cov 1: the variance of q'_x + q'_y + q'_z.
                (c00 + c11 + c22) + 2.0 * (c10 + c20 + c21),
                volume_scale,
                0.5 * terms.alpha,
            ),
            half_alpha: (0.5 * terms.alpha) as f32,
            mean_q: mean.map(|v| v as f32),
            chol: cholesky_psd(lower).map(|v| v as f32),
            volume_scale: volume_scale as f32,
        }
    }

    /// The radius, in units of `s` and within `[lo, hi]`, of the sphere minimising eq. 12
    /// ([`SphereTerms::optimal_radius`]).
    pub fn optimal_sphere(&self, lo: f64, hi: f64) -> f64 {
        self.sphere.optimal_radius(lo, hi)
    }

    /// Eq. 12 restricted to spheres, for the optimal sphere in two steps.
    pub fn sphere(&self) -> &SphereTerms {
        &self.sphere
    }

    /// Eq. 12 at semi-axes `r' = r / s`.
    #[inline]
    pub fn fitness(&self, r: &[f32; 3]) -> f32 {
        let w = r.map(|v| 1.0 / (v * v));
        let [l00, l10, l11, l20, l21, l22] = self.chol;
        let a = 1.0 - (w[0] * self.mean_q[0] + w[1] * self.mean_q[1] + w[2] * self.mean_q[2]);
        let b0 = l00 * w[0] + l10 * w[1] + l20 * w[2];
        let b1 = l11 * w[1] + l21 * w[2];
        let b2 = l22 * w[2];
        let four_mean_square = a * a + b0 * b0 + b1 * b1 + b2 * b2;
        self.half_alpha * sqrt32(four_mean_square) + self.volume_scale * (r[0] * r[1] * r[2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fitness::VolumeTerm;
    use crate::moments::Moments;
    use crate::test_support::{OrFail, TestResult};

    #[test]
    fn f32_fitness_agrees_with_the_f64_form_on_a_near_perfect_fit() -> TestResult {
        // A thin noisy shell, far from the origin: the raw form's hard case.
        let mut m = Moments::new();
        let mut state = 5u64;
        for i in 0..500 {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            let noise = ((state >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 1e-3;
            let (t, u) = (i as f64 * 0.37, i as f64 * 0.11);
            m.add_f64([
                100.0 + 0.3 * (1.0 + noise) * libm::cos(t) * libm::sin(u),
                -40.0 + 0.2 * libm::sin(t) * libm::sin(u),
                7.0 + 0.1 * libm::cos(u),
            ]);
        }
        let central = m.central().or_fail("points")?;
        let terms = FitnessTerms::new(&central, 0.8, VolumeTerm::Exact);
        let s = central.rms_radius();
        let fast = Fitness32::new(&terms, s);
        for r in [
            [0.3, 0.2, 0.1],
            [0.31, 0.19, 0.1],
            [0.5, 0.5, 0.5],
            [0.05, 2.0, 0.01],
        ] {
            let want = terms.fitness(&r);
            let got = f64::from(fast.fitness(&r.map(|v| (v / s) as f32)));
            // The semi-axes themselves are rounded to f32 (6e-8), which moves eq. 12 by a few
            // times that; the evaluation adds its own rounding on top, at the same level.
            if (got - want).abs() > 1e-5 * want + 1e-8 {
                return Err("f32 fitness differs from the f64 form");
            }
        }
        Ok(())
    }

    #[test]
    fn sqrt32_is_the_correctly_rounded_root() {
        // The f64 root of an f32 rounded to f32 is the correctly rounded f32 root (f64 carries
        // more than twice f32's 24 bits, so the double rounding is innocuous).
        let mut x = f32::from_bits(1);
        while x < f32::MAX / 3.2 {
            for m in [1.0f32, 1.3, 2.0, 2.9, 3.7] {
                let v = x * m;
                assert_eq!(sqrt32(v), libm::sqrt(f64::from(v)) as f32, "{v}");
            }
            x *= 3.1;
        }
        assert_eq!(sqrt32(0.0), 0.0);
        assert_eq!(sqrt32(f32::INFINITY), f32::INFINITY);
        assert!(sqrt32(-1.0).is_nan() && sqrt32(f32::NAN).is_nan());
    }

    #[test]
    fn cholesky_of_a_singular_matrix_reproduces_it() {
        // Rank one: the second and third pivots vanish.
        let v = [1.0, 2.0, -0.5];
        let c = [0, 1, 2].map(|j| [0, 1, 2].map(|k| v[j] * v[k]));
        let [l00, l10, l11, l20, l21, l22] =
            cholesky_psd([c[0][0], c[1][0], c[1][1], c[2][0], c[2][1], c[2][2]]);
        let l = [[l00, 0.0, 0.0], [l10, l11, 0.0], [l20, l21, l22]];
        for j in 0..3 {
            for k in 0..3 {
                let back: f64 = (0..3).map(|i| l[j][i] * l[k][i]).sum();
                assert!((back - c[j][k]).abs() < 1e-12, "{j} {k}");
            }
        }
        assert_eq!(cholesky_psd([0.0; 6]), [0.0; 6]);
    }
}
