//! The device's side of the link back: the map, an entity per frame, to the host (PROTOCOL.md,
//! "Device to host").
//!
//! A frame is framed as every other ([`super::framing`]) with the header the host and device
//! share ([`super::frame`]): the device's boot in every frame, the host's session in every frame
//! of it (`0` in frames of no session), and a sequence number the host checks for gaps:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 1 | version `0x83` |
//! | 1 | 1 | kind: `0` entity, `1` end of map, `2` progress, `3` device timing, `4` answer, `5` session |
//! | 2 | 4 | session: the host's the device is in (`0`: none) |
//! | 6 | 4 | boot: the device's, new at every boot |
//! | 10 | 4 | sequence: 0 for the first frame after boot, +1 per frame |
//! | 14 | n | the kind's payload |
//! | 14 + n | 4 | CRC-32 of every byte before it |
//!
//! A **session** frame says the device booted (in no session), began the frame's session with a
//! fresh map, or refused it, and what map it makes (capacity, working clusters, model).
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
//! frames it refused ([`crate::link::uplink`]): a sender that keeps what it has sent and the device
//! has not taken under the ring's size never overruns it, however slowly the device maps, and
//! one that sees the refused count grow sends again from the frame expected.

use super::cobs::cobs_max_encoded_len;
use super::frame::{Address, Emitter, HEADER_LEN, LinkError, LinkFrame};
use super::framing::CRC_LEN;
use crate::geometry::{Entity, EntityKind, Point3};
use crate::map::record::Quantization;
use crate::map::{Layout, MapEntity};
use crate::rotation::Rotation;

/// The receive ring of a mema device: two of the largest points frames, so one frame can be
/// decoded while the next lands. A sender keeps at most this many bytes beyond the device's
/// last progress frame in flight.
pub const RING_BYTES: usize = 2 * crate::link::wire::MAX_FRAME_LEN;

/// The version byte of a device-to-host frame (`0x81` before sessions and boots).
pub const DOWNLINK_VERSION: u8 = 0x83;
/// An entity frame's payload: index, kind, centre, weights, rotation.
pub const ENTITY_PAYLOAD_LEN: usize = 4 + 1 + 12 + 12 + 16;
/// An end frame's payload: count, layout and grid, shift, origin, file length and CRC, points
/// and frames mapped.
pub const END_PAYLOAD_LEN: usize = 4 + 1 + 12 + 12 + 24 + 4 + 4 + 4 + 4;
/// A progress frame's payload: bytes taken, frames mapped, the carry frame expected next and
/// the host's frames refused.
pub const PROGRESS_PAYLOAD_LEN: usize = 4 + 4 + 4 + 4;
/// A timing frame's payload: busy, interrupt and longest-tick counts, the calibration, the
/// deepest stack, the busy cycles, the ring's and the line's overruns.
pub const TIMING_PAYLOAD_LEN: usize = 8 + 8 + 8 + 8 + 8 + 8 + 8 + 4 + 4;
/// An answer frame's payload: the query's number, what, entity, value, ticks.
pub const ANSWER_PAYLOAD_LEN: usize = 4 + 1 + 4 + 8 + 4;
/// The most entities a map sent over the link holds (a board holds 700; a host's streaming
/// mapper 2,048): an end frame saying more, or an entity frame indexed past it, is refused, so
/// no count from the line sizes more than this on the host.
pub const MAX_MAP_ENTITIES: u32 = 1 << 20;

/// A session frame's payload: status, reason, the map's capacity and working clusters, model.
pub const SESSION_PAYLOAD_LEN: usize = 1 + 1 + 4 + 4 + 1;
/// A retraction's payload: the entity's index.
pub const RETRACT_PAYLOAD_LEN: usize = 4;
/// The longest raw frame.
pub const MAX_RAW_LEN: usize = HEADER_LEN + END_PAYLOAD_LEN + CRC_LEN;
/// The longest frame on the wire, its delimiter included.
pub const MAX_DOWN_FRAME_LEN: usize = cobs_max_encoded_len(MAX_RAW_LEN) + 1;

const KIND_ENTITY: u8 = 0;
const KIND_END: u8 = 1;
const KIND_PROGRESS: u8 = 2;
const KIND_TIMING: u8 = 3;
const KIND_ANSWER: u8 = 4;
const KIND_SESSION: u8 = 5;
const KIND_RETRACT: u8 = 6;

/// What a session frame says of the device's session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SessionStatus {
    /// The device has just booted and is in no session (its frame's session is `0`).
    Booted,
    /// The device is in the frame's session, its map begun for it.
    Started,
    /// The device will not begin the frame's session, for `reason` ([`REASON_LISTENING`]).
    Refused { reason: u8 },
}

/// A refusal's reason: the device maps a sensor wired to it, and takes no host's stream.
pub const REASON_LISTENING: u8 = 1;

