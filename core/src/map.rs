//! The map: entities in a fixed-capacity vector, and the versioned `.mema` binary file.
//!
//! File layout (little-endian; every field at a fixed offset):
//!
//! | bytes        | field                                                        |
//! |--------------|--------------------------------------------------------------|
//! | 0..4         | magic `MEMA`                                                 |
//! | 4..6         | version, u16 = 1                                             |
//! | 6..8         | flags, u16, 0 (reserved)                                     |
//! | 8..32        | origin x, y, z: f64 (the local frame's origin in the cloud's own coordinates) |
//! | 32..36       | entity count n, u32                                          |
//! | 36..36+25n   | per entity: centre x, y, z (f32), weights w_x, w_y, w_z (f32), kind (u8) |
//! | last 4       | CRC-32 (IEEE) of every byte before it                        |
//!
//! A weight is `1 / r^2`, zero for a degenerated axis; kind codes are those of [`EntityKind`].
//! [`MapFile::new_checked`] validates everything once; after it, no accessor can fail.

use crate::crc32::{Crc32, crc32};
use crate::geometry::{Entity, EntityKind, Point3};

pub const MAGIC: [u8; 4] = *b"MEMA";
pub const VERSION: u16 = 1;
pub const HEADER_LEN: usize = 36;
pub const ENTITY_LEN: usize = 25;
pub const CRC_LEN: usize = 4;

mod field {
    use core::ops::Range;
    pub const MAGIC: Range<usize> = 0..4;
    pub const VERSION: Range<usize> = 4..6;
    pub const FLAGS: Range<usize> = 6..8;
    pub const ORIGIN: Range<usize> = 8..32;
    pub const COUNT: Range<usize> = 32..36;
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

/// Size of the `.mema` encoding of `count` entities.
pub const fn encoded_len(count: usize) -> usize {
    HEADER_LEN + ENTITY_LEN * count + CRC_LEN
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncodeError {
    BufferTooSmall { needed: usize, got: usize },
    TooManyEntities,
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::BufferTooSmall { needed, got } => {
                write!(f, "map needs {needed} bytes, buffer has {got}")
            }
            Self::TooManyEntities => write!(f, "more than 2^32 - 1 entities"),
        }
    }
}

impl core::error::Error for EncodeError {}

/// Writes the `.mema` encoding into `out`, returning the bytes used.
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
    let needed = encoded_len(entities.clone().count());
    let got = out.len();
    let Some(mut out) = out.get_mut(..needed) else {
        return Err(EncodeError::BufferTooSmall { needed, got });
    };
    encode_pieces(origin, entities, |piece| {
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

/// Writes the `.mema` encoding piece by piece (header, each entity, CRC) into `sink`, returning
/// the bytes written: the bytes of [`encode`], for a device that has no room for the whole map
/// (400 entities are 10 KB) and sends it out as it goes.
pub fn encode_pieces<I>(
    origin: [f64; 3],
    entities: I,
    mut sink: impl FnMut(&[u8]),
) -> Result<usize, EncodeError>
where
    I: Iterator<Item = MapEntity> + Clone,
{
    let len = entities.clone().count();
    let count = u32::try_from(len).map_err(|_| EncodeError::TooManyEntities)?;
    let mut header = [0u8; HEADER_LEN];
    header[field::MAGIC].copy_from_slice(&MAGIC);
    header[field::VERSION].copy_from_slice(&VERSION.to_le_bytes());
    header[field::FLAGS].copy_from_slice(&0u16.to_le_bytes());
    for (chunk, v) in header[field::ORIGIN].chunks_exact_mut(8).zip(origin.iter()) {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
    header[field::COUNT].copy_from_slice(&count.to_le_bytes());
    let mut crc = Crc32::new();
    crc.update(&header);
    sink(&header);
    for e in entities.take(len) {
        let mut record = [0u8; ENTITY_LEN];
        let c = e.entity.center.to_array();
        let values = [
            c[0],
            c[1],
            c[2],
            e.entity.weights[0],
            e.entity.weights[1],
            e.entity.weights[2],
        ];
        for (chunk, v) in record.chunks_exact_mut(4).zip(values.iter()) {
            chunk.copy_from_slice(&v.to_le_bytes());
        }
        if let Some(kind) = record.last_mut() {
            *kind = e.kind as u8;
        }
        crc.update(&record);
        sink(&record);
    }
    sink(&crc.finish().to_le_bytes());
    Ok(encoded_len(len))
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
                "map version {v} is not supported (this build reads {VERSION})"
            ),
            Self::BadCrc { stored, computed } => {
                write!(
                    f,
                    "checksum mismatch: stored {stored:08x}, computed {computed:08x}"
                )
            }
            Self::NonFiniteOrigin => write!(f, "origin is not finite"),
            Self::InvalidEntity { index } => write!(
                f,
                "entity {index} has a non-finite centre or an invalid weight"
            ),
            Self::UnknownKind { index, code } => {
                write!(f, "entity {index} has unknown kind code {code}")
            }
        }
    }
}

impl core::error::Error for DecodeError {}

/// A validated view of `.mema` bytes.
#[derive(Clone, Copy, Debug)]
pub struct MapFile<'a> {
    header: &'a [u8; HEADER_LEN],
    body: &'a [u8],
}

