//! The one framing every frame on every line uses: a raw frame ends in the CRC-32 of the bytes
//! before it, is COBS-encoded so it holds no zero, and is followed by one `0x00` delimiter.
//!
//! [`seal`] writes a frame in that form; [`Deframer`] takes a byte stream in pieces of any size
//! and gives back each block between delimiters already COBS-decoded, in one pass over each
//! byte; [`check_crc`] then checks a raw frame's CRC and hands back what it protects. The sensor
//! frames ([`super::wire`]) and the host-device frames ([`super::frame`]) differ only in the
//! header inside.

use super::cobs::cobs_encode;
use super::crc32::crc32;

/// Bytes of the CRC-32 at the end of every raw frame.
pub const CRC_LEN: usize = 4;

/// Why a block is not a frame, before anything inside it is read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FramingError {
    /// More bytes than the longest frame before a delimiter.
    Oversized,
    /// The COBS block is malformed (a code pointing past its end).
    Cobs,
    /// Too short to hold a CRC and the header.
    Short { len: usize },
    /// The CRC does not match the bytes before it.
    Crc { stored: u32, computed: u32 },
}

impl core::fmt::Display for FramingError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Oversized => write!(f, "no delimiter within the longest frame"),
            Self::Cobs => write!(f, "malformed COBS block"),
            Self::Short { len } => write!(f, "a block of {len} bytes is too short for a frame"),
            Self::Crc { stored, computed } => write!(
                f,
                "CRC mismatch: stored {stored:08x}, computed {computed:08x}"
            ),
        }
    }
}

impl core::error::Error for FramingError {}

/// Writes the CRC-32 of `raw[..body_len]` after it, then the raw frame COBS-encoded into `out`
/// with its delimiter; returns the bytes to send, or `None` if `raw` or `out` is too short.
pub fn seal(raw: &mut [u8], body_len: usize, out: &mut [u8]) -> Option<usize> {
    let len = put_crc(raw, body_len)?;
    frame_raw(raw.get(..len)?, out)
}

/// Writes the CRC-32 of `raw[..body_len]` after it: the raw frame's length.
pub fn put_crc(raw: &mut [u8], body_len: usize) -> Option<usize> {
    let crc = crc32(raw.get(..body_len)?);
    raw.get_mut(body_len..body_len + CRC_LEN)?
        .copy_from_slice(&crc.to_le_bytes());
    Some(body_len + CRC_LEN)
}

/// A raw frame (its CRC in place) COBS-encoded into `out` with its delimiter: the bytes to send.
pub fn frame_raw(raw: &[u8], out: &mut [u8]) -> Option<usize> {
    let n = cobs_encode(raw, out)?;
    *out.get_mut(n)? = 0;
    Some(n + 1)
}

/// COBS-decodes one whole block (the bytes between two delimiters) in place: the raw frame,
/// for a caller that has the block already (a test, a capture cut at its delimiters).
pub fn decode_block(block: &mut [u8]) -> Result<&[u8], FramingError> {
    let n = super::cobs::cobs_decode_in_place(block).ok_or(FramingError::Cobs)?;
    Ok(block.get(..n).unwrap_or(&[]))
}

/// The CRC stored at the end of a raw frame and the one its bytes give.
pub fn crcs(raw: &[u8]) -> (u32, u32) {
    let body_len = raw.len().saturating_sub(CRC_LEN);
    let mut stored = [0u8; CRC_LEN];
    if let Some(tail) = raw.get(body_len..) {
        for (slot, b) in stored.iter_mut().zip(tail) {
            *slot = *b;
        }
    }
    let body = raw.get(..body_len).unwrap_or(&[]);
    (u32::from_le_bytes(stored), crc32(body))
}

/// The bytes a raw frame's CRC protects, if it holds at least `min_body` of them and its CRC
/// matches.
pub fn check_crc(raw: &[u8], min_body: usize) -> Result<&[u8], FramingError> {
    if raw.len() < min_body + CRC_LEN {
        return Err(FramingError::Short { len: raw.len() });
    }
    let (stored, computed) = crcs(raw);
    if stored != computed {
        return Err(FramingError::Crc { stored, computed });
    }
    Ok(raw.get(..raw.len() - CRC_LEN).unwrap_or(&[]))
}

