//! `mema bench`: the README's performance figures, each against a baseline run in the same
//! process (timings are printed, never asserted by a test).
//!
//! 1. fitness: eq. 12 from moments vs the direct per-point sum, per evaluation and per fit;
//! 2. kmeans: accelerated vs plain k-means (the same labels and centre bits, checked);
//! 3. pipeline: read + k-means + fit + eval with stage shares and peak memory, 1 vs 2 threads;
//! 4. python: the same cloud and k through numpy + scikit-learn + a numpy DE (`--python`);
//! 5. fidelity (only when asked): the default map, the paper's and a Gaussian mixture at equal
//!    bytes on every shared cloud, scored two ways (`--python`).

pub mod ablation;
pub mod fidelity;
mod fidelity_report;
mod fitness_case;
pub mod free_space;
pub mod gmm;
mod memory;
mod pipeline_case;
pub mod query;
mod scene;
pub mod stream;

use anyhow::{Context, Result, bail};
use mema_core::Point3;
use mema_core::kmeans::KMeansParams;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::io::cloud::load_cloud_in_metres;
use crate::mapping::options::FitOptions;
use crate::mapping::pipeline::{KMeansEngine, run_kmeans};
pub use pipeline_case::{Case, PipelineRow, run_case};
pub use scene::{GAP, MEMBERS, Scene, environment};

/// The benchmarks `mema bench` runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Which {
    /// Eq. 12 from moments vs the direct per-point sum.
    Fitness,
    /// Accelerated vs plain k-means.
    Kmeans,
    /// The whole pipeline, stage by stage, with its peak memory, on 1 and 2 threads.
    Pipeline,
    /// The same clouds through numpy, scikit-learn and a numpy DE.
    Python,
    /// The default, the paper's and a Gaussian mixture's maps at equal bytes, scored two ways.
    Fidelity,
    /// Held-out rays of the shared Ouster sweeps at mema's maps and OctoMap's at equal bytes.
    FreeSpace,
}

/// What a `mema bench` run does.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOptions {
    /// Directory holding the shared clouds.
    pub data: PathBuf,
    /// Benchmarks to run (empty: fitness, kmeans, pipeline, plus python when `python` is given).
    pub only: Vec<Which>,
    /// A Python with numpy and scikit-learn, for benchmarks 4 and 5.
    pub python: Option<PathBuf>,
    /// Only these clouds: fidelity's of `data` (empty: every PLY, PCD, LAS and LAZ file there),
    /// the timing benchmarks' among their own cases (empty: all).
    pub clouds: Vec<String>,
    /// Fidelity: map budgets in bytes.
    pub budgets: Vec<usize>,
    /// Fidelity: where GMM fits are kept and reused.
    pub gmm_cache: Option<PathBuf>,
    /// Fidelity: print the results as one JSON object on stdout instead of the tables.
    pub json: bool,
    /// Iteration cap of the plain k-means on the environment case.
    pub plain_cap: u32,
    /// Timed runs per measurement; the fastest is reported.
    pub repeat: usize,
    /// Run one pipeline case (`NAME:K:THREADS`) in this process and print it as JSON: each
    /// case runs in a fresh `mema bench` process so that its peak memory is its own.
    pub case: Option<String>,
}

/// The fastest of `repeat` runs, with the last run's value.
pub fn fastest<T>(repeat: usize, mut f: impl FnMut() -> Result<T>) -> Result<(Duration, T)> {
    let mut best = Duration::MAX;
    let mut last = None;
    for _ in 0..repeat.max(1) {
        let t = Instant::now();
        let v = f()?;
        best = best.min(t.elapsed());
        last = Some(v);
    }
    last.map(|v| (best, v)).context("no run")
}

/// A duration in milliseconds.
pub fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// A cloud of the shared data, or the environment scene for `"environment"`.
pub fn load(data: &Path, name: &str) -> Result<Vec<Point3>> {
    if name == "environment" {
        return Ok(environment(data)?.points);
    }
    Ok(load_cloud_in_metres(&data.join(name), None)?.0.points)
}

