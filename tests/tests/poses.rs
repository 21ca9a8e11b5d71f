//! Protocol version 2 (issue 12): a sensor's poses on the link, sessions, and version 1 as it
//! always was. Poses and sensor-frame points are computed here with nalgebra, independently of
//! the core's quaternion arithmetic.

use crate::util::{Dir, MemaCommand, eval_chamfer, shared};
use mema::io::load_cloud;
use mema::link::frames::{
    PosedScan, encode_posed_stream, encode_stream, push_frame_v2, quantise, wire_pose,
};
use mema::link::stream::{Capacity, map_points_directly};
use mema_core::link::receiver::{Received, Receiver};
use mema_core::link::wire::{Content, FrameReprV2, WirePose};
use nalgebra::{Point3 as P, UnitQuaternion, Vector3};

/// car6's points (metres, around its bounding-box centre), standing for the world.
fn car() -> Vec<[f64; 3]> {
    let cloud = load_cloud(&shared("car6.pcd")).expect("car6");
    cloud.points.iter().map(|p| p.to_f64()).collect()
}

/// `mema replay` of `bytes`; returns the JSON summary and the map's bytes.
fn replay(dir: &Dir, name: &str, bytes: &[u8], extra: &[&str]) -> (serde_json::Value, Vec<u8>) {
    let capture = dir.write(&format!("{name}.bin"), bytes);
    let map = dir.join(&format!("{name}.mema"));
    let ran = MemaCommand::new(dir)
        .arg("replay")
        .arg(&capture)
        .args(["-k", "150", "--json", "-o"])
        .arg(&map)
        .args(extra)
        .run()
        .assert_ok();
    (ran.json(), std::fs::read(&map).expect("map"))
}

/// Version 2 points frames at pose 0, with no pose frame: a sensor that never moves.
fn unposed_v2(points: &[[i32; 3]]) -> Vec<u8> {
    let chunks: Vec<&[[i32; 3]]> = points.chunks(100).collect();
    let mut out = vec![0u8];
    for (i, c) in chunks.iter().enumerate() {
        let repr = FrameReprV2 {
            sequence: i as u32 + 7,
            end_of_stream: i + 1 == chunks.len(),
            session_start: i == 0,
            unit_exponent: -3,
            content: Content::Points { pose: 0, points: c },
        };
        push_frame_v2(&mut out, &repr).expect("frame");
    }
    out
}

/// Version 1 captures map as they always did: the same bytes as the mapper fed `v * 10^e` in
/// f32 directly. A version 2 stream of the same points at pose 0, or after an identity pose
/// frame, maps to the same bytes, in both entity models.
#[test]
fn version_1_and_version_2_at_the_identity_map_alike() {
    let dir = Dir::new("v1-v2");
    let cloud = load_cloud(&shared("car6.pcd")).expect("car6");
    let wire: Vec<[i32; 3]> = cloud
        .points
        .iter()
        .map(|p| quantise(*p).expect("fits"))
        .collect();
    let identity = [PosedScan {
        pose: WirePose::IDENTITY,
        pose_exponent: -3,
        points: &wire,
    }];
    let captures = [
        ("v1", encode_stream(&wire).expect("v1")),
        ("v2-pose0", unposed_v2(&wire)),
        (
            "v2-identity",
            encode_posed_stream(&identity, -3).expect("v2"),
        ),
    ];
    let fit = mema::mapping::FitOptions::default()
        .config(150)
        .expect("defaults")
        .fit;
    let direct = map_points_directly(&cloud, Capacity::all_working(150), 0, fit)
        .expect("direct")
        .to_mema()
        .expect("encode");
    for model in ["paper", "shells"] {
        let mut maps = Vec::new();
        for (name, bytes) in &captures {
            let (json, map) = replay(&dir, &format!("{name}-{model}"), bytes, &["--model", model]);
            assert_eq!(json["points"], wire.len(), "{name}: {json}");
            maps.push(map);
        }
        assert!(
            maps.iter().all(|m| *m == maps[0]),
            "{model}: the three captures differ"
        );
        if model == "paper" {
            assert_eq!(maps[0], direct, "version 1 against the mapper fed directly");
        }
    }
}

/// A view: the sensor's pose (sensor to world) and the world points it saw.
type View = (UnitQuaternion<f64>, Vector3<f64>, Vec<[f64; 3]>);

/// Three views of the car, each sent in its own sensor frame after its pose: nalgebra puts each
/// world point into its sensor's frame, the wire rounds it to 0.1 mm, and the receiver must
/// bring every point back to the world within that rounding.
fn views() -> Vec<View> {
    let world = car();
    let poses = [
        (
            UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0),
            Vector3::new(12.5, -3.25, 0.75),
        ),
        (
            UnitQuaternion::from_euler_angles(-2.5, 0.2, 0.9),
            Vector3::new(-40.0, 7.0, 1.5),
        ),
        (
            UnitQuaternion::from_euler_angles(1.4, 0.0, -0.6),
            Vector3::new(3.0, 3.0, -2.0),
        ),
    ];
    let third = world.len().div_ceil(3);
    world
        .chunks(third)
        .zip(poses)
        .map(|(part, (q, t))| (q, t, part.to_vec()))
        .collect()
}

