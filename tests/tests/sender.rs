//! The independent sender (`tests/sender/mema_send.py`, written from PROTOCOL.md alone, sharing
//! no code with mema): its bytes are mema's own, byte for byte, for the same wire integers, and
//! the bunny scans it reads and sends itself map like `mema map --stream` of the .conf.

use crate::util::{Dir, MemaCommand, eval_chamfer, shared};
use mema::link::scanner::{WireScans, quantise_scans, scans_of, send_scans};
use serde_json::json;
use std::path::PathBuf;
use std::process::Command;

/// Runs the independent sender in `dir` with `args`; panics with its stderr if it fails.
pub fn python_sender(dir: &Dir, args: &[&str]) {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("sender/mema_send.py");
    let out = Command::new("python3")
        .arg(script)
        .args(args)
        .current_dir(dir.join(""))
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "mema_send.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `wire` as the sender's --ints JSON, written to `dir/name`.
pub fn write_ints(dir: &Dir, name: &str, wire: &WireScans) -> PathBuf {
    let scans: Vec<_> = wire
        .scans
        .iter()
        .map(|s| {
            json!({
                "pose_exponent": wire.pose_exponent,
                "translation": s.pose.translation,
                "rotation": s.pose.rotation,
                "points": s.points,
            })
        })
        .collect();
    let doc = json!({"unit_exponent": wire.unit_exponent, "scans": scans});
    dir.write(name, doc.to_string().as_bytes())
}

/// The same integers give the same bytes: the bunny's five posed scans and car6 as one scan.
#[test]
fn the_independent_sender_emits_mema_bytes() {
    let dir = Dir::new("sender-bytes");
    for (name, path) in [("bunny", shared("bun.conf")), ("car6", shared("car6.pcd"))] {
        let scans = scans_of(&path, None).expect("scans");
        let wire = quantise_scans(&scans).expect("wire");
        let ints = write_ints(&dir, &format!("{name}.json"), &wire);
        let out = format!("{name}.bin");
        python_sender(&dir, &["--ints", ints.to_str().expect("utf8"), &out]);
        let theirs = std::fs::read(dir.join(&out)).expect("capture");
        let ours = send_scans(&scans).expect("send").bytes;
        assert_eq!(theirs.len(), ours.len(), "{name}");
        assert!(theirs == ours, "{name}: the bytes differ");
    }
}

/// The sender reads the .conf and the ASCII scans itself, rounds to 0.1 mm and sends: every
/// frame is taken, and the map lies as close to the merged bunny as `mema map --stream`'s.
#[test]
fn the_bunny_scans_from_the_independent_sender_map_like_mema_own() {
    let dir = Dir::new("sender-bunny");
    let conf = shared("bun.conf");
    let conf = conf.to_str().expect("utf8");
    python_sender(&dir, &["--conf", conf, "--unit", "-4", "bunny.bin"]);
    let replay = MemaCommand::new(&dir)
        .args([
            "replay",
            "bunny.bin",
            "-k",
            "400",
            "-o",
            "theirs.mema",
            "--json",
        ])
        .run()
        .assert_ok()
        .json();
    assert_eq!(replay["poses"], 5, "{replay}");
    assert_eq!(replay["frames_rejected"], 0, "{replay}");
    assert_eq!(replay["frames_without_pose"], 0, "{replay}");
    assert_eq!(replay["frames_lost"], 0, "{replay}");
    MemaCommand::new(&dir)
        .args(["map", conf, "--stream", "-k", "400", "-o", "ours.mema"])
        .run()
        .assert_ok();
    let chamfer = |map: &str| eval_chamfer(&dir, &shared("bun_zipper.ply"), map);
    let (theirs, ours) = (chamfer("theirs.mema"), chamfer("ours.mema"));
    eprintln!("bunny views: independent sender Chamfer {theirs} m, mema's {ours} m");
    assert!(
        (theirs - ours).abs() < 0.05 * ours,
        "independent {theirs} m, mema {ours} m"
    );
}
