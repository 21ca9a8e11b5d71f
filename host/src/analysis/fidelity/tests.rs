//! The sampler and the areas against independent quadratures; determinism over thread counts.

use super::surface::{self, Patch};
use super::*;

/// Area of `(a sin t cos f, b sin t sin f, c cos t)` where `keep` holds, by the midpoint rule
/// on an `n x 2n` grid of (t, f) with the parametric area element `|r_t x r_f|`: independent
/// of the sphere mapping and of Carlson's integrals.
fn parametric_area(r: [f64; 3], n: usize, keep: &dyn Fn([f64; 3]) -> bool) -> f64 {
    let [a, b, c] = r;
    let (dt, df) = (
        std::f64::consts::PI / n as f64,
        std::f64::consts::PI / n as f64,
    );
    let mut area = 0.0;
    for i in 0..n {
        let t = (i as f64 + 0.5) * dt;
        let (st, ct) = t.sin_cos();
        for k in 0..2 * n {
            let f = (k as f64 + 0.5) * df;
            let (sf, cf) = f.sin_cos();
            let p = [a * st * cf, b * st * sf, c * ct];
            if keep(p) {
                let element = st
                    * (b * b * c * c * st * st * cf * cf
                        + a * a * c * c * st * st * sf * sf
                        + a * a * b * b * ct * ct)
                        .sqrt();
                area += element * dt * df;
            }
        }
    }
    area
}

/// Areas of the ten equal slabs of x over `[-a, a]` and of z over `[-c, c]`, by the same
/// midpoint rule as [`parametric_area`].
fn parametric_slabs(r: [f64; 3], n: usize) -> [[f64; 10]; 2] {
    let [a, b, c] = r;
    let d = std::f64::consts::PI / n as f64;
    let mut slabs = [[0.0; 10]; 2];
    for i in 0..n {
        let t = (i as f64 + 0.5) * d;
        let (st, ct) = t.sin_cos();
        for k in 0..2 * n {
            let (sf, cf) = ((k as f64 + 0.5) * d).sin_cos();
            let element = st
                * (b * b * c * c * st * st * cf * cf
                    + a * a * c * c * st * st * sf * sf
                    + a * a * b * b * ct * ct)
                    .sqrt()
                * d
                * d;
            for (slab, u) in slabs.iter_mut().zip([st * cf, ct]) {
                slab[(((u + 1.0) * 5.0) as usize).min(9)] += element;
            }
        }
    }
    slabs
}

#[test]
fn carlson_areas_match_closed_forms_quadrature_and_thomsen() {
    let pi = std::f64::consts::PI;
    assert!((surface::ellipsoid_area(2.0, 2.0, 2.0) / (16.0 * pi) - 1.0).abs() < 1e-14);
    assert!((surface::ellipse_perimeter(3.0, 3.0) / (6.0 * pi) - 1.0).abs() < 1e-14);
    // A flat disc of radius 1 has area 2 pi (both faces); a needle tends to pi^2 a b.
    assert!((surface::ellipsoid_area(1.0, 1.0, 1e-9) / (2.0 * pi) - 1.0).abs() < 1e-6);
    // Degenerate ellipse: a segment of length 2a has perimeter 4a.
    assert!((surface::ellipse_perimeter(1.5, 0.0) / 6.0 - 1.0).abs() < 1e-14);
    for r in [
        [1.0, 0.1, 0.01],
        [3.0, 2.0, 1.0],
        [0.2, 0.5, 0.21],
        [1.0, 1.0, 0.3],
    ] {
        let exact = surface::ellipsoid_area(r[0], r[1], r[2]);
        let quadrature = parametric_area(r, 1500, &|_| true);
        assert!(
            (exact / quadrature - 1.0).abs() < 1e-5,
            "{r:?}: {exact} vs {quadrature}"
        );
        let thomsen = surface::thomsen_area(r[0], r[1], r[2]);
        assert!(
            (exact / thomsen - 1.0).abs() < 0.0107,
            "{r:?}: {exact} vs {thomsen}"
        );
    }
    for (a, b) in [(1.0, 0.01), (2.0, 1.0), (0.3, 0.7)] {
        // The periodic trapezoid rule converges geometrically for the perimeter integrand.
        let n = 20_000;
        let trapezoid: f64 = (0..n)
            .map(|i| {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                (a * a * t.sin().powi(2) + b * b * t.cos().powi(2)).sqrt()
            })
            .sum::<f64>()
            * std::f64::consts::TAU
            / n as f64;
        let exact = surface::ellipse_perimeter(a, b);
        assert!(
            (exact / trapezoid - 1.0).abs() < 1e-9,
            "{a} {b}: {exact} vs {trapezoid}"
        );
    }
}

