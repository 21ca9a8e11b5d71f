//! LAS 1.0-1.4 and LAZ through the `las` crate (with its `laz` feature).
//!
//! LAS stores coordinates as i32 counts of the header's scale plus its offset; `las` applies
//! that transform in f64, and the points stay f64 until `Points::finish` moves them to the
//! bounding-box centre, so a UTM easting keeps its millimetres.
//!
//! Points are pulled in fixed batches rather than with `read_all`: `read_all` sizes its buffer
//! from the header's point count, which a corrupt header could set to 2^64.

use std::io::{Read, Seek};

use super::{At, Cloud, Ctx, Format, Points, ReadError};

/// Bytes of records per batch: 64k records of the 32 bytes most point formats take. A format
/// with extra bytes (a record may have up to 64 KiB) is read fewer records at a time: a LAZ
/// batch is not bounded by the file's length, and 64k of those would be 4 GiB.
const BATCH_BYTES: u64 = 1 << 21;

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
    let mut reader = las::Reader::new(source).map_err(|e| header_error(ctx, e))?;
    let header = reader.header();
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
        for ((x, y), z) in batch.x().zip(batch.y()).zip(batch.z()) {
            points.push([x, y, z]);
        }
        read += got;
        if got < want {
            return Err(ctx.truncated(format!(
                "the header declares {declared} points, the data ends after {read}"
            )));
        }
    }
    points.finish(ctx, format)
}

/// The header's offset to point data (bytes 96..100 in every LAS version; 0 if the file is
/// shorter, which `las` then reports), leaving `source` at its start.
fn data_offset(ctx: Ctx, source: &mut (impl Read + Seek)) -> Result<u32, ReadError> {
    let io = |cause| ReadError::Io {
        path: ctx.name().into(),
        cause,
    };
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
    use super::super::testkit::{XorShift, shared};
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
    }

    #[test]
    fn a_header_claiming_more_points_than_the_file_holds() {
        let mut b = shared("simple.las");
        b[107..111].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = read_cloud_bytes("big.las", &b).unwrap_err();
        assert!(matches!(e, ReadError::Truncated { .. }), "{e:?}");
    }
}
