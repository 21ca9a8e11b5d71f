//! The device's side of the link back: the map, an entity per frame, to the host (PROTOCOL.md,
//! "Device to host").
//!
//! A frame is framed as the points frames are (COBS, a `0x00` delimiter, CRC-32), with a
//! version byte of its own (`0x81`: bit 7 tells a device's frame from a sender's on a relay
//! or in a capture of both directions) and a sequence number the host checks for gaps:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 1 | version `0x81` |
//! | 1 | 1 | kind: `0` entity, `1` end of map, `2` progress, `3` device timing, `4` answer |
//! | 2 | 4 | sequence: 0 for the first frame after boot, +1 per frame |
//! | 6 | n | the kind's payload |
//! | 6 + n | 4 | CRC-32 of every byte before it |
//!
//! An **entity** frame carries one entity and its index in the map (frozen entities as they
//! freeze, the working ones at the end): index u32, kind u8, centre, weights and rotation
//! (x, y, z, w) as f32, in the mapper's frame (relative to the receiver's origin). The
//! **end** frame says how the map's file is written from them: the count, the layout
//! (0 axis-aligned, 1 oriented, 2 quantized, with the grid's three f32), the shift from the
//! receiver's origin to the file's (f32), the receiver's origin (f64, metres), the file's
//! length and CRC-32 (so a host that rebuilds the file with [`stored_entity`] and
//! `map::encode_as` knows it holds the device's map to the bit), and the points and points
//! frames the device mapped. A **progress** frame says how
//! many bytes the device has taken from its receive ring (u32, wrapping), how many points
//! frames it has mapped, and which carry frame it expects next with how many of the host's
//! frames it refused ([`crate::uplink`]): a sender that keeps what it has sent and the device
//! has not taken under the ring's size never overruns it, however slowly the device maps, and
//! one that sees the refused count grow sends again from the frame expected.

use crate::crc32::crc32;
use crate::geometry::{Entity, EntityKind, Point3};
use crate::map::record::Quantization;
use crate::map::{Layout, MapEntity};
use crate::rotation::Rotation;
use crate::wire::{cobs_decode_in_place, cobs_encode, cobs_max_encoded_len};

/// The receive ring of a mema device: two of the largest points frames, so one frame can be
/// decoded while the next lands. A sender keeps at most this many bytes beyond the device's
/// last progress frame in flight.
pub const RING_BYTES: usize = 2 * crate::wire::MAX_FRAME_LEN;

/// The version byte of a device-to-host frame.
pub const DOWNLINK_VERSION: u8 = 0x81;
const HEADER_LEN: usize = 6;
const CRC_LEN: usize = 4;
/// An entity frame's payload: index, kind, centre, weights, rotation.
pub const ENTITY_PAYLOAD_LEN: usize = 4 + 1 + 12 + 12 + 16;
/// An end frame's payload: count, layout and grid, shift, origin, file length and CRC, points
/// and frames mapped.
pub const END_PAYLOAD_LEN: usize = 4 + 1 + 12 + 12 + 24 + 4 + 4 + 4 + 4;
/// A progress frame's payload: bytes taken, frames mapped, the carry frame expected next and
/// the host's frames refused.
pub const PROGRESS_PAYLOAD_LEN: usize = 4 + 4 + 4 + 4;
/// A timing frame's payload: busy, interrupt and longest-tick counts, the calibration, the
/// deepest stack.
pub const TIMING_PAYLOAD_LEN: usize = 8 + 8 + 8 + 8 + 8 + 8;
/// An answer frame's payload: the query's number, what, entity, value, ticks.
pub const ANSWER_PAYLOAD_LEN: usize = 4 + 1 + 4 + 8 + 4;
/// The longest raw frame.
pub const MAX_RAW_LEN: usize = HEADER_LEN + END_PAYLOAD_LEN + CRC_LEN;
/// The longest frame on the wire, its delimiter included.
pub const MAX_DOWN_FRAME_LEN: usize = cobs_max_encoded_len(MAX_RAW_LEN) + 1;

const KIND_ENTITY: u8 = 0;
const KIND_END: u8 = 1;
const KIND_PROGRESS: u8 = 2;
const KIND_TIMING: u8 = 3;
const KIND_ANSWER: u8 = 4;

