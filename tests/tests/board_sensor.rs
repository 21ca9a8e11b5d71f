//! A sensor wired to the board (issue 30, item 2): the STM32F405 image under QEMU with USART1
//! and USART2 on ptys, `mema scanner-sim` playing car6 or the demo drive into USART1 as a
//! sensor sends (its own frames, no carry frames, nothing heard back), and `mema device
//! --listen` on USART2. The map the listener writes is `mema replay`'s of the bytes the board
//! received, byte for byte, in both entity models. Through relays that drop, flip and duplicate
//! bytes on both lines, the sensor's damaged frames are lost to the board's map, which is then
//! replay's of what arrived, and what the listener lost on its line it asks for again.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use mema::link::session::stream_counts;
use mema_firmware::{BOARD_FROZEN, BOARD_WORKING};

use crate::board_link::{BOARD_IDLE_TIMEOUT, Killed, board_image, open, relay, start_board};
use crate::board_sessions::finished;
use crate::device::{capture_and_replay, replay};
use crate::guides::{says, thousands};
use crate::stream::PtyPair;
use crate::util::{Dir, MemaCommand, mema_bin, shared};

/// The board's layout, K = 700: 150 working clusters and 550 frozen entities.
const LAYOUT: (usize, usize) = (BOARD_WORKING + BOARD_FROZEN, BOARD_WORKING);

