//! A robot's real world (issue 23): the map does not depend on where the world frame's origin
//! is, and one corrupt-but-CRC-valid frame or pose far away costs nothing of it.

use mema::link::frames::push_frame_v2;
use mema_core::stream::StreamModel;
use mema_core::wire::{Content, FrameReprV2, QUATERNION_ONE, WirePose};
use mema_firmware_sim::firmware::SHELLS;
use mema_firmware_sim::harness::RunConfig;

use crate::firmware::play_model;
use crate::link_faults::{frame, replay};
use crate::util::{Dir, MemaCommand, eval_chamfer, shared, shared_data};

/// A 1 m plane of 128 points in millimetres, with a small wave so its fits have a shape.
fn plane() -> Vec<[i32; 3]> {
    (0..128)
        .map(|i| {
            let (x, y) = (i % 16, i / 16);
            [x * 66, y * 140, ((x * 7 + y * 13) % 5) - 2]
        })
        .collect()
}

/// The plane's points at i32's extremes in kilometres: 2.1 x 10^12 m out, as a wrong unit or
/// a corrupt frame that passed its CRC gives them.
fn far_points() -> Vec<[i32; 3]> {
    vec![
        [i32::MAX, i32::MIN, i32::MAX],
        [i32::MIN, i32::MAX, 0],
        [i32::MAX; 3],
    ]
}

/// One frame of far points amid the plane's: the map is, byte for byte, the map of the plane
/// alone (it was every entity a 3,712 km ellipsoid at 0), the firmware's too, and the summary
/// counts the points it refused.
#[test]
fn a_frame_of_far_points_costs_nothing_of_the_map() {
    let dir = Dir::new("far-frame");
    let plane = plane();
    let mut with_far = vec![0u8];
    with_far.extend(frame(0, false, -3, &plane[..64]));
    with_far.extend(frame(1, false, 3, &far_points()));
    with_far.extend(frame(2, true, -3, &plane[64..]));
    let mut clean = vec![0u8];
    clean.extend(frame(0, false, -3, &plane[..64]));
    clean.extend(frame(2, true, -3, &plane[64..]));
    for model in ["shells", "paper"] {
        let (code, json, far_map) = replay(
            &dir,
            &format!("far-{model}"),
            &with_far,
            "8",
            &["--model", model],
        );
        assert_eq!(code, 0, "{json}");
        assert_eq!(json["points_out_of_reach"], 3, "{json}");
        assert_eq!(json["points"], 128, "{json}");
        let (_, _, clean_map) = replay(
            &dir,
            &format!("clean-{model}"),
            &clean,
            "8",
            &["--model", model],
        );
        assert_eq!(far_map, clean_map, "{model}: the far frame changed the map");
        // The firmware's path: the same bytes.
        let stream_model = if model == "paper" {
            StreamModel::Paper
        } else {
            SHELLS
        };
        let firmware = play_model(&with_far, (8, 0), stream_model, &RunConfig::default());
        assert_eq!(firmware.map, far_map, "{model}: firmware vs replay");
    }
    let ran = MemaCommand::new(&dir)
        .args(["replay", "far-shells.bin", "-k", "8", "-o", "again.mema"])
        .run()
        .assert_ok();
    assert!(
        ran.stderr().contains("3 points out of reach (not mapped)"),
        "{}",
        ran.stderr()
    );
}

/// A version 2 frame, framed.
fn v2(sequence: u32, end: bool, exponent: i8, content: Content) -> Vec<u8> {
    let mut out = Vec::new();
    let repr = FrameReprV2 {
        sequence,
        end_of_stream: end,
        session_start: sequence == 0,
        unit_exponent: exponent,
        content,
    };
    push_frame_v2(&mut out, &repr).expect("frame");
    out
}

fn pose(number: u32, translation: [i32; 3]) -> Content<'static> {
    Content::Pose {
        number,
        pose: WirePose {
            translation,
            rotation: [0, 0, 0, QUATERNION_ONE],
        },
    }
}