fn f64_at(bytes: &[u8; HEADER_LEN], at: usize) -> f64 {
    let mut b = [0u8; 8];
    if let Some(src) = bytes.get(at..at + 8) {
        b.copy_from_slice(src);
    }
    f64::from_le_bytes(b)
}

fn entity_from_record(record: &[u8]) -> (Entity, u8) {
    let mut values = [0f32; 6];
    for (v, chunk) in values.iter_mut().zip(record.chunks_exact(4)) {
        let mut b = [0u8; 4];
        b.copy_from_slice(chunk);
        *v = f32::from_le_bytes(b);
    }
    let kind = record.get(ENTITY_LEN - 1).copied().unwrap_or(u8::MAX);
    let entity = Entity {
        center: Point3::new(values[0], values[1], values[2]),
        weights: [values[3], values[4], values[5]],
    };
    (entity, kind)
}

impl<'a> MapFile<'a> {
    pub fn new_checked(bytes: &'a [u8]) -> Result<Self, DecodeError> {
        let got = bytes.len();
        let Some((header, rest)) = bytes.split_first_chunk::<HEADER_LEN>() else {
            return Err(DecodeError::Truncated {
                needed: encoded_len(0),
                got,
            });
        };
        if header[..4] != MAGIC {
            return Err(DecodeError::BadMagic);
        }
        let version = u16::from_le_bytes([header[4], header[5]]);
        if version != VERSION {
            return Err(DecodeError::UnsupportedVersion(version));
        }
        let count = u32::from_le_bytes([header[32], header[33], header[34], header[35]]) as usize;
        let needed = count
            .checked_mul(ENTITY_LEN)
            .and_then(|b| b.checked_add(HEADER_LEN + CRC_LEN))
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
        let (body, crc_bytes) = rest.split_at(ENTITY_LEN * count);
        let mut stored = [0u8; 4];
        stored.copy_from_slice(crc_bytes);
        let stored = u32::from_le_bytes(stored);
        let computed = crc32(bytes.get(..got - CRC_LEN).unwrap_or(&[]));
        if stored != computed {
            return Err(DecodeError::BadCrc { stored, computed });
        }
        let file = Self { header, body };
        if !file.origin().iter().all(|v| v.is_finite()) {
            return Err(DecodeError::NonFiniteOrigin);
        }
        for (index, record) in body.chunks_exact(ENTITY_LEN).enumerate() {
            let (entity, code) = entity_from_record(record);
            if !entity.center.is_finite()
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

    pub fn len(&self) -> usize {
        self.body.len() / ENTITY_LEN
    }

    pub fn is_empty(&self) -> bool {
        self.body.is_empty()
    }

    pub fn entities(&self) -> impl Iterator<Item = MapEntity> + 'a {
        self.body.chunks_exact(ENTITY_LEN).map(|record| {
            let (entity, code) = entity_from_record(record);
            MapEntity {
                entity,
                // Checked in new_checked; the fallback is never taken.
                kind: EntityKind::from_u8(code).unwrap_or(EntityKind::Ellipsoid),
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{OrFail, TestResult};

    fn sample() -> Result<Map<4>, &'static str> {
        let mut map = Map::<4>::new([1e6, -2.5, 300.125]);
        for (i, kind) in EntityKind::ALL.into_iter().enumerate() {
            let w = i as f32;
            map.push(MapEntity {
                entity: Entity {
                    center: Point3::new(w, -w, 0.5),
                    weights: [w, 1.0, 0.0],
                },
                kind,
            })
            .or_fail("room for four")?;
        }
        Ok(map)
    }

    #[test]
    fn round_trip_and_capacity() -> TestResult {
        let mut map = sample()?;
        let mut buf = [0u8; encoded_len(4)];
        let n = encode(map.origin, map.entities(), &mut buf).or_fail("fits")?;
        assert_eq!(n, buf.len());
        let file = MapFile::new_checked(&buf).or_fail("valid")?;
        assert_eq!(Map::<4>::from_file(&file).or_fail("fits")?, map);
        assert_eq!(
            Map::<3>::from_file(&file),
            Err(CapacityExceeded { capacity: 3 })
        );
        let extra = map.entities()[0];
        assert_eq!(map.push(extra), Err(CapacityExceeded { capacity: 4 }));
        assert_eq!(map.entities().len(), 4);
        let mut small = [0u8; 10];
        assert!(matches!(
            encode(map.origin, map.entities(), &mut small),
            Err(EncodeError::BufferTooSmall { .. })
        ));
        Ok(())
    }

    #[test]
    fn every_corruption_is_rejected() -> TestResult {
        let map = sample()?;
        let mut buf = [0u8; encoded_len(4)];
        encode(map.origin, map.entities(), &mut buf).or_fail("fits")?;
        for cut in 0..buf.len() {
            assert!(MapFile::new_checked(&buf[..cut]).is_err(), "cut at {cut}");
        }
        for byte in 0..buf.len() {
            for bit in 0..8 {
                let mut bad = buf;
                bad[byte] ^= 1 << bit;
                assert!(MapFile::new_checked(&bad).is_err(), "flip {byte}.{bit}");
            }
        }
        Ok(())
    }
}
