//! `mema ablation`: the choices the paper leaves open, measured on one cloud with the same
//! clusters for every variant, so only the fit differs.

use anyhow::Result;
use mema_core::de::OutOfBounds;
use mema_core::fit::{FitParams, Initialisation, SemiAxisBounds};
use mema_core::fitness::VolumeTerm;
use mema_core::kmeans::KMeansParams;
use serde::Serialize;

use crate::analysis::stats::ErrorStats;
use crate::io::cloud::LocalCloud;
use crate::mapping::pipeline;

/// One fit variant's row of `mema ablation`.
#[derive(Serialize)]
pub struct VariantRow {
    pub variant: String,
    /// Mean eq. 13 error of the ellipsoids.
    pub ellipsoid_mean: f64,
    /// Change of that mean against the default, in percent.
    pub change_percent: f64,
    pub sphere_mean: f64,
    /// Clusters whose ellipsoid has an axis on the search box's upper bound, percent.
    pub on_upper_bound_percent: f64,
    /// Entities stored with a degenerated axis (pseudocylinder or plane pair), percent.
    pub degenerated_percent: f64,
    /// Clusters where the ellipsoid's eq. 12 fitness is worse than the sphere's by more than
    /// rounding (1e-9 relative), percent.
    pub ellipsoid_worse_than_sphere_percent: f64,
    /// Mean share of eq. 12 taken by the volume term at the fitted ellipsoid.
    pub volume_share: f64,
}

/// The variants measured, named: the default first, then one option changed at a time.
pub fn variants() -> Vec<(&'static str, FitParams)> {
    let d = FitParams::default();
    vec![
        ("default (spread 0.05-3 s linear, clamp, exact, seeded)", d),
        (
            "bounds threshold (0.05 s to threshold, ln r)",
            FitParams {
                bounds: SemiAxisBounds::Threshold { lower: 0.05 },
                ..d
            },
        ),
        (
            "bounds spread 0.05-10 s (linear)",
            FitParams {
                bounds: SemiAxisBounds::Spread {
                    lower: 0.05,
                    upper: 10.0,
                },
                ..d
            },
        ),
        (
            "out-of-bounds reflect",
            FitParams {
                out_of_bounds: OutOfBounds::Reflect,
                ..d
            },
        ),
        (
            "out-of-bounds resample",
            FitParams {
                out_of_bounds: OutOfBounds::Resample,
                ..d
            },
        ),
        (
            "volume spread-relative",
            FitParams {
                volume: VolumeTerm::SpreadRelative,
                ..d
            },
        ),
        (
            "init random (paper)",
            FitParams {
                initialisation: Initialisation::Random,
                ..d
            },
        ),
        (
            "init random, resample",
            FitParams {
                initialisation: Initialisation::Random,
                out_of_bounds: OutOfBounds::Resample,
                ..d
            },
        ),
    ]
}

/// Clusters `cloud` once into `k`, fits every variant to the same clusters and prints the
/// table (or one JSON document).
pub fn run(cloud: &LocalCloud, k: usize, seed: u64, json: bool) -> Result<()> {
    let clusters = pipeline::cluster(
        &cloud.points,
        k,
        &KMeansParams {
            seed,
            ..KMeansParams::default()
        },
    )?;
    let n = clusters.moments.len() as f64;
    let mut rows: Vec<VariantRow> = Vec::new();
    for (name, params) in variants() {
        let fitted = pipeline::fit_all(&clusters.moments, seed, &params);
        let mean_error = |fits: &[mema_core::fit::Fit]| {
            let entities: Vec<_> = fits.iter().map(|f| f.entity).collect();
            ErrorStats::from_errors(&pipeline::cluster_errors(
                &cloud.points,
                &clusters.labels,
                &entities,
            ))
            .mean
        };
        let ellipsoid_mean = mean_error(&fitted.ellipsoids);
        let percent = |count: usize| 100.0 * count as f64 / n;
        let baseline = rows.first().map_or(ellipsoid_mean, |r| r.ellipsoid_mean);
        rows.push(VariantRow {
            variant: name.to_string(),
            ellipsoid_mean,
            change_percent: 100.0 * (ellipsoid_mean / baseline - 1.0),
            sphere_mean: mean_error(&fitted.spheres),
            on_upper_bound_percent: percent(
                fitted
                    .ellipsoids
                    .iter()
                    .filter(|f| f.on_upper_bound > 0)
                    .count(),
            ),
            degenerated_percent: percent(
                fitted
                    .ellipsoids
                    .iter()
                    .filter(|f| f.entity.degenerated_axes() > 0)
                    .count(),
            ),
            ellipsoid_worse_than_sphere_percent: percent(
                fitted
                    .ellipsoids
                    .iter()
                    .zip(fitted.spheres.iter())
                    .filter(|(e, s)| e.fitness > s.fitness * (1.0 + 1e-9))
                    .count(),
            ),
            volume_share: fitted
                .ellipsoids
                .iter()
                .map(|f| f.volume_term / f.fitness)
                .sum::<f64>()
                / n,
        });
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    println!(
        "| variant | mean e_i ellipsoid | vs default | mean e_i sphere | axis on upper bound | degenerated | ellipsoid worse than sphere (eq. 12) | volume share of eq. 12 |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {:.6} | {:+.1}% | {:.6} | {:.1}% | {:.1}% | {:.1}% | {:.2e} |",
            r.variant,
            r.ellipsoid_mean,
            r.change_percent,
            r.sphere_mean,
            r.on_upper_bound_percent,
            r.degenerated_percent,
            r.ellipsoid_worse_than_sphere_percent,
            r.volume_share
        );
    }
    Ok(())
}
