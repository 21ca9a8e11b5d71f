//! Acceptance 1: eq. 12 from moments equals the direct per-point f64 sum on real clusters.

use crate::util::shared_data;
use mema::io::load_cloud;
use mema::mapping::pipeline;
use mema_core::fit::FitParams;
use mema_core::fitness::FitnessTerms;
use mema_core::kmeans::KMeansParams;

/// Eq. 12 by a direct pass over the points in f64, centre = their mean: no moments involved.
fn direct_fitness(points: &[[f64; 3]], alpha: f64, r: [f64; 3]) -> f64 {
    let n = points.len() as f64;
    let mut c = [0.0; 3];
    for p in points {
        for j in 0..3 {
            c[j] += p[j];
        }
    }
    let c = c.map(|v| v / n);
    let mut sum = 0.0;
    for p in points {
        let s: f64 = (0..3)
            .map(|j| (p[j] - c[j]) * (p[j] - c[j]) / (r[j] * r[j]))
            .sum();
        let g = 0.5 * (1.0 - s);
        sum += g * g;
    }
    alpha * (sum / n).sqrt()
        + (1.0 - alpha) * 4.0 / 3.0 * std::f64::consts::PI * r[0] * r[1] * r[2] / n
}

#[test]
fn fitness_from_moments_equals_direct_sum_on_every_readable_cloud() {
    let mut clouds = 0;
    let mut checked = 0;
    let mut worst = (0.0f64, String::new());
    let mut names: Vec<_> = std::fs::read_dir(shared_data())
        .expect("shared data")
        .map(|e| e.expect("entry").path())
        .collect();
    names.sort();
    for path in names {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        if !["ply", "pcd", "xyz", "csv"].contains(&ext) {
            continue; // LAS/LAZ come with the toolbox issue; SOURCES.md is not a cloud.
        }
        let cloud = load_cloud(&path).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        let n = cloud.points.len();
        let k = (n / 200).clamp(10, 100);
        let params = KMeansParams {
            max_iterations: 15,
            ..KMeansParams::default()
        };
        let clusters = pipeline::cluster(&cloud.points, k, &params).expect("clusters");
        let fit = FitParams::default();
        let fitted = pipeline::fit_all(&clusters.moments, 0, &fit);
        let mut members: Vec<Vec<[f64; 3]>> = vec![Vec::new(); k];
        for (p, &l) in cloud.points.iter().zip(clusters.labels.iter()) {
            members[l as usize].push(p.to_f64());
        }
        for (i, pts) in members.iter().enumerate() {
            let terms = FitnessTerms::new(&clusters.moments[i], fit.alpha, fit.volume);
            let fitted_axes = fitted.ellipsoids[i].semi_axes;
            let sphere = fitted.spheres[i].semi_axes;
            let skewed = [
                fitted_axes[0] * 1.3,
                fitted_axes[1] * 0.8,
                fitted_axes[2] * 1.1,
            ];
            for r in [fitted_axes, sphere, skewed] {
                let want = direct_fitness(pts, fit.alpha, r);
                let got = terms.fitness(&r);
                let rel = (got - want).abs() / want;
                if rel > worst.0 {
                    worst = (
                        rel,
                        format!("{} cluster {i} ({} points)", path.display(), pts.len()),
                    );
                }
                assert!(
                    rel <= 1e-4,
                    "{} cluster {i}: moments {got} vs direct {want}",
                    path.display()
                );
                checked += 1;
            }
        }
        clouds += 1;
    }
    assert!(clouds >= 9, "only {clouds} clouds read");
    eprintln!(
        "fitness: {checked} evaluations on {clouds} clouds, worst relative error {:.2e} at {}",
        worst.0, worst.1
    );
}