/// What a delimiter ended.
#[derive(Debug, PartialEq, Eq)]
pub enum Block<'a> {
    /// Nothing since the last delimiter: idle line fill.
    Idle,
    /// A block, COBS-decoded: a raw frame if its CRC says so.
    Raw(&'a [u8]),
    /// Not a frame at all.
    Refused(FramingError),
}

/// A byte stream cut at its delimiters, each block COBS-decoded as its bytes arrive, in fixed
/// memory: `N` is the longest encoded block taken (a longer one is refused whole, to the next
/// delimiter). It takes and refuses exactly the blocks [`super::cobs::cobs_decode_in_place`]
/// does (tested on hostile input).
#[derive(Clone, Debug)]
pub struct Deframer<const N: usize> {
    /// The block so far, decoded (never longer than the encoded bytes, so `N` holds it).
    buf: [u8; N],
    /// Bytes of the block so far, encoded (what the oversize limit counts).
    len: usize,
    /// Decoded bytes of the block in `buf`.
    out: usize,
    /// Data bytes left in the block's current COBS group; 0: the next byte is a code.
    run: u8,
    /// The last code stands for a zero, written when another group follows it.
    zero: bool,
    /// The block outgrew `N`: bytes are dropped until the next delimiter.
    overflowed: bool,
}

impl<const N: usize> Default for Deframer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Deframer<N> {
    #[inline(always)]
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            out: 0,
            run: 0,
            zero: false,
            overflowed: false,
        }
    }

    /// Takes `input` up to its first delimiter and returns where that is (`None`: all of it was
    /// taken and no block ended); then [`Deframer::end_block`] says what the block was.
    // Out of line: inlined into the callers' frame checks, its state went to the stack.
    #[inline(never)]
    pub fn accumulate(&mut self, input: &[u8]) -> Option<usize> {
        let Self {
            buf,
            len,
            out,
            run,
            zero,
            overflowed,
        } = self;
        // The block's state in locals: stores into `buf` may alias the fields to the compiler.
        let (mut l, mut o, mut r, mut z) = (*len, *out, *run, *zero);
        let mut end = None;
        for (i, &byte) in input.iter().enumerate() {
            if byte == 0 {
                end = Some(i);
                break;
            }
            if l == N {
                *overflowed = true;
                continue;
            }
            l += 1;
            if r != 0 {
                r -= 1;
                if let Some(slot) = buf.get_mut(o) {
                    *slot = byte;
                    o += 1;
                }
            } else {
                // A code byte: the zero the previous code stood for, if any, then its data.
                if z && let Some(slot) = buf.get_mut(o) {
                    *slot = 0;
                    o += 1;
                }
                r = byte - 1;
                z = byte != 0xFF;
            }
        }
        (*len, *out, *run, *zero) = (l, o, r, z);
        end
    }

    /// After a delimiter: what the block before it was. The deframer starts the next block;
    /// the raw bytes stay readable ([`Deframer::raw`]) until the next [`Deframer::accumulate`].
    pub fn end_block(&mut self) -> Block<'_> {
        let (len, out, unfinished) = (self.len, self.out, self.run != 0);
        (self.len, self.out, self.run, self.zero) = (0, 0, 0, false);
        if core::mem::take(&mut self.overflowed) {
            return Block::Refused(FramingError::Oversized);
        }
        if len == 0 {
            return Block::Idle;
        }
        if unfinished {
            // The last code pointed past the block's end.
            return Block::Refused(FramingError::Cobs);
        }
        Block::Raw(self.buf.get(..out).unwrap_or(&[]))
    }

    /// The first `len` decoded bytes of the last block, while no new byte has been taken.
    pub fn raw(&self, len: usize) -> &[u8] {
        self.buf.get(..len).unwrap_or(&[])
    }

    /// Whether part of a block has been taken since the last delimiter.
    pub fn in_block(&self) -> bool {
        self.len != 0 || self.overflowed
    }

    /// Drops the block under way (after a reset of the line).
    pub fn clear(&mut self) {
        (self.len, self.out, self.run, self.zero, self.overflowed) = (0, 0, 0, false, false);
    }
}

