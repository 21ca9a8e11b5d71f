//! The rangefinder wire protocol: frames of points and of sensor poses, COBS-framed, CRC-32
//! protected.
//!
//! This module doc is the contract; `PROTOCOL.md` at the repository root walks a firmware engineer
//! through writing a sender. Every multi-byte field is little-endian.
//!
//! A frame before framing (the *raw* frame), version 2:
//!
//! | bytes            | field                                                          |
//! |------------------|----------------------------------------------------------------|
//! | 0                | protocol version, u8 = 2                                        |
//! | 1                | flags, u8: bit 0 = end of stream, bit 1 = session start; others 0 |
//! | 2..6             | sequence number, u32, +1 per frame (wraps)                      |
//! | 6..8             | point count n, u16, 0..=[`MAX_POINTS`] (0 in a pose frame)      |
//! | 8                | unit exponent e, i8, [`MIN_UNIT_EXPONENT`]..=[`MAX_UNIT_EXPONENT`]: a length is `value * 10^e` metres |
//! | 9                | kind, u8: 0 = points, 1 = pose, 2 = wide pose                   |
//! | 10..14           | pose number, u32: a points frame's pose; a pose frame's own number (not 0) |
//! | 14..14+12n       | points frame: x, y, z as i32 each, in the sensor frame          |
//! | 14..42           | pose frame: translation x, y, z as i32 (`10^e` m), then the rotation's unit quaternion x, y, z, w as i32 in units of 2^-30 |
//! | 14..54           | wide pose frame: translation x, y, z as i64 (`10^e` m), then the quaternion as in a pose frame |
//! | last 4           | CRC-32 (IEEE, as zip/PNG) of every byte before it               |
//!
//! A pose is sensor to world: `x_world = R(q) x_sensor + t`. It applies to the points frames
//! that name its number. Each session starts at pose 0, the identity, which no frame carries.
//!
//! Version 1 frames are still taken: the same first 9 bytes, byte 9 reserved (0), flag bit 1 not
//! used, points from byte 10, no poses (their points are in the world frame).
//!
//! On the wire the raw frame is COBS-encoded (Cheshire and Baker, 1999), so it contains no zero
//! byte, and followed by one `0x00` delimiter: the link's one framing ([`super::framing`]). A receiver that joins mid-stream, or loses bytes,
//! resynchronises at the next `0x00`.
//!
//! Why integers: a rangefinder measures to about a millimetre, i32 millimetres cover +-2,147 km
//! exactly, and an integer cannot be NaN, so a frame that passes its CRC holds finite points.
//! A point is measured in the sensor frame, well within that; a pose is given in the robot's
//! world frame, which may be the globe's (UTM northings to 10,000 km, ECEF to 6,400 km): a
//! sender writes a pose whose translation is past i32 in its unit as a wide pose, with i64
//! translations, and every other pose as before, so older captures are the same bytes.
//!
//! [`Frame::new_checked`] validates a raw frame once (length, version, kind, count, unit, CRC,
//! the pose's quaternion); after it, no accessor can fail. [`FrameRepr::emit`] and
//! [`FrameReprV2::emit`] cannot fail into a buffer of their `buffer_len()` bytes. The CRC check
//! is skipped under `cfg(fuzzing)` so a fuzzer reaches the field logic.

mod decoder;
mod frame;
mod repr;

pub use decoder::{Decoded, Decoder, DecoderStats, MAX_GAP};
pub use frame::{Frame, FrameError, FrameKind};
pub use repr::{Content, FrameRepr, FrameReprV2, WirePose};

