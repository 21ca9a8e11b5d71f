//! PCD reader: v0.7 headers, and the older ones PCL still reads (no VERSION line; `COLUMNS`
//! for FIELDS; SIZE and TYPE missing, meaning 4-byte floats).
//!
//! `DATA ascii` is one point per line; `DATA binary` is row-major, one little-endian record per
//! point; `DATA binary_compressed` is a u32 compressed size, a u32 uncompressed size, then LZF
//! data that decompresses field-major (every point's first field, then every point's second,
//! ...), with padding fields named `_` left out as PCL's writer does. Organized clouds keep
//! invalid pixels as NaN slots; they are counted and dropped.

use super::{
    At, Cloud, Ctx, Endian, Format, Line, Lines, Points, ReadError, Scalar, lzf, parse_f64,
    parse_usize, quote, tokens,
};

/// True if the first line that is not a comment starts a PCD header.
pub(super) fn has_header(bytes: &[u8]) -> bool {
    for line in Lines::new(bytes) {
        let text = line.text.trim_ascii_start();
        if text.starts_with(b"# .PCD") {
            return true;
        }
        if text.is_empty() || text.starts_with(b"#") {
            continue;
        }
        return matches!(
            tokens(text).next(),
            Some(b"VERSION" | b"FIELDS" | b"COLUMNS")
        );
    }
    false
}

struct Field {
    name: String,
    size: usize,
    ty: u8,
    count: usize,
}

#[derive(Clone, Copy)]
enum Data {
    Ascii,
    Binary,
    Compressed,
}

/// Where one coordinate sits in each of the three layouts.
#[derive(Clone, Copy)]
struct Coord {
    scalar: Scalar,
    /// Index among the values of an ascii line.
    value: usize,
    /// Byte offset inside a row-major record.
    offset: usize,
    /// Byte offset of its column per point of the field-major layout (times the point count).
    column: usize,
}

/// A header line's values, with its line number for errors.
type Entries<T> = Option<(usize, Vec<T>)>;

pub(super) fn read(ctx: Ctx, bytes: &[u8]) -> Result<Cloud, ReadError> {
    let mut lines = Lines::new(bytes);
    let mut names: Entries<String> = None;
    let mut sizes: Entries<usize> = None;
    let mut types: Entries<u8> = None;
    let mut counts: Entries<usize> = None;
    let (mut width, mut height, mut points) = (None, None, None);
    let data = loop {
        // A header line without its newline is a cut file, whatever the line says.
        let Some(line) = lines.next().filter(|l| l.terminated) else {
            return Err(ctx.truncated(format!(
                "PCD header ends at byte {} before its DATA line",
                bytes.len()
            )));
        };
        let at = At::Line(line.number);
        let mut toks = tokens(line.text);
        let Some(keyword) = toks.next() else { continue };
        let number = |t: &[u8]| {
            parse_usize(t).ok_or_else(|| {
                ctx.bad_header(
                    at,
                    format!("{} is not a count for {}", quote(t), quote(keyword)),
                )
            })
        };
        match keyword {
            _ if keyword.starts_with(b"#") => {}
            b"VERSION" | b"VIEWPOINT" => {}
            b"FIELDS" | b"COLUMNS" => {
                let list = toks
                    .map(|t| String::from_utf8_lossy(t).into_owned())
                    .collect();
                names = Some((line.number, list));
            }
            b"SIZE" => sizes = Some((line.number, toks.map(number).collect::<Result<_, _>>()?)),
            b"COUNT" => counts = Some((line.number, toks.map(number).collect::<Result<_, _>>()?)),
            b"TYPE" => {
                let list = toks.map(|t| match t {
                    [ty @ (b'F' | b'I' | b'U')] => Ok(*ty),
                    _ => Err(ctx.bad_header(at, format!("TYPE {}; expected F, I or U", quote(t)))),
                });
                types = Some((line.number, list.collect::<Result<_, _>>()?));
            }
            b"WIDTH" | b"HEIGHT" | b"POINTS" => {
                let t = toks.next().unwrap_or_default();
                let n = Some(number(t)?);
                match keyword {
                    b"WIDTH" => width = n,
                    b"HEIGHT" => height = n,
                    _ => points = n,
                }
            }
            b"DATA" => {
                break match toks.next() {
                    Some(b"ascii") => Data::Ascii,
                    Some(b"binary") => Data::Binary,
                    Some(b"binary_compressed") => Data::Compressed,
                    Some(other) => return Err(ctx.unsupported(format!("DATA {}", quote(other)))),
                    None => return Err(ctx.bad_header(at, "DATA line without a kind")),
                };
            }
            other => {
                return Err(ctx.bad_header(at, format!("unknown header keyword {}", quote(other))));
            }
        }
    };

    let fields = fields(ctx, names, sizes, types, counts)?;
    let slots = slots(ctx, width, height, points)?;
    let [x, y, z] = ["x", "y", "z"].map(|axis| coord(ctx, &fields, axis));
    let coords = [x?, y?, z?];
    let format = match data {
        Data::Ascii => Format::PcdAscii,
        Data::Binary => Format::PcdBinary,
        Data::Compressed => Format::PcdBinaryCompressed,
    };
    let points = if slots == 0 {
        Points::with_capacity(0)
    } else {
        match data {
            Data::Ascii => ascii(ctx, lines, &fields, slots, coords)?,
            Data::Binary => binary(ctx, bytes, lines.pos(), &fields, slots, coords)?,
            Data::Compressed => compressed(ctx, bytes, lines.pos(), &fields, slots, coords)?,
        }
    };
    points.finish(ctx, format)
}

