//! LAS 1.0-1.4 and LAZ through the `las` crate (with its `laz` feature).
//!
//! LAS stores coordinates as i32 counts of the header's scale plus its offset; `las` applies
//! that transform in f64, and the points stay f64 until `Points::finish` moves them to the
//! bounding-box centre, so a UTM easting keeps its millimetres.
//!
//! Points are pulled in fixed batches rather than with `read_all`: `read_all` sizes its buffer
//! from the header's point count, which a corrupt header could set to 2^64.

use std::io::{Read, Seek, SeekFrom};

use super::{At, Cloud, Ctx, Format, Points, ReadError};
use crate::io::units::{FileUnit, from_geokeys, from_wkt};

mod guard;
#[cfg(test)]
pub(super) use guard::EVLR_HEADER;

/// Bytes of records per batch: 64k records of the 32 bytes most point formats take. A format
/// with extra bytes (a record may have up to 64 KiB) is read fewer records at a time: a LAZ
/// batch is not bounded by the file's length, and 64k of those would be 4 GiB.
pub(super) const BATCH_BYTES: u64 = 1 << 21;

/// Every LAS and LAZ file starts with this signature.
pub fn has_signature(bytes: &[u8]) -> bool {
    bytes.starts_with(b"LASF")
}

/// Reads the `len` bytes of `source`, positioned anywhere; `las` wants it owned and seekable.
pub fn read<R>(ctx: Ctx, mut source: R, len: u64) -> Result<Cloud, ReadError>
where
    R: Read + Seek + Send + Sync + 'static,
{
    let data_at = data_offset(ctx, &mut source)?;
    // `las` reads the first EVLR with the header, so this goes before `check_chunk_table`.
    guard::check_evlrs(ctx, &mut source, len)?;
    guard::check_point_extent(ctx, &mut source, len)?;
    source.rewind().map_err(io_error(ctx))?;
    check_chunk_table(ctx, &mut source, data_at, len)?;
    source.rewind().map_err(io_error(ctx))?;
    let mut reader = las::Reader::new(source).map_err(|e| header_error(ctx, e))?;
    let header = reader.header();
    let unit = file_unit(header);
    // A cloud that cannot be had in metres is refused before its points are decoded.
    ctx.units(unit.as_ref())?;
    let declared = header.number_of_points();
    let compressed = header.point_format().is_compressed;
    let format = if compressed { Format::Laz } else { Format::Las };
    let record_len = u64::from(header.point_format().len()).max(1);
    // The records the point data could hold stored as they are.
    let plain = len.saturating_sub(u64::from(data_at)) / record_len;
    if !compressed && declared > plain {
        // Uncompressed records can be counted before any is read.
        return Err(ctx.truncated(format!(
            "the header declares {declared} points of {record_len} bytes, the file holds {plain}"
        )));
    }
    // A LAS file's points, all of them. LAZ has no bound from its length: its arithmetic coder
    // codes a point like the one before in well under a bit, so 300,000 identical points take
    // 2.5 KB (a test below writes them) and 5 million 36 KB. It starts with room for the points
    // its bytes would hold stored plainly, 24 bytes of slots for each record of 20 or more, and
    // grows as points are decoded (`Points::grow`), never past the count declared.
    let capacity = usize::try_from(declared.min(plain)).unwrap_or(0);
    let mut points = Points::with_capacity(ctx, capacity)?;
    let mut batch = las::PointDataBuilder::new()
        .for_header(reader.header())
        .build();
    let mut read = 0u64;
    while read < declared {
        let want = (BATCH_BYTES / record_len).max(1).min(declared - read);
        let got = reader
            .fill_points(want, &mut batch)
            .map_err(|e| data_error(ctx, read, e))?;
        let most = usize::try_from(declared - read).unwrap_or(usize::MAX);
        points.grow(ctx, usize::try_from(got).unwrap_or(usize::MAX), most)?;
        // The withheld flag: bit 7 of the classification byte in formats 0-5, bit 2 of the
        // classification flags in 6-10 (LAS 1.4, Table 15 and Table 16).
        let extended = batch.format().is_extended;
        let record_len = batch.record_len().max(1);
        let withheld = batch.raw_bytes().chunks_exact(record_len).map(|record| {
            record
                .get(15)
                .is_some_and(|&f| f & if extended { 0b100 } else { 0x80 } != 0)
        });
        let classes = batch.classification().zip(withheld);
        for (((x, y), z), (class, withheld)) in batch.x().zip(batch.y()).zip(batch.z()).zip(classes)
        {
            match ctx.classes().keeps(class, withheld) {
                Ok(()) => points.push([x, y, z]),
                Err(why) => points.leave_out(why),
            }
        }
        read += got;
        if got < want {
            return Err(ctx.truncated(format!(
                "the header declares {declared} points, the data ends after {read}"
            )));
        }
    }
    points.finish_in(ctx, format, unit)
}

