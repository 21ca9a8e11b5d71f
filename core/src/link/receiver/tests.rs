use super::*;
use crate::link::cobs::cobs_encode;
use crate::link::wire::{Content, FrameRepr, FrameReprV2, MAX_RAW_LEN, QUATERNION_ONE, WirePose};
use crate::test_support::{OrFail, TestResult};

/// Appends frame `sequence` (COBS and delimiter) to `out` at `at`; returns the new end.
fn push(
    out: &mut [u8],
    at: usize,
    sequence: u32,
    end_of_stream: bool,
    unit_exponent: i8,
    points: &[[i32; 3]],
) -> Result<usize, &'static str> {
    let repr = FrameRepr {
        sequence,
        end_of_stream,
        unit_exponent,
        points,
    };
    let mut raw = [0u8; MAX_RAW_LEN];
    let len = repr.emit(&mut raw).or_fail("emit")?;
    let room = out.get_mut(at..).or_fail("room")?;
    let n = cobs_encode(raw.get(..len).or_fail("raw")?, room).or_fail("encode")?;
    *out.get_mut(at + n).or_fail("room")? = 0;
    Ok(at + n + 1)
}

/// Feeds `input` in chunks of `chunk`, the way a caller loops; returns the points mapped (as
/// a sum of their coordinates and a count, enough to tell two streams apart) and the number
/// of frames mapped.
fn receive(r: &mut Receiver, input: &[u8], chunk: usize) -> ([f64; 3], usize, usize) {
    let mut sum = [0.0f64; 3];
    let (mut points, mut frames, mut restarts) = (0, 0, 0);
    for piece in input.chunks(chunk.max(1)) {
        r.feed_all(
            piece,
            |frame, placement| {
                frames += 1;
                for p in placement.points(&frame) {
                    for (s, v) in sum.iter_mut().zip(p.to_array()) {
                        *s += v as f64;
                    }
                    points += 1;
                }
            },
            || restarts += 1,
        );
    }
    assert_eq!(restarts, 0, "no pose here can give up the origin");
    (sum, points, frames)
}

/// Frames after the end-of-stream frame were mapped, and how many depended on the chunking
/// (100 points with 1-byte chunks, 200 with 4 KiB, as the caller stopped after its chunk):
/// now they are counted and never mapped, whatever the chunking.
#[test]
fn frames_after_the_end_are_counted_not_mapped() -> TestResult {
    let mut wire = [0u8; 4096];
    let mut at = 1;
    for seq in 0..6u32 {
        let pts = [[seq as i32, 2, 3], [4, seq as i32 * 10, 6]];
        // Frame 2 ends the stream; 3..6 follow it on the same line.
        at = push(&mut wire, at, seq, seq == 2, -3, &pts)?;
    }
    let input = wire.get(..at).or_fail("wire")?;
    let mut expected = None;
    for chunk in [1, 2, 5, 13, 64, at] {
        let mut r = Receiver::new();
        let got = receive(&mut r, input, chunk);
        assert_eq!((got.1, got.2), (6, 3), "chunk {chunk}: frames 0..=2 only");
        assert!(r.ended());
        assert_eq!(r.stats().after_end, 3, "chunk {chunk}");
        assert_eq!(r.decoder_stats().accepted, 6);
        match expected {
            None => expected = Some(got),
            Some(e) => assert_eq!(got, e, "chunk {chunk}"),
        }
    }
    Ok(())
}