fn fields(
    ctx: Ctx,
    names: Entries<String>,
    sizes: Entries<usize>,
    types: Entries<u8>,
    counts: Entries<usize>,
) -> Result<Vec<Field>, ReadError> {
    let (line, names) = names.ok_or_else(|| ctx.bad_header(At::Header, "no FIELDS line"))?;
    let n = names.len();
    if n == 0 {
        return Err(ctx.bad_header(At::Line(line), "FIELDS names no field"));
    }
    let check = |keyword: &str, entries: Option<(usize, usize)>| match entries {
        Some((line, len)) if len != n => Err(ctx.bad_header(
            At::Line(line),
            format!("{keyword} has {len} entries, FIELDS has {n}"),
        )),
        _ => Ok(()),
    };
    check("SIZE", sizes.as_ref().map(|(l, v)| (*l, v.len())))?;
    check("TYPE", types.as_ref().map(|(l, v)| (*l, v.len())))?;
    check("COUNT", counts.as_ref().map(|(l, v)| (*l, v.len())))?;
    // Old headers without SIZE/TYPE/COUNT mean one 4-byte float per field, as in PCL.
    let sizes = sizes.map_or_else(|| vec![4; n], |(_, v)| v);
    let types = types.map_or_else(|| vec![b'F'; n], |(_, v)| v);
    let counts = counts.map_or_else(|| vec![1; n], |(_, v)| v);
    let fields = names
        .into_iter()
        .zip(sizes)
        .zip(types.into_iter().zip(counts))
        .map(|((name, size), (ty, count))| Field {
            name,
            size,
            ty,
            count,
        })
        .collect();
    Ok(fields)
}

fn slots(
    ctx: Ctx,
    width: Option<usize>,
    height: Option<usize>,
    points: Option<usize>,
) -> Result<usize, ReadError> {
    match (width, height, points) {
        (Some(w), h, p) => {
            let h = h.unwrap_or(1);
            let wh = w.checked_mul(h).ok_or_else(|| {
                ctx.bad_header(At::Header, format!("WIDTH {w} × HEIGHT {h} overflows"))
            })?;
            match p {
                Some(p) if p != wh => Err(ctx.bad_header(
                    At::Header,
                    format!("POINTS {p}, but WIDTH {w} × HEIGHT {h} = {wh}"),
                )),
                _ => Ok(wh),
            }
        }
        (None, None, Some(p)) => Ok(p),
        (None, Some(h), _) => Err(ctx.bad_header(At::Header, format!("HEIGHT {h} without WIDTH"))),
        (None, None, None) => Err(ctx.bad_header(At::Header, "no WIDTH or POINTS line")),
    }
}