/// The unit the header's coordinate system gives: the WKT where the header's flag says the
/// CRS is WKT (LAS 1.4), else the GeoKeys, else any WKT record.
fn file_unit(header: &las::Header) -> Option<FileUnit> {
    let record = |id: u16| {
        header
            .all_vlrs()
            .find(|v| v.user_id.eq_ignore_ascii_case("LASF_Projection") && v.record_id == id)
            .map(|v| v.data.as_slice())
    };
    let wkt = || from_wkt(&String::from_utf8_lossy(record(2112)?));
    let geokeys = || from_geokeys(record(34735)?, record(34736));
    if header.has_wkt_crs() {
        wkt().or_else(geokeys)
    } else {
        geokeys().or_else(wkt)
    }
}

/// The header's offset to point data (bytes 96..100 in every LAS version; 0 if the file is
/// shorter, which `las` then reports), leaving `source` at its start.
fn data_offset(ctx: Ctx, source: &mut (impl Read + Seek)) -> Result<u32, ReadError> {
    let io = io_error(ctx);
    source.rewind().map_err(io)?;
    let mut head = Vec::with_capacity(100);
    source
        .by_ref()
        .take(100)
        .read_to_end(&mut head)
        .map_err(io)?;
    source.rewind().map_err(io)?;
    let offset = head.get(96..100).and_then(|b| b.try_into().ok());
    Ok(offset.map_or(0, u32::from_le_bytes))
}

/// LASzip compressors that keep a chunk table: point-wise chunked (2) and layered chunked (3).
/// Point-wise (1) codes the points as one stream with no table, and `laz` reads none.
const CHUNKED: [u16; 2] = [2, 3];

/// The fewest bytes a chunk of points takes: it opens with its first point stored whole, and the
/// shortest LAS record (format 0) is 20 bytes.
pub(super) const MIN_CHUNK_BYTES: u64 = 20;

