//! docs/performance.md's account of what reading costs, from the readers' own limits: a limit
//! changed here or a figure changed there fails until the guide is written again.

use super::testkit::{guide_says, shared, thousands};
use super::{HEAD_LIMIT, UNSIZED_LIMIT, las, lzf, pcd, ply, points, stream};

#[test]
fn the_performance_guide_states_the_readers_limits() {
    guide_says(
        "docs/performance.md",
        &format!(
            "The readers stream the file through a {} KiB buffer",
            stream::BUFFER >> 10
        ),
    );
    guide_says(
        "docs/performance.md",
        &format!(
            "staged as f64 in a {}-byte layout with the alignment of `[f32; 3]`",
            size_of::<points::Wide>()
        ),
    );
    guide_says(
        "docs/performance.md",
        &format!(
            "decoded with a {} KiB sliding window (an LZF back reference reaches at most {} KiB back)",
            lzf::WINDOW >> 10,
            lzf::MAX_DISTANCE >> 10
        ),
    );
    // The decompressed size a binary_compressed PCD states after its DATA line.
    let five = shared("five_people.pcd");
    let data = b"DATA binary_compressed\n";
    let at = five
        .windows(data.len())
        .position(|w| w == data)
        .expect("a DATA line")
        + data.len();
    let unpacked = u32::from_le_bytes(five[at + 4..at + 8].try_into().unwrap());
    guide_says(
        "docs/performance.md",
        &format!(
            "neither the file nor the {:.1} MB of decompressed five_people is ever held",
            f64::from(unpacked) / 1e6
        ),
    );
    // What a compressed body of 49 MB may claim: LZF's bound on its output, within the u32
    // size the header gives it, as x, y, z f32 columns.
    let claimed =
        (49e6 * lzf::MAX_EXPANSION as f64).min(f64::from(u32::MAX)) / size_of::<[f32; 3]>() as f64;
    guide_says(
        "docs/performance.md",
        &format!(
            "reserves at most {} MiB of slots before its output arrives and makes the rest as the \
             first coordinate column is decoded (LZF's {}x bound lets 49 MB claim {:.0} million \
             points, the most a u32 size allows)",
            pcd::UPFRONT >> 20,
            lzf::MAX_EXPANSION,
            claimed / 1e6
        ),
    );
    guide_says(
        "docs/performance.md",
        &format!(
            "a PCD header keeps one line per keyword, up to {} MiB and {} fields",
            pcd::MAX_LINE >> 20,
            thousands(pcd::MAX_FIELDS as u64)
        ),
    );
    guide_says(
        "docs/performance.md",
        &format!(
            "a PLY header keeps {} bytes and the name of each property",
            size_of::<ply::Property>()
        ),
    );
    guide_says(
        "docs/performance.md",
        &format!(
            "up to {} properties, {} elements and {} KiB a line",
            thousands(ply::MAX_PROPERTIES as u64),
            thousands(ply::MAX_ELEMENTS as u64),
            ply::MAX_LINE >> 10
        ),
    );
    guide_says(
        "docs/performance.md",
        &format!(
            "in batches of at most {} MiB of records",
            las::BATCH_BYTES >> 20
        ),
    );
    guide_says(
        "docs/performance.md",
        &format!(
            "than the bytes before it hold at {} bytes a chunk",
            las::MIN_CHUNK_BYTES
        ),
    );
    guide_says(
        "docs/performance.md",
        &format!(
            "if the first starts too late for its {}-byte header",
            las::EVLR_HEADER
        ),
    );
    guide_says(
        "docs/performance.md",
        &format!(
            "format detection reads at most {} MiB, and a pipe or device at most {} GiB",
            HEAD_LIMIT >> 20,
            UNSIZED_LIMIT >> 30
        ),
    );
}
