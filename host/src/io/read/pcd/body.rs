//! The three PCD bodies, each read from the stream as it arrives.
//!
//! `binary_compressed` is the one that needs care: its LZF output is field-major, so no point
//! is complete before the z column arrives near the end. Decompressing it whole (307,200 slots
//! of 16 bytes for an organized 640 × 480 frame) and then picking the coordinates out would
//! hold the file, the output and the points at once; instead the decoder keeps a sliding
//! window and hands each piece of output to [`Columns`], which writes x, y and z straight into
//! one slot per point and ignores every other field. The slots are the points, NaN ones
//! included, and are compacted in place at the end.
//!
//! The slot count comes from the header, and the only check before decoding is that the
//! compressed bytes could expand to it (LZF's 88×): 49 MB may claim 358 million points. So the
//! slots are made as the first coordinate column's values are decoded, past [`UPFRONT`] bytes
//! reserved at the start, and every reservation is fallible: a claim costs memory only as far
//! as the data backs it, and memory the machine refuses is an error, not an abort.

use std::collections::TryReserveError;

use super::super::points::Wide;
use super::super::stream::{Input, Line};
use super::super::xyz::{parse_f64, quote, tokens};
use super::super::{At, Endian, Points, ReadError, Scalar, lzf};
use super::{Coord, Field, record_size};

pub(super) fn ascii(
    input: &mut Input,
    fields: &[Field],
    slots: usize,
    coords: [Coord; 3],
) -> Result<Points, ReadError> {
    let ctx = input.ctx();
    let values = fields
        .iter()
        .try_fold(0usize, |sum, f| sum.checked_add(f.count));
    let values = values.ok_or_else(|| ctx.bad_header(At::Header, "too many values per point"))?;
    // Each value takes at least a character and a separator; `values` >= 3 (x, y, z).
    let room = input.remaining() / (values as u64).saturating_mul(2).max(1);
    let capacity = usize::try_from(room).map_or(slots, |r| r.min(slots));
    let mut points = Points::with_capacity(ctx, capacity)?;
    for done in 0..slots {
        let Some(line) = input.next_non_blank()? else {
            let what = format!("DATA ascii ends after {done} of {slots} points");
            return Err(ctx.truncated(what));
        };
        let p = ascii_point(ctx, &line, values, coords);
        points.push(p.map_err(|e| ctx.cut_short(&line, e))?);
    }
    Ok(points)
}

fn ascii_point(
    ctx: super::super::Ctx,
    line: &Line,
    values: usize,
    coords: [Coord; 3],
) -> Result<[f64; 3], ReadError> {
    let at = At::Line(line.number);
    let mut p = [f64::NAN; 3];
    let mut found = 0;
    for (i, tok) in tokens(line.text).enumerate() {
        found += 1;
        for ((c, coord), axis) in p.iter_mut().zip(coords).zip(["x", "y", "z"]) {
            if coord.value == i {
                let what = || format!("{} is not a number; expected {axis}", quote(tok));
                *c = parse_f64(tok).ok_or_else(|| ctx.bad_value(at, what()))?;
            }
        }
    }
    if found != values {
        return Err(ctx.bad_value(at, format!("{found} values; the fields need {values}")));
    }
    Ok(p)
}

/// Checks that the file holds `need` bytes from `body` (where the data section starts), or
/// names what is missing.
fn need(input: &Input, body: u64, what: &str, need: u128) -> Result<(), ReadError> {
    let have = input.len().saturating_sub(body);
    if need > u128::from(have) {
        return Err(input.ctx().truncated(format!(
            "DATA {what} needs {need} bytes after the header at offset {body}, file has {have}"
        )));
    }
    Ok(())
}

#[inline]
fn read_at(bytes: &[u8], at: usize, scalar: Scalar) -> f64 {
    // Callers pass offsets inside records they sized from the same fields; NaN is unreachable.
    let value = bytes.get(at..).and_then(|b| scalar.read(b, Endian::Little));
    value.unwrap_or(f64::NAN)
}

pub(super) fn binary(
    input: &mut Input,
    fields: &[Field],
    slots: usize,
    coords: [Coord; 3],
) -> Result<Points, ReadError> {
    // `stride` >= 3: x, y and z each take at least a byte.
    let stride = record_size(input.ctx(), fields, |_| true)?.max(1);
    need(input, input.pos(), "binary", slots as u128 * stride as u128)?;
    let mut points = Points::with_capacity(input.ctx(), slots)?;
    let point = |record: &[u8]| coords.map(|c| read_at(record, c.offset, c.scalar));
    // Fewer only if the file shrank after its length was checked.
    if input.records(stride, slots, |record| points.push(point(record)))? < slots {
        return Err(input.ended("DATA binary"));
    }
    Ok(points)
}

