//! `mema eval`: eq. 13 (Tables 2 and 4) and, beside it, the two-way fidelity score and the
//! bytes the map file really takes.

use anyhow::{Context, Result};
use serde::Serialize;
use std::path::Path;

use crate::analysis::fidelity::{self, FidelityScore};
use crate::analysis::stats::{self, MemoryRow};
use crate::cli::{EvalArgs, UsageError};
use crate::commands::{EvalReport, LocalCloud, evaluate, load_cloud};
use crate::io::mapfile::{HostMap, MapFormat};
use mema_core::map::MapFile;

/// Past this many surface samples the score costs memory and time for no added precision.
pub const MAX_SAMPLES: usize = 100_000_000;

/// `mema eval --json`: eq. 13's keys first and unchanged, then the score's and the bytes'.
#[derive(Serialize)]
pub struct EvalJson {
    #[serde(flatten)]
    pub eq13: EvalReport,
    #[serde(flatten)]
    pub fidelity: FidelityScore,
    #[serde(flatten)]
    pub bytes: FileBytes,
}

/// What the map file stores, measured on disk.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FileBytes {
    pub file_bytes: u64,
    /// What the file's format takes for a map of no entities: for `.mema` its layout's header
    /// and CRC trailer (40 bytes in version 1, 52 in version 2), for CSV the header line.
    pub header_bytes: u64,
    /// `(file_bytes - header_bytes) / entities`.
    pub bytes_per_entity: f64,
}

impl FileBytes {
    pub fn of(path: &Path, map: &HostMap) -> Result<Self> {
        let file_bytes = std::fs::metadata(path)
            .with_context(|| format!("{}: cannot read map", path.display()))?
            .len();
        let header_bytes = match MapFormat::from_path(path)? {
            // The file's own layout (version 1, 2 or quantized), not the one this map would
            // be written in today.
            MapFormat::Mema => {
                let bytes = std::fs::read(path)
                    .with_context(|| format!("{}: cannot read map", path.display()))?;
                MapFile::new_checked(&bytes)
                    .map_err(anyhow::Error::from)
                    .with_context(|| path.display().to_string())?
                    .layout()
                    .encoded_len(0) as u64
            }
            format => {
                let empty = HostMap {
                    entities: Vec::new(),
                    ..map.clone()
                };
                empty.encode_as(format)?.len() as u64
            }
        };
        Ok(Self {
            file_bytes,
            header_bytes,
            bytes_per_entity: file_bytes.saturating_sub(header_bytes) as f64
                / map.entities.len().max(1) as f64,
        })
    }
}

/// The cloud's points in the map's frame, in f64 (the two origins differ in general).
pub fn points_in_map_frame(cloud: &LocalCloud, map: &HostMap) -> Vec<[f64; 3]> {
    let shift = [0, 1, 2].map(|j| cloud.origin[j] - map.origin[j]);
    cloud
        .points
        .iter()
        .map(|p| {
            let q = p.to_f64();
            [q[0] + shift[0], q[1] + shift[1], q[2] + shift[2]]
        })
        .collect()
}

pub fn eval(args: &EvalArgs) -> Result<()> {
    if args.samples == 0 || args.samples > MAX_SAMPLES {
        return Err(UsageError(format!(
            "--samples {} must be between 1 and {MAX_SAMPLES}",
            args.samples
        ))
        .into());
    }
    let cloud = crate::progress::stage("reading", || load_cloud(&args.input))?;
    let map = HostMap::read(&args.map)?;
    if map.entities.is_empty() {
        anyhow::bail!("{}: the map has no entities", args.map.display());
    }
    let bytes = FileBytes::of(&args.map, &map)?;
    let eq13 = crate::progress::stage("evaluating", || evaluate(&cloud, &map));
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    let score = crate::progress::stage("scoring", || {
        fidelity::two_way_score(
            &points_in_map_frame(&cloud, &map),
            &entities,
            args.seed,
            args.samples,
        )
    })
    .with_context(|| format!("{} against {}", args.map.display(), args.input.display()))?;
    if args.json {
        let doc = EvalJson {
            eq13,
            fidelity: score,
            bytes,
        };
        println!("{}", serde_json::to_string(&doc)?);
        return Ok(());
    }
    println!("{}", stats::MEMORY_HEADER);
    println!(
        "{}",
        stats::format_memory_row(&MemoryRow::new(eq13.points, map.entities.len()))
    );
    println!();
    println!(
        "eq. 13 error over {} non-empty clusters",
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

fn print_score(s: &FidelityScore, seed: u64) {
    // No reader learns a unit from its file, so lengths are in whatever the cloud used.
    println!(
        "two-way score, lengths in cloud units ({} surface samples, seed {seed}):",
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
        "tau {:.6} (2 x median point spacing): phantom {:.1}% of {:.6} surface area; precision {:.3}, recall {:.3}, F-score {:.3}",
        s.tau,
        100.0 * s.phantom,
        s.area,
        s.precision,
        s.recall,
        s.f_score
    );
    println!("chamfer {:.6}", s.chamfer);
}
