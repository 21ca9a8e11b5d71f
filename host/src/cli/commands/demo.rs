//! `mema demo`: a first run that explains itself. It maps a simulated scan of the built-in
//! scene, writes the scan, the map and a picture of both where the user can open them, says
//! what the numbers mean, and what to run next on those files.

use anyhow::{Context, Result};
use mema::analysis::stats;
use mema::batch::{MapReport, map_cloud_with};
use mema::io::cloud::LocalCloud;
use mema::io::mapfile::HostMap;
use mema::io::output::check_output_file;
use mema::io::scene::{ScanConfig, Scene, scan};
use mema::io::write_cloud::write_ply;
use mema::mapping::{EntityChoice, Model, ShellModel};
use mema::progress::stage;
use serde::Serialize;
use std::path::Path;

use super::demo_files::{DemoFiles, shell_word, write_picture};
use crate::cli::args::DemoArgs;
use mema::render::picture::TitleError;

/// `mema demo --json`: the map's report (as `mema map --json` gives it) and the files.
#[derive(Serialize)]
struct DemoJson<'a> {
    #[serde(flatten)]
    report: &'a MapReport,
    files: &'a DemoFiles,
    /// The picture's title, with the mean of Table 4 as `report` has it.
    picture_title: String,
}

pub fn demo(args: &DemoArgs) -> Result<()> {
    let config = args.fit.config(args.k)?;
    let dir = &args.out_dir();
    std::fs::create_dir_all(dir)
        .with_context(|| format!("--out-dir {}: cannot make the directory", dir.display()))?;
    let files = DemoFiles::in_dir(dir);
    check_output_file(&files.map, "map")?;
    let scan_config = ScanConfig::default();
    let scan = stage("scanning", || scan(&Scene::demo(), &scan_config));
    write_ply(&files.scan, &scan.points)?;
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
        ShellModel::default(),
        EntityChoice::Ellipsoid,
        &files.map,
        None,
    )
    .context("demo scene")?;
    let map = HostMap::read(&files.map)?;
    let picture_title = write_picture(
        &cloud,
        map,
        &files.picture,
        TitleError::TableFour(&[report.ellipsoidal.mean]),
    )?;
    if args.json {
        let doc = DemoJson {
            report: &report,
            files: &files,
            picture_title,
        };
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    explain(&report, &files, dir, scan_config.range_noise_sigma);
    Ok(())
}

/// Millimetres, for lengths a newcomer reads at a glance.
fn mm(metres: f64) -> String {
    format!("{:.1} mm", 1000.0 * metres)
}

fn explain(r: &MapReport, files: &DemoFiles, dir: &Path, noise: f64) {
    let points = r.memory.points;
    let entities = r.memory.entities;
    let what = match r.model {
        Model::Shells => "oriented shells (thin ellipsoids lying along the surfaces)",
        Model::Paper => "the paper's axis-aligned ellipsoids, fitted by DE on eq. 12",
    };
    println!(
        "mema demo: a simulated rangefinder scan of a built-in scene (a floor, a trash can, a box\n\
         and a person): {points} points, in metres. The points are clustered, and each cluster\n\
         becomes one entity of the map: {entities} {what}."
    );
    println!();
    println!(
        "Memory (the paper's Table 2): the scan at 12 bytes a point, the map at {} bytes an entity.",
        r.memory.map_bytes / entities.max(1)
    );
    println!("{}", stats::MEMORY_HEADER);
    println!("{}", stats::format_memory_row(&r.memory));
    println!();
    println!(
        "Error as fitted (the paper's Table 4, eq. 13): for each cluster, the RMS distance from its points\n\
         to its entity's surface, in metres; its mean, spread (std), extremes and sum over the\n\
         {} clusters.",
        r.ellipsoidal.clusters
    );
    println!("{}", stats::ERROR_HEADER);
    match &r.spherical {
        Some(spherical) => {
            println!("{}", stats::format_error_row("ellipsoidal", &r.ellipsoidal));
            println!("{}", stats::format_error_row("spherical", spherical));
            println!(
                "(spherical: the same clusters fitted with one radius each, the paper's comparison)"
            );
        }
        None => println!("{}", stats::format_error_row("shells", &r.ellipsoidal)),
    }
    println!(
        "So a cluster's points lie {} from its surface on average (RMS; the simulated range noise\n\
         is {}), {} in the worst cluster.",
        mm(r.ellipsoidal.mean),
        mm(noise),
        mm(r.ellipsoidal.max)
    );
    println!(
        "kinds: {} ellipsoid, {} sphere, {} pseudocylinder, {} plane_pair",
        r.kinds.ellipsoid, r.kinds.sphere, r.kinds.pseudocylinder, r.kinds.plane_pair
    );
    println!();
    println!("Wrote, in {}:", shell_word(dir));
    println!("  scan.ply     the scan ({points} points, PLY)");
    println!("  map.mema     the map ({entities} entities)");
    println!("  picture.png  the map's entities drawn over the scan's points");
    println!();
    let (scan, map) = (shell_word(&files.scan), shell_word(&files.map));
    let coarse = shell_word(&dir.join("k100.mema"));
    let top = shell_word(&dir.join("k100.png"));
    println!("Next:");
    println!("  mema info {map}");
    println!("      what the map holds: entities by kind, extent, bytes");
    println!("  mema eval {scan} {map}");
    println!("      score the map against the scan, both ways");
    println!("  mema map {scan} -k 100 -o {coarse}");
    println!("      a coarser map of the same scan (any PLY, PCD, LAS/LAZ or XYZ cloud maps so)");
    println!("  mema draw {scan} {coarse} -o {top} --view top");
    println!("      draw it from above");
}