/// The version senders should use: 2, with poses and sessions. Version 1 is still received.
pub const VERSION: u8 = 2;
/// The first version: points only, in the world frame.
pub const VERSION_1: u8 = 1;
/// Points per frame: 1,554 raw bytes, under a typical UART DMA buffer.
pub const MAX_POINTS: usize = 128;
/// Header bytes of a version 2 frame.
pub const HEADER_LEN: usize = 14;
/// Header bytes of a version 1 frame.
pub const HEADER_LEN_V1: usize = 10;
pub const CRC_LEN: usize = super::framing::CRC_LEN;
pub const POINT_LEN: usize = 12;
/// A pose: translation (3 x i32) and quaternion (4 x i32).
pub const POSE_LEN: usize = 28;
/// The whole raw pose frame.
pub const POSE_FRAME_LEN: usize = HEADER_LEN + POSE_LEN + CRC_LEN;
/// A wide pose: translation (3 x i64) and quaternion (4 x i32).
pub const WIDE_POSE_LEN: usize = 40;
/// The whole raw wide pose frame.
pub const WIDE_POSE_FRAME_LEN: usize = HEADER_LEN + WIDE_POSE_LEN + CRC_LEN;
/// Flag bit 0: the sender has nothing more to send.
pub const FLAG_END_OF_STREAM: u8 = 1;
/// Flag bit 1 (version 2): the sender (re)starts; the receiver begins a new session.
pub const FLAG_SESSION_START: u8 = 2;
/// A quaternion component of 1.0 on the wire: 2^30, so `w = 1` fits an i32 and a component
/// resolves 9.3e-10 (a micrometre at a kilometre).
pub const QUATERNION_ONE: i32 = 1 << 30;
/// The smallest unit exponent a receiver takes: nanometres (`10^-9` m).
///
/// Outside `MIN_UNIT_EXPONENT..=MAX_UNIT_EXPONENT` a frame is refused: at `10^-45` every
/// coordinate rounds to 0 in f32 and a cloud collapses into one point, at `10^38` every
/// coordinate overflows, and neither is a unit a length sensor reports in.
pub const MIN_UNIT_EXPONENT: i8 = -9;
/// The largest unit exponent a receiver takes: kilometres (`10^3` m).
pub const MAX_UNIT_EXPONENT: i8 = 3;

/// `10^e` for `e` in `MIN_UNIT_EXPONENT..=MAX_UNIT_EXPONENT`, each the nearest f64 (the value a
/// sender's `1e-5` literal has). A table rather than `libm::pow`: pow costs 1.2 KB of a 64 KiB
/// part's flash and is one ulp off at `10^-5`; at `10^-3`, the unit of every capture before
/// there was a table, both agree (tested), so those captures map to the same bits.
const UNIT_SCALES: [f64; 13] = [
    1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1e0, 1e1, 1e2, 1e3,
];

/// The metres in one unit of exponent `e`, or `None` outside the range a receiver takes.
pub fn unit_scale(e: i8) -> Option<f64> {
    let i = usize::try_from(i16::from(e) - i16::from(MIN_UNIT_EXPONENT)).ok()?;
    UNIT_SCALES.get(i).copied()
}

/// The largest raw frame (a version 2 points frame of [`MAX_POINTS`]).
pub const MAX_RAW_LEN: usize = HEADER_LEN + POINT_LEN * MAX_POINTS + CRC_LEN;
/// The largest frame on the wire, COBS overhead and delimiter included: size UART buffers from it.
pub const MAX_FRAME_LEN: usize = super::cobs::cobs_max_encoded_len(MAX_RAW_LEN) + 1;

pub(crate) mod field {
    use core::ops::Range;
    pub const VERSION: usize = 0;
    pub const FLAGS: usize = 1;
    pub const SEQUENCE: Range<usize> = 2..6;
    pub const COUNT: Range<usize> = 6..8;
    pub const UNIT_EXPONENT: usize = 8;
    /// Version 1: reserved, 0. Version 2: the kind.
    pub const RESERVED: usize = 9;
    pub const KIND: usize = 9;
    pub const POSE_NUMBER: Range<usize> = 10..14;
    /// A pose frame's body, after the version 2 header.
    pub const TRANSLATION: usize = 14;
    pub const ROTATION: usize = 26;
    /// A wide pose frame's quaternion, after its three i64.
    pub const WIDE_ROTATION: usize = 38;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_scales_are_powers_of_ten() {
        for e in MIN_UNIT_EXPONENT..=MAX_UNIT_EXPONENT {
            let pow = libm::pow(10.0, e as f64);
            let scale = unit_scale(e).unwrap_or(f64::NAN);
            assert!((scale / pow - 1.0).abs() <= f64::EPSILON, "10^{e}");
            // Millimetres, the unit of every capture so far: the bits pow gave them.
            if e == -3 {
                assert_eq!(scale.to_bits(), pow.to_bits());
            }
        }
        assert_eq!(unit_scale(MIN_UNIT_EXPONENT - 1), None);
        assert_eq!(unit_scale(MAX_UNIT_EXPONENT + 1), None);
        assert_eq!(unit_scale(i8::MIN), None);
    }
}
