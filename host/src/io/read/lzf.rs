//! LZF decompression (Marc Lehmann's liblzf format, as PCL's `DATA binary_compressed` uses).
//!
//! The stream is a sequence of chunks, each starting with a control byte `c`:
//! - `c < 32`: a literal run; the next `c + 1` bytes are copied to the output.
//! - otherwise a back reference: `len = c >> 5`, and if `len == 7` one more byte is added to it;
//!   then one byte `lo` gives the distance `((c & 0x1f) << 8 | lo) + 1` back from the end of the
//!   output, from where `len + 2` bytes are copied (the source may overlap the bytes being
//!   written, which repeats a pattern).
//!
//! Every length and distance comes from the file, so each is checked before use: corrupt input
//! is an [`LzfError`], never a panic or an out-of-bounds read.

use std::fmt;

/// The most output one input byte can produce: a 3-byte back reference copies up to 264 bytes.
pub(super) const MAX_EXPANSION: usize = 88;

/// The farthest back a reference reaches: 13 bits of distance, plus one.
pub(super) const MAX_DISTANCE: usize = 1 << 13;

/// The longest chunk in the input: a control byte and a 32-byte literal run.
pub(crate) const MAX_CHUNK: usize = 33;

/// The most output one chunk produces: a back reference of 7 + 255 + 2 bytes.
const MAX_CHUNK_OUT: usize = 264;

/// The output held at a time: the history a back reference may reach, plus the new output
/// between two hand-overs to the sink (24 KiB of it here; smaller means more sliding).
pub(super) const WINDOW: usize = 32 * 1024;

/// Why an LZF stream could not be decompressed; `at` is the offset in the compressed input.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum LzfError {
    /// The declared output is larger than any stream of this length could produce.
    CannotExpand { input: usize, expected: usize },
    /// A literal run or back reference reads past the end of the input.
    InputEnds { at: usize },
    /// A back reference points before the start of the output.
    BeforeStart {
        at: usize,
        distance: usize,
        produced: usize,
    },
    /// The stream produces more than the declared output size.
    TooLong { at: usize, expected: usize },
    /// The stream ends before producing the declared output size.
    TooShort { produced: usize, expected: usize },
}

impl LzfError {
    /// Offset in the compressed input where the problem was found.
    pub fn at(&self) -> usize {
        match *self {
            LzfError::CannotExpand { .. } | LzfError::TooShort { .. } => 0,
            LzfError::InputEnds { at }
            | LzfError::BeforeStart { at, .. }
            | LzfError::TooLong { at, .. } => at,
        }
    }
}

impl fmt::Display for LzfError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            LzfError::CannotExpand { input, expected } => write!(
                f,
                "{input} compressed bytes cannot expand to the declared {expected} bytes"
            ),
            LzfError::InputEnds { at } => {
                write!(
                    f,
                    "LZF chunk at compressed byte {at} runs past the end of the data"
                )
            }
            LzfError::BeforeStart {
                at,
                distance,
                produced,
            } => write!(
                f,
                "LZF back reference at compressed byte {at} reaches {distance} bytes back, \
                 but only {produced} are decompressed"
            ),
            LzfError::TooLong { at, expected } => write!(
                f,
                "LZF data at compressed byte {at} decompresses past the declared {expected} bytes"
            ),
            LzfError::TooShort { produced, expected } => write!(
                f,
                "LZF data decompresses to {produced} bytes, the header declares {expected}"
            ),
        }
    }
}

/// Decompresses a stream fed in pieces of any size, handing the output to a sink in order and
/// holding only the last [`WINDOW`] bytes of it: no back reference reaches farther than
/// 8 KiB, so the whole output never needs to exist at once.
pub(crate) struct Decoder {
    /// The tail of the output: at least the last `MAX_DISTANCE` bytes produced (or all of them).
    window: Vec<u8>,
    /// Output offset of `window[0]`.
    base: usize,
    /// `window[..sent]` has been handed to the sink.
    sent: usize,
    expected: usize,
    /// Compressed bytes decoded so far.
    at: usize,
}

impl Decoder {
    /// A decoder for `packed` compressed bytes that must produce exactly `expected` bytes.
    pub fn new(packed: usize, expected: usize) -> Result<Self, LzfError> {
        if expected > packed.saturating_mul(MAX_EXPANSION) {
            return Err(LzfError::CannotExpand {
                input: packed,
                expected,
            });
        }
        Ok(Decoder {
            window: Vec::with_capacity(expected.min(WINDOW)),
            base: 0,
            sent: 0,
            expected,
            at: 0,
        })
    }

