//! A whole `mema device` session over a port: the host starts a session of its own, which the
//! device begins with a fresh map; the points stream goes out in carry frames
//! ([`mema_core::link::uplink`]) within the device's receive ring, and again from the first one
//! the device has not taken when it refuses one or stays quiet; the map comes back as frames
//! ([`super::device::MapFrames`]), and what did not arrive intact is asked for again. A device
//! that restarts mid-session is noticed at its first frame, and the session starts again from
//! the beginning; a map whose counts are not the stream's is refused.

use std::io::{Read, Write};
use std::ops::Range;
use std::time::{Duration, Instant};

use mema_core::link::frame::Address;
use mema_core::link::receiver::{DEFAULT_REACH, Receiver};
use mema_core::link::uplink::{self, MAX_CARRIED, MAX_RESEND, MAX_UP_FRAME_LEN, Request, UpFrame};

use super::device::{DeviceError, MapFrames};
use super::port::{ReadOutcome, read_some};

/// How long the device may say nothing new (an acknowledgement, an entity, the end) before
/// the session is given up, unless the caller says otherwise.
pub const SILENCE: Duration = Duration::from_secs(30);
/// How long frames may go unacknowledged, or an answer not come, before they are sent or asked
/// for again. A device acknowledges within a tick (milliseconds); after this long with nothing
/// taken, its ring is empty, whatever the line lost of what was counted in flight. Each time it
/// passes with nothing taken the sender waits twice as long, up to [`MAX_PATIENCE`]: a device
/// slowed down (a loaded machine under QEMU) is not sent the same frames again and again.
pub const RETRY: Duration = Duration::from_secs(1);
pub const MAX_PATIENCE: Duration = Duration::from_secs(8);
/// Times the same missing entities are asked for before the session gives up on them.
pub const MAX_ASKS: u32 = 20;
/// Times a lost timing frame is asked for again (with the end) before the map is taken without it.
pub const TIMING_ASKS: u32 = 3;
/// Times a session is started again after the device restarted in it, before the host gives up.
pub const MAX_RESTARTS: u32 = 3;

/// How a session runs: never more than `window` bytes beyond what the device has taken from
/// its ring, given up after `silence` with nothing new, carry frames numbered from
/// `first_carry` (0; a test starts them just before their wrap).
#[derive(Clone, Copy, Debug)]
pub struct SessionLimits {
    pub window: usize,
    pub silence: Duration,
    pub first_carry: u32,
}

/// What a session reports as it goes.
#[derive(Debug)]
pub enum SessionEvent<'a> {
    /// Bytes of carry frames the device has taken, bytes it has taken off its line.
    Progress { done: usize, taken: u64 },
    /// The session is starting again from the beginning, for this reason.
    Restart(&'a DeviceError),
}

/// The points and points frames a device maps of `stream`, as the receiver of `mema replay`
/// and of the device takes them (wrapping at 2^32, as the device's end frame counts).
pub fn stream_counts(stream: &[u8]) -> (u32, u32) {
    let mut receiver = Receiver::reaching(DEFAULT_REACH);
    // Both closures count into one place: a restart starts the counts again, as the device's.
    let counts = std::cell::Cell::new((0u32, 0u32));
    receiver.feed_all(
        stream,
        |frame, placement| {
            let (points, frames) = counts.get();
            counts.set((
                points.wrapping_add(placement.points(&frame).count() as u32),
                frames.wrapping_add(1),
            ));
        },
        || counts.set((0, 0)),
    );
    counts.get()
}

/// A session identifier no earlier session of this host is likely to have had: never 0.
pub fn new_session_id() -> u32 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    // splitmix64 of the time and the process: two hosts, or two runs, differ.
    let mut z = nanos ^ (u64::from(std::process::id()) << 32);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z as u32).max(1)
}

/// The stream as carry frames, each encoded once.
struct CarryFrames {
    wire: Vec<u8>,
    frames: Vec<Range<usize>>,
}

