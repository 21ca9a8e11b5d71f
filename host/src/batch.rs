//! `mema map`'s work as library calls: cluster, fit, write the map (and the points' labels),
//! and report eq. 13 and the memory of what was written.
//!
//! The steps live in [`crate::mapping`] and the measures in [`crate::analysis`]; this layer only
//! puts them together, so both stay free of each other's reports.

use anyhow::Result;
use mema_core::shell::ShellParams;
use mema_core::{Degeneration, MapEntity, Point3};
use serde::Serialize;
use std::path::Path;

use crate::analysis::stats::{ErrorStats, MemoryRow};
use crate::error::ConfigError;
use crate::io::cloud::LocalCloud;
use crate::io::free_space;
use crate::io::mapfile::{HostMap, KindCounts};
use crate::io::output::write_labels;
use crate::mapping::filter::FilterCounts;
use crate::mapping::options::{EntityChoice, Model, PipelineConfig, ShellModel};
use crate::mapping::tolerance::{self, EntityFit, ToleranceOutcome};
use crate::mapping::{pipeline, shells, surface_clusters};
use crate::progress::stage;

mod shaping;
pub use shaping::RayShapingReport;
use shaping::shape_to_rays;

/// What `mema map` and `mema demo` report.
#[derive(Clone, Debug, Serialize)]
pub struct MapReport {
    pub model: Model,
    pub memory: MemoryRow,
    /// Eq. 13 of the written map's entities (the shells, or the paper's ellipsoids).
    pub ellipsoidal: ErrorStats,
    /// The paper's spherical comparison (null for shells).
    pub spherical: Option<ErrorStats>,
    pub kinds: KindCounts,
    pub kmeans_iterations: u32,
    pub kmeans_converged: bool,
    /// Rounds of surface following run after k-means (null for the paper's maps and for
    /// `--surface-rounds 0`).
    pub surface_rounds: Option<usize>,
    pub entity: EntityChoice,
    /// The written map's fitted axes that ended on a bound of DE's search box (null for
    /// shells, which are not searched).
    pub axes_on_bound: Option<AxesOnBound>,
    pub dropped_non_finite: usize,
    /// Points of a classified file (LAS/LAZ) left out by `--classes`.
    pub dropped_by_class: crate::io::read::ClassDrops,
    /// Isolated points `--outliers` dropped, and the worst of them.
    pub outliers: crate::io::read::OutlierDrops,
    pub output: String,
    /// Points read, then left by `--crop` and `--voxel` (null when not asked for).
    pub filter: FilterCounts,
    /// The input's slots: `filter.read` and every point the read left out (NaN or infinite,
    /// by class, isolated, no-return), over every scan of a registration file or message of
    /// a bag.
    pub slots: usize,
    /// Points left out as no-returns: at their sensor origin (`--min-range`).
    pub no_returns: usize,
    /// Where the mapped points were seen from; null where the input does not say, and then
    /// no free space is recorded.
    pub rays: Option<RaysSeen>,
    /// The free space the map keeps: its scans' range images (null: none recorded).
    pub free_space: Option<FreeSpaceKept>,
    /// What shaping the shells to the input's rays did (null: no rays, or not asked for).
    pub ray_shaping: Option<RayShapingReport>,
}

/// The free space a map keeps ([`crate::io::free_space`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct FreeSpaceKept {
    /// Scans whose range image the map keeps.
    pub images: usize,
    /// Bytes of the map file's free-space part (within `--bytes`).
    pub bytes: usize,
}

/// The rays a map's points are the ends of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct RaysSeen {
    /// Points with a sensor origin.
    pub points: usize,
    /// Distinct scans (sensor positions) they were seen from.
    pub origins: usize,
}

impl RaysSeen {
    /// What `cloud` says of its rays; `None` if it has no sensor origins.
    pub fn of(cloud: &LocalCloud) -> Option<Self> {
        (!cloud.sensors.is_empty()).then(|| Self {
            points: cloud.sensors.points(),
            origins: cloud.sensors.origins.len(),
        })
    }
}

