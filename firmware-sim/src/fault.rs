//! A seeded fault injector that wraps any [`ByteSource`], after smoltcp's `FaultInjector`: it
//! brings its own PCG32 stream, so it stays `no_std`, and [`FaultInjector::into_inner`] returns
//! the wrapped source.
//!
//! Faults, each at its own rate:
//! - **noise**: a random byte inserted into the stream (line noise);
//! - **overrun**: a run of 1..=64 bytes dropped (the UART FIFO overflowed while the CPU was busy);
//! - **truncation**: the rest of the current frame dropped up to its delimiter, which still
//!   arrives (the sender was cut off mid-frame);
//! - **reset**: the board resets, and the bytes of that delivery are lost with it.
//!
//! Byte faults are drawn per byte, in parts per million; resets per delivery, also in ppm.
//!
//! [`LineFaults`] is the line between two ends that both talk (a host and a mapping device):
//! a byte dropped, one of its bits flipped, or the byte duplicated, at a rate of one byte in
//! `one_in`. Every test of the link's faults, in memory or through QEMU's serial port, draws
//! its faults from these two.

use mema_core::rng::{Pcg32, index_below, stream_rng};
use mema_firmware::source::{ByteSource, Delivery};

/// Fault rates, all in parts per million.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultConfig {
    pub seed: u64,
    /// Per byte: a random byte is inserted before it.
    pub noise_ppm: u32,
    /// Per byte: it and up to 63 following bytes are dropped.
    pub overrun_ppm: u32,
    /// Per byte: it and the rest of its frame, up to the delimiter, are dropped.
    pub truncate_ppm: u32,
    /// Per delivery: the board resets instead of receiving it.
    pub reset_ppm: u32,
}

/// What was injected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultStats {
    pub noise_bytes: u64,
    pub overruns: u64,
    pub overrun_bytes: u64,
    pub truncations: u64,
    pub truncated_bytes: u64,
    pub resets: u64,
}

/// The scratch size: one delivery from the wrapped source is at most this many bytes.
const SCRATCH: usize = 512;

#[derive(Debug)]
pub struct FaultInjector<S> {
    inner: S,
    config: FaultConfig,
    rng: Pcg32,
    stats: FaultStats,
    /// Bytes still to drop of the current overrun.
    dropping: u32,
    /// Dropping up to (not including) the next delimiter.
    truncating: bool,
    scratch: [u8; SCRATCH],
}

impl<S: ByteSource> FaultInjector<S> {
    pub fn new(inner: S, config: FaultConfig) -> Self {
        Self {
            inner,
            config,
            rng: stream_rng(config.seed, 0xFA17),
            stats: FaultStats::default(),
            dropping: 0,
            truncating: false,
            scratch: [0; SCRATCH],
        }
    }

    pub fn stats(&self) -> &FaultStats {
        &self.stats
    }

    /// The wrapped, clean source.
    pub fn into_inner(self) -> S {
        self.inner
    }

    fn happens(&mut self, ppm: u32) -> bool {
        ppm > 0 && index_below(&mut self.rng, 1_000_000) < ppm as usize
    }
}

impl<S: ByteSource> ByteSource for FaultInjector<S> {
    type Error = S::Error;

    fn deliver(&mut self, buf: &mut [u8]) -> Result<Delivery, S::Error> {
        // Each input byte can become two (noise + byte), so ask for at most half the room.
        let ask = (buf.len() / 2).clamp(1, SCRATCH);
        let mut scratch = self.scratch;
        let n = match self
            .inner
            .deliver(scratch.get_mut(..ask).unwrap_or(&mut []))?
        {
            Delivery::Bytes(n) => n,
            other => return Ok(other),
        };
        if self.happens(self.config.reset_ppm) {
            self.stats.resets += 1;
            self.dropping = 0;
            self.truncating = false;
            return Ok(Delivery::Reset);
        }
        let mut out = 0;
        for &byte in scratch.get(..n).unwrap_or(&[]) {
            if self.dropping == 0 && !self.truncating {
                if self.happens(self.config.overrun_ppm) {
                    self.dropping = 1 + index_below(&mut self.rng, 64) as u32;
                    self.stats.overruns += 1;
                } else if self.happens(self.config.truncate_ppm) && byte != 0 {
                    self.truncating = true;
                    self.stats.truncations += 1;
                }
            }
            if self.dropping > 0 {
                self.dropping -= 1;
                self.stats.overrun_bytes += 1;
                continue;
            }
            if self.truncating {
                if byte != 0 {
                    self.stats.truncated_bytes += 1;
                    continue;
                }
                self.truncating = false;
            }
            if self.happens(self.config.noise_ppm) {
                let noise = self.rng_byte();
                if let Some(slot) = buf.get_mut(out) {
                    *slot = noise;
                    out += 1;
                    self.stats.noise_bytes += 1;
                }
            }
            if let Some(slot) = buf.get_mut(out) {
                *slot = byte;
                out += 1;
            }
        }
        self.scratch = scratch;
        Ok(Delivery::Bytes(out))
    }
}

