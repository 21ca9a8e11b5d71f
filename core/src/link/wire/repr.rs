//! The content of valid frames, for emitting: version 1 points ([`FrameRepr`]) and version 2
//! points or poses ([`FrameReprV2`]).

use super::frame::KIND_WIDE_POSE;
use super::frame::points_len;
use super::{
    CRC_LEN, FLAG_END_OF_STREAM, FLAG_SESSION_START, HEADER_LEN, HEADER_LEN_V1, MAX_POINTS,
    POINT_LEN, POSE_FRAME_LEN, VERSION, VERSION_1, WIDE_POSE_FRAME_LEN, field,
};

/// A sensor pose as the wire carries it: sensor to world, `x_world = R(q) x_sensor + t`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WirePose {
    /// In units of `10^e` metres, `e` the frame's unit exponent. Past i32 it goes as a wide
    /// pose frame.
    pub translation: [i64; 3],
    /// The unit quaternion `x, y, z, w` (scalar last) in units of 2^-30
    /// ([`super::QUATERNION_ONE`]).
    pub rotation: [i32; 4],
}

impl WirePose {
    /// The identity at the origin.
    pub const IDENTITY: Self = Self {
        translation: [0; 3],
        rotation: [0, 0, 0, super::QUATERNION_ONE],
    };

    /// Whether the translation needs a wide pose frame: past i32 on some axis.
    pub const fn is_wide(&self) -> bool {
        const fn fits(v: i64) -> bool {
            v >= i32::MIN as i64 && v <= i32::MAX as i64
        }
        let [x, y, z] = self.translation;
        !(fits(x) && fits(y) && fits(z))
    }
}

/// The content of a valid version 1 frame, for emitting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRepr<'a> {
    pub sequence: u32,
    pub end_of_stream: bool,
    pub unit_exponent: i8,
    pub points: &'a [[i32; 3]],
}

/// Writes the points of a frame after its header.
fn emit_points(body: &mut [u8], points: &[[i32; 3]]) {
    for (record, p) in body.chunks_exact_mut(POINT_LEN).zip(points.iter()) {
        for (slot, v) in record.chunks_exact_mut(4).zip(p.iter()) {
            slot.copy_from_slice(&v.to_le_bytes());
        }
    }
}

/// The first `len - 4` bytes of `out`, zeroed, the CRC's four zeroed after them; `None` if short.
fn frame_body(out: &mut [u8], len: usize) -> Option<&mut [u8]> {
    let out = out.get_mut(..len)?;
    out.fill(0);
    out.get_mut(..len.checked_sub(CRC_LEN)?)
}

/// The header fields both versions share.
fn emit_common(
    header: &mut [u8],
    version: u8,
    flags: u8,
    sequence: u32,
    count: usize,
    unit_exponent: i8,
) -> Option<()> {
    *header.get_mut(field::VERSION)? = version;
    *header.get_mut(field::FLAGS)? = flags;
    header
        .get_mut(field::SEQUENCE)?
        .copy_from_slice(&sequence.to_le_bytes());
    header
        .get_mut(field::COUNT)?
        .copy_from_slice(&(count as u16).to_le_bytes());
    *header.get_mut(field::UNIT_EXPONENT)? = unit_exponent as u8;
    Some(())
}

impl FrameRepr<'_> {
    pub const fn len_for(points: usize) -> usize {
        points_len(VERSION_1, points)
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
        let body = frame_body(out, len)?;
        let flags = if self.end_of_stream {
            FLAG_END_OF_STREAM
        } else {
            0
        };
        let (header, points) = body.split_at_mut(HEADER_LEN_V1);
        emit_common(
            header,
            VERSION_1,
            flags,
            self.sequence,
            self.points.len(),
            self.unit_exponent,
        )?;
        emit_points(points, self.points);
        crate::link::framing::put_crc(out, len - CRC_LEN)
    }
}

/// What a version 2 frame carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Content<'a> {
    /// Points in the sensor frame, measured at pose `pose` (0: the session's start, the
    /// identity).
    Points { pose: u32, points: &'a [[i32; 3]] },
    /// The sensor's pose number `number` (not 0), for the points frames after it that name it.
    Pose { number: u32, pose: WirePose },
}

/// The content of a valid version 2 frame, for emitting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameReprV2<'a> {
    pub sequence: u32,
    pub end_of_stream: bool,
    /// The first frame after the sender started or reset.
    pub session_start: bool,
    /// Of the points, or of the pose's translation.
    pub unit_exponent: i8,
    pub content: Content<'a>,
}

impl FrameReprV2<'_> {
    pub const fn buffer_len(&self) -> usize {
        match self.content {
            Content::Points { points, .. } => points_len(VERSION, points.len()),
            Content::Pose { pose, .. } if pose.is_wide() => WIDE_POSE_FRAME_LEN,
            Content::Pose { .. } => POSE_FRAME_LEN,
        }
    }

    /// Writes the raw frame; returns its length, or `None` if the buffer is short or there are
    /// more than [`MAX_POINTS`] points. (A pose numbered 0 or a quaternion that is not a unit
    /// one is written as given; the receiver refuses it.)
    pub fn emit(&self, out: &mut [u8]) -> Option<usize> {
        let len = self.buffer_len();
        let body = frame_body(out, len)?;
        let flags = (u8::from(self.end_of_stream) * FLAG_END_OF_STREAM)
            | (u8::from(self.session_start) * FLAG_SESSION_START);
        let (header, rest) = body.split_at_mut(HEADER_LEN);
        let (kind, number, count) = match self.content {
            Content::Points { pose, points } => {
                if points.len() > MAX_POINTS {
                    return None;
                }
                emit_points(rest, points);
                (0, pose, points.len())
            }
            Content::Pose { number, pose } => {
                let wide = pose.is_wide();
                let width = if wide { 8 } else { 4 };
                // Narrow: each value fits i32 (`is_wide`), whose bytes are i64's first four.
                let translation = pose
                    .translation
                    .into_iter()
                    .flat_map(|v| v.to_le_bytes().into_iter().take(width));
                let rotation = pose.rotation.into_iter().flat_map(i32::to_le_bytes);
                for (slot, b) in rest.iter_mut().zip(translation.chain(rotation)) {
                    *slot = b;
                }
                (if wide { KIND_WIDE_POSE } else { 1 }, number, 0)
            }
        };
        emit_common(
            header,
            VERSION,
            flags,
            self.sequence,
            count,
            self.unit_exponent,
        )?;
        *header.get_mut(field::KIND)? = kind;
        header
            .get_mut(field::POSE_NUMBER)?
            .copy_from_slice(&number.to_le_bytes());
        crate::link::framing::put_crc(out, len - CRC_LEN)
    }
}
