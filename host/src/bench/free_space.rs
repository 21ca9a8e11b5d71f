//! `mema bench --only free-space` (issue 29): mema's maps and OctoMap at equal bytes on the
//! shared Ouster sweeps, in one run. Sweeps 0 and 2 are mapped with their poses, sweep 1's rays
//! are cast again at each map and scored by one function ([`crate::query::held_out::score`]):
//! agree, stop early, run on, and the occupancy score. OctoMap (pyoctomap, through
//! `scripts/octomap_rays.py`) inserts the same points with their sensor origins
//! (`insertPointCloud` casts every ray) at the finest resolution whose binary tree fits the
//! budget. Ingest rates are points per second of building the map from points in memory.

use anyhow::{Context, Result, bail};
use serde::Deserialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::BenchOptions;
use crate::batch::build_map;
use crate::io::cloud::{LocalCloud, load_input_keeping};
use crate::io::read::Screening;
use crate::mapping::{EntityChoice, FitOptions, Model, ShellModel, most_entities};
use crate::query::held_out::{
    DEFAULT_TOLERANCE, MapRays, Ray, State, held_out_rays, samples, score,
};

/// The budgets measured: the two, and one between them (more bytes must never lower the
/// agreement).
pub const BUDGETS: [usize; 3] = [9_600, 19_200, 38_400];

/// What `scripts/octomap_rays.py` prints.
#[derive(Debug, Deserialize)]
struct OctomapRun {
    resolution: f64,
    bytes: u64,
    insert_s: f64,
    points: usize,
    hits: Vec<Option<f64>>,
    states: Vec<u8>,
}

/// A .conf of the lines of the shared `ouster_os1.conf` naming `frames`, by absolute path.
fn conf_of(data: &Path, dir: &Path, name: &str, frames: &[usize]) -> Result<PathBuf> {
    let conf = std::fs::read_to_string(data.join("ouster_os1.conf"))
        .with_context(|| format!("{}", data.join("ouster_os1.conf").display()))?;
    let mut text = String::new();
    for i in frames {
        let file = format!("ouster_os1_{i}.pcd");
        let line = conf
            .lines()
            .find(|l| l.contains(&file))
            .with_context(|| format!("ouster_os1.conf has no line for {file}"))?;
        let path = std::fs::canonicalize(data.join(&file))?;
        text.push_str(&line.replace(&file, &path.display().to_string()));
        text.push('\n');
    }
    let path = dir.join(name);
    std::fs::write(&path, text)?;
    Ok(path)
}

fn write_f64(path: &Path, rows: impl Iterator<Item = f64>) -> Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for v in rows {
        out.write_all(&v.to_le_bytes())?;
    }
    out.flush()?;
    Ok(())
}

/// Writes what OctoMap is given and asked: each mapped sweep's world points and sensor origin,
/// the held-out rays and the sample points.
fn write_inputs(dir: &Path, mapped: &LocalCloud, rays: &[Ray], samples: &[[f64; 3]]) -> Result<()> {
    let o = mapped.origin;
    let mut frames = Vec::new();
    for (k, (range, origin)) in mapped.sensors.runs().enumerate() {
        let name = format!("frame{k}.f64");
        let points = mapped.points.get(range).unwrap_or_default();
        write_f64(
            &dir.join(&name),
            points
                .iter()
                .flat_map(|p| (0..3).map(move |j| o[j] + f64::from(p.to_array()[j]))),
        )?;
        frames.push(serde_json::json!({ "points": name, "origin": origin }));
    }
    write_f64(
        &dir.join("rays.f64"),
        rays.iter().flat_map(|r| r.origin.into_iter().chain(r.end)),
    )?;
    write_f64(&dir.join("samples.f64"), samples.iter().flatten().copied())?;
    let manifest = serde_json::json!({ "tolerance": DEFAULT_TOLERANCE, "frames": frames });
    std::fs::write(dir.join("manifest.json"), manifest.to_string())?;
    Ok(())
}