impl<S> FaultInjector<S> {
    fn rng_byte(&mut self) -> u8 {
        index_below(&mut self.rng, 256) as u8
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mema_firmware::source::UartSource;

    fn drain<S: ByteSource<Error = core::convert::Infallible>>(
        source: &mut S,
        out: &mut [u8],
    ) -> (usize, u32) {
        let mut at = 0;
        let mut resets = 0;
        let mut buf = [0u8; 300];
        loop {
            match source.deliver(&mut buf) {
                Ok(Delivery::Bytes(n)) => {
                    out[at..at + n].copy_from_slice(&buf[..n]);
                    at += n;
                }
                Ok(Delivery::Reset) => resets += 1,
                Ok(Delivery::End) => return (at, resets),
                Err(e) => match e {},
            }
        }
    }

    #[test]
    fn no_faults_is_transparent_and_into_inner_returns_the_source() {
        let capture: [u8; 4000] = core::array::from_fn(|i| (i % 251) as u8);
        let mut f = FaultInjector::new(UartSource::new(&capture, 1, 97), FaultConfig::default());
        let mut out = [0u8; 4000];
        assert_eq!(drain(&mut f, &mut out), (4000, 0));
        assert_eq!(out, capture);
        assert_eq!(f.stats(), &FaultStats::default());
        assert_eq!(f.into_inner().position(), 4000);
    }

    #[test]
    fn every_fault_kind_happens_and_is_accounted_for() {
        // Delimiters every 100 bytes, as frames would have them.
        let capture: [u8; 20_000] = core::array::from_fn(|i| {
            if i % 100 == 99 {
                0
            } else {
                1 + (i % 200) as u8
            }
        });
        let config = FaultConfig {
            seed: 5,
            noise_ppm: 2_000,
            overrun_ppm: 1_000,
            truncate_ppm: 1_000,
            reset_ppm: 20_000,
        };
        let mut f = FaultInjector::new(UartSource::new(&capture, 2, 200), config);
        let mut out = [0u8; 40_000];
        let (len, resets) = drain(&mut f, &mut out);
        let s = *f.stats();
        assert!(s.noise_bytes > 0 && s.overruns > 0 && s.truncations > 0 && s.resets > 0);
        assert_eq!(resets as u64, s.resets);
        // Every byte is accounted for except those lost with a reset's delivery.
        let accounted = len as u64 + s.overrun_bytes + s.truncated_bytes - s.noise_bytes;
        assert!(accounted <= 20_000 && accounted + 200 * s.resets >= 20_000);
        // Truncation keeps delimiters: every dropped tail still ends its frame.
        let delimiters = out[..len].iter().filter(|&&b| b == 0).count();
        // An overrun (at most 64 bytes) spans at most one; a reset's delivery (200) at most two.
        assert!(delimiters as u64 + s.overruns + 2 * s.resets >= 200);
    }
}

/// A serial line that drops, flips or duplicates bytes, one in `one_in` of them (`0`: a clean
/// line), the kind of each fault equally likely; seeded, so a run is repeatable.
#[derive(Clone, Debug)]
pub struct LineFaults {
    rng: Pcg32,
    one_in: u32,
    /// Faults made so far.
    pub faults: u64,
}

impl LineFaults {
    pub fn new(seed: u64, one_in: u32) -> Self {
        Self {
            rng: stream_rng(seed, 0x11FE),
            one_in,
            faults: 0,
        }
    }

    /// Carries `bytes` across the line, handing what arrives to `out` byte by byte.
    pub fn carry(&mut self, bytes: &[u8], mut out: impl FnMut(u8)) {
        for &b in bytes {
            if self.one_in == 0 || index_below(&mut self.rng, self.one_in as usize) != 0 {
                out(b);
                continue;
            }
            self.faults += 1;
            match index_below(&mut self.rng, 3) {
                0 => {}
                1 => out(b ^ (1 << index_below(&mut self.rng, 8))),
                _ => {
                    out(b);
                    out(b);
                }
            }
        }
    }
}

#[cfg(test)]
mod line_tests {
    use super::*;

    /// A clean line carries every byte; a faulty one makes about the rate's faults, each a
    /// byte dropped, flipped in one bit, or duplicated, and nothing else.
    #[test]
    fn the_line_makes_the_faults_it_counts() {
        let bytes: [u8; 4096] = core::array::from_fn(|i| (i * 7) as u8);
        let mut clean = LineFaults::new(1, 0);
        let mut out = [0u8; 8192];
        let mut n = 0;
        clean.carry(&bytes, |b| {
            out[n] = b;
            n += 1;
        });
        assert_eq!((&out[..n], clean.faults), (&bytes[..], 0));
        let mut line = LineFaults::new(7, 64);
        n = 0;
        line.carry(&bytes, |b| {
            out[n] = b;
            n += 1;
        });
        assert!((30..=100).contains(&line.faults), "{} faults", line.faults);
        // Each fault changes the length by -1, 0 or +1, and no more bytes differ than faults
        // can explain (checked on the length here; the links' tests check what they do).
        assert!(n.abs_diff(bytes.len()) as u64 <= line.faults);
    }
}
