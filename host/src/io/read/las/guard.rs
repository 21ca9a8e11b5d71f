//! Checks on a LAS file's header fields that `las` would trust into an allocation or an
//! overflow, made before `las` reads them: the extended VLRs of LAS 1.4, and the point count;
//! and on the LASzip VLR's items, which `laz` would trust into a panic.
//!
//! `las` 0.11's `raw::Vlr::read_from` sizes an EVLR's buffer from the u64 length in its header
//! before reading a byte of it, so a length of 2^40 asks for 1 TiB and aborts the process.
//! Past these checks every EVLR lies inside the file, so the buffer is at most its length.
//!
//! The regular VLRs need no such check: their length is a u16, so one buffer is at most 64 KiB,
//! and `las` reads them one after another, each filled before the next is made, so their count
//! (a u32) costs memory only as far as the file's bytes back it.

use std::io::{Read, Seek};

use super::super::{At, Ctx, ReadError};
use super::bytes_at;

/// The LAS 1.4 header's offset to the first EVLR (u64) and EVLR count (u32), which follow the
/// 235 bytes of a 1.3 header. `las` reads them in that version only, where it reads them at all.
const EVLR_START_AT: u64 = 235;
const EVLR_COUNT_AT: u64 = 243;

/// An EVLR's header: a reserved u16, a 16-byte user id, a u16 record id, the u64 length of the
/// data after the header (at byte 20) and a 32-byte description.
pub(in crate::io::read) const EVLR_HEADER: u64 = 60;
const EVLR_LENGTH_AT: u64 = 20;

/// Where the point data starts (u32), each record's length (u16), the legacy point count (u32)
/// and LAS 1.4's 64-bit point count (u64).
const POINT_DATA_AT: u64 = 96;
const RECORD_LENGTH_AT: u64 = 105;
const LEGACY_COUNT_AT: u64 = 107;
const COUNT_AT: u64 = 247;

/// Refuses a point count whose records' end, `offset + count * record length`, does not fit in
/// a u64: `las` computes it unchecked (`raw::Header::offset_to_end_of_points`), which panics in
/// a build with overflow checks and wraps into a misleading error without them. A header cut
/// before these fields is left to `las`.
pub(super) fn check_point_extent(
    ctx: Ctx,
    source: &mut (impl Read + Seek),
    len: u64,
) -> Result<(), ReadError> {
    if len < LEGACY_COUNT_AT + 4 {
        return Ok(());
    }
    let offset = u64::from(u32::from_le_bytes(bytes_at(ctx, source, POINT_DATA_AT)?));
    let record = u64::from(u16::from_le_bytes(bytes_at(ctx, source, RECORD_LENGTH_AT)?));
    let legacy = u64::from(u32::from_le_bytes(bytes_at(ctx, source, LEGACY_COUNT_AT)?));
    let mut counts = vec![(LEGACY_COUNT_AT, legacy)];
    let [major, minor] = bytes_at(ctx, source, 24)?;
    if (major, minor) >= (1, 4) && len >= COUNT_AT + 8 {
        counts.push((
            COUNT_AT,
            u64::from_le_bytes(bytes_at(ctx, source, COUNT_AT)?),
        ));
    }
    for (at, count) in counts {
        if count
            .checked_mul(record)
            .and_then(|b| b.checked_add(offset))
            .is_none()
        {
            return Err(ctx.bad_value(
                At::Offset(at),
                format!(
                    "the header counts {count} points of {record} bytes from byte {offset},                      past any file's end"
                ),
            ));
        }
    }
    Ok(())
}

