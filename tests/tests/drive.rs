//! The moving robot (issue 12): `mema demo --moving` and `mema scanner-sim` without a cloud drive
//! a rangefinder through the built-in scene and stream its scans with their poses. The streamed
//! map must be the replayed capture's, byte for byte, and line up with the scene: checked here
//! by brute force over the map's entities (no index), against the scene's exact ray casts and
//! the world-frame points, and against the same drive sent with its turns left out.

use crate::sender::{python_sender, write_ints};
use crate::util::{Dir, MemaCommand};
use mema::io::drive::{DriveConfig, drive};
use mema::io::mapfile::HostMap;
use mema::io::scene::Scene;
use mema::link::scanner::{SensorScan, quantise_scans};
use mema_core::Entity;
use mema_core::closest_point::surface_distance;
use mema_core::query::brute_force;

fn entities(map: &HostMap) -> Vec<Entity> {
    map.entities.iter().map(|e| e.entity).collect()
}

/// Mean distance from every `step`-th world point to the nearest entity surface, over all
/// entities.
fn brute_accuracy(map: &HostMap, world: &[[f64; 3]], step: usize) -> f64 {
    let es = entities(map);
    let d: Vec<f64> = world
        .iter()
        .step_by(step)
        .map(|p| {
            let q = [0, 1, 2].map(|j| p[j] - map.origin[j]);
            es.iter()
                .map(|e| surface_distance(e, q))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    d.iter().sum::<f64>() / d.len() as f64
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn the_moving_demo_maps_the_drive_in_the_world_frame() {
    let dir = Dir::new("drive");
    let demo = MemaCommand::new(&dir)
        .args(["demo", "--moving", "--out-dir", "demo", "--json"])
        .run()
        .assert_ok()
        .json();
    assert_eq!(demo["stops"], 8, "{demo}");
    assert_eq!(demo["poses_received"], 8, "{demo}");
    assert_eq!(demo["frames_without_pose"], 0, "{demo}");
    // The rangefinder's 5 mm noise on 0.6 degree steps: 1 mm units.
    assert_eq!(demo["unit_exponent"], -3, "{demo}");

    // scanner-sim's default is the same drive; its capture replays to the demo's map.
    let sim = MemaCommand::new(&dir)
        .args(["scanner-sim", "--port", "drive.bin"])
        .run()
        .assert_ok();
    assert!(sim.stderr().contains("8 scans"), "{}", sim.stderr());
    let replay = MemaCommand::new(&dir)
        .args([
            "replay",
            "drive.bin",
            "-k",
            "250",
            "-o",
            "replay.mema",
            "--json",
        ])
        .run()
        .assert_ok()
        .json();
    assert_eq!(replay["poses"], 8, "{replay}");
    assert_eq!(replay["frames_rejected"], 0, "{replay}");
    assert_eq!(replay["points"], demo["points"], "{replay}");
    let demo_map = std::fs::read(dir.join("demo/map.mema")).expect("demo map");
    assert_eq!(
        demo_map,
        std::fs::read(dir.join("replay.mema")).expect("replayed map")
    );

    // Re-cast by brute force over the entities on every 25th ray of every stop: the map's range
    // agrees with the scene's exact one.
    let map = HostMap::read(&dir.join("demo/map.mema")).expect("map");
    let es = entities(&map);
    let stops = drive(&Scene::demo(), &DriveConfig::default());
    let scene = Scene::demo();
    let (mut errors, mut scene_hits, mut both) = (Vec::new(), 0usize, 0usize);
    for stop in &stops {
        let c = &stop.config;
        let o = [0, 1, 2].map(|j| c.sensor[j] - map.origin[j]);
        for d in c.ray_directions().step_by(25) {
            let truth = scene.ray_cast(c.sensor, d, c.max_range);
            let hit = brute_force::ray_cast(&es, o, d, c.max_range);
            if let Some(t) = truth {
                scene_hits += 1;
                if let Some(h) = hit {
                    both += 1;
                    errors.push((h.t - t.range).abs());
                }
            }
        }
    }
    let median_error = median(errors);
    eprintln!(
        "drive re-cast by brute force: {both} of {scene_hits} scene hits hit the map, median range error {median_error} m (demo: {})",
        demo["recast"]["range_median_abs"]
    );
    assert!(
        both as f64 > 0.9 * scene_hits as f64,
        "{both} of {scene_hits}"
    );
    assert!(median_error < 0.01, "median range error {median_error} m");
    let reported = demo["recast"]["range_median_abs"].as_f64().expect("median");
    assert!(
        (reported - median_error).abs() < 0.3 * median_error + 1e-3,
        "demo says {reported} m, brute force {median_error} m"
    );

    // The world points lie on the map: brute-force accuracy agrees with the demo's score.
    let world: Vec<[f64; 3]> = stops
        .iter()
        .flat_map(|s| s.world.points.iter().copied())
        .collect();
    let accuracy = brute_accuracy(&map, &world, 7);
    let reported = demo["score"]["accuracy"]["mean"]
        .as_f64()
        .expect("accuracy");
    eprintln!("drive accuracy by brute force {accuracy} m, demo {reported} m");
    assert!(accuracy < 0.01, "{accuracy} m");
    assert!(
        (accuracy - reported).abs() < 0.1 * reported,
        "{accuracy} vs {reported}"
    );

    // The control: the same integers sent by the independent sender with every turn left out
    // (the robot's heading ignored) put the views in the wrong place.
    let sensor: Vec<SensorScan> = stops.iter().map(SensorScan::of_drive).collect();
    let mut wire = quantise_scans(&sensor).expect("wire");
    for scan in &mut wire.scans {
        scan.pose.rotation = [0, 0, 0, 1 << 30];
    }
    let ints = write_ints(&dir, "unturned.json", &wire);
    python_sender(
        &dir,
        &["--ints", ints.to_str().expect("utf8"), "unturned.bin"],
    );
    MemaCommand::new(&dir)
        .args(["replay", "unturned.bin", "-k", "250", "-o", "unturned.mema"])
        .run()
        .assert_ok();
    let unturned = HostMap::read(&dir.join("unturned.mema")).expect("map");
    let wrong = brute_accuracy(&unturned, &world, 7);
    eprintln!("drive without its turns: accuracy {wrong} m");
    assert!(wrong > 5.0 * accuracy, "{wrong} vs {accuracy}");
}
