//! Cropping and voxel-grid downsampling (`mema map --crop`, `--voxel`), as PCL's CropBox and
//! VoxelGrid filters do them.
//!
//! Both work in the file's own coordinates (f64): the crop box is given in them, and voxel
//! boundaries sit at multiples of SIZE from the file's zero, so the same file cropped two ways
//! keeps the same voxels. The result is moved to its own bounding-box centre, as a fresh read is.

use std::str::FromStr;

use crate::error::ConfigError;
use crate::io::cloud::LocalCloud;

/// An axis-aligned box, bounds included; parsed from `xmin,ymin,zmin,xmax,ymax,zmax`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CropBox {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl FromStr for CropBox {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let values: Vec<f64> = s
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| {
                format!("'{s}' is not six numbers; expected xmin,ymin,zmin,xmax,ymax,zmax")
            })?;
        let [x0, y0, z0, x1, y1, z1] = values[..] else {
            return Err(format!(
                "'{s}' has {} values; expected six: xmin,ymin,zmin,xmax,ymax,zmax",
                values.len()
            ));
        };
        let (min, max) = ([x0, y0, z0], [x1, y1, z1]);
        if min.iter().chain(&max).any(|v| !v.is_finite()) {
            return Err(format!("'{s}': the bounds must be finite"));
        }
        if (0..3).any(|j| min[j] > max[j]) {
            return Err(format!("'{s}': each minimum must not exceed its maximum"));
        }
        Ok(Self { min, max })
    }
}

impl CropBox {
    /// Whether `p` is inside the box (bounds included).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|j| self.min[j] <= p[j] && p[j] <= self.max[j])
    }
}

/// Checks a voxel grid's edge.
pub fn check_voxel(size: f64) -> Result<f64, ConfigError> {
    if size > 0.0 && size.is_finite() {
        Ok(size)
    } else {
        Err(ConfigError::Voxel(size))
    }
}

/// What the filters can leave unworkable in a given cloud.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FilterError {
    /// No point of the cloud lies in the crop box.
    #[error("the crop box {min:?}..{max:?} leaves no points of the cloud")]
    CropLeavesNothing {
        /// The box's corners.
        min: [f64; 3],
        /// The box's corners.
        max: [f64; 3],
    },
    /// A voxel so small that the cloud's coordinates pass 2^53 voxels from zero.
    #[error(
        "the voxel size {size} is too small for this cloud: its coordinates reach {reach}, more than 2^53 voxels from zero; use at least {least:e} (in the file's units)"
    )]
    VoxelTooSmall {
        /// The voxel size asked for.
        size: f64,
        /// The largest absolute coordinate of the cloud.
        reach: f64,
        /// The smallest voxel that works.
        least: f64,
    },
}

/// Point counts through the filters, for the report: `null` where a filter was not asked for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FilterCounts {
    pub read: usize,
    pub cropped: Option<usize>,
    pub voxelized: Option<usize>,
    /// Points carving left out: seen through by other scans (`--free-space`,
    /// [`crate::mapping::carve`]).
    pub carved: Option<usize>,
}

/// Applies the crop, then the voxel grid; fails if nothing is left or the voxel is too small
/// for the cloud's coordinates.
pub fn apply(
    cloud: LocalCloud,
    crop: Option<CropBox>,
    voxel: Option<f64>,
) -> Result<(LocalCloud, FilterCounts), FilterError> {
    let mut counts = FilterCounts {
        read: cloud.points.len(),
        ..FilterCounts::default()
    };
    if crop.is_none() && voxel.is_none() {
        return Ok((cloud, counts));
    }
    let origin = cloud.origin;
    let world = |p: &mema_core::Point3| {
        let q = p.to_f64();
        [0, 1, 2].map(|j| origin[j] + q[j])
    };
    let mut points: Vec<[f64; 3]> = cloud.points.iter().map(world).collect();
    let mut sensors = cloud.sensors.clone();
    if let Some(b) = crop {
        sensors = sensors.retain(|i| points.get(i).is_some_and(|p| b.contains(*p)));
        points.retain(|p| b.contains(*p));
        counts.cropped = Some(points.len());
        if points.is_empty() {
            return Err(FilterError::CropLeavesNothing {
                min: b.min,
                max: b.max,
            });
        }
    }
    if let Some(size) = voxel {
        // Past 2^53 voxels from zero, f64 cannot tell neighbouring voxels apart and far ones
        // would share a saturated index: refuse rather than merge unrelated points.
        let reach = points
            .iter()
            .flat_map(|p| p.iter())
            .fold(0.0f64, |m, c| m.max(c.abs()));
        let limit = (1u64 << 53) as f64;
        if reach / size >= limit {
            return Err(FilterError::VoxelTooSmall {
                size,
                reach,
                least: reach / limit,
            });
        }
        points = voxel_centroids(&points, size);
        counts.voxelized = Some(points.len());
        // A voxel's centroid mixes the points of several rays, often of several scans: it is
        // no one ray's end, so no free space is recorded from it.
        sensors = Default::default();
    }
    let mut out = LocalCloud::from_world(&points);
    out.dropped_non_finite = cloud.dropped_non_finite;
    out.dropped_by_class = cloud.dropped_by_class;
    out.outliers = cloud.outliers;
    out.unit = cloud.unit;
    out.sensors = sensors;
    out.no_returns = cloud.no_returns;
    Ok((out, counts))
}

