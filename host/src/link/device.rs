//! The host's side of a mapping device's link (`mema device`): the points go out within the
//! device's receive ring, the map comes back as frames ([`mema_core::link::downlink`]), and the map
//! file is rebuilt from them and checked against the length and CRC-32 the device sends.
//!
//! [`MapFrames`] takes the device's bytes in any pieces; [`super::session`] runs a whole
//! session over a port.

use mema_core::link::downlink::{
    self, DOWNLINK_VERSION, DeviceLayout, DeviceTiming, DownFrame, MAX_DOWN_FRAME_LEN, MapEnd,
    SessionStatus, map_checksum, stored_entity,
};
use mema_core::link::frame::{Address, LinkError};
use mema_core::link::framing::{Block, Deframer};
use mema_core::map::{MapEntity, encode_as};
use serde::Serialize;

/// Why a session gave no map.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    #[error("the device sent its end but entities {missing:?} never arrived intact")]
    Missing { missing: Vec<u32> },
    #[error(
        "the map rebuilt from the device's frames is not its map ({got_len} bytes, CRC-32 {got_crc:08x}; the device says {len} bytes, {crc:08x})"
    )]
    Mismatch {
        got_len: usize,
        got_crc: u32,
        len: u32,
        crc: u32,
    },
    #[error("the device's map cannot be written: {0:?}")]
    MapEncode(mema_core::map::EncodeError),
    #[error(
        "the device sent its end but entities {missing:?} never arrived intact, asked for {asks} times"
    )]
    StillMissing { missing: Vec<u32>, asks: u32 },
    #[error("the device said nothing new for {seconds} s ({sent} of {total} bytes acknowledged)")]
    Silent {
        seconds: f64,
        sent: usize,
        total: usize,
    },
    #[error(
        "nothing from the device for {seconds} s ({frames} frames heard, {entities} entities, no end; its last progress: {mapped} stream frames mapped, {refused} refused): no sensor streams to it, or this is not its map's line"
    )]
    Quiet {
        seconds: f64,
        frames: u64,
        entities: usize,
        /// The stream's frames the device said it had mapped, and refused, in its last
        /// progress: which side of the device the silence is on.
        mapped: u32,
        refused: u32,
    },
    #[error(
        "the device restarted mid-session (boot {from} -> {to}): its map lost what it had mapped"
    )]
    Rebooted { from: u32, to: u32 },
    #[error("the device refused the session: {0}")]
    Refused(String),
    #[error(
        "the device mapped {got_points} points in {got_frames} frames, but the stream sent holds {points} in {frames}: not this stream's map"
    )]
    Counts {
        got_points: u32,
        got_frames: u32,
        points: u32,
        frames: u32,
    },
    #[error(
        "the device speaks another protocol (version 0x{0:02x}; this mema speaks 0x{DOWNLINK_VERSION:02x}): update its firmware or mema"
    )]
    Version(u8),
    #[error("a frame could not be encoded: {0}")]
    Encode(LinkError),
    #[error(
        "no valid frame in {seconds} s ({refused} blocks refused): a line at another baud rate than the device's garbles every byte"
    )]
    NoValidFrame { seconds: f64, refused: u64 },
    #[error("the port is gone: {0}")]
    Gone(String),
    #[error("the port: {0}")]
    Io(#[from] std::io::Error),
}

/// What the device's frames said, and what went wrong on the way.
#[derive(Clone, Debug, Default, Serialize)]
pub struct DownlinkCounts {
    /// Frames decoded intact.
    pub frames: u64,
    /// Blocks refused (a CRC, COBS or length failure): line noise.
    pub refused: u64,
    /// Frames the sequence numbers say never arrived.
    pub lost: u64,
    /// The host's frames the device refused (its count: damaged, or ahead of their turn).
    pub device_refused: u32,
    /// Carry frames the host sent again, and the times it went back to send them.
    pub resent: u64,
    pub went_back: u64,
    /// Entities the host asked for again (each time asked), and the end.
    pub asked_again: u64,
    pub ends_asked: u64,
    /// Entities the device retracted: carved after it sent them.
    pub retracted: u64,
    /// Entities received (each once).
    pub entities: usize,
    /// Frames intact but not of this session and boot (a previous session's, or another
    /// host's): never part of the map.
    pub foreign: u64,
    /// Times the session was started again from the beginning (the device restarted).
    pub restarts: u32,
    /// Points and points frames the device mapped (its end frame's count, else its last
    /// progress's frames).
    pub points: u32,
    pub device_frames: u32,
    /// What the work cost the device, in instructions, where it said (a timing frame).
    pub instructions: Option<Instructions>,
}

