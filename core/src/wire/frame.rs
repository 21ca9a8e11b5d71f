//! The raw frame: a checked view over bytes (`Frame`) and the valid content it carries (`FrameRepr`).

use super::{
    CRC_LEN, HEADER_LEN, MAX_POINTS, MAX_UNIT_EXPONENT, MIN_UNIT_EXPONENT, POINT_LEN, VERSION,
    field,
};
use crate::crc32::crc32;

/// Why a raw frame was refused. Each kind is counted separately by the decoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// Shorter than a header and CRC.
    Truncated {
        len: usize,
    },
    /// The length does not match the point count.
    LengthMismatch {
        expected: usize,
        got: usize,
    },
    TooManyPoints {
        count: u16,
    },
    UnsupportedVersion {
        version: u8,
    },
    /// Reserved bits or bytes are not zero.
    Reserved,
    /// A unit exponent outside [`MIN_UNIT_EXPONENT`]`..=`[`MAX_UNIT_EXPONENT`].
    UnitOutOfRange {
        exponent: i8,
    },
    BadCrc {
        stored: u32,
        computed: u32,
    },
    /// The COBS block was malformed (only the decoder reports this).
    BadCobs,
    /// More bytes than [`super::MAX_FRAME_LEN`] before a delimiter (only the decoder reports this).
    Oversized,
    /// A repeat of the last accepted frame (same sequence number and CRC), used once only.
    Duplicate {
        sequence: u32,
    },
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Truncated { len } => write!(f, "truncated frame ({len} bytes)"),
            Self::LengthMismatch { expected, got } => {
                write!(f, "frame of {got} bytes, its point count needs {expected}")
            }
            Self::TooManyPoints { count } => write!(f, "{count} points, at most {MAX_POINTS}"),
            Self::UnsupportedVersion { version } => write!(f, "protocol version {version}"),
            Self::Reserved => write!(f, "reserved bits set"),
            Self::UnitOutOfRange { exponent } => write!(
                f,
                "unit exponent {exponent} outside {MIN_UNIT_EXPONENT}..={MAX_UNIT_EXPONENT}"
            ),
            Self::BadCrc { stored, computed } => {
                write!(
                    f,
                    "CRC mismatch: stored {stored:08x}, computed {computed:08x}"
                )
            }
            Self::BadCobs => write!(f, "malformed COBS block"),
            Self::Oversized => write!(f, "no delimiter within the largest frame"),
            Self::Duplicate { sequence } => write!(f, "repeated sequence number {sequence}"),
        }
    }
}

impl core::error::Error for FrameError {}

/// A view over a raw (COBS-decoded) frame. Any accessor works on any bytes, returning zeros for
/// missing fields, so an invalid frame can still be printed; [`Frame::new_checked`] makes the
/// values trustworthy.
#[derive(Clone, Copy, Debug)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

fn byte_at(bytes: &[u8], at: usize) -> u8 {
    bytes.get(at).copied().unwrap_or(0)
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    let mut b = [0u8; 4];
    if let Some(src) = bytes.get(at..at + 4) {
        b.copy_from_slice(src);
    }
    u32::from_le_bytes(b)
}

impl<T: AsRef<[u8]>> Frame<T> {
    pub const fn new_unchecked(buffer: T) -> Self {
        Self { buffer }
    }

    /// The underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// `new_unchecked` followed by [`Frame::check`].
    pub fn new_checked(buffer: T) -> Result<Self, FrameError> {
        let frame = Self::new_unchecked(buffer);
        frame.check()?;
        Ok(frame)
    }

    /// The one place that validates: length, version, count, reserved fields, CRC.
    pub fn check(&self) -> Result<(), FrameError> {
        let bytes = self.buffer.as_ref();
        let len = bytes.len();
        if len < HEADER_LEN + CRC_LEN {
            return Err(FrameError::Truncated { len });
        }
        if self.version() != VERSION {
            return Err(FrameError::UnsupportedVersion {
                version: self.version(),
            });
        }
        let count = self.point_count();
        if count as usize > MAX_POINTS {
            return Err(FrameError::TooManyPoints { count });
        }
        let expected = FrameRepr::len_for(count as usize);
        if len != expected {
            return Err(FrameError::LengthMismatch { expected, got: len });
        }
        if self.flags() & !super::FLAG_END_OF_STREAM != 0 || byte_at(bytes, field::RESERVED) != 0 {
            return Err(FrameError::Reserved);
        }
        let exponent = self.unit_exponent();
        if !(MIN_UNIT_EXPONENT..=MAX_UNIT_EXPONENT).contains(&exponent) {
            return Err(FrameError::UnitOutOfRange { exponent });
        }
        let (stored, computed) = (self.stored_crc(), self.computed_crc());
        if stored != computed && !cfg!(fuzzing) {
            return Err(FrameError::BadCrc { stored, computed });
        }
        Ok(())
    }

    pub fn version(&self) -> u8 {
        byte_at(self.buffer.as_ref(), field::VERSION)
    }

    pub fn flags(&self) -> u8 {
        byte_at(self.buffer.as_ref(), field::FLAGS)
    }