/// The sensor-frame points of a view, as the wire carries them (0.1 mm), and the scan.
fn sensor_wire(q: &UnitQuaternion<f64>, t: &Vector3<f64>, part: &[[f64; 3]]) -> Vec<[i32; 3]> {
    part.iter()
        .map(|w| {
            let s = q.inverse() * (P::new(w[0], w[1], w[2]) - t);
            [s.x, s.y, s.z].map(|v| (v * 1e4).round() as i32)
        })
        .collect()
}

fn posed_capture(views: &[View]) -> (Vec<u8>, Vec<Vec<[i32; 3]>>) {
    let sensor: Vec<Vec<[i32; 3]>> = views
        .iter()
        .map(|(q, t, part)| sensor_wire(q, t, part))
        .collect();
    let scans: Vec<PosedScan<'_>> = views
        .iter()
        .zip(&sensor)
        .map(|((q, t, _), points)| PosedScan {
            pose: wire_pose([t.x, t.y, t.z], [q.i, q.j, q.k, q.w], -4).expect("pose"),
            pose_exponent: -4,
            points,
        })
        .collect();
    (encode_posed_stream(&scans, -4).expect("stream"), sensor)
}

#[test]
fn a_moving_sensor_maps_in_one_world_frame() {
    let dir = Dir::new("posed");
    let views = views();
    let (bytes, _) = posed_capture(&views);
    let world: Vec<[f64; 3]> = views.iter().flat_map(|v| v.2.iter().copied()).collect();

    // The receiver's world points against the world points they were made from.
    let mut receiver = Receiver::new();
    let mut placed = Vec::new();
    let mut window: &[u8] = &bytes;
    loop {
        match receiver.feed(window) {
            Received::Consumed => break,
            Received::Skipped { why, .. } => panic!("a frame was skipped: {why:?}"),
            Received::Pose { remaining, .. } => window = remaining,
            Received::Restart { number, .. } => panic!("pose {number} gave up the origin"),
            Received::Points {
                frame,
                placement,
                remaining,
            } => {
                placed.extend(placement.points(&frame).map(|p| p.to_f64()));
                window = remaining;
            }
        }
    }
    assert_eq!(placed.len(), world.len());
    let origin = receiver.origin();
    let worst = placed
        .iter()
        .zip(&world)
        .map(|(p, w)| {
            (0..3)
                .map(|j| (p[j] + origin[j] - w[j]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    // 0.1 mm units round each coordinate by up to 0.05 mm: 0.087 mm in all, plus f32.
    assert!(worst < 1e-4, "worst point {worst} m from where it was");

    // The binary maps it; the map is as close to the car as the map of the world points sent
    // unposed (eval's two-way score against the same points).
    let (json, _) = replay(&dir, "posed", &bytes, &[]);
    assert_eq!(json["points"], world.len(), "{json}");
    assert_eq!(
        (json["poses"].as_u64(), json["frames_without_pose"].as_u64()),
        (Some(3), Some(0))
    );
    let plain: Vec<[i32; 3]> = world
        .iter()
        .map(|w| w.map(|v| (v * 1e3).round() as i32))
        .collect();
    replay(&dir, "plain", &encode_stream(&plain).expect("v1"), &[]);
    let text: String = world
        .iter()
        .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
        .collect();
    let cloud = dir.write("world.xyz", text.as_bytes());
    let chamfer = |map: &str| eval_chamfer(&dir, &cloud, map);
    let (posed, unposed) = (chamfer("posed.mema"), chamfer("plain.mema"));
    eprintln!("car6 in three posed views: Chamfer {posed} m; unposed {unposed} m");
    assert!(
        posed < 1.2 * unposed,
        "posed {posed} m, unposed {unposed} m"
    );
}

/// A lost pose frame: the points that name it are counted and not mapped (they would land at
/// the previous view's pose), and the map is that of the other views alone.
#[test]
fn points_whose_pose_was_lost_are_counted_not_mapped() {
    let dir = Dir::new("lost-pose");
    let views = views();
    let (bytes, sensor) = posed_capture(&views);
    // Cut the second pose frame: it follows the first view's frames (the leading delimiter, a
    // pose frame, then ceil(n / 100) points frames).
    let frames: Vec<&[u8]> = bytes[1..].split_inclusive(|&b| b == 0).collect();
    let second = 1 + sensor[0].len().div_ceil(100);
    let mut cut = vec![0u8];
    for (i, f) in frames.iter().enumerate() {
        if i != second {
            cut.extend_from_slice(f);
        }
    }
    let (json, map) = replay(&dir, "cut", &cut, &[]);
    let without = sensor[1].len().div_ceil(100);
    assert_eq!(json["frames_without_pose"], without, "{json}");
    assert_eq!(json["points"], sensor[0].len() + sensor[2].len(), "{json}");
    assert_eq!(json["frames_lost"], 1, "{json}");
    let kept = [&views[0], &views[2]].map(|(q, t, part)| (*q, *t, part.clone()));
    let (alone, _) = posed_capture(&kept);
    assert_eq!(map, replay(&dir, "alone", &alone, &[]).1);
}