/// The cases of a timing benchmark that `--clouds` keeps (all of them when it names none).
fn chosen<T: Copy>(args: &BenchOptions, cases: &[(&'static str, T)]) -> Vec<(&'static str, T)> {
    cases
        .iter()
        .filter(|(name, _)| args.clouds.is_empty() || args.clouds.iter().any(|c| c == name))
        .copied()
        .collect()
}

/// Runs the benchmarks `args` asks for, printing their tables.
pub fn run(args: &BenchOptions) -> Result<()> {
    if let Some(case) = &args.case {
        return pipeline_case::child(args, case);
    }
    let mut which = args.only.clone();
    if which.is_empty() {
        which = vec![Which::Fitness, Which::Kmeans, Which::Pipeline];
        if args.python.is_some() {
            which.push(Which::Python);
        }
    }
    if !which.contains(&Which::Fidelity) && !which.contains(&Which::FreeSpace) {
        let known =
            |c: &String| c == "office1.pcd" || PIPELINE_CASES.iter().any(|(name, _)| name == c);
        if let Some(unknown) = args.clouds.iter().find(|c| !known(c)) {
            bail!(
                "--clouds: {unknown} is none of the timing benchmarks' clouds (car6.pcd, office1.pcd, five_people.pcd, cturtle.pcd, environment)"
            );
        }
    }
    let header = format!(
        "mema bench: {} threads in the global pool, data {}",
        rayon::current_num_threads(),
        args.data.display()
    );
    // Keeps stdout one JSON document under --json.
    if args.json {
        eprintln!("{header}");
    } else {
        println!("{header}");
    }
    for w in which {
        match w {
            Which::Fitness => fitness_case::fitness(args)?,
            Which::Kmeans => kmeans(args)?,
            Which::Pipeline => pipeline(args)?,
            Which::Python => python(args)?,
            Which::Fidelity => fidelity_bench(args)?,
            Which::FreeSpace => free_space::free_space(args)?,
        }
    }
    Ok(())
}

fn same_bits(a: &[Point3], b: &[Point3]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b.iter())
            .all(|(p, q)| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits))
}

fn kmeans(args: &BenchOptions) -> Result<()> {
    println!();
    println!("2. k-means: accelerated vs plain (same seed; labels and centre bits compared)");
    println!(
        "{:<20} {:>8} {:>5} {:>5} {:>10} {:>10} {:>10} {:>7} {:>7} {:>8} {:>5}",
        "cloud",
        "n",
        "k",
        "iters",
        "plain ms",
        "fast 1t ms",
        "fast 2t ms",
        "x (1t)",
        "x (2t)",
        "searched",
        "same"
    );
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build()?;
    let cases = chosen(
        args,
        &[
            ("car6.pcd", (150, None)),
            ("office1.pcd", (2000, None)),
            ("environment", (8880, Some(args.plain_cap))),
        ],
    );
    for (name, (k, cap)) in cases {
        let points = load(&args.data, name)?;
        let params = KMeansParams {
            max_iterations: cap.unwrap_or(KMeansParams::default().max_iterations),
            ..KMeansParams::default()
        };
        // The plain run is the slow baseline: once is enough.
        let (plain_time, plain) =
            fastest(1, || run_kmeans(&points, k, &params, KMeansEngine::Plain))?;
        let (one_time, fast) = one.install(|| {
            fastest(args.repeat, || {
                run_kmeans(&points, k, &params, KMeansEngine::Accelerated)
            })
        })?;
        let (two_time, fast2) = two.install(|| {
            fastest(args.repeat, || {
                run_kmeans(&points, k, &params, KMeansEngine::Accelerated)
            })
        })?;
        let same = plain.labels == fast.labels
            && same_bits(&plain.centres, &fast.centres)
            && fast2.labels == fast.labels
            && same_bits(&fast2.centres, &fast.centres);
        let label = match cap {
            Some(c) => format!("{name} (cap {c})"),
            None => name.to_string(),
        };
        println!(
            "{:<20} {:>8} {:>5} {:>5} {:>10.1} {:>10.1} {:>10.1} {:>6.0}x {:>6.0}x {:>7.1}% {:>5}",
            label,
            points.len(),
            k,
            fast.outcome.iterations,
            ms(plain_time),
            ms(one_time),
            ms(two_time),
            plain_time.as_secs_f64() / one_time.as_secs_f64(),
            plain_time.as_secs_f64() / two_time.as_secs_f64(),
            100.0 * fast.searches as f64 / fast.visits.max(1) as f64,
            if same { "yes" } else { "NO" }
        );
        if !same {
            bail!("{name}: accelerated k-means differs from the plain one");
        }
        if cap.is_some() {
            let full = KMeansParams::default();
            let (t1, r1) = one.install(|| {
                fastest(args.repeat, || {
                    run_kmeans(&points, k, &full, KMeansEngine::Accelerated)
                })
            })?;
            let (t2, _) = two.install(|| {
                fastest(args.repeat, || {
                    run_kmeans(&points, k, &full, KMeansEngine::Accelerated)
                })
            })?;
            println!(
                "{:<20} {:>8} {:>5} {:>5} {:>10} {:>10.1} {:>10.1} {:>7} {:>7} {:>7.1}%",
                format!("{name} (full)"),
                points.len(),
                k,
                r1.outcome.iterations,
                "-",
                ms(t1),
                ms(t2),
                "",
                "",
                100.0 * r1.searches as f64 / r1.visits.max(1) as f64,
            );
        }
    }
    println!(
        "(searched: share of point visits that needed the kd-tree; the rest were decided by bounds)"
    );
    Ok(())
}

