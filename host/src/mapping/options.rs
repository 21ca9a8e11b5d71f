//! What a map is made with: plain configuration, checked into the core's parameters.

use mema_core::Degeneration;
use mema_core::de::{DeParams, OutOfBounds};
use mema_core::fit::{FitParams, Initialisation, SemiAxisBounds};
use mema_core::fitness::VolumeTerm;
use mema_core::kmeans::KMeansParams;
use mema_core::shell::ShellParams;

use super::surface_clusters::DEFAULT_ROUNDS;
use crate::error::ConfigError;

/// Which entity a map of the paper's model is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum EntityChoice {
    /// The paper's ellipsoids (and their degenerations).
    Ellipsoid,
    /// The paper's spherical comparison: one radius a cluster.
    Sphere,
}

/// How each cluster becomes an entity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Model {
    /// The paper: axis-aligned semi-axes fitted by DE on eq. 12 (and a sphere beside it).
    Paper,
    /// Oriented shells of the clusters' covariances, quantized (`mapping::shells`).
    Shells,
}

/// Fewest points a cluster of a map made to a byte budget is given: a covariance (or eq. 12's
/// DE) needs more than a couple of points to have a shape.
pub const MIN_POINTS_PER_ENTITY: usize = 4;

impl Model {
    /// Bytes one entity takes in this model's map file.
    pub fn bytes_per_entity(self) -> usize {
        match self {
            Self::Paper => mema_core::map::ENTITY_LEN,
            Self::Shells => mema_core::map::record::QUANTIZED_LEN,
        }
    }

    /// Entities a map file of `bytes` holds, its header and checksum aside.
    ///
    /// ```
    /// use mema::mapping::Model;
    ///
    /// assert_eq!(Model::Shells.entities_in(2_400), Ok(171));
    /// assert_eq!(Model::Paper.entities_in(2_400), Ok(96));
    /// assert!(Model::Shells.entities_in(3).is_err());
    /// ```
    pub fn entities_in(self, bytes: usize) -> Result<usize, ConfigError> {
        let per = self.bytes_per_entity();
        if bytes < per {
            return Err(ConfigError::BudgetTooSmall { bytes, per });
        }
        Ok(bytes / per)
    }

    /// Entities a map file of `bytes` holds beside the free space of `scans` scans with sensor
    /// origins (the shells' maps keep each scan's range image, [`crate::io::free_space`]; the
    /// paper's keep none), its header and checksum aside.
    ///
    /// ```
    /// use mema::mapping::Model;
    ///
    /// // Two scans' images take 2 x (36 + 8 x 64) + 6 bytes.
    /// assert_eq!(Model::Shells.entities_beside_free_space(9_600, 2), Ok(607));
    /// assert_eq!(Model::Paper.entities_beside_free_space(2_400, 2), Ok(96));
    /// assert!(Model::Shells.entities_beside_free_space(1_000, 2).is_err());
    /// ```
    pub fn entities_beside_free_space(
        self,
        bytes: usize,
        scans: usize,
    ) -> Result<usize, ConfigError> {
        let free = match self {
            Self::Shells => crate::io::free_space::part_bytes_for(scans),
            Self::Paper => 0,
        };
        let per = self.bytes_per_entity();
        match bytes.checked_sub(free) {
            Some(left) if left >= per => Ok(left / per),
            _ if free == 0 => Err(ConfigError::BudgetTooSmall { bytes, per }),
            _ => Err(ConfigError::BudgetTakenByFreeSpace {
                bytes,
                scans,
                free,
                per,
            }),
        }
    }
}

/// Most entities worth fitting to `points` points (at least one): past that, clusters of one to
/// three points have no shape to fit, so a budget is an upper bound.
pub fn most_entities(points: usize) -> usize {
    (points / MIN_POINTS_PER_ENTITY).max(1)
}

/// The checked configuration of the batch pipeline (k-means, then a fit per cluster).
#[derive(Clone, Copy, Debug)]
pub struct PipelineConfig {
    /// Clusters, hence entities.
    pub k: usize,
    /// Seed of the fits' random streams.
    pub seed: u64,
    pub kmeans: KMeansParams,
    pub fit: FitParams,
}

/// The fit and clustering options, as a user chooses them; [`FitOptions::config`] checks them.
///
/// `Default` is the paper's settings plus mema's measured choices, the same as `mema map`'s
/// defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Weight of the residual term of eq. 12 (the paper: 0.8).
    pub alpha: f64,
    /// Seed of k-means++ and DE; the same seed gives the same map bytes.
    pub seed: u64,
    /// Semi-axis length at which an axis degenerates (infinite); the paper: 4 m.
    pub threshold: f64,
    /// Relative tolerance within which three semi-axes make a sphere.
    pub sphere_tolerance: f64,
    /// DE's search box for the semi-axes.
    pub bounds: SemiAxisBounds,
    /// What DE does with a candidate outside the box.
    pub out_of_bounds: OutOfBounds,
    /// Eq. 12's volume term.
    pub volume: VolumeTerm,
    /// DE's first population.
    pub initialisation: Initialisation,
    /// DE generations (the paper: 50).
    pub generations: u32,
    /// Lloyd iteration cap.
    pub max_iterations: u32,
}

