//! ROS 2 bags (issue 14): bags written by an independent writer, `rosbags` in Python
//! (`tests/bags/write_bag.py`), read by mema. The bunny scans of bun.conf as PointCloud2
//! messages with their poses on /tf and /tf_static map in frame `world` to the .conf's map bit
//! for bit, in batch and through the streaming mapper; a bag of awkward layouts decodes to
//! numpy's points; a missing topic or transform and a damaged bag are one-line errors.
//!
//! The writer runs in the virtual environment `scripts/test.sh` makes (`target/py-venv`, with
//! rosbags 0.11.9), or the Python `MEMA_PY` names. Without one the tests fail: they never skip.

use crate::guides::{says, thousands};
use crate::util::{Dir, MemaCommand, shared};
use mema::io::bag::{BagError, BagOptions, read_bag};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The Python with rosbags: `MEMA_PY`, else the workspace's `target/py-venv`.
fn python() -> PathBuf {
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/py-venv/bin/python");
    let python = std::env::var_os("MEMA_PY").map_or(venv, PathBuf::from);
    assert!(
        python.exists(),
        "{}: no Python for the bag writer; run scripts/test.sh (it makes target/py-venv with \
         rosbags==0.11.9 and numpy), or set MEMA_PY to a Python that has them",
        python.display()
    );
    python
}

/// The bags, written once per test run: `bunny/bunny.mcap`, `messy/messy.mcap` and
/// `messy/expected.txt`.
fn bags() -> &'static Path {
    static BAGS: OnceLock<PathBuf> = OnceLock::new();
    BAGS.get_or_init(|| {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mema-bags");
        let _ = std::fs::remove_dir_all(&out);
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("bags/write_bag.py");
        let ran = Command::new(python())
            .arg(&script)
            .arg("--data")
            .arg(crate::util::shared_data())
            .arg(&out)
            .output()
            .expect("the bag writer runs");
        assert!(
            ran.status.success(),
            "{} failed (is rosbags==0.11.9 installed in that Python? scripts/test.sh installs it):\n{}",
            script.display(),
            String::from_utf8_lossy(&ran.stderr)
        );
        out
    })
}

fn bunny() -> PathBuf {
    bags().join("bunny/bunny.mcap")
}

fn messy() -> PathBuf {
    bags().join("messy/messy.mcap")
}

/// The batch map's options for the bag against bun.conf.
const BATCH: [&str; 4] = ["-k", "120", "--seed", "3"];
/// Mutations of the two bags between them, and the most bits each flips.
const MUTATIONS: usize = 120;
const MOST_FLIPS: u64 = 4;

fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn bag_in_world_maps_as_the_conf_does_bit_for_bit() {
    let dir = Dir::new("bag-batch");
    let conf = shared("bun.conf");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&conf)
        .args(BATCH)
        .args(["-o", "conf.mema"])
        .run()
        .assert_ok();
    MemaCommand::new(&dir)
        .arg("map")
        .arg(bunny())
        .args(["--topic", "/points", "--frame", "world"])
        .args(BATCH)
        .args(["-o", "bag.mema"])
        .run()
        .assert_ok();
    assert!(
        bytes(&dir.join("bag.mema")) == bytes(&dir.join("conf.mema")),
        "the bag's map in frame world differs from bun.conf's"
    );
    // eval of the bag in frame world scores as eval of bun.conf.
    let eval = |input: &Path, frame: &[&str]| {
        MemaCommand::new(&dir)
            .arg("eval")
            .arg(input)
            .args(frame)
            .args(["conf.mema", "--samples", "20000", "--json"])
            .run()
            .assert_ok()
            .json()
    };
    let (mut by_bag, mut by_conf) = (eval(&bunny(), &["--frame", "world"]), eval(&conf, &[]));
    // Every figure but the unit's source (REP 103 for the bag, assumed for the PLY scans).
    assert_eq!(by_bag["unit"]["unit"], by_conf["unit"]["unit"]);
    for doc in [&mut by_bag, &mut by_conf] {
        doc.as_object_mut().expect("an object").remove("unit");
    }
    assert_eq!(by_bag, by_conf);
    // The library's cloud, too: the same origin and the same f32 points.
    let options = BagOptions {
        topic: None,
        frame: Some("world".into()),
    };
    let (from_bag, _) = mema::io::cloud::load_bag_in_metres(&bunny(), &options, None).unwrap();
    let (from_conf, _) = mema::io::cloud::load_registered_in_metres(&conf, None).unwrap();
    assert_eq!(from_bag, from_conf);
    // The rosbag2 directory rosbags wrote (metadata.yaml beside the .mcap) reads the same.
    let (from_dir, _) =
        mema::io::cloud::load_bag_in_metres(&bags().join("bunny"), &options, None).unwrap();
    assert_eq!(from_dir, from_conf);
    // Without a frame each scan stays in its own: a different cloud.
    let (raw, _) =
        mema::io::cloud::load_bag_in_metres(&bunny(), &BagOptions::default(), None).unwrap();
    assert_eq!(raw.points.len(), from_conf.points.len());
    assert_ne!(raw.origin, from_conf.origin);
}