impl MapReport {
    /// Sets what `--crop` and `--voxel` left of the points read, and the slots they and the
    /// read's drops make.
    pub fn set_filter(&mut self, filter: FilterCounts) {
        self.slots = filter.read
            + self.no_returns
            + self.dropped_non_finite
            + self.dropped_by_class.total()
            + self.outliers.dropped;
        self.filter = filter;
    }
}

/// How many fitted semi-axes ended on a bound of the box DE searched (`--bounds`): there the
/// box, not eq. 12, chose their length.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct AxesOnBound {
    /// Semi-axes fitted (a sphere's radius counts once).
    pub axes: usize,
    pub lower: usize,
    pub upper: usize,
}

impl AxesOnBound {
    /// Counts over `fits`.
    pub fn of(fits: &[mema_core::fit::Fit], sphere: bool) -> Self {
        let per_fit = if sphere { 1 } else { 3 };
        fits.iter().fold(
            Self {
                axes: per_fit * fits.len(),
                ..Self::default()
            },
            |acc, f| Self {
                lower: acc.lower + usize::from(f.on_lower_bound),
                upper: acc.upper + usize::from(f.on_upper_bound),
                ..acc
            },
        )
    }

    /// Whether most axes rest on a bound.
    pub fn most(&self) -> bool {
        2 * (self.lower + self.upper) > self.axes
    }
}

/// The paper's model: clusters, fits both entity types, evaluates eq. 13 for both, writes the
/// chosen map (and the points' cluster labels if asked).
pub fn map_cloud(
    cloud: &LocalCloud,
    config: &PipelineConfig,
    entity: EntityChoice,
    output: &Path,
    labels: Option<&Path>,
) -> Result<MapReport> {
    map_cloud_with(
        cloud,
        config,
        Model::Paper,
        ShellModel::default(),
        entity,
        output,
        labels,
    )
}

/// [`map_cloud`] in either model (`shells` for shells; their degeneration is `config`'s).
///
/// The map is written to `output` in the format of its extension (`.mema`, `.csv`, `.json`),
/// atomically; `labels`, if given, gets each point's cluster, one a line.
///
/// A cloud mapped with shells at a budget of 2,400 bytes, as `mema map --bytes 2400` does it:
///
/// ```
/// use mema::mapping::{EntityChoice, FitOptions, Model, ShellModel, most_entities};
///
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/car6.pcd");
/// let cloud = mema::io::load_cloud(path.as_ref())?;
/// let k = Model::Shells.entities_in(2_400)?.min(most_entities(cloud.points.len()));
/// let config = FitOptions::default().config(k)?;
/// let output = std::env::temp_dir().join(format!("mema-doc-{}.mema", std::process::id()));
/// let report = mema::batch::map_cloud_with(
///     &cloud,
///     &config,
///     Model::Shells,
///     ShellModel::default(),
///     EntityChoice::Ellipsoid,
///     &output,
///     None,
/// )?;
/// assert!(report.memory.entities <= 171);
/// let map = mema::io::HostMap::read(&output)?;
/// assert_eq!(map.entities.len(), report.memory.entities);
/// // The budget counts entities; the file adds its header and checksum.
/// assert!(std::fs::metadata(&output)?.len() <= 2_400 + 52);
/// # std::fs::remove_file(&output)?;
/// # Ok::<(), anyhow::Error>(())
/// ```
pub fn map_cloud_with(
    cloud: &LocalCloud,
    config: &PipelineConfig,
    model: Model,
    shells: ShellModel,
    entity: EntityChoice,
    output: &Path,
    labels: Option<&Path>,
) -> Result<MapReport> {
    let built = build_map(cloud, config, model, shells, entity)?;
    built.map.write(output)?;
    // After the map: labels never describe a map that was not written.
    if let Some(path) = labels {
        write_labels(path, &built.labels)?;
    }
    Ok(MapReport {
        output: output.display().to_string(),
        ..built.report
    })
}

