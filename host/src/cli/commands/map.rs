//! `mema map`: the arguments checked in the order the user reads them, the library's
//! [`mema::batch`] run, and Tables 2 and 4 (or one JSON object).

use anyhow::{Context, Result};
use mema::analysis::stats;
use mema::batch::{MapReport, RaysSeen, ToleranceOptions, map_cloud_with, map_to_tolerance};
use mema::io::Units;
use mema::io::output::{check_map_output, check_output_file, write_labels};
use mema::io::read::{ClassDrops, input_name};
use mema::link::scanner::{scans_of_input, unit_name};
use mema::link::stream::{Capacity, link_params, stream_scans};
use mema::mapping::filter::{self, FilterCounts, check_voxel};
use mema::mapping::{MIN_POINTS_PER_ENTITY, Model, PipelineConfig, ShellModel, most_entities};
use mema_core::shell::ShellParams;

use super::{check_bag_args, read_input};
use crate::cli::args::fit::BoundsArg;
use crate::cli::args::{EntityArg, MapArgs};
use crate::cli::errors::UsageError;

/// The shell model `mema map`'s arguments ask for, checked before any work.
fn shell_model(args: &MapArgs) -> Result<ShellModel> {
    let model = ShellModel {
        shell: ShellParams {
            tangent_scale: args.tangent_scale,
            normal_scale: args.normal_scale,
            ..Default::default()
        },
        surface_rounds: args.surface_rounds,
        free_space: args.free_space,
        ray_shaping: !args.no_ray_shaping,
    };
    model.check()?;
    Ok(model)
}

pub fn map(args: &MapArgs) -> Result<()> {
    let model = if args.paper {
        Model::Paper
    } else {
        args.model.into()
    };
    if model == Model::Shells && args.entity == EntityArg::Sphere {
        return Err(UsageError(
            "--entity sphere is the paper's comparison; add --paper (or --model paper)".into(),
        )
        .into());
    }
    // Only the shells keep free space: asked for elsewhere, it would be silently missing.
    if args.free_space {
        let without = if model == Model::Paper {
            Some("the paper's model (--paper)")
        } else if args.tolerance.is_some() {
            Some("--tolerance")
        } else {
            None
        };
        if let Some(without) = without {
            return Err(UsageError(format!(
                "--free-space is kept by the shells' maps only, not with {without}"
            ))
            .into());
        }
    }
    let shells = shell_model(args)?;
    if let Some(t) = args.tolerance {
        return tolerance(args, t, model, shells.shell);
    }
    let k = match args.bytes {
        Some(bytes) => model.entities_in(bytes)?,
        None => args.k.unwrap_or(0),
    };
    let mut config = args.fit.config(k)?;
    let voxel = args.voxel.map(check_voxel).transpose()?;
    check_map_output(&args.output)?;
    if args.stream {
        return stream_map(args, &config, model);
    }
    if let Some(labels) = &args.labels {
        check_output_file(labels, "labels")?;
    }
    let (cloud, units) = read_input(&args.input, &args.units, &args.bag, args.outliers)?;
    let (cloud, mut counts) =
        filter::apply(cloud, args.crop, voxel).with_context(|| input_name(&args.input))?;
    // A map that keeps free space agrees with it: what other scans saw through is not surface.
    let cloud = if shells.free_space && model == Model::Shells {
        let (carved, dropped) = mema::mapping::carve::carve(cloud);
        counts.carved = Some(dropped);
        carved
    } else {
        cloud
    };
    // The budget holds the scans' free space too: its entities are what is left.
    if let (Some(bytes), true) = (args.bytes, shells.free_space) {
        config.k = model.entities_beside_free_space(bytes, cloud.sensors.origins.len())?;
    }
    // A budget is an upper bound: past a quarter of the points, clusters of one to three points
    // have no shape to fit, so a small cloud gets fewer entities than the bytes could hold.
    let most = most_entities(cloud.points.len());
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
        args.entity.into(),
        &args.output,
        args.labels.as_deref(),
    )
    .with_context(|| input_name(&args.input))?;
    report.set_filter(counts);
    if !warn_if_degenerate(&report, args.fit.threshold, &units) {
        warn_if_on_bounds(&report, args, &units);
    }
    print_map_report(&report, &units, args.json)
}