/// The clouds of the pipeline and Python benchmarks, each at its k.
const PIPELINE_CASES: &[(&str, usize)] = &[
    ("car6.pcd", 150),
    ("five_people.pcd", 350),
    ("cturtle.pcd", 2000),
    ("environment", 8880),
];

fn pipeline(args: &BenchOptions) -> Result<()> {
    println!();
    println!("3. pipeline: read + k-means + fit (ellipsoid and sphere) + eval (eq. 13, both maps)");
    println!(
        "{:<16} {:>8} {:>5} {:>3} {:>9} {:>6} {:>6} {:>6} {:>6} {:>8} {:>8} {:>6} {:>8} {:>6} {:>6} {:>5}",
        "cloud",
        "n",
        "k",
        "thr",
        "wall ms",
        "read",
        "kmeans",
        "fit",
        "eval",
        "cloud MB",
        "heap MB",
        "heap/c",
        "VmHWM MB",
        "hwm/c",
        "above",
        "same"
    );
    for (name, k) in chosen(args, PIPELINE_CASES) {
        let one = pipeline_case::spawn(args, name, k, 1)?;
        println!("{}", one.format(1, true));
        let two = pipeline_case::spawn(args, name, k, 2)?;
        println!("{}", two.format(2, two.fingerprint == one.fingerprint));
        let mb = |b: Option<u64>| b.map_or("-".to_string(), |b| format!("{:.2}", b as f64 / 1e6));
        println!(
            "{:<16} 2 threads: {:.2}x faster than 1; before reading: {} MB resident, {} MB of heap live",
            "",
            one.wall.as_secs_f64() / two.wall.as_secs_f64(),
            mb(two.before),
            mb(two.heap_before),
        );
        if let Some(stages) = two.heap_stages {
            let cloud = (two.points * crate::analysis::stats::CLOUD_BYTES_PER_POINT) as f64;
            let [read, kmeans, fit, eval] = stages.map(|b| b as f64 / cloud);
            println!(
                "{:<16} heap peak by stage (x cloud, 2 threads): read {read:.2}, k-means {kmeans:.2}, fit {fit:.2}, eval {eval:.2}",
                ""
            );
        }
    }
    println!(
        "(each row a fresh `mema bench --case` process; stage columns: share of wall time; cloud MB:"
    );
    println!(
        " 12 bytes per point, the paper's count; heap: the most heap bytes live at once during a run,"
    );
    println!(
        " above those live before it read anything (counting allocator), largest of the runs; VmHWM:"
    );
    println!(
        " the process's peak resident size, binary and threads included, first run; above: VmHWM minus"
    );
    println!(
        " the resident size before reading, over the cloud; same: map bits equal to the 1-thread run)"
    );
    Ok(())
}