impl CarryFrames {
    fn of(stream: &[u8], to: Address, first: u32) -> Result<Self, DeviceError> {
        let mut wire = Vec::with_capacity(stream.len() + stream.len() / 20);
        let mut frames = Vec::with_capacity(stream.len() / MAX_CARRIED + 1);
        let mut out = [0u8; MAX_UP_FRAME_LEN];
        for (sequence, bytes) in stream.chunks(MAX_CARRIED).enumerate() {
            let frame = UpFrame::Carry {
                // Numbers wrap at 2^32 as the device's do.
                sequence: first.wrapping_add(sequence as u32),
                bytes,
            };
            let n = uplink::encode(to, &frame, &mut out).map_err(DeviceError::Encode)?;
            let start = wire.len();
            wire.extend_from_slice(&out[..n]);
            frames.push(start..wire.len());
        }
        Ok(Self { wire, frames })
    }

    fn frame(&self, i: usize) -> &[u8] {
        self.frames.get(i).map_or(&[], |r| &self.wire[r.clone()])
    }
}

/// The sender's account of the line.
struct Sender {
    /// The next carry frame to send.
    next: usize,
    /// Bytes written, and those of them believed lost on the line (after a quiet spell the
    /// device's ring is empty, whatever it has counted as taken).
    written: u64,
    lost: u64,
    /// When the device last took a carry frame, and what it expected then.
    acked_at: Instant,
    acked: u64,
    /// How long to wait for an acknowledgement now.
    patience: Duration,
    /// The device's refused count last seen, and the bytes written when the sender last went
    /// back: a refusal of bytes written before that is one it has already answered.
    refused: u32,
    back_at: u64,
}