impl Default for FitOptions {
    fn default() -> Self {
        let fit = FitParams::default();
        Self {
            alpha: fit.alpha,
            seed: 0,
            threshold: fit.degeneration.threshold,
            sphere_tolerance: fit.degeneration.sphere_tolerance,
            bounds: fit.bounds,
            out_of_bounds: fit.out_of_bounds,
            volume: fit.volume,
            initialisation: fit.initialisation,
            generations: fit.de.generations,
            max_iterations: KMeansParams::default().max_iterations,
        }
    }
}

impl FitOptions {
    /// Checks the values and builds the pipeline's configuration for `k` clusters.
    ///
    /// ```
    /// use mema::mapping::FitOptions;
    ///
    /// let config = FitOptions::default().config(150)?;
    /// assert_eq!(config.fit, mema_core::fit::FitParams::default());
    /// let bad = FitOptions { alpha: 1.5, ..FitOptions::default() };
    /// assert_eq!(bad.config(150).unwrap_err(), mema::ConfigError::Alpha(1.5));
    /// # Ok::<(), mema::ConfigError>(())
    /// ```
    pub fn config(&self, k: usize) -> Result<PipelineConfig, ConfigError> {
        if k == 0 {
            return Err(ConfigError::NoClusters);
        }
        if !(self.alpha >= 0.0 && self.alpha <= 1.0) {
            return Err(ConfigError::Alpha(self.alpha));
        }
        if !(self.threshold > 0.0 && self.threshold.is_finite()) {
            return Err(ConfigError::Threshold(self.threshold));
        }
        if !(self.sphere_tolerance >= 0.0 && self.sphere_tolerance.is_finite()) {
            return Err(ConfigError::SphereTolerance(self.sphere_tolerance));
        }
        let fit = FitParams {
            alpha: self.alpha,
            volume: self.volume,
            de: DeParams {
                generations: self.generations,
                ..DeParams::default()
            },
            bounds: self.bounds,
            out_of_bounds: self.out_of_bounds,
            initialisation: self.initialisation,
            degeneration: Degeneration {
                threshold: self.threshold,
                sphere_tolerance: self.sphere_tolerance,
            },
        };
        Ok(PipelineConfig {
            k,
            seed: self.seed,
            kmeans: KMeansParams {
                max_iterations: self.max_iterations,
                seed: self.seed,
                ..KMeansParams::default()
            },
            fit,
        })
    }
}

/// The shell model's settings: the shell of a cluster, and how its clusters are made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellModel {
    pub shell: ShellParams,
    /// Rounds of surface following after k-means (`mapping::surface_clusters`); 0 keeps the
    /// k-means cells.
    pub surface_rounds: usize,
    /// Keep the free space the input's scans saw through ([`crate::io::free_space`]): each
    /// scan's range image, within the byte budget. Off by default while its cost to the
    /// surface at equal bytes is weighed (issue 29).
    pub free_space: bool,
    /// Shape the shells to the input's rays where it says where its sensor was
    /// ([`crate::mapping::ray_shaping`]), keeping the shaped map only if it scores no worse
    /// both ways against the points.
    pub ray_shaping: bool,
}

impl Default for ShellModel {
    fn default() -> Self {
        Self {
            shell: ShellParams::default(),
            surface_rounds: DEFAULT_ROUNDS,
            free_space: false,
            ray_shaping: true,
        }
    }
}

impl ShellModel {
    /// Fails unless both scales are positive lengths (in standard deviations).
    pub fn check(&self) -> Result<(), ConfigError> {
        let ShellParams {
            tangent_scale,
            normal_scale,
            ..
        } = self.shell;
        if !(tangent_scale > 0.0 && tangent_scale.is_finite()) {
            return Err(ConfigError::TangentScale(tangent_scale));
        }
        if !(normal_scale > 0.0 && normal_scale.is_finite()) {
            return Err(ConfigError::NormalScale(normal_scale));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_settings() {
        let config = FitOptions::default().config(10).expect("valid");
        assert_eq!(config.fit, FitParams::default());
        assert_eq!(config.kmeans.max_iterations, 100);
        assert_eq!(config.kmeans.seed, 0);
        assert_eq!(
            FitOptions::default().config(0).unwrap_err(),
            ConfigError::NoClusters
        );
    }

    #[test]
    fn shell_scales_are_checked_tangent_first() {
        let mut m = ShellModel::default();
        assert_eq!(m.check(), Ok(()));
        m.shell.normal_scale = f64::NAN;
        m.shell.tangent_scale = 0.0;
        assert_eq!(m.check(), Err(ConfigError::TangentScale(0.0)));
    }
}
