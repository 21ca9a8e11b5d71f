//! Text: the line and number primitives every text part of these formats is read with, and
//! the XYZ/CSV reader: one point per line, x y z first, separated by whitespace or commas.
//!
//! Lines before the first data line that do not start with three numbers are taken as a header
//! (`x,y,z,intensity`, a scanner's banner); after data has started such a line is an error, since
//! silently skipping it would hide a damaged file. Blank lines and `#` comments are skipped
//! anywhere; columns after z are not parsed.

use super::stream::Input;
use super::{At, Cloud, Format, Points, ReadError};

/// Text is anything without control bytes other than whitespace in its first few KiB; bytes
/// >= 0x80 pass so that Latin-1 or UTF-8 header comments do not disqualify a file.
pub(super) fn looks_like_text(bytes: &[u8]) -> bool {
    let head = bytes.get(..4096).unwrap_or(bytes);
    head.iter()
        .all(|&b| matches!(b, b'\t' | b'\n' | b'\r' | 0x0c) || (b >= 0x20 && b != 0x7f))
}

/// Quotes a token from the file for an error message: lossy, short and on one line.
pub(crate) fn quote(token: &[u8]) -> String {
    let text = String::from_utf8_lossy(token);
    let mut out: String = text.chars().take(40).flat_map(char::escape_debug).collect();
    if text.chars().nth(40).is_some() {
        out.push_str("...");
    }
    format!("'{out}'")
}

/// A name from a header for a message: lossy, on one line, and cut short if long, as
/// [`quote`] has it but without the quotes.
pub(crate) fn short(name: &[u8]) -> String {
    let quoted = quote(name);
    let inner = quoted.strip_prefix('\'').and_then(|q| q.strip_suffix('\''));
    inner.unwrap_or(&quoted).to_owned()
}

pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

pub(crate) fn parse_usize(token: &[u8]) -> Option<usize> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// Whitespace-separated tokens of a line.
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(u8::is_ascii_whitespace)
        .filter(|t| !t.is_empty())
}

/// Why a line is not a data line.
enum NotData<'a> {
    NotANumber(&'a [u8]),
    TooFew(usize),
}

pub(super) fn read(input: &mut Input) -> Result<Cloud, ReadError> {
    let ctx = input.ctx();
    // Spreadsheet exports start with a byte-order mark, which would turn the first data line
    // into a "header" and silently lose its point.
    let bom = "\u{feff}".as_bytes();
    if input.peek(bom.len())?.starts_with(bom) {
        input.consume(bom.len());
    }
    let mut points = Points::new();
    let mut started = false;
    while let Some(line) = input.next_line()? {
        let text = line.text.trim_ascii();
        if text.is_empty() || text.starts_with(b"#") {
            continue;
        }
        match parse_line(text) {
            Ok(p) => {
                started = true;
                points.push(p);
            }
            Err(_) if !started => {}
            Err(not_data) => {
                let what = match not_data {
                    NotData::NotANumber(tok) => {
                        format!("{} is not a number; expected x y z", quote(tok))
                    }
                    NotData::TooFew(n) => format!("{n} values; expected at least 3 (x y z)"),
                };
                let e = ctx.bad_value(At::Line(line.number), what);
                return Err(ctx.cut_short(&line, e));
            }
        }
    }
    if !started {
        return Err(ctx.not_a_cloud("text, but no line starts with three numbers x y z"));
    }
    points.finish(ctx, Format::Xyz)
}

fn parse_line(text: &[u8]) -> Result<[f64; 3], NotData<'_>> {
    if text.contains(&b',') {
        first_three(text.split(|&b| b == b',').map(<[u8]>::trim_ascii))
    } else {
        first_three(tokens(text))
    }
}

fn first_three<'a>(toks: impl Iterator<Item = &'a [u8]>) -> Result<[f64; 3], NotData<'a>> {
    let mut p = [0.0; 3];
    let mut n = 0;
    for (c, tok) in p.iter_mut().zip(toks) {
        *c = parse_f64(tok).ok_or(NotData::NotANumber(tok))?;
        n += 1;
    }
    if n < 3 {
        return Err(NotData::TooFew(n));
    }
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::super::{Format, ReadError, read_cloud_bytes};

    fn read(text: &str) -> Result<super::Cloud, ReadError> {
        read_cloud_bytes("pts.xyz", text.as_bytes())
    }

    #[test]
    fn whitespace_csv_headers_and_comments() {
        let text = "Scanner v2 export\nx,y,z,i\n# a comment\n\n1 2 3 9\n\t3  4\t5\r\n# another\n5 6 7 extra columns\n";
        let cloud = read(text).unwrap();
        assert_eq!(
            (cloud.format, cloud.slots, cloud.origin),
            (Format::Xyz, 3, [3.0, 4.0, 5.0])
        );
        assert_eq!(
            cloud.points,
            [[-2.0, -2.0, -2.0], [0.0, 0.0, 0.0], [2.0, 2.0, 2.0]]
        );
        let csv = read("\u{feff}1, 2,3,0.5\n-1,-2,-3,1\n").unwrap();
        assert_eq!((csv.origin, csv.points[0]), ([0.0; 3], [1.0, 2.0, 3.0]));
    }

    #[test]
    fn far_coordinates_keep_their_precision() {
        // UTM-like eastings: 0.001 steps survive because they are stored around the origin.
        let cloud = read("500000.001 4000000.002 10\n500000.003 4000000.006 12\n").unwrap();
        let want = [500000.002, 4000000.004, 11.0];
        assert!(
            cloud
                .origin
                .iter()
                .zip(want)
                .all(|(o, w)| (o - w).abs() < 1e-9)
        );
        let p = cloud.points[0];
        assert!((p[0] + 0.001).abs() < 1e-6 && (p[1] + 0.002).abs() < 1e-6 && p[2] == -1.0);
    }

    #[test]
    fn bad_lines_after_data_starts() {
        let e = read("x y z\n1 2 3\n4 5 6\nabc 1 2\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "pts.xyz: line 4: 'abc' is not a number; expected x y z"
        );
        let e = read("1 2 3\n4 5\n6 7 8\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "pts.xyz: line 2: 2 values; expected at least 3 (x y z)"
        );
        let e = read("1,2,3\n4,,6\n").unwrap_err();
        assert!(matches!(e, ReadError::BadValue { .. }), "{e:?}");
        let e = read("1 2 3\n4 5 6\n7 8").unwrap_err();
        assert_eq!(
            e.to_string(),
            "pts.xyz: truncated: the file ends inside line 3"
        );
    }

    #[test]
    fn non_finite_points_are_counted() {
        let cloud = read("1 2 3\nnan 0 0\n0 inf 0\n3 4 5\n").unwrap();
        assert_eq!(
            (cloud.slots, cloud.dropped_non_finite, cloud.points.len()),
            (4, 2, 2)
        );
        let e = read_cloud_bytes("nan.xyz", "NaN nan nan\n".repeat(12).as_bytes()).unwrap_err();
        assert!(matches!(e, ReadError::NoFinitePoints { slots: 12, .. }));
        assert_eq!(
            e.to_string(),
            "nan.xyz: no finite points (12 slots, all NaN or infinite)"
        );
        let e = read("1e300 0 0\n-1e300 0 0\n").unwrap_err();
        assert!(matches!(e, ReadError::Unsupported { .. }), "{e:?}");
    }
}
