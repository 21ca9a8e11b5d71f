//! The subcommands: each reads, runs the pipeline, prints, and writes atomically.

use anyhow::{Context, Result};
use mema_core::{EntityKind, Point3};
use serde::Serialize;
use std::path::Path;

use crate::analysis::stats::{self, ErrorStats, MemoryRow};
use crate::cli::{AblationArgs, DemoArgs, InfoArgs, MapArgs};
use crate::io::mapfile::HostMap;
use crate::io::read::read_cloud;
use crate::mapping::pipeline::{self, EntityChoice, Model, PipelineConfig};

/// A cloud in its local frame, ready for the core.
pub struct LocalCloud {
    pub origin: [f64; 3],
    pub points: Vec<Point3>,
    pub dropped_non_finite: usize,
}

impl LocalCloud {
    /// From world coordinates: the bounding-box centre becomes the origin.
    pub fn from_world(points: &[[f64; 3]]) -> Self {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points {
            for j in 0..3 {
                lo[j] = lo[j].min(p[j]);
                hi[j] = hi[j].max(p[j]);
            }
        }
        let origin = [0, 1, 2].map(|j| {
            if points.is_empty() {
                0.0
            } else {
                0.5 * (lo[j] + hi[j])
            }
        });
        let points = points
            .iter()
            .map(|p| {
                Point3::new(
                    (p[0] - origin[0]) as f32,
                    (p[1] - origin[1]) as f32,
                    (p[2] - origin[2]) as f32,
                )
            })
            .collect();
        Self {
            origin,
            points,
            dropped_non_finite: 0,
        }
    }
}

pub fn load_cloud(path: &Path) -> Result<LocalCloud> {
    let cloud = read_cloud(path)?;
    Ok(LocalCloud {
        origin: cloud.origin,
        points: cloud.points.into_iter().map(Point3::from).collect(),
        dropped_non_finite: cloud.dropped_non_finite,
    })
}

#[derive(Serialize)]
pub struct KindCounts {
    pub ellipsoid: usize,
    pub sphere: usize,
    pub pseudocylinder: usize,
    pub plane_pair: usize,
}

impl KindCounts {
    pub fn of(map: &HostMap) -> Self {
        let count = |k: EntityKind| map.entities.iter().filter(|e| e.kind == k).count();
        Self {
            ellipsoid: count(EntityKind::Ellipsoid),
            sphere: count(EntityKind::Sphere),
            pseudocylinder: count(EntityKind::Pseudocylinder),
            plane_pair: count(EntityKind::PlanePair),
        }
    }
}

/// What `mema map` and `mema demo` report.
#[derive(Serialize)]
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
    pub dropped_non_finite: usize,
    pub output: String,
    /// Points read, then left by `--crop` and `--voxel` (null when not asked for).
    pub filter: crate::mapping::filter::FilterCounts,
}

/// Clusters, fits both entity types, evaluates eq. 13 for both, writes the chosen map (and the
/// points' cluster labels if asked).
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
        crate::mapping::shells::ShellModel::default(),
        entity,
        output,
        labels,
    )
}

/// [`map_cloud`] in either model (`shells` for shells; their degeneration is `config`'s).
pub fn map_cloud_with(
    cloud: &LocalCloud,
    config: &PipelineConfig,
    model: Model,
    shells: crate::mapping::shells::ShellModel,
    entity: EntityChoice,
    output: &Path,
    labels: Option<&Path>,
) -> Result<MapReport> {
    let clusters = crate::progress::stage("k-means", || {
        pipeline::cluster(&cloud.points, config.k, &config.kmeans)
    })?;
    let (report, refined) = match model {
        Model::Shells => shells_report(cloud, config, shells, &clusters, output)?,
        Model::Paper => (
            paper_report(cloud, config, entity, &clusters, output)?,
            None,
        ),
    };
    // After the map: labels never describe a map that was not written.
    if let Some(path) = labels {
        write_labels(path, refined.as_deref().unwrap_or(&clusters.labels))?;
    }
    Ok(report)
}

