//! A byte-at-a-time frame decoder: feed it whatever slice the UART delivered, from one byte to
//! kilobytes, and it hands back each frame with the unconsumed rest of the input.

use super::{Frame, FrameError, MAX_FRAME_LEN};
use crate::link::framing::{Block, Deframer, FramingError};

/// Counters for every outcome, so a link's health can be reported.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecoderStats {
    pub bytes: u64,
    pub accepted: u64,
    /// Frames refused (CRC, COBS, length, version or kind, reserved bits, oversize, unit, pose).
    pub rejected: u64,
    pub bad_crc: u64,
    pub bad_cobs: u64,
    pub bad_length: u64,
    pub bad_version: u64,
    pub oversized: u64,
    /// Frames whose unit exponent is outside the range a receiver takes.
    pub bad_unit: u64,
    /// Pose frames numbered 0, with points, or whose quaternion is not a unit one.
    pub bad_pose: u64,
    /// Valid frames that repeat the last accepted one, sequence number and CRC (not counted as
    /// rejected).
    pub duplicates: u64,
    /// Frames never seen: gaps in the sequence numbers of accepted frames.
    pub lost: u64,
    /// Sessions begun: the first frame, a version 2 frame flagged session start, and every
    /// frame that shows the sender started again (a sequence number behind the last, or the
    /// same one on other content, or a jump of more than [`MAX_GAP`] frames).
    pub sessions: u64,
}

/// The longest run of lost frames counted as lost: a jump further ahead is taken for a sender
/// that started again (the protocol lets a sender start its sequence anywhere), not for 2^31
/// lost frames. 65,535 frames of [`MAX_POINTS`](super::MAX_POINTS) points are 102 MB, over 18
/// minutes of a 921,600-baud link.
pub const MAX_GAP: u32 = 0xFFFF;

/// What one call to [`Decoder::feed`] produced. Every variant but `Consumed` carries the rest of
/// the input, to be fed next.
#[derive(Debug)]
pub enum Decoded<'d, 'i> {
    /// All input was taken; no frame ended in it.
    Consumed,
    Frame {
        frame: Frame<&'d [u8]>,
        remaining: &'i [u8],
    },
    Rejected {
        error: FrameError,
        remaining: &'i [u8],
    },
}

