use super::*;
use crate::link::wire::{Content, FrameRepr, FrameReprV2, QUATERNION_ONE};
use crate::test_support::{OrFail, TestResult};

const POINTS: [[i32; 3]; 3] = [[1, -2, 3], [i32::MAX, i32::MIN, 0], [-1500, 250, 999_999]];

#[test]
fn emit_then_parse() -> TestResult {
    let repr = FrameRepr {
        sequence: 0xDEAD_BEEF,
        end_of_stream: true,
        unit_exponent: -3,
        points: &POINTS,
    };
    let mut buf = [0u8; 64];
    let n = repr.emit(&mut buf).or_fail("fits")?;
    assert_eq!(n, 10 + 36 + 4);
    let frame = Frame::new_checked(&buf[..n]).or_fail("valid")?;
    assert_eq!(frame.sequence(), 0xDEAD_BEEF);
    assert!(frame.end_of_stream());
    assert_eq!(frame.unit_exponent(), -3);
    for (i, p) in POINTS.iter().enumerate() {
        assert_eq!(frame.point(i), Some(*p));
    }
    assert_eq!(frame.point(3), None);
    for first in 0..=4 {
        assert!(
            frame
                .points_from(first)
                .eq((first..3).filter_map(|i| frame.point(i)))
        );
    }
    let metres: [[f64; 3]; 1] = [frame.points_metres().next().or_fail("one point")?];
    assert_eq!(metres[0], [0.001, -0.002, 0.003]);
    // Byte layout, field by field (the PROTOCOL.md example).
    assert_eq!(&buf[..10], &[1, 1, 0xEF, 0xBE, 0xAD, 0xDE, 3, 0, 0xFD, 0]);
    Ok(())
}

/// The example of PROTOCOL.md, whose bytes were computed independently (Python, zlib).
#[test]
fn protocol_example() -> TestResult {
    let points = [[1000, -2000, 500], [0, 0, -1]];
    let repr = FrameRepr {
        sequence: 7,
        end_of_stream: true,
        unit_exponent: -3,
        points: &points,
    };
    let mut raw = [0u8; 64];
    let n = repr.emit(&mut raw).or_fail("fits")?;
    let want_raw: [u8; 38] = [
        0x01, 0x01, 0x07, 0x00, 0x00, 0x00, 0x02, 0x00, 0xfd, 0x00, 0xe8, 0x03, 0x00, 0x00, 0x30,
        0xf8, 0xff, 0xff, 0xf4, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
        0xff, 0xff, 0xff, 0xff, 0x3d, 0x7e, 0xf4, 0x5a,
    ];
    assert_eq!(&raw[..n], &want_raw);
    let mut wire = [0u8; 64];
    let m = crate::link::cobs::cobs_encode(&raw[..n], &mut wire).or_fail("fits")?;
    let want_wire: [u8; 39] = [
        0x04, 0x01, 0x01, 0x07, 0x01, 0x01, 0x02, 0x02, 0x02, 0xfd, 0x03, 0xe8, 0x03, 0x01, 0x07,
        0x30, 0xf8, 0xff, 0xff, 0xf4, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01,
        0x09, 0xff, 0xff, 0xff, 0xff, 0x3d, 0x7e, 0xf4, 0x5a,
    ];
    assert_eq!(&wire[..m], &want_wire);
    Ok(())
}

#[test]
fn one_test_per_rejection_rule() -> TestResult {
    let repr = FrameRepr {
        sequence: 7,
        end_of_stream: false,
        unit_exponent: -3,
        points: &POINTS,
    };
    let mut good = [0u8; 64];
    let n = repr.emit(&mut good).or_fail("fits")?;
    let check = |bytes: &[u8]| Frame::new_checked(bytes).map(|_| ());
    assert_eq!(check(&good[..5]), Err(FrameError::Truncated { len: 5 }));
    assert_eq!(
        check(&good[..n - 1]),
        Err(FrameError::LengthMismatch {
            expected: n,
            got: n - 1
        })
    );
    let mut v = good;
    v[0] = 3;
    assert_eq!(
        check(&v[..n]),
        Err(FrameError::UnsupportedVersion { version: 3 })
    );
    let mut c = good;
    c[6] = 200;
    assert_eq!(
        check(&c[..n]),
        Err(FrameError::TooManyPoints { count: 200 })
    );
    let mut r = good;
    r[9] = 1;
    assert_eq!(check(&r[..n]), Err(FrameError::Reserved));
    let mut f = good;
    f[1] = 0x80;
    assert_eq!(check(&f[..n]), Err(FrameError::Reserved));
    // Units: nanometres and kilometres are the ends; past them points would vanish or
    // overflow in f32 (the CRC is recomputed, so only the exponent is wrong).
    for (exponent, ok) in [
        (-9i8, true),
        (3, true),
        (-10, false),
        (4, false),
        (38, false),
        (-45, false),
    ] {
        let mut u = [0u8; 64];
        let m = FrameRepr {
            unit_exponent: exponent,
            ..repr
        }
        .emit(&mut u)
        .or_fail("fits")?;
        let want = if ok {
            Ok(())
        } else {
            Err(FrameError::UnitOutOfRange { exponent })
        };
        assert_eq!(check(&u[..m]), want, "exponent {exponent}");
    }
    let mut crc = good;
    crc[20] ^= 4;
    assert!(matches!(check(&crc[..n]), Err(FrameError::BadCrc { .. })));
    let too_many = [[0i32; 3]; MAX_POINTS + 1];
    let big = FrameRepr {
        points: &too_many,
        ..repr
    };
    assert_eq!(big.emit(&mut [0u8; 2048]), None);
    Ok(())
}

