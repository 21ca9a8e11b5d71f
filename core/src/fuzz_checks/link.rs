//! The host-device frames' decoders ([`crate::link::uplink`], [`crate::link::downlink`]) on
//! any bytes: every block between delimiters, COBS-decoded by the plain in-place decoder, is
//! decoded as it is and again with its CRC made right (so a mutation reaches the header and
//! payload checks behind the CRC). Whatever a decoder accepts must be within the protocol's
//! bounds and must re-encode, with the address and number it decoded, to exactly the raw frame
//! it came from: a decoder that takes a frame the encoder never writes (or reads it as another)
//! would let two byte strings mean one thing, or one thing arrive as another.

use super::Violation;
use crate::link::cobs::cobs_decode_in_place;
use crate::link::crc32::crc32;
use crate::link::downlink::{self, DownFrame, MAX_DOWN_FRAME_LEN, MAX_MAP_ENTITIES};
use crate::link::framing::{CRC_LEN, seal};
use crate::link::uplink::{self, MAX_CARRIED, MAX_RESEND, MAX_UP_FRAME_LEN, Request, UpFrame};

/// Longest block the checks decode: four times the longest frame of either direction. A longer
/// block is no frame (its raw frame would be longer than any kind's), and is only counted.
pub const MAX_CHECKED_BLOCK: usize = 4 * MAX_UP_FRAME_LEN;

/// What the decoder made of a stream's blocks, each counted twice (as it came, and with its
/// CRC made right): so a test can see that both outcomes were reached.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FramesOutcome {
    /// Blocks the decoder took, and those it refused (a COBS failure included).
    pub decoded: usize,
    pub refused: usize,
}

/// The uplink decoder on every block of `bytes`.
pub fn uplink_frames(bytes: &[u8]) -> Result<FramesOutcome, Violation> {
    each_block(bytes, check_up)
}

/// The downlink decoder on every block of `bytes`.
pub fn downlink_frames(bytes: &[u8]) -> Result<FramesOutcome, Violation> {
    each_block(bytes, check_down)
}

/// Splits `bytes` at every `0x00` (a trailing block without its delimiter included: a decoder
/// may be handed any raw bytes), COBS-decodes each block in a copy and hands the raw frame, and
/// the raw frame with its CRC recomputed, to `check`.
fn each_block(
    bytes: &[u8],
    check: fn(&[u8]) -> Result<bool, Violation>,
) -> Result<FramesOutcome, Violation> {
    let mut outcome = FramesOutcome::default();
    let mut count = |taken: bool| {
        if taken {
            outcome.decoded += 1;
        } else {
            outcome.refused += 1;
        }
    };
    let mut buf = [0u8; MAX_CHECKED_BLOCK];
    for block in bytes.split(|&b| b == 0).filter(|b| !b.is_empty()) {
        let Some(copy) = buf.get_mut(..block.len()) else {
            count(false);
            continue;
        };
        copy.copy_from_slice(block);
        let Some(len) = cobs_decode_in_place(copy) else {
            count(false);
            continue;
        };
        let raw = copy.get_mut(..len).unwrap_or(&mut []);
        count(check(raw)?);
        if let Some(body_len) = raw.len().checked_sub(CRC_LEN) {
            let crc = crc32(raw.get(..body_len).unwrap_or(&[]));
            if let Some(tail) = raw.get_mut(body_len..) {
                tail.copy_from_slice(&crc.to_le_bytes());
            }
            count(check(raw)?);
        }
    }
    Ok(outcome)
}

/// The blocks a plain reader sees in `bytes`, for the models the carrier's and the assembler's
/// checks hold them to: each block ended by a delimiter (what follows the last one is no frame
/// yet), empty ones left out, COBS-decoded in place by the plain decoder if at most `longest`
/// bytes (a receiver keeps no longer block). `each` gets the block's place in `bytes` and its
/// raw frame, or `None` for a block refused before any header is read.
pub fn plain_blocks(
    bytes: &[u8],
    longest: usize,
    mut each: impl FnMut(core::ops::Range<usize>, Option<&[u8]>),
) {
    let mut buf = [0u8; MAX_CHECKED_BLOCK];
    let (mut at, mut rest) = (0, bytes);
    while let Some(end) = rest.iter().position(|&b| b == 0) {
        let (block, span) = (rest.get(..end).unwrap_or(&[]), at..at + end);
        (at, rest) = (at + end + 1, rest.get(end + 1..).unwrap_or(&[]));
        if block.is_empty() {
            continue;
        }
        let copy = buf
            .get_mut(..block.len())
            .filter(|_| block.len() <= longest);
        let raw = copy.and_then(|copy| {
            copy.copy_from_slice(block);
            let n = cobs_decode_in_place(copy)?;
            copy.get(..n)
        });
        each(span, raw);
    }
}

