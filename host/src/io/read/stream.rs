//! The byte source every reader pulls from: a file (or a slice) read through one small buffer,
//! so that a reader holds the points it returns and not the file they came from.
//!
//! The input's total length is known up front (the file's metadata, or the slice's length),
//! and the input is that many bytes: a file that grows while it is read is read as it was.
//! That keeps the readers' contract that a size from a header is checked against the bytes
//! actually present before anything is allocated or looped over: `remaining()` is those bytes.
//!
//! Offsets and indices into the buffer are the reader's own bookkeeping, never a value from the
//! file; a record or line longer than the buffer grows it, which only happens while the input
//! still has that many bytes, so the buffer never outgrows the file.

use std::io::{ErrorKind, Read};

use super::{Ctx, ReadError};

/// Bytes read from the source at a time. Small next to any cloud worth streaming, large enough
/// that a 100 MB file takes a few thousand reads.
pub(super) const BUFFER: usize = 32 * 1024;

/// One line: its 1-based number, its text without the line ending, and whether a newline ended
/// it (the last line of a cut file has none). It borrows the input's buffer until the next read.
pub(crate) struct Line<'b> {
    pub number: usize,
    pub text: &'b [u8],
    pub terminated: bool,
}

pub(crate) struct Input<'a> {
    ctx: Ctx<'a>,
    source: &'a mut dyn Read,
    buf: Vec<u8>,
    /// `buf[start..end]` holds the bytes read but not yet consumed.
    start: usize,
    end: usize,
    /// Input offset of `buf[0]`.
    offset: u64,
    len: u64,
    eof: bool,
    /// Lines returned so far, so that numbers run on from a header into a body.
    lines: usize,
}

impl<'a> Input<'a> {
    /// `len` is the input's total length in bytes, as its metadata states it.
    pub fn new(ctx: Ctx<'a>, source: &'a mut dyn Read, len: u64) -> Self {
        // A small input gets a buffer its own size.
        let size = usize::try_from(len).map_or(BUFFER, |n| n.min(BUFFER));
        Input {
            ctx,
            source,
            buf: vec![0; size],
            start: 0,
            end: 0,
            offset: 0,
            len,
            eof: false,
            lines: 0,
        }
    }

