//! Argument parsing by hand (no clap), so the minimal build that the cross-build check compiles
//! in debug and with `-C target-cpu=native` is the core, this crate and nothing else.

#[cfg(feature = "reference")]
use std::path::PathBuf;
use std::sync::Mutex;

use mema_core::stream::StreamModel;
use mema_firmware::{Firmware, SHELLS, Snapshot, model_params, stream_params};
use mema_firmware_sim::board::{Board, BoardSpec};
use mema_firmware_sim::fault::FaultConfig;
use mema_firmware_sim::harness::{RunConfig, RunReport, run};

/// The simulator's capacity: `-k` may be at most this (the budget's largest K).
pub const SIM_K: usize = 1000;
/// Working clusters: with none frozen, the stream keeps a finer summary until its end
/// (`mema_core::stream::summary_layout`), which this holds whole up to k = 512, as the host's
/// `replay` does.
pub const SIM_WORKING: usize = 4096;
/// Centre-hash buckets: about twice the working clusters.
pub const SIM_G: usize = 8192;

/// The firmware's state and its snapshot, in statics as on the device. The mutex is the board's
/// ownership check: a second owner gets `WouldBlock`, never a second reference.
/// Frozen entities share the capacity: `-k` counts working and frozen together.
static FIRMWARE: Mutex<Firmware<SIM_WORKING, SIM_G, SIM_K>> =
    Mutex::new(Firmware::new(stream_params(0, 150, 0)));
static SNAPSHOT: Mutex<Snapshot<SIM_WORKING, SIM_G, SIM_K>> =
    Mutex::new(Snapshot::new(stream_params(0, 150, 0)));

/// What can go wrong, by kind: usage (exit 2) or a failed run or check (exit 1).
#[derive(Debug)]
pub enum CliError {
    Usage(String),
    Failed(String),
}

impl CliError {
    pub fn exit_code(&self) -> u8 {
        match self {
            Self::Usage(_) => 2,
            Self::Failed(_) => 1,
        }
    }
}

impl std::fmt::Display for CliError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Usage(m) => write!(
                f,
                "{m}\nConsider `mema-firmware-sim run CAPTURE -k 150 -o MAP`, `budget` or `reference`."
            ),
            Self::Failed(m) => write!(f, "{m}"),
        }
    }
}

fn usage(m: impl Into<String>) -> CliError {
    CliError::Usage(m.into())
}

fn failed(m: impl Into<String>) -> CliError {
    CliError::Failed(m.into())
}

/// Options as `--name value` pairs, flags and positionals.
pub struct Args {
    pub positional: Vec<String>,
    pairs: Vec<(String, String)>,
    flags: Vec<String>,
}

const FLAGS: [&str; 1] = ["--json"];

impl Args {
    pub fn parse(args: &[String]) -> Result<Self, CliError> {
        let mut out = Self {
            positional: Vec::new(),
            pairs: Vec::new(),
            flags: Vec::new(),
        };
        let mut it = args.iter();
        while let Some(a) = it.next() {
            if FLAGS.contains(&a.as_str()) {
                out.flags.push(a.clone());
            } else if a.starts_with('-') && a.len() > 1 {
                let v = it
                    .next()
                    .ok_or_else(|| usage(format!("{a} needs a value")))?;
                out.pairs.push((a.clone(), v.clone()));
            } else {
                out.positional.push(a.clone());
            }
        }
        Ok(out)
    }

    pub fn flag(&self, name: &str) -> bool {
        self.flags.iter().any(|f| f == name)
    }

    pub fn get(&self, names: &[&str]) -> Option<&str> {
        self.pairs
            .iter()
            .rev()
            .find(|(k, _)| names.contains(&k.as_str()))
            .map(|(_, v)| v.as_str())
    }

    pub fn number<T: std::str::FromStr>(&self, names: &[&str], default: T) -> Result<T, CliError> {
        match self.get(names) {
            None => Ok(default),
            Some(v) => v
                .parse()
                .map_err(|_| usage(format!("{}: '{v}' is not a valid number", names[0]))),
        }
    }

    /// Refuses options this command does not know, naming them.
    pub fn only(&self, known: &[&str]) -> Result<(), CliError> {
        match self
            .pairs
            .iter()
            .find(|(k, _)| !known.contains(&k.as_str()))
        {
            Some((k, _)) => Err(usage(format!("unknown option {k}"))),
            None => Ok(()),
        }
    }
}

pub fn dispatch(args: &[String]) -> Result<(), CliError> {
    let (command, rest) = args
        .split_first()
        .ok_or_else(|| usage("no command given"))?;
    let parsed = Args::parse(rest)?;
    match command.as_str() {
        "run" => run_command(&parsed),
        #[cfg(feature = "reference")]
        "budget" => crate_budget(&parsed),
        #[cfg(feature = "reference")]
        "reference" => crate_reference(&parsed),
        other => Err(usage(format!("unknown command '{other}'"))),
    }
}

