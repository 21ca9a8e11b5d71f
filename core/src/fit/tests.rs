use super::*;
use crate::moments::Moments;
use crate::rng::stream_rng;
use crate::test_support::{OrFail, TestResult};

fn shell(axes: [f64; 3], n: usize) -> Result<CentralMoments, &'static str> {
    let mut m = Moments::new();
    let golden = core::f64::consts::PI * (3.0 - libm::sqrt(5.0));
    for i in 0..n {
        // Fibonacci sphere: near-uniform directions without randomness.
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let rho = libm::sqrt(1.0 - z * z);
        let t = golden * i as f64;
        m.add_f64([
            2.0 + axes[0] * rho * libm::cos(t),
            -1.0 + axes[1] * rho * libm::sin(t),
            0.5 + axes[2] * z,
        ]);
    }
    m.central().or_fail("points")
}

#[test]
fn recovers_the_semi_axes_of_a_sampled_ellipsoid() -> TestResult {
    let axes = [0.3, 0.2, 0.1];
    let moments = shell(axes, 2000)?;
    // 50 generations of 10 from random starts get close, not exact; the seeded start is exact.
    for (init, tolerance) in [
        (Initialisation::Random, 0.1),
        (Initialisation::MomentSeeded, 0.01),
    ] {
        let params = FitParams {
            initialisation: init,
            ..FitParams::default()
        };
        let fit = fit_ellipsoid_paper(&moments, &params, &mut stream_rng(0, 0));
        // The streaming mapper's entity-only fit is the same entity, bit for bit.
        let entity = fit_entity_paper(&moments, &params, &mut stream_rng(0, 0));
        assert_eq!(entity, fit.entity);
        for (got, want) in fit.semi_axes.iter().zip(axes.iter()) {
            assert!(
                (got - want).abs() < tolerance * want,
                "{init:?}: {:?}",
                fit.semi_axes
            );
        }
    }
    // The least-squares candidate alone is exact here.
    let seeded = least_squares_semi_axes(&moments, 0.0, 10.0).or_fail("solvable")?;
    for (got, want) in seeded.iter().zip(axes.iter()) {
        assert!((got - want).abs() < 1e-3 * want, "{seeded:?}");
    }
    Ok(())
}

#[test]
fn sphere_fit_finds_the_radius_and_never_beats_the_seeded_ellipsoid() -> TestResult {
    let moments = shell([0.25, 0.25, 0.25], 1000)?;
    let params = FitParams::default();
    let sphere = fit_sphere_paper(&moments, &params, &mut stream_rng(0, 1));
    assert!(
        (sphere.semi_axes[0] - 0.25).abs() < 1e-3,
        "{:?}",
        sphere.semi_axes
    );
    let ellipsoid = fit_ellipsoid_paper(&moments, &params, &mut stream_rng(0, 1));
    assert!(ellipsoid.fitness <= sphere.fitness * (1.0 + 1e-9));
    Ok(())
}

#[test]
fn a_cylinder_patch_degenerates_under_threshold_bounds() -> TestResult {
    // Points on a cylinder of radius 0.2 along z, 1 m long: the fit wants r_z infinite.
    let mut m = Moments::new();
    for i in 0..400 {
        let t = i as f64 * 0.157;
        let z = (i % 20) as f64 * 0.05 - 0.5;
        m.add_f64([0.2 * libm::cos(t), 0.2 * libm::sin(t), z]);
    }
    let moments = m.central().or_fail("points")?;
    let threshold_box = FitParams {
        bounds: SemiAxisBounds::Threshold { lower: 0.05 },
        ..FitParams::default()
    };
    let fit = fit_ellipsoid_paper(&moments, &threshold_box, &mut stream_rng(1, 0));
    assert_eq!(
        fit.entity.kind(0.01),
        crate::geometry::EntityKind::Pseudocylinder,
        "{:?}",
        fit.semi_axes
    );
    assert_eq!(fit.entity.weights[2], 0.0);
    let spread_params = FitParams {
        bounds: SemiAxisBounds::Spread {
            lower: 0.05,
            upper: 3.0,
        },
        ..FitParams::default()
    };
    // The spread box caps the axis at 3 s: nothing degenerates, and the long axis is z. (Where
    // in the box it ends is DE's luck: 50 generations do not settle this flat valley, and the
    // runs of six streams end between 0.72 and the bound, 1.05.)
    let spread = fit_ellipsoid_paper(&moments, &spread_params, &mut stream_rng(1, 0));
    let s = moments.rms_radius();
    assert!(
        spread.entity.weights.iter().all(|&w| w > 0.0)
            && spread.semi_axes[2] <= 3.0 * s * (1.0 + 1e-6)
            && spread.semi_axes[2] > 2.0 * spread.semi_axes[0].max(spread.semi_axes[1]),
        "{:?}",
        spread.semi_axes
    );
    Ok(())
}
