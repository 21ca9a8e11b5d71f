//! `mema stream-bench`: the streaming mapper against the batch pipeline on one cloud, and its
//! ingest rate against the SRI-500's 800,000 points/s (the paper's scanner), in one process.

use anyhow::Result;
use mema_core::Point3;
use serde::Serialize;
use std::time::Instant;

use crate::commands::{LocalCloud, evaluate};
use crate::pipeline::{self, PipelineConfig};
use crate::serial::frames::{dequantise, encode_stream, quantise};
use crate::serial::link::{Capacity, Link, new_mapper};

/// The paper's scanner rate (Section 4).
pub const SRI_500_POINTS_PER_S: f64 = 800_000.0;

#[derive(Serialize)]
pub struct StreamBench {
    pub points: usize,
    pub k: usize,
    pub stream_entities: usize,
    pub batch_entities: usize,
    pub stream_mean_error: f64,
    /// Largest per-cluster eq. 13 error of the streaming map (nearest-centre membership).
    pub stream_max_error: f64,
    pub batch_mean_error: f64,
    /// stream / batch mean eq. 13 error, minus one, in percent.
    pub error_change_percent: f64,
    /// Points per second into the mapper alone (best of the repetitions, one thread).
    pub mapper_points_per_s: f64,
    /// Points per second from wire bytes: decoder plus mapper.
    pub wire_points_per_s: f64,
    pub mapper_vs_sri500: f64,
    pub wire_vs_sri500: f64,
    pub finish_seconds: f64,
    pub merges: u64,
}

pub fn run(
    cloud: &LocalCloud,
    config: &PipelineConfig,
    capacity: Capacity,
    repetitions: usize,
    tolerance: f64,
) -> Result<StreamBench> {
    let wire: Vec<[i32; 3]> = cloud
        .points
        .iter()
        .map(|p| quantise(*p))
        .collect::<Result<_>>()?;
    let points: Vec<Point3> = wire.iter().map(|q| dequantise(*q)).collect();
    let bytes = encode_stream(&wire)?;

    let mut mapper_rate = 0.0f64;
    let mut wire_rate = 0.0f64;
    for _ in 0..repetitions.max(1) {
        let mut mapper = new_mapper(capacity, config.seed, config.fit, tolerance);
        let start = Instant::now();
        mapper.add_all(&points);
        mapper_rate = mapper_rate.max(points.len() as f64 / start.elapsed().as_secs_f64());

        let mut link = Link::new(capacity, config.seed, config.fit, tolerance);
        let start = Instant::now();
        link.feed(&bytes);
        wire_rate = wire_rate.max(points.len() as f64 / start.elapsed().as_secs_f64());
    }

    let mut link = Link::new(capacity, config.seed, config.fit, tolerance);
    link.feed(&bytes);
    let start = Instant::now();
    let mut stream_map = link.finish();
    let finish_seconds = start.elapsed().as_secs_f64();
    // The stream's points are the cloud's local points (to the millimetre): same frame.
    stream_map.origin = cloud.origin;

    let clusters = pipeline::cluster(&cloud.points, config.k, &config.kmeans)?;
    let fitted = pipeline::fit_all(&clusters.moments, config.seed, &config.fit);
    let batch_map = pipeline::to_map(
        cloud.origin,
        &fitted.ellipsoids,
        config.fit.degeneration.sphere_tolerance,
    );

    let stream_eval = evaluate(cloud, &stream_map);
    let batch_eval = evaluate(cloud, &batch_map);
    Ok(StreamBench {
        points: points.len(),
        k: config.k,
        stream_entities: stream_map.entities.len(),
        batch_entities: batch_map.entities.len(),
        stream_mean_error: stream_eval.errors.mean,
        stream_max_error: stream_eval.errors.max,
        batch_mean_error: batch_eval.errors.mean,
        error_change_percent: 100.0 * (stream_eval.errors.mean / batch_eval.errors.mean - 1.0),
        mapper_points_per_s: mapper_rate,
        wire_points_per_s: wire_rate,
        mapper_vs_sri500: mapper_rate / SRI_500_POINTS_PER_S,
        wire_vs_sri500: wire_rate / SRI_500_POINTS_PER_S,
        finish_seconds,
        merges: link.mapper.stats().merges,
    })
}
