//! The raw frame: a checked view over bytes ([`Frame`]), for both versions and both kinds.

use super::{
    CRC_LEN, FLAG_END_OF_STREAM, FLAG_SESSION_START, HEADER_LEN, HEADER_LEN_V1, MAX_POINTS,
    MAX_UNIT_EXPONENT, MIN_UNIT_EXPONENT, POINT_LEN, POSE_FRAME_LEN, QUATERNION_ONE, VERSION,
    VERSION_1, WIDE_POSE_FRAME_LEN, WirePose, field,
};

/// Why a raw frame was refused. Each kind is counted separately by the decoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// Shorter than a header and CRC.
    Truncated {
        len: usize,
    },
    /// The length does not match the point count (or a pose frame's length).
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
    /// A version 2 kind other than points (0) or pose (1).
    UnknownKind {
        kind: u8,
    },
    /// Reserved bits or bytes are not zero.
    Reserved,
    /// A unit exponent outside [`MIN_UNIT_EXPONENT`]`..=`[`MAX_UNIT_EXPONENT`].
    UnitOutOfRange {
        exponent: i8,
    },
    /// A pose frame numbered 0 (the identity a session starts at), carrying points, or whose
    /// quaternion is not a unit one (within 2^-20 in its squared norm).
    BadPose,
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
                write!(f, "frame of {got} bytes, its header needs {expected}")
            }
            Self::TooManyPoints { count } => write!(f, "{count} points, at most {MAX_POINTS}"),
            Self::UnsupportedVersion { version } => write!(f, "protocol version {version}"),
            Self::UnknownKind { kind } => write!(f, "frame kind {kind}"),
            Self::Reserved => write!(f, "reserved bits set"),
            Self::UnitOutOfRange { exponent } => write!(
                f,
                "unit exponent {exponent} outside {MIN_UNIT_EXPONENT}..={MAX_UNIT_EXPONENT}"
            ),
            Self::BadPose => write!(f, "pose numbered 0, with points, or not a unit quaternion"),
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

/// What a frame carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameKind {
    Points,
    /// The sensor's pose for the points frames that name its number (version 2): kind 1, or
    /// kind 2 with a wide translation ([`Frame::wide_pose`]).
    Pose,
}

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

fn i32_at(bytes: &[u8], at: usize) -> i32 {
    u32_at(bytes, at) as i32
}

fn i64_at(bytes: &[u8], at: usize) -> i64 {
    let mut b = [0u8; 8];
    if let Some(src) = bytes.get(at..at + 8) {
        b.copy_from_slice(src);
    }
    i64::from_le_bytes(b)
}

/// The kind byte of a wide pose frame.
pub(crate) const KIND_WIDE_POSE: u8 = 2;

/// The raw length of a points frame of `points` in `version`.
pub(crate) const fn points_len(version: u8, points: usize) -> usize {
    let header = if version == VERSION_1 {
        HEADER_LEN_V1
    } else {
        HEADER_LEN
    };
    header + POINT_LEN * points + CRC_LEN
}

