//! The device's main loop, one pass at a time: the same code on the STM32F405 board
//! (`boards/stm32f405`, between its `wfi`s) and in the simulator's session tests.
//!
//! A pass moves what the line's ring holds through the [`Carrier`] (the host's stream in carry
//! frames, its requests), ticks the [`Firmware`] while there is mapping work, sends what the
//! downlink has due, and once the stream has ended finishes the map, sends its last entities
//! and its end, and answers requests and queries. A start request for a session other than the
//! one the device is in asks the caller to reset the device into it ([`Poll::Reset`]): the new
//! session's map then starts from a fresh boot, with nothing of the last one in RAM.
//!
//! A device with a second line ([`Device::wired`]) also maps a sensor wired to the first one:
//! booted in no session, it passes the line's bytes to the mapper as they come (a sensor's
//! points and pose frames, PROTOCOL.md) while its carrier watches them for a host's start
//! request; once the mapper has taken a sensor's frame, the line is the sensor's alone
//! ([`Feed`]). The map then goes out on the second line ([`Out::Listener`]), whose receive
//! side carries a listener's requests (entities or the end again, queries).

use core::borrow::Borrow;

use mema_core::link::downlink::{DeviceLayout, DeviceTiming, DownFrame, SessionStatus};
use mema_core::link::frame::Address;
use mema_core::query::brute_force;

use super::{Carrier, Carving, Firmware, RX_CAPACITY, Request, Ring};

mod wired;

/// The second line's receive ring: a listener's requests only (a request is at most 45 bytes on
/// the wire; asking again for 550 entities takes nine of 26).
pub const LISTENER_RING: usize = 512;

/// Where a frame goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Out {
    /// The first line's transmitter: to the host whose session the device is in.
    Host,
    /// The second line's: to a listener, the map of a sensor wired to the first line.
    Listener,
}

/// What the first line's bytes are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feed {
    /// A host's session: its carry frames, taken in turn.
    Carried,
    /// No session, a second line wired: passed to the mapper as they come, and watched for a
    /// host's start request until the mapper takes a sensor's frame.
    Open,
    /// A sensor's frames: passed to the mapper, nothing else looked for.
    Sensor,
}

/// How far a ray is followed, metres (the host's `RAY_REACH`).
pub const RAY_REACH: f64 = 1_000.0;

/// The board's account of time: each piece of work runs inside one of these, so the timing
/// frame can say what mapping cost (a board times with its clock; a simulator need not).
pub trait Clock {
    /// One tick of the firmware: mapping work, its longest kept apart.
    fn tick(&mut self, work: impl FnOnce());
    /// The loop's other work (the carrier, the downlink).
    fn other<T>(&mut self, work: impl FnOnce() -> T) -> T;
    /// A query's work, and the ticks it took.
    fn query<T>(&mut self, work: impl FnOnce() -> T) -> (T, u32);
    /// What the work has cost so far.
    fn timing(&self) -> DeviceTiming;
}

/// A clock that keeps no time (the timing frame then says 0).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoClock;

impl Clock for NoClock {
    fn tick(&mut self, work: impl FnOnce()) {
        work()
    }
    fn other<T>(&mut self, work: impl FnOnce() -> T) -> T {
        work()
    }
    fn query<T>(&mut self, work: impl FnOnce() -> T) -> (T, u32) {
        (work(), 0)
    }
    fn timing(&self) -> DeviceTiming {
        DeviceTiming::default()
    }
}

/// What the caller does after a pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Poll {
    /// Nothing more to do until bytes arrive: sleep unless [`Device::awake`] says otherwise.
    Idle,
    /// A host asked for a new session: reset the device and boot it into `session`, its carry
    /// frames numbered from `first`.
    Reset { session: u32, first: u32 },
}

/// What a boot starts from: the device's boot and the session it was reset into (`0`: none),
/// the number of that session's first carry frame, and where its own counters start (the
/// downlink's sequence: `0` on a board; a test starts it just before its wrap).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Boot {
    pub address: Address,
    pub first_carry: u32,
    pub first_sequence: u32,
}