/// How the map's file is written from its entities.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapEnd {
    /// Entities in the map.
    pub entities: u32,
    pub layout: Layout,
    /// From the receiver's origin to the file's, in the mapper's frame (f32 metres).
    pub shift: [f32; 3],
    /// The receiver's origin in the world, metres.
    pub origin: [f64; 3],
    /// The file's length in bytes and its CRC-32.
    pub map_len: u32,
    pub map_crc: u32,
    /// Points and points frames the device mapped (wrapping past 2^32).
    pub points: u32,
    pub frames: u32,
}

/// What a device-to-host frame carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DownFrame {
    Entity {
        index: u32,
        entity: MapEntity,
    },
    End(MapEnd),
    /// Bytes taken from the receive ring since boot (wrapping) and points frames mapped; the
    /// number of the carry frame expected next and the host's frames refused since boot
    /// ([`crate::uplink`]; both `0` for a device fed without carry frames).
    Progress {
        taken: u32,
        frames: u32,
        next: u32,
        refused: u32,
    },
    /// What the device's work cost it, in its timer's ticks, sent before the end.
    Timing(DeviceTiming),
    /// The answer to a host's query ([`crate::uplink::Request::Query`]): the entity found
    /// (`u32::MAX`: none), the signed distance to the nearest surface or the distance along
    /// the ray, and the timer's ticks the query took.
    Answer {
        query: u32,
        ray: bool,
        entity: u32,
        value: f64,
        ticks: u32,
    },
}

/// A device's own account of its work, in ticks of its timer, with the calibration that turns
/// them into instructions (`calib_insns` instructions took `calib_ticks`): under QEMU's
/// `-icount` the timer counts instructions executed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceTiming {
    /// Ticks of the main loop's work (ticks of the firmware and the downlink), interrupts
    /// within them included.
    pub busy_ticks: u64,
    /// Ticks in the receive interrupt, all of them.
    pub interrupt_ticks: u64,
    /// The longest single tick of the firmware.
    pub longest_tick: u64,
    pub calib_ticks: u64,
    pub calib_insns: u64,
    /// The deepest the stack went, in bytes (painted at boot; `0` where not measured).
    pub stack_bytes: u64,
}

/// Why a frame was not decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DownlinkError {
    /// The COBS block is malformed.
    Cobs,
    /// Shorter than a header and a CRC, or not the length its kind has.
    Length { got: usize },
    /// The CRC does not match.
    Crc { stored: u32, computed: u32 },
    /// Not a device-to-host frame of this version.
    Version(u8),
    /// A kind, entity kind or layout code this version does not define.
    Code(u8),
    /// A value that no map holds (a non-finite centre or origin, a negative weight).
    Value,
    /// The output buffer is too small.
    BufferTooSmall,
}

/// The file's record of `entity` in `layout` for a file shifted by `shift` from the mapper's
/// frame: what a device's `.mema` holds and what a host rebuilds it from.
pub fn stored_entity(entity: MapEntity, shift: [f32; 3], layout: Layout) -> MapEntity {
    let mut e = entity;
    let c = e.entity.center;
    e.entity.center = Point3::new(c.x - shift[0], c.y - shift[1], c.z - shift[2]);
    match layout {
        Layout::Quantized(grid) => grid.quantize(e),
        _ => e,
    }
}

