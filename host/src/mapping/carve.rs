//! Carving (issue 29): a point that other scans saw through is not surface. A thing seen in
//! one scan and seen through in two others (a person who walked on, a ghost of a bad frame) is
//! left out before clustering, so no entity stands where the rays say the space is empty.
//!
//! Each scan's range image is made at a fine resolution (64 rows and at most 512 columns, none
//! narrower than 0.7 degrees: a spinning lidar's sweep in 64 x 512, a scanner's 50-degree view
//! in 71 columns; only while mapping, never stored), and a point of one scan is seen through by
//! another when that scan's image puts it nearer than its pixel's nearest return by
//! [`CARVE_MARGIN`]. The nearest return of a pixel is the least range over it and its eight
//! neighbours ([`FreeImage::nearest_around`]), so neither a floor or a wall the other scan sees
//! at a grazing angle, whose nearest return lies at or before the point, carves it, nor the
//! other scan's rays passing just beside an object's edge (the walking drive with nobody
//! walking: 1,572 of its 67,200 points carved by the pixel alone, none with its neighbours).
//!
//! What a moving thing leaves next to the floor it stood on (a walker's feet) lies within the
//! margin of the floor behind it, and the other scans' neighbouring pixels hold that floor: a
//! point within [`REST_REACH`] of a carved point of its own scan goes when one other scan saw
//! through it by [`REST_MARGIN`], in its own pixel. (On the walking drive, two scans left 17 of
//! the walker's 3,695 points, and those few raised the floor's shells beside their legs:
//! 2.6-6.6 % of the walker within 25 cm of new surface over five seeds; one scan leaves 6, all
//! under 10 cm, and 0.03-0.05 %.)

use mema_core::Point3;
use std::collections::HashMap;

use rayon::prelude::*;

use crate::io::cloud::LocalCloud;
use crate::io::free_space::{FreeImage, image_of_view};

/// Pixels of the images carving looks through, at most: rows of elevation, columns of azimuth.
pub const CARVE_SIZE: [u16; 2] = [64, 512];
/// The narrowest column carving looks through (radians): a whole turn over `CARVE_SIZE[1]`
/// columns, 0.703 degrees, so a narrow view (a scanner's 50 degrees) gets no finer columns
/// than a spinning lidar's sweep, and its rays, spaced finer than them, leave none empty.
pub const CARVE_COLUMN: f32 = core::f32::consts::TAU / CARVE_SIZE[1] as f32;

/// Other scans that must see through a point for it to go.
pub const SEEN_THROUGH: usize = 2;
/// How much nearer than a pixel's nearest return a point must be to be seen through (the
/// map's unit): a lidar's range noise and more.
pub const CARVE_MARGIN: f32 = 0.2;
/// How near a carved point of its own scan a point must lie to be the rest of what was carved
/// (the map's unit): a walker's foot from the ankle above it.
pub const REST_REACH: f32 = 0.1;
/// The margin the rest of what was carved is seen through by, in its pixel alone: a range
/// sensor's noise.
pub const REST_MARGIN: f32 = 0.05;
/// Other scans that must see through the rest of what was carved: its neighbours already
/// say the thing moved.
pub const REST_SEEN_THROUGH: usize = 1;

/// A scan's range images as carving reads them: as made, and with each pixel's nearest return
/// taken over its neighbours too ([`FreeImage::nearest_around`]). `None`: the scan has no
/// returns to make an image of.
pub struct ScanImages {
    exact: Option<FreeImage>,
    around: Option<FreeImage>,
}

impl ScanImages {
    /// The images of a scan from `sensor` (the map's local frame) whose returns are `points`.
    pub fn of(sensor: Point3, points: &[Point3]) -> Self {
        let exact = image_of_view(sensor, points.iter().copied(), CARVE_SIZE, CARVE_COLUMN);
        let around = exact.as_ref().map(FreeImage::nearest_around);
        Self { exact, around }
    }
}

