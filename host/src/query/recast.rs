//! A scan's rays cast again, at the map made of it and at the scene they first hit: how well
//! the map stands in for the world along the rays a robot casts (`mema query-bench` on the
//! static demo, `mema demo --moving` on the drive).

use anyhow::Result;
use serde::Serialize;

use super::{build_index, local};
use crate::io::mapfile::HostMap;
use crate::io::scene::{ScanConfig, Scene};

/// Rays of one or more scans cast at the scene and at a map of it.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Recast {
    pub rays: usize,
    pub rays_hit_both: usize,
    pub rays_scene_only: usize,
    pub rays_map_only: usize,
    /// RMS of map range - scene range over rays that hit both (metres).
    pub range_rmse: f64,
    /// Median and 95th percentile of |map range - scene range| over rays that hit both (metres).
    pub range_median_abs: f64,
    pub range_p95_abs: f64,
}

/// Casts every ray of every scan in `views` (each from its own sensor, in the world frame) at
/// `scene`, noise-free, and at `map` through its index, up to the scan's range.
pub fn recast(map: &HostMap, scene: &Scene, views: &[ScanConfig]) -> Result<Recast> {
    let index = build_index(map)?;
    let mut r = Recast::default();
    let mut sum2 = 0.0;
    let mut abs_errors = Vec::new();
    for view in views {
        let sensor = local(map, view.sensor);
        for d in view.ray_directions() {
            r.rays += 1;
            let truth = scene.ray_cast(view.sensor, d, view.max_range);
            let mapped = index.ray_cast(sensor, d, view.max_range);
            match (truth, mapped) {
                (Some(t), Some(m)) => {
                    r.rays_hit_both += 1;
                    sum2 += (m.t - t.range) * (m.t - t.range);
                    abs_errors.push((m.t - t.range).abs());
                }
                (Some(_), None) => r.rays_scene_only += 1,
                (None, Some(_)) => r.rays_map_only += 1,
                (None, None) => {}
            }
        }
    }
    if r.rays_hit_both > 0 {
        r.range_rmse = (sum2 / r.rays_hit_both as f64).sqrt();
    }
    r.range_median_abs = quantile(&mut abs_errors, 0.5);
    r.range_p95_abs = quantile(&mut abs_errors, 0.95);
    Ok(r)
}

impl Recast {
    /// The report's lines, as `query-bench` and `demo --moving` print them.
    pub fn lines(&self, what: &str) -> String {
        format!(
            "  {what}: {} rays, {} hit both, {} only the scene, {} only the map\n  range error over rays hitting both: RMSE {:.4} m, median {:.4} m, 95th percentile {:.4} m",
            self.rays,
            self.rays_hit_both,
            self.rays_scene_only,
            self.rays_map_only,
            self.range_rmse,
            self.range_median_abs,
            self.range_p95_abs
        )
    }
}

fn quantile(values: &mut [f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * q).round() as usize]
}
