//! The Gaussian-mixture baseline of the fidelity benchmark: scikit-learn fits the mixture
//! (`scripts/gmm_fit.py`), and each component becomes the oriented shell two standard
//! deviations out along its principal axes.

use anyhow::{Context, Result, bail};
use mema_core::shell::symmetric_eigen;
use mema_core::{Degeneration, Entity, EntityKind, MapEntity, Point3, Rotation};
use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::mapfile::HostMap;

/// Bytes of one component as the issue counts them: mean 3, covariance 6 and weight 1, f32.
pub const BYTES_PER_COMPONENT: usize = 40;

/// The shell's semi-axes in standard deviations.
pub const SIGMAS: f64 = 2.0;

/// What `scripts/gmm_fit.py` prints.
#[derive(Debug, Deserialize)]
pub struct GmmFit {
    pub converged: bool,
    pub iterations: u64,
    pub max_iter: u64,
    pub fit_s: f64,
    #[serde(default)]
    pub peak_rss_bytes: Option<u64>,
    pub means: Vec<[f64; 3]>,
    pub covariances: Vec<[[f64; 3]; 3]>,
    pub weights: Vec<f64>,
}

/// How the fit went, for the report (the components themselves are in the map).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct GmmSummary {
    pub components: usize,
    pub converged: bool,
    pub iterations: u64,
    pub max_iter: u64,
    /// EM alone, as Python timed it; the process's start and the transfer are outside it.
    pub fit_s: f64,
    pub peak_rss_bytes: Option<u64>,
    /// Components whose covariance gave no shell (not finite or not positive definite).
    pub dropped: usize,
}

/// The 2-sigma shell of one component: centre at the mean, semi-axes `2 sqrt(lambda_j)` along
/// the eigenvectors. `None` unless the covariance is finite and positive definite (scikit-learn
/// adds `reg_covar` to the diagonal, so a fit of its own never gives one that is not).
pub fn gmm_shell(mean: [f64; 3], covariance: [[f64; 3]; 3]) -> Option<Entity> {
    if !mean.iter().chain(covariance.iter().flatten()).all(|v| v.is_finite()) {
        return None;
    }
    // The lower triangle mirrored: a covariance read back from text may be asymmetric by an
    // ulp, and Jacobi assumes exact symmetry.
    let mut sym = covariance;
    for i in 0..3 {
        for j in 0..i {
            let m = 0.5 * (covariance[i][j] + covariance[j][i]);
            sym[i][j] = m;
            sym[j][i] = m;
        }
    }
    let (values, vectors) = symmetric_eigen(sym);
    if !values.iter().all(|&v| v > 0.0) {
        return None;
    }
    let rotation = Rotation::from_matrix(vectors)?;
    let semi_axes = values.map(|v| SIGMAS * v.sqrt());
    // A Gaussian has no infinite axis: no length degenerates, however long.
    let keep_finite = Degeneration {
        threshold: f64::INFINITY,
        ..Degeneration::default()
    };
    let center = Point3::new(mean[0] as f32, mean[1] as f32, mean[2] as f32);
    Some(Entity::from_semi_axes(center, semi_axes, &keep_finite).with_rotation(rotation))
}

/// The map of a fitted mixture (means in the cloud's local frame about `origin`), stored in f32
/// records like any oriented map, and how many components gave no shell.
pub fn gmm_map(origin: [f64; 3], fit: &GmmFit) -> Result<(HostMap, usize)> {
    if fit.means.len() != fit.covariances.len() || fit.means.len() != fit.weights.len() {
        bail!(
            "the mixture has {} means, {} covariances and {} weights",
            fit.means.len(),
            fit.covariances.len(),
            fit.weights.len()
        );
    }
    let entities: Vec<MapEntity> = fit
        .means
        .iter()
        .zip(&fit.covariances)
        .filter_map(|(&m, &c)| gmm_shell(m, c))
        .map(|entity| MapEntity {
            entity,
            kind: EntityKind::Ellipsoid,
        })
        .collect();
    let dropped = fit.means.len() - entities.len();
    Ok((HostMap::new(origin, entities), dropped))
}

/// Runs `script` (`scripts/gmm_fit.py`) on the points of `npy` with `components` components.
pub fn fit_gmm(python: &Path, script: &Path, npy: &Path, components: usize) -> Result<GmmFit> {
    let out = std::process::Command::new(python)
        .arg(script)
        .arg(npy)
        .arg(components.to_string())
        .output()
        .with_context(|| format!("running {}", python.display()))?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        // Python's traceback ends with the line that says what went wrong.
        let last = stderr.lines().rev().find(|l| !l.trim().is_empty());
        bail!(
            "{} failed ({}): {}",
            script.display(),
            out.status,
            last.unwrap_or("no message")
        );
    }
    serde_json::from_slice(&out.stdout)
        .with_context(|| format!("{} printed no mixture", script.display()))
}