/// The paper's maps of the clusters (ellipsoids and spheres by DE on eq. 12), the chosen one
/// written, and their report.
fn paper_report(
    cloud: &LocalCloud,
    config: &PipelineConfig,
    entity: EntityChoice,
    clusters: &pipeline::Clusters,
    output: &Path,
) -> Result<MapReport> {
    let fitted = crate::progress::stage("fitting", || {
        pipeline::fit_all(&clusters.moments, config.seed, &config.fit)
    });
    let tolerance = config.fit.degeneration.sphere_tolerance;
    let ellipsoids = pipeline::to_map(cloud.origin, &fitted.ellipsoids, tolerance);
    let spheres = pipeline::to_map(cloud.origin, &fitted.spheres, tolerance);
    let errors = |map: &HostMap| {
        let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
        ErrorStats::from_errors(&crate::progress::stage("evaluating", || {
            pipeline::cluster_errors(&cloud.points, &clusters.labels, &entities)
        }))
    };
    let chosen = match entity {
        EntityChoice::Ellipsoid => &ellipsoids,
        EntityChoice::Sphere => &spheres,
    };
    chosen.write(output)?;
    Ok(MapReport {
        model: Model::Paper,
        memory: MemoryRow::new(cloud.points.len(), chosen.entities.len()),
        ellipsoidal: errors(&ellipsoids),
        spherical: Some(errors(&spheres)),
        kinds: KindCounts::of(chosen),
        kmeans_iterations: clusters.outcome.iterations,
        kmeans_converged: clusters.outcome.converged,
        surface_rounds: None,
        entity,
        dropped_non_finite: cloud.dropped_non_finite,
        output: output.display().to_string(),
        filter: crate::mapping::filter::FilterCounts {
            read: cloud.points.len(),
            ..Default::default()
        },
    })
}