/// The link's deframer plus frame validation and sequence tracking, in fixed memory.
///
/// Blocks are COBS-decoded as their bytes arrive ([`Deframer`]): one pass over each byte rather
/// than a copy and then a decode in place (a third of the firmware's cost per point beside
/// the mapper, once its placement took no soft float).
#[derive(Clone, Debug)]
pub struct Decoder {
    blocks: Deframer<MAX_FRAME_LEN>,
    /// Sequence number and CRC of the last accepted frame: a repeat matches both.
    last: Option<(u32, u32)>,
    /// Length of the frame last returned, still in `buf` until the next `feed` (0: none).
    held: usize,
    stats: DecoderStats,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder {
    #[inline(always)]
    pub const fn new() -> Self {
        Self {
            blocks: Deframer::new(),
            last: None,
            held: 0,
            stats: DecoderStats {
                bytes: 0,
                accepted: 0,
                rejected: 0,
                bad_crc: 0,
                bad_cobs: 0,
                bad_length: 0,
                bad_version: 0,
                oversized: 0,
                bad_unit: 0,
                bad_pose: 0,
                duplicates: 0,
                lost: 0,
                sessions: 0,
            },
        }
    }

    pub const fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// The frame the last [`Decoder::feed`] returned, until the next `feed` overwrites it: a
    /// caller can map its points over several calls without a copy of its own.
    pub fn held_frame(&self) -> Option<Frame<&[u8]>> {
        match self.held {
            0 => None,
            len => Some(Frame::new_unchecked(self.blocks.raw(len))),
        }
    }

    /// Takes bytes until a frame ends (delimiter) or the input runs out.
    pub fn feed<'d, 'i>(&'d mut self, input: &'i [u8]) -> Decoded<'d, 'i> {
        self.held = 0;
        // Bytes before `counted` are in the stats already (idle delimiters skipped in place:
        // recursing once per idle byte overflowed a small stack on a run of zeros).
        let mut counted = 0;
        loop {
            let rest = input.get(counted..).unwrap_or(&[]);
            let Some(at) = self.blocks.accumulate(rest) else {
                self.stats.bytes += rest.len() as u64;
                return Decoded::Consumed;
            };
            let remaining = rest.get(at + 1..).unwrap_or(&[]);
            self.stats.bytes += (at + 1) as u64;
            counted += at + 1;
            let raw = match self.blocks.end_block() {
                // Back-to-back delimiters: idle line fill, not a frame.
                Block::Idle => continue,
                Block::Raw(raw) => raw,
                Block::Refused(FramingError::Oversized) => {
                    return self.reject(FrameError::Oversized, remaining);
                }
                Block::Refused(_) => return self.reject(FrameError::BadCobs, remaining),
            };
            let raw_len = raw.len();
            let frame = match Frame::new_checked(raw) {
                Ok(frame) => frame,
                Err(error) => return self.reject(error, remaining),
            };
            let (sequence, crc) = (frame.sequence(), frame.stored_crc());
            match self.last {
                Some(last) if last == (sequence, crc) => {
                    self.stats.duplicates += 1;
                    return Decoded::Rejected {
                        error: FrameError::Duplicate { sequence },
                        remaining,
                    };
                }
                Some(_) if frame.session_start() => self.stats.sessions += 1,
                Some((last, _)) => {
                    // A serial link neither reorders nor replays old frames: a number behind
                    // the last, the last number on other content, or a long jump means the
                    // sender started again, and its frames are as good as the first session's.
                    let ahead = sequence.wrapping_sub(last);
                    if ahead == 0 || ahead > MAX_GAP {
                        self.stats.sessions += 1;
                    } else {
                        self.stats.lost += u64::from(ahead - 1);
                    }
                }
                None => self.stats.sessions += 1,
            }
            self.last = Some((sequence, crc));
            self.stats.accepted += 1;
            self.held = raw_len;
            return Decoded::Frame {
                frame: Frame::new_unchecked(self.blocks.raw(raw_len)),
                remaining,
            };
        }
    }

    fn reject<'d, 'i>(&'d mut self, error: FrameError, remaining: &'i [u8]) -> Decoded<'d, 'i> {
        let s = &mut self.stats;
        s.rejected += 1;
        match error {
            FrameError::BadCrc { .. } => s.bad_crc += 1,
            FrameError::BadCobs => s.bad_cobs += 1,
            FrameError::Oversized => s.oversized += 1,
            FrameError::UnsupportedVersion { .. }
            | FrameError::UnknownKind { .. }
            | FrameError::Reserved => s.bad_version += 1,
            FrameError::BadPose => s.bad_pose += 1,
            FrameError::UnitOutOfRange { .. } => s.bad_unit += 1,
            FrameError::Truncated { .. }
            | FrameError::LengthMismatch { .. }
            | FrameError::TooManyPoints { .. } => s.bad_length += 1,
            FrameError::Duplicate { .. } => {}
        }
        Decoded::Rejected { error, remaining }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::cobs::cobs_encode;
    use crate::link::wire::{FrameRepr, MAX_RAW_LEN};
    use crate::test_support::{OrFail, TestResult};

    /// Encodes frames 0..n with a few points each into `out`; returns the length.
    fn stream(n: u32, out: &mut [u8]) -> Result<usize, &'static str> {
        stream_from(0, n, out)
    }

    /// Encodes `n` frames numbered from `first` (wrapping) into `out`; returns the length.
    fn stream_from(first: u32, n: u32, out: &mut [u8]) -> Result<usize, &'static str> {
        let mut at = 0;
        for seq in (0..n).map(|i| first.wrapping_add(i)) {
            let pts = [[seq as i32, 2, 3], [4, 5, seq as i32 * 1000]];
            let repr = FrameRepr {
                sequence: seq,
                end_of_stream: seq.wrapping_add(1) == first.wrapping_add(n),
                unit_exponent: -3,
                points: &pts,
            };
            let mut raw = [0u8; MAX_RAW_LEN];
            let len = repr.emit(&mut raw).or_fail("emit")?;
            at += cobs_encode(&raw[..len], out.get_mut(at..).or_fail("room")?).or_fail("encode")?;
            *out.get_mut(at).or_fail("room")? = 0;
            at += 1;
        }
        Ok(at)
    }

    /// Feeds `input` in chunks of `chunk` bytes; returns the sequence numbers decoded.
    fn decode_all(d: &mut Decoder, input: &[u8], chunk: usize, seqs: &mut [u32; 64]) -> usize {
        let mut found = 0;
        for piece in input.chunks(chunk.max(1)) {
            let mut window = piece;
            loop {
                match d.feed(window) {
                    Decoded::Consumed => break,
                    Decoded::Frame { frame, remaining } => {
                        if let Some(slot) = seqs.get_mut(found) {
                            *slot = frame.sequence();
                            found += 1;
                        }
                        window = remaining;
                    }
                    Decoded::Rejected { remaining, .. } => window = remaining,
                }
            }
        }
        found
    }

