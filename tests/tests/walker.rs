//! Forgetting what moved (issue 29): someone walks across the robot's line of sight in the
//! simulated room ([`mema::io::drive::walking`]), and the batch and streamed maps with
//! `--free-space` keep little of them, while the same drive with nobody walking maps no worse
//! with it than without.

use mema::io::drive::{DriveConfig, DriveScan, drive, room, walking};
use mema::link::scanner::{SensorScan, send_scans};

use crate::free_space::surface_distances;
use crate::guides::says;
use crate::util::{Dir, MemaCommand};

/// The demo's entities, which the drive is replayed at.
const ENTITIES: usize = 250;

/// How near map surface a walker's point counts as kept, in metres.
const NEAR: f64 = 0.25;

/// The share of the walker's points within [`NEAR`] of `map`'s surface where the map without
/// the walker (its distances `clean`) has none: the trail the walker left.
fn on_new_surface(
    dir: &Dir,
    map: &std::path::Path,
    name: &str,
    walker: &[[f64; 3]],
    clean: &[f64],
) -> f64 {
    surface_distances(dir, map, name, walker)
        .iter()
        .zip(clean)
        .filter(|(w, c)| w.abs() <= NEAR && c.abs() > NEAR)
        .count() as f64
        / walker.len() as f64
}

/// The drive's bytes as `scanner-sim` sends a drive (poses, then points), in `name`.
fn capture(dir: &Dir, name: &str, stops: &[DriveScan]) -> std::path::PathBuf {
    let scans: Vec<SensorScan> = stops.iter().map(SensorScan::of_drive).collect();
    dir.write(name, &send_scans(&scans).expect("sent").bytes)
}

/// The walking drive, its walker's points (the world frame), and the same drive with nobody
/// walking.
struct Drives {
    walked: Vec<DriveScan>,
    walker: Vec<[f64; 3]>,
    still: Vec<DriveScan>,
}

fn drives() -> Drives {
    let walked = drive(&room(), &walking());
    let walker: Vec<[f64; 3]> = walked
        .iter()
        .flat_map(|s| s.world.points.iter().zip(&s.on_walker))
        .filter(|(_, on)| **on)
        .map(|(p, _)| *p)
        .collect();
    assert!(walker.len() > 1_000, "{} walker points", walker.len());
    let still = drive(
        &room(),
        &DriveConfig {
            walker: None,
            ..walking()
        },
    );
    Drives {
        walked,
        walker,
        still,
    }
}

/// The drive as a registration file of its stops, each in its sensor's frame with its pose
/// (Stanford's convention, `x_world = R(q)^T x_scan + t`: the quaternion of the turn by -yaw).
fn conf(dir: &Dir, name: &str, stops: &[DriveScan]) -> std::path::PathBuf {
    let mut conf = String::new();
    for (i, stop) in stops.iter().enumerate() {
        let xyz: String = stop
            .points
            .iter()
            .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
            .collect();
        let file = dir.write(&format!("{name}-{i}.xyz"), xyz.as_bytes());
        let [x, y, z] = stop.translation;
        let half = 0.5 * stop.yaw;
        conf += &format!(
            "bmesh {} {x} {y} {z} 0 0 {} {}\n",
            file.display(),
            -half.sin(),
            half.cos()
        );
    }
    dir.write(&format!("{name}.conf"), conf.as_bytes())
}

/// `mema replay` of `capture` at the demo's 250 entities, with `--free-space` or without: the
/// map and its summary.
fn replay(
    dir: &Dir,
    capture: &std::path::Path,
    name: &str,
    free_space: bool,
) -> (std::path::PathBuf, serde_json::Value) {
    let map = dir.join(name);
    let ran = MemaCommand::new(dir)
        .arg("replay")
        .arg(capture)
        .args(["-k", &ENTITIES.to_string(), "--json", "-o"])
        .arg(&map)
        .args(free_space.then_some("--free-space"))
        .run()
        .assert_ok();
    (map, ran.json())
}