/// Refuses a LAZ chunk table that lists more chunks than the file can hold. `laz` 0.13's
/// `ChunkTable::read` reserves 16 bytes for each chunk the table counts before decoding any,
/// so a count of 2^32 asks for 64 GiB and aborts the process. Past this check each chunk but
/// one takes at least 20 of the file's bytes, so the reservation stays under its length.
///
/// The layout is `laz`'s: point data opens with an i64 offset to the table (at most the start
/// of point data when the writer could not go back to set it, and then the file's last 8 bytes
/// hold it instead), and the table opens with a u32 version and a u32 count. A file without
/// the LASzip VLR, with a chunk size field cut off or with no table is left to `las` and `laz`,
/// which read it or report it.
fn check_chunk_table(
    ctx: Ctx,
    source: &mut (impl Read + Seek),
    data_at: u32,
    len: u64,
) -> Result<(), ReadError> {
    let header = las::Header::new(&mut *source).map_err(|e| header_error(ctx, e))?;
    if !header.point_format().is_compressed {
        return Ok(());
    }
    let Some(vlr) = header.vlrs().iter().find(|v| las::laz::is_laszip_vlr(v)) else {
        return Ok(());
    };
    // Before `las` hands the items to `laz`, which panics on some.
    guard::check_laz_items(ctx, &vlr.data, header.point_format().len())?;
    guard::check_first_chunk_layers(
        ctx,
        source,
        &vlr.data,
        u64::from(data_at),
        header.point_format().len(),
        len,
    )?;
    let field = |at: usize| {
        vlr.data
            .get(at..at + 4)
            .and_then(|b| <[u8; 4]>::try_from(b).ok())
    };
    let (Some([c0, c1, _, _]), Some(chunk_size)) = (field(0), field(12)) else {
        return Ok(());
    };
    if !CHUNKED.contains(&u16::from_le_bytes([c0, c1])) {
        return Ok(());
    }
    let Some((offset_at, table_at)) = table_offset(ctx, source, data_at, len)? else {
        return Ok(());
    };
    if table_at.checked_add(8).is_none_or(|end| end > len) {
        return Err(ctx.bad_value(
            At::Offset(offset_at),
            format!(
                "the LAZ chunk table offset {table_at} is past the end of the file ({len} bytes)"
            ),
        ));
    }
    let [_, _, _, _, n0, n1, n2, n3] = bytes_at::<8>(ctx, source, table_at)?;
    let chunks = u64::from(u32::from_le_bytes([n0, n1, n2, n3]));
    let points = header.number_of_points();
    // A writer always closes a chunk, so points in no chunk are a damaged table, and `laz`
    // 0.13 indexes past its end on them (a `cloud_readers` campaign finding).
    if chunks == 0 && points > 0 {
        return Err(ctx.bad_value(
            At::Offset(table_at + 4),
            format!("the LAZ chunk table lists no chunk for {points} points"),
        ));
    }
    // A chunk size of 0 or 2^32 - 1 means chunks of any size, as `LazVlr` reads it.
    let by_points = match u32::from_le_bytes(chunk_size) {
        0 | u32::MAX => points,
        size => points.div_ceil(u64::from(size)),
    };
    let chunk_bytes = table_at.saturating_sub(u64::from(data_at) + 8);
    // One more for the chunk a writer closes on finishing, empty if the points filled the last:
    // `laz` records it always, so an empty LAZ file has a table of one chunk.
    let most = by_points
        .min(chunk_bytes / MIN_CHUNK_BYTES)
        .saturating_add(1);
    if chunks > most {
        return Err(ctx.bad_value(
            At::Offset(table_at + 4),
            format!(
                "the LAZ chunk table lists {chunks} chunks, more than the {most} that \
                 {points} points in {chunk_bytes} bytes can make"
            ),
        ));
    }
    Ok(())
}

/// Where the offset to the chunk table sits and what it says, as `laz` finds them; `None` where
/// `laz` finds no table or cannot read the offset (and says so itself).
fn table_offset(
    ctx: Ctx,
    source: &mut (impl Read + Seek),
    data_at: u32,
    len: u64,
) -> Result<Option<(u64, u64)>, ReadError> {
    for at in [u64::from(data_at), len.saturating_sub(8)] {
        if len < 8 || at > len - 8 {
            return Ok(None);
        }
        let offset = i64::from_le_bytes(bytes_at(ctx, source, at)?);
        if offset > i64::from(data_at) {
            return Ok(u64::try_from(offset).ok().map(|table| (at, table)));
        }
    }
    Ok(None)
}

/// The `N` bytes at `at`, which the caller has checked lie inside the file.
fn bytes_at<const N: usize>(
    ctx: Ctx,
    source: &mut (impl Read + Seek),
    at: u64,
) -> Result<[u8; N], ReadError> {
    let mut bytes = [0; N];
    source.seek(SeekFrom::Start(at)).map_err(io_error(ctx))?;
    source.read_exact(&mut bytes).map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            ctx.truncated(format!(
                "the file ends before byte {at}, short of its length"
            ))
        } else {
            io_error(ctx)(e)
        }
    })?;
    Ok(bytes)
}