#[cfg(feature = "reference")]
fn crate_budget(args: &Args) -> Result<(), CliError> {
    args.only(&["--image", "--qemu-report", "--board", "--board-run"])?;
    let path = |name: &str| args.get(&[name]).map(PathBuf::from);
    let report = mema_firmware_sim::budget::report(
        path("--image").as_deref(),
        path("--qemu-report").as_deref(),
        path("--board").as_deref(),
        path("--board-run").as_deref(),
    )
    .map_err(|e| failed(e.to_string()))?;
    if args.flag("--json") {
        println!("{}", report.json());
    } else {
        print!("{}", report.text());
    }
    Ok(())
}

#[cfg(feature = "reference")]
fn crate_reference(args: &Args) -> Result<(), CliError> {
    args.only(&["-k", "--working", "--seed", "--sum-bits"])?;
    let k: usize = args.number(&["-k"], 150)?;
    let seed: u64 = args.number(&["--seed"], 0)?;
    let setup = mema_firmware_sim::compare::Setup {
        sum_bits: args.number(
            &["--sum-bits"],
            mema_firmware_sim::compare::Setup::F64_SUM_BITS,
        )?,
        working: args.number(&["--working"], k)?,
        ..mema_firmware_sim::compare::Setup::new(k, seed)
    };
    let clouds: Vec<PathBuf> = if args.positional.is_empty() {
        mema_firmware_sim::compare::shared_clouds().map_err(|e| failed(e.to_string()))?
    } else {
        args.positional.iter().map(PathBuf::from).collect()
    };
    let summary = mema_firmware_sim::compare::compare_clouds(&clouds, &setup);
    if args.flag("--json") {
        println!("{}", summary.json());
    } else {
        print!("{}", summary.text());
    }
    if summary.passed() {
        Ok(())
    } else {
        Err(failed(
            "the core and the f64 reference disagree beyond the tolerances (above)",
        ))
    }
}

fn run_command(args: &Args) -> Result<(), CliError> {
    args.only(&[
        "-k",
        "--working",
        "--seed",
        "-o",
        "--output",
        "--chunk-seed",
        "--max-chunk",
        "--snapshot-every",
        "--fault-seed",
        "--noise",
        "--overrun",
        "--truncate",
        "--reset",
        "--accepted",
        "--ram",
        "--model",
        "--reach",
    ])?;
    let [capture] = args.positional.as_slice() else {
        return Err(usage("run takes exactly one CAPTURE"));
    };
    let k: usize = args.number(&["-k"], 150)?;
    if k == 0 || k > SIM_K {
        return Err(usage(format!(
            "-k {k}: must be 1..={SIM_K}, the simulator's capacity"
        )));
    }
    let working: usize = args.number(&["--working"], k)?;
    if working == 0 || working > k {
        return Err(usage(format!("--working {working}: must be 1..=k ({k})")));
    }
    let seed: u64 = args.number(&["--seed"], 0)?;
    // The host's default (`mema replay`), so both map a capture to the same bytes.
    let model = match args.get(&["--model"]).unwrap_or("shells") {
        "paper" => StreamModel::Paper,
        "shells" => SHELLS,
        other => return Err(usage(format!("--model {other}: must be paper or shells"))),
    };
    let faults = FaultConfig {
        seed: args.number(&["--fault-seed"], 0)?,
        noise_ppm: args.number(&["--noise"], 0)?,
        overrun_ppm: args.number(&["--overrun"], 0)?,
        truncate_ppm: args.number(&["--truncate"], 0)?,
        reset_ppm: args.number(&["--reset"], 0)?,
    };
    let config = RunConfig {
        chunk_seed: args.number(&["--chunk-seed"], 0)?,
        max_chunk: args.number(&["--max-chunk"], 256)?,
        snapshot_every: args.number(&["--snapshot-every"], 16)?,
        faults: (faults
            != FaultConfig {
                seed: faults.seed,
                ..FaultConfig::default()
            })
        .then_some(faults),
    };
    let bytes = std::fs::read(capture).map_err(|e| failed(format!("{capture}: {e}")))?;

    // The board: RAM as on mps2-an386 (4 MiB) unless told; statics declared before anything runs.
    let mut board = Board::new(BoardSpec {
        ram_bytes: args.number(&["--ram"], 4 << 20)?,
        stack_bytes: 64 * 1024,
    });
    board
        .declare::<Firmware<SIM_WORKING, SIM_G, SIM_K>>("FIRMWARE")
        .and_then(|()| board.declare::<Snapshot<SIM_WORKING, SIM_G, SIM_K>>("SNAPSHOT"))
        .map_err(|e| failed(format!("board: {e}")))?;
    let mut firmware = FIRMWARE
        .try_lock()
        .map_err(|_| failed("FIRMWARE already has an owner"))?;
    let mut snapshot = SNAPSHOT
        .try_lock()
        .map_err(|_| failed("SNAPSHOT already has an owner"))?;
    // Power-on: the statics take this run's seed and k (their initialiser had the defaults).
    let params = model_params(seed, working, k - working, model);
    let reach: f32 = args.number(&["--reach"], mema_core::link::receiver::DEFAULT_REACH)?;
    if !(reach > 0.0 && reach.is_finite()) {
        return Err(usage(format!(
            "--reach {reach}: must be a positive number of metres"
        )));
    }
    *firmware = Firmware::with_reach(params, reach);
    *snapshot = Snapshot::new(params);

    let report = run(&board, &mut firmware, &mut snapshot, &bytes, &config)
        .map_err(|e| failed(e.to_string()))?;
    if let Some(out) = args.get(&["-o", "--output"]) {
        std::fs::write(out, &report.map).map_err(|e| failed(format!("{out}: {e}")))?;
    }
    if let Some(path) = args.get(&["--accepted"]) {
        let text: String = report.accepted.iter().map(|s| format!("{s}\n")).collect();
        std::fs::write(path, text).map_err(|e| failed(format!("{path}: {e}")))?;
    }
    if args.flag("--json") {
        println!("{}", json(&report, &board));
    } else {
        eprint!("{}", text(&report, &board, capture));
    }
    Ok(())
}

