//! `mema query-bench`: queries per second through the index against a brute-force scan of the
//! same map (and their answers compared), and the demo scan's rays re-cast at its own map.

use anyhow::Result;
use mema_core::query::brute_force;
use serde::Serialize;
use std::time::Instant;

use crate::io::mapfile::HostMap;
use crate::io::scene::{ScanConfig, Scene};
use crate::query::recast::{Recast, recast};
use crate::query::{build_index, random_queries};

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
    #[serde(flatten)]
    pub recast: Recast,
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

    let recast = match ray_check {
        Some(scene) => recast(map, scene, &[ScanConfig::default()])?,
        None => Recast::default(),
    };
    let per_s = |secs: f64| queries as f64 * 3.0 / secs;
    Ok(QueryBench {
        entities: map.entities.len(),
        queries: queries * 3,
        disagreements,
        index_queries_per_s: per_s(index_s),
        brute_force_queries_per_s: per_s(brute_s),
        speedup: brute_s / index_s,
        recast,
    })
}