    /// A sender's sequence numbers crossing their wrap are one session, nothing lost.
    #[test]
    fn sequence_numbers_across_their_wrap() -> TestResult {
        let mut wire = [0u8; 2048];
        let n = stream_from(u32::MAX - 9, 20, &mut wire)?;
        let mut d = Decoder::new();
        let mut seqs = [0u32; 64];
        assert_eq!(decode_all(&mut d, &wire[..n], 5, &mut seqs), 20);
        for (i, &s) in seqs[..20].iter().enumerate() {
            assert_eq!(s, (u32::MAX - 9).wrapping_add(i as u32));
        }
        let stats = d.stats();
        assert_eq!((stats.accepted, stats.lost, stats.sessions), (20, 0, 1));
        Ok(())
    }

    #[test]
    fn same_frames_whatever_the_chunking() -> TestResult {
        let mut wire = [0u8; 2048];
        let n = stream(20, &mut wire)?;
        for chunk in [1, 2, 3, 7, 64, 4096] {
            let mut d = Decoder::new();
            let mut seqs = [0u32; 64];
            assert_eq!(
                decode_all(&mut d, &wire[..n], chunk, &mut seqs),
                20,
                "chunk {chunk}"
            );
            assert!(seqs[..20].iter().enumerate().all(|(i, &s)| s == i as u32));
            assert_eq!(d.stats().accepted, 20);
            assert_eq!(d.stats().bytes, n as u64);
        }
        Ok(())
    }

    /// A line idling at zero for a long time is skipped in place and counted once (it once
    /// recursed per idle byte, and 512 zeros overflowed a 256 KiB stack in a debug build; the
    /// test profile's optimiser turns that tail call into a loop, so this checks the counts).
    #[test]
    fn a_long_idle_run_takes_constant_stack() -> TestResult {
        static ZEROS: [u8; 1 << 20] = [0; 1 << 20];
        let mut wire = [0u8; 2048];
        let n = stream(2, &mut wire)?;
        let mut d = Decoder::new();
        assert!(matches!(d.feed(&ZEROS), Decoded::Consumed));
        assert_eq!(d.stats().bytes, ZEROS.len() as u64);
        let mut seqs = [0u32; 64];
        assert_eq!(decode_all(&mut d, &wire[..n], n, &mut seqs), 2);
        assert_eq!(d.stats().bytes, (ZEROS.len() + n) as u64);
        Ok(())
    }

    #[test]
    fn resyncs_after_garbage_counts_gaps_and_repeats() -> TestResult {
        let mut wire = [0u8; 2048];
        let n = stream(6, &mut wire)?;
        // Garbage first, then the sender's leading delimiter (PROTOCOL.md: a sender starts with
        // 0x00 so a receiver that saw noise resyncs before frame 0), then frames 0..6 with
        // frame 2 sent twice and frame 4 cut out.
        let mut input = [0u8; 4096];
        let mut at = 0;
        for b in [0x13u8, 0x77, 0x01, 0xFF, 0x42, 0x00] {
            input[at] = b;
            at += 1;
        }
        let mut starts = [0usize; 7];
        let mut k = 1;
        for (i, &b) in wire[..n].iter().enumerate() {
            if b == 0 && k < 7 {
                starts[k] = i + 1;
                k += 1;
            }
        }
        for frame in [0usize, 1, 2, 2, 3, 5] {
            let bytes = &wire[starts[frame]..starts[frame + 1]];
            input[at..at + bytes.len()].copy_from_slice(bytes);
            at += bytes.len();
        }
        let mut d = Decoder::new();
        let mut seqs = [0u32; 64];
        let found = decode_all(&mut d, &input[..at], 5, &mut seqs);
        assert_eq!(&seqs[..found], &[0, 1, 2, 3, 5]);
        let s = d.stats();
        assert_eq!((s.accepted, s.duplicates, s.lost, s.rejected), (5, 1, 1, 1));
        // Without the leading delimiter the noise runs into frame 0, which is then refused.
        let mut no_delimiter = [0u8; 4096];
        no_delimiter[..5].copy_from_slice(&input[..5]);
        no_delimiter[5..at - 1].copy_from_slice(&input[6..at]);
        let mut d = Decoder::new();
        let found = decode_all(&mut d, &no_delimiter[..at - 1], 5, &mut seqs);
        assert_eq!(&seqs[..found], &[1, 2, 3, 5]);
        assert_eq!(d.stats().rejected, 1);
        Ok(())
    }

