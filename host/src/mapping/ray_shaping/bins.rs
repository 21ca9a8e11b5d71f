//! Rays binned by direction around their scan's origin, so that the rays passing near a
//! sphere are found from the bins its cone covers rather than by testing every ray.

use std::f64::consts::{FRAC_PI_2, PI};

use super::Ray;

/// About this many rays a bin: fewer bins cost a cone more rays to test, more cost memory.
const RAYS_PER_BIN: usize = 2;

/// One scan's rays (one origin), binned by elevation and azimuth.
struct Scan {
    origin: [f64; 3],
    rows: usize,
    columns: usize,
    /// Bin `b` holds `rays[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    rays: Vec<u32>,
}

pub(super) struct DirectionBins {
    scans: Vec<Scan>,
}

impl DirectionBins {
    /// The rays' bins; consecutive rays with the same origin make one scan.
    pub(super) fn of(rays: &[Ray]) -> Self {
        let mut scans = Vec::new();
        let mut start = 0;
        while start < rays.len() {
            let origin = rays[start].origin;
            let end = start
                + rays[start..]
                    .iter()
                    .take_while(|r| r.origin == origin)
                    .count();
            scans.push(Scan::of(origin, rays, start..end));
            start = end;
        }
        Self { scans }
    }

    /// Calls `visit` with every ray whose direction lies in (or beside) the cone from its
    /// scan's origin around the sphere of centre `c` and `radius`: a superset of the rays
    /// that pass within `radius` of `c`.
    pub(super) fn visit_cone(&self, c: [f64; 3], radius: f64, mut visit: impl FnMut(u32)) {
        for scan in &self.scans {
            scan.visit_cone(c, radius, &mut visit);
        }
    }
}

impl Scan {
    fn of(origin: [f64; 3], rays: &[Ray], range: std::ops::Range<usize>) -> Self {
        let n = range.len();
        let rows = ((n / RAYS_PER_BIN / 2) as f64).sqrt().ceil().max(1.0) as usize;
        let columns = 2 * rows;
        let mut counts = vec![0u32; rows * columns + 1];
        let bin_of = |r: &Ray| {
            let (row, column) = cell(r.direction, rows, columns);
            row * columns + column
        };
        for r in &rays[range.clone()] {
            counts[bin_of(r) + 1] += 1;
        }
        for b in 1..counts.len() {
            counts[b] += counts[b - 1];
        }
        let starts = counts.clone();
        let mut fill = counts;
        let mut sorted = vec![0u32; n];
        for i in range {
            let b = bin_of(&rays[i]);
            sorted[fill[b] as usize] = i as u32;
            fill[b] += 1;
        }
        Self {
            origin,
            rows,
            columns,
            starts,
            rays: sorted,
        }
    }

    fn visit_bin(&self, row: usize, column: usize, visit: &mut impl FnMut(u32)) {
        let b = row * self.columns + column;
        let (a, z) = (self.starts[b] as usize, self.starts[b + 1] as usize);
        for &r in &self.rays[a..z] {
            visit(r);
        }
    }

    fn visit_cone(&self, c: [f64; 3], radius: f64, visit: &mut impl FnMut(u32)) {
        let v = [0, 1, 2].map(|j| c[j] - self.origin[j]);
        let distance = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        // A sphere around the origin (or a NaN distance) covers every direction.
        if distance.partial_cmp(&radius) != Some(std::cmp::Ordering::Greater) {
            self.rays.iter().for_each(|&r| visit(r));
            return;
        }
        let half = (radius / distance).asin();
        let elevation = (v[2] / distance).clamp(-1.0, 1.0).asin();
        let (rows, columns) = (self.rows as f64, self.columns as f64);
        let row_of = |e: f64| ((e + FRAC_PI_2) / PI * rows).floor();
        // One bin of margin each way: a direction on a bin's edge may round into either.
        let lo = (row_of(elevation - half) - 1.0).max(0.0) as usize;
        let hi = (row_of(elevation + half) + 1.0).min(rows - 1.0) as usize;
        let widest = elevation.abs() + half;
        let all_columns = widest >= FRAC_PI_2 || half.sin() >= widest.cos();
        if all_columns {
            for row in lo..=hi {
                for column in 0..self.columns {
                    self.visit_bin(row, column, visit);
                }
            }
            return;
        }
        let spread = (half.sin() / widest.cos()).asin();
        let azimuth = v[1].atan2(v[0]);
        let column_of = |a: f64| ((a + PI) / (2.0 * PI) * columns).floor() as i64;
        let (first, last) = (
            column_of(azimuth - spread) - 1,
            column_of(azimuth + spread) + 1,
        );
        let span = (last - first + 1).min(self.columns as i64);
        for row in lo..=hi {
            for k in 0..span {
                let column = (first + k).rem_euclid(self.columns as i64) as usize;
                self.visit_bin(row, column, visit);
            }
        }
    }
}

/// The bin of a unit direction: rows of elevation from -90 to 90 degrees, columns of azimuth
/// from -180 to 180.
fn cell(d: [f64; 3], rows: usize, columns: usize) -> (usize, usize) {
    let elevation = d[2].clamp(-1.0, 1.0).asin();
    let azimuth = d[1].atan2(d[0]);
    let row = ((elevation + FRAC_PI_2) / PI * rows as f64).floor() as usize;
    let column = ((azimuth + PI) / (2.0 * PI) * columns as f64).floor() as usize;
    (row.min(rows - 1), column.min(columns - 1))
}
