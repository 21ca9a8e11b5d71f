//! The space a cloud's sensors saw through, as the map keeps it (issue 29): each scan's range
//! image ([`mema_core::free_space`]) in the map file's free-space part.
//!
//! A scan's image spans the elevations and azimuths its returns came from (a spinning lidar's
//! whole turn, a scanner's narrow view), 8 x 64 pixels (548 bytes with its geometry), ranges
//! coded from half its nearest return. `scripts/free_space_options.py` measured the choice on
//! the shared lidar sweeps: 8 x 64 images call 91 % of the points before held-out ends free
//! (16 x 128, four times the bytes, 96 %) and 98 % of the points behind walls unknown; a voxel
//! octree of the same rays is in [`mema_core::free_space`].

use mema_core::Point3;
use mema_core::free_space::{self, Geometry, NO_RETURN};

use crate::io::cloud::LocalCloud;

/// Rows of elevation in a scan's image.
pub const ROWS: u16 = 8;
/// Columns of azimuth in a scan's image.
pub const COLUMNS: u16 = 64;
/// Scans a map keeps images of at most; beyond, scans spread evenly over the input are kept.
pub const MAX_IMAGES: usize = 16;

/// How much nearer than a pixel's nearest return a point must be to be free (the map's unit):
/// a lidar's range noise and more, so a point on a surface is not called free.
pub const FREE_MARGIN: f32 = 0.2;

/// One scan's range image, its origin relative to the map's origin.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeImage {
    pub geometry: Geometry,
    pub cells: Vec<u8>,
}

impl FreeImage {
    /// Whether the scan saw through `p` (the map's local frame) by more than `margin`.
    pub fn sees_free(&self, p: Point3, margin: f32) -> bool {
        free_space::sees_free(&self.geometry, &self.cells, p, margin)
    }

    /// The image with each pixel that holds a return given the nearest return of it and its
    /// eight neighbours (columns wrap round a whole turn; pixels without a return stay so).
    /// Rays a pixel apart leave an object's edge anywhere within one: a point at the edge of
    /// what this scan saw, in a pixel whose rays passed just beside it, is not seen through.
    pub fn nearest_around(&self) -> FreeImage {
        let rows = usize::from(self.geometry.rows);
        let columns = usize::from(self.geometry.columns);
        let whole_turn = self.geometry.azimuth[1] >= core::f32::consts::TAU * 0.999;
        let at = |row: usize, column: isize| -> u8 {
            let column = if whole_turn {
                column.rem_euclid(columns as isize)
            } else {
                column
            };
            usize::try_from(column)
                .ok()
                .filter(|c| *c < columns)
                .and_then(|c| self.cells.get(row * columns + c).copied())
                .unwrap_or(NO_RETURN)
        };
        let mut cells = self.cells.clone();
        for (i, cell) in cells.iter_mut().enumerate() {
            if *cell == NO_RETURN {
                continue;
            }
            let (row, column) = (i / columns.max(1), (i % columns.max(1)) as isize);
            let around = row.saturating_sub(1)..=(row + 1).min(rows.saturating_sub(1));
            *cell = around
                .flat_map(|r| [column - 1, column, column + 1].map(|c| at(r, c)))
                .min()
                .unwrap_or(*cell);
        }
        FreeImage {
            geometry: self.geometry,
            cells,
        }
    }

    /// Bytes the image takes in the map file.
    pub fn file_bytes(&self) -> usize {
        mema_core::map::free_space_part::GEOMETRY_LEN + self.cells.len()
    }
}

/// Bytes the free-space part of `images` takes in the map file (0 for none).
pub fn part_bytes(images: &[FreeImage]) -> usize {
    if images.is_empty() {
        0
    } else {
        6 + images.iter().map(FreeImage::file_bytes).sum::<usize>()
    }
}

/// The bytes of the free-space part of `scans` images of the standard size: what `--bytes`
/// leaves out for them before it counts entities.
pub fn part_bytes_for(scans: usize) -> usize {
    let kept = scans.min(MAX_IMAGES);
    if kept == 0 {
        0
    } else {
        6 + kept
            * (mema_core::map::free_space_part::GEOMETRY_LEN
                + usize::from(ROWS) * usize::from(COLUMNS))
    }
}

/// The scans of `cloud` an image is kept of: all of them up to [`MAX_IMAGES`], else that many
/// spread evenly (the first and the last among them).
pub fn kept_scans(scans: usize) -> Vec<usize> {
    if scans <= MAX_IMAGES {
        return (0..scans).collect();
    }
    (0..MAX_IMAGES)
        .map(|i| i * (scans - 1) / (MAX_IMAGES - 1))
        .collect()
}

