//! Benchmark 1: eq. 12 from moments against the direct per-point sum, per evaluation and per
//! fit, on patches of five_people.pcd.

use anyhow::{Context, Result};
use mema_core::Point3;
use mema_core::de::PAPER_POPULATION;
use mema_core::fit::{FitParams, fit_ellipsoid_f64, fit_ellipsoid_paper};
use mema_core::fitness::FitnessTerms;
use mema_core::moments::Moments;
use mema_core::rng::stream_rng;

use super::{BenchOptions, fastest, load};

/// Eq. 12 by a pass over the points (f64, centre = their mean): what moments replace.
fn direct_fitness(points: &[[f64; 3]], mean: [f64; 3], alpha: f64, r: &[f64; 3]) -> f64 {
    let n = points.len() as f64;
    let w = r.map(|r| 1.0 / (r * r));
    let mut sum = 0.0;
    for p in points {
        let s: f64 = (0..3)
            .map(|j| (p[j] - mean[j]) * (p[j] - mean[j]) * w[j])
            .sum();
        let g = 0.5 * (1.0 - s);
        sum += g * g;
    }
    alpha * (sum / n).sqrt()
        + (1.0 - alpha) * 4.0 / 3.0 * std::f64::consts::PI * r[0] * r[1] * r[2] / n
}

pub(super) fn fitness(args: &BenchOptions) -> Result<()> {
    println!();
    println!(
        "1. fitness: eq. 12 from moments vs the direct per-point sum (five_people.pcd patches)"
    );
    println!(
        "{:>7} {:>13} {:>13} {:>8} {:>12} {:>13} {:>11} {:>11} {:>8}",
        "|S|",
        "direct ns/ev",
        "moments ns/ev",
        "ratio",
        "max rel diff",
        "moments us",
        "fit us",
        "f64 fit us",
        "speedup"
    );
    let cloud = load(&args.data, "five_people.pcd")?;
    let anchor = cloud.first().copied().context("empty cloud")?;
    let mut by_distance: Vec<Point3> = cloud.clone();
    by_distance.sort_by(|a, b| {
        a.distance_squared(anchor)
            .total_cmp(&b.distance_squared(anchor))
    });
    let params = FitParams::default();
    for size in [100usize, 1_000, 10_000] {
        let patch: Vec<[f64; 3]> = by_distance.iter().take(size).map(|p| p.to_f64()).collect();
        let (moments_time, central) = fastest(args.repeat, || {
            let mut m = Moments::new();
            for p in &patch {
                m.add_f64(*p);
            }
            m.central().context("empty patch")
        })?;
        let terms = FitnessTerms::new(&central, params.alpha, params.volume);
        let s = central.rms_radius();
        // Candidate semi-axes as DE would draw them: 0.2 s to 3 s per axis.
        let mut rng = stream_rng(1, 1);
        let candidates: Vec<[f64; 3]> = (0..1000)
            .map(|_| [0; 3].map(|_| s * (0.2 + 2.8 * mema_core::rng::uniform(&mut rng))))
            .collect();
        // Enough direct passes for about 2 M point visits, at least 20.
        let direct_evals = (2_000_000 / size).clamp(20, candidates.len());
        let (direct_time, direct_values) = fastest(args.repeat, || {
            Ok(candidates
                .iter()
                .take(direct_evals)
                .map(|r| {
                    direct_fitness(&patch, central.mean, params.alpha, std::hint::black_box(r))
                })
                .collect::<Vec<f64>>())
        })?;
        let moment_reps = 200;
        let (moment_time, moment_values) = fastest(args.repeat, || {
            let mut v = Vec::with_capacity(candidates.len());
            for _ in 0..moment_reps {
                v.clear();
                v.extend(
                    candidates
                        .iter()
                        .map(|r| terms.fitness(std::hint::black_box(r))),
                );
            }
            Ok(v)
        })?;
        let rel = direct_values
            .iter()
            .zip(moment_values.iter())
            .map(|(d, m)| ((d - m) / d).abs())
            .fold(0.0f64, f64::max);
        let fits = 200;
        let (fit_time, _) = fastest(args.repeat, || {
            let mut last = None;
            for i in 0..fits {
                last = Some(fit_ellipsoid_paper(
                    &central,
                    &params,
                    &mut stream_rng(0, i),
                ));
            }
            Ok(last)
        })?;
        // The fit as it was before the f32 search (f64 DE on the raw moment form), same run.
        let (f64_fit_time, _) = fastest(args.repeat, || {
            let mut last = None;
            for i in 0..fits {
                last = Some(fit_ellipsoid_f64::<PAPER_POPULATION, _>(
                    &central,
                    &params,
                    &mut stream_rng(0, i),
                ));
            }
            Ok(last)
        })?;
        let direct_ns = direct_time.as_secs_f64() * 1e9 / direct_evals as f64;
        let moment_ns = moment_time.as_secs_f64() * 1e9 / (moment_reps * candidates.len()) as f64;
        println!(
            "{:>7} {:>13.1} {:>13.1} {:>7.0}x {:>12.1e} {:>13.1} {:>11.2} {:>11.2} {:>7.1}x",
            size,
            direct_ns,
            moment_ns,
            direct_ns / moment_ns,
            rel,
            moments_time.as_secs_f64() * 1e6,
            fit_time.as_secs_f64() * 1e6 / fits as f64,
            f64_fit_time.as_secs_f64() * 1e6 / fits as f64,
            f64_fit_time.as_secs_f64() / fit_time.as_secs_f64()
        );
    }
    println!(
        "(moments us: building the moments once, O(|S|); fit us: one 50-generation DE from them, \
         in f32 on the Cholesky form; f64 fit us: the f64 DE on the raw moment form it replaced)"
    );
    Ok(())
}