/// Which of `points`, the returns of scan `own` of `scans`, the other scans saw through: at
/// least [`SEEN_THROUGH`] of them by [`CARVE_MARGIN`], or, within [`REST_REACH`] of such a
/// point, [`REST_SEEN_THROUGH`] of them by [`REST_MARGIN`].
pub fn seen_through(points: &[Point3], own: usize, scans: &[&ScanImages]) -> Vec<bool> {
    let others = |p: &Point3, image: fn(&ScanImages) -> Option<&FreeImage>, margin: f32| {
        scans
            .iter()
            .enumerate()
            .filter(|(scan, images)| {
                *scan != own && image(images).is_some_and(|i| i.sees_free(*p, margin))
            })
            .count()
    };
    let seen: Vec<bool> = points
        .par_iter()
        .map(|p| others(p, |s| s.around.as_ref(), CARVE_MARGIN) >= SEEN_THROUGH)
        .collect();
    let carved = CarvedNearby::new(points, &seen);
    points
        .par_iter()
        .zip(&seen)
        .map(|(p, seen)| {
            *seen
                || (carved.near(p)
                    && others(p, |s| s.exact.as_ref(), REST_MARGIN) >= REST_SEEN_THROUGH)
        })
        .collect()
}

/// `cloud` without the points its other scans saw through ([`seen_through`]), and how many
/// those were. A cloud of fewer than three scans with sensor origins is returned whole.
pub fn carve(cloud: LocalCloud) -> (LocalCloud, usize) {
    let runs: Vec<_> = cloud.sensors.runs().collect();
    if runs.len() <= SEEN_THROUGH {
        return (cloud, 0);
    }
    let sensor = |origin: [f64; 3]| {
        let o = [0, 1, 2].map(|j| (origin[j] - cloud.origin[j]) as f32);
        Point3::new(o[0], o[1], o[2])
    };
    let scan_points =
        |range: &std::ops::Range<usize>| cloud.points.get(range.clone()).unwrap_or_default();
    let scans: Vec<ScanImages> = runs
        .par_iter()
        .map(|(range, origin)| ScanImages::of(sensor(*origin), scan_points(range)))
        .collect();
    let scans: Vec<&ScanImages> = scans.iter().collect();
    let mut carved = vec![false; cloud.points.len()];
    for (own, (range, _)) in runs.iter().enumerate() {
        let seen = seen_through(scan_points(range), own, &scans);
        if let Some(slots) = carved.get_mut(range.clone()) {
            slots.copy_from_slice(&seen);
        }
    }
    let dropped = carved.iter().filter(|s| **s).count();
    if dropped == 0 {
        return (cloud, 0);
    }
    let keep = |i: usize| !carved.get(i).copied().unwrap_or(false);
    let sensors = cloud.sensors.retain(keep);
    let points = cloud
        .points
        .iter()
        .enumerate()
        .filter(|(i, _)| keep(*i))
        .map(|(_, p)| *p)
        .collect();
    (
        LocalCloud {
            points,
            sensors,
            ..cloud
        },
        dropped,
    )
}

/// A scan's carved points in cells of [`REST_REACH`], to find a point's carved neighbours.
struct CarvedNearby {
    cells: HashMap<[i64; 3], Vec<Point3>>,
}

impl CarvedNearby {
    fn new(points: &[Point3], carved: &[bool]) -> Self {
        let mut cells: HashMap<_, Vec<Point3>> = HashMap::new();
        for (p, _) in points.iter().zip(carved).filter(|(_, c)| **c) {
            cells.entry(cell_of(p)).or_default().push(*p);
        }
        Self { cells }
    }

    /// Whether a carved point lies within [`REST_REACH`] of `p`.
    fn near(&self, p: &Point3) -> bool {
        if self.cells.is_empty() {
            return false;
        }
        let [x, y, z] = cell_of(p);
        let offsets = [-1, 0, 1];
        offsets.iter().any(|dx| {
            offsets.iter().any(|dy| {
                offsets.iter().any(|dz| {
                    self.cells
                        .get(&[x + dx, y + dy, z + dz])
                        .is_some_and(|near| {
                            near.iter().any(|q| {
                                let d = [q.x - p.x, q.y - p.y, q.z - p.z];
                                d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= REST_REACH * REST_REACH
                            })
                        })
                })
            })
        })
    }
}

fn cell_of(p: &Point3) -> [i64; 3] {
    [p.x, p.y, p.z].map(|v| (v / REST_REACH).floor() as i64)
}
