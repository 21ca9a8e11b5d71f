//! PLY reader: `ascii`, `binary_little_endian` and `binary_big_endian`, format 1.0.
//!
//! Only the `vertex` element's x, y, z are kept, whatever their type and position among the
//! other properties. Elements before `vertex` are skipped: a fixed-size element in one step,
//! one with list properties instance by instance, reading each list's count. Elements after
//! `vertex` are never read: the points are complete by then, and a damaged face list should
//! not cost the user a cloud.

use super::stream::{Input, Line};
use super::xyz::{parse_f64, parse_usize, quote, short, tokens};
use super::{At, Cloud, Ctx, Endian, Format, Points, ReadError, Scalar};

/// The longest header line read, comments aside (they are skipped, not kept). A line holds at
/// most five words (`property list uchar int vertex_indices`) and real ones are under fifty
/// bytes; 64 KiB leaves room for any name a tool means, and bounds the names kept per line.
pub(super) const MAX_LINE: usize = 1 << 16;

/// The most elements a header may declare. Real files have a few (vertex, face, edge,
/// material, range_grid, camera); each one kept costs some 80 bytes of bookkeeping.
pub(super) const MAX_ELEMENTS: usize = 1 << 12;

/// The most properties a header may declare, over all its elements. Real vertices have a few
/// dozen at most (a 3D Gaussian splat has 62); each one kept costs 4 bytes and its name.
pub(super) const MAX_PROPERTIES: usize = 1 << 16;

/// How many names an error message lists.
const LISTED: usize = 8;

#[derive(Clone, Copy)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

/// A property as the body is read; its name is in its element's `names`, looked up only for
/// matching x, y, z and for messages.
#[derive(Clone, Copy)]
pub(super) struct Property {
    kind: Kind,
    /// 0, 1, 2 for the vertex's x, y, z; `None` for everything that is skipped.
    axis: Option<u8>,
}

impl Property {
    /// The coordinate this property is, as an index.
    fn axis(self) -> Option<usize> {
        self.axis.map(usize::from)
    }
}

struct Element {
    /// As messages print it (see [`short`]); only `vertex` is ever compared.
    name: String,
    count: usize,
    /// The properties' names, in order, each followed by a space (a name is a token, so it has
    /// none): one text per element rather than a `String` per property line.
    names: Vec<u8>,
    props: Vec<Property>,
}

impl Element {
    /// Bytes per instance if every list is empty: the least each instance takes.
    fn min_stride(&self) -> usize {
        let size = |p: &Property| match p.kind {
            Kind::Scalar(s) | Kind::List { count: s, .. } => s.size(),
        };
        self.props.iter().map(size).sum()
    }

    fn has_lists(&self) -> bool {
        self.props
            .iter()
            .any(|p| matches!(p.kind, Kind::List { .. }))
    }

    /// The name of property `at`, for a message.
    fn prop_name(&self, at: usize) -> String {
        tokens(&self.names).nth(at).map(short).unwrap_or_default()
    }

    /// The first few property names, for a message: thousands would make one no one reads.
    fn prop_names(&self) -> String {
        listed(
            tokens(&self.names).map(short),
            self.props.len(),
            "properties",
        )
    }
}

/// The first [`LISTED`] of `names`, and how many there are in all if that is more.
fn listed(names: impl Iterator<Item = String>, all: usize, what: &str) -> String {
    let mut names: Vec<String> = names.take(LISTED).collect();
    if all > LISTED {
        names.push(format!("... {all} {what} in all"));
    }
    names.join(" ")
}

pub(super) fn read(input: &mut Input) -> Result<Cloud, ReadError> {
    let ctx = input.ctx();
    let (encoding, mut elements) = parse_header(input)?;
    // The header keeps the elements up to the first vertex, so it is the last if there is one.
    let Some(vertex) = elements.last_mut().filter(|e| e.name == "vertex") else {
        let names = listed(
            elements.iter().map(|e| e.name.clone()),
            elements.len(),
            "elements",
        );
        let what = format!("no vertex element (elements: {names})");
        return Err(ctx.bad_header(At::Header, what));
    };
    for (axis, name) in (0u8..).zip(["x", "y", "z"]) {
        let at = tokens(&vertex.names).position(|n| n == name.as_bytes());
        let Some(prop) = at.and_then(|at| vertex.props.get_mut(at)) else {
            let names = vertex.prop_names();
            let what = format!("element vertex has no property {name} (it has: {names})");
            return Err(ctx.bad_header(At::Header, what));
        };
        if let Kind::List { .. } = prop.kind {
            return Err(ctx.unsupported(format!("vertex property {name} is a list")));
        }
        prop.axis = Some(axis);
    }
    let format = match encoding {
        None => Format::PlyAscii,
        Some(Endian::Little) => Format::PlyBinaryLittleEndian,
        Some(Endian::Big) => Format::PlyBinaryBigEndian,
    };
    let points = match encoding {
        None => ascii(input, &elements)?,
        Some(endian) => binary(input, endian, &elements)?,
    };
    points.finish(ctx, format)
}

