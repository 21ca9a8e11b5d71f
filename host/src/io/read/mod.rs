//! Point-cloud readers: PLY, PCD, LAS/LAZ, XYZ/CSV text and KITTI `.bin`, recognised by content
//! (KITTI, having no header, by its extension).
//!
//! The contract every reader keeps:
//! - the file is streamed through a small buffer (`stream::Input`), so the cloud is held
//!   once, as the points returned (an organized cloud's NaN slots until they are compacted in
//!   place), never next to a copy of the file or of a decompressed body;
//! - no input makes a reader panic: bytes are reached through `get`, `chunks_exact` and
//!   iterators, never through indexing that the file controls;
//! - a size taken from a header is checked against the bytes actually present (the file's
//!   length) before it is allocated or looped over, so a header claiming 10^18 points is an
//!   error, not an allocation; where the length cannot settle it (LZF may expand 88×), memory
//!   comes as the data is decoded; and an allocation the machine refuses is
//!   [`ReadError::OutOfMemory`], not an abort;
//! - coordinates are parsed as f64 and only cast to f32 after moving to the bounding-box centre,
//!   because real captures (airborne lidar in UTM metres, say) sit far from zero and would lose
//!   centimetres in f32.
//!
//! Format detection looks at the first bytes (`ply` magic line, a PCD header, the `LASF`
//! signature, then text with a line of at least three numbers); the file extension only sharpens
//! the error message, except for headerless KITTI `.bin` scans, which it selects.
//!
//! The path `-` is standard input ([`STDIN`]), read as a pipe is (to 1 GiB, each wait for bytes
//! bounded) and recognised by its content the same way; a KITTI scan, which only its name
//! tells apart, cannot come that way. A file named `-` is `./-`.

pub mod classes;
pub mod fuzz_checks;
mod kitti;
mod las;
mod lzf;
pub mod outliers;
mod pcd;
mod ply;
mod points;
mod stream;
mod xyz;

use std::fmt;
use std::fs::File;
use std::io::{IsTerminal, Seek};
use std::path::{Path, PathBuf};

use crate::io::units::{self, FileUnit, LengthUnit, Units};
pub use classes::{ClassDrops, Classes};
pub use outliers::{OutlierDrops, Outliers};

pub(crate) use points::{Endian, Points, Scalar};
use stream::{Input, Line};

/// What a read holds beside its points at most: the stream's buffer and the LZF window, the
/// figure the performance guide gives for reading.
pub const READ_OVERHEAD: usize = stream::BUFFER + lzf::WINDOW;

/// A cloud read from a file: coordinates moved to a local origin so they survive the trip to f32.
#[derive(Debug, Clone, PartialEq)]
pub struct Cloud {
    /// The bounding-box centre of the finite points, in the file's own coordinates (f64).
    pub origin: [f64; 3],
    /// Finite points minus `origin`, as f32.
    pub points: Vec<[f32; 3]>,
    /// Point slots the file declares (including NaN/inf ones), e.g. WIDTH*HEIGHT of an organized PCD.
    pub slots: usize,
    /// Slots dropped because a coordinate was NaN or infinite.
    pub dropped_non_finite: usize,
    /// Points of a classified file (LAS/LAZ) left out: noise, withheld, other classes.
    pub dropped_by_class: ClassDrops,
    /// Isolated points left out ([`Outliers`]).
    pub outliers: OutlierDrops,
    /// The encoding the points were read from.
    pub format: Format,
    /// The unit the file says its coordinates are in (LAS GeoKeys or WKT); `None` where it
    /// says nothing, as PLY, PCD, XYZ and KITTI never do.
    pub unit: Option<FileUnit>,
    /// The unit the coordinates were scaled from to metres ([`read_cloud_in_metres`]); `None`
    /// where they are the file's own ([`read_cloud`]).
    pub units: Option<Units>,
    /// Where the sensor was, in the same coordinates as `origin` (a PCD's `VIEWPOINT`, or the
    /// frame's origin for an organized PCD without one and for a KITTI scan); `None` where the
    /// file does not say, and then the points are not rays.
    pub sensor: Option<[f64; 3]>,
    /// Points left out as no-returns: within the screening's `min_range` of `sensor`.
    pub no_returns: usize,
}

