//! PCD reader: v0.7 headers, and the older ones PCL still reads (no VERSION line; `COLUMNS`
//! for FIELDS; SIZE and TYPE missing, meaning 4-byte floats).
//!
//! `DATA ascii` is one point per line; `DATA binary` is row-major, one little-endian record per
//! point; `DATA binary_compressed` is a u32 compressed size, a u32 uncompressed size, then LZF
//! data that decompresses field-major (every point's first field, then every point's second,
//! ...), with padding fields named `_` left out as PCL's writer does. Organized clouds keep
//! invalid pixels as NaN slots; they are counted and dropped.

mod body;
#[cfg(test)]
pub(super) use body::UPFRONT;

use super::stream::Input;
use super::xyz::{parse_usize, quote, short, tokens};
use super::{At, Cloud, Ctx, Format, Points, ReadError, Scalar};

/// The keywords a PCD header may start with (after comments).
const FIRST_KEYWORDS: [&[u8]; 3] = [b"VERSION", b"FIELDS", b"COLUMNS"];

/// Whether the first line that is not a comment starts a PCD header; `None` if `head`, the
/// start of the file, ends inside a line that could still decide it and `whole` says there is
/// more of the file.
pub(super) fn has_header(head: &[u8], whole: bool) -> Option<bool> {
    let mut lines = head.split(|&b| b == b'\n').peekable();
    while let Some(line) = lines.next() {
        // The last piece of a partial head may be the start of a longer line. Only a blank
        // line or a comment (`# .PCD` may yet follow, or a header after it) is worth reading
        // on for, and a first word that may still grow into a keyword: any other line
        // decides now, so a file without newlines is not read whole to find its first line.
        let cut = lines.peek().is_none() && !whole;
        let text = line.trim_ascii_start();
        if text.starts_with(b"# .PCD") {
            return Some(true);
        }
        if text.is_empty() || text.starts_with(b"#") {
            if cut {
                return None;
            }
            continue;
        }
        let word = tokens(text).next().unwrap_or_default();
        if cut && word.len() == text.len() && FIRST_KEYWORDS.iter().any(|k| k.starts_with(word)) {
            return None;
        }
        return Some(FIRST_KEYWORDS.contains(&word));
    }
    Some(false)
}

/// The header keywords other than DATA. `COLUMNS`, the old name of `FIELDS`, shares its place,
/// so that the later of the two is the one read, as with a keyword given twice.
const KEYWORDS: [&[u8]; 9] = [
    b"VERSION",
    b"FIELDS",
    b"SIZE",
    b"TYPE",
    b"COUNT",
    b"WIDTH",
    b"HEIGHT",
    b"VIEWPOINT",
    b"POINTS",
];

/// The longest header line kept (a keyword line; comments are skipped). A FIELDS line of
/// [`MAX_FIELDS`] names of ten letters is 720 KB; real ones are under a hundred bytes.
pub(super) const MAX_LINE: usize = 1 << 20;

/// The most fields a header may name. Real clouds have a few dozen at most (a descriptor is one
/// field with a large COUNT); each takes some 60 bytes of bookkeeping.
pub(super) const MAX_FIELDS: usize = 1 << 16;

/// How many field names an error message lists.
const LISTED: usize = 8;

/// A header line: its keyword as written, its number, and its text after the keyword, whose
/// whitespace-separated tokens are the values. One allocation per line, whatever it holds.
struct Entry {
    key: &'static str,
    line: usize,
    text: Vec<u8>,
}

impl Entry {
    fn values(&self) -> impl Iterator<Item = &[u8]> {
        tokens(&self.text)
    }
}

/// The last line given for each of [`KEYWORDS`].
type Header = [Option<Entry>; KEYWORDS.len()];

struct Field<'h> {
    /// Borrowed from the FIELDS line.
    name: &'h [u8],
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

/// The header lines up to DATA, and the kind of data that follows.
fn header_lines(input: &mut Input) -> Result<(Header, Format), ReadError> {
    let (ctx, len) = (input.ctx(), input.len());
    let mut header: Header = Default::default();
    loop {
        // A header line without its newline is a cut file, whatever the line says.
        let Some(line) = input.next_line()?.filter(|l| l.terminated) else {
            return Err(ctx.truncated(format!(
                "PCD header ends at byte {len} before its DATA line"
            )));
        };
        let mut toks = tokens(line.text);
        let format = match toks.next() {
            None => continue,
            Some(key) if key.starts_with(b"#") => continue,
            Some(b"DATA") => match toks.next() {
                Some(b"ascii") => Format::PcdAscii,
                Some(b"binary") => Format::PcdBinary,
                Some(b"binary_compressed") => Format::PcdBinaryCompressed,
                Some(other) => return Err(ctx.unsupported(format!("DATA {}", quote(other)))),
                None => return Err(ctx.bad_header(At::Line(line.number), "DATA without a kind")),
            },
            Some(key) if let Some(at) = place(key) => {
                // The keyword is the line's first token, so the values follow it.
                let text = line.text.trim_ascii_start().get(key.len()..);
                let text = text.unwrap_or_default();
                if text.len() > MAX_LINE {
                    let (n, bytes) = (line.number, text.len());
                    return Err(ctx.too_large(format!(
                        "PCD header line {n} is {bytes} bytes; header lines are read up to {MAX_LINE}"
                    )));
                }
                let key = if key == b"COLUMNS" {
                    "COLUMNS"
                } else {
                    name(at)
                };
                let entry = Entry {
                    key,
                    line: line.number,
                    text: text.to_vec(),
                };
                if let Some(slot) = header.get_mut(at) {
                    *slot = Some(entry);
                }
                continue;
            }
            Some(other) => {
                let what = format!("unknown header keyword {}", quote(other));
                return Err(ctx.bad_header(At::Line(line.number), what));
            }
        };
        return Ok((header, format));
    }
}

