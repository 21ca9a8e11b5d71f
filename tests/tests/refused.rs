//! What a receiver refuses costs nothing of the map: a frame of far points, a far pose, a glitch
//! as the very first point; and a stream whose every frame is refused says so and exits 1.

use mema_core::link::cobs::cobs_encode;
use mema_core::link::wire::{Content, FrameRepr, MAX_FRAME_LEN, MAX_RAW_LEN};
use mema_core::stream::StreamModel;
use mema_firmware::SHELLS;
use mema_firmware_sim::harness::RunConfig;

use crate::firmware::play_model;
use crate::link_faults::{frame, replay};
use crate::util::{Dir, MemaCommand};
use crate::world_frame::{
    Sent, WORLD_SHIFTS, chamfer_moved_back, far_points, frames_of_capture, moved_capture, plane,
    pose, rewritten, v2,
};

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

/// Frames holding no-returns (points at the sensor itself, as lidar drivers write a beam that
/// returned nothing), first and amid the plane's: the map is, byte for byte, the map of the
/// plane alone (no surface at the sensor), the firmware's too, and the summary counts them.
#[test]
fn no_returns_are_counted_and_never_mapped() {
    let dir = Dir::new("no-returns");
    let plane = plane();
    let mut half = plane[..64].to_vec();
    half.splice(10..10, [[0, 0, 0]; 20]);
    let mut with_none = vec![0u8];
    with_none.extend(frame(0, false, -3, &[[0, 0, 0]; 12]));
    with_none.extend(frame(1, false, -3, &half));
    with_none.extend(frame(2, true, -3, &plane[64..]));
    let mut clean = vec![0u8];
    clean.extend(frame(1, false, -3, &plane[..64]));
    clean.extend(frame(2, true, -3, &plane[64..]));
    let (code, json, with_map) = replay(&dir, "with", &with_none, "8", &[]);
    assert_eq!(code, 0, "{json}");
    assert_eq!(json["no_returns"], 32, "{json}");
    assert_eq!(json["points_out_of_reach"], 0, "{json}");
    assert_eq!(json["points"], 128, "{json}");
    let (_, _, clean_map) = replay(&dir, "clean", &clean, "8", &[]);
    assert_eq!(with_map, clean_map, "the no-returns changed the map");
    let firmware = play_model(&with_none, (8, 0), SHELLS, &RunConfig::default());
    assert_eq!(firmware.map, with_map, "firmware vs replay");
    let ran = MemaCommand::new(&dir)
        .args(["replay", "with.bin", "-k", "8", "-o", "again.mema"])
        .run()
        .assert_ok();
    assert!(
        ran.stderr()
            .contains("32 no-returns at the sensor (not mapped)"),
        "{}",
        ran.stderr()
    );
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

/// A stream whose every frame the receiver refuses maps nothing, and says so: `replay` exits 1
/// with the reason rather than 0 with an empty map (poses past the world's 20,000 km, which
/// all its points name; then frames whose every CRC is wrong).
#[test]
fn a_stream_whose_every_frame_is_refused_exits_non_zero_with_the_reason() {
    let dir = Dir::new("all-refused");
    let plane = plane();
    let mut beyond = vec![0u8];
    for (i, pose_number) in (1..=3u32).enumerate() {
        // 30,000 km in millimetres: a wide pose, past any world frame.
        let far = 30_000_000_000_i64 + i as i64;
        beyond.extend(v2(2 * i as u32, false, -3, pose(pose_number, [far, 0, 0])));
        beyond.extend(v2(
            2 * i as u32 + 1,
            i == 2,
            -3,
            Content::Points {
                pose: pose_number,
                points: &plane,
            },
        ));
    }
    let (code, json, _) = replay(&dir, "beyond", &beyond, "8", &[]);
    assert_eq!(code, 1, "{json}");
    let ran = MemaCommand::new(&dir)
        .args(["replay", "beyond.bin", "-k", "8", "-o", "beyond.mema"])
        .run();
    assert_eq!(ran.output.status.code(), Some(1), "{}", ran.stderr());
    assert!(
        ran.stderr()
            .contains("nothing was mapped: 3 poses out of reach"),
        "{}",
        ran.stderr()
    );
    // Every CRC wrong: the frames are rejected, and that is the reason given.
    let mut broken = vec![0u8];
    for (sequence, half) in plane.chunks(64).enumerate() {
        let mut raw = [0u8; MAX_RAW_LEN];
        let len = FrameRepr {
            sequence: sequence as u32,
            end_of_stream: sequence == 1,
            unit_exponent: -3,
            points: half,
        }
        .emit(&mut raw)
        .expect("emit");
        raw[len - 1] ^= 0x10;
        let mut framed = vec![0u8; MAX_FRAME_LEN];
        let n = cobs_encode(&raw[..len], &mut framed).expect("encode");
        broken.extend(&framed[..n]);
        broken.push(0);
    }
    dir.write("broken.bin", &broken);
    let ran = MemaCommand::new(&dir)
        .args(["replay", "broken.bin", "-k", "8", "-o", "broken.mema"])
        .run();
    assert_eq!(ran.output.status.code(), Some(1), "{}", ran.stderr());
    assert!(
        ran.stderr()
            .contains("nothing was mapped: 2 frames rejected (2 bad CRC)"),
        "{}",
        ran.stderr()
    );
}

/// A sensor glitch as the very first point of a stream (1,500 km out in the sensor frame),
/// which used to become the map's origin and leave every later point out of reach: the origin
/// is the point most of the first frame lies near, the glitch is refused, and the map (replay
/// and the firmware's path) is the clean stream's to within 1.02x of its Chamfer.
#[test]
fn a_glitch_as_the_very_first_point_costs_nothing() {
    let dir = Dir::new("first-glitch");
    let capture = moved_capture(&dir, WORLD_SHIFTS[1], "utm");
    let mut frames = frames_of_capture(&std::fs::read(&capture).expect("capture"));
    let clean = rewritten(&frames, [0; 3], false);
    let first = frames
        .iter_mut()
        .find_map(|f| match f {
            Sent::Points { points, .. } if !points.is_empty() => Some(points),
            _ => None,
        })
        .expect("a points frame");
    first[0] = [1_500_000_000, -7, 3];
    let glitched = rewritten(&frames, [0; 3], false);
    let mut chamfers = Vec::new();
    for (name, bytes) in [("clean", &clean), ("glitched", &glitched)] {
        let (code, json, map) = replay(&dir, name, bytes, "150", &[]);
        assert_eq!(code, 0, "{name}: {json}");
        let refused = json["points_out_of_reach"].as_u64();
        assert_eq!(refused, Some(u64::from(name == "glitched")), "{json}");
        let firmware = play_model(bytes, (150, 0), SHELLS, &RunConfig::default());
        assert_eq!(firmware.map, map, "{name}: firmware vs replay");
        chamfers.push(chamfer_moved_back(
            &dir,
            &format!("{name}.mema"),
            WORLD_SHIFTS[1],
        ));
    }
    assert!(
        chamfers[1] <= 1.02 * chamfers[0],
        "Chamfer {} m with the glitch against {} m clean",
        chamfers[1],
        chamfers[0]
    );
}

/// `frames` with the translation of their `nth` pose moved by `metres` along x.
fn pose_moved(frames: &[Sent], nth: usize, metres: i64) -> Vec<Sent> {
    let mut out = frames.to_vec();
    let (exponent, pose) = out
        .iter_mut()
        .filter_map(|f| match f {
            Sent::Pose { exponent, pose, .. } => Some((*exponent, pose)),
            Sent::Points { .. } => None,
        })
        .nth(nth)
        .expect("the pose");
    pose.translation[0] += metres * 10i64.pow(u32::from((-exponent).unsigned_abs()));
    out
}

/// `frames` without the scans of poses `drop` (each pose frame and the points frames after it).
fn without_scans(frames: &[Sent], drop: &[usize]) -> Vec<Sent> {
    let mut scan = None::<usize>;
    let mut out = Vec::new();
    for f in frames {
        if matches!(f, Sent::Pose { .. }) {
            scan = Some(scan.map_or(0, |s| s + 1));
        }
        if !scan.is_some_and(|s| drop.contains(&s)) {
            out.push(f.clone());
        }
    }
    out
}

/// A glitch as the very first pose (1,500 km off, in a UTM-like frame) set the map's origin
/// and every later pose was refused as out of reach: a map of the glitched scan alone, exit 0.
/// Now the next two poses, which agree with each other, outvote it: the map starts again under
/// them and is, byte for byte, the map of the stream without the first two scans (replay and
/// the firmware's path), and the summary says it started again. A glitch as the second pose
/// (one pose cannot outvote one) costs only its own scan: the map is the stream's without it.
#[test]
fn a_glitch_as_the_very_first_pose_costs_two_scans_not_the_map() {
    let dir = Dir::new("first-pose-glitch");
    let capture = moved_capture(&dir, WORLD_SHIFTS[1], "utm");
    let frames = frames_of_capture(&std::fs::read(&capture).expect("capture"));
    let cases = [
        ("first", pose_moved(&frames, 0, 1_500_000), vec![0, 1], 1),
        ("second", pose_moved(&frames, 1, 1_500_000), vec![1], 0),
    ];
    for (name, glitched, lost, restarts) in cases {
        let (code, json, map) =
            replay(&dir, name, &rewritten(&glitched, [0; 3], false), "150", &[]);
        assert_eq!(code, 0, "{name}: {json}");
        assert_eq!(json["origin_restarts"], restarts, "{name}: {json}");
        assert_eq!(json["poses_out_of_reach"], 1, "{name}: {json}");
        let kept = rewritten(&without_scans(&frames, &lost), [0; 3], false);
        let (_, kept_json, kept_map) = replay(&dir, &format!("{name}-kept"), &kept, "150", &[]);
        assert_eq!(json["points"], kept_json["points"], "{name}: {json}");
        assert_eq!(map, kept_map, "{name}: not the map of the scans kept");
        let firmware = play_model(
            &rewritten(&glitched, [0; 3], false),
            (150, 0),
            SHELLS,
            &RunConfig::default(),
        );
        assert_eq!(firmware.map, map, "{name}: firmware vs replay");
    }
    let ran = MemaCommand::new(&dir)
        .args(["replay", "first.bin", "-k", "150", "-o", "again.mema"])
        .run()
        .assert_ok();
    assert!(
        ran.stderr().contains("started again 1 time"),
        "{}",
        ran.stderr()
    );
}
