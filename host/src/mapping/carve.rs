//! Carving (issue 29): a point that other scans saw through is not surface. A thing seen in
//! one scan and seen through in two others (a person who walked on, a ghost of a bad frame) is
//! left out before clustering, so no entity stands where the rays say the space is empty.
//!
//! Each scan's range image is made at a fine resolution (64 rows and at most 512 columns, none
//! narrower than 0.7 degrees: a spinning lidar's sweep in 64 x 512, a scanner's 50-degree view
//! in 71 columns; only while mapping, never stored), and a point of one scan is seen through by
//! another when that scan's image puts it nearer than its pixel's nearest return by
//! [`CARVE_MARGIN`]. The nearest return of a pixel is its least range, so a floor or a wall the
//! other scan sees at a grazing angle, whose nearest return in the pixel lies at or before the
//! point, never carves it.

use mema_core::Point3;
use rayon::prelude::*;

use crate::io::cloud::LocalCloud;
use crate::io::free_space::image_of_view;

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

/// `cloud` without the points at least [`SEEN_THROUGH`] of its other scans saw through, and how
/// many those were. A cloud of fewer than three scans with sensor origins is returned whole.
pub fn carve(cloud: LocalCloud) -> (LocalCloud, usize) {
    let runs: Vec<_> = cloud.sensors.runs().collect();
    if runs.len() <= SEEN_THROUGH {
        return (cloud, 0);
    }
    let sensor = |origin: [f64; 3]| {
        let o = [0, 1, 2].map(|j| (origin[j] - cloud.origin[j]) as f32);
        Point3::new(o[0], o[1], o[2])
    };
    let images: Vec<_> = runs
        .par_iter()
        .map(|(range, origin)| {
            let points = cloud.points.get(range.clone()).unwrap_or_default();
            image_of_view(
                sensor(*origin),
                points.iter().copied(),
                CARVE_SIZE,
                CARVE_COLUMN,
            )
        })
        .collect();
    let mut scan_of = vec![usize::MAX; cloud.points.len()];
    for (scan, (range, _)) in runs.iter().enumerate() {
        if let Some(slots) = scan_of.get_mut(range.clone()) {
            slots.fill(scan);
        }
    }
    let seen_through: Vec<bool> = cloud
        .points
        .par_iter()
        .zip(&scan_of)
        .map(|(p, own)| {
            images
                .iter()
                .enumerate()
                .filter(|(scan, image)| {
                    scan != own
                        && image
                            .as_ref()
                            .is_some_and(|i| i.sees_free(*p, CARVE_MARGIN))
                })
                .count()
                >= SEEN_THROUGH
        })
        .collect();
    let dropped = seen_through.iter().filter(|s| **s).count();
    if dropped == 0 {
        return (cloud, 0);
    }
    let keep = |i: usize| !seen_through.get(i).copied().unwrap_or(false);
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