fn octomap(python: &Path, script: &Path, dir: &Path, budget: usize) -> Result<OctomapRun> {
    let out = std::process::Command::new(python)
        .arg(script)
        .arg(dir)
        .arg(budget.to_string())
        .output()
        .with_context(|| format!("running {}", python.display()))?;
    if !out.status.success() {
        bail!(
            "{} {}: {}",
            python.display(),
            script.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    serde_json::from_slice(&out.stdout).context("reading octomap_rays.py's output")
}

/// Runs the benchmark and prints its table.
pub fn free_space(args: &BenchOptions) -> Result<()> {
    let python = args
        .python
        .as_deref()
        .context("--only free-space needs --python (a Python with numpy and pyoctomap)")?;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/octomap_rays.py");
    let dir = std::env::temp_dir().join(format!("mema-free-space-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mapped_conf = conf_of(&args.data, &dir, "frames02.conf", &[0, 2])?;
    let held_conf = conf_of(&args.data, &dir, "frame1.conf", &[1])?;
    let (mapped, _) =
        load_input_keeping(&mapped_conf, None, &Default::default(), Screening::MAPPING)?;
    let (held, _) = load_input_keeping(&held_conf, None, &Default::default(), Screening::DEFAULT)?;
    let rays = held_out_rays(&held);
    let sample_points = samples(&rays, DEFAULT_TOLERANCE);
    let points: Vec<[f64; 3]> = sample_points.iter().map(|s| s.point).collect();
    write_inputs(&dir, &mapped, &rays, &points)?;
    println!();
    println!(
        "free space: sweeps 0 and 2 of ouster_os1 mapped ({} points, {} no-returns left out), sweep 1's {} rays cast again, tolerance {DEFAULT_TOLERANCE} m",
        mapped.points.len(),
        mapped.no_returns,
        rays.len()
    );
    println!(
        "| map | bytes | agree | stop early | run on | occupancy accuracy | ROC AUC | free said occupied | ingest points/s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for budget in BUDGETS {
        // The shells as made, the map shaped to its rays, and that map with free space (its
        // scans' range images within the same bytes; two scans, so nothing is carved).
        for (free_space, ray_shaping) in [(false, false), (false, true), (true, true)] {
            let scans = if free_space {
                mapped.sensors.origins.len()
            } else {
                0
            };
            let k = Model::Shells
                .entities_beside_free_space(budget, scans)?
                .min(most_entities(mapped.points.len()));
            let config = FitOptions::default().config(k)?;
            let shells = ShellModel {
                free_space,
                ray_shaping,
                ..ShellModel::default()
            };
            let t = Instant::now();
            let built = build_map(
                &mapped,
                &config,
                Model::Shells,
                shells,
                EntityChoice::Ellipsoid,
            )?;
            let mema_rate = mapped.points.len() as f64 / t.elapsed().as_secs_f64();
            let path = dir.join("map.mema");
            built.map.write(&path)?;
            let bytes = std::fs::metadata(&path)?.len();
            let s = MapRays::new(&built.map, DEFAULT_TOLERANCE)?.score(&rays);
            let name = match (built.report.free_space, ray_shaping) {
                (Some(f), _) => {
                    format!("mema --free-space, k = {k} and {} B of free space", f.bytes)
                }
                (None, true) => format!("mema, k = {k}"),
                (None, false) => format!("mema --no-ray-shaping, k = {k}"),
            };
            row(&name, bytes, &s, mema_rate);
        }
        let run = octomap(python, &script, &dir, budget)?;
        if run.hits.len() != rays.len() || run.states.len() != sample_points.len() {
            bail!(
                "octomap_rays.py answered {} rays and {} samples",
                run.hits.len(),
                run.states.len()
            );
        }
        let states: Vec<State> = run
            .states
            .iter()
            .map(|&s| match s {
                0 => State::Free,
                1 => State::Occupied,
                _ => State::Unknown,
            })
            .collect();
        let o = score(&rays, &run.hits, &sample_points, &states, DEFAULT_TOLERANCE);
        let rate = run.points as f64 / run.insert_s;
        row(
            &format!("OctoMap, {:.3} m voxels", run.resolution),
            run.bytes,
            &o,
            rate,
        );
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

fn row(name: &str, bytes: u64, s: &crate::query::held_out::RayScores, rate: f64) {
    let o = &s.occupancy;
    println!(
        "| {name} | {bytes} | {:.1}% | {:.1}% | {:.1}% | {:.3} | {:.3} | {} | {:.0} |",
        100.0 * s.agree_fraction,
        100.0 * s.early_fraction,
        100.0 * s.run_on_fraction,
        o.accuracy,
        o.auc,
        o.free_said_occupied,
        rate
    );
}