#[test]
fn bag_replay_and_stream_map_as_the_conf_streams() {
    let dir = Dir::new("bag-stream");
    let conf = shared("bun.conf");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&conf)
        .args(["--stream", "-k", "200", "-o", "conf.mema"])
        .run()
        .assert_ok();
    MemaCommand::new(&dir)
        .arg("map")
        .arg(bunny())
        .args([
            "--frame", "world", "--stream", "-k", "200", "-o", "bag.mema",
        ])
        .run()
        .assert_ok();
    let replay = MemaCommand::new(&dir)
        .arg("replay")
        .arg(bunny())
        .args(["--frame", "world", "-k", "200", "--chunk-bytes", "1000"])
        .args(["-o", "replay.mema", "--json"])
        .run()
        .assert_ok();
    // scanner-sim sends the bag's scans as replay takes them: its capture replays to the same.
    MemaCommand::new(&dir)
        .arg("scanner-sim")
        .arg(bunny())
        .args(["--frame", "world", "--port", "bag.capture"])
        .run()
        .assert_ok();
    MemaCommand::new(&dir)
        .args(["replay", "bag.capture", "-k", "200", "-o", "capture.mema"])
        .run()
        .assert_ok();
    let conf_map = bytes(&dir.join("conf.mema"));
    assert!(
        bytes(&dir.join("capture.mema")) == conf_map,
        "scanner-sim BAG"
    );
    assert!(bytes(&dir.join("bag.mema")) == conf_map, "map --stream");
    assert!(bytes(&dir.join("replay.mema")) == conf_map, "replay");
    let summary = replay.json();
    assert_eq!(summary["poses"], 5, "{summary}");
    assert_eq!(summary["frames_rejected"], 0, "{summary}");
    says(
        "docs/ros2-bags.md",
        &format!(
            "through `replay` ({} poses, no frame refused)",
            summary["poses"]
        ),
    );
    assert_eq!(summary["frames_without_pose"], 0, "{summary}");
}

#[test]
fn stream_bench_takes_a_bag() {
    let dir = Dir::new("bag-bench");
    let ran = MemaCommand::new(&dir)
        .arg("stream-bench")
        .arg(messy())
        .args([
            "--topic",
            "/cloud",
            "-k",
            "8",
            "--repetitions",
            "1",
            "--json",
        ])
        .run()
        .assert_ok();
    let r = ran.json();
    // 150 + 100 slots in /cloud's first two messages, 22 of them NaN or infinite (and all 5
    // of the third's).
    assert_eq!(r["points"], 228, "{r}");
}

/// `messy/expected.txt`: numpy's points, per scan, and the counts.
fn expected() -> (Vec<Vec<[f64; 3]>>, u64, usize) {
    let text = std::fs::read_to_string(bags().join("messy/expected.txt")).unwrap();
    let (mut scans, mut dropped, mut empty) = (Vec::new(), 0, 0);
    for line in text.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["scan", _] => scans.push(Vec::new()),
            ["dropped", d, "empty", e] => {
                (dropped, empty) = (d.parse().unwrap(), e.parse().unwrap())
            }
            [x, y, z] => scans
                .last_mut()
                .expect("a scan line first")
                .push([x, y, z].map(|v| v.parse::<f64>().unwrap())),
            _ => panic!("expected.txt: {line}"),
        }
    }
    (scans, dropped, empty)
}

#[test]
fn awkward_layouts_decode_to_numpys_points() {
    let options = BagOptions {
        topic: Some("/cloud".into()),
        frame: None,
    };
    let bag = read_bag(&messy(), &options, None).unwrap();
    let (want, dropped, empty) = expected();
    assert_eq!(bag.messages, 3);
    assert_eq!(bag.slots, 150 + 100 + 5);
    assert_eq!(
        (bag.dropped_non_finite, bag.empty_messages),
        (dropped, empty)
    );
    assert_eq!(bag.scans.len(), want.len());
    says(
        "docs/ros2-bags.md",
        &format!("the {dropped} non-finite points and the empty message are counted"),
    );
    for (i, (scan, want)) in bag.scans.iter().zip(&want).enumerate() {
        assert_eq!(scan.frame_id, "lidar");
        assert_eq!(scan.points.len(), want.len(), "scan {i}");
        for (j, (got, want)) in scan.points.iter().zip(want).enumerate() {
            assert!(
                got.map(f64::to_bits) == want.map(f64::to_bits),
                "scan {i} point {j}: {got:?}, numpy {want:?}"
            );
        }
    }
}