/// `mema map --stream`: the bytes `mema scanner-sim` would send of the file, through the
/// receiver and the streaming mapper `mema stream` maps with.
fn stream_map(args: &MapArgs, config: &PipelineConfig, model: Model) -> Result<()> {
    let capacity = Capacity::checked(config.k, args.working, false)?;
    check_bag_args(&args.input, &args.bag)?;
    let scans = scans_of_input(&args.input, args.units.units.as_ref(), &args.bag.options())
        .with_context(|| args.input.display().to_string())?;
    let (sent, link, map) = stream_scans(
        &scans,
        link_params(config, capacity, None, model),
        args.free_space,
    )?;
    map.write(&args.output)?;
    let summary = StreamMapSummary {
        map: args.output.display().to_string(),
        scans: sent.scans,
        points: link.mapper.stats().points,
        unit_exponent: sent.unit_exponent,
        spacing: sent.spacing,
        entities: map.entities.len(),
        carved: link.mapper.stats().carved,
        origin: map.origin,
    };
    let carved = if args.free_space {
        format!(
            ", {} clusters carved (seen through by two later scans)",
            summary.carved
        )
    } else {
        String::new()
    };
    eprintln!(
        "mema: map --stream: {} scans, {} points in units of {}, {} entities{carved}",
        summary.scans,
        summary.points,
        unit_name(summary.unit_exponent),
        summary.entities
    );
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        println!("{}", summary.map);
    }
    Ok(())
}

/// `mema map --stream --json`.
#[derive(serde::Serialize)]
struct StreamMapSummary {
    map: String,
    scans: usize,
    points: u64,
    /// The wire's unit, `10^e` m, as scanner-sim picks it.
    unit_exponent: i8,
    /// The median nearest-point spacing it was picked from (metres).
    spacing: f64,
    entities: usize,
    /// Clusters carved (`--free-space`): two later scans saw through them.
    carved: u64,
    origin: [f64; 3],
}

/// A warning on stderr when most entities degenerated: clusters wider than the threshold
/// (the paper's 4 m) everywhere mostly mean coordinates in millimetres or feet read as metres.
/// Returns whether it warned.
fn warn_if_degenerate(r: &MapReport, threshold: f64, units: &Units) -> bool {
    let degenerate = r.kinds.pseudocylinder + r.kinds.plane_pair;
    let all = r.memory.entities;
    let most = all > 0 && 2 * degenerate > all;
    if most {
        eprintln!(
            "mema: warning: {degenerate} of {all} entities degenerated (an axis past the {threshold} m threshold); \
             the cloud was read in {units}: if its coordinates are not in that unit, give --units (e.g. --units mm)"
        );
    }
    most
}

/// A warning on stderr when most fitted semi-axes ended on a bound of DE's search box: the
/// box chose them, not eq. 12. With `--bounds threshold` the upper bound is in metres, so a
/// cloud in millimetres read as metres puts every axis on it (the bunny: all 180, though only
/// half its entities degenerate); `--alpha 0` leaves eq. 12 only its volume term, which puts
/// every axis on the lower bound.
fn warn_if_on_bounds(r: &MapReport, args: &MapArgs, units: &Units) {
    let Some(on) = r.axes_on_bound.filter(|b| b.most()) else {
        return;
    };
    let the_box = match args.fit.bounds {
        BoundsArg::Spread => "spread: 0.05 to 3 times each cluster's RMS radius".to_owned(),
        BoundsArg::Threshold => format!(
            "threshold: 0.05 times each cluster's RMS radius to the {} m threshold",
            args.fit.threshold
        ),
    };
    eprintln!(
        "mema: warning: {} of {} fitted semi-axes ended on a bound of the fit's search box ({} on its lower bound, {} on its upper; --bounds {the_box}), so the box chose their lengths, not eq. 12; \
         the cloud was read in {units}: if its coordinates are not in that unit, give --units (e.g. --units mm), otherwise consider another --bounds, --alpha or --volume",
        on.lower + on.upper,
        on.axes,
        on.lower,
        on.upper
    );
}

