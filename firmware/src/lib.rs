//! `mema-firmware`: the device's code, `no_std` and without an allocator, the one copy the 64 KiB
//! image (`firmware-sim/image`), the STM32F405 board (`firmware-sim/boards/stm32f405`) and the
//! simulator that checks them (`mema-firmware-sim`) all build.
//!
//! - [`Firmware`]: UART ring, frame decoder and streaming mapper in one struct, sized at compile
//!   time and meant to live in a `static`; [`Ring`], the receive ring an interrupt pushes into;
//! - [`Carrier`] and [`device::Device`]: a mapping device's end of the host's link (carry
//!   frames in turn, sessions, the map sent back), the board's main loop one pass at a time;
//! - [`source`]: the byte-source boundary between a UART and the firmware;
//! - `cortex_m` (feature `cortex-m`): what both Cortex-M images share, a painted stack and
//!   SysTick's clock and calibration.
//!
//! The firmware application:
//! The receive interrupt calls [`Firmware::on_receive`], which only copies bytes into the ring;
//! the main loop calls [`Firmware::tick`], which decodes what the ring holds and maps the points
//! of every accepted frame. Mapping never depends on how bytes were split between interrupts, so
//! the map is a function of the accepted frames alone. The ring is single-producer,
//! single-consumer ([`Ring`]): on a board it is a `static` the USART interrupt pushes into
//! while the main loop ticks ([`Firmware::with_ring`] holds a reference to it); the simulator
//! calls both from one thread, between ticks, which is the same ordering.
//!
//! **Snapshots.** [`Firmware::save`] copies the mapper (its whole state: clusters, centre grid,
//! join radius, counters, so the refit schedule resumes exactly) into a [`Snapshot`], which stands
//! for memory that survives a reset (retained RAM, or flash). After a reset,
//! [`Firmware::restart_from`] restores the mapper (and the map's origin) and starts a fresh
//! receiver, which resynchronises at the next delimiter. Frames accepted after the snapshot and before the reset are lost with
//! the RAM; the final map equals that of an uninterrupted run over the frames the restored mapper
//! holds plus those accepted after the restart.

#![cfg_attr(not(test), no_std)]
#![deny(missing_debug_implementations)]

use core::borrow::Borrow;

use mema_core::de::{DeParams, OutOfBounds};

use mema_core::fit::{FitParams, Initialisation, SemiAxisBounds};
use mema_core::fitness::VolumeTerm;
use mema_core::geometry::Degeneration;
use mema_core::link::receiver::{Received, Receiver, ReceiverStats, is_no_return};
use mema_core::link::wire::DecoderStats;
use mema_core::map::EncodeError;
use mema_core::stream::{
    Pacing, StreamMapper, StreamModel, StreamParams, StreamStats, summary_layout,
};

mod carrier;
pub mod carving;
#[cfg(feature = "cortex-m")]
pub mod cortex_m;
pub mod device;
mod downlink;
mod ring;
pub mod source;
pub use carrier::{Carrier, LineReport, Request};
pub use carving::Carving;
use downlink::Downlink;
pub use downlink::PROGRESS_EVERY;
pub use ring::Ring;

/// The receive ring: two of the largest frames, so one frame can be decoded while the next
/// lands (the size `mema device` keeps in flight).
pub const RX_CAPACITY: usize = mema_core::link::downlink::RING_BYTES;

/// The image's layout: K = 400 ellipsoids as 150 working clusters and 250 frozen entities, the
/// split that fits a 64 KiB part with its stack (`mema-firmware-sim budget`).
pub const IMAGE_WORKING: usize = 150;
pub const IMAGE_FROZEN: usize = 250;
/// The STM32F405 board's layout (`boards/stm32f405`): the same 150 working clusters and 550
/// frozen entities, K = 700. The part's time binds before its RAM: every entity frozen costs a
/// fit, and `firmware-sim/check.sh` holds the board under 10,000 instructions a point on car6
/// and the demo drive in both models. The map's fidelity at K = 700 against K = 400 and the
/// host's batch map: docs/board.md ("The board's layout").
pub const BOARD_WORKING: usize = IMAGE_WORKING;
pub const BOARD_FROZEN: usize = 550;
/// The board's carving images (rows, columns around the whole sphere: 1.45 by 0.70 degrees),
/// one byte a pixel, in its 64 KiB of core-coupled RAM, which nothing else uses: 124 rows, not
/// 128, leave room for the carver's own fields and its table of ranges. The board's map is
/// `mema replay -k 700 --working 150 --carve 124x512`'s.
pub const BOARD_CARVE_IMAGE: [u16; 2] = [124, 512];
/// The board's images take every other return of a scan ([`mema_core::stream::Carver::sample`]):
/// every return costs the demo drive's paper model about 400 instructions a point, above the
/// board's 10,000 (`firmware-sim/check.sh`); every other one carved the walking drive's walker
/// as all of them did (`mema replay --carve-every`, tests/tests/walker.rs).
pub const BOARD_CARVE_EVERY: u16 = 2;
/// Pixels of [`BOARD_CARVE_IMAGE`].
pub const BOARD_CARVE_PIXELS: usize = BOARD_CARVE_IMAGE[0] as usize * BOARD_CARVE_IMAGE[1] as usize;

