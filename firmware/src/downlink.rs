//! The firmware's side of the way back ([`mema_core::link::downlink`]): entities as they freeze,
//! progress for the sender's window, the end, and what the host asks again.

use core::borrow::Borrow;

use mema_core::link::downlink::{self, DownFrame, MAX_DOWN_FRAME_LEN, MapEnd};
use mema_core::link::frame::Address;
use mema_core::map::{EncodeError, MapEntity};

use super::{Carving, Firmware, LineReport, RX_CAPACITY, Ring};

/// What the map's way back to the host has sent.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Downlink {
    /// The device's boot and the session it is in, in every frame.
    pub(super) address: Address,
    /// The next frame's sequence number.
    pub(super) sequence: u32,
    /// Frozen entities already sent.
    pub(super) sent_frozen: usize,
    /// The ring's taken count last reported.
    pub(super) reported: u32,
}

impl Downlink {
    /// Encodes `frame` as the next in sequence and hands its bytes to `sink`.
    fn send(&mut self, frame: &DownFrame, sink: &mut impl FnMut(&[u8])) {
        let mut out = [0u8; MAX_DOWN_FRAME_LEN];
        if let Ok(n) = downlink::encode(self.address, self.sequence, frame, &mut out) {
            sink(out.get(..n).unwrap_or(&[]));
            self.sequence = self.sequence.wrapping_add(1);
        }
    }

    /// Sends the map's entity `index` as the next frame.
    fn send_entity(&mut self, index: usize, entity: MapEntity, sink: &mut impl FnMut(&[u8])) {
        let index = index as u32;
        self.send(&DownFrame::Entity { index, entity }, sink);
    }
}

/// A progress frame goes out once the device has taken this many bytes since the last one: a
/// tenth of the ring, so a sender keeping the ring's size in flight is never held up long,
/// for 36 bytes back (a progress frame on the wire) per 312 in.
pub const PROGRESS_EVERY: u32 = (RX_CAPACITY / 10) as u32;

