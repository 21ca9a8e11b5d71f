//! `mema eval`: eq. 13 (Tables 2 and 4) and, beside it, the two-way fidelity score and the
//! bytes the map file really takes.

use anyhow::{Context, Result};
use mema::analysis::eval::{
    EvalDocument, EvalReport, FileBytes, MAX_SAMPLES, WorldBox, evaluate, points_in_map_frame,
};
use mema::analysis::fidelity::{self, FidelityScore};
use mema::analysis::stats::{self, MemoryRow};
use mema::io::cloud::LocalCloud;
use mema::io::mapfile::HostMap;
use mema::io::read::{Outliers, input_name};
use mema::progress::stage;
use mema::query::held_out::{MapRays, RayScores, held_out_rays};

use super::read_input;
use crate::cli::args::EvalArgs;
use crate::cli::errors::UsageError;

pub fn eval(args: &EvalArgs) -> Result<()> {
    if args.samples == 0 || args.samples > MAX_SAMPLES {
        return Err(UsageError(format!(
            "--samples {} must be between 1 and {MAX_SAMPLES}",
            args.samples
        ))
        .into());
    }
    let (cloud, units) = read_input(&args.input, &args.units, &args.bag, Outliers::Unchecked)?;
    let map = HostMap::read(&args.map)?;
    if map.entities.is_empty() {
        anyhow::bail!("{}: the map has no entities", args.map.display());
    }
    if args.rays {
        return eval_rays(args, &cloud, &map);
    }
    let bytes = FileBytes::of(&args.map, &map)?;
    let eq13 = stage("evaluating", || evaluate(&cloud, &map));
    warn_if_apart(args, &cloud, &map, &eq13);
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    let score = stage("scoring", || {
        fidelity::two_way_score(
            &points_in_map_frame(&cloud, &map),
            &entities,
            args.seed,
            args.samples,
        )
    })
    .with_context(|| format!("{} against {}", args.map.display(), input_name(&args.input)))?;
    if args.json {
        let doc = EvalDocument {
            eq13,
            fidelity: score,
            bytes,
            dropped_non_finite: cloud.dropped_non_finite,
            unit: serde_json::to_value(&units)?,
        };
        println!("{}", serde_json::to_string(&doc)?);
        return Ok(());
    }
    println!("cloud unit: {units}, scaled to metres; lengths below in metres");
    // As map's points line: the points read and every drop add up to the input's slots.
    let by_class = cloud.dropped_by_class.total();
    let class_text = if by_class > 0 {
        format!(", {by_class} left out by class (--classes)")
    } else {
        String::new()
    };
    println!(
        "cloud points: {} read, {} more dropped for a NaN or infinite coordinate{class_text}: {} in the input",
        eq13.points,
        cloud.dropped_non_finite,
        eq13.points + cloud.dropped_non_finite + by_class
    );
    let record = map.layout().record_len();
    println!("Table 2: memory (12 bytes per point, {record} per entity)");
    println!("{}", stats::MEMORY_HEADER);
    println!(
        "{}",
        stats::format_memory_row(&MemoryRow::with_entity_bytes(
            eq13.points,
            map.entities.len(),
            record
        ))
    );
    println!();
    println!(
        "eq. 13 by nearest centre (m; each point joins the entity of its nearest centre, where\n\
         map's \"eq. 13 as fitted\" keeps each cluster's own points), over {} non-empty clusters",
        eq13.errors.clusters
    );
    println!("{}", stats::ERROR_HEADER);
    println!("{}", stats::format_error_row("map", &eq13.errors));
    println!();
    print_score(&score, args.seed);
    println!(
        "bytes: {} in the file, {:.2} per entity past its {}-byte header",
        bytes.file_bytes, bytes.bytes_per_entity, bytes.header_bytes
    );
    Ok(())
}

