//! Sessions against one running board (issue 30): the STM32F405 image under QEMU, never reset
//! between `mema device` runs. Each run starts a session of its own, which the board begins
//! with a fresh map, and writes its own capture's map, `mema replay`'s bytes; a board reset
//! mid-session (QEMU's `system_reset`) is noticed and the session starts again, and the map
//! written is still the whole capture's. Never a previous session's map, never part of one.

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mema_firmware::{BOARD_FROZEN, BOARD_WORKING};

use crate::board_link::{BOARD_IDLE_TIMEOUT, Killed, board_image, start_board};
use crate::device::capture_and_replay;
use crate::util::{Dir, mema_bin};

/// Runs `mema device --json` for `capture` against `port`, asking QEMU's monitor for a
/// `system_reset` after `reset_after` if given; its exit status, summary and stderr.
pub(crate) fn session(
    port: &Path,
    capture: &Path,
    out: &Path,
    reset: Option<(&Path, Duration)>,
) -> (bool, serde_json::Value, String) {
    let child = Command::new(mema_bin())
        .arg("device")
        .arg("--port")
        .arg(port)
        .arg(capture)
        .arg("-o")
        .arg(out)
        .args(["--json", "--idle-timeout", BOARD_IDLE_TIMEOUT])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mema runs");
    finished(Killed(child), reset)
}

/// Waits for a `mema device --json` run (at most 300 s), asking QEMU's monitor for a
/// `system_reset` after `reset_after` if given; its exit status, summary and stderr.
pub(crate) fn finished(
    mut device: Killed,
    reset: Option<(&Path, Duration)>,
) -> (bool, serde_json::Value, String) {
    let started = Instant::now();
    let mut reset = reset;
    let deadline = started + Duration::from_secs(300);
    while device.0.try_wait().expect("wait").is_none() {
        assert!(Instant::now() < deadline, "mema device hung");
        if let Some((monitor, after)) = reset
            && started.elapsed() >= after
        {
            system_reset(monitor);
            reset = None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let (mut stdout, mut stderr) = (String::new(), String::new());
    if let Some(mut s) = device.0.stdout.take() {
        let _ = s.read_to_string(&mut stdout);
    }
    if let Some(mut s) = device.0.stderr.take() {
        let _ = s.read_to_string(&mut stderr);
    }
    let ok = device.0.wait().expect("status").success();
    assert!(
        reset.is_none(),
        "the session ended before the reset, after {:?}",
        started.elapsed()
    );
    eprintln!("session took {:?}", started.elapsed());
    let summary = serde_json::from_str(stdout.trim()).unwrap_or(serde_json::Value::Null);
    (ok, summary, stderr)
}

/// QEMU's monitor resets the machine: its prompt first (a command sent before it is lost),
/// then the command, then the prompt again once it has been carried out.
fn system_reset(monitor: &Path) {
    let mut m = UnixStream::connect(monitor).expect("QEMU's monitor");
    m.set_read_timeout(Some(Duration::from_secs(10)))
        .expect("a timeout");
    let mut said = Vec::new();
    let mut prompts = |m: &mut UnixStream, n: usize| {
        let mut buf = [0u8; 512];
        while said.windows(7).filter(|w| w == b"(qemu) ").count() < n {
            let got = m.read(&mut buf).expect("the monitor answers");
            assert!(got > 0, "the monitor closed");
            said.extend_from_slice(&buf[..got]);
        }
    };
    prompts(&mut m, 1);
    m.write_all(b"system_reset\n")
        .expect("the monitor takes it");
    prompts(&mut m, 2);
}

#[test]
fn sessions_in_a_row_and_a_reset_each_give_their_own_captures_map() {
    let dir = Dir::new("board-sessions");
    let layout = (BOARD_WORKING + BOARD_FROZEN, BOARD_WORKING);
    let (car6, _, car6_map) = capture_and_replay(&dir, "car6.pcd", layout, "shells");
    let (lamppost, _, lamppost_map) = capture_and_replay(&dir, "lamppost.pcd", layout, "shells");
    assert_ne!(car6_map, lamppost_map);
    let image = board_image("shells");
    let monitor = dir.join("monitor.sock");
    let (_qemu, ptys) = start_board(&dir, &image, Some(&monitor), 1);
    let port = &ptys[0];
    let runs = [
        ("car6", &car6, &car6_map, None),
        ("lamppost", &lamppost, &lamppost_map, None),
        // Reset 1.5 s into the session (of about 6): the board has taken part of the stream.
        (
            "car6 reset",
            &car6,
            &car6_map,
            Some(Duration::from_millis(1500)),
        ),
        ("lamppost after", &lamppost, &lamppost_map, None),
    ];
    let mut boots = Vec::new();
    for (i, (name, capture, replayed, reset_after)) in runs.into_iter().enumerate() {
        let out = dir.join(&format!("session-{i}.mema"));
        let reset = reset_after.map(|after| (monitor.as_path(), after));
        let (ok, summary, stderr) = session(port, capture, &out, reset);
        eprintln!("{name}: {summary}\n{stderr}");
        assert!(ok, "{name}: {stderr}");
        let map = std::fs::read(&out).expect("a map");
        assert!(map == *replayed, "{name}: not its capture's map: {summary}");
        assert_eq!(
            (
                summary["layout"]["capacity"].as_u64(),
                summary["layout"]["working"].as_u64()
            ),
            (Some(layout.0 as u64), Some(layout.1 as u64)),
            "{name}"
        );
        let restarts = summary["restarts"].as_u64().unwrap_or(u64::MAX);
        if reset_after.is_some() {
            assert_eq!(restarts, 1, "{name}: the reset went unnoticed: {summary}");
            assert!(stderr.contains("restarted mid-session"), "{name}: {stderr}");
        } else {
            assert_eq!(restarts, 0, "{name}: {summary}");
        }
        boots.push(summary["layout"]["boot"].as_u64().unwrap_or(0));
    }
    // Every session began in a boot of its own (a start resets the board into it).
    let mut distinct = boots.clone();
    distinct.dedup();
    assert_eq!(distinct.len(), boots.len(), "boots {boots:?}");
}
