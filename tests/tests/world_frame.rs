//! A robot's real world (issue 23): the map does not depend on where the world frame's origin
//! is, as far as UTM and ECEF put it; the glitches a link meets are `refused.rs`.

use mema::link::frames::push_frame_v2;
use mema_core::link::wire::{Content, FrameReprV2, QUATERNION_ONE, WirePose};
use mema_firmware::SHELLS;
use mema_firmware_sim::harness::RunConfig;

use crate::firmware::play_model;
use crate::guides::{says, thousands};
use crate::link_faults::{frame, replay};
use crate::util::{Dir, MemaCommand, eval_chamfer, shared, shared_data};

/// A 1 m plane of 128 points in millimetres, with a small wave so its fits have a shape.
pub(crate) fn plane() -> Vec<[i32; 3]> {
    (0..128)
        .map(|i| {
            let (x, y) = (i % 16, i / 16);
            [x * 66, y * 140, ((x * 7 + y * 13) % 5) - 2]
        })
        .collect()
}

/// The plane's points at i32's extremes in kilometres: 2.1 x 10^12 m out, as a wrong unit or
/// a corrupt frame that passed its CRC gives them.
pub(crate) fn far_points() -> Vec<[i32; 3]> {
    vec![
        [i32::MAX, i32::MIN, i32::MAX],
        [i32::MIN, i32::MAX, 0],
        [i32::MAX; 3],
    ]
}