fn crc_of(map: &[u8]) -> u32 {
    map.last_chunk::<4>().map_or(0, |c| u32::from_le_bytes(*c))
}

/// The entity count the map's header states (any version).
fn entities_of(map: &[u8]) -> u32 {
    map.get(32..36)
        .and_then(|c| c.try_into().ok())
        .map_or(0, u32::from_le_bytes)
}

fn text(r: &RunReport, board: &Board, capture: &str) -> String {
    let d = &r.decoder;
    let f = &r.faults;
    format!(
        "firmware-sim: {capture}\n\
         \x20 delivered  {} chunks, {} ticks, ring peak {} bytes, ring overruns {}\n\
         \x20 frames     {} accepted, {} rejected (crc {}, cobs {}, length {}, oversize {}), {} lost, {} repeated\n\
         \x20 faults     {} noise bytes, {} overruns ({} bytes), {} truncations ({} bytes), {} resets\n\
         \x20 mapper     {} points, {} clusters (peak {}), {} merges, {} refits, {} paced joins, {} shed, {} restarts\n\
         \x20 statics    {} bytes ({})\n\
         \x20 map        {} bytes, CRC-32 {:08x}, end of stream: {}\n",
        r.deliveries,
        r.ticks,
        r.peak_pending,
        r.firmware.ring_overruns,
        d.accepted,
        d.rejected,
        d.bad_crc,
        d.bad_cobs,
        d.bad_length,
        d.oversized,
        d.lost,
        d.duplicates,
        f.noise_bytes,
        f.overruns,
        f.overrun_bytes,
        f.truncations,
        f.truncated_bytes,
        f.resets,
        r.mapper.points,
        entities_of(&r.map),
        r.peak_clusters,
        r.mapper.merges,
        r.mapper.refits,
        r.mapper.paced_joins,
        r.mapper.paced_shed,
        r.firmware.restarts,
        board.static_bytes(),
        board
            .statics()
            .iter()
            .map(|(n, b)| format!("{n} {b}"))
            .collect::<Vec<_>>()
            .join(", "),
        r.map.len(),
        crc_of(&r.map),
        r.end_of_stream,
    )
}

fn json(r: &RunReport, board: &Board) -> String {
    let d = &r.decoder;
    let f = &r.faults;
    format!(
        "{{\"map_bytes\":{},\"map_crc\":{},\"entities\":{},\"end_of_stream\":{},\"points\":{},\
         \"frames_accepted\":{},\"frames_rejected\":{},\"frames_lost\":{},\"frames_repeated\":{},\
         \"held_frames\":{},\"restarts\":{},\"resets\":{},\"noise_bytes\":{},\"overruns\":{},\
         \"truncations\":{},\"ring_overruns\":{},\"ring_peak\":{},\"peak_clusters\":{},\
         \"ticks\":{},\"deliveries\":{},\"static_bytes\":{},\"paced_joins\":{},\"paced_shed\":{}}}",
        r.map.len(),
        crc_of(&r.map),
        entities_of(&r.map),
        r.end_of_stream,
        r.mapper.points,
        d.accepted,
        d.rejected,
        d.lost,
        d.duplicates,
        r.accepted.len(),
        r.firmware.restarts,
        f.resets,
        f.noise_bytes,
        f.overruns,
        f.truncations,
        r.firmware.ring_overruns,
        r.peak_pending,
        r.peak_clusters,
        r.ticks,
        r.deliveries,
        board.static_bytes(),
        r.mapper.paced_joins,
        r.mapper.paced_shed,
    )
}
