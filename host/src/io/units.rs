//! Units of a cloud's coordinates: what a file says (LAS GeoKeys or OGC WKT), what `--units`
//! says where it says nothing, and the step that brings a cloud to metres.
//!
//! Maps are always in metres, and so is every length on the command line (the paper's 4 m
//! degeneration threshold among them); a cloud in feet or millimetres is scaled on reading.
//! The readers themselves keep the file's own coordinates ([`crate::io::read::Cloud`] and
//! [`crate::io::load_cloud`]), with the unit they found beside them.

use serde::Serialize;
use std::fmt;

/// A unit of length and its size in metres.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LengthUnit {
    /// Its name, singular ("metre", "foot", "US survey foot", or the name a WKT gives).
    pub name: String,
    /// Metres in one of it.
    pub metres: f64,
}

impl LengthUnit {
    pub fn new(name: impl Into<String>, metres: f64) -> Self {
        Self {
            name: name.into(),
            metres,
        }
    }

    pub fn metre() -> Self {
        Self::new("metre", 1.0)
    }

    /// The units `--units` takes: `m`, `mm`, `cm`, `km`, `in`, `ft` (international foot,
    /// 0.3048 m) and `us-ft` (US survey foot, 1200/3937 m).
    pub const CHOICES: &'static [&'static str] = &["m", "mm", "cm", "km", "in", "ft", "us-ft"];

    /// One of [`Self::CHOICES`] (a few spellings more: `metre`, `meter`, `foot`, `feet`...).
    pub fn parse(s: &str) -> Option<Self> {
        let (name, metres) = match s.trim().to_ascii_lowercase().as_str() {
            "m" | "metre" | "meter" | "metres" | "meters" => ("metre", 1.0),
            "mm" | "millimetre" | "millimeter" | "millimetres" | "millimeters" => {
                ("millimetre", 1e-3)
            }
            "cm" | "centimetre" | "centimeter" | "centimetres" | "centimeters" => {
                ("centimetre", 1e-2)
            }
            "km" | "kilometre" | "kilometer" | "kilometres" | "kilometers" => ("kilometre", 1e3),
            "in" | "inch" | "inches" => ("inch", 0.0254),
            "ft" | "foot" | "feet" => ("foot", 0.3048),
            "us-ft" | "us-foot" | "us-feet" | "ftus" | "us_survey_foot" => {
                ("US survey foot", US_SURVEY_FOOT)
            }
            _ => return None,
        };
        Some(Self::new(name, metres))
    }

    /// Whether this is the metre itself, so that scaling is no work at all.
    pub fn is_metre(&self) -> bool {
        self.metres == 1.0
    }
}

const US_SURVEY_FOOT: f64 = 1200.0 / 3937.0;

/// What a file says its coordinates are in.
#[derive(Clone, Debug, PartialEq)]
pub enum FileUnit {
    /// Lengths (a projected or geocentric CRS).
    Length {
        unit: LengthUnit,
        source: &'static str,
    },
    /// Angles: a geographic CRS (longitude and latitude in degrees, say), which no map of
    /// ellipsoids can take as lengths.
    Geographic { unit: String, source: &'static str },
    /// A unit these readers do not know (an EPSG unit code without a size, say).
    Unknown { what: String, source: &'static str },
}

impl fmt::Display for FileUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FileUnit::Length { unit, source } => write!(f, "{} ({source})", unit.name),
            FileUnit::Geographic { unit, source } => {
                write!(f, "geographic, in {unit} ({source})")
            }
            FileUnit::Unknown { what, source } => write!(f, "{what} ({source})"),
        }
    }
}

/// Where the unit a cloud was taken in came from.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum UnitSource {
    /// The file says so (the string names where: "LAS GeoKeys", "LAS WKT").
    File(&'static str),
    /// `--units` (or the library caller) said so.
    Given,
    /// Nobody said: metres assumed.
    Assumed,
}

/// The unit a cloud was read in, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Units {
    pub unit: LengthUnit,
    pub source: UnitSource,
    /// What the file said, where the unit given overrode a different one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub overrides: Option<String>,
}

impl Units {
    /// Metres, nobody having said.
    pub fn assumed() -> Self {
        Self {
            unit: LengthUnit::metre(),
            source: UnitSource::Assumed,
            overrides: None,
        }
    }
}

impl fmt::Display for Units {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.source {
            UnitSource::File(from) => write!(f, "{} ({from})", self.unit.name),
            UnitSource::Given => write!(f, "{} (--units)", self.unit.name),
            UnitSource::Assumed => write!(f, "{} (assumed; --units to change)", self.unit.name),
        }
    }
}

