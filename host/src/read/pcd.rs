//! PCD reader: v0.7 headers, and the older ones PCL still reads (no VERSION line; `COLUMNS`
//! for FIELDS; SIZE and TYPE missing, meaning 4-byte floats).
//!
//! `DATA ascii` is one point per line; `DATA binary` is row-major, one little-endian record per
//! point; `DATA binary_compressed` is a u32 compressed size, a u32 uncompressed size, then LZF
//! data that decompresses field-major (every point's first field, then every point's second,
//! ...), with padding fields named `_` left out as PCL's writer does. Organized clouds keep
//! invalid pixels as NaN slots; they are counted and dropped.

use super::xyz::{Line, Lines, parse_f64, parse_usize, quote, tokens};
use super::{At, Cloud, Ctx, Endian, Format, Points, ReadError, Scalar, lzf};

/// True if the first line that is not a comment starts a PCD header.
pub(super) fn has_header(bytes: &[u8]) -> bool {
    for line in Lines::new(bytes) {
        let text = line.text.trim_ascii_start();
        if text.starts_with(b"# .PCD") {
            return true;
        }
        if !text.is_empty() && !text.starts_with(b"#") {
            let keyword = tokens(text).next();
            return matches!(keyword, Some(b"VERSION" | b"FIELDS" | b"COLUMNS"));
        }
    }
    false
}

/// A header line: its keyword, line number and values.
struct Entry<'a> {
    key: &'a [u8],
    line: usize,
    values: Vec<&'a [u8]>,
}

struct Field<'a> {
    name: &'a [u8],
    size: usize,
    ty: u8,
    count: usize,
}

/// Where one coordinate sits in each of the three layouts.
#[derive(Clone, Copy)]
struct Coord {
    scalar: Scalar,
    /// Index among the values of an ascii line.
    value: usize,
    /// Byte offset inside a row-major record.
    offset: usize,
    /// Bytes per point of the columns before it in the field-major layout.
    column: usize,
}

pub(super) fn read(ctx: Ctx, bytes: &[u8]) -> Result<Cloud, ReadError> {
    let mut lines = Lines::new(bytes);
    let mut header = Vec::new();
    let format = loop {
        // A header line without its newline is a cut file, whatever the line says.
        let Some(line) = lines.next().filter(|l| l.terminated) else {
            let at = bytes.len();
            return Err(ctx.truncated(format!("PCD header ends at byte {at} before its DATA line")));
        };
        let mut toks = tokens(line.text);
        match toks.next() {
            None => {}
            Some(key) if key.starts_with(b"#") => {}
            Some(b"DATA") => match toks.next() {
                Some(b"ascii") => break Format::PcdAscii,
                Some(b"binary") => break Format::PcdBinary,
                Some(b"binary_compressed") => break Format::PcdBinaryCompressed,
                Some(other) => return Err(ctx.unsupported(format!("DATA {}", quote(other)))),
                None => return Err(ctx.bad_header(At::Line(line.number), "DATA without a kind")),
            },
            Some(
                key @ (b"VERSION" | b"FIELDS" | b"COLUMNS" | b"SIZE" | b"TYPE" | b"COUNT"
                | b"WIDTH" | b"HEIGHT" | b"VIEWPOINT" | b"POINTS"),
            ) => header.push(Entry {
                key,
                line: line.number,
                values: toks.collect(),
            }),
            Some(other) => {
                let what = format!("unknown header keyword {}", quote(other));
                return Err(ctx.bad_header(At::Line(line.number), what));
            }
        }
    };
    let find = |keys: &[&[u8]]| header.iter().rev().find(|e| keys.contains(&e.key));
    let Some(names) = find(&[b"FIELDS", b"COLUMNS"]).filter(|e| !e.values.is_empty()) else {
        return Err(ctx.bad_header(At::Header, "no FIELDS line naming the fields"));
    };
    let n = names.values.len();
    // Old headers without SIZE/TYPE/COUNT mean one 4-byte float per field, as in PCL.
    let sizes = per_field(ctx, find(&[b"SIZE"]), n, 4, parse_usize)?;
    let counts = per_field(ctx, find(&[b"COUNT"]), n, 1, parse_usize)?;
    let types = per_field(ctx, find(&[b"TYPE"]), n, b'F', |t| match t {
        [ty @ (b'F' | b'I' | b'U')] => Some(*ty),
        _ => None,
    })?;
    let fields: Vec<Field> = (names.values.iter().zip(sizes).zip(types).zip(counts))
        .map(|(((name, size), ty), count)| Field {
            name,
            size,
            ty,
            count,
        })
        .collect();
    let one = |key: &[u8]| match find(&[key]) {
        None => Ok(None),
        Some(e) => e
            .values
            .first()
            .and_then(|t| parse_usize(t))
            .map(Some)
            .ok_or_else(|| {
                let what = format!("{} needs a count", quote(key));
                ctx.bad_header(At::Line(e.line), what)
            }),
    };
    let slots = slots(ctx, one(b"WIDTH")?, one(b"HEIGHT")?, one(b"POINTS")?)?;
    let [x, y, z] = ["x", "y", "z"].map(|axis| coord(ctx, &fields, axis));
    let coords = [x?, y?, z?];
    let body = lines.pos();
    let points = match format {
        _ if slots == 0 => Points::with_capacity(0),
        Format::PcdAscii => ascii(ctx, lines, &fields, slots, coords)?,
        Format::PcdBinary => binary(ctx, bytes, body, &fields, slots, coords)?,
        _ => compressed(ctx, bytes, body, &fields, slots, coords)?,
    };
    points.finish(ctx, format)
}

