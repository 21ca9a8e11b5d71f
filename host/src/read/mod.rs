//! Point-cloud readers: PLY, PCD, LAS/LAZ, XYZ/CSV text and KITTI `.bin`, recognised by content
//! (KITTI, having no header, by its extension).
//!
//! The contract every reader keeps:
//! - the file is read once into memory and parsed from that slice;
//! - no input makes a reader panic: bytes are reached through `get`, `chunks_exact` and
//!   iterators, never through indexing that the file controls;
//! - a size taken from a header is checked against the bytes actually present before it is
//!   allocated or looped over, so a header claiming 10^18 points is an error, not an allocation;
//! - coordinates are parsed as f64 and only cast to f32 after moving to the bounding-box centre,
//!   because real captures (airborne lidar in UTM metres, say) sit far from zero and would lose
//!   centimetres in f32.
//!
//! Format detection looks at the bytes first (`ply` magic line, a PCD header, the `LASF`
//! signature, then text with a line of at least three numbers); the file extension only sharpens
//! the error message, except for headerless KITTI `.bin` scans, which it selects.

mod kitti;
mod las;
mod lzf;
mod pcd;
mod ply;
mod xyz;

use std::fmt;
use std::path::{Path, PathBuf};

use xyz::Line;

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
    /// The encoding the points were read from.
    pub format: Format,
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
    Offset(usize),
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
}

fn no_finite_points(slots: &usize) -> String {
    match slots {
        0 => "no points (the file declares 0)".to_owned(),
        n => format!("no finite points ({n} slots, all NaN or infinite)"),
    }
}

/// Reads a PLY, PCD, LAS/LAZ, XYZ/CSV or KITTI `.bin` file.
pub fn read_cloud(path: &Path) -> Result<Cloud, ReadError> {
    let bytes = std::fs::read(path).map_err(|cause| ReadError::Io {
        path: path.to_owned(),
        cause,
    })?;
    read_cloud_bytes(&path.display().to_string(), &bytes)
}

/// Same from bytes already in memory; `name` is used in error messages.
pub fn read_cloud_bytes(name: &str, bytes: &[u8]) -> Result<Cloud, ReadError> {
    let ctx = Ctx(name);
    if bytes.is_empty() {
        let name = name.to_owned();
        return Err(ReadError::Empty { name });
    }
    if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") {
        return ply::read(ctx, bytes);
    }
    if pcd::has_header(bytes) {
        return pcd::read(ctx, bytes);
    }
    if las::has_signature(bytes) {
        return las::read(ctx, bytes);
    }
    if kitti::is_named_bin(name) {
        return kitti::read(ctx, bytes);
    }
    if xyz::looks_like_text(bytes) {
        return xyz::read(ctx, bytes);
    }
    Err(ctx.not_a_cloud("no PLY/PCD/LAS header, and not XYZ/CSV text"))
}

/// The file name, carried by every reader to build its errors.
#[derive(Clone, Copy)]
pub(crate) struct Ctx<'a>(&'a str);

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

/// A binary number type, as PLY and PCD declare them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Endian {
    Little,
    Big,
}

impl Scalar {
    pub fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::I64 | Scalar::U64 | Scalar::F64 => 8,
        }
    }

    pub fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The value at the start of `bytes`, or `None` if `bytes` is too short. 64-bit integers
    /// round to the nearest f64; a count too large to be exact is too large for any file.
    #[inline]
    pub fn read(self, bytes: &[u8], endian: Endian) -> Option<f64> {
        macro_rules! get {
            ($t:ty) => {{
                let raw = *bytes.first_chunk::<{ size_of::<$t>() }>()?;
                (match endian {
                    Endian::Little => <$t>::from_le_bytes(raw),
                    Endian::Big => <$t>::from_be_bytes(raw),
                }) as f64
            }};
        }
        Some(match self {
            Scalar::I8 => get!(i8),
            Scalar::U8 => get!(u8),
            Scalar::I16 => get!(i16),
            Scalar::U16 => get!(u16),
            Scalar::I32 => get!(i32),
            Scalar::U32 => get!(u32),
            Scalar::I64 => get!(i64),
            Scalar::U64 => get!(u64),
            Scalar::F32 => get!(f32),
            Scalar::F64 => get!(f64),
        })
    }
}