/// Where a keyword's line is kept in a [`Header`].
fn place(key: &[u8]) -> Option<usize> {
    let key = if key == b"COLUMNS" { b"FIELDS" } else { key };
    KEYWORDS.iter().position(|k| *k == key)
}

/// The keyword kept at `at`, for messages.
fn name(at: usize) -> &'static str {
    let key = KEYWORDS.get(at).copied().unwrap_or_default();
    std::str::from_utf8(key).unwrap_or_default()
}

pub(super) fn read(input: &mut Input) -> Result<Cloud, ReadError> {
    let ctx = input.ctx();
    let (header, format) = header_lines(input)?;
    let find = |key: &[u8]| {
        place(key)
            .and_then(|at| header.get(at))
            .and_then(Option::as_ref)
    };
    let Some(names) = find(b"FIELDS").filter(|e| e.values().next().is_some()) else {
        return Err(ctx.bad_header(At::Header, "no FIELDS line naming the fields"));
    };
    let n = names.values().count();
    if n > MAX_FIELDS {
        let (key, line) = (names.key, names.line);
        return Err(ctx.too_large(format!(
            "{key} on line {line} names {n} fields; at most {MAX_FIELDS} are read"
        )));
    }
    // Old headers without SIZE/TYPE/COUNT mean one 4-byte float per field, as in PCL.
    let sizes = per_field(ctx, find(b"SIZE"), n, 4, parse_usize)?;
    let counts = per_field(ctx, find(b"COUNT"), n, 1, parse_usize)?;
    let types = per_field(ctx, find(b"TYPE"), n, b'F', |t| match t {
        [ty @ (b'F' | b'I' | b'U')] => Some(*ty),
        _ => None,
    })?;
    let fields: Vec<Field> = (names.values().zip(sizes).zip(types).zip(counts))
        .map(|(((name, size), ty), count)| Field {
            name,
            size,
            ty,
            count,
        })
        .collect();
    let one = |key: &[u8]| match find(key) {
        None => Ok(None),
        Some(e) => e
            .values()
            .next()
            .and_then(parse_usize)
            .map(Some)
            .ok_or_else(|| {
                let what = format!("{} needs a count", quote(key));
                ctx.bad_header(At::Line(e.line), what)
            }),
    };
    let slots = slots(ctx, one(b"WIDTH")?, one(b"HEIGHT")?, one(b"POINTS")?)?;
    let [x, y, z] = ["x", "y", "z"].map(|axis| coord(ctx, &fields, axis));
    let coords = [x?, y?, z?];
    let organized = one(b"HEIGHT")?.is_some_and(|h| h > 1);
    let sensor = viewpoint(find(b"VIEWPOINT"), organized);
    let mut points = match format {
        _ if slots == 0 => Points::new(),
        Format::PcdAscii => body::ascii(input, &fields, slots, coords)?,
        Format::PcdBinary => body::binary(input, &fields, slots, coords)?,
        _ => body::compressed(input, &fields, slots, coords)?,
    };
    if let Some(sensor) = sensor {
        points.set_sensor(sensor);
    }
    points.finish(ctx, format)
}

/// Where the sensor was: the translation of the `VIEWPOINT` line (PCL writes one in every
/// file, the sensor's pose in the cloud's frame), else the frame's origin for an organized
/// cloud (a range image is taken from its own origin); `None` for an unorganized cloud without
/// one. A VIEWPOINT whose first three values are not finite numbers says nothing.
fn viewpoint(entry: Option<&Entry>, organized: bool) -> Option<[f64; 3]> {
    let Some(e) = entry else {
        return organized.then_some([0.0; 3]);
    };
    let mut values = e.values().map(|v| {
        std::str::from_utf8(v)
            .ok()
            .and_then(|t| t.parse::<f64>().ok())
            .filter(|c| c.is_finite())
    });
    let mut sensor = [0.0; 3];
    for c in &mut sensor {
        *c = values.next().flatten()?;
    }
    Some(sensor)
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
    let (at, key) = (At::Line(e.line), e.key);
    let given = e.values().count();
    if given != n {
        let what = format!("{key} has {given} entries, FIELDS has {n}");
        return Err(ctx.bad_header(at, what));
    }
    let what = |t: &[u8]| format!("{} is not a valid {key} entry", quote(t));
    let value = |t: &[u8]| parse(t).ok_or_else(|| ctx.bad_header(at, what(t)));
    e.values().map(value).collect()
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
    // A few names say what the file has; thousands would make a message no one reads.
    let mut names: Vec<String> = fields.iter().take(LISTED).map(|f| short(f.name)).collect();
    if fields.len() > LISTED {
        names.push(format!("... {} fields in all", fields.len()));
    }
    let what = format!("no field {axis} (FIELDS {})", names.join(" "));
    Err(ctx.bad_header(At::Header, what))
}

/// Sum of `size × count` over the fields `keep` selects, checked.
fn record_size(ctx: Ctx, fields: &[Field], keep: fn(&Field) -> bool) -> Result<usize, ReadError> {
    let add = |sum: usize, f: &Field| f.size.checked_mul(f.count).and_then(|b| sum.checked_add(b));
    let size = fields.iter().filter(|f| keep(f)).try_fold(0, add);
    size.ok_or_else(|| ctx.bad_header(At::Header, "the point size overflows"))
}

#[cfg(test)]
pub(crate) mod tests;