fn python(args: &BenchOptions) -> Result<()> {
    let Some(python) = &args.python else {
        bail!(
            "benchmark 4 needs --python PATH (a Python with numpy and scikit-learn; see scripts/bench.sh)"
        );
    };
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/bench_python.py");
    println!();
    println!(
        "4. python: numpy + scikit-learn KMeans + numpy DE (both fits) vs mema's read + k-means + fit"
    );
    println!(
        "{:<16} {:>8} {:>5} {:>8} {:>11} {:>10} {:>9} {:>8} {:>10} {:>10} {:>9} {:>7}",
        "cloud",
        "n",
        "k",
        "py iters",
        "py kmeans s",
        "py fit s",
        "py tot s",
        "iters",
        "mema km s",
        "mema fit s",
        "mema s",
        "ratio"
    );
    let dir = std::env::temp_dir().join(format!("mema-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    for (name, k) in chosen(args, PIPELINE_CASES) {
        let row = pipeline_case::spawn(args, name, k, rayon::current_num_threads())?;
        let points = load(&args.data, name)?;
        let npy = dir.join(format!("{name}.npy"));
        write_npy(&npy, &points)?;
        let out = std::process::Command::new(python)
            .arg(&script)
            .arg(&npy)
            .arg(k.to_string())
            .output()
            .with_context(|| format!("running {}", python.display()))?;
        std::fs::remove_file(&npy).ok();
        if !out.status.success() {
            bail!(
                "{} failed: {}",
                script.display(),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        let py: serde_json::Value = serde_json::from_slice(&out.stdout)
            .with_context(|| format!("{} printed no JSON", script.display()))?;
        let get = |key: &str| py.get(key).and_then(|v| v.as_f64()).unwrap_or(f64::NAN);
        let ours = (row.read + row.kmeans + row.fit).as_secs_f64();
        println!(
            "{:<16} {:>8} {:>5} {:>8} {:>11.2} {:>10.2} {:>9.2} {:>8} {:>10.3} {:>10.3} {:>9.3} {:>6.0}x",
            name,
            row.points,
            k,
            get("iterations"),
            get("kmeans_s"),
            get("fit_s"),
            get("total_s"),
            row.iterations,
            row.kmeans.as_secs_f64(),
            row.fit.as_secs_f64(),
            ours,
            get("total_s") / ours
        );
    }
    std::fs::remove_dir_all(&dir).ok();
    println!(
        "(mema on all threads of the global pool; scikit-learn on its own OpenMP threads; both read"
    );
    println!(
        " their input (mema the cloud file or scene, Python the same points as .npy); eval excluded)"
    );
    Ok(())
}

fn fidelity_bench(args: &BenchOptions) -> Result<()> {
    let Some(python) = &args.python else {
        bail!(
            "the fidelity benchmark needs --python PATH (a Python with numpy and scikit-learn; see scripts/bench.sh)"
        );
    };
    if let Some(&b) = args.budgets.iter().find(|&&b| b == 0) {
        return Err(crate::error::ConfigError::ZeroBudget(b).into());
    }
    let opts = fidelity::FidelityOptions {
        data: args.data.clone(),
        python: python.clone(),
        clouds: args.clouds.clone(),
        budgets: args.budgets.clone(),
        // k is set per budget; 1 only passes the check.
        base: FitOptions::default().config(1)?,
        samples: crate::analysis::fidelity::DEFAULT_SAMPLES,
        seed: 0,
        gmm_cache: args.gmm_cache.clone(),
    };
    if let Some(dir) = &opts.gmm_cache {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let report = fidelity::run(&opts)?;
    // Under --json the tables go to stderr: one run gives both, and stdout stays one document.
    let (mut stdout, mut stderr) = (std::io::stdout().lock(), std::io::stderr().lock());
    let out: &mut dyn std::io::Write = if args.json { &mut stderr } else { &mut stdout };
    writeln!(out)?;
    writeln!(
        out,
        "5. fidelity: default (shells), paper, GMM (2-sigma shells) and streamed maps at equal bytes, two-way score as read back"
    )?;
    fidelity_report::print_tables(&report, out)?;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    }
    Ok(())
}

/// Writes points as a NumPy `.npy` (format 1.0, little-endian float32, n x 3).
fn write_npy(path: &Path, points: &[Point3]) -> Result<()> {
    let dict = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({}, 3), }}",
        points.len()
    );
    // Magic (6) + version (2) + length (2) + dict + padding + newline, to a multiple of 64.
    let unpadded = 10 + dict.len() + 1;
    let header_len = dict.len() + 1 + (64 - unpadded % 64) % 64;
    let mut bytes = Vec::with_capacity(10 + header_len + points.len() * 12);
    bytes.extend_from_slice(b"\x93NUMPY\x01\x00");
    bytes.extend_from_slice(&(header_len as u16).to_le_bytes());
    bytes.extend_from_slice(dict.as_bytes());
    bytes.resize(10 + header_len - 1, b' ');
    bytes.push(b'\n');
    for p in points {
        for v in p.to_array() {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}