/// `mema map --tolerance T`.
fn tolerance(args: &MapArgs, tolerance: f64, model: Model, shell: ShellParams) -> Result<()> {
    let options = ToleranceOptions {
        tolerance,
        capacity: args.capacity,
        voronoi_rounds: args.voronoi_rounds,
    };
    options.check()?;
    let config = args.fit.config(1)?;
    let voxel = args.voxel.map(check_voxel).transpose()?;
    check_map_output(&args.output)?;
    if args.stream {
        return stream_map(args, &config, model);
    }
    if let Some(labels) = &args.labels {
        check_output_file(labels, "labels")?;
    }
    let (cloud, units) = read_input(&args.input, &args.units, &args.bag, args.outliers)?;
    let (cloud, counts) =
        filter::apply(cloud, args.crop, voxel).with_context(|| input_name(&args.input))?;
    let built = map_to_tolerance(&cloud, &options, &config, model, shell)
        .with_context(|| input_name(&args.input))?;
    built.map.write(&args.output)?;
    if let Some(path) = &args.labels {
        write_labels(path, &built.labels(cloud.points.len()))?;
    }
    let report = built.report(&cloud, &args.output);
    if args.json {
        let mut doc = serde_json::to_value(&report)?;
        doc["unit"] = serde_json::to_value(&units)?;

        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    println!("unit: {units}, scaled to metres");
    println!(
        "{}",
        points_line(
            &counts,
            cloud.dropped_non_finite,
            &cloud.dropped_by_class,
            cloud.outliers.dropped,
            cloud.no_returns
        )
    );
    println!("{}", rays_line(RaysSeen::of(&cloud)));
    println!(
        "tolerance {tolerance} m: k = {} ({} splits, {} merges{})",
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
        "eq. 13 as fitted (m; each cluster's error on its own points), {} over the tolerance",
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

fn print_map_report(r: &MapReport, units: &Units, json: bool) -> Result<()> {
    if json {
        let mut doc = serde_json::to_value(r)?;
        doc["unit"] = serde_json::to_value(units)?;

        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    println!("unit: {units}, scaled to metres; map in metres");
    println!(
        "{}",
        points_line(
            &r.filter,
            r.dropped_non_finite,
            &r.dropped_by_class,
            r.outliers.dropped,
            r.no_returns
        )
    );
    println!("{}", rays_line(r.rays));
    if let Some(f) = r.free_space {
        println!(
            "free space: range images of {} scan{} ({} x {} pixels each), {} bytes of the map",
            f.images,
            if f.images == 1 { "" } else { "s" },
            mema::io::free_space::ROWS,
            mema::io::free_space::COLUMNS,
            f.bytes
        );
    }
    if let Some(s) = r.ray_shaping {
        println!("{}", ray_shaping_line(&s));
    }
    println!(
        "Table 2: memory (12 bytes per point, {} per entity)",
        r.memory.map_bytes / r.memory.entities.max(1)
    );
    println!("{}", stats::MEMORY_HEADER);
    println!("{}", stats::format_memory_row(&r.memory));
    println!();
    println!(
        "Table 4: eq. 13 as fitted (m; each cluster's error on its own points), over {} clusters",
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

/// The points the map was made of: read, dropped for a NaN or infinite coordinate (a scanner's
/// empty returns), by class or as isolated, and the input's slots these add up to (over every
/// scan of a registration file or message of a bag); then what `--crop` and `--voxel` left.
fn points_line(
    counts: &FilterCounts,
    dropped: usize,
    by_class: &ClassDrops,
    isolated: usize,
    no_returns: usize,
) -> String {
    let mut line = format!(
        "points: {} read, {dropped} more dropped for a NaN or infinite coordinate",
        counts.read
    );
    if by_class.total() > 0 {
        line.push_str(&format!(
            ", {} left out by class (--classes)",
            by_class.total()
        ));
    }
    if isolated > 0 {
        line.push_str(&format!(", {isolated} as isolated (--outliers)"));
    }
    if no_returns > 0 {
        line.push_str(&format!(
            ", {no_returns} at their sensor origin (no return, --min-range)"
        ));
    }
    // As `MapReport::set_filter` counts them (the tolerance mode's report has no drops).
    let slots = counts.read + dropped + by_class.total() + isolated + no_returns;
    line.push_str(&format!(": {slots} in the input"));
    let mut after = "; ";
    if let Some(n) = counts.cropped {
        line.push_str(&format!("{after}{n} inside --crop"));
        after = ", ";
    }
    if let Some(n) = counts.voxelized {
        line.push_str(&format!("{after}{n} after --voxel"));
        after = ", ";
    }
    if let Some(n) = counts.carved {
        line.push_str(&format!(
            "{after}{n} left out as seen through by two other scans (--free-space)"
        ));
    }
    line
}

/// What shaping the shells to the rays did, and whether the map kept it.
fn ray_shaping_line(s: &mema::batch::RayShapingReport) -> String {
    let share = |n: usize| 100.0 * n as f64 / s.rays.max(1) as f64;
    format!(
        "ray shaping: {} of {} sampled rays agree within {:.1} mm and {} stop early as made; shaped ({} shells changed): {} agree, {} stop early; Chamfer {:.6} -> {:.6} m, {}",
        format_args!("{:.1}%", share(s.agree[0])),
        s.rays,
        1e3 * s.tolerance,
        format_args!("{:.1}%", share(s.early[0])),
        s.changed,
        format_args!("{:.1}%", share(s.agree[1])),
        format_args!("{:.1}%", share(s.early[1])),
        s.chamfer[0],
        s.chamfer[1],
        if s.kept {
            "kept"
        } else {
            "not kept (--no-ray-shaping is the same map)"
        }
    )
}

/// Whether the points were rays: where they were seen from, or that no free space was recorded.
fn rays_line(rays: Option<RaysSeen>) -> String {
    match rays {
        Some(r) => format!(
            "rays: {} points seen from {} sensor origin{}",
            r.points,
            r.origins,
            if r.origins == 1 { "" } else { "s" }
        ),
        None => "rays: none (the input says nowhere where its sensor was): no free space recorded"
            .to_owned(),
    }
}