/// The shell model's map of the clusters, written, its report, and the points' labels when
/// surface following changed them.
fn shells_report(
    cloud: &LocalCloud,
    config: &PipelineConfig,
    model: crate::mapping::shells::ShellModel,
    clusters: &pipeline::Clusters,
    output: &Path,
) -> Result<(MapReport, Option<Vec<u32>>)> {
    let params = model.shell;
    // A shell spans its cluster's points, which are bounded: an infinite axis would only add
    // surface where there are no points, so shells never degenerate (--threshold is the paper's).
    let params = mema_core::shell::ShellParams {
        degeneration: mema_core::Degeneration {
            threshold: f64::INFINITY,
            ..config.fit.degeneration
        },
        ..params
    };
    let centres: Vec<Point3> = clusters
        .moments
        .iter()
        .map(|m| Point3::new(m.mean[0] as f32, m.mean[1] as f32, m.mean[2] as f32))
        .collect();
    let surfaces = (model.surface_rounds > 0).then(|| {
        crate::progress::stage("following surfaces", || {
            crate::mapping::surface_clusters::follow_surfaces(
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
    let map = crate::progress::stage("fitting", || {
        crate::mapping::shells::shell_map(cloud.origin, &cloud.points, labels, anchors, &params)
    });
    map.write(output)?;
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    let errors = crate::progress::stage("evaluating", || {
        pipeline::cluster_errors(&cloud.points, labels, &entities)
    });
    let report = MapReport {
        model: Model::Shells,
        memory: MemoryRow::with_entity_bytes(
            cloud.points.len(),
            map.entities.len(),
            crate::mapping::shells::BYTES_PER_ENTITY,
        ),
        ellipsoidal: ErrorStats::from_errors(&errors),
        spherical: None,
        kinds: KindCounts::of(&map),
        kmeans_iterations: clusters.outcome.iterations,
        kmeans_converged: clusters.outcome.converged,
        surface_rounds: surfaces.as_ref().map(|s| s.rounds),
        entity: EntityChoice::Ellipsoid,
        dropped_non_finite: cloud.dropped_non_finite,
        output: output.display().to_string(),
        filter: crate::mapping::filter::FilterCounts {
            read: cloud.points.len(),
            ..Default::default()
        },
    };
    Ok((report, surfaces.map(|s| s.labels)))
}

fn print_map_report(r: &MapReport, json: bool) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(r)?);
        return Ok(());
    }
    println!(
        "Table 2: memory (12 bytes per point, {} per entity)",
        r.memory.map_bytes / r.memory.entities.max(1)
    );
    println!("{}", stats::MEMORY_HEADER);
    println!("{}", stats::format_memory_row(&r.memory));
    println!();
    println!(
        "Table 4: eq. 13 error per cluster (cloud units), over {} clusters",
        r.ellipsoidal.clusters
    );
    println!("{}", stats::ERROR_HEADER);
    match &r.spherical {
        Some(spherical) => {
            println!("{}", stats::format_error_row("ellipsoidal", &r.ellipsoidal));
            println!("{}", stats::format_error_row("spherical", spherical));
        }
        None => println!("{}", stats::format_error_row("shells", &r.ellipsoidal)),
    }
    println!();
    println!(
        "kinds: {} ellipsoid, {} sphere, {} pseudocylinder, {} plane_pair",
        r.kinds.ellipsoid, r.kinds.sphere, r.kinds.pseudocylinder, r.kinds.plane_pair
    );
    let surfaces = match r.surface_rounds {
        Some(n) => format!("; surface following: {n} rounds"),
        None => String::new(),
    };
    eprintln!(
        "k-means: {} iterations{}{surfaces}; wrote {}",
        r.kmeans_iterations,
        if r.kmeans_converged {
            ", converged"
        } else {
            ", iteration cap reached"
        },
        r.output
    );
    Ok(())
}

/// Fails before any work if the map could not be written where asked.
pub fn check_output(path: &Path) -> Result<()> {
    crate::io::mapfile::MapFormat::from_path(path)?;
    check_output_file(path, "map")
}

/// Fails before any work if `path`'s directory is missing or not writable.
pub fn check_output_dir(path: &Path) -> Result<()> {
    check_output_file(path, "file")
}

/// Fails before any work if a `what` file could not be written at `path`: its directory must
/// exist, be a directory, and take a new file (probed with an empty file, removed at once).
pub fn check_output_file(path: &Path, what: &str) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.exists() {
        anyhow::bail!(
            "cannot write {what} to {}: directory {} does not exist",
            path.display(),
            dir.display()
        );
    }
    if !dir.is_dir() {
        anyhow::bail!(
            "cannot write {what} to {}: {} is not a directory",
            path.display(),
            dir.display()
        );
    }
    let probe = dir.join(format!(".mema-probe.{}", std::process::id()));
    match std::fs::File::create(&probe) {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => Err(e).with_context(|| {
            format!(
                "cannot write {what} to {}: directory {} is not writable",
                path.display(),
                dir.display()
            )
        }),
    }
}

/// Fewest points a cluster of a `--bytes` map is given: a covariance (or eq. 12's DE) needs
/// more than a couple of points to have a shape.
pub const MIN_POINTS_PER_ENTITY: usize = 4;

/// The shell model `mema map`'s arguments ask for, checked before any work.
fn shell_model(args: &MapArgs) -> Result<crate::mapping::shells::ShellModel> {
    for (name, v) in [
        ("--tangent-scale", args.tangent_scale),
        ("--normal-scale", args.normal_scale),
    ] {
        if !(v > 0.0 && v.is_finite()) {
            return Err(crate::cli::UsageError(format!("{name} {v} must be positive")).into());
        }
    }
    Ok(crate::mapping::shells::ShellModel {
        shell: mema_core::shell::ShellParams {
            tangent_scale: args.tangent_scale,
            normal_scale: args.normal_scale,
            ..Default::default()
        },
        surface_rounds: args.surface_rounds,
    })
}

pub fn map(args: &MapArgs) -> Result<()> {
    let model = if args.paper { Model::Paper } else { args.model };
    if model == Model::Shells && args.entity == EntityChoice::Sphere {
        return Err(crate::cli::UsageError(
            "--entity sphere is the paper's comparison; add --paper (or --model paper)".into(),
        )
        .into());
    }
    let shells = shell_model(args)?;
    if let Some(t) = args.tolerance {
        return map_to_tolerance(args, t, model, shells.shell);
    }
    let k = match args.bytes {
        Some(bytes) => {
            let per = model.bytes_per_entity();
            if bytes < per {
                return Err(crate::cli::UsageError(format!(
                    "--bytes {bytes} holds no entity; one takes {per} bytes in this model"
                ))
                .into());
            }
            bytes / per
        }
        None => args.k.unwrap_or(0),
    };
    let config = args.fit.config(k)?;
    let voxel = args
        .voxel
        .map(crate::mapping::filter::check_voxel)
        .transpose()?;
    check_output(&args.output)?;
    if let Some(labels) = &args.labels {
        check_output_file(labels, "labels")?;
    }
    let cloud = crate::progress::stage("reading", || load_cloud(&args.input))?;
    let (cloud, filter) = crate::mapping::filter::apply(cloud, args.crop, voxel)
        .with_context(|| args.input.display().to_string())?;
    let mut config = config;
    // A budget is an upper bound: past a quarter of the points, clusters of one to three points
    // have no shape to fit, so a small cloud gets fewer entities than the bytes could hold.
    let most = (cloud.points.len() / MIN_POINTS_PER_ENTITY).max(1);
    if args.bytes.is_some() && config.k > most {
        eprintln!(
            "mema: {} bytes hold {} entities, but {} points make at most {most} clusters of {MIN_POINTS_PER_ENTITY}; mapping with k = {most}",
            args.bytes.unwrap_or(0),
            config.k,
            cloud.points.len()
        );
        config.k = most;
    }
    let mut report = map_cloud_with(
        &cloud,
        &config,
        model,
        shells,
        args.entity,
        &args.output,
        args.labels.as_deref(),
    )
    .with_context(|| args.input.display().to_string())?;
    report.filter = filter;
    print_map_report(&report, args.json)
}

pub fn demo(args: &DemoArgs) -> Result<()> {
    let config = args.fit.config(args.k)?;
    check_output(&args.output)?;
    let scan = crate::io::scene::scan(
        &crate::io::scene::Scene::demo(),
        &crate::io::scene::ScanConfig::default(),
    );
    eprintln!(
        "demo: simulated rangefinder scan of the built-in scene (floor, trash can, box, person): {} points from {} rays",
        scan.points.len(),
        scan.rays
    );
    let cloud = LocalCloud::from_world(&scan.points);
    let model = if args.paper {
        Model::Paper
    } else {
        Model::Shells
    };
    let report = map_cloud_with(
        &cloud,
        &config,
        model,
        crate::mapping::shells::ShellModel::default(),
        EntityChoice::Ellipsoid,
        &args.output,
        None,
    )
    .context("demo scene")?;
    print_map_report(&report, args.json)
}

/// Eq. 13's part of `mema eval`'s JSON (documented in the README; keys are stable): `points`,
/// the statistics' `clusters, mean, std, max, min, total`, then `cloud_bytes, map_bytes,
/// percent`. `eval::EvalJson` adds the two-way score after them.
#[derive(Serialize)]
pub struct EvalReport {
    pub points: usize,
    #[serde(flatten)]
    pub errors: ErrorStats,
    pub cloud_bytes: usize,
    pub map_bytes: usize,
    pub percent: f64,
}

/// Eq. 13 statistics of any map against any cloud; each point joins its nearest centre.
pub fn evaluate(cloud: &LocalCloud, map: &HostMap) -> EvalReport {
    // Express the cloud in the map's frame (in f64, then f32 like the map's own centres).
    let shift = [0, 1, 2].map(|j| cloud.origin[j] - map.origin[j]);
    let points: Vec<Point3> = cloud
        .points
        .iter()
        .map(|p| {
            let q = p.to_f64();
            Point3::new(
                (q[0] + shift[0]) as f32,
                (q[1] + shift[1]) as f32,
                (q[2] + shift[2]) as f32,
            )
        })
        .collect();
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    let centres: Vec<Point3> = entities.iter().map(|e| e.center).collect();
    let labels = pipeline::nearest_centre_labels(&points, &centres);
    let mut members = vec![0usize; entities.len()];
    for &l in &labels {
        members[l as usize] += 1;
    }
    let errors: Vec<f64> = pipeline::cluster_errors(&points, &labels, &entities)
        .into_iter()
        .zip(members.iter())
        .filter(|(_, n)| **n > 0)
        .map(|(e, _)| e)
        .collect();
    let memory = MemoryRow::new(points.len(), entities.len());
    EvalReport {
        points: points.len(),
        errors: ErrorStats::from_errors(&errors),
        cloud_bytes: memory.cloud_bytes,
        map_bytes: memory.map_bytes,
        percent: memory.percent,
    }
}

#[derive(Serialize)]
struct InfoReport {
    entities: usize,
    kinds: KindCounts,
    origin: [f64; 3],
    /// World bounding box of the entity centres.
    center_min: [f64; 3],
    center_max: [f64; 3],
    /// Smallest and largest finite semi-axis.
    semi_axis_min: f64,
    semi_axis_max: f64,
    /// The paper's count: 24 bytes per entity.
    map_bytes: usize,
    file_bytes: u64,
    /// How `.mema` stores (or would store) these entities, and its bytes per entity.
    layout: String,
    record_bytes: usize,
    /// Entities with a rotation other than the identity.
    oriented: usize,
}

fn layout_name(layout: &mema_core::map::Layout) -> &'static str {
    match layout {
        mema_core::map::Layout::AxisAligned => "version 1, axis-aligned f32",
        mema_core::map::Layout::Oriented => "version 2, oriented f32",
        mema_core::map::Layout::Quantized(_) => "version 2, oriented, quantized",
    }
}