/// The image's reach (metres from the map's origin on any axis; see
/// [`mema_core::link::receiver::DEFAULT_REACH`]): a layout for a robot that stays closer to its
/// first point can refuse more.
pub const IMAGE_REACH: f32 = mema_core::link::receiver::DEFAULT_REACH;
/// The image's centre-hash buckets: 0.85 per working cluster keeps chains short. The map does
/// not depend on it (the host maps with 4,096 to the same bytes); 256 rather than 512 bought
/// back the 512 bytes of RAM that the frozen entities' rotation codes and the shell model's
/// parameters cost, and 128 rather than 256 half of the 564 that the coarsening's sweep order
/// and longer candidate list cost, so static RAM and the stack stay under 64 KiB.
pub const IMAGE_BUCKETS: usize = 128;

/// Most points one tick maps: with at most one fit or merge pass on top, the tick's length is
/// bounded whatever the ring holds (a frame carries up to 128).
pub const TICK_POINTS: usize = 32;

/// One cluster refit per this many points: the host's `REFIT_INTERVAL`, so both map alike.
pub const REFIT_INTERVAL: u32 = 1024;

/// The sphere tolerance of the host's defaults (`--sphere-tolerance`).
const SPHERE_TOLERANCE: f64 = 0.01;

/// The host's default parameters as a constant expression, so a `static` can be initialised with
/// them (`FitParams::default()` is not `const`). A test checks they equal the host's defaults.
pub const fn stream_params(seed: u64, max_clusters: usize, max_frozen: usize) -> StreamParams {
    model_params(seed, max_clusters, max_frozen, StreamModel::Paper)
}

/// Shells as the host's `--model shells` makes them.
pub const SHELLS: StreamModel = StreamModel::shells(SPHERE_TOLERANCE);

/// [`stream_params`] with the entity model chosen.
pub const fn model_params(
    seed: u64,
    max_clusters: usize,
    max_frozen: usize,
    model: StreamModel,
) -> StreamParams {
    StreamParams {
        fit: FitParams {
            alpha: mema_core::fitness::PAPER_ALPHA,
            volume: VolumeTerm::Exact,
            de: DeParams {
                mutation: 1.2,
                crossover: 0.7,
                generations: 50,
            },
            bounds: SemiAxisBounds::Spread {
                lower: 0.05,
                upper: 3.0,
            },
            out_of_bounds: OutOfBounds::Clamp,
            initialisation: Initialisation::MomentSeeded,
            degeneration: Degeneration {
                threshold: 4.0,
                sphere_tolerance: SPHERE_TOLERANCE,
            },
        },
        seed,
        max_clusters: summary_layout(max_clusters + max_frozen, max_frozen).0,
        max_frozen,
        refit_interval: REFIT_INTERVAL,
        tolerance: 0.0,
        model,
        pacing: Pacing::device(&model),
        final_clusters: summary_layout(max_clusters + max_frozen, max_frozen).1,
    }
}

/// What the firmware counts itself (the decoder and mapper keep their own counters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FirmwareStats {
    pub ticks: u64,
    /// Frames whose points are in the map: since boot (or restored with a snapshot), or since
    /// the map last started again ([`FirmwareStats::map_starts`]).
    pub frames: u64,
    /// Times the map started again because later poses outvoted the first
    /// ([`mema_core::link::receiver::Received::Restart`]).
    pub map_starts: u64,
    /// Bytes the ring had no room for.
    pub ring_overruns: u64,
    /// Most bytes the ring held at a tick.
    pub ring_peak: usize,
    /// Most points one tick mapped.
    pub tick_points_peak: usize,
    pub restarts: u64,
    pub end_of_stream: bool,
}

/// One accepted frame, as a tick reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AcceptedFrame {
    pub sequence: u32,
    /// Its place among the frames whose points are in the map (0: the first since the map
    /// started): a caller that lists them drops the ones from this place on.
    pub place: u64,
    pub points: u16,
    pub end_of_stream: bool,
}

