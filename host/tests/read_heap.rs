//! The readers hold a cloud once: reading a file costs its points (an organized cloud's slots,
//! NaN ones included, until they are compacted) and fixed-size buffers, never a copy of the
//! file or of a decompressed body.
//!
//! A test binary of its own: the counting allocator is global to a process and counts every
//! thread's allocations, so this binary runs one test and nothing else allocates meanwhile.

use mema::heap::{self, Counting};
use mema::io::read::{ReadError, read_cloud, read_cloud_bytes};
use std::path::Path;

#[global_allocator]
static HEAP: Counting = Counting;

/// The stream's buffer and the LZF window are 32 KiB each; the header and the rest of the
/// reader's bookkeeping take a few KiB.
const FIXED: usize = 96 * 1024;

/// The slot bytes a binary_compressed PCD reserves before its data backs them (`UPFRONT` in
/// `read/pcd/body.rs`).
const UPFRONT: usize = 16 << 20;

#[test]
fn reading_holds_the_cloud_once() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    // Bytes a slot takes while the file is read: f32 coordinates are kept as they are; text
    // and LAS's scaled integers are held as f64 until they are centred, in the same allocation.
    let (f32s, f64s) = (size_of::<[f32; 3]>(), size_of::<[f64; 3]>());
    for (name, per_slot) in [
        // binary_compressed: two organized depth frames, three unorganized scans
        ("five_people.pcd", f32s),
        ("office1.pcd", f32s),
        ("cturtle.pcd", f32s),
        ("car6.pcd", f32s),
        ("milk.pcd", f32s),
        // ascii PLY and PCD
        ("bun_zipper.ply", f64s),
        ("bun000.ply", f64s),
        ("rops_cloud.pcd", f64s),
        ("lamppost.pcd", f64s),
    ] {
        let path = data.join(name);
        let file = std::fs::metadata(&path).expect(name).len() as usize;
        let before = heap::reset_peak();
        let cloud = read_cloud(&path).expect(name);
        let peak = heap::peak().saturating_sub(before);
        let points = cloud.points.len() * size_of::<[f32; 3]>();
        let slots = cloud.slots * per_slot;
        eprintln!(
            "{name}: heap peak {peak} bytes for {points} bytes of points ({slots} of slots), file {file} bytes"
        );
        assert!(heap::counting(), "the counting allocator is installed");
        assert!(
            peak <= slots + FIXED,
            "{name}: reading peaked at {peak} heap bytes, more than its {slots} bytes of slots + {FIXED}"
        );
        // What the pipeline goes on with is exactly the points: the NaN slots were handed back.
        assert_eq!(cloud.points.capacity(), cloud.points.len(), "{name}");
        // Reading may free something allocated before it (a buffer the test harness grew), so
        // the live bytes can end below where they started: that is none left, not a wrap.
        let after = heap::live().saturating_sub(before);
        assert!(
            after <= points + 1024,
            "{name}: {after} heap bytes still live for {points} bytes of points"
        );
    }

    // A header's claim is not an allocation: 4 million points of `TYPE I I I` (96 MB of f64
    // slots) over compressed bytes that decode to 273 KB reserve `UPFRONT` bytes, no more.
    let bogus = claim_beyond_its_data();
    let before = heap::reset_peak();
    let e = read_cloud_bytes("claim.pcd", &bogus).expect_err("the data ends early");
    assert!(matches!(e, ReadError::BadValue { .. }), "{e:?}");
    let peak = heap::peak().saturating_sub(before);
    eprintln!(
        "claim.pcd: heap peak {peak} bytes, file {} bytes",
        bogus.len()
    );
    assert!(
        peak <= UPFRONT + FIXED,
        "claim.pcd: reading peaked at {peak} heap bytes for a {} byte file",
        bogus.len()
    );

    // Nor is a header's length: a keyword given 100,000 times is kept once.
    let header = "VIEWPOINT 0 0 0 1 0 0 0\n".repeat(100_000);
    let pcd = format!("FIELDS x y z\n{header}WIDTH 1\nDATA ascii\n1 2 3\n");
    let before = heap::reset_peak();
    let cloud = read_cloud_bytes("long_header.pcd", pcd.as_bytes()).expect("one point");
    assert_eq!(cloud.format, mema::io::read::Format::PcdAscii);
    let peak = heap::peak().saturating_sub(before);
    eprintln!(
        "long_header.pcd: heap peak {peak} bytes, file {} bytes",
        pcd.len()
    );
    assert!(
        peak <= FIXED,
        "long_header.pcd: reading peaked at {peak} heap bytes"
    );

    // LAZ has no bound from its length, so it holds room for no more points than its bytes
    // would store plainly and makes more as they are decoded. autzen_trim.laz has 110,000 points
    // in 603 KB: claiming 4 billion costs the copy that `read_cloud_bytes` makes for `las`,
    // a 2 MiB batch of records, and no more than twice the points decoded, 24 bytes each; so
    // does claiming records of 64 KiB besides.
    let laz = std::fs::read(data.join("autzen_trim.laz")).expect("autzen_trim.laz");
    let real = 110_000;
    for record in [None, Some(u16::MAX)] {
        let mut claim = claiming(&laz, u32::MAX);
        if let Some(len) = record {
            claim[105..107].copy_from_slice(&len.to_le_bytes());
        }
        let before = heap::reset_peak();
        let e = read_cloud_bytes("claim.laz", &claim).expect_err("the data ends early");
        let peak = heap::peak().saturating_sub(before);
        eprintln!("{e}; heap peak {peak} bytes, file {} bytes", claim.len());
        assert!(
            matches!(e, ReadError::Truncated { .. } | ReadError::BadValue { .. }),
            "{e:?}"
        );
        let bound = claim.len() + (2 << 20) + 2 * real * 24 + FIXED;
        assert!(
            peak <= bound,
            "claim.laz, records of {record:?}: reading peaked at {peak} heap bytes, more than {bound}"
        );
    }

    // A PLY header keeps a property in 4 bytes and its name, not a `String` and 48 bytes of
    // bookkeeping: 60,000 `property char p` lines cost less than their own bytes, and 70,000 are
    // past the cap, which stops reading before they are kept.
    for (properties, cloud) in [(60_000, true), (70_000, false)] {
        let lines = "property char p\n".repeat(properties);
        let head = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex 1\n{lines}\
             property float x\nproperty float y\nproperty float z\nend_header\n"
        );
        let ply = [head.into_bytes(), vec![0; properties + 12]].concat();
        let before = heap::reset_peak();
        let read = read_cloud_bytes("wide.ply", &ply);
        let peak = heap::peak().saturating_sub(before);
        eprintln!(
            "wide.ply, {properties} properties: heap peak {peak} bytes, file {} bytes",
            ply.len()
        );
        match read {
            Ok(c) => assert!(cloud && c.format == mema::io::read::Format::PlyBinaryLittleEndian),
            Err(e) => assert!(!cloud && matches!(e, ReadError::TooLarge { .. }), "{e:?}"),
        }
        assert!(
            peak <= ply.len(),
            "wide.ply: reading peaked at {peak} heap bytes for a {} byte file",
            ply.len()
        );
    }
}

/// `file` with its header's point count (the legacy u32 of LAS 1.0-1.3) set to `points`.
fn claiming(file: &[u8], points: u32) -> Vec<u8> {
    let mut bytes = file.to_vec();
    bytes[107..111].copy_from_slice(&points.to_le_bytes());
    bytes
}

/// A binary_compressed PCD claiming 4 million points with the fewest compressed bytes LZF's
/// 88× bound allows, all of them one-byte literal runs.
fn claim_beyond_its_data() -> Vec<u8> {
    let (points, record) = (4_000_000usize, 12);
    let unpacked = points * record;
    let packed = unpacked.div_ceil(88).next_multiple_of(2);
    let header = format!(
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE I I I\nCOUNT 1 1 1\nWIDTH {points}\n\
         HEIGHT 1\nPOINTS {points}\nDATA binary_compressed\n"
    );
    let sizes = [packed as u32, unpacked as u32]
        .map(u32::to_le_bytes)
        .concat();
    [header.into_bytes(), sizes, vec![0; packed]].concat()
}