impl<const K: usize, const G: usize, const F: usize, R: Borrow<Ring<RX_CAPACITY>>, C: Carving>
    Firmware<K, G, F, R, C>
{
    /// The downlink's frames due now, each handed to `sink` whole: the entities frozen since
    /// the last call (final, so each leaves the device once), then a progress frame if the
    /// ring has given up [`PROGRESS_EVERY`] bytes since the last one. For the main loop,
    /// between ticks, of a device fed points frames directly (no carry frames).
    pub fn send_downlink(&mut self, mut sink: impl FnMut(&[u8])) {
        self.send_frozen(&mut sink);
        let taken = self.rx.borrow().taken() as u32;
        if taken.wrapping_sub(self.down.reported) >= PROGRESS_EVERY {
            self.down.reported = taken;
            let line = LineReport {
                taken,
                next: 0,
                refused: 0,
            };
            self.send_progress(line, sink);
        }
    }

    /// The entities frozen since the last call, each as a frame, once the map's origin has
    /// settled (before, a rival's poses may yet start the map again,
    /// [`mema_core::link::receiver::Received::Restart`]; [`Firmware::send_end`] sends what
    /// waited).
    pub fn send_frozen(&mut self, mut sink: impl FnMut(&[u8])) {
        if !self.receiver.settled() {
            return;
        }
        self.send_carved(&mut sink);
        let frozen = self.mapper.frozen().len();
        while self.down.sent_frozen < frozen {
            let index = self.down.sent_frozen;
            if let Some(entity) = self.mapper.frozen_entity(index) {
                self.down.send_entity(index, entity, &mut sink);
            }
            self.down.sent_frozen += 1;
        }
    }

    /// What carving and coarsening changed of the frozen entities already sent: slots the map
    /// no longer has are retracted (the highest first), and slots that hold another entity now
    /// are sent again, so the host's copy is the device's.
    fn send_carved(&mut self, sink: &mut impl FnMut(&[u8])) {
        let frozen = self.mapper.frozen().len();
        while self.down.sent_frozen > frozen {
            self.down.sent_frozen -= 1;
            let index = self.down.sent_frozen as u32;
            self.down.send(&DownFrame::Retract { index }, sink);
        }
        while let Some(index) = self.mapper.take_changed(self.down.sent_frozen) {
            if let Some(entity) = self.mapper.frozen_entity(index) {
                self.down.send_entity(index, entity, sink);
            }
        }
    }

    /// A progress frame with the line's account (a [`super::Carrier`]'s, on a device fed
    /// carry frames) and the points frames mapped.
    pub fn send_progress(&mut self, line: LineReport, mut sink: impl FnMut(&[u8])) {
        let frame = DownFrame::Progress {
            taken: line.taken,
            frames: self.stats.frames as u32,
            next: line.next,
            refused: line.refused,
        };
        self.down.send(&frame, &mut sink);
    }

    /// The device's boot and session its frames say they are from.
    pub fn link_address(&self) -> Address {
        self.down.address
    }

    /// Sets the boot and session the frames say they are from, and the next frame's sequence
    /// number: at boot.
    pub fn set_link_address(&mut self, address: Address, sequence: u32) {
        self.down.address = address;
        self.down.sequence = sequence;
    }

    /// Sends one downlink frame of the caller's (a board's [`DownFrame::Timing`]) in the
    /// downlink's sequence.
    pub fn send_frame(&mut self, frame: &DownFrame, mut sink: impl FnMut(&[u8])) {
        self.down.send(frame, &mut sink);
    }

    /// One frame addressed to a session other than the device's (a refusal of a host's start
    /// request names the session it refuses), in the downlink's sequence.
    pub fn send_frame_to(&mut self, session: u32, frame: &DownFrame, mut sink: impl FnMut(&[u8])) {
        let own = self.down.address;
        self.down.address.session = session;
        self.down.send(frame, &mut sink);
        self.down.address = own;
    }

    /// After [`Firmware::finish`]: the entities not sent yet (the working clusters'), then the
    /// end frame. Returns the file's length.
    pub fn send_end(&mut self, mut sink: impl FnMut(&[u8])) -> Result<usize, EncodeError> {
        // The last scan's carving, judged when the stream ended, on what was sent.
        self.send_carved(&mut sink);
        let first = self.down.sent_frozen;
        for (index, entity) in self.mapper.entities().enumerate().skip(first) {
            self.down.send_entity(index, entity, &mut sink);
        }
        self.send_end_again(sink)
    }

    /// The end frame alone (again, when the host asks): the file's layout, length and CRC-32,
    /// which the map is encoded once more to compute, a piece at a time (no buffer for it).
    pub fn send_end_again(&mut self, mut sink: impl FnMut(&[u8])) -> Result<usize, EncodeError> {
        // The file's own checksum, its last four bytes (the CRC-32 of every byte before them:
        // `downlink::map_checksum`), read as the map streams past.
        let mut last = [0u8; 4];
        // One pass over the shells for the layout, one to write them: each is a shell made
        // again per working cluster.
        let layout = self.mapper.layout();
        let len = self
            .mapper
            .encode_pieces_in(layout, self.receiver.origin(), |piece| {
                for &b in piece {
                    last = [last[1], last[2], last[3], b];
                }
            })?;
        let count = self.mapper.entity_count();
        let end = MapEnd {
            entities: u32::try_from(count).map_err(|_| EncodeError::TooManyEntities)?,
            layout,
            shift: self.mapper.file_shift(layout),
            origin: self.receiver.origin(),
            map_len: u32::try_from(len).map_err(|_| EncodeError::TooManyEntities)?,
            map_crc: u32::from_le_bytes(last),
            points: self.mapper.stats().points as u32,
            frames: self.stats.frames as u32,
        };
        self.down.send(&DownFrame::End(end), &mut sink);
        Ok(len)
    }

    /// Entity frames `first .. first + count` again, as the host asks: any frozen one, and
    /// after the end of the stream any of the map's (a working cluster's entity is not final
    /// before it).
    pub fn resend(&mut self, first: u32, count: u16, mut sink: impl FnMut(&[u8])) {
        let (first, count) = (first as usize, usize::from(count));
        let frozen = self.mapper.frozen().len();
        if self.stats.end_of_stream {
            let entities = self.mapper.entities().enumerate().skip(first).take(count);
            for (index, entity) in entities {
                self.down.send_entity(index, entity, &mut sink);
            }
            return;
        }
        if !self.receiver.settled() {
            return;
        }
        for index in first..first.saturating_add(count).min(frozen) {
            if let Some(entity) = self.mapper.frozen_entity(index) {
                self.down.send_entity(index, entity, &mut sink);
            }
        }
    }
}