fn io_error(ctx: Ctx) -> impl Fn(std::io::Error) -> ReadError + Copy {
    move |cause| ReadError::Io {
        path: ctx.name().into(),
        cause,
    }
}

fn header_error(ctx: Ctx, e: las::Error) -> ReadError {
    match e {
        las::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            ctx.truncated("the file ends inside the LAS header or its VLRs")
        }
        other => ctx.bad_header(At::Header, one_line(&other)),
    }
}

fn data_error(ctx: Ctx, point: u64, e: las::Error) -> ReadError {
    match e {
        las::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            ctx.truncated(format!("the point data ends after about {point} points"))
        }
        other => ctx.bad_value(At::Header, format!("point {point}: {}", one_line(&other))),
    }
}

/// `las` and `laz` errors sometimes span lines; a mema error never does.
fn one_line(e: &dyn std::error::Error) -> String {
    e.to_string()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::super::read_cloud_bytes;
    use super::super::testkit::{XorShift, expect_err, guide_says, shared, thousands};
    use super::*;

    fn u32_at(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    fn f64_at(b: &[u8], at: usize) -> f64 {
        f64::from_le_bytes(b[at..at + 8].try_into().unwrap())
    }

    /// The point count as the LAS specification lays the header out: the legacy u32 at 107, or
    /// the u64 at 247 from version 1.4 on.
    fn declared(b: &[u8]) -> u64 {
        let legacy = u64::from(u32_at(b, 107));
        if b[25] >= 4 && legacy == 0 {
            u64::from_le_bytes(b[247..255].try_into().unwrap())
        } else {
            legacy
        }
    }

    #[test]
    fn shared_files_read_with_their_header_counts() {
        for (name, format) in [
            ("simple.las", Format::Las),
            ("vegetation_1_3.las", Format::Las),
            ("autzen_trim.laz", Format::Laz),
        ] {
            let bytes = shared(name);
            let cloud = read_cloud_bytes(name, &bytes).unwrap();
            assert_eq!(cloud.format, format, "{name}");
            assert_eq!(cloud.slots as u64, declared(&bytes), "{name}");
            assert_eq!(cloud.points.len(), cloud.slots, "{name}");
        }
    }

    /// Each point against the raw i32 record scaled by hand: within half the file's scale (the
    /// f32 local coordinate's own rounding is far below it at these extents).
    #[test]
    fn coordinates_round_trip_within_the_scale() {
        for name in ["simple.las", "vegetation_1_3.las"] {
            let b = shared(name);
            let data_at = u32_at(&b, 96) as usize;
            let record = usize::from(u16::from_le_bytes([b[105], b[106]]));
            let scale = [131, 139, 147].map(|at| f64_at(&b, at));
            let offset = [155, 163, 171].map(|at| f64_at(&b, at));
            let cloud = read_cloud_bytes(name, &b).unwrap();
            let records = b[data_at..].chunks_exact(record);
            for (i, (r, p)) in records.zip(&cloud.points).enumerate() {
                for j in 0..3 {
                    let raw = i32::from_le_bytes(r[4 * j..4 * j + 4].try_into().unwrap());
                    let want = f64::from(raw) * scale[j] + offset[j];
                    let got = cloud.origin[j] + f64::from(p[j]);
                    let err = (got - want).abs();
                    assert!(
                        err <= scale[j] / 2.0,
                        "{name} point {i} axis {j}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn cut_and_mutated_files_are_one_line_errors() {
        let seeds = ["simple.las", "vegetation_1_3.las", "autzen_trim.laz"].map(shared);
        for (bytes, cut) in seeds
            .iter()
            .flat_map(|b| [10, 200, 400, b.len() - 7].map(|c| (b, c)))
        {
            let e = read_cloud_bytes("cut.las", &bytes[..cut]).unwrap_err();
            let msg = e.to_string();
            assert!(msg.starts_with("cut.las: ") && !msg.contains('\n'), "{msg}");
        }
        let mut rng = XorShift(0x1a5);
        for case in 0..300 {
            let seed = &seeds[rng.below(seeds.len())];
            let mut bytes = seed[..seed.len().min(40_000)].to_vec();
            for _ in 0..1 + rng.below(4) {
                let at = 4 + rng.below(bytes.len() - 4);
                bytes[at] = rng.next() as u8;
            }
            let result = std::panic::catch_unwind(|| read_cloud_bytes("m.las", &bytes));
            match result.unwrap_or_else(|_| panic!("case {case} panicked")) {
                Ok(cloud) => assert!(cloud.points.iter().flatten().all(|c| c.is_finite())),
                Err(e) => assert!(!e.to_string().contains('\n'), "{e}"),
            }
        }
    }

    /// LAZ may hold far more points than bytes, so no bound from its length is safe: 300,000
    /// identical points take some 2.5 KB, and every one is read, room made as they are decoded.
    #[test]
    fn laz_denser_than_a_point_a_byte() {
        let n = 300_000;
        let mut builder = las::Builder::from((1, 2));
        builder.point_format = las::point::Format::new(1).unwrap();
        builder.point_format.is_compressed = true;
        let header = builder.into_header().unwrap();
        let mut writer = las::Writer::new(std::io::Cursor::new(Vec::new()), header).unwrap();
        let point = las::Point {
            x: 1.0,
            y: 2.0,
            z: 3.0,
            gps_time: Some(0.0),
            ..Default::default()
        };
        for _ in 0..n {
            writer.write_point(point.clone()).unwrap();
        }
        writer.close().unwrap();
        let bytes = writer.into_inner().unwrap().into_inner();
        assert!(bytes.len() < n / 10, "{} bytes", bytes.len());
        let cloud = read_cloud_bytes("dense.laz", &bytes).unwrap();
        assert_eq!(
            (cloud.format, cloud.slots, cloud.points.len()),
            (Format::Laz, n, n)
        );
        assert_eq!(cloud.origin, [1.0, 2.0, 3.0]);
        guide_says(
            "docs/performance.md",
            &format!(
                "({} identical points take {:.1} KB)",
                thousands(n as u64),
                bytes.len() as f64 / 1e3
            ),
        );
    }

    /// `laz` reserves room for every chunk its table counts before decoding one: a count of
    /// 2^32 - 1 would ask for 64 GiB and abort the test binary. An offset past the end is
    /// refused too, from the start of point data or, unset there, from the file's last 8 bytes.
    #[test]
    fn a_laz_chunk_table_the_file_cannot_hold_is_an_error() {
        let laz = shared("autzen_trim.laz");
        let data_at = u32_at(&laz, 96) as usize;
        let table_at = i64::from_le_bytes(laz[data_at..data_at + 8].try_into().unwrap()) as usize;
        assert_eq!(
            u32_at(&laz, table_at + 4),
            3,
            "110,000 points in chunks of 50,000"
        );
        let (count_at, end) = (table_at + 4, laz.len() - 8);
        let past = (laz.len() as i64 - 7).to_le_bytes();
        let (huge, five, far, unset) = (
            u32::MAX.to_le_bytes(),
            5u32.to_le_bytes(),
            i64::MAX.to_le_bytes(),
            (-1i64).to_le_bytes(),
        );
        let edit = |edits: &[(usize, &[u8])]| {
            let mut b = laz.clone();
            for (at, value) in edits {
                b[*at..at + value.len()].copy_from_slice(value);
            }
            b
        };
        for (name, edits, at) in [
            ("chunks.laz", &[(count_at, &huge[..])][..], count_at),
            ("chunks_5.laz", &[(count_at, &five[..])], count_at),
            ("past.laz", &[(data_at, &past[..])], data_at),
            ("far.laz", &[(data_at, &far[..])], data_at),
            ("tail.laz", &[(data_at, &unset[..]), (end, &past)], end),
        ] {
            let e = expect_err(name, &edit(edits), "BadValue");
            assert!(
                matches!(e, ReadError::BadValue { at: At::Offset(o), .. } if o == at as u64),
                "{name}: {e:?}"
            );
        }
        // The table as written reads; one chunk more passes this check, and `laz` then fails
        // to decode a fourth entry from the table's bytes and says so.
        let cloud = read_cloud_bytes("chunks_3.laz", &edit(&[])).unwrap();
        assert_eq!(cloud.points.len(), 110_000);
        let four = 4u32.to_le_bytes();
        let e = read_cloud_bytes("chunks_4.laz", &edit(&[(count_at, &four)])).unwrap_err();
        assert!(
            !matches!(e, ReadError::BadValue { at: At::Offset(o), .. } if o == count_at as u64),
            "{e:?}"
        );
    }

    /// `laz` closes a file with the chunk it has open, so a LAZ of no points has a table of one
    /// chunk: not one too many.
    #[test]
    fn an_empty_laz_is_no_points_not_a_bad_chunk_table() {
        let mut builder = las::Builder::from((1, 2));
        builder.point_format.is_compressed = true;
        let header = builder.into_header().unwrap();
        let mut writer = las::Writer::new(std::io::Cursor::new(Vec::new()), header).unwrap();
        writer.close().unwrap();
        let bytes = writer.into_inner().unwrap().into_inner();
        let data_at = u32_at(&bytes, 96) as usize;
        let table_at = i64::from_le_bytes(bytes[data_at..data_at + 8].try_into().unwrap());
        assert_eq!(u32_at(&bytes, table_at as usize + 4), 1);
        expect_err("empty.laz", &bytes, "NoFinitePoints");
    }

    #[test]
    fn a_header_claiming_more_points_than_the_file_holds() {
        let mut b = shared("simple.las");
        b[107..111].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = read_cloud_bytes("big.las", &b).unwrap_err();
        assert!(matches!(e, ReadError::Truncated { .. }), "{e:?}");
    }

    /// Noise (7, 18) and withheld points are left out and counted, in a legacy and an extended
    /// point format written by the `las` crate; `Classes::All` keeps them.
    #[test]
    fn noise_and_withheld_points_are_left_out_and_counted() {
        use crate::io::read::{Classes, Screening, read_cloud_in_metres_keeping};
        let keeping = |classes| Screening {
            classes,
            ..Screening::DEFAULT
        };
        let dir = std::env::temp_dir().join(format!("mema-las-classes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (format, version) in [(1u8, (1, 2)), (6, (1, 4))] {
            let mut builder = las::Builder::from(version);
            builder.point_format = las::point::Format::new(format).unwrap();
            let header = builder.into_header().unwrap();
            let path = dir.join(format!("classes-{format}.las"));
            let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
            let mut writer = las::Writer::new(file, header).unwrap();
            let classes = [2u8, 7, 18, 6, 2];
            for (i, &class) in classes.iter().enumerate() {
                let point = las::Point {
                    x: i as f64,
                    y: 0.0,
                    z: if class == 7 || class == 18 { 1e5 } else { 0.0 },
                    classification: las::point::Classification::new(class).unwrap(),
                    is_withheld: i == 4,
                    gps_time: Some(0.0),
                    ..Default::default()
                };
                writer.write_point(point).unwrap();
            }
            writer.close().unwrap();
            let kept =
                read_cloud_in_metres_keeping(&path, None, keeping(Classes::default())).unwrap();
            assert_eq!(kept.points.len(), 2, "format {format}");
            let d = kept.dropped_by_class;
            assert_eq!(
                (d.noise, d.withheld, d.other_classes),
                (2, 1, 0),
                "format {format}"
            );
            let all = read_cloud_in_metres_keeping(&path, None, keeping(Classes::All)).unwrap();
            assert_eq!((all.points.len(), all.dropped_by_class.total()), (5, 0));
            let only: Classes = "6".parse().unwrap();
            let six = read_cloud_in_metres_keeping(&path, None, keeping(only)).unwrap();
            assert_eq!(
                (six.points.len(), six.dropped_by_class.other_classes),
                (1, 3)
            );
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