/// Writes `frame` as sequence `sequence` into `out`, COBS-encoded and delimited; returns the
/// bytes to send.
pub fn encode(sequence: u32, frame: &DownFrame, out: &mut [u8]) -> Result<usize, DownlinkError> {
    let mut raw = [0u8; MAX_RAW_LEN];
    let mut w = Writer {
        buf: &mut raw,
        at: 0,
    };
    w.put(&[DOWNLINK_VERSION]);
    match frame {
        DownFrame::Entity { index, entity } => {
            w.put(&[KIND_ENTITY]);
            w.put(&sequence.to_le_bytes());
            w.put(&index.to_le_bytes());
            w.put(&[entity.kind as u8]);
            let e = &entity.entity;
            for v in e.center.to_array().into_iter().chain(e.weights) {
                w.put(&v.to_le_bytes());
            }
            let r = e.rotation;
            for v in [r.x, r.y, r.z, r.w] {
                w.put(&v.to_le_bytes());
            }
        }
        DownFrame::End(end) => {
            w.put(&[KIND_END]);
            w.put(&sequence.to_le_bytes());
            w.put(&end.entities.to_le_bytes());
            let (code, grid) = match end.layout {
                Layout::AxisAligned => (0u8, [0.0f32; 3]),
                Layout::Oriented => (1, [0.0; 3]),
                Layout::Quantized(q) => (2, [q.centre_step, q.axis_min, q.axis_log_step]),
            };
            w.put(&[code]);
            for v in grid.into_iter().chain(end.shift) {
                w.put(&v.to_le_bytes());
            }
            for v in end.origin {
                w.put(&v.to_le_bytes());
            }
            w.put(&end.map_len.to_le_bytes());
            w.put(&end.map_crc.to_le_bytes());
            w.put(&end.points.to_le_bytes());
            w.put(&end.frames.to_le_bytes());
        }
        DownFrame::Progress {
            taken,
            frames,
            next,
            refused,
        } => {
            w.put(&[KIND_PROGRESS]);
            w.put(&sequence.to_le_bytes());
            for v in [taken, frames, next, refused] {
                w.put(&v.to_le_bytes());
            }
        }
        DownFrame::Answer {
            query,
            ray,
            entity,
            value,
            ticks,
        } => {
            w.put(&[KIND_ANSWER]);
            w.put(&sequence.to_le_bytes());
            w.put(&query.to_le_bytes());
            w.put(&[u8::from(*ray)]);
            w.put(&entity.to_le_bytes());
            w.put(&value.to_le_bytes());
            w.put(&ticks.to_le_bytes());
        }
        DownFrame::Timing(t) => {
            w.put(&[KIND_TIMING]);
            w.put(&sequence.to_le_bytes());
            for v in [
                t.busy_ticks,
                t.interrupt_ticks,
                t.longest_tick,
                t.calib_ticks,
                t.calib_insns,
                t.stack_bytes,
            ] {
                w.put(&v.to_le_bytes());
            }
        }
    }
    let len = w.at;
    let crc = crc32(raw.get(..len).unwrap_or(&[]));
    let mut w = Writer {
        buf: &mut raw,
        at: len,
    };
    w.put(&crc.to_le_bytes());
    let len = w.at;
    let encoded =
        cobs_encode(raw.get(..len).unwrap_or(&[]), out).ok_or(DownlinkError::BufferTooSmall)?;
    *out.get_mut(encoded).ok_or(DownlinkError::BufferTooSmall)? = 0;
    Ok(encoded + 1)
}