/// Refuses EVLRs that run past the end of the file (`len` bytes): a first one starting too late
/// for its header, a count more than the bytes from it can hold, or one whose length runs past
/// the end. `las` reads only the first, and only in version 1.4; the others, and versions past
/// 1.4 with the same header, are checked too, so that a `las` reading more stays guarded. A
/// version before 1.4, a start or count of 0 (`las` then reads no EVLR) or a header cut before
/// these fields are left to `las`, which reads them or reports them.
pub(super) fn check_evlrs(
    ctx: Ctx,
    source: &mut (impl Read + Seek),
    len: u64,
) -> Result<(), ReadError> {
    if len < EVLR_COUNT_AT + 4 {
        return Ok(());
    }
    let [major, minor] = bytes_at(ctx, source, 24)?;
    if (major, minor) < (1, 4) {
        return Ok(());
    }
    let start = u64::from_le_bytes(bytes_at(ctx, source, EVLR_START_AT)?);
    let count = u32::from_le_bytes(bytes_at(ctx, source, EVLR_COUNT_AT)?);
    if start == 0 || count == 0 {
        return Ok(());
    }
    if start.checked_add(EVLR_HEADER).is_none_or(|end| end > len) {
        return Err(ctx.bad_value(
            At::Offset(EVLR_START_AT),
            format!(
                "the first EVLR starts at byte {start}, too late for its {EVLR_HEADER}-byte \
                 header in a file of {len} bytes"
            ),
        ));
    }
    let most = (len - start) / EVLR_HEADER;
    if u64::from(count) > most {
        return Err(ctx.bad_value(
            At::Offset(EVLR_COUNT_AT),
            format!(
                "the header counts {count} EVLRs, more than the {most} headers of \
                 {EVLR_HEADER} bytes that the file holds from byte {start}"
            ),
        ));
    }
    let mut at = start;
    for i in 0..count {
        // `at` never passes `len`: each step below is checked against it.
        let Some(room) = (len - at).checked_sub(EVLR_HEADER) else {
            return Err(ctx.bad_value(
                At::Offset(EVLR_COUNT_AT),
                format!(
                    "the header counts {count} EVLRs, the file ends after {i} of them at byte \
                     {at}"
                ),
            ));
        };
        let length_at = at + EVLR_LENGTH_AT;
        let length = u64::from_le_bytes(bytes_at(ctx, source, length_at)?);
        if length > room {
            return Err(ctx.bad_value(
                At::Offset(length_at),
                format!(
                    "EVLR {i} at byte {at} declares {length} bytes of data, the file holds \
                     {room} after its header"
                ),
            ));
        }
        at += EVLR_HEADER + length;
    }
    Ok(())
}

/// The LASzip VLR's item count (u16), after its compressor, coder, version, options, chunk
/// size and special EVLRs; then each item's type, size and version (u16 each).
const LAZ_ITEMS_AT: usize = 32;

/// The bytes a LASzip item of a fixed-size type decodes to, as `laz` 0.13 decodes it (its
/// `LazItemType::size`); `None` for extra bytes (types 0 and 14), which take the size they
/// declare, and for types `laz` does not know and reports itself.
fn laz_item_size(item_type: u16) -> Option<u16> {
    match item_type {
        6 => Some(20),      // Point10
        7 => Some(8),       // GPS time
        8 | 11 => Some(6),  // RGB
        9 | 13 => Some(29), // wave packet
        10 => Some(30),     // Point14
        12 => Some(8),      // RGB and NIR
        _ => None,
    }
}