/// `mema eval --rays`: the cloud's points cast as held-out rays at the map.
fn eval_rays(args: &EvalArgs, cloud: &LocalCloud, map: &HostMap) -> Result<()> {
    let tolerance = args.ray_tolerance;
    if !(tolerance > 0.0 && tolerance.is_finite()) {
        return Err(UsageError(format!(
            "--ray-tolerance {tolerance} must be a positive length (metres)"
        ))
        .into());
    }
    if cloud.sensors.is_empty() {
        return Err(UsageError(format!(
            "{}: --rays needs points with their sensor origins, and this input says nowhere where its sensor was (give a .conf of frames with their poses, a PCD with VIEWPOINT, a KITTI scan or a bag with --frame)",
            input_name(&args.input)
        ))
        .into());
    }
    let rays = held_out_rays(cloud);
    let scores = stage("casting", || {
        MapRays::new(map, tolerance).map(|model| model.score(&rays))
    })?;
    if args.json {
        let doc = serde_json::json!({
            "rays": scores,
            "no_returns": cloud.no_returns,
            "dropped_non_finite": cloud.dropped_non_finite,
        });
        println!("{}", serde_json::to_string(&doc)?);
        return Ok(());
    }
    print_rays(&scores, cloud);
    Ok(())
}

fn print_rays(s: &RayScores, cloud: &LocalCloud) {
    println!(
        "rays: {} held out from {} sensor origin(s) ({} no-returns at their origin left out), tolerance {} m",
        s.rays,
        cloud.sensors.origins.len(),
        cloud.no_returns,
        s.tolerance
    );
    let pct = |f: f64| 100.0 * f;
    println!(
        "agree {:.1}% ({}), stop early {:.1}% ({}, map surface where the sensor saw through), run on {:.1}% ({}, no map surface by the measured range)",
        pct(s.agree_fraction),
        s.agree,
        pct(s.early_fraction),
        s.early,
        pct(s.run_on_fraction),
        s.run_on
    );
    let o = &s.occupancy;
    println!(
        "occupancy of {} points along the rays ({} ends, occupied; the rest free): accuracy {:.3}, ROC AUC {:.3} (unknown counts 0.5); the map said {} occupied, {} free, {} unknown; {} free points said occupied",
        o.samples,
        o.occupied_samples,
        o.accuracy,
        o.auc,
        o.said_occupied,
        o.said_free,
        o.said_unknown,
        o.free_said_occupied
    );
}

/// One warning line each when the map and the cloud do not look like each other's: their
/// boxes do not meet, or most entities are nearest to none of the points. Either way the
/// scores below measure two unrelated things.
fn warn_if_apart(args: &EvalArgs, cloud: &LocalCloud, map: &HostMap, eq13: &EvalReport) {
    let (map_name, cloud_name) = (args.map.display(), input_name(&args.input));
    if let (Some(c), Some(m)) = (WorldBox::of_cloud(cloud), WorldBox::of_map(map))
        && !c.overlaps(&m)
    {
        eprintln!(
            "mema: warning: {map_name} lies apart from {cloud_name} (entities within {:?}..{:?} m, points within {:?}..{:?} m): the map was made from another cloud, or one of them is in another unit or frame (--units)",
            round(m.min),
            round(m.max),
            round(c.min),
            round(c.max)
        );
    }
    let entities = map.entities.len();
    let empty = entities.saturating_sub(eq13.errors.clusters);
    if 2 * empty > entities {
        eprintln!(
            "mema: warning: {empty} of {entities} entities of {map_name} are nearest to none of the points of {cloud_name}: the map likely covers another cloud, or another part of this one"
        );
    }
}

/// A corner rounded to the millimetre, for a readable message.
fn round(p: [f64; 3]) -> [f64; 3] {
    p.map(|v| (v * 1000.0).round() / 1000.0)
}

fn print_score(s: &FidelityScore, seed: u64) {
    println!(
        "two-way score, lengths in metres ({} surface samples, seed {seed}):",
        s.samples
    );
    println!(
        "{:<28} {:>12} {:>12} {:>12} {:>12}",
        "", "mean", "rms", "p95", "max"
    );
    println!(
        "{:<28} {:>12.6} {:>12.6} {:>12.6} {:>12.6}",
        "accuracy (cloud to map)", s.accuracy.mean, s.accuracy.rms, s.accuracy.p95, s.accuracy.max
    );
    println!(
        "{:<28} {:>12.6} {:>12.6} {:>12.6} {:>12}",
        "completeness (map to cloud)",
        s.completeness.mean,
        s.completeness.rms,
        s.completeness.p95,
        "-"
    );
    println!(
        "tau {:.6} m (2 x median point spacing): phantom {:.1}% of {:.6} m^2 surface area; precision {:.3}, recall {:.3}, F-score {:.3}",
        s.tau,
        100.0 * s.phantom,
        s.area,
        s.precision,
        s.recall,
        s.f_score
    );
    println!("chamfer {:.6} m", s.chamfer);
}