    fn produced(&self) -> usize {
        self.base + self.window.len()
    }

    /// Hands the new output to `sink` (with its output offset) and slides the window.
    fn flush(&mut self, sink: &mut impl FnMut(usize, &[u8])) {
        let fresh = self.window.get(self.sent..).unwrap_or_default();
        if !fresh.is_empty() {
            sink(self.base + self.sent, fresh);
        }
        let keep = self.window.len().min(MAX_DISTANCE);
        let drop = self.window.len() - keep;
        self.window.copy_within(drop.., 0);
        self.window.truncate(keep);
        self.base += drop;
        self.sent = keep;
    }

    /// Decodes the whole chunks at the start of `input` and returns how many bytes they took.
    /// With `last`, `input` is the rest of the stream and a chunk it cuts short is an error;
    /// otherwise the cut chunk is left for the next call, which must start with it.
    pub fn feed(
        &mut self,
        input: &[u8],
        last: bool,
        sink: &mut impl FnMut(usize, &[u8]),
    ) -> Result<usize, LzfError> {
        let mut ip = 0;
        while let Some(&ctrl) = input.get(ip) {
            let at = self.at + ip;
            let ctrl = usize::from(ctrl);
            // A chunk cut by the end of `input` waits for the next piece, unless there is none.
            let cut = || {
                if last {
                    Err(LzfError::InputEnds { at })
                } else {
                    Ok(())
                }
            };
            if self.window.len() + MAX_CHUNK_OUT > WINDOW {
                self.flush(sink);
            }
            let expected = self.expected;
            if ctrl < 32 {
                let Some(run) = input.get(ip + 1..ip + 2 + ctrl) else {
                    cut()?;
                    break;
                };
                if self.produced() + run.len() > expected {
                    return Err(LzfError::TooLong { at, expected });
                }
                self.window.extend_from_slice(run);
                ip += 2 + ctrl;
            } else {
                let long = ctrl >> 5 == 7;
                let size = if long { 3 } else { 2 };
                let Some(chunk) = input.get(ip..ip + size) else {
                    cut()?;
                    break;
                };
                let (extra, lo) = match chunk {
                    [_, e, lo] => (usize::from(*e), usize::from(*lo)),
                    [_, lo] => (0, usize::from(*lo)),
                    _ => return Err(LzfError::InputEnds { at }),
                };
                let len = (ctrl >> 5) + extra + 2;
                let distance = ((ctrl & 0x1f) << 8 | lo) + 1;
                let produced = self.produced();
                // The window holds min(produced, MAX_DISTANCE) bytes or more, and a distance
                // is at most MAX_DISTANCE: reaching before the window means before the start.
                let start =
                    self.window
                        .len()
                        .checked_sub(distance)
                        .ok_or(LzfError::BeforeStart {
                            at,
                            distance,
                            produced,
                        })?;
                if produced + len > expected {
                    return Err(LzfError::TooLong { at, expected });
                }
                // Copy in pieces no longer than what already exists past `start`: for an
                // overlapping reference this repeats the pattern exactly as a byte-by-byte
                // copy would, and every range stays inside the window.
                let mut left = len;
                while left > 0 {
                    let piece = left.min(self.window.len() - start);
                    self.window.extend_from_within(start..start + piece);
                    left -= piece;
                }
                ip += size;
            }
        }
        self.at += ip;
        Ok(ip)
    }

    /// Hands the rest of the output to `sink`; the stream must have produced all of it.
    pub fn finish(mut self, sink: &mut impl FnMut(usize, &[u8])) -> Result<(), LzfError> {
        if self.produced() != self.expected {
            return Err(LzfError::TooShort {
                produced: self.produced(),
                expected: self.expected,
            });
        }
        self.flush(sink);
        Ok(())
    }
}