/// A pose frame 10^12 m away (kilometre units at i32's reach) amid a moving sensor's: refused
/// and counted, and the map is, byte for byte, the map of the stream without it (the points
/// that name it are not mapped either way).
#[test]
fn a_far_pose_costs_nothing_of_the_map() {
    let dir = Dir::new("far-pose");
    let plane = plane();
    let stream = |far: bool| {
        let mut out = vec![0u8];
        out.extend(v2(0, false, -3, pose(1, [1_000, -2_000, 500])));
        out.extend(v2(
            1,
            false,
            -3,
            Content::Points {
                pose: 1,
                points: &plane[..64],
            },
        ));
        if far {
            out.extend(v2(2, false, 3, pose(2, [1_000_000_000, -1_000_000_000, 7])));
        }
        out.extend(v2(
            3,
            false,
            -3,
            Content::Points {
                pose: 2,
                points: &plane[64..],
            },
        ));
        out.extend(v2(4, false, -3, pose(3, [1_500, -2_000, 500])));
        out.extend(v2(
            5,
            true,
            -3,
            Content::Points {
                pose: 3,
                points: &plane[64..],
            },
        ));
        out
    };
    for model in ["shells", "paper"] {
        let (code, json, far_map) = replay(
            &dir,
            &format!("pose-{model}"),
            &stream(true),
            "8",
            &["--model", model],
        );
        assert_eq!(code, 0, "{json}");
        assert_eq!(json["poses_out_of_reach"], 1, "{json}");
        assert_eq!(json["poses"], 2, "{json}");
        assert_eq!(json["points"], 128, "{json}");
        let (_, _, clean_map) = replay(
            &dir,
            &format!("clean-{model}"),
            &stream(false),
            "8",
            &["--model", model],
        );
        assert_eq!(far_map, clean_map, "{model}: the far pose changed the map");
    }
}

/// `bun.conf` with every scan's translation moved by `shift` metres, scans named by their
/// absolute paths.
fn moved_conf(dir: &Dir, shift: [f64; 3]) -> std::path::PathBuf {
    let text = std::fs::read_to_string(shared("bun.conf")).expect("bun.conf");
    let data = shared_data();
    let mut out = String::new();
    for line in text.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["bmesh", file, t @ .., qx, qy, qz, qw] if t.len() == 3 => {
                let t: Vec<f64> = t.iter().map(|v| v.parse().expect("translation")).collect();
                out.push_str(&format!(
                    "bmesh {} {:.10} {:.10} {:.10} {qx} {qy} {qz} {qw}\n",
                    data.join(file).display(),
                    t[0] + shift[0],
                    t[1] + shift[1],
                    t[2] + shift[2]
                ));
            }
            _ => out.push_str(&format!("{line}\n")),
        }
    }
    dir.write("moved.conf", out.as_bytes())
}

/// The five bunny scans with their poses, streamed as `scanner-sim --conf` sends them, with the
/// world frame moved up to 2,000 km (in the middle of the old 1,024 m cell too): replayed and
/// through the firmware's path, the map moved back scores within 1.02x the two-way Chamfer
/// against `bun_zipper.ply` of the same scans at the origin (3.6x worse before).
#[test]
fn the_bunny_maps_alike_anywhere_in_the_world() {
    let dir = Dir::new("world-bunny");
    let zipper = shared("bun_zipper.ply");
    let chamfer_at = |shift: [f64; 3]| {
        let conf = moved_conf(&dir, shift);
        MemaCommand::new(&dir)
            .arg("scanner-sim")
            .arg("--conf")
            .arg(&conf)
            .args(["--port", "moved.bin"])
            .run()
            .assert_ok();
        let (code, json, map) = replay(
            &dir,
            "moved",
            &std::fs::read(dir.join("moved.bin")).expect("capture"),
            "150",
            &[],
        );
        assert_eq!(code, 0, "{json}");
        let capture = std::fs::read(dir.join("moved.bin")).expect("capture");
        let firmware = play_model(&capture, (150, 0), SHELLS, &RunConfig::default());
        assert_eq!(firmware.map, map, "{shift:?}: firmware vs replay");
        let back = shift.map(|v| format!("{}", -v)).join(",");
        MemaCommand::new(&dir)
            .args(["transform", "moved.mema", "-o", "back.mema"])
            .arg(format!("--translate={back}"))
            .run()
            .assert_ok();
        eval_chamfer(&dir, &zipper, "back.mema")
    };
    let home = chamfer_at([0.0; 3]);
    for shift in [
        [512.4, -511.6, 512.5],
        [1_999_488.3, -1_500_000.7, 123.45],
        [-2_000_000.0, 2_000_000.0, -1_999_999.5],
    ] {
        let far = chamfer_at(shift);
        assert!(
            far <= 1.02 * home,
            "{shift:?}: Chamfer {far} m against {home} m at the origin"
        );
    }
}
