//! Issue 4: the core as firmware runs it. Same map whatever the chunking, equal to the host's
//! `mema replay` (real binaries), faults and resets lose only what they must, the core within
//! tolerance of the independent f64 reference on every shared cloud, and fuzzed readers.
//! Debug vs release, `-C target-cpu=native` and the Cortex-M4F image under QEMU are compared by
//! `firmware-sim/check.sh`, which `scripts/test.sh` runs (it builds those variants).

use std::process::Command;

use mema::link::frames::{encode_stream, quantise};
use mema_core::stream::StreamModel;
use mema_firmware::{Firmware, SHELLS, Snapshot, model_params, stream_params};
use mema_firmware_sim::board::{Board, BoardSpec};
use mema_firmware_sim::compare::{Setup, compare_clouds, shared_clouds};
use mema_firmware_sim::fault::FaultConfig;
use mema_firmware_sim::harness::{RunConfig, RunReport, frames_of, map_of_frames, run};

use crate::guides::says;
use crate::util::{Dir, MemaCommand, mema_bin, shared};

const K: usize = 2048;
const G: usize = 4096;
/// Room for frozen entities; a run uses it only when its shape asks (`stream_params`).
const F: usize = 256;

/// Working clusters and frozen entities of a run: `(150, 0)` keeps all in working memory,
/// `(150, 250)` is the image's K = 400 layout.
pub(crate) type Shape = (usize, usize);

pub(crate) fn capture_of(cloud: &str) -> Vec<u8> {
    encode_stream(&wire_points_of(cloud)).expect("encodes")
}

/// `cloud`'s points as the wire carries them (i32 millimetres, in the cloud's local frame).
pub(crate) fn wire_points_of(cloud: &str) -> Vec<[i32; 3]> {
    let cloud = mema::io::load_cloud(&shared(cloud)).expect("cloud reads");
    cloud
        .points
        .iter()
        .map(|p| quantise(*p).expect("fits"))
        .collect()
}

fn play(capture: &[u8], k: usize, config: &RunConfig) -> RunReport {
    play_shaped(capture, (k, 0), config)
}

fn play_shaped(capture: &[u8], shape: Shape, config: &RunConfig) -> RunReport {
    play_model(capture, shape, StreamModel::Paper, config)
}

pub(crate) fn play_model(
    capture: &[u8],
    (working, frozen): Shape,
    model: StreamModel,
    config: &RunConfig,
) -> RunReport {
    let board = Board::new(BoardSpec {
        ram_bytes: 4 << 20,
        stack_bytes: 64 << 10,
    });
    let params = model_params(0, working, frozen, model);
    let mut firmware: Box<Firmware<K, G, F>> = Box::new(Firmware::new(params));
    let mut snapshot: Box<Snapshot<K, G, F>> = Box::new(Snapshot::new(params));
    run(&board, &mut firmware, &mut snapshot, capture, config).expect("runs")
}

#[test]
fn the_map_is_the_same_whatever_the_chunking() {
    let capture = capture_of("car6.pcd");
    let whole = play(
        &capture,
        150,
        &RunConfig {
            max_chunk: 1 << 20,
            ..RunConfig::default()
        },
    );
    assert!(whole.end_of_stream && whole.mapper.points == 10_031);
    for (chunk_seed, max_chunk) in [(0, 1), (1, 2), (2, 7), (3, 256), (4, 1024)] {
        let r = play(
            &capture,
            150,
            &RunConfig {
                chunk_seed,
                max_chunk,
                ..RunConfig::default()
            },
        );
        assert_eq!(
            r.map, whole.map,
            "chunks of 1..={max_chunk}, seed {chunk_seed}"
        );
        assert!(r.deliveries > whole.deliveries);
    }
}

