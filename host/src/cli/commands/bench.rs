//! `mema bench`, `mema stream-bench` and `mema ablation`: the library's benchmarks, with the
//! command line's printing where the library leaves it.

use anyhow::{Context, Result};
use mema::bench::{ablation, stream};
use mema::io::read::{Outliers, input_name};

use super::serial::capacity;
use super::{read_in_metres, read_input};
use crate::cli::args::{AblationArgs, BenchArgs, StreamBenchArgs};

pub fn bench(args: &BenchArgs) -> Result<()> {
    mema::bench::run(&args.options())
}

pub fn ablation(args: &AblationArgs) -> Result<()> {
    let (cloud, _) = read_in_metres(&args.input, &args.units)?;
    ablation::run(&cloud, args.k, args.seed, args.json).with_context(|| input_name(&args.input))
}

pub fn stream_bench(args: &StreamBenchArgs) -> Result<()> {
    let config = args.fit.config(args.k)?;
    let capacity = capacity(args.k, &args.shape)?;
    let (cloud, _) = read_input(&args.input, &args.units, &args.bag, Outliers::Unchecked)?;
    let r = stream::run(
        &cloud,
        &config,
        capacity,
        args.repetitions,
        args.shape.tolerance.unwrap_or(0.0),
        args.shape.model.into(),
    )
    .with_context(|| input_name(&args.input))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!(
            "{}: {} points, k = {}, model {:?}\n  entities: stream {} / batch {}\n  eq. 13 by nearest centre (as mema eval), mean: stream {:.6} / batch {:.6} ({:+.1}%), stream max {:.6}\n  two-way score, stream / batch: Chamfer {:.6} / {:.6}, accuracy mean {:.6} / {:.6}, completeness mean {:.6} / {:.6}, phantom {:.3} / {:.3}\n  ingest, one thread: mapper {:.0} points/s ({:.1}x SRI-500), wire+mapper {:.0} points/s ({:.1}x)\n  final refit {:.3} s, {} merges",
            input_name(&args.input),
            r.points,
            r.k,
            r.model,
            r.stream_entities,
            r.batch_entities,
            r.stream_mean_error,
            r.batch_mean_error,
            r.error_change_percent,
            r.stream_max_error,
            r.stream_score.chamfer,
            r.batch_score.chamfer,
            r.stream_score.accuracy.mean,
            r.batch_score.accuracy.mean,
            r.stream_score.completeness.mean,
            r.batch_score.completeness.mean,
            r.stream_score.phantom,
            r.batch_score.phantom,
            r.mapper_points_per_s,
            r.mapper_vs_sri500,
            r.wire_points_per_s,
            r.wire_vs_sri500,
            r.finish_seconds,
            r.merges
        );
    }
    Ok(())
}