/// The file formats and encodings the readers understand.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    PlyAscii,
    PlyBinaryLittleEndian,
    PlyBinaryBigEndian,
    PcdAscii,
    PcdBinary,
    PcdBinaryCompressed,
    Xyz,
    Las,
    Laz,
    KittiBin,
    /// A ROS 2 bag's PointCloud2 messages ([`crate::io::bag`]).
    RosBag,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::PlyAscii => "PLY ascii",
            Format::PlyBinaryLittleEndian => "PLY binary_little_endian",
            Format::PlyBinaryBigEndian => "PLY binary_big_endian",
            Format::PcdAscii => "PCD ascii",
            Format::PcdBinary => "PCD binary",
            Format::PcdBinaryCompressed => "PCD binary_compressed",
            Format::Xyz => "XYZ text",
            Format::Las => "LAS",
            Format::Laz => "LAZ",
            Format::KittiBin => "KITTI bin",
            Format::RosBag => "ROS 2 bag (MCAP)",
        })
    }
}

/// Where in a file a problem sits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum At {
    /// The header as a whole (a missing field, an inconsistency between lines).
    Header,
    /// A 1-based line of a text header or text body.
    Line(usize),
    /// A byte offset from the start of the file.
    Offset(u64),
}

impl fmt::Display for At {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            At::Header => f.write_str("header"),
            At::Line(n) => write!(f, "line {n}"),
            At::Offset(n) => write!(f, "offset {n}"),
        }
    }
}

/// Why a file could not be read as a point cloud. Each Display is one line that starts with
/// the file's name.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReadError {
    /// The file could not be read from disk. The OS error is part of the message rather than a
    /// `source`, so a `{:#}` chain does not print it twice.
    #[error("{}: {cause}", path.display())]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    /// The file has no bytes at all.
    #[error("{name}: empty file")]
    Empty { name: String },
    /// The bytes are none of the formats above.
    #[error("{name}: not a point cloud ({why})")]
    NotAPointCloud { name: String, why: String },
    /// The file ends before the header or the data it declares.
    #[error("{name}: truncated: {what}")]
    Truncated { name: String, what: String },
    /// The header is malformed or inconsistent.
    #[error("{name}: {at}: {what}")]
    BadHeader { name: String, at: At, what: String },
    /// A value in the data cannot be used (not a number, a negative list count, corrupt LZF).
    #[error("{name}: {at}: {what}")]
    BadValue { name: String, at: At, what: String },
    /// Every declared slot has a NaN or infinite coordinate, or none is declared.
    #[error("{name}: {}", no_finite_points(.slots))]
    NoFinitePoints { name: String, slots: usize },
    /// A valid file that uses something these readers do not handle.
    #[error("{name}: unsupported: {what}")]
    Unsupported { name: String, what: String },
    /// The memory for the points the file declares could not be had.
    #[error("{name}: out of memory: {what}")]
    OutOfMemory { name: String, what: String },
    /// The input is past a limit these readers set (a pipe's bytes, a header's size).
    #[error("{name}: too large: {what}")]
    TooLarge { name: String, what: String },
    /// The coordinates cannot be taken to metres: geographic, or in a unit not known.
    #[error(transparent)]
    Units(units::UnitError),
    /// The cloud's span is too wide for f32 at its point spacing (a far outlier kept, or a
    /// cloud that needs cropping).
    #[error("{name}: {loss}")]
    Precision {
        name: String,
        loss: outliers::PrecisionLoss,
    },
    /// `-` was given while standard input is a terminal: a cloud is piped in, not typed.
    #[error(
        "{}: a terminal, not a cloud; pipe one in (e.g. `mema map - -k 150 -o scan.mema < scan.ply`)",
        STDIN_NAME
    )]
    Terminal,
}

/// The path that reads standard input.
pub const STDIN: &str = "-";

/// How messages name standard input.
const STDIN_NAME: &str = "standard input";

/// How messages name the input at `path`: its path, or "standard input" for [`STDIN`].
pub fn input_name(path: &Path) -> String {
    if path == Path::new(STDIN) {
        STDIN_NAME.to_owned()
    } else {
        path.display().to_string()
    }
}

