//! The receiver: bytes from the link become points in the map's frame, exactly as PROTOCOL.md's
//! "What the receiver does" says, in fixed memory and the same on the host and the device.
//!
//! [`Receiver`] owns the frame [`Decoder`] and adds what a stream means beyond one frame:
//! - **The end.** Frames after the end-of-stream frame are counted and never mapped, so the map
//!   does not depend on how many of them arrived in the same chunk as the end.
//! - **The map's frame.** The mapper works in f32, which near 2,000 km resolves only 0.25 m. The
//!   receiver therefore keeps an f64 origin, taken from the first point mapped and rounded to
//!   [`ORIGIN_CELL`], and hands the mapper points relative to it: millimetres stay millimetres
//!   within 16 km of the origin, wherever on the link's range the map lies. A cloud within
//!   512 m of 0 keeps origin 0, so its points reach the mapper with the same bits as before
//!   there was an origin.

use crate::geometry::Point3;
use crate::wire::{Decoded, Decoder, DecoderStats, Frame, FrameError};

/// The map origin is the first mapped point rounded to a multiple of this (metres): a power of
/// two, so the origin is exact in f64 and the same on every target.
pub const ORIGIN_CELL: f64 = 1024.0;

/// Where a frame's points go: the map's origin (and, with poses, the sensor's pose), with the
/// frame's unit, worked out once per frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    origin: [f64; 3],
    /// Metres per unit of the frame.
    scale: f64,
    /// Added to a point in metres: minus the origin.
    offset: [f64; 3],
    /// The origin is 0: a point reaches the mapper as `(v * 10^e) as f32`, the bits it had
    /// before there was an origin, and without three soft-float additions on a device.
    at_zero: bool,
}

impl Placement {
    fn new(origin: [f64; 3], exponent: i8) -> Self {
        Self {
            origin,
            scale: crate::wire::unit_scale(exponent).unwrap_or(f64::NAN),
            offset: origin.map(|o| -o),
            at_zero: origin == [0.0; 3],
        }
    }

    /// The map's origin, in the world frame (metres).
    pub const fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// Point `i` of `frame` in the map's frame (metres from the origin), or `None` past its
    /// points. `frame` is the frame this placement was made for.
    pub fn point<T: AsRef<[u8]>>(&self, frame: &Frame<T>, i: usize) -> Option<Point3> {
        let [x, y, z] = frame.point(i)?;
        let s = self.scale;
        if self.at_zero {
            return Some(Point3::new(
                (x as f64 * s) as f32,
                (y as f64 * s) as f32,
                (z as f64 * s) as f32,
            ));
        }
        let [ox, oy, oz] = self.offset;
        let local = |v: i32, o: f64| (v as f64 * s + o) as f32;
        Some(Point3::new(local(x, ox), local(y, oy), local(z, oz)))
    }

    /// Every point of `frame`, as [`Placement::point`] gives them.
    pub fn points<'a, T: AsRef<[u8]>>(
        &'a self,
        frame: &'a Frame<T>,
    ) -> impl Iterator<Item = Point3> + 'a {
        (0..usize::from(frame.point_count())).filter_map(move |i| self.point(frame, i))
    }
}

/// Why a frame was not mapped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skip {
    /// The decoder refused it (its reason and counter are the decoder's).
    Rejected(FrameError),
    /// It came after the end-of-stream frame.
    AfterEnd,
}

/// What one call to [`Receiver::feed`] produced; every variant but `Consumed` carries the rest
/// of the input, to be fed next.
#[derive(Debug)]
pub enum Received<'r, 'i> {
    /// All input was taken; no frame ended in it.
    Consumed,
    /// A frame whose points go into the map, placed by `placement`.
    Points {
        frame: Frame<&'r [u8]>,
        placement: Placement,
        remaining: &'i [u8],
    },
    /// A frame that ended and is not mapped.
    Skipped { why: Skip, remaining: &'i [u8] },
}

/// The receiver's own counters; the decoder's are [`Receiver::decoder_stats`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReceiverStats {
    /// Valid frames after the end-of-stream frame, not mapped.
    pub after_end: u64,
}