/// A map made in memory by [`build_map`], not yet written.
#[derive(Clone, Debug)]
pub struct BuiltMap {
    /// The map `mema map` writes: the shells, or the paper's entities of the kind chosen.
    pub map: HostMap,
    /// Its report; `output` is empty until the map is written somewhere.
    pub report: MapReport,
    /// Each point's cluster (after surface following, for shells), in the cloud's order: what
    /// `mema map --labels` writes.
    pub labels: Vec<u32>,
}

/// [`map_cloud_with`]'s work without the files: the map, its report and the points' labels,
/// for a caller that keeps the map in memory (the Python package) or writes it elsewhere.
/// Written with [`HostMap::write`], the map is the same bytes `map_cloud_with` writes.
///
/// ```
/// use mema::mapping::{EntityChoice, FitOptions, Model, ShellModel};
///
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/car6.pcd");
/// let cloud = mema::io::load_cloud(path.as_ref())?;
/// let config = FitOptions::default().config(40)?;
/// let (shells, entity) = (ShellModel::default(), EntityChoice::Ellipsoid);
/// let built = mema::batch::build_map(&cloud, &config, Model::Shells, shells, entity)?;
/// assert_eq!(built.map.entities.len(), 40);
/// assert_eq!(built.labels.len(), cloud.points.len());
/// # Ok::<(), anyhow::Error>(())
/// ```
pub fn build_map(
    cloud: &LocalCloud,
    config: &PipelineConfig,
    model: Model,
    shells: ShellModel,
    entity: EntityChoice,
) -> Result<BuiltMap> {
    let clusters = stage("k-means", || {
        pipeline::cluster(&cloud.points, config.k, &config.kmeans)
    })?;
    Ok(match model {
        Model::Shells => shells_map(cloud, config, shells, clusters),
        Model::Paper => paper_map(cloud, config, entity, clusters),
    })
}

/// The paper's maps of the clusters (ellipsoids and spheres by DE on eq. 12), the chosen one
/// and their report.
fn paper_map(
    cloud: &LocalCloud,
    config: &PipelineConfig,
    entity: EntityChoice,
    clusters: pipeline::Clusters,
) -> BuiltMap {
    let fitted = stage("fitting", || {
        pipeline::fit_all(&clusters.moments, config.seed, &config.fit)
    });
    let tolerance = config.fit.degeneration.sphere_tolerance;
    let ellipsoids = pipeline::to_map(cloud.origin, &fitted.ellipsoids, tolerance);
    let spheres = pipeline::to_map(cloud.origin, &fitted.spheres, tolerance);
    let errors = |map: &HostMap| {
        let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
        ErrorStats::from_errors(&stage("evaluating", || {
            pipeline::cluster_errors(&cloud.points, &clusters.labels, &entities)
        }))
    };
    let (ellipsoidal, spherical) = (errors(&ellipsoids), errors(&spheres));
    let (chosen, on_bound) = match entity {
        EntityChoice::Ellipsoid => (ellipsoids, AxesOnBound::of(&fitted.ellipsoids, false)),
        EntityChoice::Sphere => (spheres, AxesOnBound::of(&fitted.spheres, true)),
    };
    let mut report = MapReport {
        model: Model::Paper,
        memory: MemoryRow::new(cloud.points.len(), chosen.entities.len()),
        ellipsoidal,
        spherical: Some(spherical),
        kinds: KindCounts::of(&chosen),
        kmeans_iterations: clusters.outcome.iterations,
        kmeans_converged: clusters.outcome.converged,
        surface_rounds: None,
        entity,
        axes_on_bound: Some(on_bound),
        dropped_non_finite: cloud.dropped_non_finite,
        dropped_by_class: cloud.dropped_by_class,
        outliers: cloud.outliers,
        output: String::new(),
        filter: FilterCounts::default(),
        slots: 0,
        no_returns: cloud.no_returns,
        rays: RaysSeen::of(cloud),
        free_space: None,
        ray_shaping: None,
    };
    report.set_filter(FilterCounts {
        read: cloud.points.len(),
        ..Default::default()
    });
    BuiltMap {
        map: chosen,
        report,
        labels: clusters.labels,
    }
}

