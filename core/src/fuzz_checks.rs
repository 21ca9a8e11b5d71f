//! The properties the fuzz targets check (`core/fuzz/`, run by `scripts/fuzz.sh` under
//! cargo-fuzz) and the test suite's stable mutation loops check on the same seeds: one
//! definition, so a campaign and a test run hold the decoders to the same promises. Each
//! returns the first broken property instead of panicking; the callers panic.

use crate::link::crc32::crc32;
use crate::link::wire::{Decoded, Decoder};
use crate::map::{CRC_LEN, Layout, MapEntity, MapFile, encode_as};

mod link;
pub use link::{
    FramesOutcome, MAX_CHECKED_BLOCK, crcs_made_right, downlink_frames, plain_blocks, uplink_frames,
};

/// A property a decoder broke.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Violation {
    /// An accepted map holds an entity that is not finite, or a rotation that is not unit.
    UnsoundEntity,
    /// An accepted map does not re-encode, or re-encodes to other entities.
    NoRoundTrip,
    /// The wire decoder gave other frames for the same bytes fed in other pieces.
    ChunkingChangedFrames,
    /// The wire decoder's counters disagree with what it returned.
    CountersDisagree,
    /// A host-device frame the decoder accepted does not re-encode, with the address and
    /// number it decoded, to the raw frame it came from.
    FrameNoRoundTrip,
    /// A host-device frame the decoder accepted carries a value outside the protocol's bounds.
    FrameOutOfBounds,
}

/// Largest map the check re-encodes (the scratch buffer is on the stack).
pub const MAX_CHECKED_MAP: usize = 64 * 1024;

/// The map decoder on `bytes` as they are, and again with the CRC recomputed so that a
/// mutation reaches the header and record checks behind it: whatever it accepts is sound and
/// re-encodes, in its own layout, to the same entities (a quantized rotation to within a quarter
/// degree: see `check_map`).
pub fn map_file(bytes: &[u8]) -> Result<(), Violation> {
    check_map(bytes)?;
    let mut fixed = [0u8; MAX_CHECKED_MAP];
    let Some(copy) = fixed.get_mut(..bytes.len()) else {
        return Ok(());
    };
    copy.copy_from_slice(bytes);
    if let Some(body_len) = copy.len().checked_sub(CRC_LEN) {
        let crc = crc32(copy.get(..body_len).unwrap_or(&[]));
        if let Some(tail) = copy.get_mut(body_len..) {
            tail.copy_from_slice(&crc.to_le_bytes());
        }
    }
    check_map(copy)
}

fn check_map(bytes: &[u8]) -> Result<(), Violation> {
    let Ok(file) = MapFile::new_checked(bytes) else {
        return Ok(());
    };
    for e in file.entities() {
        let r = e.entity.rotation.to_array();
        let norm: f32 = r.iter().map(|v| v * v).sum();
        if !e.entity.center.is_finite()
            || !e.entity.weights.iter().all(|w| w.is_finite() && *w >= 0.0)
            || !(libm::fabsf(norm - 1.0) < 1e-3)
        {
            return Err(Violation::UnsoundEntity);
        }
    }
    let mut again = [0u8; MAX_CHECKED_MAP];
    let reread = reencode(&file, &mut again)?;
    let quantized = matches!(file.layout(), Layout::Quantized(_));
    if reread.layout() != file.layout()
        || reread.origin() != file.origin()
        || reread.len() != file.len()
        || !reread
            .entities()
            .zip(file.entities())
            .all(|(a, b)| same_entity(a, b, quantized))
    {
        return Err(Violation::NoRoundTrip);
    }
    // A quantized rotation code whose omitted component is not the largest is a valid rotation
    // the encoder never writes: re-encoding turns it to within the grid's quarter degree (and a
    // near tie between the two largest components can flip again on every pass, as close).
    Ok(())
}

fn reencode<'b>(file: &MapFile<'_>, out: &'b mut [u8]) -> Result<MapFile<'b>, Violation> {
    let len = encode_as(file.layout(), file.origin(), file.entities(), out)
        .map_err(|_| Violation::NoRoundTrip)?;
    MapFile::new_checked(out.get(..len).unwrap_or(&[])).map_err(|_| Violation::NoRoundTrip)
}

/// Equal, but for a quantized rotation: the same one to within 1e-4 of the quaternions' dot
/// product (a quarter degree is 2.4e-6).
fn same_entity(a: MapEntity, b: MapEntity, quantized: bool) -> bool {
    if !quantized {
        return a == b;
    }
    let (qa, qb) = (a.entity.rotation.to_array(), b.entity.rotation.to_array());
    let dot: f32 = qa.iter().zip(qb.iter()).map(|(x, y)| x * y).sum();
    a.kind == b.kind
        && a.entity.center == b.entity.center
        && a.entity.weights == b.entity.weights
        && libm::fabsf(dot) >= 1.0 - 1e-4
}

/// What a decoder returned for a stream: a digest of the accepted frames' bytes and the
/// counts of frames and refusals.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Outcome {
    digest: u32,
    frames: u64,
    refused: u64,
}

/// The wire decoder on `bytes` fed whole and fed in pieces of `piece` bytes (at least 1): the
/// same frames in the same order, and counters that agree with what came out.
pub fn wire_stream(bytes: &[u8], piece: usize) -> Result<(), Violation> {
    let whole = decode(bytes, bytes.len().max(1))?;
    let pieces = decode(bytes, piece.max(1))?;
    if whole != pieces {
        return Err(Violation::ChunkingChangedFrames);
    }
    Ok(())
}

fn decode(bytes: &[u8], piece: usize) -> Result<Outcome, Violation> {
    let mut decoder = Decoder::new();
    let mut outcome = Outcome {
        digest: 0,
        frames: 0,
        refused: 0,
    };
    for chunk in bytes.chunks(piece) {
        let mut window = chunk;
        loop {
            match decoder.feed(window) {
                Decoded::Consumed => break,
                Decoded::Frame { frame, remaining } => {
                    outcome.frames += 1;
                    outcome.digest = crc32(frame.into_inner()) ^ outcome.digest.rotate_left(5);
                    window = remaining;
                }
                Decoded::Rejected { remaining, .. } => {
                    outcome.refused += 1;
                    window = remaining;
                }
            }
        }
    }
    let stats = decoder.stats();
    if stats.accepted != outcome.frames
        || stats.rejected + stats.duplicates != outcome.refused
        || stats.bytes != bytes.len() as u64
    {
        return Err(Violation::CountersDisagree);
    }
    Ok(outcome)
}