/// Collects points, counting slots and dropping non-finite ones, then centres them.
///
/// While every coordinate is exactly an f32 (binary float clouds, the common case) the points
/// are held as f32, 12 bytes each, and centred in place: the cloud then exists once, not as an
/// f64 staging copy (24 bytes a point) plus the f32 result. The first coordinate that is not an
/// exact f32 (text, doubles) moves them to f64 for the rest. Centring computes
/// `(p - origin) as f32` from the same f64 value either way, so the bits do not depend on it.
pub(crate) struct Points {
    narrow: Vec<[f32; 3]>,
    wide: Vec<[f64; 3]>,
    lo: [f64; 3],
    hi: [f64; 3],
    slots: usize,
    dropped: usize,
}

impl Points {
    /// `capacity` must already be bounded by what the file's bytes could hold.
    pub fn with_capacity(capacity: usize) -> Self {
        Points {
            narrow: Vec::with_capacity(capacity),
            wide: Vec::new(),
            lo: [f64::INFINITY; 3],
            hi: [f64::NEG_INFINITY; 3],
            slots: 0,
            dropped: 0,
        }
    }

    #[inline]
    pub fn push(&mut self, p: [f64; 3]) {
        self.slots += 1;
        if p.iter().all(|c| c.is_finite()) {
            for ((lo, hi), c) in self.lo.iter_mut().zip(&mut self.hi).zip(p) {
                *lo = lo.min(c);
                *hi = hi.max(c);
            }
            let narrow = p.map(|c| c as f32);
            if self.wide.is_empty() && narrow.iter().zip(p).all(|(&n, c)| n as f64 == c) {
                self.narrow.push(narrow);
            } else {
                if self.wide.is_empty() {
                    let mut wide = Vec::with_capacity(self.narrow.capacity());
                    wide.extend(self.narrow.iter().map(|q| q.map(f64::from)));
                    self.wide = wide;
                    self.narrow = Vec::new();
                }
                self.wide.push(p);
            }
        } else {
            self.dropped += 1;
        }
    }

    pub fn finish(self, ctx: Ctx, format: Format) -> Result<Cloud, ReadError> {
        if self.wide.is_empty() && self.narrow.is_empty() {
            let (name, slots) = (ctx.name(), self.slots);
            return Err(ReadError::NoFinitePoints { name, slots });
        }
        // Halving before adding keeps the centre and the half-extent finite even for
        // coordinates near f64::MAX.
        let origin: [f64; 3] = std::array::from_fn(|i| self.lo[i] / 2.0 + self.hi[i] / 2.0);
        for (axis, (lo, hi)) in ["x", "y", "z"].iter().zip(self.lo.iter().zip(&self.hi)) {
            if hi / 2.0 - lo / 2.0 > f64::from(f32::MAX) {
                return Err(ctx.unsupported(format!(
                    "{axis} spans {lo:e} to {hi:e}, beyond f32 even after centring"
                )));
            }
        }
        let local = |p: [f64; 3]| std::array::from_fn(|i| (p[i] - origin[i]) as f32);
        let points = if self.wide.is_empty() {
            let mut points = self.narrow;
            for p in points.iter_mut() {
                *p = local(p.map(f64::from));
            }
            points
        } else {
            self.wide.iter().map(|p| local(*p)).collect()
        };
        Ok(Cloud {
            origin,
            points,
            slots: self.slots,
            dropped_non_finite: self.dropped,
            format,
        })
    }
}

/// Helpers shared by the readers' tests.
#[cfg(test)]
pub(crate) mod testkit {
    use super::{Cloud, ReadError, read_cloud_bytes};

    /// The real clouds; read in place, never copied into the repository.
    pub const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data");

