//! The host's frames to a mapping device (PROTOCOL.md, "Host to device"): the points stream
//! carried in numbered pieces that the device takes strictly in order, and the host's requests
//! for downlink frames it missed.
//!
//! A frame is framed as every other (COBS, a `0x00` delimiter, CRC-32), with a version byte of
//! its own, `0x82`:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 1 | version `0x82` |
//! | 1 | 1 | kind: `0` carry, `1` resend entities, `2` resend the end, `3` query |
//! | 2 | 4 | carry: its number (0 for the first, +1 per carry frame); query: the host's number for it, which the answer repeats; other requests: `0` |
//! | 6 | n | the kind's payload |
//! | 6 + n | 4 | CRC-32 of every byte before it |
//!
//! A **carry** frame holds 1 to [`MAX_CARRIED`] bytes of the points stream (PROTOCOL.md's
//! points and pose frames, as a sender or a capture has them). The device passes a carry
//! frame's bytes on only when its number is the next it expects, so the points stream reaches
//! its receiver whole and in order whatever the line did, and the map is the one `mema replay`
//! makes of the same stream. Its progress frames say which number it expects next and how many
//! frames it refused: the host sends again from there. A **resend entities** request (`first`
//! u32, `count` u16) asks for entity frames again, a **resend the end** request (no payload)
//! for the timing and end frames once the map is finished, and a **query** (`what` u8: `0`
//! nearest surface, `1` ray; a point and a direction, f32, in the map's frame) asks the
//! finished map a question, answered by a downlink answer frame.

use crate::crc32::crc32;
use crate::wire::{cobs_decode_in_place, cobs_encode, cobs_max_encoded_len};

/// The version byte of a host-to-device frame.
pub const UPLINK_VERSION: u8 = 0x82;
/// Most stream bytes one carry frame holds: its raw frame is then 250 bytes, which COBS
/// lengthens by one.
pub const MAX_CARRIED: usize = 240;
const HEADER_LEN: usize = 6;
const CRC_LEN: usize = 4;
/// Where a decoded carry frame's stream bytes start in its block.
pub const CARRIED_AT: usize = HEADER_LEN;
/// Most entities one resend request asks for: the device answers one in a bounded time.
pub const MAX_RESEND: u16 = 64;
/// The longest raw frame.
pub const MAX_UP_RAW_LEN: usize = HEADER_LEN + MAX_CARRIED + CRC_LEN;
/// The longest frame on the wire, its delimiter included.
pub const MAX_UP_FRAME_LEN: usize = cobs_max_encoded_len(MAX_UP_RAW_LEN) + 1;

const KIND_CARRY: u8 = 0;
const KIND_RESEND: u8 = 1;
const KIND_RESEND_END: u8 = 2;
const KIND_QUERY: u8 = 3;
const QUERY_LEN: usize = 1 + 12 + 12;

/// What a host-to-device frame carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UpFrame<'a> {
    /// Stream bytes, number `sequence` of the carry frames.
    Carry { sequence: u32, bytes: &'a [u8] },
    /// A request of the host's.
    Request(Request),
}

/// A request of the host's, for the device to answer on the downlink.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request {
    /// Entity frames `first .. first + count` again (count at most [`MAX_RESEND`]).
    Resend { first: u32, count: u16 },
    /// The timing and end frames again, once the map is finished.
    ResendEnd,
    /// The distance from `point` to the nearest surface, or (`ray`) the first surface along
    /// `direction` from it; in the map's frame (metres from the receiver's origin). The answer
    /// repeats `number`.
    Query {
        number: u32,
        ray: bool,
        point: [f32; 3],
        direction: [f32; 3],
    },
}

/// Why a frame was not decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UplinkError {
    /// The COBS block is malformed.
    Cobs,
    /// Shorter than a header and a CRC, or not a length its kind has.
    Length { got: usize },
    /// The CRC does not match.
    Crc { stored: u32, computed: u32 },
    /// Not a host-to-device frame of this version.
    Version(u8),
    /// A kind this version does not define.
    Code(u8),
    /// The output buffer is too small, or a carry frame with no bytes or too many.
    BufferTooSmall,
}