fn coord(ctx: Ctx, fields: &[Field], axis: &str) -> Result<Coord, ReadError> {
    let overflow = || ctx.bad_header(At::Header, "the point size overflows");
    let (mut value, mut offset, mut column) = (0usize, 0usize, 0usize);
    for f in fields {
        let bytes = f.size.checked_mul(f.count).ok_or_else(overflow)?;
        if f.name == axis {
            let scalar = match (f.ty, f.size) {
                (b'F', 4) => Scalar::F32,
                (b'F', 8) => Scalar::F64,
                (b'I', 1) => Scalar::I8,
                (b'I', 2) => Scalar::I16,
                (b'I', 4) => Scalar::I32,
                (b'I', 8) => Scalar::I64,
                (b'U', 1) => Scalar::U8,
                (b'U', 2) => Scalar::U16,
                (b'U', 4) => Scalar::U32,
                (b'U', 8) => Scalar::U64,
                (ty, size) => {
                    let ty = char::from(ty);
                    return Err(ctx.unsupported(format!("field {axis} is TYPE {ty} SIZE {size}")));
                }
            };
            if f.count != 1 {
                return Err(ctx.unsupported(format!("field {axis} has COUNT {}", f.count)));
            }
            return Ok(Coord {
                scalar,
                value,
                offset,
                column,
            });
        }
        value = value.checked_add(f.count).ok_or_else(overflow)?;
        offset = offset.checked_add(bytes).ok_or_else(overflow)?;
        if f.name != "_" {
            column = column.checked_add(bytes).ok_or_else(overflow)?;
        }
    }
    let names: Vec<&str> = fields.iter().map(|f| f.name.as_str()).collect();
    Err(ctx.bad_header(
        At::Header,
        format!("no field {axis} (FIELDS {})", names.join(" ")),
    ))
}

/// Sum of `size × count` over the fields `keep` selects, checked.
fn record_size(
    ctx: Ctx,
    fields: &[Field],
    keep: impl Fn(&Field) -> bool,
) -> Result<usize, ReadError> {
    fields
        .iter()
        .filter(|f| keep(f))
        .try_fold(0usize, |sum, f| {
            f.size.checked_mul(f.count).and_then(|b| sum.checked_add(b))
        })
        .ok_or_else(|| ctx.bad_header(At::Header, "the point size overflows"))
}

fn ascii(
    ctx: Ctx,
    mut lines: Lines,
    fields: &[Field],
    slots: usize,
    coords: [Coord; 3],
) -> Result<Points, ReadError> {
    let values = fields
        .iter()
        .try_fold(0usize, |sum, f| sum.checked_add(f.count));
    let values = values.ok_or_else(|| ctx.bad_header(At::Header, "too many values per point"))?;
    // Each value takes at least a character and a separator; `values` >= 3 (x, y, z).
    let mut points = Points::with_capacity(slots.min(lines.remaining() / values.saturating_mul(2)));
    for done in 0..slots {
        let line = lines.next_non_blank().ok_or_else(|| {
            ctx.truncated(format!(
                "DATA ascii has {done} point lines, POINTS declares {slots}"
            ))
        })?;
        let p = ascii_point(ctx, &line, values, coords).map_err(|e| ctx.cut_short(&line, e))?;
        points.push(p);
    }
    Ok(points)
}

fn ascii_point(
    ctx: Ctx,
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
                *c = parse_f64(tok).ok_or_else(|| {
                    ctx.bad_value(
                        at,
                        format!("{} is not a number; expected {axis}", quote(tok)),
                    )
                })?;
            }
        }
    }
    if found != values {
        return Err(ctx.bad_value(at, format!("{found} values; the fields need {values}")));
    }
    Ok(p)
}