    pub fn shared(name: &str) -> Vec<u8> {
        std::fs::read(format!("{DATA}/{name}")).unwrap_or_else(|e| panic!("{DATA}/{name}: {e}"))
    }

    /// The number after `keyword` in a text header, e.g. `POINTS` or `element vertex`.
    pub fn header_count(bytes: &[u8], keyword: &str) -> usize {
        let head = String::from_utf8_lossy(bytes.get(..4096).unwrap_or(bytes));
        let line = head
            .lines()
            .find(|l| l.starts_with(keyword))
            .expect(keyword);
        line[keyword.len()..].trim().parse().expect(line)
    }

    /// Requires reading `bytes` to fail with the `variant` (its Debug name), and the message to
    /// be one line starting with the file's name.
    pub fn expect_err(name: &str, bytes: &[u8], variant: &str) -> ReadError {
        let e = read_cloud_bytes(name, bytes).expect_err(name);
        let msg = e.to_string();
        assert!(
            msg.starts_with(&format!("{name}: ")) && !msg.contains('\n'),
            "{msg}"
        );
        assert!(
            format!("{e:?}").starts_with(variant),
            "want {variant}: {e:?}"
        );
        e
    }

    /// Requires `cloud` to hold exactly `want`, in order, to 1e-6 of the cloud's extent.
    pub fn assert_same(cloud: &Cloud, want: &[[f64; 3]], what: &str) {
        assert_eq!(cloud.points.len(), want.len(), "{what}: point count");
        let axis = |k: usize| want.iter().map(move |p| p[k]);
        let span = |k| axis(k).fold(f64::MIN, f64::max) - axis(k).fold(f64::MAX, f64::min);
        let tolerance = 1e-6 * span(0).max(span(1)).max(span(2));
        for (i, (p, w)) in cloud.points.iter().zip(want).enumerate() {
            let got: [f64; 3] = std::array::from_fn(|k| cloud.origin[k] + f64::from(p[k]));
            let err = (0..3).map(|k| (got[k] - w[k]).abs()).fold(0.0, f64::max);
            assert!(err <= tolerance, "{what}: point {i} is {got:?}, want {w:?}");
        }
    }

    /// xorshift64: enough randomness for mutation tests, and the same on every machine.
    pub struct XorShift(pub u64);

    impl XorShift {
        pub fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }

        pub fn below(&mut self, n: usize) -> usize {
            (self.next() % n.max(1) as u64) as usize
        }
    }
}

#[cfg(test)]
mod tests {
    use super::testkit::{XorShift, expect_err, shared};
    use super::*;

    #[test]
    fn content_decides_the_format_not_the_extension() {
        let car = read_cloud_bytes("car6.ply", &shared("car6.pcd")).unwrap();
        assert_eq!(car.format, Format::PcdBinaryCompressed);
        assert_eq!(car.slots, 10_031);
        let bunny = read_cloud_bytes("bunny.txt", &shared("bun_zipper.ply")).unwrap();
        assert_eq!((bunny.format, bunny.slots), (Format::PlyAscii, 35_947));
        let text = read_cloud_bytes("a.pcd", b"# comment\n1 2 3\n").unwrap();
        assert_eq!(text.format, Format::Xyz);
        let disk = read_cloud(Path::new(&format!("{}/milk.pcd", testkit::DATA))).unwrap();
        let memory = read_cloud_bytes("milk.pcd", &shared("milk.pcd")).unwrap();
        assert_eq!(disk, memory);
    }

    #[test]
    fn empty_random_and_missing_files() {
        expect_err("empty.ply", b"", "Empty");
        let mut rng = XorShift(7);
        let noise: Vec<u8> = (0..4096).map(|_| rng.next() as u8).collect();
        let e = expect_err("x.dat", &noise, "NotAPointCloud");
        let want = "x.dat: not a point cloud (no PLY/PCD/LAS header, and not XYZ/CSV text)";
        assert_eq!(e.to_string(), want);
        let e = expect_err("x.ply", &noise, "NotAPointCloud");
        assert!(e.to_string().contains("named .ply"), "{e}");
        let notes = b"Meeting notes\nnothing numeric\n";
        expect_err("notes.txt", notes, "NotAPointCloud");
        let e = read_cloud(Path::new("/nonexistent/dir/cloud.ply")).unwrap_err();
        assert!(matches!(e, ReadError::Io { .. }));
        let msg = e.to_string();
        assert!(msg.starts_with("/nonexistent/dir/cloud.ply: "), "{msg}");
    }

