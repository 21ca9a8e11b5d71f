//! The device's end of the host's carry frames ([`mema_core::link::uplink`]): it takes the line's
//! bytes, passes on the stream bytes of each carry frame that is the next in number into the
//! ring the firmware maps from, and refuses the rest, so the firmware sees the host's stream
//! whole and in order whatever the line dropped, flipped or repeated. What it refused and the
//! number it expects go back in the progress frames; the host sends again from there.

use mema_core::link::frame::Address;
use mema_core::link::framing::{Block, Deframer};
pub use mema_core::link::uplink::Request;
use mema_core::link::uplink::{self, CARRIED_AT, MAX_UP_FRAME_LEN, UpFrame};

use super::{PROGRESS_EVERY, Ring};

/// What a progress frame reports of the line: bytes taken from the line's ring, the carry frame
/// expected next, the host's frames refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LineReport {
    pub taken: u32,
    pub next: u32,
    pub refused: u32,
}

/// The carry frames' receiver (one frame's block of [`MAX_UP_FRAME_LEN`] bytes and a few
/// counters). It takes frames only of
/// the session the device is in and addressed to its boot; a start request it hands on with
/// the session asked for, whatever the device is in.
#[derive(Debug)]
pub struct Carrier {
    blocks: Deframer<MAX_UP_FRAME_LEN>,
    /// The device's boot and the session it is in (`0`: none).
    address: Address,
    /// Stream bytes of the last carry frame not yet passed on: the deframer's raw frame from
    /// `held` to `held_end`.
    held: usize,
    held_end: usize,
    next: u32,
    refused: u32,
    /// Something the host should hear of at once: a refused frame, one ahead of its turn, a
    /// repeat of one taken (its acknowledgement may have been lost).
    alert: bool,
    /// The line's taken count last reported.
    reported: u32,
    /// After the end of the stream: carried bytes are acknowledged and dropped.
    closed: bool,
    /// A listener's line (the map of a wired sensor goes out on it): requests of no session,
    /// never carry frames.
    listening: bool,
}

impl Carrier {
    /// The carrier of a device in boot `address.boot`, in session `address.session` (`0`:
    /// none, until a start request begins one), whose carry frames are numbered from `first`.
    pub const fn new(address: Address, first: u32) -> Self {
        Self {
            blocks: Deframer::new(),
            address,
            held: 0,
            held_end: 0,
            next: first,
            refused: 0,
            alert: false,
            reported: 0,
            closed: false,
            listening: false,
        }
    }

    /// The receiver of a listener's requests on a second line, for a device in boot `boot`
    /// mapping a sensor wired to its first: requests of no session (session `0`), addressed to
    /// this boot or to boot `0` (a listener that has heard no frame yet, asking for the end);
    /// carry frames are refused, the map comes from the sensor. A start request is handed on
    /// for the device to refuse.
    pub const fn listening(boot: u32) -> Self {
        let mut carrier = Self::new(Address { session: 0, boot }, 0);
        carrier.listening = true;
        carrier
    }

    /// In no session, with a sensor's stream possibly on the line: looks through `bytes`, which
    /// go to the mapper as they are, for a host's start request only (every other block is the
    /// sensor's, or noise, and is the mapper's business). Returns the first with its session.
    pub fn watch(&mut self, bytes: &[u8]) -> Option<(Request, u32)> {
        let mut rest = bytes;
        while let Some(end) = self.blocks.accumulate(rest) {
            rest = rest.get(end + 1..).unwrap_or(&[]);
            if let Block::Raw(raw) = self.blocks.end_block()
                && let Ok((from, UpFrame::Request(start @ Request::Start { .. }))) =
                    uplink::decode(raw)
            {
                return Some((start, from.session));
            }
        }
        None
    }

    /// Whether stream bytes wait for room in the firmware's ring.
    pub fn holding(&self) -> bool {
        self.held < self.held_end
    }

    /// From the end of the stream on, carry frames are acknowledged and their bytes dropped: the
    /// firmware no longer maps, and the line stays open for requests.
    pub fn close(&mut self) {
        self.closed = true;
        self.held = self.held_end;
    }