/// 90 degrees about z, on the wire: sin and cos of 45 degrees in units of 2^-30.
const QUARTER_TURN: i32 = 759_250_125;

/// The version 2 examples of PROTOCOL.md, whose bytes were computed independently (Python's
/// `struct` and `zlib.crc32`): a pose frame starting a session, then a frame of points at it.
#[test]
fn protocol_example_v2() -> TestResult {
    let pose = FrameReprV2 {
        sequence: 8,
        end_of_stream: false,
        session_start: true,
        unit_exponent: -3,
        content: Content::Pose {
            number: 1,
            pose: WirePose {
                translation: [1000, -2000, 500],
                rotation: [0, 0, QUARTER_TURN, QUARTER_TURN],
            },
        },
    };
    let mut raw = [0u8; 64];
    let n = pose.emit(&mut raw).or_fail("fits")?;
    let want: [u8; 46] = [
        0x02, 0x02, 0x08, 0x00, 0x00, 0x00, 0x00, 0x00, 0xfd, 0x01, 0x01, 0x00, 0x00, 0x00, 0xe8,
        0x03, 0x00, 0x00, 0x30, 0xf8, 0xff, 0xff, 0xf4, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x00, 0x00, 0xcd, 0x3c, 0x41, 0x2d, 0xcd, 0x3c, 0x41, 0x2d, 0x77, 0xd8, 0x53,
        0x5a,
    ];
    assert_eq!(raw.get(..n).or_fail("raw")?, &want);
    let frame = Frame::new_checked(raw.get(..n).or_fail("raw")?).or_fail("valid")?;
    assert_eq!(frame.kind(), Some(FrameKind::Pose));
    assert!(frame.session_start() && !frame.end_of_stream());
    assert_eq!((frame.pose_number(), frame.point_count()), (1, 0));
    assert_eq!(
        frame.pose(),
        Some(WirePose {
            translation: [1000, -2000, 500],
            rotation: [0, 0, QUARTER_TURN, QUARTER_TURN],
        })
    );
    assert_eq!(frame.point(0), None);

    let points = [[1000, 0, 0], [0, 0, -1]];
    let at_pose = FrameReprV2 {
        sequence: 9,
        end_of_stream: true,
        session_start: false,
        unit_exponent: -3,
        content: Content::Points {
            pose: 1,
            points: &points,
        },
    };
    let n = at_pose.emit(&mut raw).or_fail("fits")?;
    let want_raw: [u8; 42] = [
        0x02, 0x01, 0x09, 0x00, 0x00, 0x00, 0x02, 0x00, 0xfd, 0x00, 0x01, 0x00, 0x00, 0x00, 0xe8,
        0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x00, 0x00, 0xff, 0xff, 0xff, 0xff, 0xab, 0x1f, 0xca, 0xa6,
    ];
    assert_eq!(raw.get(..n).or_fail("raw")?, &want_raw);
    let mut wire = [0u8; 64];
    let m =
        crate::link::cobs::cobs_encode(raw.get(..n).or_fail("raw")?, &mut wire).or_fail("fits")?;
    let want_wire: [u8; 44] = [
        0x04, 0x02, 0x01, 0x09, 0x01, 0x01, 0x02, 0x02, 0x02, 0xfd, 0x02, 0x01, 0x01, 0x01, 0x03,
        0xe8, 0x03, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01,
        0x01, 0x01, 0x01, 0x01, 0x09, 0xff, 0xff, 0xff, 0xff, 0xab, 0x1f, 0xca, 0xa6, 0x00,
    ];
    assert_eq!(
        wire.get(..m).or_fail("wire")?,
        want_wire.get(..43).or_fail("body")?
    );
    let frame = Frame::new_checked(raw.get(..n).or_fail("raw")?).or_fail("valid")?;
    assert_eq!(frame.kind(), Some(FrameKind::Points));
    assert_eq!((frame.pose_number(), frame.point(1)), (1, Some([0, 0, -1])));
    assert!(frame.end_of_stream() && !frame.session_start());
    Ok(())
}

