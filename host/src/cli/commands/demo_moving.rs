//! `mema demo --moving`: the headline use of the streaming mapper. A robot drives through the
//! built-in scene; at each stop its rangefinder's scan goes over the link's bytes in the
//! sensor's frame after the stop's pose, and the streaming mapper builds one map in the world
//! frame. The scans' rays are then cast again at that map and at the scene (as `mema
//! query-bench` does for the static scan), and the map is scored against the points.

use anyhow::{Context, Result};
use mema::analysis::fidelity::{FidelityScore, two_way_score};
use mema::io::cloud::LocalCloud;
use mema::io::drive::{DriveConfig, drive};
use mema::io::output::check_output_file;
use mema::io::scene::Scene;
use mema::io::write_cloud::write_ply;
use mema::link::scanner::{SensorScan, unit_name};
use mema::link::stream::{Capacity, link_params, stream_scans};
use mema::mapping::Model;
use mema::progress::stage;
use mema::query::recast::{Recast, recast};
use serde::Serialize;

use super::demo_files::{DemoFiles, shell_word, write_picture};
use crate::cli::args::DemoArgs;
use mema::render::picture::TitleError;

/// Surface samples of the two-way score: eval's default.
const SCORE_SAMPLES: usize = 200_000;

/// `mema demo --moving --json`.
#[derive(Serialize)]
struct MovingDemo<'a> {
    stops: usize,
    points: usize,
    /// The wire's unit, `10^e` m.
    unit_exponent: i8,
    poses_received: u64,
    frames_without_pose: u64,
    entities: usize,
    recast: &'a Recast,
    score: &'a FidelityScore,
    files: &'a DemoFiles,
}

pub fn demo_moving(args: &DemoArgs) -> Result<()> {
    let config = args.fit.config(args.k)?;
    let capacity = Capacity::checked(config.k, None, false)?;
    let model = if args.paper {
        Model::Paper
    } else {
        Model::Shells
    };
    let dir = &args.out_dir();
    std::fs::create_dir_all(dir)
        .with_context(|| format!("--out-dir {}: cannot make the directory", dir.display()))?;
    let files = DemoFiles::in_dir(dir);
    check_output_file(&files.map, "map")?;
    let scene = Scene::demo();
    let stops = stage("driving", || drive(&scene, &DriveConfig::default()));
    let world: Vec<[f64; 3]> = stops
        .iter()
        .flat_map(|s| s.world.points.iter().copied())
        .collect();
    write_ply(&files.scan, &world)?;
    let sensor: Vec<SensorScan> = stops.iter().map(SensorScan::of_drive).collect();
    let (sent, link, map) = stage("streaming", || {
        stream_scans(&sensor, link_params(&config, capacity, None, model), false)
    })?;
    map.write(&files.map)?;
    let views: Vec<_> = stops.iter().map(|s| s.config.clone()).collect();
    let recast = stage("re-casting", || recast(&map, &scene, &views))?;
    let in_map: Vec<[f64; 3]> = world
        .iter()
        .map(|p| [0, 1, 2].map(|j| p[j] - map.origin[j]))
        .collect();
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    let score = stage("scoring", || {
        two_way_score(&in_map, &entities, config.seed, SCORE_SAMPLES)
    })?;
    let cloud = LocalCloud::from_world(&world);
    write_picture(
        &cloud,
        map.clone(),
        &files.picture,
        TitleError::NearestCentre,
    )?;
    let doc = MovingDemo {
        stops: stops.len(),
        points: sent.points,
        unit_exponent: sent.unit_exponent,
        poses_received: link.receiver_stats().poses,
        frames_without_pose: link.receiver_stats().no_pose,
        entities: map.entities.len(),
        recast: &recast,
        score: &score,
        files: &files,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    println!(
        "mema demo --moving: a robot drives an arc through the built-in scene and scans at {} stops.\n\
         Each scan ({} points in all) went over the link's bytes in the sensor's frame, after its\n\
         pose, in units of {}; the streaming mapper put them in one world-frame map of {} entities\n\
         ({} poses received, {} frames without their pose).",
        doc.stops,
        doc.points,
        unit_name(doc.unit_exponent),
        doc.entities,
        doc.poses_received,
        doc.frames_without_pose
    );
    println!();
    println!("Every ray of every stop cast again, at the map and at the scene (noise-free):");
    println!("{}", recast.lines("the drive re-cast at its map"));
    println!();
    println!(
        "Two-way score against the points (as `mema eval`): accuracy mean {:.4} m, completeness\n\
         mean {:.4} m, Chamfer {:.4} m, F-score {:.3} at tau {:.4} m.",
        score.accuracy.mean, score.completeness.mean, score.chamfer, score.f_score, score.tau
    );
    println!();
    println!("Wrote, in {}:", shell_word(dir));
    println!(
        "  scan.ply     the scans in the world frame ({} points, PLY)",
        doc.points
    );
    println!(
        "  map.mema     the streamed map ({} entities)",
        doc.entities
    );
    println!("  picture.png  the map's entities drawn over the points");
    println!();
    println!("Next:");
    let port = shell_word(&dir.join("drive.bin"));
    println!("  mema scanner-sim --port {port}");
    println!("      the same drive as the bytes a scanner sends (poses, then points)");
    println!(
        "  mema replay {port} -k {} -o {}",
        args.k,
        shell_word(&dir.join("again.mema"))
    );
    println!("      map those bytes: the same map, byte for byte");
    Ok(())
}