/// The walking drive mapped whole (`mema map` of its stops' .conf at 8,000 bytes) with
/// `--free-space`: the points two other stops saw through are left out before clustering, and
/// the rest of the walker next to them that one stop saw through (their feet above the floor).
/// Held to the 5 % within 25 cm of new surface (without `--free-space`, 95 %).
/// (With the scanner's 50-degree view in 512 columns of 0.1 degrees, most between its
/// 0.6-degree rays empty, nothing was carved: 95 %. Without the rest rule, the 17 points of the
/// walker's feet left raised the floor's shells beside their legs: 2.6-6.6 % over five seeds.)
#[test]
fn a_walker_leaves_no_trail_in_the_batch_map() {
    let dir = Dir::new("walker-batch");
    let Drives {
        walked,
        walker,
        still,
    } = drives();
    let map = |conf: &std::path::Path, name: &str, free_space: bool| {
        let out = dir.join(name);
        MemaCommand::new(&dir)
            .arg("map")
            .arg(conf)
            .args(["--bytes", "8000", "-o"])
            .arg(&out)
            .args(free_space.then_some("--free-space"))
            .run()
            .assert_ok();
        out
    };
    let (walked, still) = (conf(&dir, "walked", &walked), conf(&dir, "still", &still));
    let clean = surface_distances(&dir, &map(&still, "still.mema", true), "clean", &walker);
    let on_new_surface =
        |map: &std::path::Path, name: &str| on_new_surface(&dir, map, name, &walker, &clean);
    let carved = on_new_surface(&map(&walked, "carved.mema", true), "carved");
    let kept = on_new_surface(&map(&walked, "kept.mema", false), "kept");
    eprintln!(
        "batch: walker of {} points: {carved:.3} on new surface carved, {kept:.3} without free space",
        walker.len()
    );
    says(
        "docs/queries.md",
        &format!(
            "mapped whole (the drive's stops as a .conf, `mema map --bytes 8000 --free-space`) \
             {:.1} % ({:.1} % without)",
            carved * 100.0,
            kept * 100.0
        ),
    );
    assert!(carved <= 0.05, "{carved} of the walker on surface");
    assert!(
        kept > 0.9,
        "{kept}: the uncarved map should keep the walker"
    );
}

/// The walking drive replayed with `--free-space`: the fraction of the walker's points within
/// 25 cm of map surface where the map of the same drive with nobody walking has none, held to
/// the 5 %. Each scan is held until two more have judged its points
/// ([`mema::link::lag`]); with clusters carved alone, 7.1 % stayed: the clusters where the
/// walker's feet met the floor kept receiving floor points, so no scan saw through them.
/// Without `--free-space` more than 90 % stay. The same drive with nobody walking, carved, lies
/// no farther from its points (`mema eval`'s accuracy) than uncarved, within 2 %.
#[test]
fn a_walker_leaves_almost_no_trail_in_the_streamed_map() {
    let dir = Dir::new("walker");
    let Drives {
        walked,
        walker,
        still,
    } = drives();
    let walked_capture = capture(&dir, "walked.bin", &walked);
    let still_capture = capture(&dir, "still.bin", &still);

    let (clean, _) = replay(&dir, &still_capture, "still.mema", true);
    let (carved, summary) = replay(&dir, &walked_capture, "carved.mema", true);
    let (kept, _) = replay(&dir, &walked_capture, "kept.mema", false);
    let clean_distances = surface_distances(&dir, &clean, "clean", &walker);
    let on_new_surface = |map: &std::path::Path, name: &str| {
        on_new_surface(&dir, map, name, &walker, &clean_distances)
    };
    let (carved, kept) = (
        on_new_surface(&carved, "carved"),
        on_new_surface(&kept, "kept"),
    );
    eprintln!(
        "walker of {} points: {carved:.3} on new surface carved ({} clusters), {kept:.3} without free space",
        walker.len(),
        summary["carved"]
    );
    says(
        "docs/queries.md",
        &format!(
            "streamed at {ENTITIES} entities with `--free-space`, {:.1} % of the walker's points \
             stay within {:.0} cm of new surface ({:.1} % without)",
            carved * 100.0,
            NEAR * 100.0,
            kept * 100.0
        ),
    );
    assert!(carved <= 0.05, "{carved} of the walker on surface");
    assert!(
        kept > 0.9,
        "{kept}: the uncarved map should keep the walker"
    );
    // Nobody walking: carving costs the map nothing measurable.
    let world: String = still
        .iter()
        .flat_map(|s| s.world.points.iter())
        .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
        .collect();
    let points = dir.write("still.xyz", world.as_bytes());
    let (uncarved, _) = replay(&dir, &still_capture, "still-kept.mema", false);
    let accuracy = |map: &std::path::Path| {
        MemaCommand::new(&dir)
            .args(["eval", "--json"])
            .arg(&points)
            .arg(map)
            .run()
            .assert_ok()
            .json()["accuracy"]["mean"]
            .as_f64()
            .expect("accuracy")
    };
    let (with, without) = (accuracy(&clean), accuracy(&uncarved));
    eprintln!("nobody walking: accuracy {with:.5} m carved, {without:.5} m not");
    assert!(with <= without * 1.02, "{with} carved, {without} not");
}