/// Shells never degenerate: a shell spans its cluster's points, which are bounded, so an
/// infinite axis would only add surface where there are no points (the threshold is the
/// paper's).
fn shell_params(shell: ShellParams, config: &PipelineConfig) -> ShellParams {
    ShellParams {
        degeneration: Degeneration {
            threshold: f64::INFINITY,
            ..config.fit.degeneration
        },
        ..shell
    }
}

/// The shell model's map of the clusters, its report, and the points' labels (those surface
/// following left, or the k-means cells').
fn shells_map(
    cloud: &LocalCloud,
    config: &PipelineConfig,
    model: ShellModel,
    clusters: pipeline::Clusters,
) -> BuiltMap {
    let params = shell_params(model.shell, config);
    let centres: Vec<Point3> = clusters
        .moments
        .iter()
        .map(|m| Point3::new(m.mean[0] as f32, m.mean[1] as f32, m.mean[2] as f32))
        .collect();
    let surfaces = (model.surface_rounds > 0).then(|| {
        stage("following surfaces", || {
            surface_clusters::follow_surfaces(
                &cloud.points,
                &clusters.labels,
                &centres,
                model.surface_rounds,
            )
        })
    });
    let (labels, anchors) = match &surfaces {
        Some(s) => (&s.labels[..], &s.anchors[..]),
        None => (&clusters.labels[..], &centres[..]),
    };
    let mut map = stage("fitting", || {
        shells::shell_map(cloud.origin, &cloud.points, labels, anchors, &params)
    });
    let ray_shaping = if model.ray_shaping {
        stage("shaping to rays", || {
            shape_to_rays(cloud, labels, &mut map, params)
        })
    } else {
        None
    };
    if model.free_space {
        map.free_space = stage("free space", || free_space::images_of(cloud, map.origin));
    }
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    let errors = stage("evaluating", || {
        pipeline::cluster_errors(&cloud.points, labels, &entities)
    });
    let mut report = MapReport {
        model: Model::Shells,
        memory: MemoryRow::with_entity_bytes(
            cloud.points.len(),
            map.entities.len(),
            shells::BYTES_PER_ENTITY,
        ),
        ellipsoidal: ErrorStats::from_errors(&errors),
        spherical: None,
        kinds: KindCounts::of(&map),
        kmeans_iterations: clusters.outcome.iterations,
        kmeans_converged: clusters.outcome.converged,
        surface_rounds: surfaces.as_ref().map(|s| s.rounds),
        entity: EntityChoice::Ellipsoid,
        axes_on_bound: None,
        dropped_non_finite: cloud.dropped_non_finite,
        dropped_by_class: cloud.dropped_by_class,
        outliers: cloud.outliers,
        output: String::new(),
        filter: FilterCounts::default(),
        slots: 0,
        no_returns: cloud.no_returns,
        rays: RaysSeen::of(cloud),
        free_space: (!map.free_space.is_empty()).then(|| FreeSpaceKept {
            images: map.free_space.len(),
            bytes: free_space::part_bytes(&map.free_space),
        }),
        ray_shaping,
    };
    report.set_filter(FilterCounts {
        read: cloud.points.len(),
        ..Default::default()
    });
    let labels = match surfaces {
        Some(s) => s.labels,
        None => clusters.labels,
    };
    BuiltMap {
        map,
        report,
        labels,
    }
}

/// The tolerance mode's settings (`mema map --tolerance`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToleranceOptions {
    /// T: the most eq. 13 error a cluster may keep, in the cloud's units.
    pub tolerance: f64,
    /// Most clusters the hierarchy may make.
    pub capacity: usize,
    /// Rounds of re-checking T with nearest-centre membership, splitting clusters that fail.
    pub voronoi_rounds: usize,
}