/// Refuses a LASzip VLR (`vlr`, its data) whose items `laz` 0.13 would trust into a panic: no
/// item at all (`record_decompressor_from_laz_items` expects one), an item declaring a size
/// other than its type's (`laz` splits each record by the sizes its decoders take, and a part
/// longer than the declared sizes left panics in `byteslice.rs`), or items that do not add up to
/// the point record's `record_len` bytes (none would split the records into empty chunks). A
/// sound file's items describe its record exactly. A VLR too short for its items is left to
/// `laz`, which reports it.
pub(super) fn check_laz_items(ctx: Ctx, vlr: &[u8], record_len: u16) -> Result<(), ReadError> {
    let Some(items) = laz_items(vlr) else {
        return Ok(());
    };
    if items.is_empty() {
        return Err(ctx.bad_value(At::Header, "the LASzip VLR lists no items"));
    }
    for (i, &(item_type, size, _)) in items.iter().enumerate() {
        if let Some(want) = laz_item_size(item_type)
            && size != want
        {
            return Err(ctx.bad_value(
                At::Header,
                format!(
                    "LASzip item {i} (type {item_type}) declares {size} bytes, its type takes \
                     {want}"
                ),
            ));
        }
    }
    let total: u32 = items.iter().map(|&(_, size, _)| u32::from(size)).sum();
    if total != u32::from(record_len) {
        return Err(ctx.bad_value(
            At::Header,
            format!("the LASzip items take {total} bytes of each point record of {record_len}"),
        ));
    }
    Ok(())
}

/// The items of a LASzip VLR's data: type, size and version of each; `None` if the data is too
/// short for the count it gives (`laz` reports that).
fn laz_items(vlr: &[u8]) -> Option<Vec<(u16, u16, u16)>> {
    let u16_at = |at: usize| Some(u16::from_le_bytes(vlr.get(at..at + 2)?.try_into().ok()?));
    (0..usize::from(u16_at(LAZ_ITEMS_AT)?))
        .map(|i| {
            let at = LAZ_ITEMS_AT + 2 + 6 * i;
            Some((u16_at(at)?, u16_at(at + 2)?, u16_at(at + 4)?))
        })
        .collect()
}

/// Layers of a layered (LASzip version 3) item in a chunk's header: Point14's nine, RGB14's one,
/// RGB and NIR's two, a wave packet's one, extra bytes' one a byte; `None` for an item that is
/// not layered.
fn laz_layers(item_type: u16, size: u16, version: u16) -> Option<u64> {
    if version < 3 {
        return None;
    }
    match item_type {
        10 => Some(9),
        11 | 13 => Some(1),
        12 => Some(2),
        14 => Some(u64::from(size)),
        _ => None,
    }
}