/// One value per field from a SIZE, TYPE or COUNT line, or `default` for each if it is absent.
fn per_field<T: Clone>(
    ctx: Ctx,
    entry: Option<&Entry>,
    n: usize,
    default: T,
    parse: impl Fn(&[u8]) -> Option<T>,
) -> Result<Vec<T>, ReadError> {
    let Some(e) = entry else {
        return Ok(vec![default; n]);
    };
    let (at, key) = (At::Line(e.line), String::from_utf8_lossy(e.key));
    if e.values.len() != n {
        let what = format!("{key} has {} entries, FIELDS has {n}", e.values.len());
        return Err(ctx.bad_header(at, what));
    }
    let what = |t: &[u8]| format!("{} is not a valid {key} entry", quote(t));
    let value = |t: &&[u8]| parse(t).ok_or_else(|| ctx.bad_header(at, what(t)));
    e.values.iter().map(value).collect()
}

fn slots(
    ctx: Ctx,
    width: Option<usize>,
    height: Option<usize>,
    points: Option<usize>,
) -> Result<usize, ReadError> {
    let bad = |what: String| Err(ctx.bad_header(At::Header, what));
    match (width, height, points) {
        (Some(w), h, p) => {
            let h = h.unwrap_or(1);
            match (w.checked_mul(h), p) {
                (None, _) => bad(format!("WIDTH {w} × HEIGHT {h} overflows")),
                (Some(wh), Some(p)) if p != wh => {
                    bad(format!("POINTS {p}, but WIDTH {w} × HEIGHT {h} = {wh}"))
                }
                (Some(wh), _) => Ok(wh),
            }
        }
        (None, None, Some(p)) => Ok(p),
        (None, Some(h), _) => bad(format!("HEIGHT {h} without WIDTH")),
        (None, None, None) => bad("no WIDTH or POINTS line".into()),
    }
}