/// Decompresses a whole stream held in memory.
#[cfg(test)]
pub(crate) fn decompress(input: &[u8], expected: usize) -> Result<Vec<u8>, LzfError> {
    let mut out = Vec::new();
    let mut sink = |at: usize, bytes: &[u8]| {
        assert_eq!(at, out.len(), "the sink gets the output in order");
        out.extend_from_slice(bytes);
    };
    let mut decoder = Decoder::new(input.len(), expected)?;
    decoder.feed(input, true, &mut sink)?;
    decoder.finish(&mut sink)?;
    Ok(out)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A valid LZF stream of literal runs only: what a compressor may emit for data it cannot
    /// shrink, and enough for tests to write binary_compressed files without a compressor.
    pub fn literal_stream(data: &[u8]) -> Vec<u8> {
        let run = |c: &[u8]| [&[c.len() as u8 - 1][..], c].concat();
        data.chunks(32).flat_map(run).collect()
    }

    #[test]
    fn literal_streams_round_trip() {
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7919 % 251) as u8).collect();
        assert_eq!(
            decompress(&literal_stream(&data), data.len()).unwrap(),
            data
        );
    }

    /// The format as its documentation states it, with the whole output in memory and one
    /// byte copied at a time: the reference the windowed decoder is checked against.
    fn naive(input: &[u8]) -> Vec<u8> {
        let (mut out, mut ip) = (Vec::new(), 0);
        while ip < input.len() {
            let ctrl = usize::from(input[ip]);
            if ctrl < 32 {
                out.extend_from_slice(&input[ip + 1..ip + 2 + ctrl]);
                ip += 2 + ctrl;
            } else {
                let (mut len, mut at) = (ctrl >> 5, ip + 1);
                if len == 7 {
                    len += usize::from(input[at]);
                    at += 1;
                }
                let from = out.len() - (((ctrl & 0x1f) << 8 | usize::from(input[at])) + 1);
                (0..len + 2).for_each(|i| out.push(out[from + i]));
                ip = at + 1;
            }
        }
        out
    }

    /// The LZF stream of a shared binary_compressed PCD and its declared output size.
    fn real_stream(name: &str) -> (Vec<u8>, usize) {
        let bytes = super::super::testkit::shared(name);
        let tag = b"binary_compressed\n";
        let body = bytes.windows(tag.len()).position(|w| w == tag).unwrap() + tag.len();
        let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        let (packed, unpacked) = (word(body), word(body + 4));
        (bytes[body + 8..body + 8 + packed].to_vec(), unpacked)
    }

    /// Real streams whose output is far longer than the window (back references then reach
    /// into history that has slid), fed in seeded random pieces from 1 byte to 64 KiB: the same
    /// bytes as the reference, handed over in order.
    #[test]
    fn windowed_decoding_in_any_pieces_equals_the_reference() {
        let mut rng = super::super::testkit::XorShift(0x5eed);
        for name in ["five_people.pcd", "cturtle.pcd", "car6.pcd"] {
            let (stream, expected) = real_stream(name);
            let want = naive(&stream);
            assert_eq!(want.len(), expected, "{name}");
            assert!(expected > 4 * WINDOW || name == "car6.pcd", "{name}");
            assert_eq!(decompress(&stream, expected).unwrap(), want, "{name} whole");
            for round in 0..3 {
                let mut out = Vec::new();
                let mut sink = |at: usize, bytes: &[u8]| {
                    assert_eq!(at, out.len());
                    out.extend_from_slice(bytes);
                };
                let mut decoder = Decoder::new(stream.len(), expected).unwrap();
                let (mut pending, mut fed) = (Vec::new(), 0);
                while fed < stream.len() {
                    let size = 1 + rng.below(if round == 0 { 40 } else { 1 << 16 });
                    let end = (fed + size).min(stream.len());
                    pending.extend_from_slice(&stream[fed..end]);
                    fed = end;
                    let last = fed == stream.len();
                    let used = decoder.feed(&pending, last, &mut sink).unwrap();
                    pending.drain(..used);
                }
                assert!(pending.is_empty(), "{name}");
                decoder.finish(&mut sink).unwrap();
                assert!(out == want, "{name} round {round}");
            }
        }
    }

    #[test]
    fn literal_run() {
        assert_eq!(decompress(&[2, b'a', b'b', b'c'], 3).unwrap(), b"abc");
    }

    #[test]
    fn overlapping_back_reference_repeats_the_pattern() {
        // "ab", then copy 2 + 2 = 4 bytes from 2 back: "ababab".
        assert_eq!(decompress(&[1, b'a', b'b', 0x40, 1], 6).unwrap(), b"ababab");
        // One byte repeated: distance 1, length 7 + 3 + 2 = 12 via the extra length byte.
        let mut want = vec![b'z'; 13];
        assert_eq!(decompress(&[0, b'z', 0xe0, 3, 0], 13).unwrap(), want);
        want.truncate(4);
        assert_eq!(decompress(&[0, b'z', 0x20, 0], 4).unwrap(), want);
    }

    #[test]
    fn non_overlapping_back_reference() {
        // "abcd" then copy 3 bytes from 4 back: "abcdabc".
        assert_eq!(
            decompress(&[3, b'a', b'b', b'c', b'd', 0x20, 3], 7).unwrap(),
            b"abcdabc"
        );
    }

    #[test]
    fn longest_back_reference_reaches_the_expansion_bound() {
        // 3 input bytes after the literal produce 264 bytes; the whole stream is 5 bytes.
        let out = decompress(&[0, b'q', 0xe0, 255, 0], 265).unwrap();
        assert_eq!(out, vec![b'q'; 265]);
    }

    #[test]
    fn corrupt_streams_are_errors() {
        assert_eq!(
            decompress(&[5, b'a'], 6),
            Err(LzfError::InputEnds { at: 0 })
        );
        assert_eq!(
            decompress(&[0, b'a', 0x20, 5], 4),
            Err(LzfError::BeforeStart {
                at: 2,
                distance: 6,
                produced: 1
            })
        );
        assert_eq!(
            decompress(&[0, b'a', 0xe0], 9),
            Err(LzfError::InputEnds { at: 2 })
        );
        assert_eq!(
            decompress(&[0, b'a', 0xe0, 1], 9),
            Err(LzfError::InputEnds { at: 2 })
        );
        assert_eq!(
            decompress(&[2, b'a', b'b', b'c'], 2),
            Err(LzfError::TooLong { at: 0, expected: 2 })
        );
        assert_eq!(
            decompress(&[0, b'a', 0x20, 0], 2),
            Err(LzfError::TooLong { at: 2, expected: 2 })
        );
        assert_eq!(
            decompress(&[2, b'a', b'b', b'c'], 4),
            Err(LzfError::TooShort {
                produced: 3,
                expected: 4
            })
        );
        assert_eq!(
            decompress(&[0, 0], 1_000_000),
            Err(LzfError::CannotExpand {
                input: 2,
                expected: 1_000_000
            })
        );
        assert_eq!(decompress(&[], 0), Ok(Vec::new()));
    }

    #[test]
    fn every_corruption_of_a_small_stream_is_handled() {
        let good = [
            3, b'a', b'b', b'c', b'd', 0x20, 3, 0xe0, 10, 0, 1, b'x', b'y',
        ];
        let expected = decompress(&good, 4 + 3 + 19 + 2).unwrap().len();
        for i in 0..good.len() {
            for v in 0..=255u8 {
                let mut bad = good;
                bad[i] = v;
                let _ = decompress(&bad, expected);
            }
            let _ = decompress(&good[..i], expected);
        }
    }

    /// Damage to car6.pcd's LZF stream is a `BadValue` at an offset, never a panic.
    #[test]
    fn corrupt_pcd_stream_is_a_bad_value() {
        use super::super::testkit::shared;
        use super::super::{At, ReadError, read_cloud_bytes};
        let good = shared("car6.pcd");
        let body = good
            .windows(18)
            .position(|w| w == b"binary_compressed\n")
            .unwrap()
            + 18;
        let stream = body + 8;
        let read = |bytes: &[u8]| read_cloud_bytes("car6.pcd", bytes);
        let mut bad = good.clone();
        bad[stream] = 0xff; // a back reference before anything was decompressed
        let e = read(&bad).unwrap_err();
        assert!(
            matches!(e, ReadError::BadValue { at: At::Offset(o), .. } if o == stream as u64),
            "{e}"
        );
        let mut bad = good.clone();
        let packed = u32::from_le_bytes(bad[body..body + 4].try_into().unwrap());
        bad[body..body + 4].copy_from_slice(&(packed - 100).to_le_bytes());
        assert!(matches!(read(&bad), Err(ReadError::BadValue { .. })));
        let mut bad = good.clone();
        bad[body + 4..body + 8].copy_from_slice(&u32::MAX.to_le_bytes()); // not POINTS × 12
        assert!(
            matches!(read(&bad), Err(ReadError::BadValue { at: At::Offset(o), .. }) if o == body as u64 + 4)
        );
        bad.truncate(body + 8 + 100); // the stream is shorter than its declared size
        assert!(matches!(read(&bad), Err(ReadError::Truncated { .. })));
        for (i, at) in (stream..good.len()).step_by(97).enumerate() {
            let mut bad = good.clone();
            bad[at] ^= 1 << (i % 8);
            match read(&bad) {
                Ok(_) | Err(ReadError::BadValue { .. }) => {}
                Err(e) => panic!("flip at {at}: {e}"),
            }
        }
    }
}
