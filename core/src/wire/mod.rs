//! The rangefinder wire protocol: frames of points, COBS-framed, CRC-32 protected.
//!
//! This module doc is the contract; `PROTOCOL.md` at the repository root walks a firmware engineer
//! through writing a sender. Every multi-byte field is little-endian.
//!
//! A frame before framing (the *raw* frame):
//!
//! | bytes            | field                                                          |
//! |------------------|----------------------------------------------------------------|
//! | 0                | protocol version, u8 = 1                                        |
//! | 1                | flags, u8: bit 0 = end of stream; other bits 0                  |
//! | 2..6             | sequence number, u32, +1 per frame (wraps)                      |
//! | 6..8             | point count n, u16, 0..=[`MAX_POINTS`]                          |
//! | 8                | unit exponent e, i8: a coordinate is `value * 10^e` metres (-3: millimetres) |
//! | 9                | reserved, u8 = 0                                                |
//! | 10..10+12n       | points: x, y, z as i32 each, in the sensor frame               |
//! | 10+12n..14+12n   | CRC-32 (IEEE, as zip/PNG) of bytes 0..10+12n                    |
//!
//! On the wire the raw frame is COBS-encoded (Cheshire and Baker, 1999), so it contains no zero
//! byte, and followed by one `0x00` delimiter. A receiver that joins mid-stream, or loses bytes,
//! resynchronises at the next `0x00`.
//!
//! Why integers: a rangefinder measures to about a millimetre, i32 millimetres cover +-2,147 km
//! exactly, and an integer cannot be NaN, so a frame that passes its CRC holds finite points.
//!
//! [`Frame::new_checked`] validates a raw frame once (length, version, count, CRC); after it, no
//! accessor can fail. [`FrameRepr::emit`] cannot fail into a buffer of [`FrameRepr::buffer_len`]
//! bytes. The CRC check is skipped under `cfg(fuzzing)` so a fuzzer reaches the field logic.

mod cobs;
mod decoder;
mod frame;

pub use cobs::{cobs_decode_in_place, cobs_encode, cobs_max_encoded_len};
pub use decoder::{Decoded, Decoder, DecoderStats, MAX_GAP};
pub use frame::{Frame, FrameError, FrameRepr};

pub const VERSION: u8 = 1;
/// Points per frame: 1,550 raw bytes, under a typical UART DMA buffer.
pub const MAX_POINTS: usize = 128;
pub const HEADER_LEN: usize = 10;
pub const CRC_LEN: usize = 4;
pub const POINT_LEN: usize = 12;
/// Flag bit 0: the sender has nothing more to send.
pub const FLAG_END_OF_STREAM: u8 = 1;
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

/// The largest raw frame.
pub const MAX_RAW_LEN: usize = HEADER_LEN + POINT_LEN * MAX_POINTS + CRC_LEN;
/// The largest frame on the wire, COBS overhead and delimiter included: size UART buffers from it.
pub const MAX_FRAME_LEN: usize = cobs_max_encoded_len(MAX_RAW_LEN) + 1;

pub(crate) mod field {
    use core::ops::Range;
    pub const VERSION: usize = 0;
    pub const FLAGS: usize = 1;
    pub const SEQUENCE: Range<usize> = 2..6;
    pub const COUNT: Range<usize> = 6..8;
    pub const UNIT_EXPONENT: usize = 8;
    pub const RESERVED: usize = 9;
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