/// Fractions of `samples` in ten equal slabs of coordinate `axis` over `[-r, r]`.
fn slab_fractions(samples: &[[f64; 3]], axis: usize, r: f64) -> [f64; 10] {
    let mut counts = [0.0; 10];
    for p in samples {
        let bin = (((p[axis] / r + 1.0) * 5.0) as usize).min(9);
        counts[bin] += 1.0;
    }
    counts.map(|c| c / samples.len() as f64)
}

#[test]
fn ellipsoid_samples_are_uniform_by_area_on_a_flat_needle() {
    let r = [1.0, 0.1, 0.01];
    let patch = Patch::Ellipsoid { semi_axes: r };
    let n = 400_000;
    let samples = patch.sample(n, &mut Pcg32::seed_from_u64(11));
    // Every sample lies on the surface.
    for p in samples.iter().step_by(97) {
        let s: f64 = (0..3).map(|j| (p[j] / r[j]).powi(2)).sum();
        assert!((s - 1.0).abs() < 1e-12, "{p:?}");
    }
    // The naive map of a uniform sphere (no rejection) must be told apart by the same check.
    let mut rng = Pcg32::seed_from_u64(12);
    let naive: Vec<[f64; 3]> = (0..n)
        .map(|_| {
            let z = 2.0 * surface::uniform(&mut rng) - 1.0;
            let t = std::f64::consts::TAU * surface::uniform(&mut rng);
            let rho = (1.0 - z * z).sqrt();
            [r[0] * rho * t.cos(), r[1] * rho * t.sin(), r[2] * z]
        })
        .collect();
    // Exact slab areas in one pass of the quadrature: bins of x, then bins of z.
    let slabs = parametric_slabs(r, 2000);
    let total: f64 = slabs[0].iter().sum();
    let mut naive_worst: f64 = 0.0;
    for (k, axis) in [0, 2].into_iter().enumerate() {
        let got = slab_fractions(&samples, axis, r[axis]);
        let naive_got = slab_fractions(&naive, axis, r[axis]);
        for bin in 0..10 {
            let want = slabs[k][bin] / total;
            let sigma = (want * (1.0 - want) / n as f64).sqrt();
            assert!(
                (got[bin] - want).abs() < 5.0 * sigma + 2e-4,
                "axis {axis} slab {bin}: {} sampled vs {want} exact",
                got[bin]
            );
            naive_worst = naive_worst.max((naive_got[bin] - want).abs() / sigma);
        }
    }
    assert!(
        naive_worst > 20.0,
        "the check cannot see a non-uniform sampler: {naive_worst}"
    );
    // The mean of a smooth function, x^2 + 100 y^2: sampled against quadrature.
    let f = |p: [f64; 3]| p[0] * p[0] + 100.0 * p[1] * p[1];
    let sampled = samples.iter().map(|&p| f(p)).sum::<f64>() / n as f64;
    let (mut weighted, n_q) = (0.0, 2000);
    let (dt, df) = (
        std::f64::consts::PI / n_q as f64,
        std::f64::consts::PI / n_q as f64,
    );
    for i in 0..n_q {
        let t = (i as f64 + 0.5) * dt;
        let (st, ct) = t.sin_cos();
        for k in 0..2 * n_q {
            let ph = (k as f64 + 0.5) * df;
            let (sf, cf) = ph.sin_cos();
            let p = [r[0] * st * cf, r[1] * st * sf, r[2] * ct];
            let [a, b, c] = r;
            let element = st
                * (b * b * c * c * st * st * cf * cf
                    + a * a * c * c * st * st * sf * sf
                    + a * a * b * b * ct * ct)
                    .sqrt();
            weighted += f(p) * element * dt * df;
        }
    }
    let exact = weighted / total;
    assert!((sampled / exact - 1.0).abs() < 3e-3, "{sampled} vs {exact}");
}