fn no_finite_points(slots: &usize) -> String {
    match slots {
        0 => "no points (the file declares 0)".to_owned(),
        n => format!("no finite points ({n} slots, all NaN or infinite)"),
    }
}

/// The most bytes read from a pipe or a device. Such an input is held whole, since a header's
/// sizes can only be checked against a known length; 1 GiB is far more than any cloud these
/// readers are used on (the largest shared one is 3 MB), and past it the input is an error,
/// where `/dev/zero` would otherwise be read until memory ran out. A pipe that stays quiet for
/// [`crate::io::input::IDLE_TIMEOUT`] is an error too (a FIFO nobody writes to).
pub const UNSIZED_LIMIT: u64 = 1 << 30;

/// Reads a PLY, PCD, LAS/LAZ, XYZ/CSV or KITTI `.bin` file, in its own coordinates.
pub fn read_cloud(path: &Path) -> Result<Cloud, ReadError> {
    read_scaled(path, Scaling::File, Screening::default())
}

/// Reads a cloud file in metres: scaled by `given` (`--units`), else by the unit the file
/// says (LAS GeoKeys or WKT), else taken as metres. The scale is applied in f64, before the
/// points are cast to f32, and a scale of 1 is not applied at all, so a cloud in metres reads
/// bit for bit as [`read_cloud`] reads it. Geographic coordinates or a unit not known are
/// [`ReadError::Units`] unless a unit is given.
pub fn read_cloud_in_metres(path: &Path, given: Option<&LengthUnit>) -> Result<Cloud, ReadError> {
    read_scaled(path, Scaling::Metres(given), Screening::default())
}

/// What a read leaves out of a file: points by their class, isolated points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Screening {
    /// The points of a classified file (LAS/LAZ) kept.
    pub classes: Classes,
    /// What is done about isolated points.
    pub outliers: Outliers,
    /// Points this close to their sensor origin (metres) are no-returns, never surface.
    pub min_range: f64,
}

/// The default no-return range: lidar drivers write a beam that came back empty as exactly
/// the sensor's position, and no lidar or depth camera measures a surface 1 cm away, so this
/// catches those slots (and their f32 rounding after a pose) and never a real return.
pub const NO_RETURN_RANGE: f64 = 0.01;

impl Default for Screening {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl Screening {
    /// The library's plain reads: noise classes left out, every other point as the file holds it.
    pub const DEFAULT: Self = Self {
        classes: Classes::NotNoise,
        outliers: Outliers::Unchecked,
        min_range: NO_RETURN_RANGE,
    };

    /// The command line's and the Python package's reads: noise classes and isolated points
    /// left out, and a cloud too wide for f32 at its spacing refused.
    pub const MAPPING: Self = Self {
        classes: Classes::NotNoise,
        outliers: Outliers::DEFAULT,
        min_range: NO_RETURN_RANGE,
    };
}

/// [`read_cloud_in_metres`] leaving out what `screening` says: points of a classified file
/// (LAS/LAZ) by class, and isolated points ([`Screening`]).
pub fn read_cloud_in_metres_keeping(
    path: &Path,
    given: Option<&LengthUnit>,
    screening: Screening,
) -> Result<Cloud, ReadError> {
    read_scaled(path, Scaling::Metres(given), screening)
}

fn read_scaled(path: &Path, scaling: Scaling, screening: Screening) -> Result<Cloud, ReadError> {
    if path == Path::new(STDIN) {
        if std::io::stdin().is_terminal() {
            return Err(ReadError::Terminal);
        }
        // Linux's name for descriptor 0: a pipe, a socket or a redirected file alike.
        return read_unsized(Path::new("/dev/stdin"), STDIN_NAME, scaling, screening);
    }
    let io = |cause| ReadError::Io {
        path: path.to_owned(),
        cause,
    };
    // The type first: opening a FIFO blocks until a writer comes. A regular file of length 0
    // may still have bytes (/proc, /sys): it is read as a pipe is, to its end.
    let name = path.display().to_string();
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() || meta.len() == 0 {
        return read_unsized(path, &name, scaling, screening);
    }
    let mut file = File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    let ctx = Ctx(&name, scaling, screening);
    let kind = {
        let mut input = Input::new(ctx, &mut file, meta.len());
        match detect(&mut input)? {
            Kind::Las => None,
            Kind::Stream(read) => Some(read(&mut input)?),
        }
    };
    match kind {
        Some(cloud) => Ok(cloud),
        None => {
            // `las` wants an owned, seekable source: the file itself, from its start.
            file.rewind().map_err(io)?;
            las::read(ctx, std::io::BufReader::new(file), meta.len())
        }
    }
}

/// Reads a pipe, a device or a file whose length says nothing, whole (to [`UNSIZED_LIMIT`]),
/// then its bytes; `name` names it in errors.
fn read_unsized(
    path: &Path,
    name: &str,
    scaling: Scaling,
    screening: Screening,
) -> Result<Cloud, ReadError> {
    use crate::io::input::{InputError, read_bounded};
    let io = |cause| ReadError::Io {
        path: PathBuf::from(name),
        cause,
    };
    match read_bounded(path, UNSIZED_LIMIT, "point cloud") {
        Ok(bytes) => read_bytes(Ctx(name, scaling, screening), &bytes),
        Err(InputError::TooLarge { limit, .. }) => Err(ReadError::TooLarge {
            name: name.to_owned(),
            what: format!(
                "a pipe or device giving more than {limit} bytes, the most read from an input without a length"
            ),
        }),
        Err(InputError::Io { cause, .. }) => Err(io(cause)),
        Err(e @ InputError::NotA { .. }) => Err(io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            e.to_string(),
        ))),
        Err(InputError::Idle { .. }) => Err(io(std::io::Error::new(
            std::io::ErrorKind::TimedOut,
            format!(
                "nothing arrived for {} s (a pipe or device that nobody writes to is not a point cloud)",
                crate::io::input::IDLE_TIMEOUT.as_secs()
            ),
        ))),
    }
}