/// PROTOCOL.md's wide pose example, computed with Python's `struct` and `zlib.crc32`: pose 2 at
/// ECEF-like (4,198,000.4, 612,000.9, 4,762,000.2) m in millimetres, past i32, unturned.
#[test]
fn protocol_example_wide_pose() -> TestResult {
    let translation = [4_198_000_400, 612_000_900, 4_762_000_200];
    let pose = FrameReprV2 {
        sequence: 10,
        end_of_stream: false,
        session_start: false,
        unit_exponent: -3,
        content: Content::Pose {
            number: 2,
            pose: WirePose {
                translation,
                rotation: [0, 0, 0, QUATERNION_ONE],
            },
        },
    };
    let mut raw = [0u8; 64];
    let n = pose.emit(&mut raw).or_fail("fits")?;
    let want_raw: [u8; 58] = [
        0x02, 0x00, 0x0a, 0x00, 0x00, 0x00, 0x00, 0x00, 0xfd, 0x02, 0x02, 0x00, 0x00, 0x00, 0x10,
        0x67, 0x38, 0xfa, 0x00, 0x00, 0x00, 0x00, 0x84, 0x64, 0x7a, 0x24, 0x00, 0x00, 0x00, 0x00,
        0x48, 0x5b, 0xd6, 0x1b, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x40, 0x76, 0xda, 0x7f, 0x60,
    ];
    assert_eq!(raw.get(..n).or_fail("raw")?, &want_raw);
    let mut wire = [0u8; 64];
    let m =
        crate::link::cobs::cobs_encode(raw.get(..n).or_fail("raw")?, &mut wire).or_fail("fits")?;
    let want_wire: [u8; 59] = [
        0x02, 0x02, 0x02, 0x0a, 0x01, 0x01, 0x01, 0x01, 0x04, 0xfd, 0x02, 0x02, 0x01, 0x01, 0x05,
        0x10, 0x67, 0x38, 0xfa, 0x01, 0x01, 0x01, 0x05, 0x84, 0x64, 0x7a, 0x24, 0x01, 0x01, 0x01,
        0x06, 0x48, 0x5b, 0xd6, 0x1b, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01,
        0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x06, 0x40, 0x76, 0xda, 0x7f, 0x60,
    ];
    assert_eq!(wire.get(..m).or_fail("wire")?, &want_wire);
    let frame = Frame::new_checked(raw.get(..n).or_fail("raw")?).or_fail("valid")?;
    assert!(frame.wide_pose());
    assert_eq!(frame.kind(), Some(FrameKind::Pose));
    assert_eq!(frame.pose().map(|p| p.translation), Some(translation));
    // The same pose within i32 goes as an ordinary pose frame, 12 bytes shorter.
    let near = FrameReprV2 {
        content: Content::Pose {
            number: 2,
            pose: WirePose {
                translation: [4_198_000, 612_000, 4_762_000],
                rotation: [0, 0, 0, QUATERNION_ONE],
            },
        },
        ..pose
    };
    let n = near.emit(&mut raw).or_fail("fits")?;
    let frame = Frame::new_checked(raw.get(..n).or_fail("raw")?).or_fail("valid")?;
    assert_eq!((n, frame.wide_pose()), (46, false));
    // A wide pose's bytes under kind 1 are refused: the kind sets the length.
    let mut short = want_raw;
    short[9] = 1;
    assert!(matches!(
        Frame::new_checked(&short[..]),
        Err(FrameError::LengthMismatch {
            expected: 46,
            got: 58
        })
    ));
    Ok(())
}