pub(super) fn compressed(
    input: &mut Input,
    fields: &[Field],
    slots: usize,
    coords: [Coord; 3],
) -> Result<Points, ReadError> {
    let ctx = input.ctx();
    let body = input.pos();
    need(input, body, "binary_compressed", 8)?;
    let sizes = input.peek(8)?;
    let word = |i: usize| {
        sizes
            .get(i..)
            .and_then(|w| w.first_chunk())
            .map(|w| u32::from_le_bytes(*w))
    };
    let (packed, unpacked) = (word(0).unwrap_or(0) as usize, word(4).unwrap_or(0) as usize);
    need(input, body, "binary_compressed", 8 + packed as u128)?;
    input.consume(8);
    let record = record_size(ctx, fields, |f| f.name != b"_")?;
    let expected = slots as u128 * record as u128;
    if unpacked as u128 != expected {
        let what = format!(
            "uncompressed size {unpacked}, but POINTS {slots} × {record} bytes = {expected}"
        );
        return Err(ctx.bad_value(At::Offset(body + 4), what));
    }
    // Slots of f32 when every coordinate type converts to f32 exactly (floats, small integers),
    // else of f64, so that no coordinate is rounded before it is moved to the local origin.
    let narrow = coords.iter().all(|c| {
        matches!(
            c.scalar,
            Scalar::F32 | Scalar::I8 | Scalar::U8 | Scalar::I16 | Scalar::U16
        )
    });
    if narrow {
        scatter::<[f32; 3]>(input, packed, unpacked, coords, slots).map(Points::from_slots_narrow)
    } else {
        scatter::<Wide>(input, packed, unpacked, coords, slots).map(Points::from_slots_wide)
    }
}

/// Decodes the `packed` bytes of LZF at the input into one slot per point.
fn scatter<S: Slot>(
    input: &mut Input,
    packed: usize,
    unpacked: usize,
    coords: [Coord; 3],
    slots: usize,
) -> Result<Vec<S>, ReadError> {
    let (ctx, stream) = (input.ctx(), input.pos());
    let lzf_error =
        |e: lzf::LzfError| ctx.bad_value(At::Offset(stream + e.at() as u64), e.to_string());
    let oom = |_| ctx.out_of_memory(format!("{slots} point slots of {} bytes", size_of::<S>()));
    // Before any slot is reserved: `unpacked` (slots × record) must be within what `packed`
    // bytes, which the file holds, can expand to.
    let mut decoder = lzf::Decoder::new(packed, unpacked).map_err(lzf_error)?;
    let mut columns = Columns::<S>::new(coords, slots, UPFRONT).map_err(oom)?;
    let mut left = packed;
    loop {
        let buffered = input.peek(lzf::MAX_CHUNK)?;
        let piece = buffered.get(..left).unwrap_or(buffered);
        let last = piece.len() == left;
        // `peek` returns at least a whole chunk unless the file ended.
        if !last && piece.len() < lzf::MAX_CHUNK {
            return Err(input.ended("DATA binary_compressed"));
        }
        let mut sink = |at: usize, bytes: &[u8]| columns.take(at, bytes);
        let used = decoder.feed(piece, last, &mut sink).map_err(lzf_error)?;
        columns.grown().map_err(oom)?;
        input.consume(used);
        left -= used;
        if last {
            break;
        }
    }
    decoder
        .finish(&mut |at: usize, bytes: &[u8]| columns.take(at, bytes))
        .map_err(lzf_error)?;
    columns.grown().map_err(oom)?;
    // The decoder produced exactly `unpacked` bytes, so the first column reached every slot.
    if columns.slots.len() != slots {
        let what = format!("{} of {slots} point slots decoded", columns.slots.len());
        return Err(ctx.bad_value(At::Offset(stream), what));
    }
    Ok(columns.slots)
}

/// Bytes of slots reserved before any output is decoded. Common clouds fit (a 640 × 480 frame's
/// slots take 3.7 MB as f32, 7.4 MB as f64), so theirs are one allocation of the exact size, as
/// the heap test checks; a larger claim gets its slots only as the data arrives, by doubling.
pub(in crate::io::read) const UPFRONT: usize = 16 << 20;

/// A slot the coordinates are written into, one axis at a time.
pub(super) trait Slot: Copy + Default {
    fn set(&mut self, axis: usize, c: f64);
}

impl Slot for [f32; 3] {
    #[inline]
    fn set(&mut self, axis: usize, c: f64) {
        if let Some(to) = self.get_mut(axis) {
            *to = c as f32;
        }
    }
}

impl Slot for Wide {
    #[inline]
    fn set(&mut self, axis: usize, c: f64) {
        Wide::set(self, axis, c);
    }
}