    pub fn ctx(&self) -> Ctx<'a> {
        self.ctx
    }

    /// The input's total length.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Offset of the first byte not yet consumed.
    pub fn pos(&self) -> u64 {
        self.offset + self.start as u64
    }

    /// Bytes from `pos()` to the end of the input.
    pub fn remaining(&self) -> u64 {
        self.len.saturating_sub(self.pos())
    }

    fn buffered(&self) -> &[u8] {
        self.buf.get(self.start..self.end).unwrap_or_default()
    }

    /// Reads until at least `want` bytes are buffered, or the input ends.
    fn fill(&mut self, want: usize) -> Result<(), ReadError> {
        while self.end - self.start < want && !self.eof {
            if self.start > 0 {
                self.buf.copy_within(self.start..self.end, 0);
                self.offset += self.start as u64;
                self.end -= self.start;
                self.start = 0;
            }
            // The input is the `len` bytes the file had when opened, even if it grows.
            let left = self.len.saturating_sub(self.offset + self.end as u64);
            if self.end == self.buf.len() {
                // Doubling keeps a long line's reads few; the cap keeps the buffer within the
                // file, since no byte past `left` will ever be read into it.
                let most = usize::try_from(left).map_or(usize::MAX, |l| self.end.saturating_add(l));
                let grown = self.buf.len().saturating_mul(2).max(want).max(64);
                self.buf.resize(grown.min(most).max(self.end), 0);
            }
            let room = self.buf.len() - self.end;
            let room = usize::try_from(left).map_or(room, |left| left.min(room));
            if room == 0 {
                self.eof = true;
                break;
            }
            let room = self
                .buf
                .get_mut(self.end..self.end + room)
                .unwrap_or_default();
            match self.source.read(room) {
                Ok(0) => self.eof = true,
                Ok(n) => self.end += n,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(cause) => {
                    let path = self.ctx.name().into();
                    return Err(ReadError::Io { path, cause });
                }
            }
        }
        Ok(())
    }

    /// The buffered bytes after reading until there are at least `want` of them: fewer only
    /// at the end of the input, possibly more. Nothing is consumed.
    pub fn peek(&mut self, want: usize) -> Result<&[u8], ReadError> {
        self.fill(want)?;
        Ok(self.buffered())
    }

    /// Marks `n` bytes (at most those buffered) as read.
    pub fn consume(&mut self, n: usize) {
        self.start += n.min(self.end - self.start);
    }

    /// Hands up to `count` records of `stride` bytes to `each`, in order and as many at a time
    /// as are buffered; returns how many there were, fewer than `count` only if the input ends.
    pub fn records(
        &mut self,
        stride: usize,
        count: usize,
        mut each: impl FnMut(&[u8]),
    ) -> Result<usize, ReadError> {
        let stride = stride.max(1);
        let mut done = 0;
        while done < count {
            let buffered = self.peek(stride)?;
            let whole = (buffered.len() / stride).min(count - done);
            if whole == 0 {
                break;
            }
            buffered
                .chunks_exact(stride)
                .take(whole)
                .for_each(&mut each);
            self.consume(whole * stride);
            done += whole;
        }
        Ok(done)
    }

    /// The error for an input that ends inside `what`: the file is shorter than its header
    /// says, or shrank after it was opened and its length checked.
    pub fn ended(&self, what: &str) -> ReadError {
        let (pos, len) = (self.pos(), self.len);
        let what = format!("{what} runs past the end of the file at offset {pos} of {len}");
        self.ctx.truncated(what)
    }

    /// Consumes `n` bytes without looking at them; returns how many there were, fewer than
    /// `n` if the input ends first.
    pub fn skip(&mut self, n: u64) -> Result<u64, ReadError> {
        let mut left = n;
        while left > 0 {
            let have = self.peek(1)?.len();
            if have == 0 {
                break;
            }
            let step = usize::try_from(left).map_or(have, |l| l.min(have));
            self.consume(step);
            left -= step as u64;
        }
        Ok(n - left)
    }

    /// The next line, `\n` or `\r\n` terminated, or `None` at the end of the input.
    pub fn next_line(&mut self) -> Result<Option<Line<'_>>, ReadError> {
        let span = self.line_span()?;
        Ok(span.map(|span| self.line(span)))
    }

    /// The next line that has something other than whitespace in it.
    pub fn next_non_blank(&mut self) -> Result<Option<Line<'_>>, ReadError> {
        loop {
            match self.line_span()? {
                Some((at, len, _)) if self.buf_at(at, len).iter().all(u8::is_ascii_whitespace) => {}
                span => return Ok(span.map(|span| self.line(span))),
            }
        }
    }

    fn buf_at(&self, at: usize, len: usize) -> &[u8] {
        self.buf.get(at..at + len).unwrap_or_default()
    }

    fn line(&self, (at, len, terminated): (usize, usize, bool)) -> Line<'_> {
        let text = self.buf_at(at, len);
        Line {
            number: self.lines,
            text: text.strip_suffix(b"\r").unwrap_or(text),
            terminated,
        }
    }

    /// Finds and consumes the next line; returns where its text sits in the buffer. Spans
    /// rather than slices, so that a caller may skip lines in a loop and still return one.
    fn line_span(&mut self) -> Result<Option<(usize, usize, bool)>, ReadError> {
        let mut searched = 0;
        loop {
            let rest = self.buffered();
            let newline = rest
                .get(searched..)
                .and_then(|r| r.iter().position(|&b| b == b'\n'));
            let (len, used, terminated) = match newline {
                Some(i) => (searched + i, searched + i + 1, true),
                None if self.eof && rest.is_empty() => return Ok(None),
                None if self.eof => (rest.len(), rest.len(), false),
                None => {
                    searched = rest.len();
                    self.fill(searched + 1)?;
                    continue;
                }
            };
            let at = self.start;
            self.start += used;
            self.lines += 1;
            return Ok(Some((at, len, terminated)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reads at most `step` bytes per call, as a pipe or a slow disk may.
    struct Dribble<'d>(&'d [u8], usize);

    impl Read for Dribble<'_> {
        fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
            let n = self.1.min(out.len()).min(self.0.len());
            out[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    fn lines_of(bytes: &[u8], step: usize) -> Vec<(usize, Vec<u8>, bool)> {
        let mut source = Dribble(bytes, step);
        let mut input = Input::new(Ctx::new("t"), &mut source, bytes.len() as u64);
        let mut out = Vec::new();
        while let Some(l) = input.next_line().unwrap() {
            out.push((l.number, l.text.to_vec(), l.terminated));
        }
        out
    }

    #[test]
    fn lines_are_the_same_whatever_the_reads_deliver() {
        let long = "x".repeat(3 * BUFFER);
        let text = format!("a b\r\n\n{long}\nlast");
        let want = lines_of(text.as_bytes(), usize::MAX);
        assert_eq!(want.len(), 4);
        assert_eq!(want[0], (1, b"a b".to_vec(), true));
        assert_eq!(want[2].1.len(), 3 * BUFFER);
        assert_eq!(want[3], (4, b"last".to_vec(), false));
        for step in [1, 7, 4096] {
            assert_eq!(lines_of(text.as_bytes(), step), want, "step {step}");
        }
    }

    /// Growing for a long peek or line stops at the bytes the input has left.
    #[test]
    fn the_buffer_never_outgrows_the_input() {
        let bytes = vec![b'x'; 50_000];
        let mut source = Dribble(&bytes, 999);
        let mut input = Input::new(Ctx::new("t"), &mut source, bytes.len() as u64);
        assert!(input.peek(40_000).unwrap().len() >= 40_000);
        assert!(input.buf.len() <= 50_000, "{} bytes", input.buf.len());
        assert_eq!(input.skip(45_000).unwrap(), 45_000);
        assert_eq!(input.peek(1 << 20).unwrap().len(), 5_000);
        assert!(input.buf.len() <= 50_000, "{} bytes", input.buf.len());
        // A line as long as the input, read through a buffer that has to grow for it.
        let mut source = Dribble(&bytes, 4096);
        let mut input = Input::new(Ctx::new("t"), &mut source, bytes.len() as u64);
        let line = input.next_line().unwrap().unwrap();
        assert_eq!((line.text.len(), line.terminated), (50_000, false));
        assert!(input.buf.len() <= 50_000, "{} bytes", input.buf.len());
    }

    /// Records come whole, in order and however the reads cut them; a partial one at the end
    /// is left, and counted out.
    #[test]
    fn records_in_any_reads() {
        let bytes: Vec<u8> = (0..1003u32).map(|i| i as u8).collect();
        for step in [1, 7, 5000] {
            let mut source = Dribble(&bytes, step);
            let mut input = Input::new(Ctx::new("t"), &mut source, bytes.len() as u64);
            let mut seen = Vec::new();
            assert_eq!(
                input.records(10, 50, |r| seen.push(r.to_vec())).unwrap(),
                50
            );
            let rest = input.records(10, usize::MAX, |r| seen.push(r.to_vec()));
            assert_eq!(rest.unwrap(), 50, "step {step}");
            assert_eq!(seen.concat(), bytes[..1000], "step {step}");
            assert_eq!(input.remaining(), 3);
        }
    }

    #[test]
    fn peek_skip_and_positions() {
        let bytes: Vec<u8> = (0..100_000u32).map(|i| i as u8).collect();
        let mut source = Dribble(&bytes, 1000);
        let mut input = Input::new(Ctx::new("t"), &mut source, bytes.len() as u64);
        assert_eq!(input.peek(5000).unwrap()[..5000], bytes[..5000]);
        input.consume(10);
        assert_eq!(input.skip(50_000).unwrap(), 50_000);
        assert_eq!((input.pos(), input.remaining()), (50_010, 49_990));
        assert_eq!(input.peek(3).unwrap()[..3], bytes[50_010..50_013]);
        assert_eq!(input.skip(1 << 40).unwrap(), 49_990);
        assert!(input.peek(1).unwrap().is_empty());
        assert!(input.next_non_blank().unwrap().is_none());
    }
}
