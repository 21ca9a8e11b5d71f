//! The Gaussian-mixture baseline of the fidelity benchmark: scikit-learn fits the mixture
//! (`scripts/gmm_fit.py`), and each component becomes the oriented shell two standard
//! deviations out along its principal axes.

use anyhow::{Context, Result, bail};
use mema_core::shell::symmetric_eigen;
use mema_core::{Degeneration, Entity, EntityKind, MapEntity, Point3, Rotation};
use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::io::mapfile::HostMap;

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
    #[serde(default)]
    pub sklearn: Option<String>,
    /// The length the script fitted in (the cloud's RMS spread), in cloud units.
    #[serde(default)]
    pub scale: Option<f64>,
    pub means: Vec<[f64; 3]>,
    pub covariances: Vec<[[f64; 3]; 3]>,
    pub weights: Vec<f64>,
}

/// How the fit went, for the report (the components themselves are in the map).
#[derive(Clone, Debug, Serialize)]
pub struct GmmSummary {
    pub sklearn: Option<String>,
    /// Read from the fit cache instead of fitted in this run.
    pub cached: bool,
    pub scale: Option<f64>,
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
    if !mean
        .iter()
        .chain(covariance.iter().flatten())
        .all(|v| v.is_finite())
    {
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
/// With a `cache` directory, a fit of the same points and components by the same script made
/// before is read from there instead (the fits take most of the benchmark's time), and a new
/// one is kept there; the flag says which happened.
pub fn fit_gmm(
    python: &Path,
    script: &Path,
    npy: &Path,
    components: usize,
    cache: Option<&Path>,
) -> Result<(GmmFit, bool)> {
    let cached = match cache {
        Some(dir) => {
            // The script is part of the key: a fit made by another version of it is another fit.
            let mut bytes =
                std::fs::read(npy).with_context(|| format!("reading {}", npy.display()))?;
            bytes.extend(
                std::fs::read(script).with_context(|| format!("reading {}", script.display()))?,
            );
            Some(dir.join(format!("gmm-{:016x}-{components}.json", fnv1a(&bytes))))
        }
        None => None,
    };
    // A cache entry that does not parse (a run killed while writing it) is fitted again.
    if let Some(fit) = cached
        .as_ref()
        .and_then(|p| std::fs::read(p).ok())
        .and_then(|b| serde_json::from_slice(&b).ok())
    {
        return Ok((fit, true));
    }
    let mut command = std::process::Command::new(python);
    // EM multiplies n x 3 by 3 x 3 once per component: OpenBLAS's threads cost more than they
    // bring there, and spin on a shared machine (measured: the E-step 2.5 times slower).
    for var in ["OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"] {
        if std::env::var_os(var).is_none() {
            command.env(var, "1");
        }
    }
    let out = command
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
    let fit = serde_json::from_slice(&out.stdout)
        .with_context(|| format!("{} printed no mixture", script.display()))?;
    if let Some(path) = &cached {
        crate::io::mapfile::write_atomically(path, &out.stdout)?;
    }
    Ok((fit, false))
}

/// FNV-1a, 64 bits: the cache key of a cloud's points.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}