/// The application state. `K` working clusters, `G` centre-hash buckets, `F` frozen entities;
/// `R` holds the receive ring or refers to it; `C` carves what later scans see through
/// ([`Carving`]; `()`, nothing).
#[derive(Debug)]
pub struct Firmware<
    const K: usize,
    const G: usize,
    const F: usize = 0,
    R = Ring<RX_CAPACITY>,
    C = (),
> {
    /// The ring, held (the simulator's) or referred to (a board's `static`).
    rx: R,
    receiver: Receiver,
    mapper: StreamMapper<K, G, F>,
    /// The next point to map of the decoder's held frame, while a frame is part mapped.
    cursor: Option<usize>,
    /// A periodic refit fell due at a point that already fitted: the next tick runs it.
    refit_due: bool,
    stats: FirmwareStats,
    down: Downlink,
    carving: C,
}

/// The state that survives a reset.
#[derive(Debug)]
pub struct Snapshot<const K: usize, const G: usize, const F: usize = 0> {
    mapper: StreamMapper<K, G, F>,
    /// The receiver's map origin: the mapper's points are relative to it.
    origin: Option<[i64; 3]>,
    frames: u64,
    /// [`FirmwareStats::map_starts`] when saved: a snapshot of a map since started again is
    /// stale.
    map_starts: u64,
    saved: bool,
}

impl<const K: usize, const G: usize, const F: usize> Snapshot<K, G, F> {
    /// An empty snapshot: restarting from it is restarting from scratch.
    pub const fn new(params: StreamParams) -> Self {
        Self {
            mapper: StreamMapper::new(params),
            origin: None,
            frames: 0,
            map_starts: 0,
            saved: false,
        }
    }

    /// Frames the saved mapper holds.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    pub fn is_saved(&self) -> bool {
        self.saved
    }

    /// Whether this snapshot is of the map `stats` describes: not saved before the map last
    /// started again.
    pub fn is_of(&self, stats: &FirmwareStats) -> bool {
        self.map_starts == stats.map_starts
    }
}

impl<const K: usize, const G: usize, const F: usize> Firmware<K, G, F> {
    /// A `const fn`: the state can be a `static` initialiser.
    // Always inlined, down to the core's constructors: the image builds its state in place in
    // a static, and a constructor left out of line (crates built for size) returns it through a
    // stack temporary as large as the state (48 KiB of stack at boot, measured).
    #[inline(always)]
    pub const fn new(params: StreamParams) -> Self {
        Self::with_reach(params, mema_core::link::receiver::DEFAULT_REACH)
    }

    /// [`Firmware::new`] refusing points and poses farther than `reach` metres from the map's
    /// origin on any axis (the layout's choice).
    #[inline(always)]
    pub const fn with_reach(params: StreamParams, reach: f32) -> Self {
        Firmware::with_ring(params, reach, Ring::new())
    }
}

impl<const K: usize, const G: usize, const F: usize, R> Firmware<K, G, F, R> {
    /// [`Firmware::with_reach`] on the ring `rx` holds: a board passes `&'static` its ring, which
    /// its receive interrupt pushes into.
    #[inline(always)]
    pub const fn with_ring(params: StreamParams, reach: f32, rx: R) -> Self {
        Firmware::carving(params, reach, rx, ())
    }
}

impl<const K: usize, const G: usize, const F: usize, R, C> Firmware<K, G, F, R, C> {
    /// [`Firmware::with_ring`] carving with `carving` (a board's carver, in RAM of its own).
    #[inline(always)]
    pub const fn carving(params: StreamParams, reach: f32, rx: R, carving: C) -> Self {
        Self {
            rx,
            receiver: Receiver::reaching(reach),
            mapper: StreamMapper::new(params),
            cursor: None,
            refit_due: false,
            stats: FirmwareStats {
                ticks: 0,
                frames: 0,
                map_starts: 0,
                ring_overruns: 0,
                ring_peak: 0,
                tick_points_peak: 0,
                restarts: 0,
                end_of_stream: false,
            },
            down: Downlink {
                address: mema_core::link::frame::Address {
                    session: 0,
                    boot: 0,
                },
                sequence: 0,
                sent_frozen: 0,
                reported: 0,
            },
            carving,
        }
    }
}

