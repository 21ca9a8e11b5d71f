//! Real multi-view data (issue 12): the five bunny scans of Stanford's bun.conf, each in its own
//! scanner frame. Their registration is checked against the merged reconstruction with a
//! transform computed here (nalgebra, from the .conf's text); then they are streamed with their
//! poses over a real pty, replayed, and mapped by `mema map --stream`, and scored against the
//! reconstruction next to the batch map of the registered scans.

use crate::guides::says;
use crate::stream::{PtyPair, finish, spawn_mema};
use crate::util::{Dir, MemaCommand, eval_chamfer, shared};
use mema::io::load_cloud;
use mema::kdtree::KdTree;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use std::time::Duration;

/// The scans of bun.conf as the test reads them: file and `x_world = R(q)^T x + t`.
fn registration() -> Vec<(String, UnitQuaternion<f64>, Vector3<f64>)> {
    let text = std::fs::read_to_string(shared("bun.conf")).expect("bun.conf");
    text.lines()
        .filter(|l| l.starts_with("bmesh"))
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            let v: Vec<f64> = w[2..9].iter().map(|s| s.parse().expect("number")).collect();
            let q = UnitQuaternion::from_quaternion(Quaternion::new(v[6], v[3], v[4], v[5]));
            (w[1].to_string(), q, Vector3::new(v[0], v[1], v[2]))
        })
        .collect()
}