/// Where one coordinate's column sits in the decompressed output.
struct Column {
    start: usize,
    scalar: Scalar,
    /// The first bytes of a value that a piece of output cut in two.
    carry: [u8; 8],
    held: usize,
}

/// Writes the x, y and z columns of the field-major output into one slot per point.
pub(super) struct Columns<S> {
    axes: [Column; 3],
    /// The slots the header declares; `slots` reaches this many with the first column's end.
    n: usize,
    pub(super) slots: Vec<S>,
    /// A reservation the machine refused; `take` does nothing more once it is set.
    refused: Option<TryReserveError>,
}

impl<S: Slot> Columns<S> {
    /// Columns for `n` slots, with room for as many of them as `upfront` bytes hold.
    pub(super) fn new(
        coords: [Coord; 3],
        n: usize,
        upfront: usize,
    ) -> Result<Self, TryReserveError> {
        // A column starts at `column × n`: inside the output, whose size was checked to be
        // `n × record`.
        let axes = coords.map(|c| Column {
            start: c.column.saturating_mul(n),
            scalar: c.scalar,
            carry: [0; 8],
            held: 0,
        });
        let mut slots = Vec::new();
        crate::heap::fallible(|| slots.try_reserve_exact(n.min(upfront / size_of::<S>().max(1))))?;
        Ok(Columns {
            axes,
            n,
            slots,
            refused: None,
        })
    }

    /// Whether every slot the output has reached so far could be made.
    pub(super) fn grown(&mut self) -> Result<(), TryReserveError> {
        self.refused.take().map_or(Ok(()), Err)
    }

    /// Makes `slots[..upto]` exist (`upto` at most `n`). Only the first column in the output
    /// ever adds any: a later column starts where the earlier ones end, `n` values each.
    fn grow(slots: &mut Vec<S>, n: usize, upto: usize) -> Result<(), TryReserveError> {
        let (len, upto) = (slots.len(), upto.min(n));
        if upto <= len {
            return Ok(());
        }
        if upto > slots.capacity() {
            // Doubling keeps the copies few; the declared count bounds it.
            let target = upto.max(len.saturating_mul(2)).min(n);
            crate::heap::fallible(|| slots.try_reserve_exact(target - len))?;
        }
        slots.resize(upto, S::default());
        Ok(())
    }

    /// Takes the output bytes at offset `at`: the parts of them that fall in a coordinate's
    /// column become that coordinate of their slots.
    pub(super) fn take(&mut self, at: usize, bytes: &[u8]) {
        if self.refused.is_none()
            && let Err(e) = self.try_take(at, bytes)
        {
            self.refused = Some(e);
        }
    }

    fn try_take(&mut self, at: usize, bytes: &[u8]) -> Result<(), TryReserveError> {
        let n = self.n;
        for (axis, col) in self.axes.iter_mut().enumerate() {
            let size = col.scalar.size();
            let end = col.start.saturating_add(n.saturating_mul(size));
            let (lo, hi) = (at.max(col.start), at.saturating_add(bytes.len()).min(end));
            let Some(mut part) = bytes.get(lo.saturating_sub(at)..hi.saturating_sub(at)) else {
                continue;
            };
            if part.is_empty() {
                continue;
            }
            // The values this piece completes need their slots.
            Self::grow(&mut self.slots, n, (hi - col.start) / size)?;
            // A value cut by the previous piece starts this one (the pieces arrive in order).
            let mut index = (lo - col.start) / size;
            if col.held > 0 {
                let missing = (size - col.held).min(part.len());
                let (head, rest) = part.split_at(missing);
                if let Some(room) = col.carry.get_mut(col.held..col.held + missing) {
                    room.copy_from_slice(head);
                }
                col.held += missing;
                part = rest;
                if col.held < size {
                    continue;
                }
                if let Some(slot) = self.slots.get_mut(index) {
                    slot.set(axis, read_at(&col.carry, 0, col.scalar));
                }
                col.held = 0;
                index += 1;
            }
            let mut values = part.chunks_exact(size);
            let slots = self.slots.get_mut(index..).unwrap_or_default();
            if col.scalar == Scalar::F32 {
                // Nearly every cloud: the generic read's dispatch per value is worth skipping.
                for (value, slot) in values.by_ref().zip(slots) {
                    let raw = value.first_chunk().copied().unwrap_or_default();
                    slot.set(axis, f64::from(f32::from_le_bytes(raw)));
                }
            } else {
                for (value, slot) in values.by_ref().zip(slots) {
                    slot.set(axis, read_at(value, 0, col.scalar));
                }
            }
            let rest = values.remainder();
            if let Some(room) = col.carry.get_mut(..rest.len()) {
                room.copy_from_slice(rest);
                col.held = rest.len();
            }
        }
        Ok(())
    }
}