    #[test]
    fn real_files_cut_anywhere_are_errors() {
        for name in "bun000.ply bun_zipper.ply lamppost.pcd car6.pcd office1.pcd".split(' ') {
            let bytes = shared(name);
            let header = bytes
                .windows(11)
                .position(|w| w == b"end_header\n" || w.starts_with(b"DATA "));
            let body = header.unwrap();
            let after = [0, 5, 20, 1000, 30_000].map(|n| body + n);
            for cut in [12, 40].into_iter().chain(after) {
                let e = read_cloud_bytes(name, &bytes[..cut]).unwrap_err();
                assert!(e.to_string().starts_with(name), "{e}");
                let truncated = matches!(e, ReadError::Truncated { .. });
                assert!(truncated, "{name} cut at {cut}: {e:?}");
            }
        }
    }

    /// Seeded byte flips, truncations and insertions of real files: any result is fine except
    /// a panic, and every error is one line naming the file.
    #[test]
    fn mutated_real_files_never_panic() {
        let names = "bun_zipper.ply bun000.ply car6.pcd milk.pcd lamppost.pcd office1.pcd";
        let bunny = ply::tests::bunny_binary(Endian::Big);
        let car = pcd::tests::car6_as("binary", 4);
        let seeds: Vec<Vec<u8>> = names.split(' ').map(shared).chain([bunny, car]).collect();
        let one_line = |msg: &str| msg.starts_with("fuzz.in: ") && !msg.contains('\n');
        let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
        for case in 0..2000 {
            let seed = &seeds[rng.below(seeds.len())];
            // Small files whole, so that LZF streams get decoded; big ones as a prefix.
            let (n, prefix) = (seed.len(), 256 + rng.below(1 << 16));
            let len = if n < 100_000 { n } else { prefix };
            let mut bytes = seed[..len].to_vec();
            for _ in 0..1 + rng.below(4) {
                let at = rng.below(bytes.len());
                match rng.below(4) {
                    0 => bytes[at] ^= 1 << rng.below(8),
                    1 => bytes[at] = rng.next() as u8,
                    2 => bytes.truncate(at.max(1)),
                    _ => {
                        let insert: Vec<u8> =
                            (0..1 + rng.below(8)).map(|_| rng.next() as u8).collect();
                        bytes.splice(at..at, insert);
                    }
                }
            }
            let result = std::panic::catch_unwind(|| read_cloud_bytes("fuzz.in", &bytes));
            match result.unwrap_or_else(|_| panic!("case {case} panicked")) {
                Ok(cloud) => assert!(cloud.points.iter().flatten().all(|c| c.is_finite())),
                Err(e) => assert!(one_line(&e.to_string()), "{e}"),
            }
        }
    }

    /// Release-build timing of the two largest compressed clouds (printed with --nocapture);
    /// the bound only catches a pathological regression, the target is well under 100 ms.
    #[test]
    fn read_times() {
        for (name, slots) in [("five_people.pcd", 307_200), ("cturtle.pcd", 167_198)] {
            let bytes = shared(name);
            let mut best = std::time::Duration::MAX;
            for _ in 0..5 {
                let start = std::time::Instant::now();
                let cloud = read_cloud_bytes(name, &bytes).unwrap();
                best = best.min(start.elapsed());
                assert_eq!(cloud.slots, slots);
            }
            eprintln!("{name}: {slots} slots in {best:?}");
            assert!(best.as_millis() < 1000, "{name}: {best:?}");
        }
    }
}