#[test]
fn cylinder_and_plane_samples_cover_their_cut_surfaces_uniformly() {
    let cylinder = Patch::Cylinder {
        axes: [0, 2],
        semi_axes: [1.0, 0.05],
        axis: 1,
        extent: [-0.5, 2.0],
    };
    let n = 200_000;
    let samples = cylinder.sample(n, &mut Pcg32::seed_from_u64(3));
    // Uniform by arc length: the share with |x| > 0.5 is its share of the perimeter.
    let m = 200_000;
    let (mut part, mut all) = (0.0, 0.0);
    for i in 0..m {
        let t = std::f64::consts::TAU * (i as f64 + 0.5) / m as f64;
        let ds = (t.sin().powi(2) + 0.05f64.powi(2) * t.cos().powi(2)).sqrt();
        all += ds;
        if t.cos().abs() > 0.5 {
            part += ds;
        }
    }
    let got = samples.iter().filter(|p| p[0].abs() > 0.5).count() as f64 / n as f64;
    let want = part / all;
    assert!(
        (got - want).abs() < 5.0 * (want * (1.0 - want) / n as f64).sqrt(),
        "{got} vs {want}"
    );
    assert!(samples.iter().all(|p| (-0.5..=2.0).contains(&p[1])));
    assert!((cylinder.area() / (2.5 * surface::ellipse_perimeter(1.0, 0.05)) - 1.0).abs() < 1e-15);
    let planes = Patch::PlanePair {
        normal: 2,
        semi_axis: 0.25,
        axes: [0, 1],
        extents: [[0.0, 1.0], [-3.0, -1.0]],
    };
    assert_eq!(planes.area(), 4.0);
    let samples = planes.sample(10_000, &mut Pcg32::seed_from_u64(4));
    let upper = samples.iter().filter(|p| p[2] == 0.25).count();
    assert!(
        samples
            .iter()
            .all(|p| p[2].abs() == 0.25 && (-3.0..=-1.0).contains(&p[1]))
    );
    assert!((upper as f64 / 10_000.0 - 0.5).abs() < 0.025, "{upper}");
}

fn toy_map() -> (Vec<[f64; 3]>, Vec<Entity>) {
    let degeneration = mema_core::Degeneration::default();
    let entities = vec![
        Entity::from_semi_axes(Point3::new(0.0, 0.0, 0.0), [1.0, 0.5, 0.2], &degeneration),
        Entity::from_semi_axes(Point3::new(5.0, 0.0, 0.0), [0.3, 9.0, 0.3], &degeneration),
        Entity::from_semi_axes(Point3::new(0.0, 6.0, 0.0), [9.0, 9.0, 0.1], &degeneration),
        Entity::from_semi_axes(
            Point3::new(0.0, -9.0, 0.0),
            [0.002, 0.002, 0.002],
            &degeneration,
        ),
    ];
    let points: Vec<[f64; 3]> = (0..3000)
        .map(|i| {
            let t = i as f64 * 0.618_034;
            match i % 3 {
                0 => [t.cos(), 0.5 * t.sin(), 0.0],
                1 => [5.0 + 0.3 * t.cos(), (t % 2.0) - 0.5, 0.3 * t.sin()],
                _ => [(t % 1.5) - 1.0, 6.0 + (t % 0.7), 0.1],
            }
        })
        .collect();
    (points, entities)
}