/// Why a cloud cannot be brought to metres.
#[derive(Debug, thiserror::Error)]
pub enum UnitError {
    #[error(
        "{name}: the coordinates are geographic, in {unit} ({from}), not lengths; reproject the cloud to a projected CRS (e.g. UTM, in metres) first, or give --units if they really are lengths"
    )]
    Geographic {
        name: String,
        unit: String,
        from: &'static str,
    },
    #[error(
        "{name}: the coordinates are in {what} ({from}), a unit mema does not know; give --units"
    )]
    Unknown {
        name: String,
        what: String,
        from: &'static str,
    },
}

/// The unit to read a cloud in: `given` (from `--units`) if any, else what the file says, else
/// metres. A geographic or unknown unit in the file, with nothing given, is an error; `name`
/// starts its message.
pub fn resolve(
    name: &str,
    file: Option<&FileUnit>,
    given: Option<&LengthUnit>,
) -> Result<Units, UnitError> {
    if let Some(unit) = given {
        let same =
            matches!(file, Some(FileUnit::Length { unit: u, .. }) if u.metres == unit.metres);
        return Ok(Units {
            unit: unit.clone(),
            source: UnitSource::Given,
            overrides: file.filter(|_| !same).map(FileUnit::to_string),
        });
    }
    match file {
        None => Ok(Units::assumed()),
        Some(FileUnit::Length { unit, source }) => Ok(Units {
            unit: unit.clone(),
            source: UnitSource::File(source),
            overrides: None,
        }),
        Some(FileUnit::Geographic { unit, source }) => Err(UnitError::Geographic {
            name: name.to_owned(),
            unit: unit.clone(),
            from: source,
        }),
        Some(FileUnit::Unknown { what, source }) => Err(UnitError::Unknown {
            name: name.to_owned(),
            what: what.clone(),
            from: source,
        }),
    }
}

/// The size of an EPSG linear unit code (GeoTIFF's ProjLinearUnitsGeoKey), in metres.
fn epsg_linear_unit(code: u16) -> Option<LengthUnit> {
    let (name, metres) = match code {
        9001 => ("metre", 1.0),
        9002 => ("foot", 0.3048),
        9003 => ("US survey foot", US_SURVEY_FOOT),
        9005 => ("Clarke's foot", 0.304_797_265_4),
        9014 => ("fathom", 1.8288),
        9030 => ("nautical mile", 1852.0),
        9031 => ("German legal metre", 1.000_013_596_5),
        9033 => ("US survey chain", 20.116_840_233_680_47),
        9034 => ("US survey link", 0.201_168_402_336_804_7),
        9035 => ("US survey mile", 1_609.347_218_694_437),
        9036 => ("kilometre", 1000.0),
        9037 => ("Clarke's yard", 0.914_391_796_2),
        9038 => ("Clarke's chain", 20.116_619_523_6),
        9039 => ("Clarke's link", 0.201_166_195_236),
        9040 => ("British yard (Sears 1922)", 0.914_398_414_616_029),
        9041 => ("British foot (Sears 1922)", 0.304_799_471_538_676),
        9042 => ("British chain (Sears 1922)", 20.116_765_121_552_6),
        9043 => ("British link (Sears 1922)", 0.201_167_651_215_526),
        9050 => ("British yard (Benoit 1895 A)", 0.914_399_8),
        9060 => ("British yard (Benoit 1895 B)", 0.914_399_204_289_812),
        9070 => ("British foot (1865)", 0.304_800_833_333_333),
        9080 => ("Indian foot", 0.304_799_510_248_147),
        9084 => ("Indian yard", 0.914_398_530_744_44),
        9093 => ("statute mile", 1609.344),
        9094 => ("Gold Coast foot", 0.304_799_710_181_508_8),
        9095 => ("British foot (1936)", 0.304_800_747_9),
        9096 => ("yard", 0.9144),
        9097 => ("chain", 20.1168),
        9098 => ("link", 0.201_168),
        9099 => ("British yard (Sears 1922 truncated)", 0.914_398),
        _ => return None,
    };
    Some(LengthUnit::new(name, metres))
}

fn epsg_angular_unit(code: u16) -> String {
    match code {
        9101 => "radians".into(),
        9102 | 9122 => "degrees".into(),
        9103 => "arc-minutes".into(),
        9104 => "arc-seconds".into(),
        9105 => "grads".into(),
        other => format!("angular unit EPSG:{other}"),
    }
}

const GT_MODEL_TYPE: u16 = 1024;
const GEOG_LINEAR_UNITS: u16 = 2052;
const GEOG_ANGULAR_UNITS: u16 = 2054;
const PROJ_LINEAR_UNITS: u16 = 3076;
const PROJ_LINEAR_UNIT_SIZE: u16 = 3077;
const USER_DEFINED: u16 = 32767;