fn scalar(name: &[u8]) -> Option<Scalar> {
    Some(match name {
        b"char" | b"int8" => Scalar::I8,
        b"uchar" | b"uint8" => Scalar::U8,
        b"short" | b"int16" => Scalar::I16,
        b"ushort" | b"uint16" => Scalar::U16,
        b"int" | b"int32" => Scalar::I32,
        b"uint" | b"uint32" => Scalar::U32,
        b"float" | b"float32" => Scalar::F32,
        b"double" | b"float64" => Scalar::F64,
        // Not in the 1.0 spec, but written by some tools; accepting them costs nothing.
        b"int64" => Scalar::I64,
        b"uint64" => Scalar::U64,
        _ => return None,
    })
}

/// The encoding (`None` for ascii) and the elements up to the first `vertex` (all of them if
/// there is none); leaves `input` at the body. Later elements are checked and counted but not
/// kept: the body is never read past the vertex.
fn parse_header(input: &mut Input) -> Result<(Option<Endian>, Vec<Element>), ReadError> {
    let (ctx, len) = (input.ctx(), input.len());
    input.next_line()?; // the `ply` magic line, already checked by the caller
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    // Elements and properties declared so far, kept or not, and whether the current element
    // is kept.
    let (mut declared, mut properties, mut keep) = (0usize, 0usize, false);
    loop {
        // A header line without its newline is a cut file, whatever the line says.
        let Some(line) = input.next_line()?.filter(|l| l.terminated) else {
            return Err(ctx.truncated(format!("PLY header ends at byte {len} before end_header")));
        };
        let (number, at) = (line.number, At::Line(line.number));
        let bad = |what: String| ctx.bad_header(at, what);
        let mut toks = tokens(line.text);
        let Some(keyword) = toks.next() else { continue };
        if line.text.len() > MAX_LINE && !matches!(keyword, b"comment" | b"obj_info") {
            let bytes = line.text.len();
            return Err(ctx.too_large(format!(
                "PLY header line {number} is {bytes} bytes; header lines are read up to {MAX_LINE}"
            )));
        }
        let mut next = |what: &str| {
            toks.next()
                .ok_or_else(|| bad(format!("{} line without {what}", quote(keyword))))
        };
        let ty = |t: &[u8]| scalar(t).ok_or_else(|| bad(format!("unknown type {}", quote(t))));
        match keyword {
            b"comment" | b"obj_info" => {}
            b"format" if encoding.is_some() => return Err(bad("a second format line".into())),
            b"format" => {
                encoding = Some(match next("an encoding")? {
                    b"ascii" => None,
                    b"binary_little_endian" => Some(Endian::Little),
                    b"binary_big_endian" => Some(Endian::Big),
                    other => return Err(bad(format!("unknown format {}", quote(other)))),
                });
                let version = next("a version")?;
                if parse_f64(version) != Some(1.0) {
                    let v = quote(version);
                    return Err(ctx.unsupported(format!("PLY version {v}; only 1.0 is defined")));
                }
            }
            b"element" => {
                let name = next("a name")?;
                let count = next("a count")?;
                let count = parse_usize(count)
                    .ok_or_else(|| bad(format!("{} is not an element count", quote(count))))?;
                declared += 1;
                if declared > MAX_ELEMENTS {
                    return Err(ctx.too_large(format!(
                        "PLY header line {number} declares element {declared}; at most {MAX_ELEMENTS} are read"
                    )));
                }
                // The body is read up to the first vertex, so nothing after it is kept.
                keep = elements.last().is_none_or(|e| e.name != "vertex");
                if keep {
                    elements.push(Element {
                        name: short(name),
                        count,
                        names: Vec::new(),
                        props: Vec::new(),
                    });
                }
            }
            b"property" => {
                let kind = match next("a type")? {
                    b"list" => {
                        let count = ty(next("a list count type")?)?;
                        let item = ty(next("a list item type")?)?;
                        if !count.is_integer() {
                            return Err(bad("a list count type must be an integer".into()));
                        }
                        Kind::List { count, item }
                    }
                    t => Kind::Scalar(ty(t)?),
                };
                let name = next("a name")?;
                if declared == 0 {
                    return Err(bad("property before any element line".into()));
                }
                properties += 1;
                if properties > MAX_PROPERTIES {
                    return Err(ctx.too_large(format!(
                        "PLY header line {number} declares property {properties}; at most {MAX_PROPERTIES} are read"
                    )));
                }
                let Some(element) = elements.last_mut().filter(|_| keep) else {
                    continue;
                };
                let more = name.len() + 1;
                if crate::heap::fallible(|| element.names.try_reserve(more)).is_err() {
                    let what = format!(
                        "{more} bytes more for the names of element {}",
                        element.name
                    );
                    return Err(ctx.out_of_memory(what));
                }
                element.names.extend_from_slice(name);
                element.names.push(b' ');
                element.props.push(Property { kind, axis: None });
            }
            b"end_header" => break,
            other => return Err(bad(format!("unknown header keyword {}", quote(other)))),
        }
    }
    let encoding = encoding.ok_or_else(|| ctx.bad_header(At::Header, "no format line"))?;
    Ok((encoding, elements))
}

