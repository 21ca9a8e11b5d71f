//! The map: entities in a fixed-capacity vector, and the versioned `.mema` binary file.
//!
//! File layout (little-endian; every field at a fixed offset):
//!
//! | bytes        | field                                                        |
//! |--------------|--------------------------------------------------------------|
//! | 0..4         | magic `MEMA`                                                 |
//! | 4..6         | version, u16: 1 (axis-aligned) or 2 (oriented)               |
//! | 6..8         | flags, u16: version 1 none; version 2 bit 0 = quantized, others 0 |
//! | 8..32        | origin x, y, z: f64 (the local frame's origin in the cloud's own coordinates) |
//! | 32..36       | entity count n, u32                                          |
//! | 36..48       | version 2 only: the quantization grid, f32 centre step, shortest semi-axis, ln step of semi-axes (zero when not quantized) |
//! | then n records | see below                                                  |
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

pub mod record;

use crate::geometry::{Entity, EntityKind};
use crate::link::crc32::{Crc32, crc32};
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

/// Size of the version-1 `.mema` encoding of `count` entities.
pub const fn encoded_len(count: usize) -> usize {
    Layout::AxisAligned.encoded_len(count)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncodeError {
    BufferTooSmall {
        needed: usize,
        got: usize,
    },
    TooManyEntities,
    /// An oriented entity in the axis-aligned layout, which cannot hold its rotation.
    Oriented {
        index: usize,
    },
    /// A quantization grid that is not finite and positive.
    InvalidGrid,
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::BufferTooSmall { needed, got } => {
                write!(f, "map needs {needed} bytes, buffer has {got}")
            }
            Self::TooManyEntities => write!(f, "more than 2^32 - 1 entities"),
            Self::Oriented { index } => write!(
                f,
                "entity {index} is oriented; the axis-aligned (version 1) layout cannot hold it"
            ),
            Self::InvalidGrid => write!(f, "the quantization grid is not finite and positive"),
        }
    }
}

impl core::error::Error for EncodeError {}

/// Writes the version-1 `.mema` encoding into `out`, returning the bytes used.
pub fn encode(
    origin: [f64; 3],
    entities: &[MapEntity],
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    encode_into(origin, entities.iter().copied(), out)
}

/// [`encode`] from any iterator of entities (a mapper's, without copying them out first).
pub fn encode_into<I>(origin: [f64; 3], entities: I, out: &mut [u8]) -> Result<usize, EncodeError>
where
    I: Iterator<Item = MapEntity> + Clone,
{
    encode_as(Layout::AxisAligned, origin, entities, out)
}

/// The encoding in `layout` into `out`, returning the bytes used.
pub fn encode_as<I>(
    layout: Layout,
    origin: [f64; 3],
    entities: I,
    out: &mut [u8],
) -> Result<usize, EncodeError>
where
    I: Iterator<Item = MapEntity> + Clone,
{
    let needed = layout.encoded_len(entities.clone().count());
    let got = out.len();
    let Some(mut out) = out.get_mut(..needed) else {
        return Err(EncodeError::BufferTooSmall { needed, got });
    };
    encode_pieces_as(layout, origin, entities, |piece| {
        // `out` holds exactly the pieces' total, checked above.
        let rest = core::mem::take(&mut out);
        let n = piece.len().min(rest.len());
        let (head, tail) = rest.split_at_mut(n);
        if let Some(piece) = piece.get(..n) {
            head.copy_from_slice(piece);
        }
        out = tail;
    })
}

/// Writes the version-1 `.mema` encoding piece by piece (header, each entity, CRC) into `sink`,
/// returning the bytes written: the bytes of [`encode`], for a device that has no room for the
/// whole map (400 entities are 10 KB) and sends it out as it goes.
pub fn encode_pieces<I>(
    origin: [f64; 3],
    entities: I,
    sink: impl FnMut(&[u8]),
) -> Result<usize, EncodeError>
where
    I: Iterator<Item = MapEntity> + Clone,
{
    encode_pieces_as(Layout::AxisAligned, origin, entities, sink)
}

/// [`encode_pieces`] in any layout. Nothing reaches `sink` unless the whole map can be written.
pub fn encode_pieces_as<I>(
    layout: Layout,
    origin: [f64; 3],
    entities: I,
    mut sink: impl FnMut(&[u8]),
) -> Result<usize, EncodeError>
where
    I: Iterator<Item = MapEntity> + Clone,
{
    let len = entities.clone().count();
    let count = u32::try_from(len).map_err(|_| EncodeError::TooManyEntities)?;
    if layout == Layout::AxisAligned
        && let Some(index) = entities
            .clone()
            .position(|e| !e.entity.rotation.is_identity())
    {
        return Err(EncodeError::Oriented { index });
    }
    let mut header = [0u8; HEADER_V2_LEN];
    header[field::MAGIC].copy_from_slice(&MAGIC);
    header[field::VERSION].copy_from_slice(&layout.version().to_le_bytes());
    let (flags, grid) = match layout {
        Layout::Quantized(grid) => {
            if !grid.is_valid() {
                return Err(EncodeError::InvalidGrid);
            }
            (
                QUANTIZED_FLAG,
                [grid.centre_step, grid.axis_min, grid.axis_log_step],
            )
        }
        _ => (0, [0.0; 3]),
    };
    header[field::FLAGS].copy_from_slice(&flags.to_le_bytes());
    for (chunk, v) in header[field::ORIGIN].chunks_exact_mut(8).zip(origin.iter()) {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
    header[field::COUNT].copy_from_slice(&count.to_le_bytes());
    for (chunk, v) in header[field::GRID].chunks_exact_mut(4).zip(grid.iter()) {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
    let header = header.get(..layout.header_len()).unwrap_or(&[]);
    let mut crc = Crc32::new();
    crc.update(header);
    sink(header);
    let mut buffer = [0u8; ORIENTED_LEN];
    let record = buffer.get_mut(..layout.record_len()).unwrap_or(&mut []);
    for e in entities.take(len) {
        match layout {
            Layout::AxisAligned => record::write_axis_aligned(&e, record),
            Layout::Oriented => record::write_oriented(&e, record),
            Layout::Quantized(grid) => record::write_quantized(&grid, &e, record),
        }
        crc.update(record);
        sink(record);
    }
    sink(&crc.finish().to_le_bytes());
    Ok(layout.encoded_len(len))
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

/// The layout a header declares, its grid checked.
fn layout_of(bytes: &[u8], header: &[u8; HEADER_LEN]) -> Result<Layout, DecodeError> {
    let version = u16::from_le_bytes([header[4], header[5]]);
    let flags = u16::from_le_bytes([header[6], header[7]]);
    match version {
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
    }
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
        let layout = layout_of(bytes, header)?;
        let count = u32::from_le_bytes([header[32], header[33], header[34], header[35]]) as usize;
        let needed = count
            .checked_mul(layout.record_len())
            .and_then(|b| b.checked_add(layout.header_len() + CRC_LEN))
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
        let body = bytes.get(layout.header_len()..got - CRC_LEN).unwrap_or(&[]);
        let mut stored = [0u8; 4];
        stored.copy_from_slice(bytes.get(got - CRC_LEN..).unwrap_or(&[0; 4]));
        let stored = u32::from_le_bytes(stored);
        let computed = crc32(bytes.get(..got - CRC_LEN).unwrap_or(&[]));
        if stored != computed {
            return Err(DecodeError::BadCrc { stored, computed });
        }
        let file = Self {
            header,
            layout,
            body,
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