impl ToleranceOptions {
    /// Fails unless T is a positive length and the capacity at least 1.
    pub fn check(&self) -> Result<(), ConfigError> {
        if !(self.tolerance > 0.0 && self.tolerance.is_finite()) {
            return Err(ConfigError::Tolerance(self.tolerance));
        }
        if self.capacity == 0 {
            return Err(ConfigError::ToleranceCapacity);
        }
        Ok(())
    }
}

/// A map of the tolerance mode and the hierarchy it came from (not yet written).
pub struct ToleranceMap {
    pub map: HostMap,
    pub outcome: ToleranceOutcome,
    pub model: Model,
    pub tolerance: f64,
}

/// What `mema map --tolerance` reports.
#[derive(Clone, Debug, Serialize)]
pub struct ToleranceReport {
    pub tolerance: f64,
    pub model: Model,
    /// The k the hierarchy chose.
    pub k: usize,
    pub memory: MemoryRow,
    pub ellipsoidal: ErrorStats,
    pub clusters_over_tolerance: usize,
    pub splits: usize,
    pub merges: usize,
    pub capacity_reached: bool,
    pub kinds: KindCounts,
    /// Eq. 13 error of each cluster, in map order.
    pub errors: Vec<f64>,
    /// Points of the file skipped for a NaN or infinite coordinate.
    pub dropped_non_finite: usize,
    pub output: String,
}

/// Builds the map whose every cluster meets `options.tolerance` (see
/// [`crate::mapping::tolerance`]); `config` gives the fit (and seed), `shell` the shells.
pub fn map_to_tolerance(
    cloud: &LocalCloud,
    options: &ToleranceOptions,
    config: &PipelineConfig,
    model: Model,
    shell: ShellParams,
) -> Result<ToleranceMap> {
    options.check()?;
    let fit = match model {
        Model::Paper => EntityFit::Paper(config.fit),
        Model::Shells => EntityFit::shells_for(&cloud.points, shell_params(shell, config)),
    };
    let outcome = tolerance::build(
        &cloud.points,
        options.tolerance,
        options.capacity,
        options.voronoi_rounds,
        config.seed,
        &fit,
    )?;
    let sphere_tolerance = config.fit.degeneration.sphere_tolerance;
    let map = HostMap {
        origin: cloud.origin,
        entities: outcome
            .nodes
            .iter()
            .map(|n| MapEntity {
                entity: n.entity,
                kind: n.entity.kind(sphere_tolerance),
            })
            .collect(),
        quantization: match fit {
            EntityFit::Shells { grid, .. } => Some(grid),
            EntityFit::Paper(_) => None,
        },
        free_space: Vec::new(),
    };
    Ok(ToleranceMap {
        map,
        outcome,
        model,
        tolerance: options.tolerance,
    })
}

impl ToleranceMap {
    /// Each of the cloud's `points` points labelled with its cluster, in map order.
    pub fn labels(&self, points: usize) -> Vec<u32> {
        let mut labels = vec![0u32; points];
        for (c, node) in self.outcome.nodes.iter().enumerate() {
            for &i in &node.members {
                if let Some(l) = labels.get_mut(i as usize) {
                    *l = c as u32;
                }
            }
        }
        labels
    }

    /// The report of this map of `cloud`, written to `output`.
    pub fn report(&self, cloud: &LocalCloud, output: &Path) -> ToleranceReport {
        let points = cloud.points.len();
        let errors: Vec<f64> = self.outcome.nodes.iter().map(|n| n.error).collect();
        ToleranceReport {
            tolerance: self.tolerance,
            k: self.map.entities.len(),
            model: self.model,
            memory: MemoryRow::with_entity_bytes(
                points,
                self.map.entities.len(),
                self.model.bytes_per_entity(),
            ),
            ellipsoidal: ErrorStats::from_errors(&errors),
            clusters_over_tolerance: errors.iter().filter(|&&e| e > self.tolerance).count(),
            splits: self.outcome.splits,
            merges: self.outcome.merges,
            capacity_reached: self.outcome.capacity_reached,
            kinds: KindCounts::of(&self.map),
            errors,
            dropped_non_finite: cloud.dropped_non_finite,
            output: output.display().to_string(),
        }
    }
}