    /// Frames `sequences[i]` with points that differ per position `i`, framed back to back.
    fn frames_numbered(sequences: &[u32], out: &mut [u8]) -> Result<usize, &'static str> {
        let mut at = 0;
        for (i, &seq) in sequences.iter().enumerate() {
            let pts = [[i as i32, 7, -3]];
            let repr = FrameRepr {
                sequence: seq,
                end_of_stream: i + 1 == sequences.len(),
                unit_exponent: -3,
                points: &pts,
            };
            let mut raw = [0u8; MAX_RAW_LEN];
            let len = repr.emit(&mut raw).or_fail("emit")?;
            let room = out.get_mut(at..).or_fail("room")?;
            at += cobs_encode(raw.get(..len).or_fail("raw")?, room).or_fail("encode")?;
            *out.get_mut(at).or_fail("room")? = 0;
            at += 1;
        }
        Ok(at)
    }

    /// A sender that resets starts its sequence again (PROTOCOL.md lets it start anywhere):
    /// its frames are a new session and are used, never taken for repeats. Only an exact
    /// repeat of the last frame is one.
    #[test]
    fn a_sender_that_starts_again_is_a_new_session() -> TestResult {
        // 0..5, a repeat of 4 (same bytes), then the reset: 0..5 again, on other points.
        let mut sequences = [0u32; 11];
        for (i, s) in sequences.iter_mut().enumerate() {
            *s = [0, 1, 2, 3, 4, 4, 0, 1, 2, 3, 4][i];
        }
        let mut wire = [0u8; 1024];
        let n = frames_numbered(&sequences, &mut wire)?;
        let mut d = Decoder::new();
        let mut seqs = [0u32; 64];
        let found = decode_all(&mut d, wire.get(..n).or_fail("wire")?, 5, &mut seqs);
        // Position 5 carries other points than position 4, so it is a sender that went back to
        // 4 on new content: a new session, as is the return to 0.
        assert_eq!(found, 11);
        let s = d.stats();
        assert_eq!(
            (s.accepted, s.duplicates, s.lost, s.sessions),
            (11, 0, 0, 3)
        );

        // The same bytes twice in a row are a repeat, used once.
        let mut twice = [0u8; 1024];
        let one = frames_numbered(&[9], &mut twice)?;
        let (first, rest) = twice.split_at_mut(one);
        rest.get_mut(..one).or_fail("room")?.copy_from_slice(first);
        let mut d = Decoder::new();
        let found = decode_all(&mut d, twice.get(..2 * one).or_fail("twice")?, 3, &mut seqs);
        assert_eq!(found, 1);
        let s = d.stats();
        assert_eq!((s.accepted, s.duplicates, s.sessions), (1, 1, 1));
        Ok(())
    }

    /// One valid frame numbered far ahead mid-stream once made the next 300 frames repeats,
    /// and counted 2^31 lost frames: a jump past MAX_GAP is a new session, and so is the return.
    #[test]
    fn a_far_jump_drops_nothing() -> TestResult {
        let mut sequences = [0u32; 311];
        for (i, s) in sequences.iter_mut().enumerate() {
            *s = match i {
                0..10 => i as u32,
                10 => 0x7fff_fff0,
                _ => i as u32 - 1,
            };
        }
        let mut wire = [0u8; 311 * 40];
        let n = frames_numbered(&sequences, &mut wire)?;
        let mut d = Decoder::new();
        let mut seqs = [0u32; 64];
        decode_all(&mut d, wire.get(..n).or_fail("wire")?, 97, &mut seqs);
        let s = d.stats();
        assert_eq!(
            (s.accepted, s.duplicates, s.lost, s.sessions),
            (311, 0, 0, 3)
        );
        // A real gap within MAX_GAP is lost frames, in one session.
        let mut d = Decoder::new();
        let n = frames_numbered(&[5, 6, 6 + MAX_GAP], &mut wire)?;
        decode_all(&mut d, wire.get(..n).or_fail("wire")?, 97, &mut seqs);
        let s = d.stats();
        assert_eq!(
            (s.accepted, s.lost, s.sessions),
            (3, u64::from(MAX_GAP) - 1, 1)
        );
        Ok(())
    }

    #[test]
    fn an_endless_block_is_dropped_not_jammed() -> TestResult {
        let mut d = Decoder::new();
        let noise = [0x55u8; MAX_FRAME_LEN + 10];
        assert!(matches!(d.feed(&noise), Decoded::Consumed));
        assert!(matches!(
            d.feed(&[0]),
            Decoded::Rejected {
                error: FrameError::Oversized,
                ..
            }
        ));
        let mut wire = [0u8; 512];
        let n = stream(1, &mut wire)?;
        let mut seqs = [0u32; 64];
        assert_eq!(decode_all(&mut d, &wire[..n], 4096, &mut seqs), 1);
        Ok(())
    }
}
