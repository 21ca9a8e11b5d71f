//! The host's frames to a mapping device (PROTOCOL.md, "Host to device"): the points stream
//! carried in numbered pieces that the device takes strictly in order, and the host's requests
//! for downlink frames it missed.
//!
//! A frame is framed as every other ([`super::framing`]) with the header the host and device
//! share ([`super::frame`]):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 1 | version `0x84` |
//! | 1 | 1 | kind: `0` carry, `1` resend entities, `2` resend the end, `3` query, `4` start a session |
//! | 2 | 4 | session: the host's, never `0` |
//! | 6 | 4 | boot: the device's boot the host talks to (`0` in a start request: any) |
//! | 10 | 4 | carry: its number (from the start request's first, +1 per carry frame, wrapping); query: the host's number for it, which the answer repeats; other requests: `0` |
//! | 14 | n | the kind's payload |
//! | 14 + n | 4 | CRC-32 of every byte before it |
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
//! finished map a question, answered by a downlink answer frame. A **start** request (the
//! number of the session's first carry frame, u32) begins the host's session: the device
//! begins a fresh map for it (or says it is in it already), and takes the other frames only of
//! the session it is in and addressed to its own boot.

use super::frame::{Address, Emitter, HEADER_LEN, LinkError, LinkFrame};
use super::framing::CRC_LEN;
use crate::link::cobs::cobs_max_encoded_len;

/// The version byte of a host-to-device frame (`0x82` before sessions and boots).
pub const UPLINK_VERSION: u8 = 0x84;
/// Most stream bytes one carry frame holds: its raw frame is then 258 bytes, which COBS
/// lengthens by two.
pub const MAX_CARRIED: usize = 240;
/// Where a carry frame's stream bytes start in its raw frame.
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
const KIND_START: u8 = 4;
const RESEND_LEN: usize = 4 + 2;
const START_LEN: usize = 4;
const QUERY_LEN: usize = 1 + 12 + 12;

/// What a host-to-device frame carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UpFrame<'a> {
    /// Stream bytes, number `sequence` of the session's carry frames.
    Carry { sequence: u32, bytes: &'a [u8] },
    /// A request of the host's.
    Request(Request),
}

/// A request of the host's, for the device to answer on the downlink.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request {
    /// Begin the frame's session, whose carry frames are numbered from `first`: a device in
    /// another session (or none) begins a fresh map and says so in a session frame; one
    /// already in it says so again.
    Start { first: u32 },
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

/// Writes `frame`, from the host's session to the device's boot in `to`, into `out`,
/// COBS-encoded and delimited; returns the bytes to send.
pub fn encode(to: Address, frame: &UpFrame<'_>, out: &mut [u8]) -> Result<usize, LinkError> {
    let (kind, number) = match *frame {
        UpFrame::Carry { sequence, bytes } => {
            if bytes.is_empty() || bytes.len() > MAX_CARRIED {
                return Err(LinkError::BufferTooSmall);
            }
            (KIND_CARRY, sequence)
        }
        UpFrame::Request(Request::Query { number, .. }) => (KIND_QUERY, number),
        UpFrame::Request(Request::Resend { .. }) => (KIND_RESEND, 0),
        UpFrame::Request(Request::ResendEnd) => (KIND_RESEND_END, 0),
        UpFrame::Request(Request::Start { .. }) => (KIND_START, 0),
    };
    let mut e = Emitter::new(UPLINK_VERSION, kind, to, number);
    match *frame {
        UpFrame::Carry { bytes, .. } => {
            e.put(bytes);
        }
        UpFrame::Request(Request::Resend { first, count }) => {
            e.u32(first).u16(count);
        }
        UpFrame::Request(Request::Query {
            ray,
            point,
            direction,
            ..
        }) => {
            e.u8(u8::from(ray));
            for v in point.into_iter().chain(direction) {
                e.f32(v);
            }
        }
        UpFrame::Request(Request::Start { first }) => {
            e.u32(first);
        }
        UpFrame::Request(Request::ResendEnd) => {}
    }
    e.seal(out)
}

/// Reads a raw frame (a block the [`super::framing::Deframer`] decoded): who it is from and to,
/// and what it carries. A carry frame's bytes are the raw frame's from [`CARRIED_AT`] on.
pub fn decode(raw: &[u8]) -> Result<(Address, UpFrame<'_>), LinkError> {
    let frame = LinkFrame::new_checked(raw, UPLINK_VERSION)?;
    let address = frame.address();
    let number = frame.number();
    // Only carry frames and queries carry a number; the other requests' is `0` (PROTOCOL.md),
    // so no two frames mean one request (found by the `uplink_decoder` fuzz target).
    if !matches!(frame.kind(), KIND_CARRY | KIND_QUERY) && number != 0 {
        return Err(LinkError::Value);
    }
    let up = match frame.kind() {
        KIND_CARRY => {
            let bytes = frame.payload();
            if bytes.is_empty() || bytes.len() > MAX_CARRIED {
                return Err(LinkError::Length {
                    kind: KIND_CARRY,
                    got: bytes.len(),
                });
            }
            // The payload of `raw` itself, for the caller's lifetime.
            let bytes = raw.get(CARRIED_AT..CARRIED_AT + bytes.len()).unwrap_or(&[]);
            UpFrame::Carry {
                sequence: number,
                bytes,
            }
        }
        KIND_RESEND => {
            let mut p = frame.payload_of(RESEND_LEN)?;
            UpFrame::Request(Request::Resend {
                first: p.u32()?,
                count: p.u16()?.min(MAX_RESEND),
            })
        }
        KIND_RESEND_END => {
            frame.payload_of(0)?;
            UpFrame::Request(Request::ResendEnd)
        }
        KIND_START => {
            let first = frame.payload_of(START_LEN)?.u32()?;
            if address.session == 0 {
                return Err(LinkError::Value);
            }
            UpFrame::Request(Request::Start { first })
        }
        KIND_QUERY => {
            let mut p = frame.payload_of(QUERY_LEN)?;
            let ray = p.flag()?;
            let mut v = [0f32; 6];
            for x in v.iter_mut() {
                *x = p.f32()?;
            }
            UpFrame::Request(Request::Query {
                number,
                ray,
                point: [v[0], v[1], v[2]],
                direction: [v[3], v[4], v[5]],
            })
        }
        other => return Err(LinkError::Code(other)),
    };
    Ok((address, up))
}

#[cfg(test)]
mod tests;
