//! Writing `.mema` files: whole into a buffer, or piece by piece for a device that has no room
//! for the whole map.

use super::record::ORIENTED_LEN;
use super::{
    FREE_SPACE_FLAG, HEADER_V2_LEN, Layout, MAGIC, MapEntity, QUANTIZED_FLAG, field,
    free_space_part, record,
};
use crate::free_space::Geometry;
use crate::link::crc32::Crc32;

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
    /// A free-space image whose codes do not fill its geometry, or one not finite, or a
    /// free-space part in the axis-aligned (version 1) layout.
    InvalidFreeSpace,
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
            Self::InvalidFreeSpace => write!(
                f,
                "a free-space image is not finite, does not fill its pixels, or the layout is version 1"
            ),
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
    sink: impl FnMut(&[u8]),
) -> Result<usize, EncodeError>
where
    I: Iterator<Item = MapEntity> + Clone,
{
    encode_pieces_with(layout, origin, entities, core::iter::empty(), sink)
}

/// [`encode_pieces_as`] with a free-space part of `images` (range images, their origins
/// relative to `origin`), when there are any: version 2 only.
pub fn encode_pieces_with<'b, I, J>(
    layout: Layout,
    origin: [f64; 3],
    entities: I,
    images: J,
    sink: impl FnMut(&[u8]),
) -> Result<usize, EncodeError>
where
    I: Iterator<Item = MapEntity> + Clone,
    J: Iterator<Item = (Geometry, &'b [u8])> + Clone,
{
    let len = entities.clone().count();
    encode_pieces_counted(layout, origin, len, entities, images, sink)
}

/// [`encode_pieces_with`] of `len` entities, for a caller that knows how many `entities`
/// yields without going through them (a streaming mapper's shells are computed as the
/// iterator yields them: on a device, a pass over them is a tenth of a second). `len` must be
/// what `entities` yields.
pub fn encode_pieces_counted<'b, I, J>(
    layout: Layout,
    origin: [f64; 3],
    len: usize,
    entities: I,
    images: J,
    mut sink: impl FnMut(&[u8]),
) -> Result<usize, EncodeError>
where
    I: Iterator<Item = MapEntity> + Clone,
    J: Iterator<Item = (Geometry, &'b [u8])> + Clone,
{
    let free_space = match images.clone().next() {
        None => 0,
        Some(_) if layout == Layout::AxisAligned => return Err(EncodeError::InvalidFreeSpace),
        Some(_) => {
            free_space_part::part_len(images.clone()).ok_or(EncodeError::InvalidFreeSpace)?
        }
    };
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
    let flags = if free_space > 0 {
        flags | FREE_SPACE_FLAG
    } else {
        flags
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
    if free_space > 0 {
        free_space_part::write_part(images, free_space, |piece| {
            crc.update(piece);
            sink(piece);
        });
    }
    sink(&crc.finish().to_le_bytes());
    Ok(layout.encoded_len(len) + free_space)
}
