use super::testkit::{XorShift, expect_err, shared};
use super::*;
use std::io::Read;

#[test]
fn content_decides_the_format_not_the_extension() {
    let car = read_cloud_bytes("car6.ply", &shared("car6.pcd")).unwrap();
    assert_eq!(car.format, Format::PcdBinaryCompressed);
    assert_eq!(car.slots, 10_031);
    let bunny = read_cloud_bytes("bunny.txt", &shared("bun_zipper.ply")).unwrap();
    assert_eq!((bunny.format, bunny.slots), (Format::PlyAscii, 35_947));
    let text = read_cloud_bytes("a.pcd", b"# comment\n1 2 3\n").unwrap();
    assert_eq!(text.format, Format::Xyz);
    // Leading comments longer than the first look, before a PCD header or text points.
    let comments = "# a scanner's banner, repeated\n".repeat(2000);
    let pcd = [comments.as_bytes(), &shared("lamppost.pcd")].concat();
    let lamppost = read_cloud_bytes("x", &pcd).unwrap();
    assert_eq!((lamppost.format, lamppost.slots), (Format::PcdAscii, 1_771));
    let text = format!("{comments}1 2 3\n4 5 6\n");
    let xyz = read_cloud_bytes("x", text.as_bytes()).unwrap();
    assert_eq!((xyz.format, xyz.slots), (Format::Xyz, 2));
    let disk = read_cloud(Path::new(&format!("{}/milk.pcd", testkit::DATA))).unwrap();
    let memory = read_cloud_bytes("milk.pcd", &shared("milk.pcd")).unwrap();
    assert_eq!(disk, memory);
}

/// A source that counts what is read from it, delivered a page at a time as a slow pipe
/// might, so that the first look ends where the test puts it.
struct Counted<R> {
    inner: R,
    read: usize,
}

impl<R: Read> Read for Counted<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        let page = out.len().min(HEAD);
        let n = self.inner.read(out.get_mut(..page).unwrap_or_default())?;
        self.read += n;
        Ok(n)
    }
}

/// Bytes detection reads from a `len`-byte file of `start` followed by `fill` bytes, and
/// whether it takes the file for a PCD.
fn detection_reads(start: &[u8], fill: u8, len: u64) -> (usize, bool) {
    let inner = start.chain(std::io::repeat(fill));
    let mut source = Counted { inner, read: 0 };
    let mut input = Input::new(Ctx::new("x.dat"), &mut source, len);
    let pcd = starts_pcd(&mut input).unwrap();
    (source.read, pcd)
}

/// Detection reads on past the first 4 KiB only while the line cut there is a comment (or
/// blank, or a word that may become a PCD keyword), and never past 1 MiB.
#[test]
fn detection_reads_a_bounded_head() {
    let (gib, most) = (1 << 30, HEAD_LIMIT + 64 * 1024);
    // No newline at all: binary zeros, a text line, an endless comment, endless blanks.
    for (start, fill, bound) in [
        (&b""[..], 0, 64 * 1024),
        (b"1 2 3", b' ', 64 * 1024),
        (b"# an endless banner ", b'=', most),
        (b"", b' ', most),
    ] {
        let (read, pcd) = detection_reads(start, fill, gib);
        assert!(read <= bound, "{start:?} + {fill}: {read} bytes read");
        assert!(!pcd);
    }
    // A keyword cut by the first look is read whole.
    let mut start = vec![b'#'; HEAD - 3];
    start.extend_from_slice(b"\nVERSION 0.7\n");
    let (read, pcd) = detection_reads(&start, b'\n', 1 << 20);
    assert!(pcd && read < 3 * HEAD, "{read} bytes read");
    // Comments longer than the limit: not a PCD, whatever follows.
    let banner = "# a scanner's banner, repeated\n".repeat(HEAD_LIMIT / 31 + 1);
    let pcd = [banner.as_bytes(), b"VERSION 0.7\n"].concat();
    assert!(!detection_reads(&pcd, b'\n', 4 << 20).1);
}

/// A pipe is read whole (the limit and the idle timeout are `io::input`'s, tested there).
#[test]
fn pipes_are_read_whole() {
    let text = b"1 2 3\n4 5 6\n";
    let at_limit = read_cloud_bytes("pipe", &text[..]).unwrap();
    assert_eq!((at_limit.format, at_limit.slots), (Format::Xyz, 2));
    // A named pipe, through `read_cloud`: a cloud written into it reads as from the file.
    let dir = std::env::temp_dir().join(format!("mema-fifo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("cloud.xyz");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if made.as_ref().is_ok_and(|s| s.success()) {
        let writer = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::write(fifo, b"1 2 3\n4 5 6\n"))
        };
        let cloud = read_cloud(&fifo).unwrap();
        writer.join().unwrap().unwrap();
        assert_eq!(cloud, at_limit);
    } else {
        eprintln!("mkfifo failed ({made:?}): the named pipe case is skipped");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Reads `bytes` as a file that had `extra` more bytes when its length was taken, as if it
/// shrank while being read.
fn read_shrunk(name: &str, bytes: &[u8], extra: u64) -> Result<Cloud, ReadError> {
    let mut source = bytes;
    let mut input = Input::new(Ctx::new(name), &mut source, bytes.len() as u64 + extra);
    match detect(&mut input)? {
        Kind::Stream(read) => read(&mut input),
        Kind::Las => las::read(Ctx::new(name), std::io::Cursor::new(bytes.to_vec()), 0),
    }
}

/// Every reader of fixed-size records, and the LZF stream, says the same when the bytes stop
/// before the length the file had when it was opened: where, and inside what.
#[test]
fn files_that_shrink_while_read() {
    let kitti: Vec<u8> = (0..4000u32)
        .flat_map(|i| (i as f32).to_le_bytes())
        .collect();
    for (name, bytes, inside) in [
        ("b.pcd", pcd::tests::car6_as("binary", 4), "DATA binary"),
        (
            "c.pcd",
            pcd::tests::car6_as("binary_compressed", 8),
            "DATA binary_compressed",
        ),
        (
            "b.ply",
            ply::tests::bunny_binary(Endian::Little),
            "element vertex instance",
        ),
        ("k.bin", kitti, "KITTI record"),
    ] {
        let kept = bytes.len() / 4;
        let e = read_shrunk(name, &bytes[..kept], (bytes.len() - kept) as u64).unwrap_err();
        assert!(matches!(e, ReadError::Truncated { .. }), "{e:?}");
        let msg = e.to_string();
        let want = format!("{name}: truncated: {inside}");
        assert!(msg.starts_with(&want), "{msg}");
        // The offset is that of the last whole record or chunk before the cut.
        let end = format!(" of {}", bytes.len());
        assert!(
            msg.contains(" runs past the end of the file at offset "),
            "{msg}"
        );
        assert!(msg.ends_with(&end), "{msg}");
    }
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
                    let insert: Vec<u8> = (0..1 + rng.below(8)).map(|_| rng.next() as u8).collect();
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
