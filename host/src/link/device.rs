//! The host's side of a mapping device's link (`mema device`): the points go out within the
//! device's receive ring, the map comes back as frames ([`mema_core::downlink`]), and the map
//! file is rebuilt from them and checked against the length and CRC-32 the device sends.
//!
//! [`MapFrames`] takes the device's bytes in any pieces; [`super::session`] runs a whole
//! session over a port.

use mema_core::crc32::crc32;
use mema_core::downlink::{
    self, DeviceTiming, DownFrame, MAX_DOWN_FRAME_LEN, MapEnd, stored_entity,
};
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
    Encode(mema_core::map::EncodeError),
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
    /// Entities received (each once).
    pub entities: usize,
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
        })
    }
}

/// The device's frames as they arrive: entities by index, the progress, the end.
#[derive(Debug, Default)]
pub struct MapFrames {
    block: Vec<u8>,
    /// Past a block too long for any frame: skipped to the next delimiter.
    overlong: bool,
    entities: Vec<Option<MapEntity>>,
    next_sequence: Option<u32>,
    /// Bytes the device has taken from its ring (accumulated from its wrapping count).
    taken: u64,
    last_taken: u32,
    /// The carry frame the device expects next (accumulated from its wrapping number).
    acked: u64,
    last_next: u32,
    end: Option<MapEnd>,
    timing: Option<DeviceTiming>,
    /// Answers to queries, by the query's number: entity, value, ticks.
    answers: std::collections::HashMap<u32, (u32, f64, u32)>,
    pub counts: DownlinkCounts,
}

impl MapFrames {
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes the device's bytes, in any pieces.
    pub fn feed(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if b != 0 {
                if self.block.len() < MAX_DOWN_FRAME_LEN {
                    self.block.push(b);
                } else {
                    self.overlong = true;
                }
                continue;
            }
            let mut block = std::mem::take(&mut self.block);
            if std::mem::take(&mut self.overlong) {
                self.counts.refused += 1;
            } else if !block.is_empty() {
                match downlink::decode(&mut block) {
                    Ok((sequence, frame)) => self.accept(sequence, frame),
                    Err(_) => self.counts.refused += 1,
                }
            }
            block.clear();
            self.block = block;
        }
    }

    fn accept(&mut self, sequence: u32, frame: DownFrame) {
        self.counts.frames += 1;
        if let Some(expected) = self.next_sequence {
            self.counts.lost += u64::from(sequence.wrapping_sub(expected));
        }
        self.next_sequence = Some(sequence.wrapping_add(1));
        match frame {
            DownFrame::Entity { index, entity } => {
                let i = index as usize;
                // An index past any map's size is a corrupt frame that passed its CRC.
                if i >= 1 << 24 {
                    self.counts.refused += 1;
                    return;
                }
                if self.entities.len() <= i {
                    self.entities.resize(i + 1, None);
                }
                if self.entities[i].replace(entity).is_none() {
                    self.counts.entities += 1;
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
            DownFrame::Timing(t) => self.timing = Some(t),
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

    /// The entities received, in index order, in the map's frame (once the map is whole).
    pub fn entities(&self) -> Vec<mema_core::geometry::Entity> {
        self.entities.iter().flatten().map(|e| e.entity).collect()
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

    /// The entities the end says the map has and that have not arrived intact.
    pub fn missing(&self) -> Vec<u32> {
        let Some(end) = self.end else {
            return Vec::new();
        };
        (0..end.entities)
            .filter(|&i| self.entities.get(i as usize).is_none_or(Option::is_none))
            .collect()
    }

    /// The map file, once the end has come: rebuilt from the entities as the device's own
    /// encoder writes it, and checked against the length and CRC-32 it sent.
    pub fn map_file(&self) -> Option<Result<Vec<u8>, DeviceError>> {
        let end = self.end?;
        Some(self.rebuild(&end))
    }

    fn rebuild(&self, end: &MapEnd) -> Result<Vec<u8>, DeviceError> {
        let count = end.entities as usize;
        let missing = self.missing();
        if !missing.is_empty() {
            return Err(DeviceError::Missing { missing });
        }
        let entities = self.entities.iter().take(count).flatten().copied();
        let stored = entities.map(|e| stored_entity(e, end.shift, end.layout));
        let origin: [f64; 3] = std::array::from_fn(|j| end.origin[j] + f64::from(end.shift[j]));
        let mut out = vec![0u8; end.layout.encoded_len(count)];
        let len = encode_as(end.layout, origin, stored, &mut out).map_err(DeviceError::Encode)?;
        out.truncate(len);
        let got_crc = crc32(&out);
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
