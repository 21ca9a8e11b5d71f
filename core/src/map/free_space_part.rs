//! The map file's optional free-space part (version 2, flag bit 1): the range images of the
//! sweeps the map was made from ([`crate::free_space`]), after the entity records and before
//! the CRC, so a map without it reads as before.
//!
//! | bytes | field |
//! |---|---|
//! | 0..4 | the part's length L after this field, u32 |
//! | 4..6 | image count, u16 |
//! | then per image | origin x, y, z (f32, relative to the map's origin), nearest range (f32, the map's unit), elevation low and high, azimuth start and width (f32, radians), rows and columns (u16), then rows x columns range codes (u8, row by row) |

use crate::free_space::Geometry;
use crate::geometry::Point3;

/// A geometry's bytes in the part.
pub const GEOMETRY_LEN: usize = 36;

/// The bytes of the part for `images`, its length field included; `None` if an image's codes
/// do not fill its geometry or the part would not fit its u32 length.
pub fn part_len<'b>(images: impl Iterator<Item = (Geometry, &'b [u8])>) -> Option<usize> {
    let mut len = 6usize;
    let mut count = 0usize;
    for (g, cells) in images {
        if cells.len() != g.pixels() || !g.is_valid() {
            return None;
        }
        len = len.checked_add(GEOMETRY_LEN + cells.len())?;
        count += 1;
    }
    (count <= usize::from(u16::MAX) && u32::try_from(len - 4).is_ok()).then_some(len)
}

/// Writes the part piece by piece into `sink` (checked first with [`part_len`]).
pub fn write_part<'b>(
    images: impl Iterator<Item = (Geometry, &'b [u8])> + Clone,
    len: usize,
    mut sink: impl FnMut(&[u8]),
) {
    let count = images.clone().count() as u16;
    let mut head = [0u8; 6];
    head[..4].copy_from_slice(&((len - 4) as u32).to_le_bytes());
    head[4..].copy_from_slice(&count.to_le_bytes());
    sink(&head);
    for (g, cells) in images {
        let mut out = [0u8; GEOMETRY_LEN];
        let floats = [
            g.origin.x,
            g.origin.y,
            g.origin.z,
            g.near,
            g.elevation[0],
            g.elevation[1],
            g.azimuth[0],
            g.azimuth[1],
        ];
        for (chunk, v) in out.chunks_exact_mut(4).zip(floats) {
            chunk.copy_from_slice(&v.to_le_bytes());
        }
        out[32..34].copy_from_slice(&g.rows.to_le_bytes());
        out[34..36].copy_from_slice(&g.columns.to_le_bytes());
        sink(&out);
        sink(cells);
    }
}

fn f32_at(bytes: &[u8], at: usize) -> f32 {
    let mut b = [0u8; 4];
    if let Some(src) = bytes.get(at..at + 4) {
        b.copy_from_slice(src);
    }
    f32::from_le_bytes(b)
}

fn u16_at(bytes: &[u8], at: usize) -> u16 {
    let mut b = [0u8; 2];
    if let Some(src) = bytes.get(at..at + 2) {
        b.copy_from_slice(src);
    }
    u16::from_le_bytes(b)
}

/// The images of a part's body (after its length field), each checked; an error if any is
/// invalid, runs past the body, or leaves bytes after the last.
pub fn images(body: &[u8]) -> impl Iterator<Item = Result<(Geometry, &[u8]), ()>> + Clone + '_ {
    let count = usize::from(u16_at(body, 0));
    let mut at = if body.len() >= 2 { 2 } else { usize::MAX };
    let mut left = count;
    core::iter::from_fn(move || {
        if at == usize::MAX {
            return None;
        }
        if left == 0 {
            let trailing = at != body.len();
            at = usize::MAX;
            return trailing.then_some(Err(()));
        }
        left -= 1;
        let image = (|| {
            let g = body.get(at..at.checked_add(GEOMETRY_LEN)?)?;
            let geometry = Geometry {
                origin: Point3::new(f32_at(g, 0), f32_at(g, 4), f32_at(g, 8)),
                near: f32_at(g, 12),
                elevation: [f32_at(g, 16), f32_at(g, 20)],
                azimuth: [f32_at(g, 24), f32_at(g, 28)],
                rows: u16_at(g, 32),
                columns: u16_at(g, 34),
            };
            let start = at + GEOMETRY_LEN;
            let cells = body.get(start..start.checked_add(geometry.pixels())?)?;
            geometry.is_valid().then_some((geometry, cells))
        })();
        match image {
            Some((g, cells)) => {
                at += GEOMETRY_LEN + cells.len();
                Some(Ok((g, cells)))
            }
            None => {
                at = usize::MAX;
                Some(Err(()))
            }
        }
    })
}