/// The unit a GeoTIFF key directory (LAS VLR "LASF_Projection" 34735) gives, with the double
/// parameters (record 34736) for a user-defined unit's size; `None` where it says nothing of
/// the model type or the directory cannot be read.
pub fn from_geokeys(directory: &[u8], doubles: Option<&[u8]>) -> Option<FileUnit> {
    const SOURCE: &str = "LAS GeoKeys";
    let shorts: Vec<u16> = directory
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    let count = usize::from(*shorts.get(3)?);
    let keys = shorts.get(4..)?.chunks_exact(4).take(count);
    let double = |index: u16| {
        let at = usize::from(index) * 8;
        let bytes = doubles?.get(at..at + 8)?;
        Some(f64::from_le_bytes(bytes.try_into().ok()?))
    };
    let (mut model, mut linear, mut geog_linear, mut angular, mut size) =
        (None, None, None, None, None);
    for key in keys {
        let &[id, location, _count, value] = key else {
            continue;
        };
        match (id, location) {
            (GT_MODEL_TYPE, 0) => model = Some(value),
            (PROJ_LINEAR_UNITS, 0) => linear = Some(value),
            (GEOG_LINEAR_UNITS, 0) => geog_linear = Some(value),
            (GEOG_ANGULAR_UNITS, 0) => angular = Some(value),
            (PROJ_LINEAR_UNIT_SIZE, 34736) => size = double(value),
            _ => {}
        }
    }
    let length = |code: Option<u16>| match code {
        None => Some(FileUnit::Length {
            unit: LengthUnit::metre(),
            source: "LAS GeoKeys, no linear unit key: metre",
        }),
        Some(USER_DEFINED) => Some(match size.filter(|s| s.is_finite() && *s > 0.0) {
            Some(s) => FileUnit::Length {
                unit: LengthUnit::new("user-defined unit", s),
                source: SOURCE,
            },
            None => FileUnit::Unknown {
                what: "a user-defined linear unit without its size".into(),
                source: SOURCE,
            },
        }),
        Some(code) => Some(match epsg_linear_unit(code) {
            Some(unit) => FileUnit::Length {
                unit,
                source: SOURCE,
            },
            None => FileUnit::Unknown {
                what: format!("linear unit EPSG:{code}"),
                source: SOURCE,
            },
        }),
    };
    match model? {
        1 => length(linear),
        2 => Some(FileUnit::Geographic {
            unit: epsg_angular_unit(angular.unwrap_or(9102)),
            source: SOURCE,
        }),
        3 => length(geog_linear),
        _ => None,
    }
}

/// The unit an OGC WKT coordinate system (LAS VLR or EVLR "LASF_Projection" 2112) gives: the
/// projected system's own UNIT (WKT1 `PROJCS`, WKT2 `PROJCRS`), a geocentric system's, or
/// angles for a geographic one. `None` where no such system is found.
pub fn from_wkt(wkt: &str) -> Option<FileUnit> {
    const SOURCE: &str = "LAS WKT";
    let wkt = wkt.trim_matches(|c: char| c == '\0' || c.is_whitespace());
    let top = Node::parse(wkt)?;
    let system = top
        .find(&["PROJCS", "PROJCRS", "PROJECTEDCRS"])
        .or_else(|| {
            top.find(&[
                "GEOCCS",
                "GEODCRS",
                "GEODETICCRS",
                "GEOGCS",
                "GEOGCRS",
                "GEOGRAPHICCRS",
            ])
        })?;
    let kind = system.keyword.to_ascii_uppercase();
    let unit = system.own_unit();
    let geographic = match kind.as_str() {
        "GEOGCS" | "GEOGCRS" | "GEOGRAPHICCRS" => true,
        // WKT2 geodetic CRSs are geocentric with a Cartesian CS, geographic with an
        // ellipsoidal one.
        "GEODCRS" | "GEODETICCRS" => !system.children.iter().any(|c| {
            c.keyword.eq_ignore_ascii_case("CS") && c.text_arg(0).eq_ignore_ascii_case("cartesian")
        }),
        _ => false,
    };
    if geographic {
        let unit = unit.map_or_else(|| "degrees".to_owned(), |(name, _)| name);
        return Some(FileUnit::Geographic {
            unit,
            source: SOURCE,
        });
    }
    Some(match unit {
        Some((name, metres)) if metres.is_finite() && metres > 0.0 => FileUnit::Length {
            unit: LengthUnit::new(canonical(&name, metres), metres),
            source: SOURCE,
        },
        Some((name, _)) => FileUnit::Unknown {
            what: format!("unit \"{name}\" without a size"),
            source: SOURCE,
        },
        None => FileUnit::Length {
            unit: LengthUnit::metre(),
            source: "LAS WKT, no UNIT: metre",
        },
    })
}