    pub fn end_of_stream(&self) -> bool {
        self.flags() & super::FLAG_END_OF_STREAM != 0
    }

    pub fn sequence(&self) -> u32 {
        u32_at(self.buffer.as_ref(), field::SEQUENCE.start)
    }

    pub fn point_count(&self) -> u16 {
        let b = self.buffer.as_ref();
        u16::from_le_bytes([
            byte_at(b, field::COUNT.start),
            byte_at(b, field::COUNT.start + 1),
        ])
    }

    pub fn unit_exponent(&self) -> i8 {
        byte_at(self.buffer.as_ref(), field::UNIT_EXPONENT) as i8
    }

    /// Point `i` as raw integers, or `None` past the points present.
    pub fn point(&self, i: usize) -> Option<[i32; 3]> {
        if i >= self.point_count() as usize {
            return None;
        }
        let at = HEADER_LEN + POINT_LEN * i;
        let bytes = self.buffer.as_ref().get(at..at + POINT_LEN)?;
        let v = |k: usize| u32_at(bytes, 4 * k) as i32;
        Some([v(0), v(1), v(2)])
    }

    /// The metres in one unit of this frame (`10^e`); NaN for an exponent out of range, which
    /// [`Frame::check`] refuses.
    pub fn unit_scale(&self) -> f64 {
        super::unit_scale(self.unit_exponent()).unwrap_or(f64::NAN)
    }

    /// The points, in metres (`value * 10^e`, computed in f64).
    pub fn points_metres(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        let scale = self.unit_scale();
        (0..self.point_count() as usize)
            .filter_map(move |i| self.point(i))
            .map(move |p| p.map(|v| v as f64 * scale))
    }

    pub fn stored_crc(&self) -> u32 {
        let b = self.buffer.as_ref();
        u32_at(b, b.len().saturating_sub(CRC_LEN))
    }

    pub fn computed_crc(&self) -> u32 {
        let b = self.buffer.as_ref();
        crc32(b.get(..b.len().saturating_sub(CRC_LEN)).unwrap_or(&[]))
    }
}

/// The content of a valid frame, for emitting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRepr<'a> {
    pub sequence: u32,
    pub end_of_stream: bool,
    pub unit_exponent: i8,
    pub points: &'a [[i32; 3]],
}

impl FrameRepr<'_> {
    pub const fn len_for(points: usize) -> usize {
        HEADER_LEN + POINT_LEN * points + CRC_LEN
    }

    pub const fn buffer_len(&self) -> usize {
        Self::len_for(self.points.len())
    }

    /// Writes the raw frame; returns its length, or `None` if the buffer is short or there are
    /// more than [`MAX_POINTS`] points.
    pub fn emit(&self, out: &mut [u8]) -> Option<usize> {
        if self.points.len() > MAX_POINTS {
            return None;
        }
        let len = self.buffer_len();
        let out = out.get_mut(..len)?;
        let (body, crc_bytes) = out.split_at_mut(len - CRC_LEN);
        let (header, points) = body.split_at_mut(HEADER_LEN);
        header.fill(0);
        *header.get_mut(field::VERSION)? = VERSION;
        *header.get_mut(field::FLAGS)? = if self.end_of_stream {
            super::FLAG_END_OF_STREAM
        } else {
            0
        };
        header
            .get_mut(field::SEQUENCE)?
            .copy_from_slice(&self.sequence.to_le_bytes());
        header
            .get_mut(field::COUNT)?
            .copy_from_slice(&(self.points.len() as u16).to_le_bytes());
        *header.get_mut(field::UNIT_EXPONENT)? = self.unit_exponent as u8;
        for (record, p) in points.chunks_exact_mut(POINT_LEN).zip(self.points.iter()) {
            for (slot, v) in record.chunks_exact_mut(4).zip(p.iter()) {
                slot.copy_from_slice(&v.to_le_bytes());
            }
        }
        crc_bytes.copy_from_slice(&crc32(body).to_le_bytes());
        Some(len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
            0x01, 0x01, 0x07, 0x00, 0x00, 0x00, 0x02, 0x00, 0xfd, 0x00, 0xe8, 0x03, 0x00, 0x00,
            0x30, 0xf8, 0xff, 0xff, 0xf4, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            0x00, 0x00, 0xff, 0xff, 0xff, 0xff, 0x3d, 0x7e, 0xf4, 0x5a,
        ];
        assert_eq!(&raw[..n], &want_raw);
        let mut wire = [0u8; 64];
        let m = crate::wire::cobs_encode(&raw[..n], &mut wire).or_fail("fits")?;
        let want_wire: [u8; 39] = [
            0x04, 0x01, 0x01, 0x07, 0x01, 0x01, 0x02, 0x02, 0x02, 0xfd, 0x03, 0xe8, 0x03, 0x01,
            0x07, 0x30, 0xf8, 0xff, 0xff, 0xf4, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01,
            0x01, 0x01, 0x09, 0xff, 0xff, 0xff, 0xff, 0x3d, 0x7e, 0xf4, 0x5a,
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
        v[0] = 2;
        assert_eq!(
            check(&v[..n]),
            Err(FrameError::UnsupportedVersion { version: 2 })
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
}