/// `bytes` with every block that COBS-decodes to a CRC's length or more sealed again with its
/// CRC made right (by the one framing, [`seal`]), the other blocks as they are, delimiters
/// kept, handed to `emit` in pieces: what the carrier's and the assembler's checks feed, so that
/// mutations reach the fields behind a frame's CRC (a block longer than
/// [`MAX_CHECKED_BLOCK`] is no frame and stays as it is).
pub fn crcs_made_right(bytes: &[u8], mut emit: impl FnMut(&[u8])) {
    let mut raw = [0u8; MAX_CHECKED_BLOCK];
    let mut wire = [0u8; MAX_CHECKED_BLOCK + MAX_CHECKED_BLOCK / 254 + 2];
    for (i, block) in bytes.split(|&b| b == 0).enumerate() {
        if i > 0 {
            emit(&[0]);
        }
        let sealed = raw.get_mut(..block.len()).and_then(|copy| {
            copy.copy_from_slice(block);
            let n = cobs_decode_in_place(copy)?;
            seal(copy, n.checked_sub(CRC_LEN)?, &mut wire)
        });
        match sealed {
            // Without the delimiter `seal` adds: the block's own follows.
            Some(m) => emit(wire.get(..m - 1).unwrap_or(&[])),
            None => emit(block),
        }
    }
}

/// `wire` (an encoder's output, delimiter included) holds no zero before its delimiter and
/// COBS-decodes to exactly `expected`.
fn same_frame(wire: &mut [u8], expected: &[u8]) -> Result<(), Violation> {
    let Some((&mut 0, body)) = wire.split_last_mut() else {
        return Err(Violation::FrameNoRoundTrip);
    };
    if body.contains(&0) {
        return Err(Violation::FrameNoRoundTrip);
    }
    match cobs_decode_in_place(body) {
        Some(n) if body.get(..n) == Some(expected) => Ok(()),
        _ => Err(Violation::FrameNoRoundTrip),
    }
}

fn check_up(raw: &[u8]) -> Result<bool, Violation> {
    let Ok((address, frame)) = uplink::decode(raw) else {
        return Ok(false);
    };
    let bounded = match frame {
        UpFrame::Carry { bytes, .. } => !bytes.is_empty() && bytes.len() <= MAX_CARRIED,
        UpFrame::Request(Request::Resend { count, .. }) => count <= MAX_RESEND,
        UpFrame::Request(Request::Start { .. }) => address.session != 0,
        UpFrame::Request(Request::ResendEnd | Request::Query { .. }) => true,
    };
    if !bounded {
        return Err(Violation::FrameOutOfBounds);
    }
    // A resend request for more than MAX_RESEND entities is read as MAX_RESEND (PROTOCOL.md):
    // the one field the decoder rewrites, so the frame it stands for says MAX_RESEND.
    let mut expected = [0u8; MAX_UP_FRAME_LEN];
    let expected = expected
        .get_mut(..raw.len())
        .ok_or(Violation::FrameNoRoundTrip)?;
    expected.copy_from_slice(raw);
    if let UpFrame::Request(Request::Resend { count, .. }) = frame {
        let body_len = raw.len().saturating_sub(CRC_LEN);
        if let Some(field) = expected.get_mut(18..20) {
            field.copy_from_slice(&count.to_le_bytes());
        }
        let crc = crc32(expected.get(..body_len).unwrap_or(&[]));
        if let Some(tail) = expected.get_mut(body_len..) {
            tail.copy_from_slice(&crc.to_le_bytes());
        }
    }
    let mut wire = [0u8; MAX_UP_FRAME_LEN];
    let n = uplink::encode(address, &frame, &mut wire).map_err(|_| Violation::FrameNoRoundTrip)?;
    same_frame(wire.get_mut(..n).unwrap_or(&mut []), expected)?;
    Ok(true)
}

fn check_down(raw: &[u8]) -> Result<bool, Violation> {
    let Ok((address, sequence, frame)) = downlink::decode(raw) else {
        return Ok(false);
    };
    let bounded = match frame {
        DownFrame::Entity { index, entity } => {
            let e = entity.entity;
            let r = e.rotation;
            index < MAX_MAP_ENTITIES
                && e.center.is_finite()
                && e.weights.iter().all(|w| w.is_finite() && *w >= 0.0)
                && [r.x, r.y, r.z, r.w].iter().all(|q| q.is_finite())
                && libm::fabs(
                    [r.x, r.y, r.z, r.w]
                        .iter()
                        .map(|&q| f64::from(q) * f64::from(q))
                        .sum::<f64>()
                        - 1.0,
                ) <= 1e-5
        }
        DownFrame::End(end) => {
            end.entities <= MAX_MAP_ENTITIES
                && end.shift.iter().all(|s| s.is_finite())
                && end.origin.iter().all(|o| o.is_finite())
        }
        DownFrame::Answer { value, .. } => !value.is_nan(),
        DownFrame::Retract { index } => index < MAX_MAP_ENTITIES,
        DownFrame::Progress { .. } | DownFrame::Timing(_) | DownFrame::Session { .. } => true,
    };
    if !bounded {
        return Err(Violation::FrameOutOfBounds);
    }
    let mut wire = [0u8; MAX_DOWN_FRAME_LEN];
    let n = downlink::encode(address, sequence, &frame, &mut wire)
        .map_err(|_| Violation::FrameNoRoundTrip)?;
    same_frame(wire.get_mut(..n).unwrap_or(&mut []), raw)?;
    Ok(true)
}
