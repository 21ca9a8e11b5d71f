//! Where the firmware's bytes come from: one small boundary trait, and a UART that delivers a
//! capture in seeded random chunks, as a DMA or FIFO interrupt would between two main-loop ticks.

use mema_core::rng::{Pcg32, index_below, stream_rng};

/// What a byte source handed over between two ticks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delivery {
    /// This many bytes were written to the front of the buffer (possibly zero: an idle line).
    Bytes(usize),
    /// The board reset: everything in RAM is gone, the firmware restarts from its snapshot.
    Reset,
    /// The source has nothing more, ever.
    End,
}

/// A source of received bytes.
///
/// Edge rules every implementer keeps: `deliver` writes at most `buf.len()` bytes, never reports
/// more than it wrote, and once it has returned [`Delivery::End`] it keeps returning it.
pub trait ByteSource {
    type Error;

    fn deliver(&mut self, buf: &mut [u8]) -> Result<Delivery, Self::Error>;
}

/// A capture played as a UART receives it: chunks of 1..=`max_chunk` bytes, sizes drawn from a
/// seeded PCG32 stream, so a run is reproducible and every chunking can be tried.
#[derive(Debug)]
pub struct UartSource<'a> {
    capture: &'a [u8],
    at: usize,
    max_chunk: usize,
    rng: Pcg32,
}

impl<'a> UartSource<'a> {
    /// `max_chunk` 0 is taken as 1 (byte by byte).
    pub fn new(capture: &'a [u8], seed: u64, max_chunk: usize) -> Self {
        Self {
            capture,
            at: 0,
            max_chunk: max_chunk.max(1),
            // Stream 0x55 keeps the chunk sizes independent of any DE stream of the same seed.
            rng: stream_rng(seed, 0x55),
        }
    }

    /// Bytes handed over so far.
    pub fn position(&self) -> usize {
        self.at
    }
}

impl ByteSource for UartSource<'_> {
    type Error = core::convert::Infallible;

    fn deliver(&mut self, buf: &mut [u8]) -> Result<Delivery, Self::Error> {
        let rest = self.capture.get(self.at..).unwrap_or(&[]);
        if rest.is_empty() {
            return Ok(Delivery::End);
        }
        let want = 1 + index_below(&mut self.rng, self.max_chunk);
        let n = want.min(rest.len()).min(buf.len());
        if let (Some(dst), Some(src)) = (buf.get_mut(..n), rest.get(..n)) {
            dst.copy_from_slice(src);
        }
        self.at += n;
        Ok(Delivery::Bytes(n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delivers_every_byte_once_in_bounded_chunks() {
        let capture: [u8; 1000] = core::array::from_fn(|i| (i * 7) as u8);
        for (seed, max_chunk) in [(0, 1), (1, 3), (2, 64), (3, 5000)] {
            let mut uart = UartSource::new(&capture, seed, max_chunk);
            let mut got = [0u8; 1000];
            let mut at = 0;
            let mut buf = [0u8; 256];
            loop {
                match uart.deliver(&mut buf) {
                    Ok(Delivery::Bytes(n)) => {
                        assert!(n >= 1 && n <= max_chunk.min(256));
                        got[at..at + n].copy_from_slice(&buf[..n]);
                        at += n;
                    }
                    Ok(Delivery::End) => break,
                    other => panic!("{other:?}"),
                }
            }
            assert_eq!((at, got), (1000, capture));
            assert_eq!(uart.deliver(&mut buf), Ok(Delivery::End));
        }
    }
}
