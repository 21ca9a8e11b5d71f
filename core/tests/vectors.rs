//! The core against the independent f64 vectors in `../shared/vectors` (see its README.md).

use mema_core::Point3;
use mema_core::closest_point::distance_to_surface;
use mema_core::fit::{FitParams, fit_ellipsoid_paper, fit_sphere_paper};
use mema_core::fitness::{FitnessTerms, VolumeTerm};
use mema_core::moments::Moments;
use mema_core::rng::stream_rng;
use std::path::PathBuf;

fn vectors() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/vectors")
}

#[test]
fn closest_point_matches_every_vector() {
    let text =
        std::fs::read_to_string(vectors().join("closest_point.csv")).expect("vectors present");
    let mut rows = 0;
    let mut worst = 0.0f64;
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("rx"))
    {
        let v: Vec<f64> = line
            .split(',')
            .map(|s| s.trim().parse().expect("number"))
            .collect();
        let (axes, point, want) = ([v[0], v[1], v[2]], [v[3], v[4], v[5]], v[6]);
        let got = distance_to_surface(axes, point);
        // Relative to the distance, or to the smallest semi-axis for points on the surface.
        let scale = want.max(1e-6 * axes.iter().cloned().fold(f64::INFINITY, f64::min));
        let err = (got - want).abs() / scale;
        worst = worst.max(err);
        assert!(err <= 1e-9, "row {rows}: {line}: got {got}");
        rows += 1;
    }
    assert_eq!(rows, 880);
    eprintln!("closest point: worst relative error {worst:.2e} over {rows} rows");
}

#[test]
fn fitness_from_moments_matches_every_vector() {
    let text = std::fs::read_to_string(vectors().join("fitness.json")).expect("vectors present");
    let doc: serde_json::Value = serde_json::from_str(&text).expect("json");
    let cases = doc["cases"].as_array().expect("cases");
    assert_eq!(cases.len(), 40);
    let mut worst = 0.0f64;
    for (i, case) in cases.iter().enumerate() {
        let centre: Vec<f64> = case["centre"]
            .as_array()
            .expect("centre")
            .iter()
            .map(|v| v.as_f64().expect("f64"))
            .collect();
        // As the map does: points moved to a local origin (the patch mean), then stored as f32.
        let mut moments = Moments::new();
        for p in case["points"].as_array().expect("points") {
            let p: Vec<f64> = p
                .as_array()
                .expect("xyz")
                .iter()
                .map(|v| v.as_f64().expect("f64"))
                .collect();
            let local = Point3::new(
                (p[0] - centre[0]) as f32,
                (p[1] - centre[1]) as f32,
                (p[2] - centre[2]) as f32,
            );
            moments.add(local);
        }
        let central = moments.central().expect("points");
        let alpha = case["alpha"].as_f64().expect("alpha");
        let terms = FitnessTerms::new(&central, alpha, VolumeTerm::Exact);
        let axes: Vec<f64> = case["semi_axes"]
            .as_array()
            .expect("axes")
            .iter()
            .map(|v| v.as_f64().expect("f64"))
            .collect();
        let want = case["fitness"].as_f64().expect("fitness");
        let got = terms.fitness(&[axes[0], axes[1], axes[2]]);
        let err = (got - want).abs() / want;
        assert!(err <= 1e-4, "case {i} ({}): {got} vs {want}", case["cloud"]);
        let want_sphere = case["sphere_fitness"].as_f64().expect("sphere fitness");
        let got_sphere = terms.sphere_fitness(case["sphere_radius"].as_f64().expect("radius"));
        let err_sphere = (got_sphere - want_sphere).abs() / want_sphere;
        assert!(
            err_sphere <= 1e-4,
            "case {i} sphere: {got_sphere} vs {want_sphere}"
        );
        worst = worst.max(err).max(err_sphere);
        // The fitted entity is never worse than the vector's semi-axes by more than DE's reach,
        // and the seeded ellipsoid never loses to the one-radius fit.
        let params = FitParams {
            alpha,
            ..FitParams::default()
        };
        let ellipsoid = fit_ellipsoid_paper(&central, &params, &mut stream_rng(0, i as u64));
        let sphere = fit_sphere_paper(&central, &params, &mut stream_rng(0, i as u64));
        assert!(
            ellipsoid.fitness <= sphere.fitness * (1.0 + 1e-9),
            "case {i}"
        );
    }
    eprintln!("fitness: worst relative error {worst:.2e} over 40 cases");
}
