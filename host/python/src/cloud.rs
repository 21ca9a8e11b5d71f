//! Clouds between numpy and the library: an array of world coordinates becomes the
//! [`LocalCloud`] a file reader would have made of the same points, and back.

use mema::io::cloud::LocalCloud;
use mema_core::Point3;

/// The cloud of `points` (world coordinates, in metres), centred exactly as the file readers
/// centre what they read (`mema::io::read`): rows with a NaN or infinite coordinate are
/// dropped and counted, the origin is the bounding box's centre with each bound halved before
/// adding, and every point is `(p - origin)` cast to f32. An array from `read_cloud` is the
/// reader's origin plus its f32 points, exactly in f64, so this gives back that origin and those
/// points bit for bit, and `map` the command line's bytes (tested on every shared cloud).
pub fn local_cloud(points: &[[f64; 3]]) -> Result<LocalCloud, String> {
    let finite = |p: &&[f64; 3]| p.iter().all(|c| c.is_finite());
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut kept = 0;
    for p in points.iter().filter(finite) {
        for j in 0..3 {
            lo[j] = lo[j].min(p[j]);
            hi[j] = hi[j].max(p[j]);
        }
        kept += 1;
    }
    if kept == 0 {
        return Err(match points.len() {
            0 => "no points (the array has 0 rows)".to_owned(),
            n => format!("no finite points ({n} rows, all with a NaN or infinite coordinate)"),
        });
    }
    let origin: [f64; 3] = std::array::from_fn(|j| lo[j] / 2.0 + hi[j] / 2.0);
    for (axis, j) in ["x", "y", "z"].iter().zip(0..3) {
        if hi[j] / 2.0 - lo[j] / 2.0 > f64::from(f32::MAX) {
            return Err(format!(
                "{axis} spans {:e} to {:e}, beyond f32 even after centring",
                lo[j], hi[j]
            ));
        }
    }
    let local = points
        .iter()
        .filter(finite)
        .map(|p| {
            Point3::new(
                (p[0] - origin[0]) as f32,
                (p[1] - origin[1]) as f32,
                (p[2] - origin[2]) as f32,
            )
        })
        .collect();
    Ok(LocalCloud {
        origin,
        points: local,
        dropped_non_finite: points.len() - kept,
        unit: None,
    })
}

/// The cloud's points in world coordinates: origin plus each f32 point, in f64.
pub fn world_points(cloud: &LocalCloud) -> Vec<[f64; 3]> {
    cloud
        .points
        .iter()
        .map(|p| {
            let q = p.to_f64();
            [0, 1, 2].map(|j| cloud.origin[j] + q[j])
        })
        .collect()
}
