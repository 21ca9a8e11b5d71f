//! XYZ/CSV text reader: one point per line, x y z first, separated by whitespace or commas.
//!
//! Lines before the first data line that do not start with three numbers are taken as a header
//! (`x,y,z,intensity`, a scanner's banner); after data has started such a line is an error, since
//! silently skipping it would hide a damaged file. Blank lines and `#` comments are skipped
//! anywhere; columns after z are not parsed.

use super::{At, Cloud, Ctx, Format, Lines, Points, ReadError, parse_f64, quote, tokens};

/// Why a line is not a data line.
enum NotData<'a> {
    NotANumber(&'a [u8]),
    TooFew(usize),
}

pub(super) fn read(ctx: Ctx, bytes: &[u8]) -> Result<Cloud, ReadError> {
    let mut points = Points::with_capacity(0);
    let mut started = false;
    for line in Lines::new(bytes) {
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