/// The walking drive replayed as the STM32F405 board maps and carves it (`-k 700 --working 150
/// --carve 124x512 --carve-every 2`): at the board's layout most of the walker's clusters
/// freeze (150 working clusters) before two scans see through them, so the frozen entities
/// are carved too. Measured 4.7 % of the walker within 25 cm of new surface (95 % uncarved;
/// 10.5 % when a merge pass merged one pair for every 24 working clusters, 9.0 % when all
/// four axis ends of a frozen entity had to be seen through); held here to 10 %, as the
/// streamed map is.
#[test]
fn the_board_carves_the_walker_frozen_entities_too() {
    use mema_firmware::{BOARD_CARVE_EVERY, BOARD_CARVE_IMAGE, BOARD_FROZEN, BOARD_WORKING};
    let dir = Dir::new("walker-board");
    let Drives {
        walked,
        walker,
        still,
    } = drives();
    let walked_capture = capture(&dir, "walked.bin", &walked);
    let still_capture = capture(&dir, "still.bin", &still);
    let [rows, columns] = BOARD_CARVE_IMAGE;
    let (k, working) = (BOARD_WORKING + BOARD_FROZEN, BOARD_WORKING);
    let board = |capture: &std::path::Path, name: &str, carve: bool| {
        let map = dir.join(name);
        let carving = [
            "--carve".to_string(),
            format!("{rows}x{columns}"),
            "--carve-every".to_string(),
            BOARD_CARVE_EVERY.to_string(),
        ];
        MemaCommand::new(&dir)
            .arg("replay")
            .arg(capture)
            .args([
                "-k",
                &k.to_string(),
                "--working",
                &working.to_string(),
                "-o",
            ])
            .arg(&map)
            .args(carving.iter().filter(|_| carve))
            .run()
            .assert_ok();
        map
    };
    let clean = surface_distances(
        &dir,
        &board(&still_capture, "still.mema", true),
        "clean",
        &walker,
    );
    let on_new_surface =
        |map: &std::path::Path, name: &str| on_new_surface(&dir, map, name, &walker, &clean);
    let carved = on_new_surface(&board(&walked_capture, "carved.mema", true), "carved");
    let kept = on_new_surface(&board(&walked_capture, "kept.mema", false), "kept");
    eprintln!("board: {carved:.3} of the walker on new surface carved, {kept:.3} not");
    says(
        "docs/queries.md",
        &format!(
            "at the board's layout {:.1} % of the walker's points stay on new surface ({:.0} % \
             uncarved)",
            carved * 100.0,
            kept * 100.0
        ),
    );
    assert!(carved <= 0.10, "{carved} of the walker on surface");
    assert!(
        kept > 0.8,
        "{kept}: the uncarved map should keep the walker"
    );
}

/// `mema scanner-sim --walker` plays the walking drive (the bytes the library sends for it),
/// and its replay with `--free-space` carves what the walker left.
#[test]
fn scanner_sim_plays_the_walking_drive() {
    let dir = Dir::new("walker-cli");
    let played = dir.join("walking.bin");
    MemaCommand::new(&dir)
        .args(["scanner-sim", "--walker", "--port"])
        .arg(&played)
        .run()
        .assert_ok();
    let expected = capture(&dir, "expected.bin", &drive(&room(), &walking()));
    assert!(
        std::fs::read(&played).expect("played") == std::fs::read(&expected).expect("expected"),
        "scanner-sim --walker is not the walking drive"
    );
    let (_, summary) = replay(&dir, &played, "walking.mema", true);
    assert!(summary["carved"].as_u64().unwrap_or(0) > 0, "{summary}");
}