/// A device's timing turned into instructions by its own calibration (under QEMU's
/// `-icount`, its timer counts instructions).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Instructions {
    /// The main loop's work and every receive interrupt, per point mapped.
    pub per_point: f64,
    /// The receive interrupt's share of that, per point.
    pub interrupt_per_point: f64,
    /// The longest single tick of the firmware.
    pub longest_tick: f64,
    /// The deepest the device's stack went, in bytes (0: not measured).
    pub stack_bytes: u64,
    /// Core clock cycles a point, as the part's own cycle counter counted them (silicon; QEMU
    /// has none, and its figures are the instructions above).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cycles_per_point: Option<f64>,
    /// Bytes the device's receive ring had no room for, and bytes its UART lost before they
    /// were read.
    pub ring_overruns: u32,
    pub line_overruns: u32,
}

impl Instructions {
    fn of(t: &DeviceTiming, points: u32) -> Option<Self> {
        if t.calib_ticks == 0 || points == 0 {
            return None;
        }
        let insns = |ticks: u64| ticks as f64 * t.calib_insns as f64 / t.calib_ticks as f64;
        Some(Self {
            per_point: insns(t.busy_ticks) / f64::from(points),
            interrupt_per_point: insns(t.interrupt_ticks) / f64::from(points),
            longest_tick: insns(t.longest_tick),
            stack_bytes: t.stack_bytes,
            cycles_per_point: (t.busy_cycles > 0).then(|| t.busy_cycles as f64 / f64::from(points)),
            ring_overruns: t.ring_overruns,
            line_overruns: t.line_overruns,
        })
    }
}

/// The device's frames as they arrive, of one session: entities by index, the progress, the
/// end. Frames of other sessions, or from another boot of the device, are counted and left
/// out; a frame from another boot after the session began says the device restarted.
#[derive(Debug, Default)]
pub struct MapFrames {
    blocks: Box<Deframer<MAX_DOWN_FRAME_LEN>>,
    /// The host's session (`0`: none).
    session: u32,
    /// A listener's: the frames of no session, of the first boot heard ([`MapFrames::listening`]).
    listening: bool,
    /// The device's boot that began the session, and what it said of itself.
    boot: Option<u32>,
    device: Option<DeviceLayout>,
    /// The device restarted (the boot the session began in, the one now), or refused the
    /// session (its reason).
    rebooted: Option<(u32, u32)>,
    refused_session: Option<u8>,
    /// The version of the last frame of another protocol version.
    other_version: Option<u8>,
    /// The points and points frames the stream sent holds: the device's end must say it
    /// mapped exactly these.
    expected: Option<(u32, u32)>,
    /// By index: a map of what arrived, so a corrupt index that passed its CRC sizes nothing.
    entities: std::collections::BTreeMap<u32, MapEntity>,
    next_sequence: Option<u32>,
    /// Bytes the device has taken from its ring (accumulated from its wrapping count).
    taken: u64,
    last_taken: u32,
    /// The carry frame the device expects next (accumulated from its wrapping number).
    acked: u64,
    last_next: u32,
    end: Option<MapEnd>,
    timing: Option<DeviceTiming>,
    /// The times the end was asked for again for its timing ([`super::session::TIMING_ASKS`]
    /// at most): a budget of its own, so entities asked for again do not spend it.
    pub(super) timing_asks: u32,
    /// Answers to queries, by the query's number: entity, value, ticks.
    answers: std::collections::HashMap<u32, (u32, f64, u32)>,
    pub counts: DownlinkCounts,
}

impl MapFrames {
    /// The frames of the host's session `session` (never `0`).
    pub fn for_session(session: u32) -> Self {
        Self {
            session,
            ..Self::default()
        }
    }

    /// A listener's frames (`mema device --listen`): the map of a sensor wired to the device,
    /// sent in no session. The first intact frame of no session names the boot whose map this
    /// is; a frame from another boot after it says the device restarted, and its map lost
    /// what it had mapped.
    pub fn listening() -> Self {
        Self {
            listening: true,
            ..Self::default()
        }
    }

    /// The points and points frames of the stream the host sends (wrapping at 2^32, as the
    /// device counts): a map whose end frame says otherwise is refused.
    pub fn expect(&mut self, points: u32, frames: u32) {
        self.expected = Some((points, frames));
    }

