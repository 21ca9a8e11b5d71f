//! Constants the guides state (issue 32: no guide states a K, a byte count or an instruction
//! count the code does not have): each is written in a template here, `{NAME}` standing for the
//! code's value, and the guide must say exactly what the template makes of the code. Text is
//! compared with every run of white space made one space.

use mema::io::bag::MAX_RECORD;
use mema::io::free_space::{COLUMNS, FREE_MARGIN, ROWS};
use mema::io::read::NO_RETURN_RANGE;
use mema::mapping::carve::{CARVE_MARGIN, CARVE_SIZE};
use mema::query::held_out::DEFAULT_TOLERANCE;
use mema_core::link::downlink::RING_BYTES;
use mema_core::link::receiver::{DEFAULT_REACH, WORLD_LIMIT_NM};
use mema_core::link::wire::{
    CRC_LEN, HEADER_LEN, MAX_FRAME_LEN, MAX_GAP, MAX_POINTS, MAX_RAW_LEN, MAX_UNIT_EXPONENT,
    MIN_UNIT_EXPONENT, POINT_LEN, POSE_FRAME_LEN, WIDE_POSE_FRAME_LEN,
};
use mema_core::map::free_space_part::GEOMETRY_LEN;
use mema_core::map::record::{AXIS_ALIGNED_LEN, ORIENTED_LEN, QUANTIZED_LEN};
use mema_core::map::{CRC_LEN as MAP_CRC_LEN, HEADER_LEN as MAP_HEADER_LEN, HEADER_V2_LEN};
use mema_core::stream::{MAX_SUMMARY, Pacing, SUMMARY_FACTOR};
use mema_firmware::{
    BOARD_FROZEN, BOARD_WORKING, IMAGE_BUCKETS, IMAGE_FROZEN, IMAGE_WORKING, REFIT_INTERVAL,
    TICK_POINTS,
};
use mema_firmware_sim::pacing::LINK_BYTES_PER_S;

use crate::guides::{each_says, thousands};