/// Same from bytes already in memory; `name` is used in error messages.
pub fn read_cloud_bytes(name: &str, bytes: &[u8]) -> Result<Cloud, ReadError> {
    read_bytes(Ctx::new(name), bytes)
}

fn read_bytes(ctx: Ctx, bytes: &[u8]) -> Result<Cloud, ReadError> {
    let mut source = bytes;
    let mut input = Input::new(ctx, &mut source, bytes.len() as u64);
    match detect(&mut input)? {
        // `las` wants an owned source; one copy is cheap next to decoding the points.
        Kind::Las => las::read(
            ctx,
            std::io::Cursor::new(bytes.to_vec()),
            bytes.len() as u64,
        ),
        Kind::Stream(read) => read(&mut input),
    }
}

/// What the first bytes of a file say it is: LAS/LAZ, which the `las` crate reads from a
/// seekable source, or a format with a reader over the stream.
enum Kind {
    Las,
    Stream(fn(&mut Input) -> Result<Cloud, ReadError>),
}

/// Bytes of the file's start that detection looks at; more only while leading comment lines
/// leave it open whether a PCD header follows them.
const HEAD: usize = 4096;

/// The most detection reads past [`HEAD`] for leading comments: 16 times the longest banner
/// seen before a real PCD header (62 KB). Comments running on past it make the file not a PCD,
/// as if it ended there; otherwise a gigabyte with no newline would be read whole to find the
/// end of its first line.
const HEAD_LIMIT: usize = 1 << 20;

/// Whether a PCD header starts the input, after any comment lines.
fn starts_pcd(input: &mut Input) -> Result<bool, ReadError> {
    let (mut want, len) = (HEAD, input.remaining());
    loop {
        let head = input.peek(want)?;
        // Fewer bytes than asked for: the input ended (early, if it shrank since it was opened).
        let whole = head.len() as u64 >= len || head.len() < want || head.len() >= HEAD_LIMIT;
        match pcd::has_header(head, whole) {
            Some(is_pcd) => return Ok(is_pcd),
            None => want = head.len().saturating_mul(2).min(HEAD_LIMIT),
        }
    }
}