/// One point per occupied voxel: the centroid of the points in it, in voxel order (so the
/// result does not depend on the input order).
pub fn voxel_centroids(points: &[[f64; 3]], size: f64) -> Vec<[f64; 3]> {
    // `apply` refuses a voxel so small that an index passes 2^53; `as` would saturate there,
    // merging far voxels, but never panic.
    let key = |p: &[f64; 3]| p.map(|c| (c / size).floor() as i64);
    let mut order: Vec<(usize, [i64; 3])> = points.iter().map(key).enumerate().collect();
    order.sort_unstable_by(|a, b| a.1.cmp(&b.1).then(a.0.cmp(&b.0)));
    let mut out = Vec::new();
    for run in order.chunk_by(|a, b| a.1 == b.1) {
        let mut sum = [0.0f64; 3];
        for (i, _) in run {
            for (s, c) in sum.iter_mut().zip(points[*i]) {
                *s += c;
            }
        }
        out.push(sum.map(|s| s / run.len() as f64));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crop_box_parsing_and_its_errors() {
        let b: CropBox = "-1,-2,-3,1,2,3.5".parse().unwrap();
        assert_eq!((b.min, b.max), ([-1.0, -2.0, -3.0], [1.0, 2.0, 3.5]));
        assert!(b.contains([1.0, -2.0, 0.0]) && !b.contains([1.01, 0.0, 0.0]));
        for bad in [
            "1,2,3",
            "a,b,c,d,e,f",
            "0,0,0,1,1,inf",
            "2,0,0,1,1,1",
            "1,2,3,4,5,6,7",
        ] {
            let e = bad.parse::<CropBox>().unwrap_err();
            assert!(e.contains(bad) && !e.contains('\n'), "{e}");
        }
        assert!(check_voxel(0.0).is_err() && check_voxel(f64::NAN).is_err());
    }

    /// Against a direct computation: every input point lies in the voxel of exactly one output
    /// point, and that output is the mean of the inputs sharing its voxel.
    #[test]
    fn voxel_centroids_are_means_of_the_voxels() {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let points: Vec<[f64; 3]> = (0..5000)
            .map(|_| [next() * 3.0 - 1.5, next() * 2.0, 100.0 + next()])
            .collect();
        let size = 0.25;
        let out = voxel_centroids(&points, size);
        let cell = |p: &[f64; 3]| p.map(|c| (c / size).floor() as i64);
        let cells: std::collections::HashSet<_> = points.iter().map(cell).collect();
        assert_eq!(out.len(), cells.len());
        for o in &out {
            let members: Vec<_> = points.iter().filter(|p| cell(p) == cell(o)).collect();
            assert!(!members.is_empty());
            for j in 0..3 {
                let mean = members.iter().map(|p| p[j]).sum::<f64>() / members.len() as f64;
                assert!((mean - o[j]).abs() < 1e-9, "{o:?}");
            }
        }
        let mut reversed = points.clone();
        reversed.reverse();
        let again = voxel_centroids(&reversed, size);
        for (a, b) in out.iter().zip(&again) {
            assert!((0..3).all(|j| (a[j] - b[j]).abs() < 1e-9));
        }
    }
}