/// What a device says of itself in a session frame: the map it makes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceLayout {
    /// Entities the map holds at most (working clusters and frozen entities).
    pub capacity: u32,
    /// Working clusters.
    pub working: u32,
    /// The entity model: `0` the paper's, `1` shells.
    pub model: u8,
}

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
    /// ([`crate::link::uplink`]; both `0` for a device fed without carry frames).
    Progress {
        taken: u32,
        frames: u32,
        next: u32,
        refused: u32,
    },
    /// What the device's work cost it, in its timer's ticks, sent before the end.
    Timing(DeviceTiming),
    /// The answer to a host's query ([`crate::link::uplink::Request::Query`]): the entity found
    /// (`u32::MAX`: none), the signed distance to the nearest surface or the distance along
    /// the ray, and the timer's ticks the query took.
    Answer {
        query: u32,
        ray: bool,
        entity: u32,
        value: f64,
        ticks: u32,
    },
    /// The device's session: announced at boot (no session), and in answer to a start request.
    Session {
        status: SessionStatus,
        layout: DeviceLayout,
    },
    /// The map no longer has an entity at `index`: an entity sent from there was carved (seen
    /// through by later scans), and the map's last frozen entity moved into its slot, which
    /// an entity frame sends again.
    Retract {
        index: u32,
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
    /// The busy work in core clock cycles, counted by the part's own cycle counter (a
    /// Cortex-M's DWT), interrupts included as in `busy_ticks`; `0` where there is none to
    /// count (QEMU models no DWT: its figures are `busy_ticks`, instructions under `-icount`).
    pub busy_cycles: u64,
    /// Bytes lost because the receive ring was full, and bytes the UART lost before the
    /// interrupt read them (an overrun flag): what a too-fast sender or a stalled loop cost.
    pub ring_overruns: u32,
    pub line_overruns: u32,
}

