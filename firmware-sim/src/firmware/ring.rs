//! The receive ring: bytes from the UART interrupt in, contiguous runs of them out to the
//! decoder.
//!
//! Why not `heapless::Deque`: it takes bytes one at a time, about 20 instructions each in the
//! interrupt, where a chunk copies in at most two pieces here; and it hands out its front
//! slice but drops consumed bytes through `retain_back`.

/// A byte ring of `N` bytes, usable in a `static`.
#[derive(Debug)]
pub struct Ring<const N: usize> {
    buf: [u8; N],
    /// Index of the oldest byte.
    head: usize,
    len: usize,
}

impl<const N: usize> Ring<N> {
    #[inline(always)]
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            head: 0,
            len: 0,
        }
    }

    pub const fn len(&self) -> usize {
        self.len
    }

    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn clear(&mut self) {
        (self.head, self.len) = (0, 0);
    }

    /// Appends as much of `bytes` as fits; returns how much did.
    pub fn push(&mut self, bytes: &[u8]) -> usize {
        let kept = bytes.len().min(N - self.len);
        // Where the free space starts, and its part before the end of the buffer.
        let tail = (self.head + self.len) % N;
        let first = kept.min(N - tail);
        let (before, after) = bytes.split_at(first.min(bytes.len()));
        if let Some(dst) = self.buf.get_mut(tail..tail + first) {
            dst.copy_from_slice(before);
        }
        let rest = after.get(..kept - first).unwrap_or(&[]);
        if let Some(dst) = self.buf.get_mut(..rest.len()) {
            dst.copy_from_slice(rest);
        }
        self.len += kept;
        kept
    }

    /// The oldest bytes held contiguously (all of them unless they wrap).
    pub fn front(&self) -> &[u8] {
        let end = (self.head + self.len).min(N);
        self.buf.get(self.head..end).unwrap_or(&[])
    }

    /// Drops the `n` oldest bytes (at most all).
    pub fn consume(&mut self, n: usize) {
        let n = n.min(self.len);
        self.head = (self.head + n) % N;
        self.len -= n;
    }
}

impl<const N: usize> Default for Ring<N> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pushes and consumes of every size across the wrap, against a count of bytes in and out:
    /// byte `k` of the stream is `k as u8`, so what the ring holds is known from the counts.
    #[test]
    fn holds_the_stream_between_what_went_in_and_out() {
        let mut ring = Ring::<7>::new();
        let (mut pushed, mut consumed) = (0usize, 0usize);
        let mut s = 5u32;
        for _ in 0..10_000 {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            if s.is_multiple_of(2) {
                let mut bytes = [0u8; 10];
                let n = (s % 11) as usize;
                for (k, b) in bytes.iter_mut().enumerate() {
                    *b = (pushed + k) as u8;
                }
                let kept = ring.push(&bytes[..n]);
                assert_eq!(kept, n.min(7 - (pushed - consumed)));
                pushed += kept;
            } else {
                let front = ring.front();
                assert!(!front.is_empty() || pushed == consumed);
                for (k, &b) in front.iter().enumerate() {
                    assert_eq!(b, (consumed + k) as u8);
                }
                let n = (s as usize / 2) % (front.len() + 1);
                ring.consume(n);
                consumed += n;
            }
            assert_eq!(ring.len(), pushed - consumed);
        }
    }
}
