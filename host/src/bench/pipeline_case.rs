//! One timed run of the whole pipeline, stage by stage, with its peak memory.

use anyhow::Result;
use std::hash::{Hash, Hasher};
use std::path::Path;
use std::time::{Duration, Instant};

use super::{load, memory, ms};
use crate::heap;
use crate::mapping::options::FitOptions;
use crate::mapping::pipeline;

/// One pipeline case: a cloud of the shared data (or the environment scene) and its k.
pub struct Case<'a> {
    pub data: &'a Path,
    pub name: &'a str,
    pub k: usize,
}

/// The fastest of the repeated runs. The resident peak is the first run's, in a process that has
/// done nothing else yet (later runs reuse the allocator's freed pages, which would blur it);
/// the heap peak is the largest of all runs (each starts a new one).
#[derive(serde::Serialize, serde::Deserialize)]
pub struct PipelineRow {
    pub name: String,
    pub points: usize,
    pub k: usize,
    pub iterations: u32,
    pub read: Duration,
    pub kmeans: Duration,
    pub fit: Duration,
    pub eval: Duration,
    pub wall: Duration,
    /// Peak resident bytes (VmHWM) of the process by the end of the first run, and resident
    /// bytes just before it read anything.
    pub peak: Option<u64>,
    pub before: Option<u64>,
    /// Most heap bytes live at once during a run, above those live before it read anything
    /// (counted by `mema::heap`), and those live before.
    pub heap_peak: Option<u64>,
    pub heap_before: Option<u64>,
    /// The same peak within each stage: read, k-means (with the clusters' moments), fit, eval.
    pub heap_stages: Option<[u64; 4]>,
    /// Hash of the labels and both maps' bits: equal runs, equal fingerprints.
    pub fingerprint: u64,
}

impl PipelineRow {
    /// The row as the table prints it, for a run on `threads` threads; `same` tells whether its
    /// map bits equal the 1-thread run's.
    pub fn format(&self, threads: usize, same: bool) -> String {
        let share = |d: Duration| 100.0 * d.as_secs_f64() / self.wall.as_secs_f64();
        let cloud = (self.points * crate::analysis::stats::CLOUD_BYTES_PER_POINT) as f64;
        let mb = |b: Option<u64>| b.map_or("-".to_string(), |b| format!("{:.2}", b as f64 / 1e6));
        let ratio =
            |b: Option<u64>| b.map_or("-".to_string(), |b| format!("{:.2}", b as f64 / cloud));
        let above = self.peak.zip(self.before).map(|(p, b)| p.saturating_sub(b));
        format!(
            "{:<16} {:>8} {:>5} {:>3} {:>9.1} {:>5.0}% {:>5.0}% {:>5.0}% {:>5.0}% {:>8.2} {:>8} {:>6} {:>8} {:>6} {:>6} {:>5}",
            self.name,
            self.points,
            self.k,
            threads,
            ms(self.wall),
            share(self.read),
            share(self.kmeans),
            share(self.fit),
            share(self.eval),
            cloud / 1e6,
            mb(self.heap_peak),
            ratio(self.heap_peak),
            mb(self.peak),
            ratio(self.peak),
            ratio(above),
            if same { "yes" } else { "NO" }
        )
    }
}

/// Read, cluster, fit both entity kinds, evaluate both maps: `mema map`'s work, timed.
pub fn run_case(case: &Case<'_>, repeat: usize) -> Result<PipelineRow> {
    let config = FitOptions::default().config(case.k)?;
    let mut best: Option<PipelineRow> = None;
    let counting = heap::counting();
    for _ in 0..repeat.max(1) {
        let before = memory::current();
        let heap_before = heap::reset_peak();
        // Each stage's heap peak, starting a new one for the next; the run's is the largest.
        let mut heap_stages = [0u64; 4];
        let mut stage_done = |stage: usize| {
            heap_stages[stage] = heap::peak().saturating_sub(heap_before) as u64;
            heap::reset_peak();
        };
        let start = Instant::now();
        let points = load(case.data, case.name)?;
        let read = start.elapsed();
        stage_done(0);
        let t = Instant::now();
        let clusters = pipeline::cluster(&points, case.k, &config.kmeans)?;
        let kmeans = t.elapsed();
        stage_done(1);
        let t = Instant::now();
        let fitted = pipeline::fit_all(&clusters.moments, config.seed, &config.fit);
        let fit = t.elapsed();
        stage_done(2);
        let t = Instant::now();
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        clusters.labels.hash(&mut hasher);
        for fits in [&fitted.ellipsoids, &fitted.spheres] {
            let entities: Vec<_> = fits.iter().map(|f| f.entity).collect();
            let errors = pipeline::cluster_errors(&points, &clusters.labels, &entities);
            for (e, err) in entities.iter().zip(errors) {
                e.center.to_array().map(f32::to_bits).hash(&mut hasher);
                e.weights.map(f32::to_bits).hash(&mut hasher);
                err.to_bits().hash(&mut hasher);
            }
        }
        let eval = t.elapsed();
        let wall = start.elapsed();
        stage_done(3);
        let heap_stages = counting.then_some(heap_stages);
        let row = PipelineRow {
            name: case.name.to_string(),
            points: points.len(),
            k: case.k,
            iterations: clusters.outcome.iterations,
            read,
            kmeans,
            fit,
            eval,
            wall,
            peak: memory::peak(),
            before,
            heap_peak: heap_stages.and_then(|s| s.into_iter().max()),
            heap_before: counting.then_some(heap_before as u64),
            heap_stages,
            fingerprint: hasher.finish(),
        };
        best = Some(match best {
            Some(b) => {
                let heap_peak = b.heap_peak.max(row.heap_peak);
                let heap_stages = b
                    .heap_stages
                    .zip(row.heap_stages)
                    .map(|(b, r)| std::array::from_fn(|i| b[i].max(r[i])));
                let first = (b.peak, b.before, b.heap_before);
                let mut best = if b.wall <= row.wall { b } else { row };
                (best.peak, best.before, best.heap_before) = first;
                (best.heap_peak, best.heap_stages) = (heap_peak, heap_stages);
                best
            }
            None => row,
        });
    }
    best.ok_or_else(|| anyhow::anyhow!("no run"))
}

/// `mema bench --case NAME:K:THREADS`: one case in this fresh process, printed as JSON.
pub fn child(args: &super::BenchOptions, spec: &str) -> Result<()> {
    let mut parts = spec.rsplitn(3, ':');
    let (Some(threads), Some(k), Some(name)) = (parts.next(), parts.next(), parts.next()) else {
        anyhow::bail!("--case wants NAME:K:THREADS, got {spec}");
    };
    let case = Case {
        data: &args.data,
        name,
        k: k.parse()?,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.parse()?)
        .build()?;
    let row = pool.install(|| run_case(&case, args.repeat))?;
    println!("{}", serde_json::to_string(&row)?);
    Ok(())
}

/// Runs one case in a child `mema bench` process and reads its row back.
pub fn spawn(
    args: &super::BenchOptions,
    name: &str,
    k: usize,
    threads: usize,
) -> Result<PipelineRow> {
    let out = std::process::Command::new(std::env::current_exe()?)
        .arg("bench")
        .arg("--data")
        .arg(&args.data)
        .arg("--repeat")
        .arg(args.repeat.to_string())
        .arg("--case")
        .arg(format!("{name}:{k}:{threads}"))
        .output()?;
    if !out.status.success() {
        anyhow::bail!(
            "bench case {name} k={k}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(serde_json::from_slice(&out.stdout)?)
}