/// Starts a session of its own with the device on `port`, sends `stream` (encoded points
/// frames) in carry frames, never more than `window` bytes beyond what the device has taken
/// from its ring, sends again what the device did not take, and receives the map frames until
/// the map is whole. `frames` ends holding the last session's frames (its counts say what went
/// wrong on the way) and goes on taking them after (queries: [`super::queries`]). A device that
/// restarts mid-session is noticed and the session started again from the beginning, at most
/// [`MAX_RESTARTS`] times. After `silence` with nothing new from the device the session ends
/// with [`DeviceError::Silent`].
pub fn send_and_receive(
    port: &mut (impl Read + Write),
    stream: &[u8],
    limits: SessionLimits,
    frames: &mut MapFrames,
    mut report: impl FnMut(SessionEvent<'_>),
) -> Result<Vec<u8>, DeviceError> {
    let (points, frame_count) = stream_counts(stream);
    let mut restarts = 0;
    loop {
        *frames = MapFrames::for_session(new_session_id());
        frames.carry_from(limits.first_carry);
        frames.counts.restarts = restarts;
        frames.expect(points, frame_count);
        match one_session(port, stream, limits, frames, &mut report) {
            Err(e @ DeviceError::Rebooted { .. }) if restarts < MAX_RESTARTS => {
                report(SessionEvent::Restart(&e));
                restarts += 1;
            }
            done => return done,
        }
    }
}

/// Asks the device to begin `frames`' session, again each [`RETRY`], until it says it has.
fn start(
    port: &mut (impl Read + Write),
    (silence, first, total): (Duration, u32, usize),
    frames: &mut MapFrames,
) -> Result<(), DeviceError> {
    let mut out = [0u8; MAX_UP_FRAME_LEN];
    let to = Address {
        session: frames.session(),
        boot: 0,
    };
    let n = uplink::encode(to, &UpFrame::Request(Request::Start { first }), &mut out)
        .map_err(DeviceError::Encode)?;
    let began = Instant::now();
    let mut asked: Option<Instant> = None;
    let mut buf = [0u8; 4096];
    while !frames.started() {
        if let Some(e) = frames.broken() {
            return Err(e);
        }
        if began.elapsed() > silence {
            if let Some(version) = frames.other_version() {
                return Err(DeviceError::Version(version));
            }
            let c = &frames.counts;
            if c.refused > 0 && c.frames == 0 {
                return Err(DeviceError::NoValidFrame {
                    seconds: silence.as_secs_f64(),
                    refused: c.refused,
                });
            }
            return Err(DeviceError::Silent {
                seconds: silence.as_secs_f64(),
                sent: 0,
                total,
            });
        }
        if asked.is_none_or(|t| t.elapsed() > RETRY) {
            port.write_all(&out[..n])?;
            port.flush()?;
            asked = Some(Instant::now());
        }
        match read_some(port, &mut buf) {
            ReadOutcome::Bytes(got) => frames.feed(&buf[..got]),
            ReadOutcome::Idle => {}
            ReadOutcome::Gone(why) => return Err(DeviceError::Gone(why)),
        }
    }
    Ok(())
}

/// One session, from its start to the map or the reason there is none.
fn one_session(
    port: &mut (impl Read + Write),
    stream: &[u8],
    limits: SessionLimits,
    frames: &mut MapFrames,
    report: &mut impl FnMut(SessionEvent<'_>),
) -> Result<Vec<u8>, DeviceError> {
    let SessionLimits {
        window,
        silence,
        first_carry,
    } = limits;
    start(port, (silence, first_carry, stream.len()), frames)?;
    let to = frames.address();
    let carry = CarryFrames::of(stream, to, first_carry)?;
    let total = carry.frames.len();
    let mut s = Sender {
        next: 0,
        written: 0,
        lost: 0,
        acked_at: Instant::now(),
        acked: 0,
        patience: RETRY,
        refused: 0,
        back_at: 0,
    };
    let mut buf = [0u8; 4096];
    let mut heard = Instant::now();
    let mut asked: Option<Instant> = None;
    let mut asks = 0u32;
    loop {
        let acked = frames.acked().min(total as u64);
        if acked != s.acked {
            s.acked = acked;
            s.acked_at = Instant::now();
            s.patience = RETRY;
            heard = Instant::now();
        }
        let acked = acked as usize;
        s.next = s.next.max(acked);
        let pending = s.next > acked;
        let mut refused_more = frames.counts.device_refused != s.refused;
        if refused_more && frames.taken() + s.lost <= s.back_at {
            s.refused = frames.counts.device_refused;
            refused_more = false;
        }
        if pending && (refused_more || s.acked_at.elapsed() > s.patience) {
            if !refused_more {
                // Quiet that long with frames out: the device's ring is empty.
                s.lost = s.written.saturating_sub(frames.taken());
                s.patience = (s.patience * 2).min(MAX_PATIENCE);
            }
            frames.counts.resent += (s.next - acked) as u64;
            frames.counts.went_back += 1;
            s.next = acked;
            s.refused = frames.counts.device_refused;
            s.back_at = s.written;
            s.acked_at = Instant::now();
        }
        // Within the window, a few frames at a time, so the device's answers are read as
        // they come.
        let mut burst = Vec::new();
        while s.next < total && burst.len() < 1024 {
            let frame = carry.frame(s.next);
            let in_flight = s.written.saturating_sub(frames.taken() + s.lost) as usize;
            if in_flight + burst.len() + frame.len() > window {
                break;
            }
            burst.extend_from_slice(frame);
            s.next += 1;
        }
        if !burst.is_empty() {
            port.write_all(&burst)?;
            port.flush()?;
            s.written += burst.len() as u64;
        }
        match read_some(port, &mut buf) {
            ReadOutcome::Bytes(n) => {
                // Only news counts as hearing from the device: a device that answers every
                // frame with a refusal, forever, is given up on as one that says nothing.
                let before = (frames.counts.entities, frames.ended());
                frames.feed(&buf[..n]);
                if let Some(e) = frames.broken() {
                    return Err(e);
                }
                if (frames.counts.entities, frames.ended()) != before {
                    heard = Instant::now();
                }
                let done = carry
                    .frames
                    .get(acked)
                    .map_or(carry.wire.len(), |r| r.start);
                report(SessionEvent::Progress {
                    done,
                    taken: frames.taken(),
                });
            }
            ReadOutcome::Idle => {}
            ReadOutcome::Gone(why) => return Err(DeviceError::Gone(why)),
        }
        if frames.ended() {
            if let Some(done) = whole_or_ask(port, frames, &mut asked, &mut asks) {
                return done;
            }
        } else if acked == total && asked.is_none_or(|t| t.elapsed() > 2 * RETRY) {
            // Everything taken and no end yet: it may be finishing, or its end was lost.
            let mut out = [0u8; MAX_UP_FRAME_LEN];
            if let Ok(n) = uplink::encode(to, &UpFrame::Request(Request::ResendEnd), &mut out) {
                if asked.is_some() {
                    frames.counts.ends_asked += 1;
                    port.write_all(&out[..n])?;
                    port.flush()?;
                }
                asked = Some(Instant::now());
            }
        }
        if heard.elapsed() > silence {
            let done = carry
                .frames
                .get(acked)
                .map_or(carry.wire.len(), |r| r.start);
            return Err(DeviceError::Silent {
                seconds: silence.as_secs_f64(),
                sent: done,
                total: carry.wire.len(),
            });
        }
    }
}

/// Once the device's end has come: the map, if it is whole and checked, or the entities that
/// did not arrive intact asked for again (once each [`RETRY`], `asked` the last time, `asks`
/// the times so far), given up after [`MAX_ASKS`]. `None`: asked, the answers to come.
pub(super) fn whole_or_ask(
    port: &mut impl Write,
    frames: &mut MapFrames,
    asked: &mut Option<Instant>,
    asks: &mut u32,
) -> Option<Result<Vec<u8>, DeviceError>> {
    if frames.missing().is_empty() {
        // A device sends its timing just before its end, and the end again brings it again:
        // asked for a few times, as the map is whole without it and only its cost would go
        // unsaid (a device that sends none costs a session TIMING_ASKS retries).
        if frames.lacks_timing() && frames.timing_asks < TIMING_ASKS {
            if asked.is_some_and(|t| t.elapsed() <= RETRY) {
                return None;
            }
            let mut out = [0u8; MAX_UP_FRAME_LEN];
            let request = UpFrame::Request(Request::ResendEnd);
            if let Ok(n) = uplink::encode(frames.address(), &request, &mut out) {
                if let Err(e) = port.write_all(&out[..n]).and_then(|()| port.flush()) {
                    return Some(Err(e.into()));
                }
                frames.counts.ends_asked += 1;
            }
            frames.timing_asks += 1;
            *asked = Some(Instant::now());
            return None;
        }
        match frames.map_file() {
            // A lost frame may have been a retraction or a carved slot's entity sent again
            // (PROTOCOL.md, "Retract"): some slot the host holds is stale, and which one no
            // frame says. Every entity again.
            Some(Err(DeviceError::Mismatch { .. }))
                if frames.counts.lost > 0 && *asks < MAX_ASKS =>
            {
                frames.forget_entities();
            }
            file => {
                return Some(file.unwrap_or(Err(DeviceError::Missing {
                    missing: Vec::new(),
                })));
            }
        }
    }
    let missing = frames.missing();
    if asked.is_some_and(|t| t.elapsed() <= RETRY) {
        return None;
    }
    if *asks == MAX_ASKS {
        let asks = *asks;
        return Some(Err(DeviceError::StillMissing { missing, asks }));
    }
    if let Err(e) = ask_for(port, frames.address(), &missing) {
        return Some(Err(e));
    }
    frames.counts.asked_again += missing.len() as u64;
    *asks += 1;
    *asked = Some(Instant::now());
    None
}

/// Asks for `missing` (sorted entity indices) again, in runs of at most [`MAX_RESEND`].
pub(super) fn ask_for(
    port: &mut impl Write,
    to: Address,
    missing: &[u32],
) -> Result<(), DeviceError> {
    let mut out = [0u8; MAX_UP_FRAME_LEN];
    let mut i = 0;
    while let Some(&first) = missing.get(i) {
        let mut count = 1u16;
        while count < MAX_RESEND
            && missing.get(i + usize::from(count)) == Some(&(first + u32::from(count)))
        {
            count += 1;
        }
        i += usize::from(count);
        if let Ok(n) = uplink::encode(
            to,
            &UpFrame::Request(Request::Resend { first, count }),
            &mut out,
        ) {
            port.write_all(&out[..n])?;
        }
    }
    port.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests;