/// (guide, template)
const STATED: &[(&str, &str)] = &[
    (
        "PROTOCOL.md",
        "A points frame is `{POINTS_OVERHEAD} + {POINT_LEN} n` bytes, at most {MAX_RAW_LEN}; a \
         pose frame is {POSE_FRAME_LEN} bytes, a wide pose frame {WIDE_POSE_FRAME_LEN}.",
    ),
    (
        "PROTOCOL.md",
        "a frame is at most {MAX_FRAME_LEN} bytes (`MAX_FRAME_LEN`)",
    ),
    (
        "PROTOCOL.md",
        "(or a pose frame's {POSE_FRAME_LEN} bytes, a wide pose frame's {WIDE_POSE_FRAME_LEN}), a \
         count over {MAX_POINTS},",
    ),
    (
        "PROTOCOL.md",
        "a unit exponent outside **{MIN_UNIT_EXPONENT} ..= {MAX_UNIT_EXPONENT}**",
    ),
    ("PROTOCOL.md", "no delimiter within {MAX_FRAME_LEN} bytes"),
    ("PROTOCOL.md", "ahead by up to {MAX_GAP} (`MAX_GAP`)"),
    (
        "PROTOCOL.md",
        "({RING_BYTES} bytes, `mema_core::link::downlink::RING_BYTES`)",
    ),
    (
        "PROTOCOL.md",
        "({REACH_KM} km unless `--reach` says otherwise), or past ±{WORLD_KM} km in the world",
    ),
    (
        "docs/firmware.md",
        "the UART receive ring (2 × {MAX_FRAME_LEN} bytes)",
    ),
    (
        "docs/firmware.md",
        "at most {TICK_POINTS} points (`TICK_POINTS`)",
    ),
    (
        "docs/firmware.md",
        "`Firmware` with K = {IMAGE_K} ellipsoids: {IMAGE_WORKING} working clusters and \
         {IMAGE_FROZEN} frozen entities (`IMAGE_WORKING`, `IMAGE_FROZEN`), and a centre hash of \
         {IMAGE_BUCKETS} buckets (`IMAGE_BUCKETS`",
    ),
    (
        "docs/board.md",
        "has room for {BOARD_FROZEN} frozen entities: K = {BOARD_K},",
    ),
    (
        "docs/firmware.md",
        "point earns one credit, saved up to {PACING_BURST}; a freeze spends {PACING_FREEZE}, a \
         merge pass {PACING_MERGE} (`Pacing::DEVICE`,",
    ),
    (
        "docs/firmware.md",
        "a stretch of `n` points runs at most `(n + {PACING_BURST}) / {PACING_FREEZE}` freezes",
    ),
    (
        "docs/streaming.md",
        "One cluster is refitted by DE every {REFIT_INTERVAL} points",
    ),
    (
        "docs/streaming.md",
        "{SUMMARY_FACTOR} clusters an entity (at most {MAX_SUMMARY})",
    ),
    ("docs/streaming.md", "({MAX_SUMMARY} working clusters are"),
    (
        "docs/map-format.md",
        "| {MAP_COUNT_START}..{MAP_HEADER_LEN} | entity count n, u32 |",
    ),
    (
        "docs/map-format.md",
        "| {MAP_HEADER_LEN}..{HEADER_V2_LEN} | version 2 only: the quantization grid,",
    ),
    (
        "docs/map-format.md",
        "| version 1 | {AXIS_ALIGNED_LEN} | centre x, y, z",
    ),
    (
        "docs/map-format.md",
        "| version 2 | {ORIENTED_LEN} | centre (f32 x 3)",
    ),
    (
        "docs/map-format.md",
        "| version 2 quantized | {QUANTIZED_LEN} | centre (i16 x 3,",
    ),
    (
        "docs/command-line.md",
        "a `.mema` file's header and CRC: {MAP_V1_FIXED} bytes in version 1, {MAP_V2_FIXED} in \
         version 2",
    ),
    (
        "docs/command-line.md",
        "{QUANTIZED_LEN} for a quantized shell and 24 for the paper's entity",
    ),
    (
        "docs/queries.md",
        "as a version-2 `.mema` ({ORIENTED_LEN} bytes an entity, f32)",
    ),
    ("docs/board.md", "the ring's fill time ({RING_FILL_MS} ms;"),
    (
        "docs/board.md",
        "copied once into {BOARD_QUERY_COPY_KB} KB of RAM (the core's index over {BOARD_K} \
         entities would take {BOARD_INDEX_KB} KB)",
    ),
    (
        "PROTOCOL.md",
        "At 921,600 baud, 8N1 moves {LINK_BYTES_PER_S} bytes/s",
    ),
    (
        "README.md",
        "(K = {IMAGE_K}: {IMAGE_WORKING} working clusters and {IMAGE_FROZEN} frozen",
    ),
    (
        "README.md",
        "The board maps at K = {BOARD_K} ({BOARD_WORKING} working, {BOARD_FROZEN} frozen)",
    ),
    (
        "docs/ros2-bags.md",
        "(a record is at most {MAX_RECORD_GIB} GiB)",
    ),
    ("README.md", "mema needs Rust {RUST_VERSION} or later"),
    (
        "docs/queries.md",
        "(within `--min-range`, default {MIN_RANGE_CM} cm)",
    ),
    (
        "docs/queries.md",
        "within `--ray-tolerance` (default {RAY_TOLERANCE} m)",
    ),
    (
        "docs/queries.md",
        "in each of {FS_ROWS} x {FS_COLUMNS} pixels of elevation and azimuth",
    ),
    (
        "docs/queries.md",
        "({FS_IMAGE_BYTES} bytes a scan with its geometry;",
    ),
    (
        "docs/queries.md",
        "(nearer than its pixel's nearest return by {FREE_MARGIN} m)",
    ),
    (
        "docs/queries.md",
        "(nearer than their fine range images' nearest return, {CARVE_ROWS} x {CARVE_COLUMNS} \
         pixels, by {CARVE_MARGIN} m)",
    ),
];