/// The mapping device: the firmware fed by the line through the carrier, its map sent back.
#[derive(Debug)]
pub struct Device<'a, const K: usize, const G: usize, const F: usize, C = ()> {
    firmware: &'a mut Firmware<K, G, F, &'a Ring<RX_CAPACITY>, C>,
    line: &'a Ring<RX_CAPACITY>,
    map: &'a Ring<RX_CAPACITY>,
    carrier: Carrier,
    layout: DeviceLayout,
    /// The line's delimiter count at the last pass that looked at the line.
    delimiters: u32,
    /// A session frame is due (at boot, and again when the host asks to start the session the
    /// device is in: its answer may have been lost).
    announce: bool,
    /// The timing frame sent with the end, once the map is finished.
    finished: Option<DownFrame>,
    feed: Feed,
    /// A sensor-fed pass stopped after a frame with bytes left: the next pass is due without a
    /// new delimiter.
    backlog: bool,
    /// The second line's receive ring and its requests' receiver, if one is wired.
    listener: Option<(&'a Ring<LISTENER_RING>, Carrier)>,
}

impl<'a, const K: usize, const G: usize, const F: usize, C: Carving> Device<'a, K, G, F, C> {
    /// A device in boot `boot` (`session`: the one it booted into, `0` for none), mapping into
    /// `firmware` from `map`, the line's bytes coming into `line`. Queries of the finished map
    /// scan the mapper's entities as it gives them: a copy of the map to scan would take a
    /// board 28 KB of RAM at K = 700.
    pub fn new(
        firmware: &'a mut Firmware<K, G, F, &'a Ring<RX_CAPACITY>, C>,
        (line, map): (&'a Ring<RX_CAPACITY>, &'a Ring<RX_CAPACITY>),
        boot: Boot,
        layout: DeviceLayout,
    ) -> Self {
        firmware.set_link_address(boot.address, boot.first_sequence);
        Self {
            firmware,
            line,
            map,
            carrier: Carrier::new(boot.address, boot.first_carry),
            layout,
            delimiters: 0,
            announce: true,
            finished: None,
            feed: Feed::Carried,
            backlog: false,
            listener: None,
        }
    }

    /// The device with a second line, whose receiver pushes into `listener`: booted in no
    /// session, it maps a sensor wired to the first line and sends the map on the second
    /// ([`Feed::Open`]); in a host's session the second line is not used.
    pub fn wired(mut self, listener: &'a Ring<LISTENER_RING>) -> Self {
        let address = self.carrier.address();
        if address.session == 0 {
            self.feed = Feed::Open;
        }
        self.listener = Some((listener, Carrier::listening(address.boot)));
        self
    }

    /// What the first line's bytes are taken for now.
    pub fn feed(&self) -> Feed {
        self.feed
    }

    /// Whether a pass has work without new bytes: mapping under way, carried bytes waiting, a
    /// frame to announce, or the line's ring full (its receiver waits for room, and a full
    /// ring of noise holds no delimiter to wake the loop).
    pub fn awake(&self, delimiters: u32) -> bool {
        delimiters != self.delimiters
            || self.announce
            || self.firmware.mapping()
            || self.carrier.holding()
            || self.backlog
            || self.line.len() == RX_CAPACITY
    }