fn coord(ctx: Ctx, fields: &[Field], axis: &str) -> Result<Coord, ReadError> {
    let overflow = || ctx.bad_header(At::Header, "the point size overflows");
    let (mut value, mut offset, mut column) = (0usize, 0usize, 0usize);
    for f in fields {
        if f.name == axis.as_bytes() {
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
        let bytes = f.size.checked_mul(f.count).ok_or_else(overflow)?;
        value = value.checked_add(f.count).ok_or_else(overflow)?;
        offset = offset.checked_add(bytes).ok_or_else(overflow)?;
        if f.name != b"_" {
            column = column.checked_add(bytes).ok_or_else(overflow)?;
        }
    }
    let names: Vec<_> = fields
        .iter()
        .map(|f| String::from_utf8_lossy(f.name))
        .collect();
    let what = format!("no field {axis} (FIELDS {})", names.join(" "));
    Err(ctx.bad_header(At::Header, what))
}

/// Sum of `size × count` over the fields `keep` selects, checked.
fn record_size(ctx: Ctx, fields: &[Field], keep: fn(&Field) -> bool) -> Result<usize, ReadError> {
    let add = |sum: usize, f: &Field| f.size.checked_mul(f.count).and_then(|b| sum.checked_add(b));
    let size = fields.iter().filter(|f| keep(f)).try_fold(0, add);
    size.ok_or_else(|| ctx.bad_header(At::Header, "the point size overflows"))
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
        let Some(line) = lines.next_non_blank() else {
            let what = format!("DATA ascii ends after {done} of {slots} points");
            return Err(ctx.truncated(what));
        };
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

/// The first `need` bytes of the data section, or a `Truncated` naming what is missing.
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
    let value = bytes.get(at..).and_then(|b| scalar.read(b, Endian::Little));
    value.unwrap_or(f64::NAN)
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
            .map(|w| u32::from_le_bytes(*w))
    };
    let (packed, unpacked) = (word(0).unwrap_or(0) as usize, word(4).unwrap_or(0) as usize);
    let stream = need(ctx, bytes, body, "binary_compressed", 8 + packed as u128)?;
    let record = record_size(ctx, fields, |f| f.name != b"_")?;
    let expected = slots as u128 * record as u128;
    if unpacked as u128 != expected {
        let what = format!(
            "uncompressed size {unpacked}, but POINTS {slots} × {record} bytes = {expected}"
        );
        return Err(ctx.bad_value(At::Offset(body + 4), what));
    }
    let data = lzf::decompress(stream.get(8..).unwrap_or_default(), unpacked)
        .map_err(|e| ctx.bad_value(At::Offset(body + 8 + e.at()), e.to_string()))?;
    // A column starts at `column × slots` and spans `slots × size` bytes, inside `data`
    // because its length was checked to be `slots × record`.
    let column = |c: Coord| {
        let start = c.column * slots;
        let bytes = data
            .get(start..start + slots * c.scalar.size())
            .unwrap_or_default();
        bytes
            .chunks_exact(c.scalar.size())
            .map(move |b| read_at(b, 0, c.scalar))
    };
    let [cx, cy, cz] = coords;
    let mut points = Points::with_capacity(slots);
    for ((x, y), z) in column(cx).zip(column(cy)).zip(column(cz)) {
        points.push([x, y, z]);
    }
    Ok(points)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::lzf::tests::literal_stream;
    use super::super::testkit::{DATA, assert_same, expect_err, header_count, shared};
    use super::super::{Format, read_cloud_bytes};

    /// (name, TYPE, SIZE, COUNT) of a field to write.
    type Field<'a> = (&'a str, char, usize, usize);

    /// Writes a PCD; each row holds every value of a point, in field order.
    pub fn write_pcd(data: &str, fields: &[Field], width: usize, rows: &[Vec<f64>]) -> Vec<u8> {
        let list = |f: fn(&Field) -> String| fields.iter().map(f).collect::<Vec<_>>().join(" ");
        let (height, points) = (rows.len() / width, rows.len());
        let mut out = format!(
            "# .PCD v0.7 - written by the tests\nVERSION 0.7\nFIELDS {}\nSIZE {}\nTYPE {}\nCOUNT {}\n\
             WIDTH {width}\nHEIGHT {height}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points}\nDATA {data}\n",
            list(|f| f.0.into()),
            list(|f| f.2.to_string()),
            list(|f| f.1.into()),
            list(|f| f.3.to_string()),
        )
        .into_bytes();
        let put = |out: &mut Vec<u8>, f: &Field, v: f64| match (f.1, f.2) {
            _ if data == "ascii" => out.extend_from_slice(format!("{} ", v as f32).as_bytes()),
            ('F', 4) => out.extend_from_slice(&(v as f32).to_le_bytes()),
            ('F', 8) => out.extend_from_slice(&v.to_le_bytes()),
            ('U', 1) => out.push(v as u8),
            ('U', 4) => out.extend_from_slice(&(v as u32).to_le_bytes()),
            ('I', 2) => out.extend_from_slice(&(v as i16).to_le_bytes()),
            other => panic!("{other:?}"),
        };
        // (field, index of its first value in a row)
        let starts = fields
            .iter()
            .scan(0, |n, f| Some((f, std::mem::replace(n, *n + f.3))));
        if data == "binary_compressed" {
            // Field-major, without the padding fields, as PCL writes it.
            let mut columns = Vec::new();
            for (f, start) in starts.filter(|(f, _)| f.0 != "_") {
                rows.iter()
                    .for_each(|r| (0..f.3).for_each(|c| put(&mut columns, f, r[start + c])));
            }
            let stream = literal_stream(&columns);
            out.extend_from_slice(&(stream.len() as u32).to_le_bytes());
            out.extend_from_slice(&(columns.len() as u32).to_le_bytes());
            return [out, stream].concat();
        }
        let starts: Vec<_> = starts.collect();
        for row in rows {
            for &(f, start) in &starts {
                (0..f.3).for_each(|c| put(&mut out, f, row[start + c]));
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
        let defs = &reader.meta().field_defs;
        let index = ["x", "y", "z"].map(|a| defs.iter().position(|f| f.name == a).unwrap());
        let value = |f: &pcd_rs::Field| match f {
            pcd_rs::Field::F32(v) => f64::from(v[0]),
            other => panic!("{other:?}"),
        };
        let records: Vec<pcd_rs::DynRecord> = reader.collect::<Result<_, _>>().unwrap();
        let point = |r: &pcd_rs::DynRecord| index.map(|i| value(&r.0[i]));
        records.iter().map(point).collect()
    }

    fn finite(points: impl IntoIterator<Item = [f64; 3]>) -> Vec<[f64; 3]> {
        let ok = |p: &[f64; 3]| p.iter().all(|c| c.is_finite());
        points.into_iter().filter(ok).collect()
    }

    #[test]
    fn shared_pcds_match_pcd_rs() {
        use Format::{PcdAscii as Ascii, PcdBinaryCompressed as Lzf};
        for (name, slots, kept, format) in [
            ("car6.pcd", 10_031, 10_031, Lzf),
            ("milk.pcd", 13_704, 13_704, Lzf),
            ("lamppost.pcd", 1_771, 1_771, Ascii),
            ("rops_cloud.pcd", 32_087, 32_087, Ascii),
            ("cturtle.pcd", 167_198, 167_198, Lzf),
            ("five_people.pcd", 307_200, 239_075, Lzf),
            ("office1.pcd", 307_200, 254_456, Lzf),
        ] {
            let bytes = shared(name);
            let cloud = read_cloud_bytes(name, &bytes).unwrap();
            assert_eq!(cloud.slots, header_count(&bytes, "POINTS"), "{name}");
            let counts = (cloud.slots, cloud.points.len(), cloud.dropped_non_finite);
            assert_eq!(counts, (slots, kept, slots - kept), "{name}");
            assert_eq!(cloud.format, format, "{name}");
            assert_same(&cloud, &finite(pcd_rs(name)), name);
        }
    }

    /// car6's points with a NaN hole every tenth slot, as an organized 5015 × 2 cloud with
    /// fields around x y z (padding among them).
    pub fn car6_as(data: &str, coord_size: usize) -> Vec<u8> {
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
        let hole = |i: usize, c: f64| if i % 10 == 3 { f64::NAN } else { c };
        let rows: Vec<Vec<f64>> = (pcd_rs("car6.pcd")[..10_030].iter().enumerate())
            .map(|(i, p)| {
                let mut row = vec![i as f64, hole(i, p[0]), 0.0, 1.0, 2.0, 3.0, 7.0];
                row.extend([p[1], 0.5, 0.2, 0.1, p[2], 255.0]);
                row
            })
            .collect();
        write_pcd(data, &fields, 5015, &rows)
    }

    #[test]
    fn car6_in_every_encoding_and_coordinate_type() {
        let car6 = pcd_rs("car6.pcd");
        let holes = car6[..10_030].iter().enumerate();
        let want = finite(holes.map(|(i, p)| if i % 10 == 3 { [f64::NAN; 3] } else { *p }));
        use Format::{PcdAscii, PcdBinary, PcdBinaryCompressed};
        for (data, format) in [
            ("ascii", PcdAscii),
            ("binary", PcdBinary),
            ("binary_compressed", PcdBinaryCompressed),
        ] {
            for size in [4, 8] {
                let cloud = read_cloud_bytes("car6.pcd", &car6_as(data, size)).unwrap();
                let got = (cloud.format, cloud.slots, cloud.dropped_non_finite);
                assert_eq!(got, (format, 10_030, 1003), "{data} F{size}");
                assert_same(&cloud, &want, &format!("{data} F{size}"));
            }
        }
    }

    #[test]
    fn old_headers_bad_headers_and_lying_counts() {
        // v0.5/0.6 style: no VERSION, COLUMNS, no SIZE/TYPE (4-byte floats), no WIDTH.
        let old = b"COLUMNS x y z\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 nan\n";
        let cloud = read_cloud_bytes("old.pcd", old).unwrap();
        assert_eq!((cloud.slots, cloud.points.len()), (2, 1));
        assert_eq!(cloud.origin, [1.0, 2.0, 3.0]);
        // XYZ stands for the field lines of x y z as 4-byte floats.
        let check = |header: &str, data: &str, body: &[u8], variant: &str| {
            let fields = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1";
            let head = format!("VERSION 0.7\n{header}\nDATA {data}\n").replace("XYZ", fields);
            expect_err("bad.pcd", &[head.as_bytes(), body].concat(), variant)
        };
        let e = check("XYZ\nWIDTH 3", "ascii", b"1 2 3\n4 5\n6 7 8\n", "BadValue");
        assert_eq!(
            e.to_string(),
            "bad.pcd: line 9: 2 values; the fields need 3"
        );
        let huge = "XYZ\nWIDTH 1000000000000000000\nHEIGHT 1\nPOINTS 1000000000000000000";
        check(huge, "binary", &[0; 100], "Truncated");
        check(huge, "ascii", b"1 2 3\n", "Truncated");
        check("XYZ\nWIDTH 1", "lzma", b"", "Unsupported");
        check(
            "XYZ\nWIDTH 2",
            "ascii",
            b"nan nan nan\nnan 1 1\n",
            "NoFinitePoints",
        );
        let count = "FIELDS x y z w\nCOUNT 1 1 1 1000000000000000000000\nWIDTH 1";
        let size = "FIELDS x y z w\nSIZE 4 4 4 1000000000000\nCOUNT 1 1 1 1000000000\nWIDTH 1";
        for (header, variant) in [
            ("XYZ\nWIDTH 4294967296\nHEIGHT 4294967296", "BadHeader"),
            ("XYZ\nWIDTH 3\nPOINTS 4", "BadHeader"),
            ("XYZ\nHEIGHT 3", "BadHeader"),
            ("XYZ\nWIDTH 0", "NoFinitePoints"),
            ("XYZ\nWIDTH 1\nFOO 3", "BadHeader"),
            ("FIELDS x y q\nWIDTH 1", "BadHeader"),
            ("FIELDS x y z\nSIZE 4 4\nWIDTH 1", "BadHeader"),
            ("FIELDS x y z\nTYPE F F Q\nWIDTH 1", "BadHeader"),
            ("FIELDS x y z\nSIZE 2 4 4\nWIDTH 1", "Unsupported"),
            ("FIELDS x y z\nCOUNT 2 1 1\nWIDTH 1", "Unsupported"),
            (count, "BadHeader"),
            (size, "BadHeader"),
        ] {
            check(header, "binary", b"", variant);
        }
    }
}