/// Decodes one COBS block (the bytes between two delimiters, delimiter not included), in
/// place: the frame's sequence number and what it carries.
pub fn decode(block: &mut [u8]) -> Result<(u32, DownFrame), DownlinkError> {
    let len = cobs_decode_in_place(block).ok_or(DownlinkError::Cobs)?;
    let raw = block.get(..len).ok_or(DownlinkError::Cobs)?;
    if len < HEADER_LEN + CRC_LEN {
        return Err(DownlinkError::Length { got: len });
    }
    let (body, tail) = raw.split_at(len - CRC_LEN);
    let stored = u32::from_le_bytes(
        tail.try_into()
            .map_err(|_| DownlinkError::Length { got: len })?,
    );
    let computed = crc32(body);
    if stored != computed {
        return Err(DownlinkError::Crc { stored, computed });
    }
    let mut r = Reader { buf: body, at: 0 };
    let version = r.u8()?;
    if version != DOWNLINK_VERSION {
        return Err(DownlinkError::Version(version));
    }
    let kind = r.u8()?;
    let sequence = r.u32()?;
    let expected = match kind {
        KIND_ENTITY => ENTITY_PAYLOAD_LEN,
        KIND_END => END_PAYLOAD_LEN,
        KIND_PROGRESS => PROGRESS_PAYLOAD_LEN,
        KIND_TIMING => TIMING_PAYLOAD_LEN,
        KIND_ANSWER => ANSWER_PAYLOAD_LEN,
        other => return Err(DownlinkError::Code(other)),
    };
    if body.len() != HEADER_LEN + expected {
        return Err(DownlinkError::Length { got: len });
    }
    let frame = if kind == KIND_ANSWER {
        let query = r.u32()?;
        let ray = match r.u8()? {
            0 => false,
            1 => true,
            other => return Err(DownlinkError::Code(other)),
        };
        let entity = r.u32()?;
        let value = r.f64()?;
        if value.is_nan() {
            return Err(DownlinkError::Value);
        }
        DownFrame::Answer {
            query,
            ray,
            entity,
            value,
            ticks: r.u32()?,
        }
    } else if kind == KIND_TIMING {
        DownFrame::Timing(DeviceTiming {
            busy_ticks: r.u64()?,
            interrupt_ticks: r.u64()?,
            longest_tick: r.u64()?,
            calib_ticks: r.u64()?,
            calib_insns: r.u64()?,
            stack_bytes: r.u64()?,
        })
    } else if kind == KIND_PROGRESS {
        DownFrame::Progress {
            taken: r.u32()?,
            frames: r.u32()?,
            next: r.u32()?,
            refused: r.u32()?,
        }
    } else if kind == KIND_ENTITY {
        let index = r.u32()?;
        let kind = EntityKind::from_u8(r.u8()?).ok_or(DownlinkError::Value)?;
        let center = Point3::new(r.f32()?, r.f32()?, r.f32()?);
        let weights = [r.f32()?, r.f32()?, r.f32()?];
        let rotation = Rotation {
            x: r.f32()?,
            y: r.f32()?,
            z: r.f32()?,
            w: r.f32()?,
        };
        let finite = center.to_array().iter().all(|c| c.is_finite())
            && weights.iter().all(|w| w.is_finite() && *w >= 0.0)
            && [rotation.x, rotation.y, rotation.z, rotation.w]
                .iter()
                .all(|q| q.is_finite());
        if !finite {
            return Err(DownlinkError::Value);
        }
        let entity = Entity {
            center,
            weights,
            rotation,
        };
        DownFrame::Entity {
            index,
            entity: MapEntity { entity, kind },
        }
    } else {
        let entities = r.u32()?;
        let code = r.u8()?;
        let grid = [r.f32()?, r.f32()?, r.f32()?];
        let shift = [r.f32()?, r.f32()?, r.f32()?];
        let origin = [r.f64()?, r.f64()?, r.f64()?];
        let layout = match code {
            0 => Layout::AxisAligned,
            1 => Layout::Oriented,
            2 => {
                let q = Quantization {
                    centre_step: grid[0],
                    axis_min: grid[1],
                    axis_log_step: grid[2],
                };
                if !q.is_valid() {
                    return Err(DownlinkError::Value);
                }
                Layout::Quantized(q)
            }
            other => return Err(DownlinkError::Code(other)),
        };
        if !shift.iter().all(|s| s.is_finite()) || !origin.iter().all(|o| o.is_finite()) {
            return Err(DownlinkError::Value);
        }
        DownFrame::End(MapEnd {
            entities,
            layout,
            shift,
            origin,
            map_len: r.u32()?,
            map_crc: r.u32()?,
            points: r.u32()?,
            frames: r.u32()?,
        })
    };
    Ok((sequence, frame))
}

/// Writes into a buffer, stopping silently at its end (the buffer is sized for every frame).
struct Writer<'a> {
    buf: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn put(&mut self, bytes: &[u8]) {
        if let Some(dst) = self.buf.get_mut(self.at..self.at + bytes.len()) {
            dst.copy_from_slice(bytes);
            self.at += bytes.len();
        }
    }
}

/// Reads from a frame's body.
struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], DownlinkError> {
        let got = self.buf.len();
        let bytes = self
            .buf
            .get(self.at..self.at + N)
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .ok_or(DownlinkError::Length { got })?;
        self.at += N;
        Ok(bytes)
    }

    fn u8(&mut self) -> Result<u8, DownlinkError> {
        let [byte] = self.take::<1>()?;
        Ok(byte)
    }

    fn u32(&mut self) -> Result<u32, DownlinkError> {
        Ok(u32::from_le_bytes(self.take()?))
    }

    fn f32(&mut self) -> Result<f32, DownlinkError> {
        Ok(f32::from_le_bytes(self.take()?))
    }

    fn u64(&mut self) -> Result<u64, DownlinkError> {
        Ok(u64::from_le_bytes(self.take()?))
    }

    fn f64(&mut self) -> Result<f64, DownlinkError> {
        Ok(f64::from_le_bytes(self.take()?))
    }
}

#[cfg(test)]
mod tests;