/// Reads `elements` (the last is the vertex) one line per instance.
fn ascii(input: &mut Input, elements: &[Element]) -> Result<Points, ReadError> {
    let ctx = input.ctx();
    let mut points = Points::new();
    for (i, el) in elements.iter().enumerate() {
        // An instance without properties has no text, and would otherwise loop `count` times.
        if el.props.is_empty() {
            continue;
        }
        let is_vertex = i + 1 == elements.len();
        if is_vertex {
            // Each value takes at least a character and a separator.
            let room = input.remaining() / (2 * el.props.len() as u64);
            let capacity = usize::try_from(room).map_or(el.count, |r| r.min(el.count));
            points = Points::with_capacity(ctx, capacity)?;
        }
        for done in 0..el.count {
            let Some(line) = input.next_non_blank()? else {
                let (name, count) = (&el.name, el.count);
                let what = format!("element {name} ends after {done} of its {count} lines");
                return Err(ctx.truncated(what));
            };
            if is_vertex {
                let p = ascii_vertex(ctx, &line, el).map_err(|e| ctx.cut_short(&line, e))?;
                points.push(p);
            }
        }
    }
    Ok(points)
}

fn ascii_vertex(ctx: Ctx, line: &Line, vertex: &Element) -> Result<[f64; 3], ReadError> {
    let at = At::Line(line.number);
    let mut toks = tokens(line.text);
    let names = || vertex.prop_names();
    let too_few = || ctx.bad_value(at, format!("too few values for properties {}", names()));
    let mut p = [f64::NAN; 3];
    for (i, prop) in vertex.props.iter().enumerate() {
        let tok = toks.next().ok_or_else(too_few)?;
        match (prop.kind, prop.axis().and_then(|a| p.get_mut(a))) {
            (Kind::List { .. }, _) => {
                let n = parse_usize(tok).ok_or_else(|| {
                    let name = vertex.prop_name(i);
                    let what = format!("{} is not a count for list {name}", quote(tok));
                    ctx.bad_value(at, what)
                })?;
                // Bounded by the tokens on this line, whatever `n` claims.
                for _ in 0..n {
                    toks.next().ok_or_else(too_few)?;
                }
            }
            (Kind::Scalar(_), None) => {}
            (Kind::Scalar(_), Some(c)) => {
                *c = parse_f64(tok).ok_or_else(|| {
                    let what = format!(
                        "{} is not a number; expected vertex {}",
                        quote(tok),
                        vertex.prop_name(i)
                    );
                    ctx.bad_value(at, what)
                })?;
            }
        }
    }
    if toks.next().is_some() {
        return Err(ctx.bad_value(at, format!("more values than the properties {}", names())));
    }
    Ok(p)
}

