//! The map: entities in a fixed-capacity vector, and the versioned `.mema` binary file.
//!
//! File layout (little-endian; every field at a fixed offset):
//!
//! | bytes        | field                                                        |
//! |--------------|--------------------------------------------------------------|
//! | 0..4         | magic `MEMA`                                                 |
//! | 4..6         | version, u16: 1 (axis-aligned) or 2 (oriented)               |
//! | 6..8         | flags, u16: version 1 none; version 2 bit 0 = quantized, bit 1 = a free-space part, others 0 |
//! | 8..32        | origin x, y, z: f64 (the local frame's origin in the cloud's own coordinates) |
//! | 32..36       | entity count n, u32                                          |
//! | 36..48       | version 2 only: the quantization grid, f32 centre step, shortest semi-axis, ln step of semi-axes (zero when not quantized) |
//! | then n records | see below                                                  |
//! | then, if flag bit 1 | the free-space part ([`free_space_part`])             |
//! | last 4       | CRC-32 (IEEE) of every byte before it                        |
//!
//! Records:
//! - version 1 (25 bytes): centre x, y, z (f32), weights w_x, w_y, w_z (f32), kind (u8);
//! - version 2 (41 bytes): centre (f32 x 3), weights (f32 x 3), quaternion x, y, z, w (f32, unit,
//!   `x_world = c + R(q) x_local`), kind (u8);
//! - version 2 quantized (14 bytes): centre (i16 x 3, times the centre step), rotation (u32,
//!   smallest three: bits 0-1 the index of the largest component, then three 10-bit components,
//!   0 = identity), semi-axes and kind (u32: bits 0-1 kind, then three 10-bit codes,
//!   `r = shortest * exp(step * code)`, 1023 = infinite). See [`record::Quantization`].
//!
//! A weight is `1 / r^2`, zero for a degenerated axis; kind codes are those of [`EntityKind`].
//! [`MapFile::new_checked`] validates everything once; after it, no accessor can fail.

mod encode;
pub mod free_space_part;
pub mod record;

pub use encode::*;

use crate::free_space::Geometry;
use crate::geometry::{Entity, EntityKind};
use crate::link::crc32::crc32;
use record::{AXIS_ALIGNED_LEN, ORIENTED_LEN, QUANTIZED_LEN, Quantization};

pub const MAGIC: [u8; 4] = *b"MEMA";
/// The newest version written; [`MapFile`] reads every version up to it.
pub const VERSION: u16 = 2;
pub const HEADER_LEN: usize = 36;
/// Version 2's header: version 1's and the quantization grid.
pub const HEADER_V2_LEN: usize = 48;
pub const ENTITY_LEN: usize = AXIS_ALIGNED_LEN;
pub const CRC_LEN: usize = 4;
const QUANTIZED_FLAG: u16 = 1;
const FREE_SPACE_FLAG: u16 = 2;

/// How a map's entities are stored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Layout {
    /// Version 1: the paper's axis-aligned entity in f32 (24 bytes and a kind).
    AxisAligned,
    /// Version 2 in f32: centre, weights and a unit quaternion (40 bytes and a kind).
    Oriented,
    /// Version 2 on a grid: 14 bytes an entity.
    Quantized(Quantization),
}

impl Layout {
    pub const fn record_len(&self) -> usize {
        match self {
            Self::AxisAligned => AXIS_ALIGNED_LEN,
            Self::Oriented => ORIENTED_LEN,
            Self::Quantized(_) => QUANTIZED_LEN,
        }
    }

    pub const fn header_len(&self) -> usize {
        match self {
            Self::AxisAligned => HEADER_LEN,
            _ => HEADER_V2_LEN,
        }
    }

    /// Size of a file of `count` entities in this layout.
    pub const fn encoded_len(&self, count: usize) -> usize {
        self.header_len() + self.record_len() * count + CRC_LEN
    }

    pub const fn version(&self) -> u16 {
        match self {
            Self::AxisAligned => 1,
            _ => 2,
        }
    }
}

mod field {
    use core::ops::Range;
    pub const MAGIC: Range<usize> = 0..4;
    pub const VERSION: Range<usize> = 4..6;
    pub const FLAGS: Range<usize> = 6..8;
    pub const ORIGIN: Range<usize> = 8..32;
    pub const COUNT: Range<usize> = 32..36;
    pub const GRID: Range<usize> = 36..48;
}

/// One stored entity and its kind (kept, since the sphere tolerance was a fit-time parameter).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapEntity {
    pub entity: Entity,
    pub kind: EntityKind,
}

/// More entities than the map's capacity `K`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CapacityExceeded {
    pub capacity: usize,
}

impl core::fmt::Display for CapacityExceeded {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "map capacity of {} entities exceeded", self.capacity)
    }
}

impl core::error::Error for CapacityExceeded {}

/// A map of at most `K` entities in fixed memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Map<const K: usize> {
    pub origin: [f64; 3],
    entities: heapless::Vec<MapEntity, K>,
}

impl<const K: usize> Default for Map<K> {
    fn default() -> Self {
        Self::new([0.0; 3])
    }
}

