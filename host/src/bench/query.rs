//! `mema query-bench`: queries per second through the index against a brute-force scan of the
//! same map (and their answers compared), and the demo scan's rays re-cast at its own map.

use anyhow::Result;
use mema_core::query::brute_force;
use serde::Serialize;
use std::time::Instant;

use crate::io::mapfile::HostMap;
use crate::io::scene::{ScanConfig, Scene};
use crate::query::{build_index, local, random_queries};

/// What `mema query-bench` reports.
#[derive(Clone, Debug, Serialize)]
pub struct QueryBench {
    pub entities: usize,
    pub queries: usize,
    pub disagreements: usize,
    pub index_queries_per_s: f64,
    pub brute_force_queries_per_s: f64,
    pub speedup: f64,
    /// The demo scene's rays cast against its own map.
    pub rays: usize,
    pub rays_hit_both: usize,
    pub rays_scene_only: usize,
    pub rays_map_only: usize,
    pub range_rmse: f64,
    /// Median and 95th percentile of |map range - scene range| over rays that hit both.
    pub range_median_abs: f64,
    pub range_p95_abs: f64,
}

/// Times `queries` random queries of each kind (nearest, occupancy, ray) on `map`, through the
/// index and by brute force; with `ray_check`, also casts the scene's scan rays at the map.
pub fn run_bench(map: &HostMap, queries: usize, ray_check: Option<&Scene>) -> Result<QueryBench> {
    let index = build_index(map)?;
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    let qs = random_queries(map, queries, 0x5EED);
    let max_range = 1e9;
    let start = Instant::now();
    let indexed: Vec<_> = qs
        .iter()
        .map(|(p, d)| {
            (
                index.nearest(*p),
                index.occupied(*p),
                index.ray_cast(*p, *d, max_range),
            )
        })
        .collect();
    let index_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let brute: Vec<_> = qs
        .iter()
        .map(|(p, d)| {
            (
                brute_force::nearest(&entities, *p),
                brute_force::occupied(&entities, *p),
                brute_force::ray_cast(&entities, *p, *d, max_range),
            )
        })
        .collect();
    let brute_s = start.elapsed().as_secs_f64();
    let disagreements = indexed
        .iter()
        .zip(brute.iter())
        .filter(|(a, b)| a != b)
        .count();

    let (mut rays, mut both, mut scene_only, mut map_only, mut sum2) = (0, 0, 0, 0, 0.0);
    let mut abs_errors = Vec::new();
    if let Some(scene) = ray_check {
        let config = ScanConfig::default();
        let sensor = local(map, config.sensor);
        for d in config.ray_directions() {
            rays += 1;
            let truth = scene.ray_cast(config.sensor, d, config.max_range);
            let mapped = index.ray_cast(sensor, d, config.max_range);
            match (truth, mapped) {
                (Some(t), Some(m)) => {
                    both += 1;
                    sum2 += (m.t - t.range) * (m.t - t.range);
                    abs_errors.push((m.t - t.range).abs());
                }
                (Some(_), None) => scene_only += 1,
                (None, Some(_)) => map_only += 1,
                (None, None) => {}
            }
        }
    }
    let per_s = |secs: f64| queries as f64 * 3.0 / secs;
    Ok(QueryBench {
        entities: map.entities.len(),
        queries: queries * 3,
        disagreements,
        index_queries_per_s: per_s(index_s),
        brute_force_queries_per_s: per_s(brute_s),
        speedup: brute_s / index_s,
        rays,
        rays_hit_both: both,
        rays_scene_only: scene_only,
        rays_map_only: map_only,
        range_rmse: if both > 0 {
            (sum2 / both as f64).sqrt()
        } else {
            0.0
        },
        range_median_abs: quantile(&mut abs_errors, 0.5),
        range_p95_abs: quantile(&mut abs_errors, 0.95),
    })
}

fn quantile(values: &mut [f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * q).round() as usize]
}