/// Writes `frame` into `out`, COBS-encoded and delimited; returns the bytes to send.
pub fn encode(frame: &UpFrame<'_>, out: &mut [u8]) -> Result<usize, UplinkError> {
    let mut raw = [0u8; MAX_UP_RAW_LEN];
    let (kind, sequence, payload_len) = match *frame {
        UpFrame::Carry { sequence, bytes } => {
            if bytes.is_empty() || bytes.len() > MAX_CARRIED {
                return Err(UplinkError::BufferTooSmall);
            }
            let dst = raw
                .get_mut(HEADER_LEN..HEADER_LEN + bytes.len())
                .ok_or(UplinkError::BufferTooSmall)?;
            dst.copy_from_slice(bytes);
            (KIND_CARRY, sequence, bytes.len())
        }
        UpFrame::Request(Request::Resend { first, count }) => {
            let dst = raw
                .get_mut(HEADER_LEN..HEADER_LEN + 6)
                .ok_or(UplinkError::BufferTooSmall)?;
            dst[..4].copy_from_slice(&first.to_le_bytes());
            dst[4..].copy_from_slice(&count.to_le_bytes());
            (KIND_RESEND, 0, 6)
        }
        UpFrame::Request(Request::ResendEnd) => (KIND_RESEND_END, 0, 0),
        UpFrame::Request(Request::Query {
            number,
            ray,
            point,
            direction,
        }) => {
            let dst = raw
                .get_mut(HEADER_LEN..HEADER_LEN + QUERY_LEN)
                .ok_or(UplinkError::BufferTooSmall)?;
            dst[0] = u8::from(ray);
            for (slot, v) in dst[1..]
                .chunks_exact_mut(4)
                .zip(point.into_iter().chain(direction))
            {
                slot.copy_from_slice(&v.to_le_bytes());
            }
            (KIND_QUERY, number, QUERY_LEN)
        }
    };
    raw[0] = UPLINK_VERSION;
    raw[1] = kind;
    raw[2..6].copy_from_slice(&sequence.to_le_bytes());
    let body = HEADER_LEN + payload_len;
    let crc = crc32(raw.get(..body).ok_or(UplinkError::BufferTooSmall)?);
    raw.get_mut(body..body + CRC_LEN)
        .ok_or(UplinkError::BufferTooSmall)?
        .copy_from_slice(&crc.to_le_bytes());
    let len = body + CRC_LEN;
    let encoded =
        cobs_encode(raw.get(..len).unwrap_or(&[]), out).ok_or(UplinkError::BufferTooSmall)?;
    *out.get_mut(encoded).ok_or(UplinkError::BufferTooSmall)? = 0;
    Ok(encoded + 1)
}

/// Decodes one COBS block (the bytes between two delimiters, delimiter not included), in
/// place. A carry frame's bytes are the block's from [`CARRIED_AT`] on.
pub fn decode(block: &mut [u8]) -> Result<UpFrame<'_>, UplinkError> {
    let len = cobs_decode_in_place(block).ok_or(UplinkError::Cobs)?;
    if len < HEADER_LEN + CRC_LEN {
        return Err(UplinkError::Length { got: len });
    }
    let raw = block.get(..len).ok_or(UplinkError::Cobs)?;
    let (body, tail) = raw.split_at(len - CRC_LEN);
    let stored = u32::from_le_bytes(
        tail.try_into()
            .map_err(|_| UplinkError::Length { got: len })?,
    );
    let computed = crc32(body);
    if stored != computed {
        return Err(UplinkError::Crc { stored, computed });
    }
    let (header, payload) = body.split_at(HEADER_LEN);
    let [version, kind, s0, s1, s2, s3] = header
        .try_into()
        .map_err(|_| UplinkError::Length { got: len })?;
    if version != UPLINK_VERSION {
        return Err(UplinkError::Version(version));
    }
    let sequence = u32::from_le_bytes([s0, s1, s2, s3]);
    match (kind, payload.len()) {
        (KIND_CARRY, 1..=MAX_CARRIED) => Ok(UpFrame::Carry {
            sequence,
            bytes: payload,
        }),
        (KIND_RESEND, 6) => {
            let [f0, f1, f2, f3, c0, c1] = payload
                .try_into()
                .map_err(|_| UplinkError::Length { got: len })?;
            Ok(UpFrame::Request(Request::Resend {
                first: u32::from_le_bytes([f0, f1, f2, f3]),
                count: u16::from_le_bytes([c0, c1]).min(MAX_RESEND),
            }))
        }
        (KIND_RESEND_END, 0) => Ok(UpFrame::Request(Request::ResendEnd)),
        (KIND_QUERY, QUERY_LEN) => {
            let mut v = [0f32; 6];
            for (x, b) in v
                .iter_mut()
                .zip(payload.get(1..).unwrap_or(&[]).chunks_exact(4))
            {
                *x =
                    f32::from_le_bytes(b.try_into().map_err(|_| UplinkError::Length { got: len })?);
            }
            let ray = match payload.first() {
                Some(0) => false,
                Some(1) => true,
                Some(&other) => return Err(UplinkError::Code(other)),
                None => return Err(UplinkError::Length { got: len }),
            };
            Ok(UpFrame::Request(Request::Query {
                number: sequence,
                ray,
                point: [v[0], v[1], v[2]],
                direction: [v[3], v[4], v[5]],
            }))
        }
        (KIND_CARRY | KIND_RESEND | KIND_RESEND_END | KIND_QUERY, _) => {
            Err(UplinkError::Length { got: len })
        }
        (other, _) => Err(UplinkError::Code(other)),
    }
}

#[cfg(test)]
mod tests;