/// A WKT unit's name as mema spells it where it is one of the common ones.
fn canonical(name: &str, metres: f64) -> String {
    let close = |m: f64| (metres - m).abs() <= 1e-9 * m;
    if close(1.0) {
        "metre".into()
    } else if close(0.3048) {
        "foot".into()
    } else if close(US_SURVEY_FOOT) {
        "US survey foot".into()
    } else {
        name.to_owned()
    }
}

/// One WKT node: `KEYWORD[arg, arg, CHILD[...], ...]`, with its quoted or bare arguments.
#[derive(Debug)]
struct Node {
    keyword: String,
    args: Vec<String>,
    children: Vec<Node>,
}

impl Node {
    fn parse(text: &str) -> Option<Node> {
        let mut chars = text.char_indices().peekable();
        let node = Self::parse_at(text, &mut chars, 0)?;
        Some(node)
    }

    fn parse_at(
        text: &str,
        chars: &mut std::iter::Peekable<std::str::CharIndices<'_>>,
        depth: usize,
    ) -> Option<Node> {
        // A WKT of any real CRS nests a few levels; a file cannot make this recurse far.
        if depth > 32 {
            return None;
        }
        while chars.next_if(|(_, c)| c.is_whitespace()).is_some() {}
        let start = chars.peek()?.0;
        let mut end = start;
        while let Some((i, c)) = chars.next_if(|(_, c)| c.is_ascii_alphanumeric() || *c == '_') {
            end = i + c.len_utf8();
        }
        let keyword = text.get(start..end)?.to_owned();
        while chars.next_if(|(_, c)| c.is_whitespace()).is_some() {}
        let mut node = Node {
            keyword,
            args: Vec::new(),
            children: Vec::new(),
        };
        let close = match chars.next_if(|(_, c)| *c == '[' || *c == '(') {
            Some((_, '[')) => ']',
            Some(_) => ')',
            None => return Some(node),
        };
        loop {
            while chars
                .next_if(|(_, c)| c.is_whitespace() || *c == ',')
                .is_some()
            {}
            let &(at, c) = chars.peek()?;
            if c == close {
                chars.next();
                return Some(node);
            }
            if c == '"' {
                chars.next();
                let mut s = String::new();
                loop {
                    let (_, c) = chars.next()?;
                    if c == '"' {
                        // A doubled quote is a quote inside the string.
                        if chars.next_if(|(_, c)| *c == '"').is_some() {
                            s.push('"');
                            continue;
                        }
                        break;
                    }
                    s.push(c);
                }
                node.args.push(s);
            } else if c.is_ascii_alphabetic() {
                let child = Self::parse_at(text, chars, depth + 1)?;
                if child.args.is_empty() && child.children.is_empty() {
                    // A bare word (an axis direction, an enumeration).
                    node.args.push(child.keyword);
                } else {
                    node.children.push(child);
                }
            } else {
                let mut end = at;
                while let Some((i, c)) =
                    chars.next_if(|(_, c)| !matches!(c, ',' | ']' | ')') && !c.is_whitespace())
                {
                    end = i + c.len_utf8();
                }
                if end == at {
                    return None;
                }
                node.args.push(text.get(at..end)?.to_owned());
            }
        }
    }

    /// This node, or the first descendant (depth first) with one of the keywords.
    fn find(&self, keywords: &[&str]) -> Option<&Node> {
        if keywords
            .iter()
            .any(|k| self.keyword.eq_ignore_ascii_case(k))
        {
            return Some(self);
        }
        self.children.iter().find_map(|c| c.find(keywords))
    }

    fn text_arg(&self, i: usize) -> &str {
        self.args.get(i).map_or("", String::as_str)
    }

    /// The system's own unit: its last direct `UNIT`/`LENGTHUNIT`/`ANGLEUNIT` child (WKT1 puts
    /// it after the parameters; WKT2 after the CS), else the first one among its axes; not the
    /// units of a base geographic system or of a conversion's parameters.
    fn own_unit(&self) -> Option<(String, f64)> {
        const UNITS: [&str; 3] = ["UNIT", "LENGTHUNIT", "ANGLEUNIT"];
        let is_unit = |n: &&Node| UNITS.iter().any(|k| n.keyword.eq_ignore_ascii_case(k));
        let unit = self.children.iter().rev().find(is_unit).or_else(|| {
            self.children
                .iter()
                .filter(|c| c.keyword.eq_ignore_ascii_case("AXIS"))
                .find_map(|a| a.children.iter().find(is_unit))
        })?;
        let factor = unit.text_arg(1).parse::<f64>().unwrap_or(f64::NAN);
        Some((unit.text_arg(0).to_owned(), factor))
    }
}

#[cfg(test)]
mod tests;