    pub fn firmware(&self) -> &Firmware<K, G, F, &'a Ring<RX_CAPACITY>, C> {
        self.firmware
    }

    /// One pass of the main loop; `delimiters` is the count of `0x00` bytes the lines have
    /// received (a frame can be whole only after one), `send` puts bytes on a line's
    /// transmitter.
    pub fn poll(
        &mut self,
        delimiters: u32,
        clock: &mut impl Clock,
        send: &mut impl FnMut(Out, &[u8]),
    ) -> Poll {
        if core::mem::take(&mut self.announce) {
            let status = if self.carrier.address().session == 0 {
                SessionStatus::Booted
            } else {
                SessionStatus::Started
            };
            let frame = DownFrame::Session {
                status,
                layout: self.layout,
            };
            // At boot a wired device does not know yet whether a host or a sensor is coming:
            // both lines hear it.
            let feed = self.feed;
            self.firmware.send_frame(&frame, |b| {
                if feed != Feed::Sensor {
                    send(Out::Host, b);
                }
                if feed != Feed::Carried {
                    send(Out::Listener, b);
                }
            });
        }
        if !self.awake(delimiters) {
            return Poll::Idle;
        }
        self.delimiters = delimiters;
        let mut start: Option<(u32, u32)> = None;
        if self.feed != Feed::Carried {
            self.map_sensor(clock, send, &mut start);
            return match start {
                Some((session, first)) => Poll::Reset { session, first },
                None => Poll::Idle,
            };
        }
        if let Some((line, _)) = &self.listener {
            // In a host's session a listener's line has nothing to say.
            line.clear();
        }
        let send = &mut |b: &[u8]| send(Out::Host, b);
        if self.finished.is_some() {
            // Finished: only after a delimiter (every byte's interrupt wakes the loop, and a
            // pass over part of a frame would send a progress frame for each byte).
            self.answer_requests(clock, send, &mut start);
        } else {
            self.map_what_came(clock, send, &mut start);
        }
        let Self {
            firmware, carrier, ..
        } = self;
        clock.other(|| {
            if let Some(report) = carrier.report_due(self.line) {
                firmware.send_progress(report, &mut *send);
            }
        });
        match start {
            Some((session, _)) if session == self.carrier.address().session => {
                self.announce = true;
                Poll::Idle
            }
            Some((session, first)) => Poll::Reset { session, first },
            None => Poll::Idle,
        }
    }

    /// Answers every request the line holds.
    fn answer_requests(
        &mut self,
        clock: &mut impl Clock,
        send: &mut impl FnMut(&[u8]),
        start: &mut Option<(u32, u32)>,
    ) {
        let Self {
            firmware,
            carrier,
            line,
            map,
            finished,
            ..
        } = self;
        while let Some((r, session)) = clock.other(|| carrier.pump(line, map)) {
            if let Some(s) = answer(firmware, r, session, finished, clock, send) {
                *start = Some(s);
            }
        }
    }

    /// Until a pass neither maps nor finishes a frame nor holds carried bytes: the rings then
    /// hold no whole frame (a tick decodes all it can), and the bytes of the next one are left
    /// to arrive, rather than ticked through a byte at a time as they come.
    fn map_what_came(
        &mut self,
        clock: &mut impl Clock,
        send: &mut impl FnMut(&[u8]),
        start: &mut Option<(u32, u32)>,
    ) {
        loop {
            self.answer_requests(clock, send, start);
            let firmware = &mut *self.firmware;
            let mut frame_done = false;
            clock.tick(|| firmware.tick(|_| frame_done = true));
            if !(frame_done || firmware.mapping() || self.carrier.holding()) {
                break;
            }
        }
        let firmware = &mut *self.firmware;
        clock.other(|| firmware.send_frozen(&mut *send));
        self.finish_if_ended(clock, send);
    }

    /// Once the stream's end has been mapped: the map finished, what the stream cost, then the
    /// rest of the map entity by entity (the device holds no copy of the file).
    fn finish_if_ended(&mut self, clock: &mut impl Clock, send: &mut impl FnMut(&[u8])) {
        let firmware = &mut *self.firmware;
        if !firmware.stats().end_of_stream || self.finished.is_some() {
            return;
        }
        firmware.finish();
        self.carrier.close();
        let timing = DownFrame::Timing(clock.timing());
        firmware.send_frame(&timing, &mut *send);
        let _ = firmware.send_end(&mut *send);
        self.finished = Some(timing);
    }
}

/// Answers a request of the host's: entities again, or once the map is finished the timing
/// and end frames again, or a query of the map (the core's no_std queries, timed). A start
/// request is handed back with its session for the loop to act on.
fn answer<
    const K: usize,
    const G: usize,
    const F: usize,
    R: Borrow<Ring<RX_CAPACITY>>,
    C: Carving,
>(
    firmware: &mut Firmware<K, G, F, R, C>,
    request: Request,
    session: u32,
    finished: &Option<DownFrame>,
    clock: &mut impl Clock,
    send: &mut impl FnMut(&[u8]),
) -> Option<(u32, u32)> {
    match (request, finished) {
        (Request::Start { first }, _) => return Some((session, first)),
        (Request::Resend { first, count }, _) => firmware.resend(first, count, &mut *send),
        (Request::ResendEnd, Some(timing)) => {
            firmware.send_frame(timing, &mut *send);
            let _ = firmware.send_end_again(&mut *send);
        }
        (
            Request::Query {
                number,
                ray,
                point,
                direction,
            },
            Some(_),
        ) => {
            let ((entity, value), ticks) = clock.query(|| {
                let map = firmware.mapper().entities().map(|e| e.entity);
                let p = point.map(f64::from);
                if ray {
                    brute_force::ray_cast_of(map, p, direction.map(f64::from), RAY_REACH)
                        .map_or((u32::MAX, f64::INFINITY), |h| (h.entity as u32, h.t))
                } else {
                    brute_force::nearest_of(map, p).map_or((u32::MAX, f64::INFINITY), |n| {
                        (n.entity as u32, n.signed_distance)
                    })
                }
            });
            let frame = DownFrame::Answer {
                query: number,
                ray,
                entity,
                value,
                ticks,
            };
            firmware.send_frame(&frame, &mut *send);
        }
        // Not finished yet: the end goes out when it is, and queries wait for the map.
        (Request::ResendEnd | Request::Query { .. }, None) => {}
    }
    None
}