/// Shells at the image's layout (frozen entities included): the same bytes whatever the UART's
/// chunking, and no DE anywhere.
#[test]
fn shells_are_the_same_whatever_the_chunking() {
    let capture = capture_of("car6.pcd");
    let play = |chunk_seed, max_chunk| {
        let config = RunConfig {
            chunk_seed,
            max_chunk,
            ..RunConfig::default()
        };
        play_model(&capture, (150, 250), SHELLS, &config)
    };
    let whole = play(0, 1 << 20);
    assert!(whole.end_of_stream && whole.mapper.points == 10_031);
    // Most of the image's 250 frozen slots filled (the join radius grows where the pacing falls
    // short, so car6's clusters are fewer and larger than the slots).
    assert!(whole.mapper.frozen > 150 && whole.mapper.refits == 0);
    for (chunk_seed, max_chunk) in [(0, 1), (2, 7), (3, 256)] {
        assert_eq!(
            play(chunk_seed, max_chunk).map,
            whole.map,
            "1..={max_chunk}"
        );
    }
}

#[test]
fn firmware_sim_equals_mema_replay_of_the_same_capture() {
    let dir = Dir::new("fw-replay");
    let fw_bin =
        mema_bin().with_file_name(format!("mema-firmware-sim{}", std::env::consts::EXE_SUFFIX));
    // The paper's model pinned as before; shells asked for, and by both defaults (no --model).
    for (cloud, k, working, model) in [
        ("car6.pcd", "150", "150", Some("paper")),
        ("bun_zipper.ply", "350", "350", Some("paper")),
        ("car6.pcd", "400", "150", Some("paper")),
        ("car6.pcd", "400", "150", None),
        ("bun_zipper.ply", "400", "150", Some("shells")),
    ] {
        let model_args: Vec<&str> = model.map_or(vec![], |m| vec!["--model", m]);
        let capture = dir.join("capture.bin");
        MemaCommand::new(&dir)
            .arg("scanner-sim")
            .arg("--port")
            .arg(&capture)
            .arg(shared(cloud))
            .run()
            .assert_ok();
        let replayed = MemaCommand::new(&dir)
            .args(["replay", "capture.bin", "-k", k, "--working", working])
            .args(&model_args)
            .args(["-o", "replay.mema", "--json"])
            .run()
            .assert_ok();
        let out = Command::new(&fw_bin)
            .args([
                "run",
                "capture.bin",
                "-k",
                k,
                "--working",
                working,
                "-o",
                "fw.mema",
                "--max-chunk",
                "97",
                "--json",
            ])
            .args(&model_args)
            .current_dir(&dir.path)
            .output()
            .expect("mema-firmware-sim runs");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let replay = std::fs::read(dir.join("replay.mema")).expect("replay map");
        let fw = std::fs::read(dir.join("fw.mema")).expect("firmware map");
        assert!(replay.len() > 52, "{cloud}: a map with entities");
        assert_eq!(
            fw, replay,
            "{cloud} {model:?}: firmware-sim and mema replay differ"
        );
        // Both report the points the pacing joined beyond the radius, and agree on them; car6
        // at the image's layout has some (its freezes come faster than the credit).
        let paced = |json: &[u8]| -> u64 {
            let v: serde_json::Value = serde_json::from_slice(json).expect("json");
            v["paced_joins"].as_u64().expect("paced_joins")
        };
        let (host, device) = (paced(&replayed.output.stdout), paced(&out.stdout));
        assert_eq!(host, device, "{cloud} {model:?}: paced joins");
        if (cloud, k, working) == ("car6.pcd", "400", "150") {
            assert!(host > 0, "{cloud} {model:?}: no paced join");
        }
        // Version 1 for the paper's fits, version 2 quantized (flags 1) for shells.
        let version_flags = &replay[4..8];
        let expected: &[u8] = if model == Some("paper") {
            &[1, 0, 0, 0]
        } else {
            &[2, 0, 1, 0]
        };
        assert_eq!(version_flags, expected, "{cloud} {model:?}");
    }
}