/// Reads `elements` (the last is the vertex) from the body.
fn binary(input: &mut Input, endian: Endian, elements: &[Element]) -> Result<Points, ReadError> {
    let ctx = input.ctx();
    let mut points = Points::new();
    for (i, el) in elements.iter().enumerate() {
        // Checked up front so that an absurd count fails at once, naming the sizes involved.
        let need = el.count as u128 * el.min_stride() as u128;
        let (pos, have) = (input.pos(), input.remaining());
        if need > u128::from(have) {
            let (name, count, stride) = (&el.name, el.count, el.min_stride());
            return Err(ctx.truncated(format!(
                "element {name} needs at least {count} × {stride} = {need} bytes from offset {pos}, file has {have}"
            )));
        }
        let is_vertex = i + 1 == elements.len();
        if is_vertex {
            points = Points::with_capacity(ctx, el.count)?;
        }
        if !el.has_lists() {
            if is_vertex {
                fixed_vertices(input, endian, el, &mut points)?;
            } else if input.skip(need as u64)? < need as u64 {
                return Err(ends(input, el, 0));
            }
            continue;
        }
        // Each instance takes at least one byte (the vertex has x, y, z; the others a list
        // count), so this loop ends with the file whatever `count` claims.
        for index in 0..el.count {
            let p = walk(input, endian, el, index)?;
            if is_vertex {
                points.push(p);
            }
        }
    }
    Ok(points)
}

/// The error for an instance that the end of the file cuts short.
fn ends(input: &Input, el: &Element, index: usize) -> ReadError {
    input.ended(&format!("element {} instance {index}", el.name))
}

/// Vertices without lists: records of one size, taken as many at a time as are buffered.
fn fixed_vertices(
    input: &mut Input,
    endian: Endian,
    vertex: &Element,
    points: &mut Points,
) -> Result<(), ReadError> {
    let stride = vertex.min_stride();
    // (byte offset in the record, type) of x, y and z.
    let mut at = [(0, Scalar::F32); 3];
    let mut offset = 0;
    for prop in &vertex.props {
        if let (Kind::Scalar(s), Some(axis)) = (prop.kind, prop.axis().and_then(|a| at.get_mut(a)))
        {
            *axis = (offset, s);
        }
        offset += match prop.kind {
            Kind::Scalar(s) | Kind::List { count: s, .. } => s.size(),
        };
    }
    let point = |record: &[u8]| {
        at.map(|(offset, s): (usize, Scalar)| {
            let v = record.get(offset..).and_then(|b| s.read(b, endian));
            // Offsets inside a record sized from the same properties; NaN is unreachable.
            v.unwrap_or(f64::NAN)
        })
    };
    let done = input.records(stride, vertex.count, |record| points.push(point(record)))?;
    if done < vertex.count {
        return Err(ends(input, vertex, done));
    }
    Ok(())
}

/// Reads one instance; returns its x, y, z if it has them.
fn walk(
    input: &mut Input,
    endian: Endian,
    el: &Element,
    index: usize,
) -> Result<[f64; 3], ReadError> {
    let mut p = [f64::NAN; 3];
    for (i, prop) in el.props.iter().enumerate() {
        match prop.kind {
            Kind::Scalar(s) => {
                let v = s.read(input.peek(s.size())?, endian);
                let v = v.ok_or_else(|| ends(input, el, index))?;
                if let Some(c) = prop.axis().and_then(|a| p.get_mut(a)) {
                    *c = v;
                }
                input.consume(s.size());
            }
            Kind::List { count, item } => {
                let n = count.read(input.peek(count.size())?, endian);
                let n = n.ok_or_else(|| ends(input, el, index))?;
                if n < 0.0 {
                    let what = format!(
                        "negative count {n} for list {} of element {}",
                        el.prop_name(i),
                        el.name
                    );
                    return Err(input.ctx().bad_value(At::Offset(input.pos()), what));
                }
                input.consume(count.size());
                let len = n as u128 * item.size() as u128;
                if len > u128::from(input.remaining()) {
                    return Err(ends(input, el, index));
                }
                if input.skip(len as u64)? < len as u64 {
                    return Err(ends(input, el, index));
                }
            }
        }
    }
    Ok(p)
}

#[cfg(test)]
pub(crate) mod tests;