fn world_points(file: &str, q: &UnitQuaternion<f64>, t: &Vector3<f64>) -> Vec<[f64; 3]> {
    let cloud = load_cloud(&shared(file)).expect("scan");
    cloud
        .points
        .iter()
        .map(|p| {
            let s = Vector3::new(
                cloud.origin[0] + p.x as f64,
                cloud.origin[1] + p.y as f64,
                cloud.origin[2] + p.z as f64,
            );
            let w = q.inverse() * s + t;
            [w.x, w.y, w.z]
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Each scan, taken to the world as `R(q)^T x + t`, lies a median 0.52-0.57 mm from the
/// vertices of the merged reconstruction bun_zipper.ply (its point spacing); `R(q)` instead
/// leaves some scans millimetres off. `mema`'s reading of the .conf gives the same world points.
#[test]
fn the_registered_bunny_scans_lie_on_the_merged_bunny() {
    let zipper = load_cloud(&shared("bun_zipper.ply")).expect("bun_zipper");
    let reference: Vec<[f64; 3]> = zipper
        .points
        .iter()
        .map(|p| [0, 1, 2].map(|j| zipper.origin[j] + p.to_f64()[j]))
        .collect();
    let tree = KdTree::build(&reference);
    let mut all = Vec::new();
    let mut worst_wrong: f64 = 0.0;
    let mut medians = Vec::new();
    for (file, q, t) in registration() {
        let world = world_points(&file, &q, &t);
        let d: Vec<f64> = world
            .iter()
            .map(|p| tree.nearest(*p, None).expect("nearest").distance)
            .collect();
        let m = median(d);
        eprintln!(
            "{file}: median {:.4} mm from bun_zipper's vertices",
            m * 1e3
        );
        // Measured here 0.523-0.575 mm (to the nearest vertex, from mema's f32 reading).
        assert!((0.0005..=0.0006).contains(&m), "{file}: median {m} m");
        medians.push(m * 1e3);
        // R(q) instead of its transpose.
        let wrong = world_points(&file, &q.inverse(), &t);
        let d: Vec<f64> = wrong
            .iter()
            .step_by(10)
            .map(|p| tree.nearest(*p, None).expect("nearest").distance)
            .collect();
        worst_wrong = worst_wrong.max(median(d));
        all.extend(world);
    }
    assert!(
        worst_wrong > 0.004,
        "R(q) leaves a scan {worst_wrong} m off"
    );
    let (lo, hi) = (
        medians.iter().copied().fold(f64::INFINITY, f64::min),
        medians.iter().copied().fold(0.0, f64::max),
    );
    says(
        "docs/streaming.md",
        &format!(
            "five shared bunny scans then lies a median {lo:.2}-{hi:.2} mm from `bun_zipper.ply`"
        ),
    );
    let read = load_cloud(&shared("bun.conf")).expect("mema reads the .conf");
    assert_eq!(read.points.len(), all.len());
    let worst = read
        .points
        .iter()
        .zip(&all)
        .map(|(p, w)| {
            (0..3)
                .map(|j| (read.origin[j] + p.to_f64()[j] - w[j]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-7,
        "mema's world points {worst} m from the test's"
    );
}

/// eval's two-way score (Chamfer, metres) of `map` against bun_zipper.ply.
fn chamfer(dir: &Dir, map: &str) -> f64 {
    eval_chamfer(dir, &shared("bun_zipper.ply"), map)
}

/// Acceptance 1: the five scans with their poses, `scanner-sim --conf` into `stream` over a
/// pty and through `replay`, give the same map bytes as `mema map --stream` of the .conf; the
/// map scores within 1.2x of the batch map of the registered scans at the same size.
#[test]
fn the_bunny_scans_streamed_with_their_poses_map_like_the_batch() {
    let dir = Dir::new("bunny-views");
    let conf = shared("bun.conf");
    let conf = conf.to_str().expect("utf8");
    let mut pty = PtyPair::new(&dir);
    let stream = spawn_mema(
        &dir,
        &[
            "stream",
            "--port",
            pty.b.to_str().expect("utf8"),
            "-k",
            "400",
            "-o",
            "stream.mema",
            "--record",
            "views.bin",
            "--json",
        ],
    );
    stream.wait_until_listening();
    let sim = MemaCommand::new(&dir)
        .args([
            "scanner-sim",
            "--port",
            pty.a.to_str().expect("utf8"),
            "--conf",
            conf,
        ])
        .args(["--chunk-bytes", "4096"])
        .run()
        .assert_ok();
    assert!(sim.stderr().contains("unit 0.1 mm"), "{}", sim.stderr());
    let (code, stdout, stderr) = finish(stream, Duration::from_secs(120));
    assert_eq!(code, 0, "{stderr}");
    pty.unplug();
    let summary: serde_json::Value = serde_json::from_str(&stdout).expect("JSON");
    assert_eq!(summary["poses"], 5, "{summary}");
    assert_eq!(summary["frames_without_pose"], 0, "{summary}");
    let total: usize = registration()
        .iter()
        .map(|(f, _, _)| load_cloud(&shared(f)).expect("scan").points.len())
        .sum();
    assert_eq!(summary["points"], total, "{summary}");

    MemaCommand::new(&dir)
        .args(["replay", "views.bin", "-k", "400", "-o", "replay.mema"])
        .run()
        .assert_ok();
    MemaCommand::new(&dir)
        .args([
            "map",
            conf,
            "--stream",
            "-k",
            "400",
            "-o",
            "map-stream.mema",
        ])
        .run()
        .assert_ok();
    let streamed = std::fs::read(dir.join("stream.mema")).expect("stream map");
    assert_eq!(
        streamed,
        std::fs::read(dir.join("replay.mema")).expect("replay")
    );
    assert_eq!(
        streamed,
        std::fs::read(dir.join("map-stream.mema")).expect("map --stream")
    );

    let entities = summary["ellipsoids"]
        .as_u64()
        .expect("entities")
        .to_string();
    MemaCommand::new(&dir)
        .args(["map", conf, "-k", &entities, "-o", "batch.mema"])
        .run()
        .assert_ok();
    let (s, b) = (chamfer(&dir, "stream.mema"), chamfer(&dir, "batch.mema"));
    eprintln!(
        "bunny views against bun_zipper: streamed Chamfer {s} m, batch {b} m ({entities} entities)"
    );
    assert!(s <= 1.2 * b, "streamed {s} m, batch {b} m");
}

/// A streamed map lies in its file's frame: car6 sent by scanner-sim and replayed scores against
/// car6.pcd like the batch map at the same size (it once sat around the cloud's centre, one
/// non-empty cluster and error 71.7), and the README's query example finds a surface near.
#[test]
fn a_streamed_map_lines_up_with_its_file() {
    let dir = Dir::new("lines-up");
    let car = shared("car6.pcd");
    MemaCommand::new(&dir)
        .arg("scanner-sim")
        .args(["--port", "car.bin"])
        .arg(&car)
        .run()
        .assert_ok();
    let replayed = MemaCommand::new(&dir)
        .args(["replay", "car.bin", "-k", "150", "-o", "car.mema", "--json"])
        .run()
        .assert_ok()
        .json();
    let n = replayed["ellipsoids"].as_u64().expect("n").to_string();
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&car)
        .args(["-k", &n, "-o", "batch.mema"])
        .run()
        .assert_ok();
    let score = |map: &str| eval_chamfer(&dir, &car, map);
    let (s, b) = (score("car.mema"), score("batch.mema"));
    eprintln!("car6 streamed Chamfer {s} m, batch {b} m");
    assert!(s < 1.5 * b, "streamed {s} m, batch {b} m");
    let q = MemaCommand::new(&dir)
        .args([
            "query",
            "car.mema",
            "--point=-37,-65,-6.5",
            "--ray=-30,-65,-6,-1,0,0",
        ])
        .run()
        .assert_ok();
    assert!(q.stdout().contains("hits entity"), "{}", q.stdout());
}