impl<const K: usize> Map<K> {
    pub const fn new(origin: [f64; 3]) -> Self {
        Self {
            origin,
            entities: heapless::Vec::new(),
        }
    }

    /// Adds an entity; a full map is left unchanged.
    pub fn push(&mut self, entity: MapEntity) -> Result<(), CapacityExceeded> {
        self.entities
            .push(entity)
            .map_err(|_| CapacityExceeded { capacity: K })
    }

    pub fn entities(&self) -> &[MapEntity] {
        &self.entities
    }

    pub fn clear(&mut self) {
        self.entities.clear();
    }

    /// Copies a decoded file into the map.
    pub fn from_file(file: &MapFile<'_>) -> Result<Self, CapacityExceeded> {
        let mut map = Self::new(file.origin());
        for e in file.entities() {
            map.push(e)?;
        }
        Ok(map)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DecodeError {
    /// Shorter than a header and checksum, or than the count says.
    Truncated {
        needed: usize,
        got: usize,
    },
    /// Longer than the count says.
    TrailingBytes {
        expected: usize,
        got: usize,
    },
    BadMagic,
    UnsupportedVersion(u16),
    BadCrc {
        stored: u32,
        computed: u32,
    },
    NonFiniteOrigin,
    /// Flags this version does not define.
    ReservedFlags(u16),
    /// A quantization grid that is not finite and positive.
    InvalidGrid,
    /// A centre or weight that is NaN, infinite or (for a weight) negative.
    InvalidEntity {
        index: usize,
    },
    UnknownKind {
        index: usize,
        code: u8,
    },
    /// A free-space part whose images are not finite, run past it or leave bytes after them.
    InvalidFreeSpace,
}

impl core::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Truncated { needed, got } => {
                write!(f, "truncated: needs {needed} bytes, has {got}")
            }
            Self::TrailingBytes { expected, got } => {
                write!(f, "{got} bytes where the entity count implies {expected}")
            }
            Self::BadMagic => write!(f, "not a mema map (magic is not MEMA)"),
            Self::UnsupportedVersion(v) => write!(
                f,
                "map version {v} is not supported (this build reads 1 to {VERSION})"
            ),
            Self::BadCrc { stored, computed } => {
                write!(
                    f,
                    "checksum mismatch: stored {stored:08x}, computed {computed:08x}"
                )
            }
            Self::NonFiniteOrigin => write!(f, "origin is not finite"),
            Self::ReservedFlags(flags) => {
                write!(f, "reserved flags {flags:#06x} are set")
            }
            Self::InvalidGrid => write!(f, "the quantization grid is not finite and positive"),
            Self::InvalidEntity { index } => write!(
                f,
                "entity {index} has a non-finite centre, an invalid weight or a non-unit rotation"
            ),
            Self::InvalidFreeSpace => write!(f, "the free-space part is not well formed"),
            Self::UnknownKind { index, code } => {
                write!(f, "entity {index} has unknown kind code {code}")
            }
        }
    }
}

impl core::error::Error for DecodeError {}

/// A validated view of `.mema` bytes of any version.
#[derive(Clone, Copy, Debug)]
pub struct MapFile<'a> {
    header: &'a [u8; HEADER_LEN],
    layout: Layout,
    body: &'a [u8],
    /// The free-space part after its length field (empty without one).
    free_space: &'a [u8],
}

fn f64_at(bytes: &[u8; HEADER_LEN], at: usize) -> f64 {
    let mut b = [0u8; 8];
    if let Some(src) = bytes.get(at..at + 8) {
        b.copy_from_slice(src);
    }
    f64::from_le_bytes(b)
}

fn f32_at(bytes: &[u8], at: usize) -> f32 {
    let mut b = [0u8; 4];
    if let Some(src) = bytes.get(at..at + 4) {
        b.copy_from_slice(src);
    }
    f32::from_le_bytes(b)
}

/// The layout a header declares, its grid checked, and whether a free-space part follows the
/// records.
fn layout_of(bytes: &[u8], header: &[u8; HEADER_LEN]) -> Result<(Layout, bool), DecodeError> {
    let version = u16::from_le_bytes([header[4], header[5]]);
    let flags = u16::from_le_bytes([header[6], header[7]]);
    let free_space = version == 2 && flags & FREE_SPACE_FLAG != 0;
    let flags = if free_space {
        flags & !FREE_SPACE_FLAG
    } else {
        flags
    };
    let layout = match version {
        1 if flags == 0 => Ok(Layout::AxisAligned),
        2 if flags == 0 => Ok(Layout::Oriented),
        2 if flags == QUANTIZED_FLAG => {
            let grid = bytes.get(field::GRID).ok_or(DecodeError::Truncated {
                needed: HEADER_V2_LEN + CRC_LEN,
                got: bytes.len(),
            })?;
            let grid = Quantization {
                centre_step: f32_at(grid, 0),
                axis_min: f32_at(grid, 4),
                axis_log_step: f32_at(grid, 8),
            };
            if grid.is_valid() {
                Ok(Layout::Quantized(grid))
            } else {
                Err(DecodeError::InvalidGrid)
            }
        }
        1 | 2 => Err(DecodeError::ReservedFlags(flags)),
        v => Err(DecodeError::UnsupportedVersion(v)),
    }?;
    Ok((layout, free_space))
}