    /// The session's carry frames are numbered from `first`: the device's first progress
    /// expects it.
    pub fn carry_from(&mut self, first: u32) {
        self.last_next = first;
    }

    /// The host's session.
    pub fn session(&self) -> u32 {
        self.session
    }

    /// Who the host's frames go to: its session and, once the session began, the device's boot.
    pub fn address(&self) -> Address {
        Address {
            session: self.session,
            boot: self.boot.unwrap_or(0),
        }
    }

    /// Whether the device has begun the session.
    pub fn started(&self) -> bool {
        self.boot.is_some()
    }

    /// What the device said of itself when the session began.
    pub fn device_layout(&self) -> Option<DeviceLayout> {
        self.device
    }

    /// Why the session cannot go on, if it cannot: the device restarted, refused it, or speaks
    /// another protocol and nothing else.
    pub fn broken(&self) -> Option<DeviceError> {
        if let Some((from, to)) = self.rebooted {
            return Some(DeviceError::Rebooted { from, to });
        }
        if let Some(reason) = self.refused_session {
            let why = match reason {
                downlink::REASON_LISTENING => "it maps a sensor wired to it".to_string(),
                other => format!("reason {other}"),
            };
            return Some(DeviceError::Refused(why));
        }
        None
    }

    /// A version the device spoke that this host does not, if it never spoke this one.
    pub fn other_version(&self) -> Option<u8> {
        self.other_version.filter(|_| self.counts.frames == 0)
    }

    /// Takes the device's bytes, in any pieces.
    pub fn feed(&mut self, bytes: &[u8]) {
        let mut rest = bytes;
        while let Some(at) = self.blocks.accumulate(rest) {
            rest = rest.get(at + 1..).unwrap_or(&[]);
            let decoded = match self.blocks.end_block() {
                Block::Idle => continue,
                Block::Raw(raw) => downlink::decode(raw),
                Block::Refused(e) => Err(e.into()),
            };
            match decoded {
                Ok((from, sequence, frame)) => self.accept(from, sequence, frame),
                Err(LinkError::Version(v)) => {
                    self.other_version = Some(v);
                    self.counts.refused += 1;
                }
                Err(_) => self.counts.refused += 1,
            }
        }
    }

    /// Whether a frame from `from` belongs to the session, noting a restart of the device.
    fn of_this_session(&mut self, from: Address, frame: &DownFrame) -> bool {
        if let Some(boot) = self.boot {
            if from.boot != boot {
                self.rebooted.get_or_insert((boot, from.boot));
                return false;
            }
            return from.session == self.session;
        }
        if self.listening {
            if from.session != 0 {
                return false;
            }
            self.boot = Some(from.boot);
            if let DownFrame::Session { layout, .. } = frame {
                self.device = Some(*layout);
            }
            return true;
        }
        if from.session != self.session || self.session == 0 {
            return false;
        }
        match frame {
            DownFrame::Session {
                status: SessionStatus::Started,
                layout,
            } => {
                self.boot = Some(from.boot);
                self.device = Some(*layout);
                true
            }
            DownFrame::Session {
                status: SessionStatus::Refused { reason },
                ..
            } => {
                self.refused_session = Some(*reason);
                false
            }
            _ => false,
        }
    }

    fn accept(&mut self, from: Address, sequence: u32, frame: DownFrame) {
        if !self.of_this_session(from, &frame) {
            self.counts.foreign += 1;
            return;
        }
        self.counts.frames += 1;
        if let Some(expected) = self.next_sequence {
            self.counts.lost += u64::from(sequence.wrapping_sub(expected));
        }
        self.next_sequence = Some(sequence.wrapping_add(1));
        match frame {
            DownFrame::Entity { index, entity } => {
                if self.entities.insert(index, entity).is_none() {
                    self.counts.entities += 1;
                }
            }
            DownFrame::Retract { index } => {
                if self.entities.remove(&index).is_some() {
                    self.counts.retracted += 1;
                }
            }
            DownFrame::Progress {
                taken,
                frames,
                next,
                refused,
            } => {
                self.taken += u64::from(taken.wrapping_sub(self.last_taken));
                self.last_taken = taken;
                // A number behind the last is a stale report: never a step back.
                let ahead = next.wrapping_sub(self.last_next);
                if ahead <= u32::MAX / 2 {
                    self.acked += u64::from(ahead);
                    self.last_next = next;
                }
                self.counts.device_refused = self.counts.device_refused.max(refused);
                self.counts.device_frames = frames;
            }
            DownFrame::Timing(t) => {
                self.timing = Some(t);
                // Asked for again, it comes after the end it should have preceded.
                if let Some(end) = self.end {
                    self.counts.instructions = Instructions::of(&t, end.points);
                }
            }
            // A listener hears what map it is getting whenever the device says it.
            DownFrame::Session { layout, .. } => {
                if self.listening {
                    self.device = Some(layout);
                }
            }
            DownFrame::Answer {
                query,
                entity,
                value,
                ticks,
                ..
            } => {
                self.answers.insert(query, (entity, value, ticks));
            }
            DownFrame::End(end) => {
                self.counts.points = end.points;
                self.counts.device_frames = end.frames;
                self.counts.instructions =
                    self.timing.and_then(|t| Instructions::of(&t, end.points));
                self.end = Some(end);
            }
        }
    }