/// A unit quaternion on the wire: its squared norm within 2^-20 of 1 (a sender rounding each
/// component to 2^-30 is within 2^-28), and never the zero quaternion.
fn is_unit_quaternion(q: [i32; 4]) -> bool {
    let one = QUATERNION_ONE as f64;
    let n2: f64 = q.iter().map(|&v| (v as f64 / one) * (v as f64 / one)).sum();
    libm::fabs(n2 - 1.0) <= 1.0 / (1u32 << 20) as f64
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

    /// The one place that validates: length, version, kind, count, reserved fields, unit, CRC,
    /// and a pose's number and quaternion.
    pub fn check(&self) -> Result<(), FrameError> {
        let bytes = self.buffer.as_ref();
        let len = bytes.len();
        if len < HEADER_LEN_V1 + CRC_LEN {
            return Err(FrameError::Truncated { len });
        }
        let version = self.version();
        let flags = match version {
            VERSION_1 => FLAG_END_OF_STREAM,
            VERSION => FLAG_END_OF_STREAM | FLAG_SESSION_START,
            _ => return Err(FrameError::UnsupportedVersion { version }),
        };
        let count = self.point_count();
        if count as usize > MAX_POINTS {
            return Err(FrameError::TooManyPoints { count });
        }
        let kind = self.kind().ok_or(FrameError::UnknownKind {
            kind: byte_at(bytes, field::KIND),
        })?;
        let expected = match kind {
            FrameKind::Points => points_len(version, count as usize),
            FrameKind::Pose if self.wide_pose() => WIDE_POSE_FRAME_LEN,
            FrameKind::Pose => POSE_FRAME_LEN,
        };
        if len != expected {
            return Err(FrameError::LengthMismatch { expected, got: len });
        }
        if self.flags() & !flags != 0
            || (version == VERSION_1 && byte_at(bytes, field::RESERVED) != 0)
        {
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
        if kind == FrameKind::Pose {
            let pose = self.pose().ok_or(FrameError::BadPose)?;
            if count != 0 || self.pose_number() == 0 || !is_unit_quaternion(pose.rotation) {
                return Err(FrameError::BadPose);
            }
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
        self.flags() & FLAG_END_OF_STREAM != 0
    }

    /// Version 2: the sender (re)started with this frame.
    pub fn session_start(&self) -> bool {
        self.version() == VERSION && self.flags() & FLAG_SESSION_START != 0
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

    /// The metres in one unit of this frame (`10^e`); NaN for an exponent out of range, which
    /// [`Frame::check`] refuses.
    pub fn unit_scale(&self) -> f64 {
        super::unit_scale(self.unit_exponent()).unwrap_or(f64::NAN)
    }

    /// Points or pose; `None` for an unknown version 2 kind. Version 1 frames hold points.
    pub fn kind(&self) -> Option<FrameKind> {
        if self.version() == VERSION_1 {
            return Some(FrameKind::Points);
        }
        match byte_at(self.buffer.as_ref(), field::KIND) {
            0 => Some(FrameKind::Points),
            1 | KIND_WIDE_POSE => Some(FrameKind::Pose),
            _ => None,
        }
    }

    /// A pose frame whose translation is three i64 (kind 2), for world frames past i32 in the
    /// frame's unit.
    pub fn wide_pose(&self) -> bool {
        self.version() == VERSION && byte_at(self.buffer.as_ref(), field::KIND) == KIND_WIDE_POSE
    }

    /// Version 2: a points frame's pose, or a pose frame's own number. Version 1: 0, the
    /// identity.
    pub fn pose_number(&self) -> u32 {
        if self.version() == VERSION_1 {
            return 0;
        }
        u32_at(self.buffer.as_ref(), field::POSE_NUMBER.start)
    }

    fn header_len(&self) -> usize {
        if self.version() == VERSION_1 {
            HEADER_LEN_V1
        } else {
            HEADER_LEN
        }
    }

    /// The points from `first` on, as raw integers: the loop over [`Frame::point`] without its
    /// header reads per point.
    pub fn points_from(&self, first: usize) -> impl Iterator<Item = [i32; 3]> + '_ {
        let count = match self.kind() {
            Some(FrameKind::Points) => usize::from(self.point_count()),
            _ => 0,
        };
        let header = self.header_len();
        let body = self.buffer.as_ref().get(header..header + POINT_LEN * count);
        let body = body.unwrap_or(&[]).get(POINT_LEN * first..).unwrap_or(&[]);
        body.chunks_exact(POINT_LEN)
            .map(|p| [i32_at(p, 0), i32_at(p, 4), i32_at(p, 8)])
    }

    /// Point `i` as raw integers, or `None` past the points present.
    pub fn point(&self, i: usize) -> Option<[i32; 3]> {
        if i >= self.point_count() as usize || self.kind() != Some(FrameKind::Points) {
            return None;
        }
        let at = self.header_len() + POINT_LEN * i;
        let bytes = self.buffer.as_ref().get(at..at + POINT_LEN)?;
        let v = |k: usize| i32_at(bytes, 4 * k);
        Some([v(0), v(1), v(2)])
    }

    /// A pose frame's pose as raw integers, or `None` for a points frame or short bytes.
    pub fn pose(&self) -> Option<WirePose> {
        if self.kind() != Some(FrameKind::Pose) {
            return None;
        }
        let b = self.buffer.as_ref();
        let (translation, rotation) = if self.wide_pose() {
            let t = |k: usize| i64_at(b, field::TRANSLATION + 8 * k);
            ([t(0), t(1), t(2)], field::WIDE_ROTATION)
        } else {
            let t = |k: usize| i64::from(i32_at(b, field::TRANSLATION + 4 * k));
            ([t(0), t(1), t(2)], field::ROTATION)
        };
        b.get(field::TRANSLATION..rotation + 16)?;
        let q = |k: usize| i32_at(b, rotation + 4 * k);
        Some(WirePose {
            translation,
            rotation: [q(0), q(1), q(2), q(3)],
        })
    }

    /// The points, in metres (`value * 10^e`, computed in f64), in the sensor frame.
    pub fn points_metres(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        let scale = self.unit_scale();
        (0..self.point_count() as usize)
            .filter_map(move |i| self.point(i))
            .map(move |p| p.map(|v| v as f64 * scale))
    }

    pub fn stored_crc(&self) -> u32 {
        crate::link::framing::crcs(self.buffer.as_ref()).0
    }

    pub fn computed_crc(&self) -> u32 {
        crate::link::framing::crcs(self.buffer.as_ref()).1
    }
}

#[cfg(test)]
mod tests;