pub fn info(args: &InfoArgs) -> Result<()> {
    let map = HostMap::read(&args.map)?;
    let file_bytes = std::fs::metadata(&args.map).map(|m| m.len()).unwrap_or(0);
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let (mut rmin, mut rmax) = (f64::INFINITY, 0.0f64);
    for e in &map.entities {
        let c = map.world_center(&e.entity);
        for j in 0..3 {
            lo[j] = lo[j].min(c[j]);
            hi[j] = hi[j].max(c[j]);
        }
        for r in e.entity.semi_axes().into_iter().filter(|r| r.is_finite()) {
            rmin = rmin.min(r as f64);
            rmax = rmax.max(r as f64);
        }
    }
    let r = InfoReport {
        entities: map.entities.len(),
        kinds: KindCounts::of(&map),
        origin: map.origin,
        center_min: lo,
        center_max: hi,
        semi_axis_min: rmin,
        semi_axis_max: rmax,
        map_bytes: map.entities.len() * stats::MAP_BYTES_PER_ENTITY,
        file_bytes,
        layout: layout_name(&map.layout()).into(),
        oriented: map
            .entities
            .iter()
            .filter(|e| !e.entity.rotation.is_identity())
            .count(),
        record_bytes: map.layout().record_len(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!("{}: {} entities", args.map.display(), r.entities);
        println!(
            "kinds: {} ellipsoid, {} sphere, {} pseudocylinder, {} plane_pair",
            r.kinds.ellipsoid, r.kinds.sphere, r.kinds.pseudocylinder, r.kinds.plane_pair
        );
        println!("origin: {:?}", r.origin);
        if r.entities == 0 {
            println!("centres: none; finite semi-axes: none (the map is empty)");
        } else {
            println!("centres: {:?} .. {:?}", r.center_min, r.center_max);
            println!(
                "finite semi-axes: {} .. {}",
                r.semi_axis_min, r.semi_axis_max
            );
        }
        println!(
            "layout: {} ({} bytes an entity), {} of {} entities oriented",
            r.layout, r.record_bytes, r.oriented, r.entities
        );
        println!(
            "bytes: {} on disk ({} at the paper's 24 per entity)",
            r.file_bytes, r.map_bytes
        );
    }
    Ok(())
}

pub fn ablation(args: &AblationArgs) -> Result<()> {
    let cloud = load_cloud(&args.input)?;
    crate::bench::ablation::run(&cloud, args.k, args.seed, args.json)
        .with_context(|| args.input.display().to_string())
}

pub fn stream_bench(args: &crate::cli::StreamBenchArgs) -> Result<()> {
    let config = args.fit.config(args.k)?;
    let capacity = crate::link::commands::capacity(args.k, &args.shape)?;
    let cloud = load_cloud(&args.input)?;
    let r = crate::bench::stream::run(
        &cloud,
        &config,
        capacity,
        args.repetitions,
        args.shape.tolerance.unwrap_or(0.0),
        args.shape.model,
    )
    .with_context(|| args.input.display().to_string())?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!(
            "{}: {} points, k = {}, model {:?}\n  entities: stream {} / batch {}\n  mean eq. 13 error: stream {:.6} / batch {:.6} ({:+.1}%), stream max {:.6}\n  two-way score, stream / batch: Chamfer {:.6} / {:.6}, accuracy mean {:.6} / {:.6}, completeness mean {:.6} / {:.6}, phantom {:.3} / {:.3}\n  ingest, one thread: mapper {:.0} points/s ({:.1}x SRI-500), wire+mapper {:.0} points/s ({:.1}x)\n  final refit {:.3} s, {} merges",
            args.input.display(),
            r.points,
            r.k,
            r.model,
            r.stream_entities,
            r.batch_entities,
            r.stream_mean_error,
            r.batch_mean_error,
            r.error_change_percent,
            r.stream_max_error,
            r.stream_score.chamfer,
            r.batch_score.chamfer,
            r.stream_score.accuracy.mean,
            r.batch_score.accuracy.mean,
            r.stream_score.completeness.mean,
            r.batch_score.completeness.mean,
            r.stream_score.phantom,
            r.batch_score.phantom,
            r.mapper_points_per_s,
            r.mapper_vs_sri500,
            r.wire_points_per_s,
            r.wire_vs_sri500,
            r.finish_seconds,
            r.merges
        );
    }
    Ok(())
}

