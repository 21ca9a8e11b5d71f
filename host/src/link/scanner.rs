//! A rangefinder's side at the level of scans: the unit a scan is sent in, each scan in its own
//! sensor frame after its pose, and the version 2 byte stream `mema scanner-sim` sends and
//! `mema map --stream` maps (the same bytes, so the same map).
//!
//! **The unit.** The wire rounds every coordinate to a unit of `10^e` m. The unit is the
//! largest power of ten at most a quarter of the scans' point spacing (the median distance
//! from a point to its nearest other point), so rounding moves a point by at most an eighth of
//! the spacing in each coordinate (about 0.07 of it RMS in 3D) and the finest detail a scan
//! holds survives. Millimetres, the unit of version 1, added 0.51 mm RMS to the bunny scans of
//! 0.55 mm spacing; their 0.1 mm unit adds 0.05 mm. A coarser unit is taken only if the scan's
//! coordinates would not fit i32.
//!
//! **The frame.** A scan's points go in its sensor frame, which keeps them small. A single
//! cloud is one scan whose sensor sits at the cloud's bounding-box centre (rounded to the
//! pose's unit), turned by nothing: the receiver adds the centre back, so a streamed map lies
//! in the file's own frame and lines up with the file (`mema eval`, `query`, `draw` on it).

use anyhow::{Result, bail};
use std::path::Path;

use super::frames::{POINTS_PER_FRAME, PosedScan, encode_posed_stream, wire_pose};
use crate::analysis::fidelity::{median, nearest_spacings};
use crate::io::bag::{BagOptions, read_bag};
use crate::io::cloud::{
    LocalCloud, bounding_box_centre, load_cloud_file_in_metres, read_scans_in_metres,
};
use crate::io::drive::DriveScan;
use crate::io::kind::InputKind;
use crate::io::units::LengthUnit;
use crate::kdtree::KdTree;
use mema_core::link::wire::{MAX_UNIT_EXPONENT, MIN_UNIT_EXPONENT, WirePose, unit_scale};

/// One scan as a sensor measured it: its pose, sensor to world (`x_world = R(q) x + t`), and its
/// points in the sensor's frame, all in metres.
#[derive(Clone, Debug)]
pub struct SensorScan {
    pub translation: [f64; 3],
    /// `[x, y, z, w]`, scalar last.
    pub rotation: [f64; 4],
    pub points: Vec<[f64; 3]>,
}

impl SensorScan {
    /// A cloud read in its local frame, given in the world's frame (the file's) as one scan.
    pub fn of_cloud(cloud: &LocalCloud) -> Result<Self> {
        Self::of_world(&cloud.world_points())
    }

    /// A stop of the drive through the demo scene: its points in the sensor's frame, its pose.
    pub fn of_drive(scan: &DriveScan) -> Self {
        Self {
            translation: scan.translation,
            rotation: scan.rotation(),
            points: scan.points.clone(),
        }
    }

    /// A cloud given in the world's frame as one scan: the sensor at the bounding-box centre
    /// rounded to whole metres, turned by nothing, so the points stay small.
    pub fn of_world(points: &[[f64; 3]]) -> Result<Self> {
        let centre = bounding_box_centre(points);
        // Whole metres: exact in any unit of 1 m or less, and the receiver's origin sits on
        // whole metres too.
        let translation = centre.map(f64::round);
        Ok(Self {
            translation,
            rotation: [0.0, 0.0, 0.0, 1.0],
            points: points
                .iter()
                .map(|p| [0, 1, 2].map(|j| p[j] - translation[j]))
                .collect(),
        })
    }
}

/// What a stream of scans was sent as.
#[derive(Clone, Debug)]
pub struct SentScans {
    pub bytes: Vec<u8>,
    /// The points' unit, `10^e` m.
    pub unit_exponent: i8,
    /// The poses' unit (translations), `10^e` m.
    pub pose_exponent: i8,
    /// The median nearest-other-point spacing the unit was chosen from (metres).
    pub spacing: f64,
    pub points: usize,
    pub scans: usize,
    /// Frames sent: a pose frame per scan and its points frames.
    pub frames: usize,
}