    /// Bytes the device has taken from its ring so far.
    pub fn taken(&self) -> u64 {
        self.taken
    }

    /// The answer to query `number`, if it has come: entity (`u32::MAX`: none), value, ticks.
    pub fn answer(&self, number: u32) -> Option<(u32, f64, u32)> {
        self.answers.get(&number).copied()
    }

    /// The map's entities, in index order, in the map's frame, once the map is whole (the
    /// end's count, every one of them arrived).
    pub fn entities(&self) -> Option<Vec<mema_core::geometry::Entity>> {
        let end = self.end?;
        (0..end.entities)
            .map(|i| self.entities.get(&i).map(|e| e.entity))
            .collect()
    }

    /// Instructions per tick of the device's timer, from its timing frame's calibration.
    pub fn instructions_per_tick(&self) -> Option<f64> {
        let t = self.timing?;
        (t.calib_ticks > 0).then(|| t.calib_insns as f64 / t.calib_ticks as f64)
    }

    /// Carry frames the device has taken (the number it expects next).
    pub fn acked(&self) -> u64 {
        self.acked
    }

    /// Whether the device has sent its end.
    pub fn ended(&self) -> bool {
        self.end.is_some()
    }

    /// Whether the end came without the timing frame a device sends just before it: lost on
    /// the line.
    pub fn lacks_timing(&self) -> bool {
        self.end.is_some() && self.timing.is_none()
    }

    /// Forgets every entity received, so all are asked for again: the copy was found stale.
    pub fn forget_entities(&mut self) {
        self.entities.clear();
    }

    /// The entities the end says the map has and that have not arrived intact.
    pub fn missing(&self) -> Vec<u32> {
        let Some(end) = self.end else {
            return Vec::new();
        };
        (0..end.entities)
            .filter(|i| !self.entities.contains_key(i))
            .collect()
    }

    /// The map file, once the end has come: rebuilt from the entities as the device's own
    /// encoder writes it, and checked against the length and CRC-32 it sent.
    pub fn map_file(&self) -> Option<Result<Vec<u8>, DeviceError>> {
        let end = self.end?;
        Some(self.rebuild(&end))
    }

    fn rebuild(&self, end: &MapEnd) -> Result<Vec<u8>, DeviceError> {
        if let Some((points, frames)) = self.expected
            && (end.points, end.frames) != (points, frames)
        {
            return Err(DeviceError::Counts {
                got_points: end.points,
                got_frames: end.frames,
                points,
                frames,
            });
        }
        let count = end.entities as usize;
        let missing = self.missing();
        if !missing.is_empty() {
            return Err(DeviceError::Missing { missing });
        }
        let entities = self.entities.range(..end.entities).map(|(_, e)| *e);
        let stored = entities.map(|e| stored_entity(e, end.shift, end.layout));
        let origin: [f64; 3] = std::array::from_fn(|j| end.origin[j] + f64::from(end.shift[j]));
        let mut out = vec![0u8; end.layout.encoded_len(count)];
        let len =
            encode_as(end.layout, origin, stored, &mut out).map_err(DeviceError::MapEncode)?;
        out.truncate(len);
        let got_crc = map_checksum(&out);
        if len != end.map_len as usize || got_crc != end.map_crc {
            return Err(DeviceError::Mismatch {
                got_len: len,
                got_crc,
                len: end.map_len,
                crc: end.map_crc,
            });
        }
        Ok(out)
    }
}