/// Bytes of the data section that must be present, or a `Truncated` naming what is missing.
fn need<'a>(
    ctx: Ctx,
    bytes: &'a [u8],
    body: usize,
    what: &str,
    need: u128,
) -> Result<&'a [u8], ReadError> {
    let have = bytes.len().saturating_sub(body);
    if need > have as u128 {
        return Err(ctx.truncated(format!(
            "DATA {what} needs {need} bytes after the header at offset {body}, file has {have}"
        )));
    }
    Ok(bytes.get(body..body + need as usize).unwrap_or_default())
}

#[inline]
fn read_at(bytes: &[u8], at: usize, scalar: Scalar) -> f64 {
    // Callers pass offsets inside records they sized from the same fields; NaN is unreachable.
    bytes
        .get(at..)
        .and_then(|b| scalar.read(b, Endian::Little))
        .unwrap_or(f64::NAN)
}

fn binary(
    ctx: Ctx,
    bytes: &[u8],
    body: usize,
    fields: &[Field],
    slots: usize,
    coords: [Coord; 3],
) -> Result<Points, ReadError> {
    let stride = record_size(ctx, fields, |_| true)?;
    let data = need(ctx, bytes, body, "binary", slots as u128 * stride as u128)?;
    let mut points = Points::with_capacity(slots);
    // `stride` >= 3: x, y and z each take at least a byte.
    for record in data.chunks_exact(stride.max(1)) {
        points.push(coords.map(|c| read_at(record, c.offset, c.scalar)));
    }
    Ok(points)
}