/// The origin is the first point: at 0 a point reaches the mapper as `(v * 10^e) as f32`;
/// far out the points keep their spacing.
#[test]
fn the_origin_keeps_millimetres_anywhere_on_the_link() -> TestResult {
    // Not (0, 0, 0): that is a no-return, never mapped nor the origin.
    let near = [[0, 0, 1], [-511_999, 0, 7]];
    let mut wire = [0u8; 512];
    let at = push(&mut wire, 1, 0, true, -3, &near)?;
    let mut r = Receiver::new();
    let Received::Points {
        frame, placement, ..
    } = r.feed(wire.get(..at).or_fail("wire")?)
    else {
        return Err("a frame of points");
    };
    assert_eq!(
        placement.origin().map(f64::to_bits),
        [0.0f64.to_bits(), 0.0f64.to_bits(), 1e-3f64.to_bits()]
    );
    for (i, q) in near.iter().enumerate() {
        let want = [q[0], q[1], q[2] - 1].map(|v| (v as f64 * libm::pow(10.0, -3.0)) as f32);
        // Bits, so a -0 would show.
        assert_eq!(
            placement.point(&frame, i).or_fail("point")?.to_array(),
            want
        );
    }

    // 2,000 km out in millimetres, 1 mm apart: f32 around 0 would resolve only 0.125 m.
    let base = 2_000_000_000i32;
    let far = [[base, -base, base / 2], [base + 1, -base + 1, base / 2 + 1]];
    let at = push(&mut wire, 1, 0, false, -3, &far)?;
    let mut r = Receiver::new();
    let Received::Points {
        frame, placement, ..
    } = r.feed(wire.get(..at).or_fail("wire")?)
    else {
        return Err("a frame of points");
    };
    let o = placement.origin();
    // The first point, exactly.
    assert_eq!(o, [2_000_000.0, -2_000_000.0, 1_000_000.0]);
    let a = placement.point(&frame, 0).or_fail("first")?.to_array();
    let b = placement.point(&frame, 1).or_fail("second")?.to_array();
    for j in 0..3 {
        assert!((b[j] - a[j] - 0.001).abs() < 1e-5, "axis {j}: {a:?} {b:?}");
        // Within the cell: the world point is origin + local to f32 precision there.
        let world = far[0][j] as f64 * 1e-3;
        assert!((o[j] + a[j] as f64 - world).abs() < 1e-4);
    }
    // A second frame keeps the first frame's origin.
    let at = push(&mut wire, 1, 1, true, -3, &near)?;
    let Received::Points { placement, .. } = r.feed(wire.get(..at).or_fail("wire")?) else {
        return Err("a frame of points");
    };
    assert_eq!(placement.origin(), o);
    Ok(())
}

/// Appends version 2 frame `repr` (COBS and delimiter) to `out` at `at`; returns the new end.
fn push_v2(out: &mut [u8], at: usize, repr: &FrameReprV2<'_>) -> Result<usize, &'static str> {
    let mut raw = [0u8; MAX_RAW_LEN];
    let len = repr.emit(&mut raw).or_fail("emit")?;
    let room = out.get_mut(at..).or_fail("room")?;
    let n = cobs_encode(raw.get(..len).or_fail("raw")?, room).or_fail("encode")?;
    *out.get_mut(at + n).or_fail("room")? = 0;
    Ok(at + n + 1)
}

fn pose_frame(sequence: u32, number: u32, pose: WirePose) -> FrameReprV2<'static> {
    FrameReprV2 {
        sequence,
        end_of_stream: false,
        session_start: sequence == 0,
        unit_exponent: -3,
        content: Content::Pose { number, pose },
    }
}

fn points_frame<'a>(sequence: u32, pose: u32, points: &'a [[i32; 3]]) -> FrameReprV2<'a> {
    FrameReprV2 {
        sequence,
        end_of_stream: false,
        session_start: sequence == 0,
        unit_exponent: -3,
        content: Content::Points { pose, points },
    }
}

/// Feeds `input` whole; returns the mapped points in order (at most 16).
fn mapped(r: &mut Receiver, input: &[u8]) -> ([[f32; 3]; 16], usize) {
    let mut out = [[0.0f32; 3]; 16];
    let (mut n, mut restarts) = (0, 0);
    r.feed_all(
        input,
        |frame, placement| {
            for p in placement.points(&frame) {
                if let Some(slot) = out.get_mut(n) {
                    *slot = p.to_array();
                    n += 1;
                }
            }
        },
        || restarts += 1,
    );
    assert_eq!(restarts, 0, "no pose here gives up the origin");
    (out, n)
}