#[test]
fn samples_follow_own_points_and_ignore_the_thread_count() {
    let (points, entities) = toy_map();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| {
                (
                    surface_samples(&points, &entities, 9, 5_000),
                    two_way_score(&points, &entities, 9, 5_000).expect("score"),
                )
            })
    };
    let (one, score_one) = run(1);
    let (two, score_two) = run(2);
    assert_eq!(one, two);
    assert_eq!(score_one, score_two);
    // Entity 3 has no points of its own and still gets its minimum.
    assert_eq!(
        one.iter().filter(|s| s.entity == 3).count(),
        MIN_SAMPLES_PER_ENTITY
    );
    // The pseudocylinder (y infinite) is cut to its points' y range, the plane pair to theirs.
    let ys = |e: u32| {
        one.iter()
            .filter(|s| s.entity == e)
            .map(|s| s.point[1])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), y| {
                (lo.min(y), hi.max(y))
            })
    };
    let (lo, hi) = ys(1);
    assert!(
        lo >= -0.5 - 1e-9 && hi <= 1.5 + 1e-9 && hi - lo > 1.9,
        "{lo} {hi}"
    );
    let (lo, hi) = ys(2);
    assert!(
        lo >= 6.0 - 1e-9 && hi <= 6.7 + 1e-9 && hi - lo > 0.6,
        "{lo} {hi}"
    );
    // Weights add up to each entity's area.
    let patches = patches(&points, &entities);
    for (i, patch) in patches.iter().enumerate() {
        let w: f64 = one
            .iter()
            .filter(|s| s.entity == i as u32)
            .map(|s| s.weight)
            .sum();
        assert!((w / patch.area() - 1.0).abs() < 1e-12, "entity {i}");
    }
}

#[test]
fn quantiles_and_empty_inputs() {
    let equal: Vec<(f64, f64)> = (1..=100).map(|i| (i as f64, 1.0)).collect();
    assert_eq!(weighted_quantile(equal, 0.95), 95.0);
    assert_eq!(weighted_quantile(vec![(1.0, 1.0), (2.0, 9.0)], 0.5), 2.0);
    assert_eq!(weighted_quantile(vec![], 0.95), 0.0);
    assert_eq!(median(&[3.0, 1.0, 2.0, 10.0]), 2.5);
    let (points, entities) = toy_map();
    assert!(two_way_score(&[], &entities, 0, 10).is_err());
    assert!(two_way_score(&points, &[], 0, 10).is_err());
}

#[test]
fn oriented_entities_are_sampled_on_their_turned_surfaces() {
    let degeneration = mema_core::Degeneration::default();
    let turn = mema_core::Rotation::from_quaternion([0.3, -0.5, 0.2, 0.8]).expect("unit");
    let entities = vec![
        Entity::from_semi_axes(Point3::new(1.0, 2.0, 3.0), [1.0, 0.5, 0.2], &degeneration)
            .with_rotation(turn),
        Entity::from_semi_axes(Point3::new(-4.0, 0.0, 1.0), [0.3, 9.0, 0.3], &degeneration)
            .with_rotation(turn),
    ];
    // The cloud lies on both surfaces: on the ellipsoid, and on the cylinder for |y| <= 1.
    let points: Vec<[f64; 3]> = (0..4000)
        .map(|i| {
            let (t, u) = (i as f64 * 0.618_034, i as f64 * 0.137);
            if i % 2 == 0 {
                let (z, rho) = (u.sin(), u.cos());
                entities[0].to_world([rho * t.cos(), 0.5 * rho * t.sin(), 0.2 * z])
            } else {
                entities[1].to_world([0.3 * t.cos(), (u % 2.0) - 1.0, 0.3 * t.sin()])
            }
        })
        .collect();
    for s in surface_samples(&points, &entities, 3, 20_000) {
        let e = &entities[s.entity as usize];
        let d = surface_distance(e, s.point);
        assert!(d < 1e-6, "entity {}: {d}", s.entity);
        // The cylinder is cut to its own points along its (turned) axis.
        if s.entity == 1 {
            assert!(e.to_local(s.point)[1].abs() <= 1.0 + 1e-6);
        }
    }
    let score = two_way_score(&points, &entities, 3, 20_000).expect("score");
    assert!(score.accuracy.max < 1e-5, "{:?}", score.accuracy);
    assert!(score.completeness.mean < 0.05, "{:?}", score.completeness);
}