/// A version 2 frame, framed.
pub(crate) fn v2(sequence: u32, end: bool, exponent: i8, content: Content) -> Vec<u8> {
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

pub(crate) fn pose(number: u32, translation: [i64; 3]) -> Content<'static> {
    Content::Pose {
        number,
        pose: WirePose {
            translation,
            rotation: [0, 0, 0, QUATERNION_ONE],
        },
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

/// Where robots' world frames put a scene (metres): the middle of the old 1,024 m cell; UTM
/// in central Europe (northing 5,400 km) and near the far end of northings (9,000 km); ECEF
/// at mid latitudes, in both signs.
pub(crate) const WORLD_SHIFTS: [[f64; 3]; 5] = [
    [512.4, -511.6, 512.5],
    [500_000.37, 5_400_000.81, 312.4],
    [833_999.2, 8_999_999.6, 1_204.3],
    [4_198_000.4, 612_000.9, 4_762_000.2],
    [-2_700_000.45, -4_300_000.15, 3_850_000.7],
];

/// `bun.conf` moved by `shift`, sent as `scanner-sim --conf` sends it: the capture's path.
pub(crate) fn moved_capture(dir: &Dir, shift: [f64; 3], name: &str) -> std::path::PathBuf {
    let conf = moved_conf(dir, shift);
    let capture = dir.join(&format!("{name}.bin"));
    MemaCommand::new(dir)
        .arg("scanner-sim")
        .arg("--conf")
        .arg(&conf)
        .arg("--port")
        .arg(&capture)
        .run()
        .assert_ok();
    capture
}

/// The two-way Chamfer against `bun_zipper.ply` of map `map` (in `dir`) moved back by `shift`.
pub(crate) fn chamfer_moved_back(dir: &Dir, map: &str, shift: [f64; 3]) -> f64 {
    let back = shift.map(|v| format!("{}", -v)).join(",");
    let moved_back = format!("{map}-back.mema");
    MemaCommand::new(dir)
        .args(["transform", map, "-o", &moved_back])
        .arg(format!("--translate={back}"))
        .run()
        .assert_ok();
    eval_chamfer(dir, &shared("bun_zipper.ply"), &moved_back)
}

/// The five bunny scans with their poses, streamed as `scanner-sim --conf` sends them, with the
/// world frame moved as far as UTM's northings and ECEF's coordinates put a robot (poses past
/// i32 millimetres go as wide pose frames): replayed and through the firmware's path, the map
/// moved back scores within 1.02x the two-way Chamfer against `bun_zipper.ply` of the same
/// scans at the origin.
#[test]
fn the_bunny_maps_alike_anywhere_on_the_globe() {
    // The far map's Chamfer against the one at the origin, at most.
    const RATIO: f64 = 1.02;
    let farthest = WORLD_SHIFTS
        .iter()
        .map(|s| s.iter().map(|v| v * v).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    says(
        "docs/streaming.md",
        &format!(
            "scans streamed with their poses at UTM and ECEF coordinates up to {} km out score \
             within {RATIO}x the Chamfer they score at 0",
            thousands((farthest / 1e6).floor() as u64 * 1000)
        ),
    );
    let dir = Dir::new("world-bunny");
    let chamfer_at = |shift: [f64; 3]| {
        let capture = std::fs::read(moved_capture(&dir, shift, "moved")).expect("capture");
        let (code, json, map) = replay(&dir, "moved", &capture, "150", &[]);
        assert_eq!(code, 0, "{json}");
        assert_eq!(json["poses"], 5, "{shift:?}: {json}");
        let firmware = play_model(&capture, (150, 0), SHELLS, &RunConfig::default());
        assert_eq!(firmware.map, map, "{shift:?}: firmware vs replay");
        chamfer_moved_back(&dir, "moved.mema", shift)
    };
    let home = chamfer_at([0.0; 3]);
    for shift in WORLD_SHIFTS {
        let far = chamfer_at(shift);
        eprintln!("{shift:?}: Chamfer {far} m, {} x the origin's", far / home);
        assert!(
            far <= RATIO * home,
            "{shift:?}: Chamfer {far} m against {home} m at the origin"
        );
    }
}

/// The same on the STM32F405 board under QEMU, at ECEF's coordinates (6,400 km from the
/// Earth's centre) and the board's layout: its map is `mema replay`'s bytes, and within 1.02x
/// of the Chamfer of the scans at the origin.
#[test]
fn the_board_maps_the_bunny_in_earth_centred_coordinates() {
    use mema_firmware::{BOARD_FROZEN, BOARD_WORKING};
    let dir = Dir::new("world-board");
    let (k, working) = (
        (BOARD_WORKING + BOARD_FROZEN).to_string(),
        BOARD_WORKING.to_string(),
    );
    let layout = ["--working", working.as_str()];
    let home = moved_capture(&dir, [0.0; 3], "home");
    let (code, json, _) = replay(
        &dir,
        "home",
        &std::fs::read(home).expect("capture"),
        &k,
        &layout,
    );
    assert_eq!(code, 0, "{json}");
    let at_home = chamfer_moved_back(&dir, "home.mema", [0.0; 3]);
    let shift = WORLD_SHIFTS[4];
    let capture = moved_capture(&dir, shift, "ecef");
    let (code, json, replayed) = replay(
        &dir,
        "ecef",
        &std::fs::read(&capture).expect("capture"),
        &k,
        &layout,
    );
    assert_eq!(code, 0, "{json}");
    let image = crate::board_link::board_image("shells");
    let (_qemu, ptys) = crate::board_link::start_board(&dir, &image, None, 1);
    let out = dir.join("board.mema");
    let (ok, summary, stderr) = crate::board_sessions::session(&ptys[0], &capture, &out, None);
    assert!(ok, "{stderr}");
    let board = std::fs::read(&out).expect("the board's map");
    assert!(
        board == replayed,
        "the board's map is not replay's: {summary}"
    );
    let far = chamfer_moved_back(&dir, "board.mema", shift);
    assert!(
        far <= 1.02 * at_home,
        "Chamfer {far} m on the board at {shift:?} against {at_home} m at the origin"
    );
}

/// A frame of a capture, as its sender meant it.
#[derive(Clone)]
pub(crate) enum Sent {
    Points {
        pose: u32,
        exponent: i8,
        points: Vec<[i32; 3]>,
    },
    Pose {
        number: u32,
        exponent: i8,
        pose: WirePose,
    },
}

/// The frames of a clean version 2 capture, in order.
pub(crate) fn frames_of_capture(capture: &[u8]) -> Vec<Sent> {
    use mema_core::link::wire::{Decoded, Decoder, FrameKind};
    let mut decoder = Decoder::new();
    let mut out = Vec::new();
    let mut window = capture;
    loop {
        window = match decoder.feed(window) {
            Decoded::Consumed => return out,
            Decoded::Rejected { remaining, .. } => panic!("a clean capture: {remaining:?}"),
            Decoded::Frame { frame, remaining } => {
                let exponent = frame.unit_exponent();
                out.push(match (frame.kind(), frame.pose()) {
                    (Some(FrameKind::Pose), Some(pose)) => Sent::Pose {
                        number: frame.pose_number(),
                        exponent,
                        pose,
                    },
                    _ => Sent::Points {
                        pose: frame.pose_number(),
                        exponent,
                        points: frame.points_from(0).collect(),
                    },
                });
                remaining
            }
        };
    }
}

/// `frames` as a capture, numbered afresh, with every pose moved by `shift` whole metres and,
/// if `glitches`, what a robot's link meets mixed in: after every pose, the same pose number
/// 10^12 m away; after every fifth points frame, a frame of points at i32's extremes in
/// kilometres and one of points 200 km out (each a frame that passed its CRC).
pub(crate) fn rewritten(frames: &[Sent], shift: [i64; 3], glitches: bool) -> Vec<u8> {
    let mut out = vec![0u8];
    let mut sequence = 0u32;
    let mut push = |out: &mut Vec<u8>, exponent: i8, content: Content| {
        out.extend(v2(sequence, false, exponent, content));
        sequence += 1;
    };
    for (i, sent) in frames.iter().enumerate() {
        match sent {
            Sent::Pose {
                number,
                exponent,
                pose,
            } => {
                let per_metre = 10i64.pow(u32::from((-exponent).unsigned_abs()));
                let translation = [0, 1, 2].map(|j| pose.translation[j] + shift[j] * per_metre);
                let moved = WirePose {
                    translation,
                    ..*pose
                };
                push(
                    &mut out,
                    *exponent,
                    Content::Pose {
                        number: *number,
                        pose: moved,
                    },
                );
                if glitches {
                    let far = WirePose {
                        translation: [1_000_000_000, -1_000_000_000, 0],
                        ..*pose
                    };
                    push(
                        &mut out,
                        3,
                        Content::Pose {
                            number: *number,
                            pose: far,
                        },
                    );
                }
            }
            Sent::Points {
                pose,
                exponent,
                points,
            } => {
                push(
                    &mut out,
                    *exponent,
                    Content::Points {
                        pose: *pose,
                        points,
                    },
                );
                if glitches && i % 5 == 2 {
                    push(
                        &mut out,
                        3,
                        Content::Points {
                            pose: *pose,
                            points: &far_points(),
                        },
                    );
                    let per_metre = 10i64.pow(u32::from((-exponent).unsigned_abs()));
                    let out_there = i32::try_from(200_000 * per_metre).unwrap_or(i32::MAX);
                    let stray = [[out_there, 0, 0], [0, -out_there, 5]];
                    push(
                        &mut out,
                        *exponent,
                        Content::Points {
                            pose: *pose,
                            points: &stray,
                        },
                    );
                }
            }
        }
    }
    // The end, as its own empty frame.
    out.extend(v2(
        sequence,
        true,
        -3,
        Content::Points {
            pose: 0,
            points: &[],
        },
    ));
    out
}

/// A real drive's world: the demo drive and the bunny scans in a far world frame, with
/// corrupt-but-CRC-valid frames, a far pose and stray points mixed in, mapped by `replay` and
/// through the firmware's path: each map, moved back, scores a two-way Chamfer against the
/// clean points within 2% of the clean run's (the refused points never reach the mapper).
#[test]
fn a_drive_and_the_bunny_in_a_far_world_with_glitches_map_as_the_clean_run() {
    let dir = Dir::new("world-drive");
    MemaCommand::new(&dir)
        .args(["demo", "--moving", "--out-dir", "drive"])
        .run()
        .assert_ok();
    MemaCommand::new(&dir)
        .args(["scanner-sim", "--port", "drive.bin"])
        .run()
        .assert_ok();
    MemaCommand::new(&dir)
        .args(["scanner-sim", "--conf"])
        .arg(shared("bun.conf"))
        .args(["--port", "bunny.bin"])
        .run()
        .assert_ok();
    for (name, clean_points, k, shift) in [
        (
            "drive",
            dir.join("drive/scan.ply"),
            "250",
            [150_000, -180_000, 512],
        ),
        (
            "bunny",
            shared("bun_zipper.ply"),
            "150",
            [-170_000, 190_000, -513],
        ),
    ] {
        let frames =
            frames_of_capture(&std::fs::read(dir.join(&format!("{name}.bin"))).expect("capture"));
        let chamfer = |label: &str, capture: &[u8], back: [i64; 3]| {
            let (code, json, map) = replay(&dir, label, capture, k, &[]);
            assert_eq!(code, 0, "{label}: {json}");
            let firmware = play_model(
                capture,
                (k.parse().expect("k"), 0),
                SHELLS,
                &RunConfig::default(),
            );
            assert_eq!(firmware.map, map, "{label}: firmware vs replay");
            let back = back.map(|v| (-v).to_string()).join(",");
            MemaCommand::new(&dir)
                .arg("transform")
                .arg(format!("{label}.mema"))
                .arg(format!("--translate={back}"))
                .args(["-o", &format!("{label}-back.mema")])
                .run()
                .assert_ok();
            (
                eval_chamfer(&dir, &clean_points, &format!("{label}-back.mema")),
                json,
            )
        };
        let (clean, _) = chamfer(
            &format!("{name}-clean"),
            &rewritten(&frames, [0; 3], false),
            [0; 3],
        );
        let (far, json) = chamfer(
            &format!("{name}-far"),
            &rewritten(&frames, shift, true),
            shift,
        );
        assert!(
            json["points_out_of_reach"].as_u64() > Some(0),
            "{name}: {json}"
        );
        assert!(
            json["poses_out_of_reach"].as_u64() > Some(0),
            "{name}: {json}"
        );
        assert!(
            far <= 1.02 * clean,
            "{name}: Chamfer {far} m far and glitched against {clean} m clean"
        );
    }
}

/// A frame of points 50 km out, within reach (a robot that did drive there, or a glitch the reach
/// lets by), leaves every other entity where the mapper put it: a quantized file's centre grid
/// spans the map, so such a map is written in f32 instead of moving every shell by 0.8 m.
#[test]
fn one_far_entity_leaves_the_others_their_places() {
    use mema::link::stream::{Capacity, Link, stream_params};
    let plane = plane();
    let far = [
        [50_000_000, 0, 0],
        [50_000_100, 30, 0],
        [50_000_000, 60, 40],
    ];
    let mut bytes = vec![0u8];
    bytes.extend(frame(0, false, -3, &plane[..64]));
    bytes.extend(frame(1, false, -3, &far));
    bytes.extend(frame(2, true, -3, &plane[64..]));
    let params = stream_params(
        Capacity::all_working(16),
        0,
        Default::default(),
        0.0,
        SHELLS,
    );
    let mut link = Link::with_params(params);
    link.feed(&bytes);
    let map = link.finish();
    let origin = link.receiver.origin();
    let in_memory: Vec<[f64; 3]> = link
        .mapper
        .entities()
        .map(|e| {
            let c = e.entity.center.to_f64();
            [0, 1, 2].map(|j| c[j] + origin[j])
        })
        .collect();
    assert_eq!(in_memory.len(), map.entities.len());
    assert!(map.quantization.is_none(), "a 50 km map quantized");
    for (e, want) in map.entities.iter().zip(&in_memory) {
        let got = map.world_center(&e.entity);
        for j in 0..3 {
            assert!((got[j] - want[j]).abs() < 1e-6, "{got:?} vs {want:?}");
        }
    }
    // The plane alone stays quantized, 14 bytes an entity.
    let mut clean = vec![0u8];
    clean.extend(frame(0, false, -3, &plane[..64]));
    clean.extend(frame(2, true, -3, &plane[64..]));
    let mut alone = Link::with_params(params);
    alone.feed(&clean);
    assert!(alone.finish().quantization.is_some());
}