/// A pose frame carries the sensor into the world: the points frames after it that name it
/// are mapped at `R(q) x + t`, computed here by hand for a quarter turn about z.
#[test]
fn a_pose_takes_sensor_points_into_the_world() -> TestResult {
    let half = libm::sqrt(0.5);
    let q = (half * QUATERNION_ONE as f64).round() as i32;
    let pose = WirePose {
        translation: [1000, -2000, 500],
        rotation: [0, 0, q, q],
    };
    let sensor = [[1000, 0, 0], [0, 2000, -1], [250, -250, 30]];
    let mut wire = [0u8; 1024];
    let mut at = push_v2(&mut wire, 1, &pose_frame(0, 1, pose))?;
    at = push_v2(&mut wire, at, &points_frame(1, 1, &sensor))?;
    let mut r = Receiver::new();
    let (got, n) = mapped(&mut r, wire.get(..at).or_fail("wire")?);
    assert_eq!(n, 3);
    assert_eq!(r.stats().poses, 1);
    // The first point, (1, -1, 0.5) m in the world.
    let origin = r.origin();
    assert_eq!(origin, [1.0, -1.0, 0.5]);
    for (p, s) in got.iter().zip(sensor) {
        let [x, y, z] = s.map(|v| v as f64 / 1000.0);
        // A quarter turn about z: (x, y, z) -> (-y, x, z).
        let want = [-y + 1.0, x - 2.0, z + 0.5];
        for j in 0..3 {
            let world = p[j] as f64 + origin[j];
            assert!(
                (world - want[j]).abs() < 1e-6,
                "{p:?} + {origin:?} vs {want:?}"
            );
        }
    }
    Ok(())
}

/// Points whose pose the receiver does not hold are counted and not mapped: its frame was lost,
/// or a new session began and took the receiver back to pose 0. Version 1 frames, and version 2
/// frames at pose 0, are at the identity with the bits a version 1 frame always had.
#[test]
fn points_without_their_pose_are_counted_not_mapped() -> TestResult {
    let shift = WirePose {
        translation: [5000, 0, 0],
        rotation: [0, 0, 0, QUATERNION_ONE],
    };
    let pts = [[1, 2, 3]];
    let mut wire = [0u8; 2048];
    let mut at = 1;
    at = push_v2(&mut wire, at, &points_frame(0, 0, &pts))?; // identity: mapped
    at = push_v2(&mut wire, at, &points_frame(1, 2, &pts))?; // pose 2 unknown
    at = push_v2(&mut wire, at, &pose_frame(2, 2, shift))?;
    at = push_v2(&mut wire, at, &points_frame(3, 2, &pts))?; // mapped at +5 m
    at = push(&mut wire, at, 4, false, -3, &pts)?; // version 1: the identity
    // The sender restarts: pose 2 is gone with its session.
    at = push_v2(&mut wire, at, &points_frame(0, 2, &pts))?;
    let mut r = Receiver::new();
    let (got, n) = mapped(&mut r, wire.get(..at).or_fail("wire")?);
    assert_eq!(n, 3);
    assert_eq!(
        (
            r.stats().no_pose,
            r.stats().poses,
            r.decoder_stats().sessions
        ),
        (2, 1, 2)
    );
    // The first point is the origin: the identity's points lie at 0 (bits: +0), the pose's
    // 5 m along x.
    let bits = |p: [f32; 3]| p.map(f32::to_bits);
    assert_eq!(r.origin(), [0.001, 0.002, 0.003]);
    assert_eq!(bits(got[0]), [0; 3]);
    assert_eq!(bits(got[2]), [0; 3]);
    assert_eq!(bits(got[1]), bits([5.0, 0.0, 0.0]));
    Ok(())
}
