//! The receiver: bytes from the link become points in the map's frame, exactly as PROTOCOL.md's
//! "What the receiver does" says, in fixed memory and the same on the host and the device.
//!
//! [`Receiver`] owns the frame [`Decoder`] and adds what a stream means beyond one frame:
//! - **Poses** (version 2). A pose frame sets the sensor's pose, sensor to world; a points
//!   frame names the pose its points were measured at, and they are mapped through it into the
//!   world frame. A points frame whose pose never arrived (its frame lost, or a session that
//!   began since) is counted and not mapped: a wrong pose would invent a surface. Each session
//!   starts at pose 0, the identity; version 1 frames are always at the identity.
//! - **Sessions.** When the decoder sees the sender start again (a session-start flag, or its
//!   sequence numbers), the pose goes back to the identity; the map goes on.
//! - **The end.** Frames after the end-of-stream frame are counted and never mapped, so the map
//!   does not depend on how many of them arrived in the same chunk as the end.
//! - **The map's frame.** The mapper works in f32, which near 2,000 km resolves only 0.25 m. The
//!   receiver therefore keeps an origin, a point of the first frame (not a glitch among them)
//!   within the world's range, exactly (in whole nanometres, where every wire unit is whole),
//!   and hands the mapper points relative to it, worked out in integers: the same bits wherever the world frame puts the scene, so
//!   the map does not depend on the world frame's origin. (Rounded to 1,024 m, as it was, a
//!   scene half a cell from its origin had f32 steps of 30 um where one at 0 had 15 nm, and
//!   mapped 3.6x worse.)
//! - **Reach.** Points farther than the reach from the origin on any axis ([`DEFAULT_REACH`],
//!   100 km), and poses beyond it or past the world's range, are counted and never mapped: one
//!   corrupt frame that passed its CRC, or a wrong unit, costs nothing of the map.
//! - **A glitch as the first pose.** The origin is taken under the first pose, which may be the
//!   glitch. Until [`SETTLED_POSES`] poses have agreed with it, poses out of its reach that agree
//!   with each other are a rival; once the rival has more poses than the origin, the origin was
//!   the glitch: it is given up, the caller is told to start the map again
//!   ([`Received::Restart`]), and the next points frame sets the origin anew. One glitched first
//!   pose then costs its own frames and those of the pose after it (two poses outvote one); a
//!   single glitch anywhere later costs only its own, and an origin of [`SETTLED_POSES`] poses is
//!   never given up.

mod placement;

pub use placement::{Placement, Pose, is_no_return};

use crate::link::wire::{
    Decoded, Decoder, DecoderStats, Frame, FrameError, FrameKind, VERSION_1, WirePose,
};

/// How far from the map's origin points may lie by default, on each axis (metres): 100 km, a
/// day's drive of a ground robot around its first point, where f32 still resolves 4 mm. A
/// robot's map, however far its world frame puts it, lies within it; a point or pose past it is
/// a glitch (a wrong unit, a corrupt frame that passed its CRC) and is counted, never mapped.
pub const DEFAULT_REACH: f32 = 100_000.0;

/// Farthest a world coordinate may be from the world frame's 0 (nanometres): 20,000 km, twice
/// the farthest frame robots are given poses in (UTM's northings reach 10,000 km, ECEF's
/// coordinates 6,400 km). The origin is taken, and poses are held, only within it.
pub const WORLD_LIMIT_NM: i64 = 20_000_000 * 1_000_000_000;

/// Poses held around the origin after which it is never given up for a rival
/// ([`Received::Restart`]): entities frozen around it are final from then on, and a device
/// sends them ([`Receiver::settled`]).
pub const SETTLED_POSES: u32 = 16;

/// An origin in whole nanometres, in metres: the map file's f64 origin.
pub fn metres_of_nm(origin: [i64; 3]) -> [f64; 3] {
    origin.map(|v| v as f64 / 1e9)
}

