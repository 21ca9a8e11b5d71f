//! The receive ring: bytes from the UART interrupt in, contiguous runs of them out to the
//! decoder.
//!
//! Why not `heapless::Deque`: it takes bytes one at a time, about 20 instructions each in the
//! interrupt, where a chunk copies in at most two pieces here; and it hands out its front
//! slice but drops consumed bytes through `retain_back`.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicUsize, Ordering};

/// A byte ring of `N` bytes, usable in a `static`, with one producer and one consumer that may
/// run in different contexts: a receive interrupt pushes ([`Ring::push`]) while the main loop
/// reads and consumes ([`Ring::consume_front`]). Each side owns a counter and a position: the
/// producer `tail` and `tail_at`, the consumer `head` and `head_at`. The counters count bytes
/// since the start and wrap, so the bytes held are `tail - head` across the wrap; the positions
/// are where each side is in the buffer, kept below `N` by each side as it moves. (A position
/// taken as `count % N` would jump at the counter's wrap, 2^32 bytes on a 32-bit part, 13 hours
/// at 921,600 baud, unless `N` divides 2^32.) Neither side ever writes what the other reads. A
/// single-core Cortex-M needs no more than these loads and stores (and their ordering).
///
/// The contract, as `heapless::spsc` has it but without splitting the ring: `push` is called
/// from one context only, and `consume_front`, `taken` and `clear` from one other context only
/// (or all of them from one context, as the simulator does).
pub struct Ring<const N: usize> {
    buf: UnsafeCell<[u8; N]>,
    /// Bytes consumed since the start (wrapping), and where the next one is; written by the
    /// consumer only.
    head: AtomicUsize,
    head_at: AtomicUsize,
    /// Bytes pushed since the start (wrapping), and where the next goes; written by the
    /// producer only.
    tail: AtomicUsize,
    tail_at: AtomicUsize,
}

// SAFETY: the producer writes only bytes outside `head..tail` (free space) and publishes them
// with a release store of `tail`; the consumer reads only bytes inside `head..tail`, seen after
// an acquire load of `tail`, and frees them with a release store of `head`, which the producer
// loads with acquire before reusing them. The two never touch the same byte at the same time.
unsafe impl<const N: usize> Sync for Ring<N> {}

impl<const N: usize> core::fmt::Debug for Ring<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Ring")
            .field("capacity", &N)
            .field("len", &self.len())
            .finish()
    }
}

impl<const N: usize> Ring<N> {
    #[inline(always)]
    pub const fn new() -> Self {
        Self::counting_from(0)
    }

    /// An empty ring whose counters start at `count` (a test starts them just before their
    /// wrap).
    #[inline(always)]
    pub const fn counting_from(count: usize) -> Self {
        Self {
            buf: UnsafeCell::new([0; N]),
            head: AtomicUsize::new(count),
            head_at: AtomicUsize::new(0),
            tail: AtomicUsize::new(count),
            tail_at: AtomicUsize::new(0),
        }
    }

    /// `at` moved on by `n <= N` bytes, kept below `N`.
    fn advance(at: usize, n: usize) -> usize {
        let next = at + n;
        if next >= N { next - N } else { next }
    }

    /// Bytes held.
    pub fn len(&self) -> usize {
        let head = self.head.load(Ordering::Acquire);
        self.tail.load(Ordering::Acquire).wrapping_sub(head).min(N)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes taken out since the start (wrapping): the consumer's count, which a device
    /// reports so a sender never has more in flight than the ring holds.
    pub fn taken(&self) -> usize {
        self.head.load(Ordering::Acquire)
    }

    /// Drops every byte held (the consumer's side: a reset).
    pub fn clear(&self) {
        let head = self.head.load(Ordering::Relaxed);
        let held = self.tail.load(Ordering::Acquire).wrapping_sub(head).min(N);
        let at = Self::advance(self.head_at.load(Ordering::Relaxed), held);
        self.head_at.store(at, Ordering::Relaxed);
        self.head.store(head.wrapping_add(held), Ordering::Release);
    }

    /// Appends as much of `bytes` as fits; returns how much did (the producer's side).
    pub fn push(&self, bytes: &[u8]) -> usize {
        let tail = self.tail.load(Ordering::Relaxed);
        let held = tail.wrapping_sub(self.head.load(Ordering::Acquire)).min(N);
        let kept = bytes.len().min(N - held);
        // Where the free space starts, and its part before the end of the buffer.
        let at = self
            .tail_at
            .load(Ordering::Relaxed)
            .min(N.saturating_sub(1));
        let first = kept.min(N - at);
        let base = self.buf.get().cast::<u8>();
        // SAFETY: `at..at + first` and `0..kept - first` lie in the buffer (`at < N`,
        // `first <= N - at`, `kept - first <= N - held - first`) and in its free space, which
        // only this side writes and the consumer does not read until `tail` says so below.
        unsafe {
            core::ptr::copy_nonoverlapping(bytes.as_ptr(), base.add(at), first);
            core::ptr::copy_nonoverlapping(bytes.as_ptr().add(first), base, kept - first);
        }
        self.tail_at
            .store(Self::advance(at, kept), Ordering::Relaxed);
        self.tail.store(tail.wrapping_add(kept), Ordering::Release);
        kept
    }

    /// Hands the oldest bytes held contiguously (all of them unless they wrap; empty when none
    /// are) to `read`, then drops as many of them as it returns: the consumer's side. The
    /// bytes are lent for the call only, so none is read after it gives them back to the
    /// producer.
    pub fn consume_front(&self, read: impl FnOnce(&[u8]) -> usize) -> usize {
        let head = self.head.load(Ordering::Relaxed);
        let held = self.tail.load(Ordering::Acquire).wrapping_sub(head).min(N);
        let at = self
            .head_at
            .load(Ordering::Relaxed)
            .min(N.saturating_sub(1));
        let run = held.min(N - at);
        // SAFETY: `at..at + run` lies in the buffer and in the bytes held, which the producer
        // does not write until `head` below gives them back, after `read` has returned and
        // its borrow of them has ended.
        let front =
            unsafe { core::slice::from_raw_parts(self.buf.get().cast::<u8>().add(at), run) };
        let taken = read(front).min(run);
        self.head_at
            .store(Self::advance(at, taken), Ordering::Relaxed);
        self.head.store(head.wrapping_add(taken), Ordering::Release);
        taken
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
        // From the start, and with the counters just before their wrap: the same stream.
        for start in [0, usize::MAX - 300] {
            holds_the_stream_from(start);
        }
    }

    fn holds_the_stream_from(start: usize) {
        let ring = Ring::<7>::counting_from(start);
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
                let n = ring.consume_front(|front| {
                    assert!(!front.is_empty() || pushed == consumed);
                    for (k, &b) in front.iter().enumerate() {
                        assert_eq!(b, (consumed + k) as u8);
                    }
                    (s as usize / 2) % (front.len() + 1)
                });
                consumed += n;
            }
            assert_eq!(ring.len(), pushed - consumed);
            assert_eq!(ring.taken(), start.wrapping_add(consumed));
        }
        assert!(consumed > 1_000, "{consumed} bytes through");
    }
}