#[test]
fn the_board_refuses_statics_over_its_ram() {
    let dir = Dir::new("fw-board");
    let fw_bin =
        mema_bin().with_file_name(format!("mema-firmware-sim{}", std::env::consts::EXE_SUFFIX));
    std::fs::write(dir.join("c.bin"), capture_of("car6.pcd")).expect("write");
    let out = Command::new(&fw_bin)
        .args(["run", "c.bin", "--ram", "131072"])
        .current_dir(&dir.path)
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("board: static FIRMWARE") && err.contains("over the"),
        "{err}"
    );
}

/// Every accepted frame is a frame that was sent, and the map equals that of an uninterrupted
/// mapper fed exactly the frames the firmware holds at the end.
fn check_against_clean_frames(report: &RunReport, capture: &[u8], (working, frozen): Shape) {
    let params = stream_params(0, working, frozen);
    // Around the origin the firmware took: the first point of the first frame it accepted.
    let frames = frames_of(capture, report.origin);
    let rebuilt = map_of_frames::<K, G, F>(params, &report.accepted, &frames, report.origin)
        .unwrap_or_else(|seq| panic!("frame {seq} was never sent"));
    assert_eq!(
        report.map, rebuilt,
        "map differs from the map of its accepted frames"
    );
    let mut sorted = report.accepted.clone();
    sorted.dedup();
    assert_eq!(
        sorted.len(),
        report.accepted.len(),
        "a frame was used twice"
    );
}

#[test]
fn byte_faults_lose_only_corrupted_frames() {
    let capture = capture_of("car6.pcd");
    let frames = frames_of(&capture, None);
    for seed in 0..4 {
        let faults = FaultConfig {
            seed,
            noise_ppm: 100,
            overrun_ppm: 60,
            truncate_ppm: 60,
            reset_ppm: 0,
        };
        let r = play(
            &capture,
            150,
            &RunConfig {
                faults: Some(faults),
                ..RunConfig::default()
            },
        );
        let f = r.faults;
        assert!(
            f.noise_bytes > 0 && f.overruns > 0 && f.truncations > 0,
            "{f:?}"
        );
        assert!(
            r.decoder.rejected > 0 && r.accepted.len() < frames.len(),
            "seed {seed}: {:?}",
            r.decoder
        );
        // Each fault spoils at most the frame it hits and, by eating a delimiter, the next one.
        let faults_injected = (f.noise_bytes + f.overruns + f.truncations) as usize;
        assert!(
            frames.len() - r.accepted.len() <= 2 * faults_injected,
            "seed {seed}"
        );
        check_against_clean_frames(&r, &capture, (150, 0));
    }
}

#[test]
fn after_a_reset_the_restored_mapper_continues_to_the_uninterrupted_map() {
    let capture = capture_of("car6.pcd");
    // Both layouts: the frozen entities are part of what a snapshot must carry.
    for shape in [(150, 0), (150, 250)] {
        resets_restore(&capture, shape);
    }
}

fn resets_restore(capture: &[u8], shape: Shape) {
    let frames = frames_of(capture, None);
    let mut resets_seen = 0;
    let mut frozen_seen = 0;
    for seed in 0..6 {
        let faults = FaultConfig {
            seed,
            reset_ppm: 3_000,
            ..FaultConfig::default()
        };
        let r = play_shaped(
            capture,
            shape,
            &RunConfig {
                snapshot_every: 8,
                faults: Some(faults),
                ..RunConfig::default()
            },
        );
        resets_seen += r.faults.resets;
        frozen_seen += r.mapper.frozen;
        assert_eq!(r.firmware.restarts, r.faults.resets);
        if r.faults.resets > 0 {
            // Frames between the last snapshot and a reset are gone: the map holds fewer.
            assert!(r.accepted.len() < frames.len(), "seed {seed}");
            assert!(
                r.accepted.len() >= 8,
                "seed {seed}: the snapshot kept earlier frames"
            );
        }
        check_against_clean_frames(&r, capture, shape);
    }
    assert!(resets_seen >= 3, "only {resets_seen} resets over 6 seeds");
    assert_eq!(
        frozen_seen > 0,
        shape.1 > 0,
        "{shape:?}: {frozen_seen} frozen"
    );
}