/// Refuses a LAZ file whose first chunk's layer sizes (layered items, LAZ 1.4) add up to more
/// bytes than the file holds after them: `laz` 0.13 sizes a buffer by each before reading it,
/// so a damaged size of 4 GB reserved 4 GB (a `cloud_readers` campaign finding). The chunk
/// starts after the chunk table's offset: the first point raw (`record_len` bytes), the chunk's
/// point count, then each layer's size (u32).
pub(super) fn check_first_chunk_layers(
    ctx: Ctx,
    source: &mut (impl Read + Seek),
    vlr: &[u8],
    data_at: u64,
    record_len: u16,
    len: u64,
) -> Result<(), ReadError> {
    let Some(items) = laz_items(vlr) else {
        return Ok(());
    };
    let mut layers = 0u64;
    for (item_type, size, version) in items {
        match laz_layers(item_type, size, version) {
            Some(n) => layers += n,
            // Items of older versions are not layered: no sizes to check.
            None => return Ok(()),
        }
    }
    let sizes_at = data_at + 8 + u64::from(record_len) + 4;
    let after = sizes_at + 4 * layers;
    if after > len {
        // A file too short for its first chunk's header is `laz`'s to report.
        return Ok(());
    }
    let mut total = 0u64;
    for k in 0..layers {
        let at = sizes_at + 4 * k;
        total += u64::from(u32::from_le_bytes(bytes_at::<4>(ctx, source, at)?));
    }
    if total > len - after {
        return Err(ctx.bad_value(
            At::Offset(sizes_at),
            format!(
                "the first LAZ chunk's layers take {total} bytes, the file holds {} after them",
                len - after
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::super::testkit::expect_err;
    use super::super::super::{Format, read_cloud_bytes};
    use super::*;

    /// A LAS 1.4 file (LAZ if `compressed`) of three points and, after them, one EVLR of
    /// `data`, as `las` writes it.
    fn las_1_4_with_evlr(data: &[u8], compressed: bool) -> Vec<u8> {
        let mut builder = las::Builder::from((1, 4));
        builder.point_format.is_compressed = compressed;
        builder.evlrs.push(las::Vlr {
            user_id: "mema".to_owned(),
            record_id: 1,
            description: "test".to_owned(),
            data: data.to_vec(),
        });
        let header = builder.into_header().unwrap();
        let mut writer = las::Writer::new(std::io::Cursor::new(Vec::new()), header).unwrap();
        for x in [1.0, 2.0, 3.0] {
            let point = las::Point {
                x,
                y: 2.0 * x,
                z: -x,
                ..Default::default()
            };
            writer.write_point(point).unwrap();
        }
        writer.close().unwrap();
        writer.into_inner().unwrap().into_inner()
    }

    fn u64_at(b: &[u8], at: u64) -> u64 {
        let at = at as usize;
        u64::from_le_bytes(b[at..at + 8].try_into().unwrap())
    }

    fn with(b: &[u8], at: u64, value: &[u8]) -> Vec<u8> {
        let (mut b, at) = (b.to_vec(), at as usize);
        b[at..at + value.len()].copy_from_slice(value);
        b
    }

    fn bad_value_at(name: &str, bytes: &[u8], at: u64) {
        let e = expect_err(name, bytes, "BadValue");
        assert!(
            matches!(e, ReadError::BadValue { at: At::Offset(o), .. } if o == at),
            "{name}: {e:?}"
        );
    }

    /// `las` makes an EVLR's buffer from its declared length before reading it: 2^40 aborted the
    /// test binary with "memory allocation of 1099511627776 bytes failed".
    #[test]
    fn a_point_count_whose_extent_overflows_is_an_error() {
        for compressed in [false, true] {
            let good = las_1_4_with_evlr(b"data", compressed);
            // Legacy count 0 makes `las` use the 64-bit one; 2^64 - 1 records overflow.
            let zero_legacy = with(&good, LEGACY_COUNT_AT, &0u32.to_le_bytes());
            let huge = with(&zero_legacy, COUNT_AT, &u64::MAX.to_le_bytes());
            bad_value_at("huge.las", &huge, COUNT_AT);
        }
    }

    #[test]
    fn an_evlr_longer_than_the_file_is_an_error() {
        let data = b"twelve bytes";
        for compressed in [false, true] {
            let file = las_1_4_with_evlr(data, compressed);
            let len = file.len() as u64;
            let start = u64_at(&file, EVLR_START_AT);
            let length_at = start + EVLR_LENGTH_AT;
            assert_eq!(file[25], 4, "version 1.4");
            assert_eq!(u64_at(&file, length_at), data.len() as u64);
            assert_eq!(
                start + EVLR_HEADER + data.len() as u64,
                len,
                "the EVLR ends the file"
            );

            // As written it reads, its points and the `las` header's EVLR as they were.
            let cloud = read_cloud_bytes("evlr.las", &file).unwrap();
            let format = if compressed { Format::Laz } else { Format::Las };
            assert_eq!(
                (cloud.format, cloud.slots, cloud.origin),
                (format, 3, [2.0, 4.0, -2.0])
            );
            let header = las::Header::new(std::io::Cursor::new(&file)).unwrap();
            assert_eq!(header.evlrs()[0].data, data);

            let huge = (1u64 << 40).to_le_bytes();
            bad_value_at("huge.las", &with(&file, length_at, &huge), length_at);
            let one_over = (data.len() as u64 + 1).to_le_bytes();
            bad_value_at("over.las", &with(&file, length_at, &one_over), length_at);
            let all = u64::MAX.to_le_bytes();
            bad_value_at("max.las", &with(&file, length_at, &all), length_at);
        }
    }

    /// Without the checks `las` reports a start past the end as a file cut short, and reads a
    /// file counting more EVLRs than it holds, since it reads only the first.
    #[test]
    fn an_evlr_start_or_count_past_the_end_is_an_error() {
        for compressed in [false, true] {
            let file = las_1_4_with_evlr(b"data", compressed);
            let len = file.len() as u64;
            for (name, start) in [
                ("past.las", len + 1),
                ("far.las", 1 << 40),
                ("max.las", u64::MAX),
                ("short.las", len - EVLR_HEADER + 1),
            ] {
                let bytes = with(&file, EVLR_START_AT, &start.to_le_bytes());
                bad_value_at(name, &bytes, EVLR_START_AT);
            }
            for count in [2, u32::MAX] {
                let bytes = with(&file, EVLR_COUNT_AT, &count.to_le_bytes());
                bad_value_at("count.las", &bytes, EVLR_COUNT_AT);
            }
            // Two EVLR headers fit in the bytes from the first, but its data leaves no room
            // for a second.
            let file = las_1_4_with_evlr(&[0; 70], compressed);
            let bytes = with(&file, EVLR_COUNT_AT, &2u32.to_le_bytes());
            bad_value_at("second.las", &bytes, EVLR_COUNT_AT);
        }
    }

    /// The items of the LASzip VLR that campaigns of `cloud_readers` found `laz` 0.13 panicking
    /// on (none: "There should be at least one LazItem" in `details.rs`; a size other than its
    /// type's: "mid > len" in `byteslice.rs`), and items not adding up to the record, are
    /// refused in one line; the items as written read.
    #[test]
    fn laz_items_laz_would_panic_on_are_an_error() {
        let mut builder = las::Builder::from((1, 2));
        builder.point_format = las::point::Format::new(3).unwrap();
        builder.point_format.is_compressed = true;
        let header = builder.into_header().unwrap();
        let mut writer = las::Writer::new(std::io::Cursor::new(Vec::new()), header).unwrap();
        for x in [1.0, 2.0, 3.0] {
            let point = las::Point {
                x,
                gps_time: Some(x),
                color: Some(las::Color::new(1, 2, 3)),
                ..Default::default()
            };
            writer.write_point(point).unwrap();
        }
        writer.close().unwrap();
        let file = writer.into_inner().unwrap().into_inner();
        let vlr_at = file
            .windows(14)
            .position(|w| w == b"laszip encoded")
            .unwrap()
            - 2;
        let count_at = (vlr_at + 54 + LAZ_ITEMS_AT) as u64;
        let item = |i: u64, field: u64| count_at + 2 + 6 * i + 2 * field;
        // Point10, GPS time, RGB: 20 + 8 + 6 bytes of each 34-byte record.
        let items: Vec<u16> = (0..10)
            .map(|k| u16::from_le_bytes(file[count_at as usize + 2 * k..][..2].try_into().unwrap()))
            .collect();
        assert_eq!(items, [3, 6, 20, 2, 7, 8, 2, 8, 6, 2]);
        assert_eq!(read_cloud_bytes("items.laz", &file).unwrap().slots, 3);
        let u16s = |v: u16| v.to_le_bytes();
        for (name, at, value) in [
            ("none.laz", count_at, u16s(0)),
            ("short_point.laz", item(0, 1), u16s(10)),
            ("long_time.laz", item(1, 1), u16s(65534)),
            ("two_points.laz", item(1, 0), u16s(6)),
            ("two_items.laz", count_at, u16s(2)),
        ] {
            let e = expect_err(name, &with(&file, at, &value), "BadValue");
            assert!(
                matches!(e, ReadError::BadValue { at: At::Header, .. }),
                "{name}: {e:?}"
            );
        }
    }

    /// Three points (x and GPS time 1, 2, 3) in a LAZ file of LAS `version` and point `format`,
    /// as `las` writes it.
    fn written_laz(version: (u8, u8), format: u8) -> Vec<u8> {
        let mut builder = las::Builder::from(version);
        builder.point_format = las::point::Format::new(format).unwrap();
        builder.point_format.is_compressed = true;
        let header = builder.into_header().unwrap();
        let mut writer = las::Writer::new(std::io::Cursor::new(Vec::new()), header).unwrap();
        for x in [1.0, 2.0, 3.0] {
            writer
                .write_point(las::Point {
                    x,
                    gps_time: Some(x),
                    ..Default::default()
                })
                .unwrap();
        }
        writer.close().unwrap();
        writer.into_inner().unwrap().into_inner()
    }

    /// A chunk table of no chunks for the points (variable-size chunks: "index out of bounds"
    /// in `laz`'s sequential decompression, a campaign finding; fixed-size ones too) is refused
    /// in one line.
    #[test]
    fn a_chunk_table_of_no_chunks_is_an_error() {
        let file = written_laz((1, 2), 1);
        assert_eq!(read_cloud_bytes("chunks.laz", &file).unwrap().slots, 3);
        let data_at = u32::from_le_bytes(file[96..100].try_into().unwrap()) as usize;
        let table_at = u64::from_le_bytes(file[data_at..data_at + 8].try_into().unwrap());
        let vlr_at = file
            .windows(14)
            .position(|w| w == b"laszip encoded")
            .unwrap()
            - 2;
        let chunk_size_at = (vlr_at + 54 + 12) as u64;
        let none = with(&file, table_at + 4, &0u32.to_le_bytes());
        for (name, bytes) in [
            ("fixed.laz", none.clone()),
            (
                "variable.laz",
                with(&none, chunk_size_at, &0u32.to_le_bytes()),
            ),
        ] {
            let e = expect_err(name, &bytes, "BadValue");
            assert!(
                matches!(e, ReadError::BadValue { at: At::Offset(o), .. } if o == table_at + 4),
                "{name}: {e:?}"
            );
        }
    }

    /// A LAZ 1.4 file (point format 6, layered) whose first chunk declares a layer of 4 GB, as
    /// a `cloud_readers` campaign found (`laz` reserved it before reading), is refused in one
    /// line at the layer sizes; the file as written reads.
    #[test]
    fn a_layer_larger_than_the_file_is_an_error() {
        let file = written_laz((1, 4), 6);
        assert_eq!(read_cloud_bytes("layers.laz", &file).unwrap().slots, 3);
        let data_at = u64::from(u32::from_le_bytes(file[96..100].try_into().unwrap()));
        let sizes_at = data_at + 8 + 30 + 4;
        for layer in [0u64, 4, 8] {
            let bytes = with(&file, sizes_at + 4 * layer, &0xFFFF_FFF0u32.to_le_bytes());
            let e = expect_err("layer.laz", &bytes, "BadValue");
            assert!(
                matches!(e, ReadError::BadValue { at: At::Offset(o), .. } if o == sizes_at),
                "layer {layer}: {e:?}"
            );
        }
    }

    /// `las` reads no EVLR where the start or the count is 0, nor in a file before 1.4, so
    /// nothing there is checked: the same lengths read as they did.
    #[test]
    fn evlr_fields_las_does_not_read_are_left_alone() {
        let file = las_1_4_with_evlr(b"data", false);
        let length_at = u64_at(&file, EVLR_START_AT) + EVLR_LENGTH_AT;
        let huge = with(&file, length_at, &(1u64 << 40).to_le_bytes());
        for (at, value) in [(EVLR_START_AT, &[0; 8][..]), (EVLR_COUNT_AT, &[0; 4])] {
            let cloud = read_cloud_bytes("off.las", &with(&huge, at, value)).unwrap();
            assert_eq!(cloud.slots, 3);
        }
        // The same bytes called 1.3: `las` reads the 375-byte header as 235 and padding.
        let cloud = read_cloud_bytes("1_3.las", &with(&huge, 25, &[3])).unwrap();
        assert_eq!(cloud.slots, 3);
    }
}