#[cfg(test)]
mod tests {
    use super::super::cobs::cobs_decode_in_place;
    use super::*;
    use crate::test_support::{OrFail, TestResult};

    /// Each block of `input` through a deframer fed in pieces of `piece`, and through the
    /// plain in-place decoder: the same raw frames, and the same refusals.
    fn agree(input: &[u8], piece: usize) -> TestResult {
        let mut d = Deframer::<64>::new();
        let mut blocks = input.split(|&b| b == 0);
        let mut ended = 0;
        for mut chunk in input.chunks(piece) {
            while let Some(i) = d.accumulate(chunk) {
                chunk = chunk.get(i + 1..).or_fail("rest")?;
                ended += 1;
                let block = blocks.next().or_fail("a block")?;
                let mut copy = [0u8; 64];
                let expected = match block.len() {
                    0 => Block::Idle,
                    65.. => Block::Refused(FramingError::Oversized),
                    n => {
                        let b = copy.get_mut(..n).or_fail("room")?;
                        b.copy_from_slice(block);
                        match cobs_decode_in_place(b) {
                            Some(m) => Block::Raw(copy.get(..m).or_fail("raw")?),
                            None => Block::Refused(FramingError::Cobs),
                        }
                    }
                };
                assert_eq!(d.end_block(), expected);
            }
        }
        assert_eq!(ended, input.iter().filter(|&&b| b == 0).count());
        Ok(())
    }

    #[test]
    fn deframes_as_the_in_place_decoder_on_hostile_input() -> TestResult {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut input = [0u8; 4000];
        for b in input.iter_mut() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            // Zeros often enough for short blocks, runs of 0xFF codes too.
            *b = match state % 16 {
                0 | 1 => 0,
                2 => 0xFF,
                _ => (state >> 8) as u8,
            };
        }
        for piece in [1, 3, 17, 4000] {
            agree(&input, piece)?;
        }
        Ok(())
    }

    #[test]
    fn sealed_frames_come_back_checked() -> TestResult {
        let mut raw = [0u8; 16];
        raw[..6].copy_from_slice(&[1, 0, 2, 0, 0, 3]);
        let mut wire = [0u8; 32];
        let n = seal(&mut raw, 6, &mut wire).or_fail("seals")?;
        assert_eq!(wire[n - 1], 0);
        assert!(!wire[..n - 1].contains(&0));
        let mut d = Deframer::<32>::new();
        assert_eq!(d.accumulate(&wire[..n]), Some(n - 1));
        let Block::Raw(block) = d.end_block() else {
            return Err("a block");
        };
        assert_eq!(check_crc(block, 6), Ok(&[1, 0, 2, 0, 0, 3][..]));
        assert!(matches!(
            check_crc(block, 7),
            Err(FramingError::Short { .. })
        ));
        let mut bad = [0u8; 10];
        bad.copy_from_slice(block);
        bad[2] ^= 4;
        assert!(matches!(check_crc(&bad, 6), Err(FramingError::Crc { .. })));
        Ok(())
    }

    #[test]
    fn an_overlong_block_is_refused_to_the_next_delimiter() -> TestResult {
        let mut d = Deframer::<8>::new();
        assert_eq!(d.accumulate(&[5; 20]), None);
        assert_eq!(d.accumulate(&[5, 0, 2, 7, 0]), Some(1));
        assert_eq!(d.end_block(), Block::Refused(FramingError::Oversized));
        assert_eq!(d.accumulate(&[2, 7, 0]), Some(2));
        assert_eq!(d.end_block(), Block::Raw(&[7]));
        Ok(())
    }
}