/// What `mema map --tolerance` reports.
#[derive(Serialize)]
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
    pub output: String,
}

fn map_to_tolerance(
    args: &MapArgs,
    tolerance: f64,
    model: Model,
    shell: mema_core::shell::ShellParams,
) -> Result<()> {
    if !(tolerance > 0.0 && tolerance.is_finite()) {
        return Err(crate::cli::UsageError(format!(
            "--tolerance {tolerance} must be a positive length in the cloud's units"
        ))
        .into());
    }
    if args.capacity == 0 {
        return Err(crate::cli::UsageError("--capacity must be at least 1".into()).into());
    }
    let config = args.fit.config(1)?;
    let voxel = args
        .voxel
        .map(crate::mapping::filter::check_voxel)
        .transpose()?;
    check_output(&args.output)?;
    if let Some(labels) = &args.labels {
        check_output_file(labels, "labels")?;
    }
    let (cloud, _) = crate::mapping::filter::apply(load_cloud(&args.input)?, args.crop, voxel)
        .with_context(|| args.input.display().to_string())?;
    let fit = match model {
        Model::Paper => crate::mapping::tolerance::EntityFit::Paper(config.fit),
        // As in shells_report: shells never degenerate.
        Model::Shells => crate::mapping::tolerance::EntityFit::shells_for(
            &cloud.points,
            mema_core::shell::ShellParams {
                degeneration: mema_core::Degeneration {
                    threshold: f64::INFINITY,
                    ..config.fit.degeneration
                },
                ..shell
            },
        ),
    };
    let outcome = crate::mapping::tolerance::build(
        &cloud.points,
        tolerance,
        args.capacity,
        args.voronoi_rounds,
        config.seed,
        &fit,
    )
    .with_context(|| args.input.display().to_string())?;
    let tol = config.fit.degeneration.sphere_tolerance;
    let map = HostMap {
        origin: cloud.origin,
        entities: outcome
            .nodes
            .iter()
            .map(|n| mema_core::MapEntity {
                entity: n.entity,
                kind: n.entity.kind(tol),
            })
            .collect(),
        quantization: match fit {
            crate::mapping::tolerance::EntityFit::Shells { grid, .. } => Some(grid),
            crate::mapping::tolerance::EntityFit::Paper(_) => None,
        },
    };
    map.write(&args.output)?;
    if let Some(path) = &args.labels {
        let mut labels = vec![0u32; cloud.points.len()];
        for (c, node) in outcome.nodes.iter().enumerate() {
            for &i in &node.members {
                if let Some(l) = labels.get_mut(i as usize) {
                    *l = c as u32;
                }
            }
        }
        write_labels(path, &labels)?;
    }
    let errors: Vec<f64> = outcome.nodes.iter().map(|n| n.error).collect();
    let report = ToleranceReport {
        tolerance,
        k: map.entities.len(),
        model,
        memory: MemoryRow::with_entity_bytes(
            cloud.points.len(),
            map.entities.len(),
            model.bytes_per_entity(),
        ),
        ellipsoidal: ErrorStats::from_errors(&errors),
        clusters_over_tolerance: errors.iter().filter(|&&e| e > tolerance).count(),
        splits: outcome.splits,
        merges: outcome.merges,
        capacity_reached: outcome.capacity_reached,
        kinds: KindCounts::of(&map),
        errors,
        output: args.output.display().to_string(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "tolerance {tolerance}: k = {} ({} splits, {} merges{})",
        report.k,
        report.splits,
        report.merges,
        if report.capacity_reached {
            ", capacity reached"
        } else {
            ""
        }
    );
    println!("{}", stats::MEMORY_HEADER);
    println!("{}", stats::format_memory_row(&report.memory));
    println!();
    println!(
        "eq. 13 error per cluster, {} over the tolerance",
        report.clusters_over_tolerance
    );
    println!("{}", stats::ERROR_HEADER);
    println!(
        "{}",
        stats::format_error_row("ellipsoidal", &report.ellipsoidal)
    );
    println!(
        "kinds: {} ellipsoid, {} sphere, {} pseudocylinder, {} plane_pair",
        report.kinds.ellipsoid,
        report.kinds.sphere,
        report.kinds.pseudocylinder,
        report.kinds.plane_pair
    );
    eprintln!("wrote {}", report.output);
    Ok(())
}

/// One cluster index per line, atomically.
pub fn write_labels(path: &Path, labels: &[u32]) -> Result<()> {
    let mut text = String::with_capacity(labels.len() * 4);
    for l in labels {
        text.push_str(&l.to_string());
        text.push('\n');
    }
    crate::io::mapfile::write_file_atomically(path, text.as_bytes(), "labels")
}
