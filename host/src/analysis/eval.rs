//! Any map against any cloud: eq. 13 (Tables 2 and 4) with each point joining its nearest
//! centre, and the bytes the map file really takes. The two-way score is
//! [`super::fidelity::two_way_score`], fed by [`points_in_map_frame`].

use anyhow::{Context, Result};
use mema_core::Point3;
use mema_core::map::MapFile;
use serde::Serialize;
use std::path::Path;

use super::stats::{ErrorStats, MemoryRow};
use crate::io::cloud::LocalCloud;
use crate::io::mapfile::{HostMap, MapFormat};
use crate::mapping::pipeline;

/// `mema eval --json` (and the Python package's `Map.eval`): eq. 13's keys first and unchanged,
/// then the two-way score's, the bytes', the points dropped on reading and the cloud's unit.
/// One type for both, so the two documents cannot drift apart.
#[derive(Clone, Debug, Serialize)]
pub struct EvalDocument {
    #[serde(flatten)]
    pub eq13: EvalReport,
    #[serde(flatten)]
    pub fidelity: super::fidelity::FidelityScore,
    #[serde(flatten)]
    pub bytes: FileBytes,
    /// Points of the cloud skipped for a NaN or infinite coordinate.
    pub dropped_non_finite: usize,
    /// The cloud's unit and where it came from (`io::Units`, as JSON).
    pub unit: serde_json::Value,
}

/// Past this many surface samples the score costs memory and time for no added precision.
pub const MAX_SAMPLES: usize = 100_000_000;

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
    /// Measures the file at `path`, which holds `map`.
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

/// An axis-aligned box in world coordinates (metres).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WorldBox {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl WorldBox {
    fn grow(b: Option<Self>, min: [f64; 3], max: [f64; 3]) -> Option<Self> {
        Some(match b {
            None => Self { min, max },
            Some(b) => Self {
                min: [0, 1, 2].map(|j| b.min[j].min(min[j])),
                max: [0, 1, 2].map(|j| b.max[j].max(max[j])),
            },
        })
    }

    /// The box of `cloud`'s points; `None` for a cloud of no points.
    pub fn of_cloud(cloud: &LocalCloud) -> Option<Self> {
        cloud.points.iter().fold(None, |b, p| {
            let q = p.to_f64();
            let w = [0, 1, 2].map(|j| cloud.origin[j] + q[j]);
            Self::grow(b, w, w)
        })
    }

    /// The box `map`'s entities reach: each centre plus and minus its largest finite
    /// semi-axis, which holds the entity whichever way it is turned (an infinite axis adds
    /// nothing: it reaches everywhere, and so says nothing of where the map lies); `None` for
    /// a map of no entities.
    pub fn of_map(map: &HostMap) -> Option<Self> {
        map.entities.iter().fold(None, |b, e| {
            let c = map.world_center(&e.entity);
            let r = e
                .entity
                .semi_axes_f64()
                .into_iter()
                .filter(|r| r.is_finite())
                .fold(0.0, f64::max);
            Self::grow(b, c.map(|v| v - r), c.map(|v| v + r))
        })
    }

    /// Whether the two boxes share a point.
    pub fn overlaps(&self, other: &Self) -> bool {
        (0..3).all(|j| self.min[j] <= other.max[j] && other.min[j] <= self.max[j])
    }
}

/// Eq. 13's part of `mema eval`'s JSON (documented in docs/command-line.md; keys are stable): `points`,
/// the statistics' `clusters, mean, std, max, min, total` (eq. 13 by nearest centre: each point
/// joins the entity of its nearest centre), then Table 2's `cloud_bytes, map_bytes, percent`
/// (`map_bytes`: the entities at their records' bytes in the map's layout, as `mema map` counts).
#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    pub points: usize,
    #[serde(flatten)]
    pub errors: ErrorStats,
    pub cloud_bytes: usize,
    pub map_bytes: usize,
    pub percent: f64,
}

/// Eq. 13 statistics of any map against any cloud; each point joins its nearest centre.
///
/// ```
/// use mema::io::{HostMap, LocalCloud};
/// use mema_core::{Entity, MapEntity, Point3};
///
/// // A unit sphere at the origin, and four points on it.
/// let sphere = Entity::sphere(Point3::new(0.0, 0.0, 0.0), 1.0);
/// let entity = MapEntity { entity: sphere, kind: sphere.kind(0.01) };
/// let map = HostMap::new([0.0; 3], vec![entity]);
/// let on_it = [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]];
/// let cloud = LocalCloud::from_world(&on_it);
/// let report = mema::analysis::eval::evaluate(&cloud, &map);
/// assert_eq!(report.points, 4);
/// assert!(report.errors.mean < 1e-6);
/// ```
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
    // Table 2 counts each entity at its record's bytes in the map's layout, as `mema map`
    // counts the map it writes: 24 for the paper's axis-aligned entity, 14 for a quantized
    // shell. The paper's own count, 24 for any entity, is `mema info`'s `paper_bytes`.
    let memory =
        MemoryRow::with_entity_bytes(points.len(), entities.len(), map.layout().record_len());
    EvalReport {
        points: points.len(),
        errors: ErrorStats::from_errors(&errors),
        cloud_bytes: memory.cloud_bytes,
        map_bytes: memory.map_bytes,
        percent: memory.percent,
    }
}