/// A map file's own checksum, which an end frame carries: the CRC-32 of every byte before the
/// file's last four (where the file keeps it). Not the CRC of the whole file: a file ending in
/// the CRC of what precedes it always has the CRC-32 residue `0x2144df1c`, whatever it holds.
pub fn map_checksum(file: &[u8]) -> u32 {
    crate::link::crc32::crc32(file.get(..file.len().saturating_sub(4)).unwrap_or(&[]))
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

/// Writes `frame`, from the device's boot in the host's session `from`, as sequence
/// `sequence` into `out`, COBS-encoded and delimited; returns the bytes to send.
pub fn encode(
    from: Address,
    sequence: u32,
    frame: &DownFrame,
    out: &mut [u8],
) -> Result<usize, LinkError> {
    let kind = match frame {
        DownFrame::Entity { .. } => KIND_ENTITY,
        DownFrame::End(_) => KIND_END,
        DownFrame::Progress { .. } => KIND_PROGRESS,
        DownFrame::Timing(_) => KIND_TIMING,
        DownFrame::Answer { .. } => KIND_ANSWER,
        DownFrame::Session { .. } => KIND_SESSION,
        DownFrame::Retract { .. } => KIND_RETRACT,
    };
    let mut w = Emitter::new(DOWNLINK_VERSION, kind, from, sequence);
    match frame {
        DownFrame::Entity { index, entity } => {
            w.u32(*index).u8(entity.kind as u8);
            let e = &entity.entity;
            for v in e.center.to_array().into_iter().chain(e.weights) {
                w.f32(v);
            }
            let r = e.rotation;
            for v in [r.x, r.y, r.z, r.w] {
                w.f32(v);
            }
        }
        DownFrame::End(end) => {
            w.u32(end.entities);
            let (code, grid) = match end.layout {
                Layout::AxisAligned => (0u8, [0.0f32; 3]),
                Layout::Oriented => (1, [0.0; 3]),
                Layout::Quantized(q) => (2, [q.centre_step, q.axis_min, q.axis_log_step]),
            };
            w.u8(code);
            for v in grid.into_iter().chain(end.shift) {
                w.f32(v);
            }
            for v in end.origin {
                w.f64(v);
            }
            w.u32(end.map_len)
                .u32(end.map_crc)
                .u32(end.points)
                .u32(end.frames);
        }
        DownFrame::Progress {
            taken,
            frames,
            next,
            refused,
        } => {
            w.u32(*taken).u32(*frames).u32(*next).u32(*refused);
        }
        DownFrame::Answer {
            query,
            ray,
            entity,
            value,
            ticks,
        } => {
            w.u32(*query)
                .u8(u8::from(*ray))
                .u32(*entity)
                .f64(*value)
                .u32(*ticks);
        }
        DownFrame::Timing(t) => {
            for v in [
                t.busy_ticks,
                t.interrupt_ticks,
                t.longest_tick,
                t.calib_ticks,
                t.calib_insns,
                t.stack_bytes,
                t.busy_cycles,
            ] {
                w.u64(v);
            }
            w.u32(t.ring_overruns).u32(t.line_overruns);
        }
        DownFrame::Retract { index } => {
            w.u32(*index);
        }
        DownFrame::Session { status, layout } => {
            let (code, reason) = match *status {
                SessionStatus::Booted => (0, 0),
                SessionStatus::Started => (1, 0),
                SessionStatus::Refused { reason } => (2, reason),
            };
            w.u8(code)
                .u8(reason)
                .u32(layout.capacity)
                .u32(layout.working)
                .u8(layout.model);
        }
    }
    w.seal(out)
}

/// Reads a raw frame (a block the [`super::framing::Deframer`] decoded): who it is from, its
/// sequence number and what it carries.
pub fn decode(raw: &[u8]) -> Result<(Address, u32, DownFrame), LinkError> {
    let f = LinkFrame::new_checked(raw, DOWNLINK_VERSION)?;
    let frame = match f.kind() {
        KIND_ANSWER => {
            let mut r = f.payload_of(ANSWER_PAYLOAD_LEN)?;
            let query = r.u32()?;
            let ray = r.flag()?;
            let entity = r.u32()?;
            let value = r.f64()?;
            if value.is_nan() {
                return Err(LinkError::Value);
            }
            DownFrame::Answer {
                query,
                ray,
                entity,
                value,
                ticks: r.u32()?,
            }
        }
        KIND_TIMING => {
            let mut r = f.payload_of(TIMING_PAYLOAD_LEN)?;
            DownFrame::Timing(DeviceTiming {
                busy_ticks: r.u64()?,
                interrupt_ticks: r.u64()?,
                longest_tick: r.u64()?,
                calib_ticks: r.u64()?,
                calib_insns: r.u64()?,
                stack_bytes: r.u64()?,
                busy_cycles: r.u64()?,
                ring_overruns: r.u32()?,
                line_overruns: r.u32()?,
            })
        }
        KIND_PROGRESS => {
            let mut r = f.payload_of(PROGRESS_PAYLOAD_LEN)?;
            DownFrame::Progress {
                taken: r.u32()?,
                frames: r.u32()?,
                next: r.u32()?,
                refused: r.u32()?,
            }
        }
        KIND_SESSION => {
            let mut r = f.payload_of(SESSION_PAYLOAD_LEN)?;
            let (code, reason) = (r.u8()?, r.u8()?);
            let status = match (code, reason) {
                (0, 0) => SessionStatus::Booted,
                (1, 0) => SessionStatus::Started,
                (2, reason) => SessionStatus::Refused { reason },
                (other, _) => return Err(LinkError::Code(other)),
            };
            let layout = DeviceLayout {
                capacity: r.u32()?,
                working: r.u32()?,
                model: r.u8()?,
            };
            DownFrame::Session { status, layout }
        }
        KIND_RETRACT => {
            let mut r = f.payload_of(RETRACT_PAYLOAD_LEN)?;
            let index = r.u32()?;
            if index >= MAX_MAP_ENTITIES {
                return Err(LinkError::Value);
            }
            DownFrame::Retract { index }
        }
        KIND_ENTITY => {
            let mut r = f.payload_of(ENTITY_PAYLOAD_LEN)?;
            let index = r.u32()?;
            if index >= MAX_MAP_ENTITIES {
                return Err(LinkError::Value);
            }
            let kind = EntityKind::from_u8(r.u8()?).ok_or(LinkError::Value)?;
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
            // A unit quaternion, within the map file's own tolerance (`map::record`, 1e-5 on
            // the squared norm in f64): another would make the host write a map that no
            // reader takes (found by the `map_frames` fuzz check).
            let norm2: f64 = [rotation.x, rotation.y, rotation.z, rotation.w]
                .iter()
                .map(|&q| f64::from(q) * f64::from(q))
                .sum();
            if !finite || !((norm2 - 1.0).abs() <= 1e-5) {
                return Err(LinkError::Value);
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
        }
        KIND_END => {
            let mut r = f.payload_of(END_PAYLOAD_LEN)?;
            let entities = r.u32()?;
            if entities > MAX_MAP_ENTITIES {
                return Err(LinkError::Value);
            }
            let code = r.u8()?;
            let grid = [r.f32()?, r.f32()?, r.f32()?];
            let shift = [r.f32()?, r.f32()?, r.f32()?];
            let origin = [r.f64()?, r.f64()?, r.f64()?];
            let layout = match code {
                // The grid is `0` but in the quantized layout (PROTOCOL.md): other bytes there
                // would be a second end frame for one map (found by `downlink_decoder`).
                0 | 1 if grid.iter().any(|g| g.to_bits() != 0) => return Err(LinkError::Value),
                0 => Layout::AxisAligned,
                1 => Layout::Oriented,
                2 => {
                    let q = Quantization {
                        centre_step: grid[0],
                        axis_min: grid[1],
                        axis_log_step: grid[2],
                    };
                    if !q.is_valid() {
                        return Err(LinkError::Value);
                    }
                    Layout::Quantized(q)
                }
                other => return Err(LinkError::Code(other)),
            };
            if !shift.iter().all(|s| s.is_finite()) || !origin.iter().all(|o| o.is_finite()) {
                return Err(LinkError::Value);
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
        }
        other => return Err(LinkError::Code(other)),
    };
    Ok((f.address(), f.number(), frame))
}

#[cfg(test)]
mod tests;