fn detect(input: &mut Input) -> Result<Kind, ReadError> {
    let ctx = input.ctx();
    let is_pcd = starts_pcd(input)?;
    let head = input.peek(HEAD)?;
    if head.is_empty() {
        let name = ctx.name();
        return Err(ReadError::Empty { name });
    }
    Ok(
        if head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n") {
            Kind::Stream(ply::read)
        } else if is_pcd {
            Kind::Stream(pcd::read)
        } else if las::has_signature(head) {
            Kind::Las
        } else if kitti::is_named_bin(ctx.0) {
            Kind::Stream(kitti::read)
        } else if xyz::looks_like_text(head) {
            Kind::Stream(xyz::read)
        } else {
            return Err(ctx.not_a_cloud("no PLY/PCD/LAS header, and not XYZ/CSV text"));
        },
    )
}

/// The file name, carried by every reader to build its errors, and whether the cloud is to be
/// scaled to metres.
#[derive(Clone, Copy)]
pub(crate) struct Ctx<'a>(&'a str, Scaling<'a>, Screening);

/// Whether a reader keeps the file's coordinates or brings them to metres, and by which unit.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Scaling<'a> {
    /// The file's own coordinates.
    File,
    /// Metres: by the unit given, else the file's, else none (see [`units::resolve`]).
    Metres(Option<&'a LengthUnit>),
}

impl<'a> Ctx<'a> {
    pub(crate) const fn new(name: &'a str) -> Self {
        Ctx(name, Scaling::File, Screening::DEFAULT)
    }

    /// A cloud to be read in metres (by `given`, else the file's unit, else none), leaving out
    /// what `screening` says.
    pub(crate) const fn in_metres_keeping(
        name: &'a str,
        given: Option<&'a LengthUnit>,
        screening: Screening,
    ) -> Self {
        Ctx(name, Scaling::Metres(given), screening)
    }

    /// The points of classified files this read keeps.
    pub(crate) const fn classes(self) -> Classes {
        self.2.classes
    }

    /// What this read leaves out.
    pub(crate) const fn screening(self) -> Screening {
        self.2
    }

    /// The unit to scale by, if the cloud is to be in metres, given what the file says.
    fn units(self, file: Option<&FileUnit>) -> Result<Option<Units>, ReadError> {
        match self.1 {
            Scaling::File => Ok(None),
            Scaling::Metres(given) => units::resolve(self.0, file, given)
                .map(Some)
                .map_err(ReadError::Units),
        }
    }
}

impl Ctx<'_> {
    fn name(self) -> String {
        self.0.to_owned()
    }

    fn truncated(self, what: impl Into<String>) -> ReadError {
        let (name, what) = (self.name(), what.into());
        ReadError::Truncated { name, what }
    }

    fn bad_header(self, at: At, what: impl Into<String>) -> ReadError {
        let (name, what) = (self.name(), what.into());
        ReadError::BadHeader { name, at, what }
    }

    fn bad_value(self, at: At, what: impl Into<String>) -> ReadError {
        let (name, what) = (self.name(), what.into());
        ReadError::BadValue { name, at, what }
    }

    fn unsupported(self, what: impl Into<String>) -> ReadError {
        let (name, what) = (self.name(), what.into());
        ReadError::Unsupported { name, what }
    }

    fn too_large(self, what: impl Into<String>) -> ReadError {
        let (name, what) = (self.name(), what.into());
        ReadError::TooLarge { name, what }
    }

    fn out_of_memory(self, what: impl Into<String>) -> ReadError {
        let (name, what) = (self.name(), what.into());
        ReadError::OutOfMemory { name, what }
    }

    /// A bad value on the last line of a file that lacks its newline is a cut file, and saying
    /// so is more useful than naming the half-written value.
    fn cut_short(self, line: &Line, e: ReadError) -> ReadError {
        if line.terminated {
            return e;
        }
        self.truncated(format!("the file ends inside line {}", line.number))
    }

    /// The extension is only a hint, so it shapes the message but never the decision.
    fn not_a_cloud(self, why: &str) -> ReadError {
        let ext = Path::new(self.0)
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        let why = match ext.as_deref() {
            Some("ply") => format!("{why}; named .ply but does not start with a 'ply' line"),
            Some("pcd") => format!("{why}; named .pcd but has no VERSION/FIELDS header"),
            _ => why.to_owned(),
        };
        let name = self.name();
        ReadError::NotAPointCloud { name, why }
    }
}

/// Helpers shared by the readers' tests.
#[cfg(test)]
pub(crate) mod testkit;

#[cfg(test)]
mod tests;

#[cfg(test)]
mod stated;