    /// Moves what the line's ring holds: stream bytes of carry frames taken in turn into `map`
    /// while it has room (the rest waits in the carrier and the line's ring), up to the next
    /// request, which it returns with the session it came from (the bytes after it wait).
    pub fn pump<const N: usize, const M: usize>(
        &mut self,
        line: &Ring<N>,
        map: &Ring<M>,
    ) -> Option<(Request, u32)> {
        loop {
            if self.holding() {
                let bytes = self
                    .blocks
                    .raw(self.held_end)
                    .get(self.held..)
                    .unwrap_or(&[]);
                self.held += map.push(bytes);
                if self.holding() {
                    return None;
                }
            }
            let (mut empty, mut request) = (false, None);
            line.consume_front(|front| {
                empty = front.is_empty();
                let mut at = 0;
                while let Some(rest) = front.get(at..).filter(|r| !r.is_empty()) {
                    let Some(end) = self.blocks.accumulate(rest) else {
                        return front.len();
                    };
                    at += end + 1;
                    request = self.end_block();
                    // The carried bytes live in the deframer until passed on.
                    if request.is_some() || self.holding() {
                        return at;
                    }
                }
                at
            });
            if request.is_some() {
                return request;
            }
            if empty {
                return None;
            }
        }
    }

    /// A delimiter has come: the block before it is a frame, or noise.
    fn end_block(&mut self) -> Option<(Request, u32)> {
        let raw = match self.blocks.end_block() {
            Block::Idle => return None,
            Block::Raw(raw) => raw,
            Block::Refused(_) => {
                self.refuse();
                return None;
            }
        };
        let raw_len = raw.len();
        let (from, frame) = match uplink::decode(raw) {
            Ok(decoded) => decoded,
            Err(_) => {
                self.refuse();
                return None;
            }
        };
        if let UpFrame::Request(start @ Request::Start { .. }) = frame {
            return Some((start, from.session));
        }
        if self.listening {
            let to_us = from.session == 0 && (from.boot == self.address.boot || from.boot == 0);
            return match frame {
                UpFrame::Request(request) if to_us => Some((request, 0)),
                _ => {
                    self.refuse();
                    None
                }
            };
        }
        // Another session's frame, or one for another boot: never this map's.
        if from != self.address || self.address.session == 0 {
            self.refuse();
            return None;
        }
        match frame {
            UpFrame::Carry { sequence, bytes } => {
                let ahead = sequence.wrapping_sub(self.next);
                if ahead == 0 {
                    self.next = self.next.wrapping_add(1);
                    if !self.closed {
                        self.held = CARRIED_AT;
                        self.held_end = (CARRIED_AT + bytes.len()).min(raw_len);
                    }
                } else if ahead > u32::MAX / 2 {
                    // A repeat of one taken: the host has not heard that it was.
                    self.alert = true;
                } else {
                    self.refuse();
                }
                None
            }
            UpFrame::Request(request) => Some((request, from.session)),
        }
    }

    /// The device's boot and session.
    pub fn address(&self) -> Address {
        self.address
    }

    fn refuse(&mut self) {
        self.refused = self.refused.wrapping_add(1);
        self.alert = true;
    }

    /// What a progress frame should say now, if one is due: after something the host should
    /// hear of at once, after [`PROGRESS_EVERY`] bytes, or, once the stream has ended, when the
    /// line has gone quiet with bytes taken since the last (the host's last frames are
    /// acknowledged without waiting). Mid-stream a sender whose window is the ring's size
    /// always has the next [`PROGRESS_EVERY`] bytes on their way, so a report at every pause of
    /// the line there (QEMU paces the bytes unevenly) would only cost instructions.
    pub fn report_due<const N: usize>(&mut self, line: &Ring<N>) -> Option<LineReport> {
        let taken = line.taken() as u32;
        let since = taken.wrapping_sub(self.reported);
        let quiet = self.closed && since > 0 && line.is_empty() && !self.holding();
        if !(core::mem::take(&mut self.alert) || since >= PROGRESS_EVERY || quiet) {
            return None;
        }
        self.reported = taken;
        Some(LineReport {
            taken,
            next: self.next,
            refused: self.refused,
        })
    }
}

#[cfg(test)]
mod tests;
