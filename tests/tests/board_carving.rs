//! The board carves (issue 29): someone walks across the robot's line of sight, each stop's
//! scan sent in pieces after the same pose, so the board's origin settles (16 poses) early and
//! it sends frozen entities as they freeze; later scans see through some of those, and the
//! board retracts them (PROTOCOL.md, "Retract") and sends what moved into their slots. Through a relay that drops, flips or duplicates
//! bytes both ways, the host's map is still `mema replay`'s at the board's layout, carving as
//! the board does, byte for byte.

use mema::io::drive::{drive, room, walking};
use mema::link::scanner::{SensorScan, send_scans};
use mema_firmware::{BOARD_FROZEN, BOARD_WORKING};

use crate::board_link::{board_image, relayed_session, start_board};
use crate::util::{Dir, MemaCommand};

/// Pieces each stop's scan is sent in, each after the stop's pose: one scan to the carver (one
/// sensor origin), four poses to the receiver, whose origin settles at the fourth stop.
const PIECES: usize = 4;

/// The walking drive (a coarser rangefinder, so runs stay short), each stop's scan sent in
/// [`PIECES`] pieces after its pose, as `scanner-sim` would send them: the stream's bytes.
pub(crate) fn walking_in_pieces() -> Vec<u8> {
    let mut config = walking();
    config.rangefinder.elevation_steps = 50;
    let scans: Vec<SensorScan> = drive(&room(), &config)
        .iter()
        .map(SensorScan::of_drive)
        .flat_map(|scan| {
            let piece = scan.points.len().div_ceil(PIECES).max(1);
            let pieces: Vec<SensorScan> = scan
                .points
                .chunks(piece)
                .map(|points| SensorScan {
                    points: points.to_vec(),
                    ..scan.clone()
                })
                .collect();
            pieces
        })
        .collect();
    send_scans(&scans).expect("sent").bytes
}

#[test]
fn the_boards_retractions_through_a_faulty_line_give_the_replay_map() {
    let dir = Dir::new("board-carving");
    let capture = dir.write("walking.bin", &walking_in_pieces());
    let layout = (BOARD_WORKING + BOARD_FROZEN, BOARD_WORKING);
    let replayed = crate::device::replay(&dir, &capture, layout, "shells");
    // What carving takes out: replay's own count, as the board carves.
    let carved = MemaCommand::new(&dir)
        .arg("replay")
        .arg(&capture)
        .args([
            "-k",
            &layout.0.to_string(),
            "--working",
            &layout.1.to_string(),
        ])
        .args(["--carve", "124x512", "--carve-every", "2", "--json", "-o"])
        .arg(dir.join("counted.mema"))
        .run()
        .assert_ok()
        .json()["carved"]
        .as_u64()
        .unwrap_or(0);
    assert!(carved > 0, "the walker was not carved");
    let image = board_image("shells");
    let mut retracted = 0;
    for (seed, faulty) in [(0u64, false), (5, true)] {
        let (board, ptys) = start_board(&dir, &image, None, 1);
        // One byte in 2,000 faulty on the way down, one in 4,000 up (as board_link's line);
        // none on the clean run.
        let (down_rate, up_rate) = if faulty {
            (2_000, 4_000)
        } else {
            (u32::MAX, u32::MAX)
        };
        let out = dir.join(&format!("board-{seed}.mema"));
        let ((ok, summary, stderr), _) = relayed_session(
            &dir,
            board,
            &ptys[0],
            &capture,
            &out,
            ((seed, down_rate), (seed.wrapping_add(1), up_rate)),
        );
        assert!(ok, "seed {seed}: {stderr}");
        eprintln!("seed {seed}: {summary}");
        let map = std::fs::read(&out).expect("the board's map");
        assert!(map == replayed, "seed {seed}: not replay's map: {summary}");
        let count = |key: &str| summary[key].as_u64().unwrap_or(0);
        retracted += count("retracted");
        if faulty {
            assert!(count("refused") + count("lost") > 0, "no fault: {summary}");
        }
    }
    assert!(retracted > 0, "the board retracted nothing");
}