/// The entity of one record and its raw kind code; `None` if the record is invalid.
fn entity_of(layout: &Layout, record: &[u8]) -> (Entity, u8, bool) {
    match layout {
        Layout::AxisAligned => {
            let (e, code) = record::read_axis_aligned(record);
            (e, code, true)
        }
        Layout::Oriented => record::read_oriented(record),
        Layout::Quantized(grid) => {
            let e = record::read_quantized(grid, record);
            (e.entity, e.kind as u8, true)
        }
    }
}

impl<'a> MapFile<'a> {
    pub fn new_checked(bytes: &'a [u8]) -> Result<Self, DecodeError> {
        let got = bytes.len();
        let Some((header, _)) = bytes.split_first_chunk::<HEADER_LEN>() else {
            return Err(DecodeError::Truncated {
                needed: encoded_len(0),
                got,
            });
        };
        if header[..4] != MAGIC {
            return Err(DecodeError::BadMagic);
        }
        let (layout, has_free_space) = layout_of(bytes, header)?;
        let count = u32::from_le_bytes([header[32], header[33], header[34], header[35]]) as usize;
        let records_end = count
            .checked_mul(layout.record_len())
            .and_then(|b| b.checked_add(layout.header_len()))
            .unwrap_or(usize::MAX);
        // The part's length field, where it must be; a file too short for it is truncated.
        let part = if has_free_space {
            let mut field = [0u8; 4];
            if let Some(src) = records_end
                .checked_add(4)
                .and_then(|end| bytes.get(records_end..end))
            {
                field.copy_from_slice(src);
            }
            4 + u32::from_le_bytes(field) as usize
        } else {
            0
        };
        let needed = records_end
            .checked_add(part)
            .and_then(|b| b.checked_add(CRC_LEN))
            .unwrap_or(usize::MAX);
        if got < needed {
            return Err(DecodeError::Truncated { needed, got });
        }
        if got > needed {
            return Err(DecodeError::TrailingBytes {
                expected: needed,
                got,
            });
        }
        let body = bytes.get(layout.header_len()..records_end).unwrap_or(&[]);
        let free_space = bytes
            .get(records_end + 4.min(part)..got - CRC_LEN)
            .unwrap_or(&[]);
        let mut stored = [0u8; 4];
        stored.copy_from_slice(bytes.get(got - CRC_LEN..).unwrap_or(&[0; 4]));
        let stored = u32::from_le_bytes(stored);
        let computed = crc32(bytes.get(..got - CRC_LEN).unwrap_or(&[]));
        if stored != computed {
            return Err(DecodeError::BadCrc { stored, computed });
        }
        if has_free_space
            && (free_space.len() < 2 || free_space_part::images(free_space).any(|i| i.is_err()))
        {
            return Err(DecodeError::InvalidFreeSpace);
        }
        let file = Self {
            header,
            layout,
            body,
            free_space,
        };
        if !file.origin().iter().all(|v| v.is_finite()) {
            return Err(DecodeError::NonFiniteOrigin);
        }
        for (index, record) in body.chunks_exact(layout.record_len()).enumerate() {
            let (entity, code, unit) = entity_of(&layout, record);
            if !unit
                || !entity.center.is_finite()
                || !entity.weights.iter().all(|w| w.is_finite() && *w >= 0.0)
            {
                return Err(DecodeError::InvalidEntity { index });
            }
            if EntityKind::from_u8(code).is_none() {
                return Err(DecodeError::UnknownKind { index, code });
            }
        }
        Ok(file)
    }

    pub fn origin(&self) -> [f64; 3] {
        [
            f64_at(self.header, 8),
            f64_at(self.header, 16),
            f64_at(self.header, 24),
        ]
    }

    /// How the file stores its entities.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    pub fn len(&self) -> usize {
        self.body.len() / self.layout.record_len()
    }

    pub fn is_empty(&self) -> bool {
        self.body.is_empty()
    }

    /// The range images of the free-space part (none without one), origins relative to the
    /// map's origin.
    pub fn free_space(&self) -> impl Iterator<Item = (Geometry, &'a [u8])> + Clone + 'a {
        // Checked in new_checked: no image is an error.
        free_space_part::images(self.free_space).filter_map(Result::ok)
    }

    pub fn entities(&self) -> impl Iterator<Item = MapEntity> + Clone + 'a {
        let layout = self.layout;
        self.body
            .chunks_exact(layout.record_len())
            .map(move |record| {
                let (entity, code, _) = entity_of(&layout, record);
                MapEntity {
                    entity,
                    // Checked in new_checked; the fallback is never taken.
                    kind: EntityKind::from_u8(code).unwrap_or(EntityKind::Ellipsoid),
                }
            })
    }
}

#[cfg(test)]
mod tests;