/// The range images of `cloud`'s scans, in the frame of a map whose origin is `map_origin`
/// (the cloud's own coordinates): none for a cloud that says nowhere where its sensor was.
pub fn images_of(cloud: &LocalCloud, map_origin: [f64; 3]) -> Vec<FreeImage> {
    let runs: Vec<_> = cloud.sensors.runs().collect();
    let shift = [0, 1, 2].map(|j| cloud.origin[j] - map_origin[j]);
    kept_scans(runs.len())
        .into_iter()
        .filter_map(|i| {
            let (range, origin) = runs.get(i)?.clone();
            let points = cloud.points.get(range)?;
            let local = |p: &Point3| {
                Point3::new(
                    (f64::from(p.x) + shift[0]) as f32,
                    (f64::from(p.y) + shift[1]) as f32,
                    (f64::from(p.z) + shift[2]) as f32,
                )
            };
            let sensor = [0, 1, 2].map(|j| (origin[j] - map_origin[j]) as f32);
            image_of(
                Point3::new(sensor[0], sensor[1], sensor[2]),
                points.iter().map(local),
                [ROWS, COLUMNS],
            )
        })
        .collect()
}

/// One scan's image of `size` (rows, columns) from its sensor origin and returns (the map's
/// frame); `None` if no return lies away from the origin.
pub fn image_of(
    origin: Point3,
    returns: impl Iterator<Item = Point3> + Clone,
    size: [u16; 2],
) -> Option<FreeImage> {
    image_from(origin, returns, size, None)
}

/// [`image_of`], its ranges coded from `near` when given (else from half the nearest return).
pub fn image_from(
    origin: Point3,
    returns: impl Iterator<Item = Point3> + Clone,
    size: [u16; 2],
    near: Option<f32>,
) -> Option<FreeImage> {
    image_with(origin, returns, size, None, near)
}

/// [`image_of`] with columns no narrower than `column` radians, and at most `size` (rows,
/// columns): a narrow view (a scanner's 50 degrees) gets as few columns as its span needs, so
/// its rays, spaced finer than the columns, leave no column between them empty.
pub fn image_of_view(
    origin: Point3,
    returns: impl Iterator<Item = Point3> + Clone,
    size: [u16; 2],
    column: f32,
) -> Option<FreeImage> {
    image_with(origin, returns, size, Some(column), None)
}

fn image_with(
    origin: Point3,
    returns: impl Iterator<Item = Point3> + Clone,
    size: [u16; 2],
    column: Option<f32>,
    near: Option<f32>,
) -> Option<FreeImage> {
    let mut elevation = [f32::INFINITY, f32::NEG_INFINITY];
    let mut azimuths = Vec::new();
    let mut nearest = f32::INFINITY;
    for p in returns.clone() {
        let d = [p.x - origin.x, p.y - origin.y, p.z - origin.z];
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if !(r.is_finite() && r > 0.0) {
            continue;
        }
        let e = (d[2] / r).clamp(-1.0, 1.0).asin();
        elevation = [elevation[0].min(e), elevation[1].max(e)];
        azimuths.push(d[1].atan2(d[0]));
        nearest = nearest.min(r);
    }
    if azimuths.is_empty() || elevation[0] >= elevation[1] {
        return None;
    }
    // A hair wider than the returns, so the core's own trigonometry puts the extreme ones in.
    let elevation = [elevation[0] - 1e-5, elevation[1] + 1e-5];
    let azimuth = azimuth_span(&mut azimuths, size[1]);
    let columns = match column {
        // Rounded down: a column is never narrower than `column`.
        Some(column) if column > 0.0 => ((azimuth[1] / column) as u16).clamp(1, size[1].max(1)),
        _ => size[1],
    };
    let geometry = Geometry {
        origin,
        near: near.unwrap_or(nearest / 2.0),
        elevation,
        azimuth,
        rows: size[0],
        columns,
    };
    let mut cells = vec![NO_RETURN; geometry.pixels()];
    for p in returns {
        free_space::add_return(&geometry, &mut cells, p);
    }
    Some(FreeImage { geometry, cells })
}

/// The azimuths' span as a start and a width: the turn less its widest gap, or the whole turn
/// when no gap is wider than two of `columns` (a spinning sensor).
fn azimuth_span(azimuths: &mut [f32], columns: u16) -> [f32; 2] {
    use std::f32::consts::{PI, TAU};
    azimuths.sort_by(f32::total_cmp);
    let (Some(&first), Some(&last)) = (azimuths.first(), azimuths.last()) else {
        return [-PI, TAU];
    };
    // The gap across -pi, then each gap between neighbours.
    let mut widest = (first + TAU - last, first);
    for pair in azimuths.windows(2) {
        if pair[1] - pair[0] > widest.0 {
            widest = (pair[1] - pair[0], pair[1]);
        }
    }
    if widest.0 <= 2.0 * TAU / f32::from(columns.max(1)) {
        return [-PI, TAU];
    }
    // A hair wider, so the last return's azimuth is inside after rounding.
    [widest.1, (TAU - widest.0) * (1.0 + 1e-6) + 1e-6]
}