/// Why a frame was not mapped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skip {
    /// The decoder refused it (its reason and counter are the decoder's).
    Rejected(FrameError),
    /// It came after the end-of-stream frame.
    AfterEnd,
    /// Its points name a pose the receiver does not hold.
    NoPose { pose: u32 },
    /// Its pose lies out of reach.
    OutOfReach,
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
        placement: &'r Placement,
        remaining: &'i [u8],
    },
    /// A pose frame: pose `number` now holds.
    Pose { number: u32, remaining: &'i [u8] },
    /// A pose frame that outvoted the origin: pose `number` now holds, the origin is given up,
    /// and everything mapped so far was placed by a pose the stream has left. The caller starts
    /// the map again (an empty mapper); the next points frame sets the origin.
    Restart { number: u32, remaining: &'i [u8] },
    /// A frame that ended and is not mapped.
    Skipped { why: Skip, remaining: &'i [u8] },
}

/// The receiver's own counters; the decoder's are [`Receiver::decoder_stats`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReceiverStats {
    /// Valid frames after the end-of-stream frame, not mapped.
    pub after_end: u64,
    /// Pose frames taken.
    pub poses: u64,
    /// Points frames not mapped because the receiver did not hold their pose.
    pub no_pose: u64,
    /// Points not mapped because they lay out of reach (counted by [`Receiver::feed_all`], or
    /// told by [`Receiver::note_refused`]).
    pub points_out_of_reach: u64,
    /// Points not mapped because they were no-returns, at the sensor itself
    /// ([`is_no_return`]).
    pub no_returns: u64,
    /// Pose frames refused because their pose lay out of reach.
    pub poses_out_of_reach: u64,
    /// Origins given up for a rival's poses ([`Received::Restart`]).
    pub restarts: u64,
}

/// What the receiver needs of a frame the decoder accepted, read before the frame's borrow of
/// the decoder ends.
struct Accepted {
    end_of_stream: bool,
    posed: bool,
    kind: Option<FrameKind>,
    pose_number: u32,
    pose: Option<WirePose>,
    exponent: i8,
}

/// Decoder, poses, sessions, end of stream and the map's frame, in fixed memory.
#[derive(Clone, Debug)]
pub struct Receiver {
    decoder: Decoder,
    /// The map's origin in the world frame, whole nanometres.
    origin: Option<[i64; 3]>,
    /// Metres from the origin, on each axis, past which points and poses are refused.
    reach: f32,
    pose: Pose,
    /// Poses held that agree with the origin (the one it was taken under included), up to
    /// [`SETTLED_POSES`]; an origin taken under no pose frame, or restored, starts settled.
    support: u32,
    /// Consecutive poses out of the origin's reach that agree with the first of them (its
    /// translation, nanometres) and how many there have been.
    rival: Option<([i64; 3], u32)>,
    /// The decoder's session count when the pose was last reset.
    session: u64,
    ended: bool,
    /// Where the points of the last points frame go: worked out once, used by every tick that
    /// maps part of it.
    placement: Placement,
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
        Self::resuming(None, DEFAULT_REACH)
    }

    /// A receiver that refuses points and poses farther than `reach` metres from the map's
    /// origin on any axis ([`Receiver::new`]: [`DEFAULT_REACH`]). Built in place, as a device's
    /// static is: a builder on a made receiver would pass its 1.7 KiB decoder through the stack.
    #[inline(always)]
    pub const fn reaching(reach: f32) -> Self {
        Self::resuming(None, reach)
    }

    /// A receiver after a reset of the device: the decoder and the stream start afresh (the
    /// pose too: points wait for the next pose frame), but the map kept in memory that survived
    /// (a snapshot) lies around `origin` ([`Receiver::map_origin`] when the snapshot was taken),
    /// so points keep going there; `reach` as before.
    #[inline(always)]
    pub const fn resuming(origin: Option<[i64; 3]>, reach: f32) -> Self {
        Self {
            decoder: Decoder::new(),
            origin,
            reach,
            pose: Pose::START,
            support: if origin.is_some() { SETTLED_POSES } else { 0 },
            rival: None,
            session: 0,
            ended: false,
            placement: Placement::NONE,
            stats: ReceiverStats {
                after_end: 0,
                poses: 0,
                no_pose: 0,
                points_out_of_reach: 0,
                no_returns: 0,
                poses_out_of_reach: 0,
                restarts: 0,
            },
        }
    }

    /// Takes bytes until a frame ends or the input runs out, like [`Decoder::feed`].
    // Out of line: inlined into the firmware's tick it doubled there and took the image's
    // flash past 64 KiB.
    #[inline(never)]
    pub fn feed<'r, 'i>(&'r mut self, input: &'i [u8]) -> Received<'r, 'i> {
        let (frame, remaining) = match self.decoder.feed(input) {
            Decoded::Consumed => return Received::Consumed,
            Decoded::Rejected { error, remaining } => {
                return Received::Skipped {
                    why: Skip::Rejected(error),
                    remaining,
                };
            }
            Decoded::Frame { frame, remaining } => (
                Accepted {
                    end_of_stream: frame.end_of_stream(),
                    posed: frame.version() != VERSION_1,
                    kind: frame.kind(),
                    pose_number: frame.pose_number(),
                    pose: frame.pose(),
                    exponent: frame.unit_exponent(),
                },
                remaining,
            ),
        };
        let sessions = self.decoder.stats().sessions;
        if sessions != self.session {
            self.session = sessions;
            self.pose = Pose::START;
            if self.origin.is_none() {
                self.support = 0;
            }
        }
        if self.ended {
            self.stats.after_end += 1;
            return Received::Skipped {
                why: Skip::AfterEnd,
                remaining,
            };
        }
        self.ended = frame.end_of_stream;
        if frame.kind == Some(FrameKind::Pose) {
            if let Some(wire) = frame.pose {
                let pose = Pose::of_wire(frame.pose_number, &wire, frame.exponent);
                if !self.holds(&pose) {
                    if self.outvoted_by(&pose) {
                        self.origin = None;
                        self.rival = None;
                        self.support = 1;
                        self.pose = pose;
                        self.stats.poses += 1;
                        self.stats.restarts += 1;
                        return Received::Restart {
                            number: frame.pose_number,
                            remaining,
                        };
                    }
                    self.stats.poses_out_of_reach += 1;
                    return Received::Skipped {
                        why: Skip::OutOfReach,
                        remaining,
                    };
                }
                // Before the origin is taken, each pose is the one it would be taken under.
                self.support = match self.origin {
                    Some(_) => self.support.saturating_add(1).min(SETTLED_POSES),
                    None => 1,
                };
                self.rival = None;
                self.pose = pose;
                self.stats.poses += 1;
            }
            return Received::Pose {
                number: frame.pose_number,
                remaining,
            };
        }
        if frame.posed && frame.pose_number != self.pose.number {
            self.stats.no_pose += 1;
            return Received::Skipped {
                why: Skip::NoPose {
                    pose: frame.pose_number,
                },
                remaining,
            };
        }
        let pose = if frame.posed { self.pose } else { Pose::START };
        let Some(held) = self.decoder.held_frame() else {
            return Received::Consumed;
        };
        if self.origin.is_none() {
            // A point of the first frame, exactly, if it is within the world's range (else
            // the next frame's): a map's points then reach the mapper with the same bits
            // wherever the world frame puts it. The point most of the frame lies near, so a
            // glitch as the very first point does not put the origin out of the scene's reach.
            self.origin = anchor(&held, frame.exponent, self.reach)
                .and_then(|raw| Placement::world_nm(raw, frame.exponent, &pose))
                .filter(|w| w.iter().all(|v| v.abs() <= WORLD_LIMIT_NM));
            // Taken under no pose frame (version 1, or pose 0), no pose can have been its
            // glitch: it stays.
            if !frame.posed || self.support == 0 {
                self.support = SETTLED_POSES;
            }
        }
        // A pose's offset past i64 nanometres leaves nothing a place: every point is refused.
        self.placement = Placement::new(
            self.origin.unwrap_or([0; 3]),
            frame.exponent,
            &pose,
            self.reach,
        )
        .unwrap_or(Placement::NONE);
        let this: &'r Self = self;
        match this.decoder.held_frame() {
            Some(frame) => Received::Points {
                frame,
                placement: &this.placement,
                remaining,
            },
            // The decoder holds the frame it just accepted until the next feed.
            None => Received::Consumed,
        }
    }

    /// Counts points of the held frame its placement refused ([`Placement::placed`]),
    /// `no_returns` of them no-returns and the rest out of reach: the caller that maps a frame
    /// point by point (the firmware's ticks) says how many there were; [`Receiver::feed_all`]
    /// counts them itself.
    pub fn note_refused(&mut self, refused: u64, no_returns: u64) {
        self.stats.no_returns += no_returns;
        self.stats.points_out_of_reach += refused.saturating_sub(no_returns);
    }

    /// Whether the receiver takes `pose`: within the world's range, and within reach of the
    /// map's origin once there is one.
    fn holds(&self, pose: &Pose) -> bool {
        let Some(t) = pose.translation_nm else {
            return false;
        };
        t.iter().all(|v| v.abs() <= WORLD_LIMIT_NM)
            && self.origin.is_none_or(|o| self.within_reach(o, t))
    }

    /// Whether a pose out of reach of `pose`'s would outvote the origin: counts `pose` into the
    /// rival it agrees with (or starts one), and says whether the rival now has more poses than
    /// the origin. Never once the origin has settled.
    fn outvoted_by(&mut self, pose: &Pose) -> bool {
        let Some(t) = pose.translation_nm else {
            return false;
        };
        if self.origin.is_none() || self.settled() || t.iter().any(|v| v.abs() > WORLD_LIMIT_NM) {
            return false;
        }
        let rival = match self.rival {
            Some((at, poses)) if self.within_reach(at, t) => (at, poses + 1),
            _ => (t, 1),
        };
        self.rival = Some(rival);
        rival.1 > self.support
    }

    /// Whether `a` and `b` (nanometres) lie within the reach of each other on every axis.
    fn within_reach(&self, a: [i64; 3], b: [i64; 3]) -> bool {
        let reach_nm = f64::from(self.reach) * 1e9;
        a.iter()
            .zip(b.iter())
            .all(|(a, b)| (a.abs_diff(*b) as f64) <= reach_nm)
    }

    /// Whether the origin is final: no pose can outvote it any more ([`SETTLED_POSES`]), so
    /// entities frozen around it are the map's for good (a device holds them back until then).
    pub fn settled(&self) -> bool {
        self.origin.is_some() && self.support >= SETTLED_POSES
    }

    /// Feeds all of `input`, calling `points` with each points frame to map and where its
    /// points go, and `restart` when the map must start again ([`Received::Restart`]): the loop
    /// over [`Receiver::feed`] a caller that maps frames whole would write.
    pub fn feed_all(
        &mut self,
        input: &[u8],
        mut points: impl FnMut(Frame<&[u8]>, &Placement),
        mut restart: impl FnMut(),
    ) {
        let mut window = input;
        loop {
            window = match self.feed(window) {
                Received::Consumed => return,
                Received::Skipped { remaining, .. } | Received::Pose { remaining, .. } => remaining,
                Received::Restart { remaining, .. } => {
                    restart();
                    remaining
                }
                Received::Points {
                    frame,
                    placement,
                    remaining,
                } => {
                    // One pass over the raw points: those the placement refuses, and how many of
                    // them are no-returns.
                    let (mut refused, mut no_returns) = (0u64, 0u64);
                    for raw in frame.points_from(0) {
                        if placement.placed(raw).is_none() {
                            refused += 1;
                            no_returns += u64::from(is_no_return(raw));
                        }
                    }
                    points(frame, placement);
                    self.note_refused(refused, no_returns);
                    remaining
                }
            };
        }
    }

    /// Where the points of the frame [`Receiver::held_frame`] holds go.
    pub fn placement(&self) -> &Placement {
        &self.placement
    }

    /// The frame the last [`Receiver::feed`] returned, until the next `feed`: a caller can map
    /// its points over several calls (the firmware's bounded ticks).
    pub fn held_frame(&self) -> Option<Frame<&[u8]>> {
        self.decoder.held_frame()
    }

    /// The map's origin in the world frame (metres); 0 until a point has arrived.
    pub fn origin(&self) -> [f64; 3] {
        metres_of_nm(self.origin.unwrap_or([0; 3]))
    }

    /// The map's origin (whole nanometres in the world frame) once the first point has set it:
    /// what a device keeps across a reset ([`Receiver::resuming`]).
    pub const fn map_origin(&self) -> Option<[i64; 3]> {
        self.origin
    }

    /// Metres from the origin, on each axis, past which points and poses are refused.
    pub const fn reach(&self) -> f32 {
        self.reach
    }

    /// The pose that holds now (sensor to world).
    pub const fn pose(&self) -> &Pose {
        &self.pose
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

/// The first point of `frame` that more than half of its points lie near (within half the
/// reach on every axis of the sensor frame, so within the reach however the pose turns them),
/// else the point most lie near (never a no-return; `None` if all are): where the map's origin
/// goes. A sensor glitch among the first
/// frame's points is then never the origin, which would leave the scene out of reach. Integer
/// compares only, and it stops at the first point a majority lies near, which in a frame
/// without glitches is the first: it costs a device one pass over one frame.
fn anchor(frame: &Frame<&[u8]>, exponent: i8, reach: f32) -> Option<[i32; 3]> {
    let scale = crate::link::wire::unit_scale(exponent)?;
    // Saturating: a reach of more units than u64 holds takes every point as near.
    let near = (f64::from(reach) / 2.0 / scale) as u64;
    let count = usize::from(frame.point_count());
    let (mut best, mut most) = (None, 0usize);
    // A no-return is never mapped, so it is never the origin either.
    for p in frame.points_from(0).filter(|&p| !is_no_return(p)) {
        let mut neighbours = 0usize;
        for q in frame.points_from(0) {
            let near_all = (u64::from(p[0].abs_diff(q[0])) <= near)
                & (u64::from(p[1].abs_diff(q[1])) <= near)
                & (u64::from(p[2].abs_diff(q[2])) <= near);
            neighbours += usize::from(near_all);
        }
        if neighbours > count / 2 {
            return Some(p);
        }
        if neighbours > most {
            (best, most) = (Some(p), neighbours);
        }
    }
    best
}

#[cfg(test)]
mod tests;