/// The scans a file holds, as a scanner sends them: each scan of a registration file (`.conf`)
/// in its own sensor frame with its pose, or a cloud as one scan in the file's frame; in metres
/// (`given`: `--units`).
pub fn scans_of(path: &Path, given: Option<&LengthUnit>) -> Result<Vec<SensorScan>> {
    scans_of_input(path, given, &BagOptions::default())
}

/// [`scans_of`] with the topic and frame of a ROS 2 bag ([`crate::io::bag`]): with a frame,
/// each PointCloud2 message is a scan in its own frame with its pose at its stamp, as a
/// registration file's scans are; without one, the messages' points are one cloud, sent as a
/// single cloud is. `bag` is ignored for every other input.
pub fn scans_of_input(
    path: &Path,
    given: Option<&LengthUnit>,
    bag: &BagOptions,
) -> Result<Vec<SensorScan>> {
    match InputKind::of(path) {
        InputKind::Bag => {
            let read = read_bag(path, bag, given)?;
            if read.frame.is_none() {
                let world: Vec<[f64; 3]> =
                    read.scans.iter().flat_map(|s| s.world_points()).collect();
                return Ok(vec![SensorScan::of_world(&world)?]);
            }
            Ok(read
                .scans
                .into_iter()
                .map(|s| SensorScan {
                    translation: s.pose.translation,
                    rotation: s.pose.rotation,
                    points: s.points,
                })
                .collect())
        }
        InputKind::Registration => {
            let (scans, _) = read_scans_in_metres(path, given)?;
            Ok(scans
                .into_iter()
                .map(|s| SensorScan {
                    translation: s.scan.translation,
                    rotation: s.scan.sensor_to_world(),
                    points: s.points,
                })
                .collect())
        }
        InputKind::StandardInput | InputKind::Cloud => {
            let (cloud, _) = load_cloud_file_in_metres(path, given)?;
            Ok(vec![SensorScan::of_cloud(&cloud)?])
        }
    }
}

/// The median distance from a point to its nearest other point, over every scan (each scan's
/// points against its own: scans overlap only once posed).
pub fn point_spacing(scans: &[SensorScan]) -> f64 {
    let mut spacings = Vec::new();
    for scan in scans {
        let tree = KdTree::build(&scan.points);
        spacings.extend(nearest_spacings(&tree, &scan.points));
    }
    median(&spacings)
}

/// The unit for points of spacing `spacing` whose coordinates reach `reach` (metres): the
/// largest `e` with `10^e <= spacing / 4` that keeps `reach` within i32, clamped to the wire's
/// range.
pub fn choose_unit(spacing: f64, reach: f64) -> Result<i8> {
    let fits = |e: i8| unit_scale(e).is_some_and(|s| reach / s <= f64::from(i32::MAX));
    let fine = (MIN_UNIT_EXPONENT..=MAX_UNIT_EXPONENT)
        .rev()
        .find(|&e| unit_scale(e).is_some_and(|s| s <= spacing / 4.0))
        .unwrap_or(MIN_UNIT_EXPONENT);
    match (fine..=MAX_UNIT_EXPONENT).find(|&e| fits(e)) {
        Some(e) => Ok(e),
        None => bail!("coordinates reaching {reach} m do not fit the wire in any unit"),
    }
}

fn quantise(p: [f64; 3], scale: f64) -> Result<[i32; 3]> {
    let q = p.map(|v| (v / scale).round());
    if q.iter()
        .any(|v| v.is_nan() || v.abs() > f64::from(i32::MAX))
    {
        bail!("point {p:?} does not fit the wire's i32 units of {scale} m");
    }
    Ok(q.map(|v| v as i32))
}

/// A scan as the wire carries it: its pose and its points in integer units.
#[derive(Clone, Debug)]
pub struct WireScan {
    pub pose: WirePose,
    pub points: Vec<[i32; 3]>,
}