/// Issue 33: a bag's counts add up. What `map` read and every point it left out make numpy's
/// slots of the topic's messages, on the `points:` line and in `--json`.
#[test]
fn a_bags_read_and_drops_add_up_to_numpys_slots() {
    let (want, dropped, _) = expected();
    let slots = want.iter().map(Vec::len).sum::<usize>() as u64 + dropped;
    let dir = Dir::new("bag-counts");
    let map = |json: bool| {
        MemaCommand::new(&dir)
            .arg("map")
            .arg(messy())
            .args(["--topic", "/cloud", "-k", "5", "-o", "messy.mema"])
            .args(if json { &["--json"][..] } else { &[][..] })
            .run()
            .assert_ok()
    };
    let json = map(true).json();
    let count = |v: &serde_json::Value| v.as_u64().expect("a count");
    let sum = count(&json["filter"]["read"])
        + count(&json["dropped_non_finite"])
        + count(&json["outliers"]["dropped"]);
    assert_eq!((sum, count(&json["slots"])), (slots, slots), "{json}");
    assert_eq!(count(&json["dropped_non_finite"]), dropped, "{json}");
    let text = map(false).stdout();
    assert!(text.contains(&format!(": {slots} in the input")), "{text}");
}

#[test]
fn a_missing_topic_or_transform_is_a_usage_error() {
    let dir = Dir::new("bag-usage");
    let map = |args: &[&str], input: &Path| {
        MemaCommand::new(&dir)
            .arg("map")
            .arg(input)
            .args(args)
            .args(["-k", "5", "-o", "x.mema"])
            .run()
    };
    map(&["--topic", "/nope"], &bunny())
        .assert_error(2, "no PointCloud2 topic /nope; consider --topic /points");
    map(&[], &messy()).assert_error(
        2,
        "2 PointCloud2 topics; choose one with --topic (/cloud, /other)",
    );
    map(&["--frame", "map"], &bunny()).assert_error(
        2,
        "no transform from `scanner_0` to `map` at 100.000000000 s",
    );
    map(&["--topic", "/cloud", "--frame", "world"], &messy())
        .assert_error(2, "no transform from `lidar` to `world`");
    map(&["--topic", "/points"], &shared("car6.pcd")).assert_error(2, "is not a bag");
    MemaCommand::new(&dir)
        .arg("replay")
        .arg(bunny())
        .args(["--frame", "base_link", "-o", "x.mema"])
        .run()
        .assert_error(2, "no transform from `scanner_0` to `base_link`");
}

#[test]
fn a_cut_or_damaged_bag_is_an_error_never_a_panic() {
    let dir = Dir::new("bag-damage");
    let whole = bytes(&bunny());
    for cut in [9, 100, whole.len() / 2, whole.len() - 30] {
        let path = dir.write("cut.mcap", &whole[..cut]);
        MemaCommand::new(&dir)
            .arg("map")
            .arg(&path)
            .args(["--frame", "world", "-k", "5", "-o", "x.mema"])
            .run()
            .assert_error(1, "cut.mcap: ");
    }
    // Mutations of both bags (the messy one's chunks are zstd), read in process: whatever the
    // bytes, a result or a typed error.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let sources = [(bytes(&messy()), "/cloud"), (whole, "/points")];
    let mut errors = 0;
    for round in 0..MUTATIONS {
        let (source, topic) = &sources[round % 2];
        let mut m = source.clone();
        for _ in 0..1 + next() % MOST_FLIPS {
            let at = (next() % m.len() as u64) as usize;
            m[at] ^= 1 << (next() % 8);
        }
        let path = dir.write("mutant.mcap", &m);
        let options = BagOptions {
            topic: Some((*topic).into()),
            frame: Some("world".into()).filter(|_| *topic == "/points"),
        };
        match read_bag(&path, &options, None) {
            Ok(bag) => assert!(!bag.scans.is_empty()),
            Err(e) => {
                let text = e.to_string();
                assert!(!text.contains('\n'), "{text}");
                assert!(!matches!(e, BagError::Io { .. }), "{text}");
                errors += 1;
            }
        }
    }
    assert!(errors > 0, "no mutation was noticed");
}

/// docs/ros2-bags.md's account of these tests, from the bag and the tests' own parameters.
#[test]
fn the_guide_describes_the_bag_these_tests_use() {
    let options = BagOptions {
        topic: Some("/points".into()),
        frame: Some("world".into()),
    };
    let bag = read_bag(&bunny(), &options, None).unwrap();
    let points: usize = bag.scans.iter().map(|s| s.points.len()).sum();
    let megabytes = std::fs::metadata(bunny()).expect("the bag").len() as f64 / 1e6;
    says(
        "docs/ros2-bags.md",
        &format!(
            "bun.conf ({} scans, {} points as FLOAT64, {megabytes:.1} MB;",
            bag.scans.len(),
            thousands(points as u64)
        ),
    );
    says(
        "docs/ros2-bags.md",
        &format!("in batch (`{}`)", BATCH.join(" ")),
    );
    says(
        "docs/ros2-bags.md",
        &format!("mutated {MUTATIONS} times between them (1-{MOST_FLIPS} bit flips)"),
    );
}