impl<const K: usize, const G: usize, const F: usize, R: Borrow<Ring<RX_CAPACITY>>, C: Carving>
    Firmware<K, G, F, R, C>
{
    /// The receive interrupt: copies bytes into the ring; bytes past its capacity are dropped and
    /// counted, as a UART overrun drops them. Returns the bytes kept.
    pub fn on_receive(&mut self, bytes: &[u8]) -> usize {
        let kept = self.rx.borrow().push(bytes);
        self.stats.ring_overruns += (bytes.len() - kept) as u64;
        kept
    }

    /// One main-loop pass, one bounded unit of work: at most [`TICK_POINTS`] points of one
    /// frame, and it ends right after a point whose mapping fitted an entity (a freeze, a merge
    /// pass, or the periodic refit), so no tick holds two fits. A refit falling due at a point that already
    /// fitted waits for the next tick, the rest of the frame and of the ring too: the main loop
    /// ticks while [`Firmware::busy`]. Ticks never change the map, only when its work is done:
    /// the points go into the mapper in the same order, with the same refits between them.
    pub fn tick(&mut self, mut on_frame: impl FnMut(AcceptedFrame)) {
        self.stats.ticks += 1;
        self.stats.ring_peak = self.stats.ring_peak.max(self.rx.borrow().len());
        if core::mem::take(&mut self.refit_due) {
            self.mapper.refit_stalest();
            return;
        }
        if self.cursor.is_none() && !self.decode_next() {
            return;
        }
        let Some(frame) = self.receiver.held_frame() else {
            self.cursor = None;
            return;
        };
        let placement = self.receiver.placement();
        let start = self.cursor.unwrap_or(0);
        if start == 0
            && !self
                .carving
                .step(placement.place([0, 0, 0]), &mut self.mapper)
        {
            return;
        }
        let fitted = |s: &StreamStats| (s.frozen, s.merges, s.refits);
        let before = fitted(self.mapper.stats());
        let mut next = start;
        // From `start`, not `points().skip(start)`: skipping an iterator of points converts
        // the points it skips, a third of a frame's conversions again at 32 points a tick.
        let (mut refused, mut no_returns) = (0, 0);
        for raw in frame.points_from(start) {
            next += 1;
            // A no-return or out of reach: counted, never mapped.
            let Some(point) = placement.placed(raw) else {
                refused += 1;
                no_returns += u64::from(is_no_return(raw));
                if next - start == TICK_POINTS {
                    break;
                }
                continue;
            };
            let refit = self.mapper.ingest_observed(point, &mut ());
            self.carving.add_return(point);
            let fitted_now = fitted(self.mapper.stats()) != before;
            if refit && fitted_now {
                self.refit_due = true;
            } else if refit {
                self.mapper.refit_stalest();
            }
            if refit || fitted_now || next - start == TICK_POINTS {
                break;
            }
        }
        self.stats.tick_points_peak = self.stats.tick_points_peak.max(next - start);
        let (count, sequence, end_of_stream) =
            (frame.point_count(), frame.sequence(), frame.end_of_stream());
        self.receiver.note_refused(refused, no_returns);
        if next < usize::from(count) {
            self.cursor = Some(next);
            return;
        }
        self.cursor = None;
        let place = self.stats.frames;
        self.stats.frames += 1;
        self.stats.end_of_stream |= end_of_stream;
        on_frame(AcceptedFrame {
            sequence,
            place,
            points: count,
            end_of_stream,
        });
    }

    /// Feeds the ring to the decoder until it accepts a frame (true) or the ring is empty.
    fn decode_next(&mut self) -> bool {
        loop {
            let (mut empty, mut accepted, mut restart) = (false, false, false);
            let mut unit = 0.0f64;
            let receiver = &mut self.receiver;
            self.rx.borrow().consume_front(|front| {
                empty = front.is_empty();
                if empty {
                    return 0;
                }
                let (taken, points) = match receiver.feed(front) {
                    Received::Consumed => (front.len(), false),
                    Received::Skipped { remaining, .. } | Received::Pose { remaining, .. } => {
                        (front.len() - remaining.len(), false)
                    }
                    Received::Restart { remaining, .. } => {
                        restart = true;
                        (front.len() - remaining.len(), false)
                    }
                    Received::Points {
                        frame, remaining, ..
                    } => {
                        unit = frame.unit_scale();
                        (front.len() - remaining.len(), true)
                    }
                };
                accepted = points;
                taken
            });
            if restart {
                self.start_map_again();
            }
            if accepted {
                self.mapper.note_resolution(unit as f32);
                self.cursor = Some(0);
                return true;
            }
            if empty {
                return false;
            }
        }
    }

    /// The receiver gave up the map's origin for a rival's poses: the map so far was placed by a
    /// glitch and starts again. Nothing of it has left the device (frozen entities wait for a
    /// settled origin, [`Firmware::send_frozen`]), and the end frame's counts are the new map's.
    fn start_map_again(&mut self) {
        self.mapper.restart();
        self.carving.restart();
        self.refit_due = false;
        self.stats.frames = 0;
        self.stats.map_starts += 1;
        self.down.sent_frozen = 0;
    }

    /// Whether mapping work is under way: a part-mapped frame or a deferred refit (bytes in the
    /// ring aside). A board's main loop that ticks only when a frame's delimiter has come asks
    /// this too, so no frame is left half-mapped.
    pub fn mapping(&self) -> bool {
        self.refit_due || self.cursor.is_some()
    }

    /// Whether work is waiting: bytes in the ring, a part-mapped frame or a deferred refit.
    pub fn busy(&self) -> bool {
        self.refit_due || self.cursor.is_some() || !self.rx.borrow().is_empty()
    }

    /// Ends the stream: every cluster refitted from its final moments.
    pub fn finish(&mut self) {
        self.carving.end(&mut self.mapper);
        self.mapper.finish();
    }

    /// Writes the `.mema` bytes of the map as it stands (around the receiver's origin, as the
    /// host's `replay` writes it; the mapper's layout) and returns their length.
    pub fn encode_map(&self, out: &mut [u8]) -> Result<usize, EncodeError> {
        self.mapper.encode_into(self.receiver.origin(), out)
    }

    /// Sends the map's `.mema` bytes out piece by piece (a UART, a file): the device needs no
    /// buffer for the whole map, which at 400 entities would be up to 10 KB of its RAM (the
    /// paper's 25 bytes an entity; shells take 14).
    pub fn send_map(&self, sink: impl FnMut(&[u8])) -> Result<usize, EncodeError> {
        self.mapper.encode_pieces(self.receiver.origin(), sink)
    }

    /// Copies the mapper into `snapshot` (the memory that survives a reset). Meant for an idle
    /// moment (not [`Firmware::busy`]): a part-mapped frame or a deferred refit is not saved.
    pub fn save(&self, snapshot: &mut Snapshot<K, G, F>) {
        snapshot.mapper.clone_from(&self.mapper);
        snapshot.origin = self.receiver.map_origin();
        snapshot.frames = self.stats.frames;
        snapshot.map_starts = self.stats.map_starts;
        snapshot.saved = true;
    }

    /// After a reset: RAM is gone, so the ring and the decoder start empty and the mapper comes
    /// back from `snapshot` (or starts empty if none was saved).
    pub fn restart_from(&mut self, snapshot: &Snapshot<K, G, F>) {
        self.rx.borrow().clear();
        self.cursor = None;
        self.refit_due = false;
        self.receiver = Receiver::resuming(snapshot.origin, self.receiver.reach());
        self.mapper.clone_from(&snapshot.mapper);
        self.carving.restart();
        self.stats.frames = snapshot.frames;
        self.stats.map_starts = snapshot.map_starts;
        self.stats.end_of_stream = false;
        self.stats.restarts += 1;
    }

    pub fn mapper(&self) -> &StreamMapper<K, G, F> {
        &self.mapper
    }

    pub fn mapper_stats(&self) -> &StreamStats {
        self.mapper.stats()
    }

    pub fn decoder_stats(&self) -> &DecoderStats {
        self.receiver.decoder_stats()
    }

    pub fn receiver_stats(&self) -> &ReceiverStats {
        self.receiver.stats()
    }

    /// The map's origin (whole nanometres in the world) once a point has set it.
    pub fn map_origin(&self) -> Option<[i64; 3]> {
        self.receiver.map_origin()
    }

    pub fn stats(&self) -> &FirmwareStats {
        &self.stats
    }

    /// Bytes waiting in the ring.
    pub fn pending(&self) -> usize {
        self.rx.borrow().len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn const_parameters_are_the_host_defaults() {
        let p = stream_params(7, 150, 250);
        assert_eq!(p.fit, FitParams::default());
        assert_eq!(
            (p.seed, p.max_clusters, p.max_frozen, p.tolerance),
            (7, 150, 250, 0.0)
        );
        assert_eq!(p.model, StreamModel::Paper);
        let StreamModel::Shells(shells) = SHELLS else {
            panic!("SHELLS is the shell model");
        };
        assert_eq!(
            (shells.tangent_scale, shells.normal_scale, shells.min_ratio),
            (2.0, 0.7, 1e-3)
        );
        assert_eq!(
            shells.degeneration.sphere_tolerance,
            FitParams::default().degeneration.sphere_tolerance
        );
    }
}