fn compressed(
    ctx: Ctx,
    bytes: &[u8],
    body: usize,
    fields: &[Field],
    slots: usize,
    coords: [Coord; 3],
) -> Result<Points, ReadError> {
    let sizes = need(ctx, bytes, body, "binary_compressed", 8)?;
    let word = |i: usize| {
        sizes
            .get(i..)
            .and_then(|w| w.first_chunk())
            .map_or(0, |w| u32::from_le_bytes(*w))
    };
    let (packed, unpacked) = (word(0) as usize, word(4) as usize);
    let stream = need(ctx, bytes, body, "binary_compressed", 8 + packed as u128)?;
    let stream = stream.get(8..).unwrap_or_default();
    let record = record_size(ctx, fields, |f| f.name != "_")?;
    let expected = slots as u128 * record as u128;
    if unpacked as u128 != expected {
        return Err(ctx.bad_value(At::Offset(body + 4), format!(
            "uncompressed size {unpacked} does not match POINTS {slots} × {record} bytes = {expected}"
        )));
    }
    let data = lzf::decompress(stream, unpacked)
        .map_err(|e| ctx.bad_value(At::Offset(body + 8 + e.at()), e.to_string()))?;
    // Each column is `slots × size` bytes starting at `column × slots`, inside `data` because
    // its length was checked to be `slots × record`.
    let column = |c: Coord| {
        let start = c.column * slots;
        data.get(start..start + slots * c.scalar.size())
            .unwrap_or_default()
            .chunks_exact(c.scalar.size())
    };
    let [cx, cy, cz] = coords;
    let mut points = Points::with_capacity(slots);
    for ((x, y), z) in column(cx).zip(column(cy)).zip(column(cz)) {
        points.push([
            read_at(x, 0, cx.scalar),
            read_at(y, 0, cy.scalar),
            read_at(z, 0, cz.scalar),
        ]);
    }
    Ok(points)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::testkit::{DATA, assert_same, header_count, shared};
    use super::super::{Format, ReadError, read_cloud_bytes};

    /// Writes a PCD; `fields` are (name, TYPE, SIZE, COUNT) and each row holds every value of
    /// a point in field order. binary_compressed uses literal-only LZF runs, which any LZF
    /// decoder must accept, so the test does not need a compressor.
    pub fn write_pcd(
        data: &str,
        fields: &[(&str, char, usize, usize)],
        width: usize,
        rows: &[Vec<f64>],
    ) -> Vec<u8> {
        let list = |f: &dyn Fn(&(&str, char, usize, usize)) -> String| {
            fields.iter().map(f).collect::<Vec<_>>().join(" ")
        };
        let mut out = format!(
            "# .PCD v0.7 - written by the tests\nVERSION 0.7\nFIELDS {}\nSIZE {}\nTYPE {}\nCOUNT {}\nWIDTH {width}\nHEIGHT {}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {}\nDATA {data}\n",
            list(&|f| f.0.to_string()),
            list(&|f| f.2.to_string()),
            list(&|f| f.1.to_string()),
            list(&|f| f.3.to_string()),
            rows.len() / width,
            rows.len()
        )
        .into_bytes();
        let put = |out: &mut Vec<u8>, (ty, size): (char, usize), v: f64| match (ty, size) {
            (_, _) if data == "ascii" => out.extend_from_slice(format!("{} ", v as f32).as_bytes()),
            ('F', 4) => out.extend_from_slice(&(v as f32).to_le_bytes()),
            ('F', 8) => out.extend_from_slice(&v.to_le_bytes()),
            ('U', 1) => out.push(v as u8),
            ('U', 4) => out.extend_from_slice(&(v as u32).to_le_bytes()),
            ('I', 2) => out.extend_from_slice(&(v as i16).to_le_bytes()),
            _ => panic!("{ty}{size}"),
        };
        // Value index of each field's first value within a row.
        let starts: Vec<usize> = fields
            .iter()
            .scan(0, |n, f| Some(std::mem::replace(n, *n + f.3)))
            .collect();
        if data == "binary_compressed" {
            let mut columns = Vec::new();
            for (f, start) in fields.iter().zip(&starts).filter(|(f, _)| f.0 != "_") {
                for row in rows {
                    (0..f.3).for_each(|c| put(&mut columns, (f.1, f.2), row[start + c]));
                }
            }
            let stream: Vec<u8> = columns
                .chunks(32)
                .flat_map(|c| [&[c.len() as u8 - 1][..], c].concat())
                .collect();
            out.extend_from_slice(&(stream.len() as u32).to_le_bytes());
            out.extend_from_slice(&(columns.len() as u32).to_le_bytes());
            out.extend_from_slice(&stream);
            return out;
        }
        for row in rows {
            for (f, start) in fields.iter().zip(&starts) {
                (0..f.3).for_each(|c| put(&mut out, (f.1, f.2), row[start + c]));
            }
            if data == "ascii" {
                out.push(b'\n');
            }
        }
        out
    }

    /// All slots of a shared PCD as the independent pcd-rs crate reads them.
    fn pcd_rs(name: &str) -> Vec<[f64; 3]> {
        let reader = pcd_rs::DynReader::open(format!("{DATA}/{name}")).unwrap();
        let index = |axis: &str| {
            reader
                .meta()
                .field_defs
                .iter()
                .position(|f| f.name == axis)
                .unwrap()
        };
        let [ix, iy, iz] = ["x", "y", "z"].map(index);
        let value = |f: &pcd_rs::Field| match f {
            pcd_rs::Field::F32(v) => f64::from(v[0]),
            pcd_rs::Field::F64(v) => v[0],
            other => panic!("{other:?}"),
        };
        let records: Vec<pcd_rs::DynRecord> = reader.collect::<Result<_, _>>().unwrap();
        records
            .iter()
            .map(|r| [value(&r.0[ix]), value(&r.0[iy]), value(&r.0[iz])])
            .collect()
    }

    fn finite(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        points
            .iter()
            .copied()
            .filter(|p| p.iter().all(|c| c.is_finite()))
            .collect()
    }

    #[test]
    fn shared_pcds_match_pcd_rs() {
        for (name, slots, kept, format) in [
            ("car6.pcd", 10_031, 10_031, Format::PcdBinaryCompressed),
            ("milk.pcd", 13_704, 13_704, Format::PcdBinaryCompressed),
            ("lamppost.pcd", 1_771, 1_771, Format::PcdAscii),
            ("rops_cloud.pcd", 32_087, 32_087, Format::PcdAscii),
            ("cturtle.pcd", 167_198, 167_198, Format::PcdBinaryCompressed),
            (
                "five_people.pcd",
                307_200,
                239_075,
                Format::PcdBinaryCompressed,
            ),
            ("office1.pcd", 307_200, 254_456, Format::PcdBinaryCompressed),
        ] {
            let bytes = shared(name);
            let cloud = read_cloud_bytes(name, &bytes).unwrap();
            assert_eq!(cloud.slots, header_count(&bytes, "POINTS"), "{name}");
            let got = (
                cloud.slots,
                cloud.points.len(),
                cloud.dropped_non_finite,
                cloud.format,
            );
            assert_eq!(got, (slots, kept, slots - kept, format), "{name}");
            assert_same(&cloud, &finite(&pcd_rs(name)), name);
        }
    }

    /// car6's points with NaN holes, as an organized 5015 × 2 cloud with extra fields around
    /// x y z (a padding field among them).
    fn car6_rows() -> Vec<Vec<f64>> {
        let points = pcd_rs("car6.pcd");
        let hole = |i: usize, c: f64| if i % 10 == 3 { f64::NAN } else { c };
        let rows = points[..10_030].iter().enumerate();
        rows.map(|(i, p)| {
            vec![
                i as f64,
                hole(i, p[0]),
                0.0,
                1.0,
                2.0,
                3.0,
                7.0,
                p[1],
                0.5,
                0.25,
                0.125,
                p[2],
                255.0,
            ]
        })
        .collect()
    }

    pub fn car6_as(data: &str) -> Vec<u8> {
        car6_as_typed(data, 4)
    }

    fn car6_as_typed(data: &str, coord_size: usize) -> Vec<u8> {
        let fields = [
            ("intensity", 'F', 4, 1),
            ("x", 'F', coord_size, 1),
            ("_", 'U', 1, 4),
            ("ring", 'I', 2, 1),
            ("y", 'F', coord_size, 1),
            ("normal", 'F', 4, 3),
            ("z", 'F', coord_size, 1),
            ("label", 'U', 4, 1),
        ];
        write_pcd(data, &fields, 5015, &car6_rows())
    }

    #[test]
    fn car6_in_every_encoding_and_coordinate_type() {
        let want: Vec<[f64; 3]> = finite(
            &car6_rows()
                .iter()
                .map(|r| [r[1], r[7], r[11]])
                .collect::<Vec<_>>(),
        );
        for (data, format) in [
            ("ascii", Format::PcdAscii),
            ("binary", Format::PcdBinary),
            ("binary_compressed", Format::PcdBinaryCompressed),
        ] {
            for size in [4, 8] {
                let cloud = read_cloud_bytes("car6.pcd", &car6_as_typed(data, size)).unwrap();
                assert_eq!(
                    (cloud.format, cloud.slots, cloud.dropped_non_finite),
                    (format, 10_030, 1003)
                );
                assert_same(&cloud, &want, &format!("{data} F{size}"));
            }
        }
    }

    #[test]
    fn old_headers_and_line_errors() {
        // v0.5/0.6 style: no VERSION, COLUMNS, no SIZE/TYPE (4-byte floats), no WIDTH.
        let old = b"COLUMNS x y z\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 nan\n";
        let cloud = read_cloud_bytes("old.pcd", old).unwrap();
        assert_eq!(
            (cloud.slots, cloud.points.len(), cloud.origin),
            (2, 1, [1.0, 2.0, 3.0])
        );
        let bad = b"FIELDS x y z\nWIDTH 2\nDATA ascii\n1 2 3\n4 5\n";
        let e = read_cloud_bytes("bad.pcd", bad).unwrap_err();
        assert_eq!(
            e.to_string(),
            "bad.pcd: line 5: 2 values; the fields need 3"
        );
        let nan = b"FIELDS x y z\nWIDTH 2\nDATA ascii\nnan nan nan\nnan 1 1\n";
        let e = read_cloud_bytes("nan.pcd", nan).unwrap_err();
        assert!(
            matches!(e, ReadError::NoFinitePoints { slots: 2, .. }),
            "{e:?}"
        );
        let e = read_cloud_bytes("x.pcd", b"FIELDS x y z\nWIDTH 1\nDATA lzma\n").unwrap_err();
        assert!(matches!(e, ReadError::Unsupported { .. }), "{e:?}");
    }
}