/// Version 2's own rules, one each: kind, flags, a pose's number, count, length and quaternion.
#[test]
fn one_test_per_v2_rejection_rule() -> TestResult {
    let pose = |number: u32, rotation: [i32; 4]| FrameReprV2 {
        sequence: 3,
        end_of_stream: false,
        session_start: false,
        unit_exponent: -3,
        content: Content::Pose {
            number,
            pose: WirePose {
                translation: [1, 2, 3],
                rotation,
            },
        },
    };
    let check = |bytes: &[u8]| Frame::new_checked(bytes).map(|_| ());
    let mut buf = [0u8; 64];
    let unit = [0, 0, 0, QUATERNION_ONE];
    let n = pose(5, unit).emit(&mut buf).or_fail("fits")?;
    assert_eq!(check(buf.get(..n).or_fail("pose")?), Ok(()));
    // Pose 0 is the session's identity: no frame may carry it.
    let n = pose(0, unit).emit(&mut buf).or_fail("fits")?;
    assert_eq!(
        check(buf.get(..n).or_fail("zero")?),
        Err(FrameError::BadPose)
    );
    // Not a unit quaternion: zero, half, and just outside 2^-20; just inside is taken.
    for (q, ok) in [
        ([0, 0, 0, 0], false),
        ([0, 0, 0, QUATERNION_ONE / 2], false),
        ([0, 0, 0, QUATERNION_ONE + (QUATERNION_ONE >> 20)], false),
        ([0, 0, 0, QUATERNION_ONE + (QUATERNION_ONE >> 22)], true),
        ([QUARTER_TURN, 0, 0, -QUARTER_TURN], true),
    ] {
        let n = pose(5, q).emit(&mut buf).or_fail("fits")?;
        let want = if ok { Ok(()) } else { Err(FrameError::BadPose) };
        assert_eq!(check(buf.get(..n).or_fail("q")?), want, "{q:?}");
    }
    let n = pose(5, unit).emit(&mut buf).or_fail("fits")?;
    let good = buf;
    // A pose frame claiming points (its CRC made right again).
    let mut c = good;
    c[6] = 1;
    let crc = crate::link::crc32::crc32(&c[..n - 4]).to_le_bytes();
    c[n - 4..n].copy_from_slice(&crc);
    assert_eq!(check(&c[..n]), Err(FrameError::BadPose));
    let mut k = good;
    k[9] = 7;
    assert_eq!(check(&k[..n]), Err(FrameError::UnknownKind { kind: 7 }));
    let mut f = good;
    f[1] = 4;
    assert_eq!(check(&f[..n]), Err(FrameError::Reserved));
    assert!(matches!(
        check(&good[..n - 1]),
        Err(FrameError::LengthMismatch { .. })
    ));
    // Version 1 has no session flag.
    let mut v1 = [0u8; 64];
    let m = FrameRepr {
        sequence: 1,
        end_of_stream: false,
        unit_exponent: -3,
        points: &POINTS,
    }
    .emit(&mut v1)
    .or_fail("fits")?;
    v1[1] = 2;
    assert_eq!(check(&v1[..m]), Err(FrameError::Reserved));
    Ok(())
}

/// Every version 2 frame kind round-trips: emit, parse, compare, over edge values.
#[test]
fn v2_frames_round_trip() -> TestResult {
    let mut buf = [0u8; crate::link::wire::MAX_RAW_LEN];
    let many = [[7i32, -7, i32::MIN]; crate::link::wire::MAX_POINTS];
    for (points, pose) in [(&POINTS[..], 0u32), (&[][..], u32::MAX), (&many[..], 42)] {
        let repr = FrameReprV2 {
            sequence: u32::MAX,
            end_of_stream: pose == 0,
            session_start: pose != 0,
            unit_exponent: -9,
            content: Content::Points { pose, points },
        };
        let n = repr.emit(&mut buf).or_fail("fits")?;
        assert_eq!(n, repr.buffer_len());
        let frame = Frame::new_checked(buf.get(..n).or_fail("raw")?).or_fail("valid")?;
        assert_eq!(frame.pose_number(), pose);
        assert_eq!(usize::from(frame.point_count()), points.len());
        for (i, p) in points.iter().enumerate() {
            assert_eq!(frame.point(i), Some(*p));
        }
        assert_eq!(frame.pose(), None);
        assert_eq!(
            (frame.end_of_stream(), frame.session_start()),
            (pose == 0, pose != 0)
        );
    }
    let too_many = [[0i32; 3]; crate::link::wire::MAX_POINTS + 1];
    let big = FrameReprV2 {
        sequence: 0,
        end_of_stream: false,
        session_start: false,
        unit_exponent: -3,
        content: Content::Points {
            pose: 0,
            points: &too_many,
        },
    };
    assert_eq!(big.emit(&mut [0u8; 2048]), None);
    Ok(())
}