/// Scans in the wire's units, before framing.
#[derive(Clone, Debug)]
pub struct WireScans {
    /// The points' unit, `10^e` m.
    pub unit_exponent: i8,
    /// The poses' unit (translations), `10^e` m.
    pub pose_exponent: i8,
    /// The median nearest-other-point spacing the unit was chosen from (metres).
    pub spacing: f64,
    pub scans: Vec<WireScan>,
}

/// `scans` in the unit [`choose_unit`] picks for all of them, poses included.
pub fn quantise_scans(scans: &[SensorScan]) -> Result<WireScans> {
    let spacing = point_spacing(scans);
    let reach = scans
        .iter()
        .flat_map(|s| s.points.iter().flatten())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let unit_exponent = choose_unit(spacing, reach)?;
    // The poses in the points' unit: a translation past i32 in it goes as a wide pose, so a
    // world frame of the globe's keeps the points' resolution.
    let pose_exponent = unit_exponent;
    let scale = unit_scale(unit_exponent).unwrap_or(f64::NAN);
    let scans = scans
        .iter()
        .map(|s| {
            Ok(WireScan {
                pose: wire_pose(s.translation, s.rotation, pose_exponent)?,
                points: s
                    .points
                    .iter()
                    .map(|p| quantise(*p, scale))
                    .collect::<Result<_>>()?,
            })
        })
        .collect::<Result<_>>()?;
    Ok(WireScans {
        unit_exponent,
        pose_exponent,
        spacing,
        scans,
    })
}

/// The version 2 byte stream of `scans`: per scan its pose frame, then its points in its
/// sensor frame, in the unit [`choose_unit`] picks for all of them.
pub fn send_scans(scans: &[SensorScan]) -> Result<SentScans> {
    let wire = quantise_scans(scans)?;
    let posed: Vec<PosedScan<'_>> = wire
        .scans
        .iter()
        .map(|s| PosedScan {
            pose: s.pose,
            pose_exponent: wire.pose_exponent,
            points: &s.points,
        })
        .collect();
    Ok(SentScans {
        bytes: encode_posed_stream(&posed, wire.unit_exponent)?,
        unit_exponent: wire.unit_exponent,
        pose_exponent: wire.pose_exponent,
        spacing: wire.spacing,
        points: wire.scans.iter().map(|s| s.points.len()).sum(),
        scans: wire.scans.len(),
        frames: wire
            .scans
            .iter()
            .map(|s| 1 + s.points.len().div_ceil(POINTS_PER_FRAME))
            .sum::<usize>()
            .max(1),
    })
}

/// `10^e` m in words, for messages: "0.1 mm", "1 mm", "1 cm", "1 m".
pub fn unit_name(e: i8) -> String {
    match e {
        -9 => "1 nm".into(),
        -8 => "10 nm".into(),
        -7 => "0.1 um".into(),
        -6 => "1 um".into(),
        -5 => "10 um".into(),
        -4 => "0.1 mm".into(),
        -3 => "1 mm".into(),
        -2 => "1 cm".into(),
        -1 => "10 cm".into(),
        0 => "1 m".into(),
        e => format!("10^{e} m"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_unit_is_a_quarter_of_the_spacing_or_finer() {
        assert_eq!(choose_unit(0.0005, 0.2).unwrap(), -4);
        assert_eq!(choose_unit(0.004, 3.0).unwrap(), -3);
        assert_eq!(choose_unit(0.05, 3.0).unwrap(), -2);
        // 1,000 km does not fit 0.1 mm units (214 km); 1 mm (2,147 km) does.
        assert_eq!(choose_unit(0.0005, 1.0e6).unwrap(), -3);
        // 3,000 km fits neither: 1 cm.
        assert_eq!(choose_unit(0.0005, 3.0e6).unwrap(), -2);
        // Duplicates only: the finest unit that reaches.
        assert_eq!(choose_unit(0.0, 1.0).unwrap(), -9);
    }
}
