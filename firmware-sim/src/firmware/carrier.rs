//! The device's end of the host's carry frames ([`mema_core::uplink`]): it takes the line's
//! bytes, passes on the stream bytes of each carry frame that is the next in number into the
//! ring the firmware maps from, and refuses the rest, so the firmware sees the host's stream
//! whole and in order whatever the line dropped, flipped or repeated. What it refused and the
//! number it expects go back in the progress frames; the host sends again from there.

pub use mema_core::uplink::Request;
use mema_core::uplink::{self, CARRIED_AT, MAX_UP_FRAME_LEN, UpFrame};

use super::{PROGRESS_EVERY, Ring};

/// What a progress frame reports of the line: bytes taken from the line's ring, the carry frame
/// expected next, the host's frames refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LineReport {
    pub taken: u32,
    pub next: u32,
    pub refused: u32,
}

/// The carry frames' receiver (about 260 bytes: one frame's block).
#[derive(Debug)]
pub struct Carrier {
    block: [u8; MAX_UP_FRAME_LEN],
    len: usize,
    /// Past a block too long for any frame: skipped to the next delimiter.
    overlong: bool,
    /// Stream bytes of the last carry frame not yet passed on: `block[held..held_end]`.
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
}

impl Default for Carrier {
    fn default() -> Self {
        Self::new()
    }
}

impl Carrier {
    pub const fn new() -> Self {
        Self {
            block: [0; MAX_UP_FRAME_LEN],
            len: 0,
            overlong: false,
            held: 0,
            held_end: 0,
            next: 0,
            refused: 0,
            alert: false,
            reported: 0,
            closed: false,
        }
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
    /// while it has room (the rest waits in the carrier and the line's ring), requests to
    /// `on_request`.
    pub fn pump<const N: usize, const M: usize>(
        &mut self,
        line: &Ring<N>,
        map: &Ring<M>,
        mut on_request: impl FnMut(Request),
    ) {
        loop {
            if self.holding() {
                let bytes = self.block.get(self.held..self.held_end).unwrap_or(&[]);
                self.held += map.push(bytes);
                if self.holding() {
                    return;
                }
            }
            let (mut empty, mut request) = (false, None);
            line.consume_front(|front| {
                empty = front.is_empty();
                let mut at = 0;
                while let Some(rest) = front.get(at..).filter(|r| !r.is_empty()) {
                    // A run of block bytes, copied at once, up to the next delimiter.
                    let run = rest.iter().position(|&b| b == 0).unwrap_or(rest.len());
                    let room = self.block.len() - self.len;
                    if let (Some(dst), Some(src)) = (
                        self.block.get_mut(self.len..self.len + run.min(room)),
                        rest.get(..run.min(room)),
                    ) {
                        dst.copy_from_slice(src);
                    }
                    self.len += run.min(room);
                    self.overlong |= run > room;
                    at += run;
                    if at == front.len() {
                        break;
                    }
                    at += 1;
                    request = self.end_block();
                    if request.is_some() || self.holding() {
                        return at;
                    }
                }
                front.len()
            });
            if let Some(r) = request {
                on_request(r);
            }
            if empty {
                return;
            }
        }
    }

    /// A delimiter has come: the block before it is a frame, or noise.
    fn end_block(&mut self) -> Option<Request> {
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overlong) {
            self.refuse();
            return None;
        }
        if len == 0 {
            return None;
        }
        let block = self.block.get_mut(..len)?;
        match uplink::decode(block) {
            Ok(UpFrame::Carry { sequence, bytes }) => {
                let ahead = sequence.wrapping_sub(self.next);
                if ahead == 0 {
                    self.next = self.next.wrapping_add(1);
                    if !self.closed {
                        self.held = CARRIED_AT;
                        self.held_end = CARRIED_AT + bytes.len();
                    }
                } else if ahead > u32::MAX / 2 {
                    // A repeat of one taken: the host has not heard that it was.
                    self.alert = true;
                } else {
                    self.refuse();
                }
                None
            }
            Ok(UpFrame::Request(request)) => Some(request),
            Err(_) => {
                self.refuse();
                None
            }
        }
    }

    fn refuse(&mut self) {
        self.refused = self.refused.wrapping_add(1);
        self.alert = true;
    }

    /// What a progress frame should say now, if one is due: after something the host should
    /// hear of at once, after [`PROGRESS_EVERY`] bytes, or when the line has gone quiet with
    /// bytes taken since the last (the host's last frames are acknowledged without waiting).
    pub fn report_due<const N: usize>(&mut self, line: &Ring<N>) -> Option<LineReport> {
        let taken = line.taken() as u32;
        let since = taken.wrapping_sub(self.reported);
        let quiet = since > 0 && line.is_empty() && !self.holding();
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