/// Decoder, end of stream and the map's frame, in fixed memory.
#[derive(Clone, Debug)]
pub struct Receiver {
    decoder: Decoder,
    origin: Option<[f64; 3]>,
    ended: bool,
    stats: ReceiverStats,
}

impl Default for Receiver {
    fn default() -> Self {
        Self::new()
    }
}

impl Receiver {
    #[inline(always)]
    pub const fn new() -> Self {
        Self::resuming(None)
    }

    /// A receiver after a reset of the device: the decoder and the stream start afresh, but the
    /// map kept in memory that survived (a snapshot) lies around `origin`
    /// ([`Receiver::map_origin`] when the snapshot was taken), so points keep going there.
    #[inline(always)]
    pub const fn resuming(origin: Option<[f64; 3]>) -> Self {
        Self {
            decoder: Decoder::new(),
            origin,
            ended: false,
            stats: ReceiverStats { after_end: 0 },
        }
    }

    /// Takes bytes until a frame ends or the input runs out, like [`Decoder::feed`].
    pub fn feed<'r, 'i>(&'r mut self, input: &'i [u8]) -> Received<'r, 'i> {
        let ended = self.ended;
        let (frame, remaining) = match self.decoder.feed(input) {
            Decoded::Consumed => return Received::Consumed,
            Decoded::Rejected { error, remaining } => {
                return Received::Skipped {
                    why: Skip::Rejected(error),
                    remaining,
                };
            }
            Decoded::Frame { frame, remaining } => (frame, remaining),
        };
        if ended {
            self.stats.after_end += 1;
            return Received::Skipped {
                why: Skip::AfterEnd,
                remaining,
            };
        }
        self.ended = frame.end_of_stream();
        if self.origin.is_none() && frame.point_count() > 0 {
            self.origin = Some(origin_for(&frame));
        }
        Received::Points {
            frame,
            // Fields, not methods: the frame still borrows the decoder.
            placement: Placement::new(self.origin.unwrap_or([0.0; 3]), frame.unit_exponent()),
            remaining,
        }
    }

    /// Where the points of the frame [`Receiver::held_frame`] holds go.
    pub fn placement(&self) -> Placement {
        let exponent = self.held_frame().map_or(0, |f| f.unit_exponent());
        Placement::new(self.origin(), exponent)
    }

    /// The frame of points the last [`Receiver::feed`] returned, until the next `feed`: a caller
    /// can map its points over several calls (the firmware's bounded ticks).
    pub fn held_frame(&self) -> Option<Frame<&[u8]>> {
        self.decoder.held_frame()
    }

    /// The map's origin in the world frame (metres); 0 until a point has arrived.
    pub fn origin(&self) -> [f64; 3] {
        self.origin.unwrap_or([0.0; 3])
    }

    /// The map's origin once the first point has set it.
    pub const fn map_origin(&self) -> Option<[f64; 3]> {
        self.origin
    }

    /// Whether the end-of-stream frame has arrived.
    pub const fn ended(&self) -> bool {
        self.ended
    }

    pub const fn stats(&self) -> &ReceiverStats {
        &self.stats
    }

    pub const fn decoder_stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }
}

/// The origin for a stream whose first point is point 0 of `frame`: that point in the world,
/// rounded to [`ORIGIN_CELL`].
fn origin_for<T: AsRef<[u8]>>(frame: &Frame<T>) -> [f64; 3] {
    let scale = frame.unit_scale();
    let first = frame.point(0).unwrap_or([0; 3]);
    // `+ 0.0` turns the -0 that rounding a small negative value gives into 0: the origin is
    // written in the map file, and 0 is what a map near 0 had before.
    first.map(|v| libm::round(v as f64 * scale / ORIGIN_CELL) * ORIGIN_CELL + 0.0)
}

#[cfg(test)]
mod tests;
