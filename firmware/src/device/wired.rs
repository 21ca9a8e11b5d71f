//! The device fed by a sensor wired to its first line ([`Feed::Open`], [`Feed::Sensor`]): the
//! line's bytes go to the mapper as they come (the sensor's own frames, no carry frames), and
//! the map and the answers to a listener's requests go out on the second line.

use mema_core::link::downlink::{DownFrame, REASON_LISTENING, SessionStatus};

use super::{Clock, Device, Feed, Out, answer};
use crate::{Carving, Request};

impl<const K: usize, const G: usize, const F: usize, C: Carving> Device<'_, K, G, F, C> {
    /// A pass fed by a sensor: the listener's requests, then the line's bytes into the
    /// mapper's ring and ticks until a frame has been mapped or nothing moves, then the frozen
    /// entities and progress, and the map once the stream has ended. One frame a pass: the
    /// loop between passes feeds the watchdog and sends what froze, while a sensor that never
    /// pauses keeps the line full. `start`: a host's start request seen on the first line
    /// while it was still open.
    pub(super) fn map_sensor(
        &mut self,
        clock: &mut impl Clock,
        send: &mut impl FnMut(Out, &[u8]),
        start: &mut Option<(u32, u32)>,
    ) {
        let to_listener = &mut |b: &[u8]| send(Out::Listener, b);
        self.answer_listener(clock, to_listener);
        if self.finished.is_some() {
            // The stream has ended: what a sensor sends after it is never mapped.
            self.line.clear();
            self.backlog = false;
            return;
        }
        let (mut frame_done, mut blocked);
        loop {
            clock.other(|| self.pass_on(start));
            // Bytes left on the line now found the ring full; those that come during the
            // tick are part of a frame whose delimiter will wake the loop.
            blocked = !self.line.is_empty();
            if start.is_some() {
                return;
            }
            let firmware = &mut *self.firmware;
            frame_done = false;
            clock.tick(|| firmware.tick(|_| frame_done = true));
            if self.feed == Feed::Open && firmware.decoder_stats().accepted > 0 {
                // A sensor's frame: the line is the sensor's, and a listener that came after
                // the boot hears what map this is.
                self.feed = Feed::Sensor;
                self.announce = true;
            }
            if frame_done || !(blocked || firmware.mapping()) {
                break;
            }
        }
        // Work left for the next pass, which no new delimiter may come to wake: the line's bytes
        // the ring had no room for, a frame part-mapped, or more whole frames after the one
        // just mapped. Part of a frame waits for its delimiter: passes that moved its bytes as
        // they came would tick once a byte, at a tick's cost each (up to a sixth of car6's
        // instructions a point, as often as the line's timing made it).
        self.backlog = blocked
            || self.firmware.mapping()
            || (frame_done && (self.firmware.busy() || !self.line.is_empty()));
        let firmware = &mut *self.firmware;
        clock.other(|| firmware.send_downlink(&mut *to_listener));
        if firmware.stats().end_of_stream {
            // With the map, what map it is: a listener may have missed every earlier saying.
            let about = DownFrame::Session {
                status: SessionStatus::Booted,
                layout: self.layout,
            };
            firmware.send_frame(&about, &mut *to_listener);
        }
        self.finish_if_ended(clock, to_listener);
    }

    /// Moves the line's bytes into the mapper's ring, as many as it has room for (the rest
    /// wait in the line's ring); while the line is open, the carrier watches them for a host's
    /// start request, and the move stops at one.
    fn pass_on(&mut self, start: &mut Option<(u32, u32)>) {
        let (map, open) = (self.map, self.feed == Feed::Open);
        loop {
            let carrier = &mut self.carrier;
            let n = self.line.consume_front(|front| {
                let n = map.push(front);
                if open
                    && let Some((Request::Start { first }, session)) =
                        carrier.watch(front.get(..n).unwrap_or(&[]))
                {
                    *start = Some((session, first));
                }
                n
            });
            if n == 0 || start.is_some() {
                return;
            }
        }
    }

    /// Answers every request the listener's line holds: entities again, the end again (after
    /// the session frame, for a listener that came after the boot), queries; a host's start
    /// request is refused, the first line being the sensor's.
    fn answer_listener(&mut self, clock: &mut impl Clock, send: &mut impl FnMut(&[u8])) {
        let Self {
            firmware,
            map,
            finished,
            layout,
            listener,
            ..
        } = self;
        let Some((line, carrier)) = listener else {
            return;
        };
        while let Some((request, session)) = clock.other(|| carrier.pump(*line, *map)) {
            let about = |status| DownFrame::Session {
                status,
                layout: *layout,
            };
            match request {
                Request::Start { .. } => {
                    let refusal = about(SessionStatus::Refused {
                        reason: REASON_LISTENING,
                    });
                    firmware.send_frame_to(session, &refusal, &mut *send);
                }
                Request::ResendEnd if finished.is_some() => {
                    firmware.send_frame(&about(SessionStatus::Booted), &mut *send);
                    let _ = answer(firmware, request, session, finished, clock, send);
                }
                _ => {
                    let _ = answer(firmware, request, session, finished, clock, send);
                }
            }
        }
    }
}