#[test]
fn the_core_agrees_with_the_f64_reference_on_every_shared_cloud() {
    let clouds = shared_clouds().expect("../shared/data lists");
    let summary = compare_clouds(&clouds, &Setup::new(150, 0));
    eprintln!("{}", summary.text());
    assert!(
        summary.clouds.len() >= 9,
        "PLY and PCD clouds read: {}",
        summary.clouds.len()
    );
    for c in &summary.clouds {
        assert!(c.diff.is_none(), "{}: {:?}", c.cloud, c.diff);
        assert!(c.clusters >= 140, "{}: {} clusters", c.cloud, c.clusters);
    }
    assert!(summary.passed());
}

/// Readers fuzzed from a seed corpus of the real files: truncations and byte mutations give an
/// error or a cloud, never a panic.
#[test]
fn readers_never_panic_on_mutated_real_files() {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for name in ["car6.pcd", "milk.pcd", "bun_zipper.ply", "lamppost.pcd"] {
        let original = std::fs::read(shared(name)).expect("reads");
        for round in 0..150 {
            let mut bytes = original.clone();
            // Mutations concentrate on the first 2 KiB (headers), where the parsing decisions are.
            let span = bytes.len().min(2048);
            for _ in 0..1 + round % 8 {
                let at = (next() as usize) % span;
                bytes[at] = next() as u8;
            }
            if round % 3 == 0 {
                bytes.truncate((next() as usize) % bytes.len());
            }
            let result =
                std::panic::catch_unwind(|| mema::io::read::read_cloud_bytes(name, &bytes));
            assert!(result.is_ok(), "{name}, round {round}: the reader panicked");
        }
    }
}

/// Why a cluster keeps 62-bit sums (240 bytes, so K = 400 does not fit 64 KiB all working) and
/// not narrower floats: the same check with f64 sums rounded after every point to f32's 24
/// significant bits fails on 7 of the 16 clouds (9 before flat optima were judged on the
/// objective), and even 48 bits fails where 2-point clusters fit almost exactly (lamppost).
#[test]
fn narrower_moment_sums_lose_the_agreement_with_the_reference() {
    // The fewest clouds 24-bit sums must fail on, and the sums the lamppost needs more than.
    const LEAST_FAILING: usize = 7;
    const WIDE_BITS: u32 = 48;
    says(
        "docs/firmware.md",
        &format!(
            "24-bit sums fail on at least {LEAST_FAILING} clouds, {WIDE_BITS}-bit ones on lamppost."
        ),
    );
    let clouds = shared_clouds().expect("../shared/data lists");
    let f32_sums = compare_clouds(
        &clouds,
        &Setup {
            sum_bits: 24,
            ..Setup::new(150, 0)
        },
    );
    let failing: Vec<&str> = f32_sums
        .clouds
        .iter()
        .filter(|c| c.diff.is_some())
        .map(|c| c.cloud.as_str())
        .collect();
    assert!(
        failing.len() >= LEAST_FAILING,
        "24-bit sums failed only on {failing:?}\n{}",
        f32_sums.text()
    );
    let lamppost: Vec<_> = clouds
        .iter()
        .filter(|p| p.ends_with("lamppost.pcd"))
        .cloned()
        .collect();
    let wide = compare_clouds(
        &lamppost,
        &Setup {
            sum_bits: WIDE_BITS,
            ..Setup::new(150, 0)
        },
    );
    assert_eq!(wide.clouds.len(), 1);
    assert!(
        !wide.passed(),
        "48-bit sums held on lamppost\n{}",
        wide.text()
    );
    assert!(compare_clouds(&lamppost, &Setup::new(150, 0)).passed());
}