/// The code's value of a constant, as the guides write it.
fn value(name: &str) -> String {
    let count = |n: usize| thousands(n as u64);
    match name {
        "POINTS_OVERHEAD" => count(HEADER_LEN + CRC_LEN),
        "POINT_LEN" => count(POINT_LEN),
        "MAX_RAW_LEN" => count(MAX_RAW_LEN),
        "POSE_FRAME_LEN" => count(POSE_FRAME_LEN),
        "WIDE_POSE_FRAME_LEN" => count(WIDE_POSE_FRAME_LEN),
        "MAX_FRAME_LEN" => count(MAX_FRAME_LEN),
        "MAX_POINTS" => count(MAX_POINTS),
        "MIN_UNIT_EXPONENT" => MIN_UNIT_EXPONENT.to_string(),
        "MAX_UNIT_EXPONENT" => MAX_UNIT_EXPONENT.to_string(),
        "MAX_GAP" => count(MAX_GAP as usize),
        "RING_BYTES" => count(RING_BYTES),
        "REACH_KM" => count((DEFAULT_REACH / 1000.0) as usize),
        "WORLD_KM" => count((WORLD_LIMIT_NM / 1_000_000_000_000) as usize),
        "TICK_POINTS" => count(TICK_POINTS),
        "IMAGE_K" => count(IMAGE_WORKING + IMAGE_FROZEN),
        "IMAGE_WORKING" => count(IMAGE_WORKING),
        "IMAGE_FROZEN" => count(IMAGE_FROZEN),
        "IMAGE_BUCKETS" => count(IMAGE_BUCKETS),
        "BOARD_K" => count(BOARD_WORKING + BOARD_FROZEN),
        "BOARD_WORKING" => count(BOARD_WORKING),
        "BOARD_FROZEN" => count(BOARD_FROZEN),
        "PACING_BURST" => Pacing::DEVICE.burst.to_string(),
        "PACING_FREEZE" => Pacing::DEVICE.freeze.to_string(),
        "PACING_MERGE" => Pacing::DEVICE.merge_pass.to_string(),
        "REFIT_INTERVAL" => count(REFIT_INTERVAL as usize),
        "SUMMARY_FACTOR" => count(SUMMARY_FACTOR),
        "MAX_SUMMARY" => count(MAX_SUMMARY),
        "BOARD_QUERY_COPY_KB" => {
            let k = BOARD_WORKING + BOARD_FROZEN;
            format!(
                "{:.0}",
                (k * size_of::<mema_core::Entity>()) as f64 / 1000.0
            )
        }
        "BOARD_INDEX_KB" => format!(
            "{:.0}",
            size_of::<mema_core::query::MapIndex<{ BOARD_WORKING + BOARD_FROZEN }>>() as f64
                / 1000.0
        ),
        "RING_FILL_MS" => format!("{:.1}", RING_BYTES as f64 / LINK_BYTES_PER_S * 1e3),
        "LINK_BYTES_PER_S" => count(LINK_BYTES_PER_S as usize),
        "MAP_COUNT_START" => count(MAP_HEADER_LEN - 4),
        "MAP_HEADER_LEN" => count(MAP_HEADER_LEN),
        "HEADER_V2_LEN" => count(HEADER_V2_LEN),
        "MAP_V1_FIXED" => count(MAP_HEADER_LEN + MAP_CRC_LEN),
        "MAP_V2_FIXED" => count(HEADER_V2_LEN + MAP_CRC_LEN),
        "AXIS_ALIGNED_LEN" => count(AXIS_ALIGNED_LEN),
        "ORIENTED_LEN" => count(ORIENTED_LEN),
        "QUANTIZED_LEN" => count(QUANTIZED_LEN),
        "MAX_RECORD_GIB" => count(MAX_RECORD >> 30),
        "RUST_VERSION" => env!("CARGO_PKG_RUST_VERSION").to_string(),
        "MIN_RANGE_CM" => format!("{:.0}", NO_RETURN_RANGE * 100.0),
        "RAY_TOLERANCE" => DEFAULT_TOLERANCE.to_string(),
        "FS_ROWS" => ROWS.to_string(),
        "FS_COLUMNS" => COLUMNS.to_string(),
        "FS_IMAGE_BYTES" => count(GEOMETRY_LEN + usize::from(ROWS) * usize::from(COLUMNS)),
        "FREE_MARGIN" => FREE_MARGIN.to_string(),
        "CARVE_ROWS" => CARVE_SIZE[0].to_string(),
        "CARVE_COLUMNS" => CARVE_SIZE[1].to_string(),
        "CARVE_MARGIN" => CARVE_MARGIN.to_string(),
        _ => panic!("no constant {name}"),
    }
}

#[test]
fn the_constants_the_guides_state_are_the_codes() {
    each_says(STATED, value, "the code's constants");
}