/// `mema device --listen` on `listen` (asking `queries` of the map after it), while `mema
/// scanner-sim` plays `cloud` (`demo`: the demo drive) into `sensor`, the board reset through
/// QEMU's monitor after a while if `reset` says so: the listener's exit status, summary and
/// stderr.
fn listen_to(
    listen: &Path,
    sensor: &Path,
    cloud: &str,
    out: &Path,
    (queries, reset): (u32, Option<(&Path, Duration)>),
) -> (bool, serde_json::Value, String) {
    let listener = Command::new(mema_bin())
        .arg("device")
        .arg("--listen")
        .arg(listen)
        .arg("-o")
        .arg(out)
        .args(["--json", "--idle-timeout", BOARD_IDLE_TIMEOUT])
        .args(["--queries", &queries.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mema runs");
    let listener = Killed(listener);
    let mut sim = Command::new(mema_bin());
    sim.args(["scanner-sim", "--port"]).arg(sensor);
    if cloud != "demo" {
        sim.arg(shared(cloud));
    }
    let mut sim = Killed(sim.stderr(Stdio::null()).spawn().expect("scanner-sim runs"));
    let heard = finished(listener, reset);
    let sent = sim.0.wait().expect("scanner-sim's status");
    assert!(sent.success(), "{cloud}: scanner-sim failed");
    heard
}

/// What every listener's summary must say: the board's layout and model, its map as many
/// points and frames as `received` holds (as replay takes them), no byte lost in the board;
/// returns the board's instructions a point.
fn check_summary(name: &str, summary: &serde_json::Value, model: &str, received: &[u8]) -> f64 {
    let layout = &summary["layout"];
    assert_eq!(
        (
            layout["capacity"].as_u64(),
            layout["working"].as_u64(),
            layout["model"].as_str()
        ),
        (Some(LAYOUT.0 as u64), Some(LAYOUT.1 as u64), Some(model)),
        "{name}: {summary}"
    );
    let (points, frames) = stream_counts(received);
    assert_eq!(
        (
            summary["points"].as_u64(),
            summary["device_frames"].as_u64()
        ),
        (Some(u64::from(points)), Some(u64::from(frames))),
        "{name}: {summary}"
    );
    let cost = &summary["instructions"];
    assert_eq!(
        (
            cost["ring_overruns"].as_u64(),
            cost["line_overruns"].as_u64()
        ),
        (Some(0), Some(0)),
        "{name}: {summary}"
    );
    let per_point = cost["per_point"].as_f64().unwrap_or(f64::INFINITY);
    eprintln!("{name}: {per_point:.0} instructions a point: {summary}");
    per_point
}

#[test]
fn a_sensor_on_usart1_gives_the_listener_on_usart2_the_replay_map() {
    const PER_POINT: f64 = 10_000.0;
    says(
        "docs/board.md",
        &format!(
            "nothing refused or lost, no overrun, under {} instructions a point",
            thousands(PER_POINT as u64)
        ),
    );
    let dir = Dir::new("board-sensor");
    for model in ["shells", "paper"] {
        let image = board_image(model);
        for cloud in ["car6.pcd", "demo"] {
            let name = format!("{cloud}, {model}");
            let (_, capture, replayed) = capture_and_replay(&dir, cloud, LAYOUT, model);
            let (_qemu, ptys) = start_board(&dir, &image, None, 2);
            // Held open for the run: the sensor closing its end would hang up QEMU's side of
            // the line before the board had read all of it.
            let _held = open(&ptys[0]);
            let out = dir.join(&format!("listened-{cloud}-{model}.mema"));
            // Queries on one run: the board answers them on the listener's line too.
            let queries = if name == "car6.pcd, shells" { 8 } else { 0 };
            let (ok, summary, stderr) = listen_to(&ptys[1], &ptys[0], cloud, &out, (queries, None));
            assert!(ok, "{name}: {stderr}");
            let map = std::fs::read(&out).expect("the listener's map");
            assert!(map == replayed, "{name}: not replay's map: {summary}");
            let per_point = check_summary(&name, &summary, model, &capture);
            // The board's budget, on a clean line (a faulty one's damaged frames cost their
            // bytes' work and map no point): under QEMU's -icount the instructions do not
            // depend on the machine's load, and a sensor's line sends nothing twice.
            assert!(per_point < PER_POINT, "{name}: {per_point} a point");
            // A clean line: nothing damaged, nothing missing.
            assert_eq!(
                (summary["refused"].as_u64(), summary["lost"].as_u64()),
                (Some(0), Some(0)),
                "{name}: {summary}"
            );
            if queries > 0 {
                let q = &summary["queries"];
                assert_eq!(q["agreed"], q["asked"], "{name}: {summary}");
                assert_eq!(q["asked"].as_u64(), Some(u64::from(queries)));
            }
        }
    }
}

#[test]
fn faulty_lines_to_and_from_the_board_cost_frames_never_a_wrong_map() {
    // One byte in SENSOR faulty on the sensor's line, one in MAP each way on the map's.
    const SENSOR: u32 = 4_000;
    const MAP: u32 = 2_000;
    says(
        "docs/board.md",
        &format!(
            "or duplicate a byte in {} on the sensor's line and one in {} each way on the map's",
            thousands(SENSOR.into()),
            thousands(MAP.into())
        ),
    );
    let dir = Dir::new("board-sensor-faults");
    let mut asked_again = 0;
    for (seed, cloud, model) in [(3u64, "car6.pcd", "shells"), (11, "demo", "paper")] {
        let name = format!("{cloud}, {model}, seed {seed}");
        let (_, capture, _) = capture_and_replay(&dir, cloud, LAYOUT, model);
        let (qemu, ptys) = start_board(&dir, &board_image(model), None, 2);
        let (sensor, listener) = (
            PtyPair::named(&dir, "sensor"),
            PtyPair::named(&dir, "listener"),
        );
        // Held open for the run: scanner-sim's end closing would end socat's copy, and
        // with it what the relay had not read yet.
        let (_held_sensor, held_board) = (open(&sensor.b), open(&ptys[0]));
        let usart2 = open(&ptys[1]);
        let near = open(&listener.a);
        // The sensor's line one byte in 4,000 (tens of its frames), the map's one in 2,000
        // both ways.
        let sensor_line = relay(open(&sensor.a), held_board, seed, SENSOR);
        let down = relay(
            usart2.try_clone().expect("clone"),
            near.try_clone().expect("clone"),
            seed.wrapping_add(1),
            MAP,
        );
        let up = relay(near, usart2, seed.wrapping_add(2), MAP);
        let out = dir.join(&format!("listened-{seed}.mema"));
        let (ok, summary, stderr) = listen_to(&listener.b, &sensor.b, cloud, &out, (0, None));
        assert!(ok, "{name}: {stderr}");
        drop((sensor, listener, qemu));
        let (faults, received) = sensor_line.join().expect("the sensor's relay");
        let down = down.join().map_or(0, |r| r.0);
        let _ = up.join();
        // What the board received, mapped by replay: the board's map to the byte.
        let received_at = dir.write(&format!("received-{seed}.bin"), &received);
        let replayed = replay(&dir, &received_at, LAYOUT, model);
        let map = std::fs::read(&out).expect("the listener's map");
        assert!(
            map == replayed,
            "{name}: not replay's map of what arrived: {summary}"
        );
        check_summary(&name, &summary, model, &received);
        // The faults cost the board frames of the sensor's, and the listener frames of the
        // board's.
        let (_, sent_frames) = stream_counts(&capture);
        let mapped = summary["device_frames"].as_u64().unwrap_or(u64::MAX);
        assert!(
            faults > 0 && down > 0 && mapped < u64::from(sent_frames),
            "{name}: {faults} faults on the sensor's line, {down} down; {mapped} of {sent_frames} frames mapped"
        );
        let count = |key: &str| summary[key].as_u64().unwrap_or(0);
        assert!(count("refused") + count("lost") > 0, "{name}: {summary}");
        asked_again += count("asked_again") + count("ends_asked");
    }
    assert!(asked_again > 0, "nothing was asked again");
}

/// A board reset while the sensor streams loses what it had mapped: the listener says so and
/// writes no map, never one pieced together from two boots. And the map's line takes no host's
/// session: `mema device` there is told the board maps a sensor wired to it.
#[test]
fn a_listener_takes_no_map_across_a_reset_and_a_host_no_session_on_its_line() {
    let dir = Dir::new("board-sensor-reset");
    let (capture, _, _) = capture_and_replay(&dir, "car6.pcd", LAYOUT, "shells");
    let monitor = dir.join("monitor.sock");
    let (_qemu, ptys) = start_board(&dir, &board_image("shells"), Some(&monitor), 2);
    let _held = open(&ptys[0]);
    let out = dir.join("reset.mema");
    // A second into the stream (of about three): the board has mapped part of it.
    let reset = Some((monitor.as_path(), Duration::from_secs(1)));
    let (ok, summary, stderr) = listen_to(&ptys[1], &ptys[0], "car6.pcd", &out, (0, reset));
    assert!(!ok, "a map across a reset: {summary}");
    assert!(stderr.contains("restarted"), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "one line: {stderr}");
    assert!(!out.exists(), "a map was written");
    let host = dir.join("host.mema");
    MemaCommand::new(&dir)
        .args(["device", "--port"])
        .arg(&ptys[1])
        .arg(&capture)
        .arg("-o")
        .arg(&host)
        .args(["--idle-timeout", "10", "--json"])
        .run()
        .assert_error(1, "it maps a sensor wired to it");
    assert!(!host.exists(), "a map was written");
}
