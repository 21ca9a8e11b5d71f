//! Constants the guides state (issue 32: no guide states a K, a byte count or an instruction
//! count the code does not have): each is written in a template here, `{NAME}` standing for the
//! code's value, or `{DEFAULT command --flag}` for the default `mema command --help` gives the
//! flag, and the guide must say exactly what the template makes of the code. Text is compared
//! with every run of white space made one space.

use mema::bench::fidelity::DEFAULT_BUDGETS;
use mema::io::bag::MAX_RECORD;
use mema::io::free_space::{COLUMNS, FREE_MARGIN, ROWS};
use mema::io::input::IDLE_TIMEOUT;
use mema::io::read::classes::{HIGH_NOISE, LOW_NOISE};
use mema::io::read::outliers::{DEFAULT_NEIGHBOURS, DEFAULT_RATIO};
use mema::io::read::{NO_RETURN_RANGE, UNSIZED_LIMIT};
use mema::link::queries::RAY_REACH;
use mema::link::session::{MAX_ASKS, MAX_RESTARTS, SILENCE};
use mema::mapping::carve::{
    CARVE_COLUMN, CARVE_MARGIN, CARVE_SIZE, REST_MARGIN, REST_REACH, REST_SEEN_THROUGH,
};
use mema::mapping::surface_clusters::CANDIDATES;
use mema::query::held_out::DEFAULT_TOLERANCE;
use mema_core::free_space::NO_RETURN;
use mema_core::kmeans::BLOCK;
use mema_core::link::downlink::{MAX_MAP_ENTITIES, RING_BYTES};
use mema_core::link::receiver::SETTLED_POSES;
use mema_core::link::receiver::{DEFAULT_REACH, WORLD_LIMIT_NM};
use mema_core::link::uplink::MAX_RESEND;
use mema_core::link::wire::{
    CRC_LEN, HEADER_LEN, MAX_FRAME_LEN, MAX_GAP, MAX_POINTS, MAX_RAW_LEN, MAX_UNIT_EXPONENT,
    MIN_UNIT_EXPONENT, POINT_LEN, POSE_FRAME_LEN, WIDE_POSE_FRAME_LEN,
};
use mema_core::link::wire::{HEADER_LEN_V1, QUATERNION_ONE};
use mema_core::map::free_space_part::GEOMETRY_LEN;
use mema_core::map::record::{AXIS_ALIGNED_LEN, ORIENTED_LEN, QUANTIZED_LEN};
use mema_core::map::{CRC_LEN as MAP_CRC_LEN, HEADER_LEN as MAP_HEADER_LEN, HEADER_V2_LEN, MAGIC};
use mema_core::stream::{MAX_SUMMARY, SUMMARY_FACTOR};
use mema_firmware::{
    BOARD_FROZEN, BOARD_WORKING, IMAGE_BUCKETS, IMAGE_FROZEN, IMAGE_WORKING, REFIT_INTERVAL,
    TICK_POINTS,
};
use mema_firmware_sim::pacing::LINK_BYTES_PER_S;

use crate::guides::{cli_default, each_says, thousands, word};

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
        "a copy of the map to scan took {BOARD_QUERY_COPY_KB} KB of RAM, and the core's index \
         over {BOARD_K} entities would take {BOARD_INDEX_KB} KB)",
    ),
    (
        "PROTOCOL.md",
        "At {BAUD} baud, 8N1 moves {LINK_BYTES_PER_S} bytes/s, which is about {POINTS_PER_S} \
         points/s at about {WIRE_PER_POINT} wire bytes per point.",
    ),
    (
        "PROTOCOL.md",
        "The receiver opens the port at `--baud`, {BAUD} by default",
    ),
    (
        "PROTOCOL.md",
        "a **points frame** carries up to {MAX_POINTS} points",
    ),
    (
        "PROTOCOL.md",
        "Build the *raw frame*: a {HEADER_LEN}-byte header",
    ),
    (
        "PROTOCOL.md",
        "| u16, 0..={MAX_POINTS}; `0` in a pose frame |",
    ),
    (
        "PROTOCOL.md",
        "| i8, {MIN_UNIT_EXPONENT} ..= {MAX_UNIT_EXPONENT}. A length is",
    ),
    (
        "PROTOCOL.md",
        "| u16, 0..={MAX_POINTS} | | 8 | 1 | unit exponent e | i8, {MIN_UNIT_EXPONENT} ..= \
         {MAX_UNIT_EXPONENT} |",
    ),
    ("PROTOCOL.md", "frame has a {HEADER_LEN_V1}-byte header"),
    (
        "PROTOCOL.md",
        "It is `{V1_OVERHEAD} + {POINT_LEN} n` bytes, at most {V1_MAX_LEN}.",
    ),
    ("PROTOCOL.md", "a jump of more than {MAX_GAP} frames"),
    ("PROTOCOL.md", "a jump past {MAX_GAP}) is a"),
    (
        "PROTOCOL.md",
        "which every unit from {MIN_UNIT_EXPONENT} to {MAX_UNIT_EXPONENT} is a whole number of",
    ),
    ("PROTOCOL.md", "within ±{WORLD_KM} km"),
    ("PROTOCOL.md", "is past ±{WORLD_KM} km, or farther"),
    (
        "PROTOCOL.md",
        "(f32 resolves a millimetre within {F32_MM_KM} km of the origin)",
    ),
    (
        "PROTOCOL.md",
        "i32 millimetres span ±{I32_MM_KM} km exactly.",
    ),
    ("PROTOCOL.md", "sends `-4` (0.1 mm, ±{I32_TENTH_MM_KM} km)"),
    (
        "PROTOCOL.md",
        "Until {SETTLED_POSES} poses have agreed with the origin (`SETTLED_POSES`)",
    ),
    (
        "PROTOCOL.md",
        "the rotation as a unit quaternion x, y, z, w (scalar last) as i32 in units of \
         2^-{QUATERNION_BITS}",
    ),
    (
        "PROTOCOL.md",
        "below 2^{MAP_ENTITIES_BITS} (`MAX_MAP_ENTITIES`)",
    ),
    (
        "PROTOCOL.md",
        "| entities u32, at most 2^{MAP_ENTITIES_BITS}:",
    ),
    (
        "PROTOCOL.md",
        "has taken a tenth of its ring ({PROGRESS_EVERY} bytes)",
    ),
    (
        "PROTOCOL.md",
        "The host keeps at most the ring's {RING_BYTES} bytes beyond",
    ),
    (
        "PROTOCOL.md",
        "a count (u16, at most {MAX_RESEND}; more is read as {MAX_RESEND}).",
    ),
    ("PROTOCOL.md", "| count u16 (at most {MAX_RESEND}) |"),
    (
        "PROTOCOL.md",
        "at most {MAX_RESTARTS} times, so the map it writes",
    ),
    (
        "PROTOCOL.md",
        "once a second, at most {MAX_ASKS} times, and for the end",
    ),
    ("PROTOCOL.md", "for {SILENCE_S} seconds (`--idle-timeout`)"),
    ("PROTOCOL.md", "(a ray is followed for {RAY_KM} km)"),
    (
        "docs/board.md",
        "ends the session after `--idle-timeout` ({SILENCE_S} s by default)",
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
        "README.md",
        "and poses farther than `--reach` ({REACH_KM} km)",
    ),
    (
        "docs/command-line.md",
        "read to {UNSIZED_GIB} GiB and failing after {IDLE_TIMEOUT_S} s",
    ),
    (
        "docs/command-line.md",
        "`--threshold` (the paper's {DEFAULT map --threshold} m)",
    ),
    (
        "docs/command-line.md",
        "(the {DEFAULT map --threshold} m threshold is {DEFAULT map --threshold} mm of bunny)",
    ),
    (
        "docs/command-line.md",
        "its noise (class {LOW_NOISE}, low noise; {HIGH_NOISE}, high noise)",
    ),
    (
        "docs/command-line.md",
        "`Classification![{LOW_NOISE}:{LOW_NOISE}]` and `[{HIGH_NOISE}:{HIGH_NOISE}]`",
    ),
    (
        "docs/command-line.md",
        "point whose mean distance to its {OUTLIER_NEIGHBOURS} nearest neighbours (the statistic of \
         PCL's and Open3D's statistical outlier removal) is over {OUTLIER_RATIO} times that \
         distance's median",
    ),
    (
        "docs/command-line.md",
        "{QUANTIZED_LEN} for a quantized shell and {PAPER_RECORD} for the paper's entity (its kind \
         byte aside); `info`'s *paper bytes* counts {PAPER_RECORD} for",
    ),
    (
        "docs/command-line.md",
        "(B / {QUANTIZED_LEN} for shells, B / {AXIS_ALIGNED_LEN} for the paper's entities;",
    ),
    (
        "docs/command-line.md",
        "after up to `--surface-rounds` rounds (default {DEFAULT map --surface-rounds},",
    ),
    (
        "docs/command-line.md",
        "its {SURFACE_CANDIDATES} nearest clusters' Gaussians explains it best",
    ),
    (
        "docs/command-line.md",
        "`--samples` points (default {DEFAULT eval --samples},",
    ),
    (
        "docs/command-line.md",
        "the score with the default {DEFAULT eval --samples} samples",
    ),
    (
        "docs/command-line.md",
        "and paper bytes ({PAPER_RECORD} per entity)",
    ),
    (
        "docs/performance.md",
        "at the default {DEFAULT draw --size} iso view",
    ),
    (
        "docs/performance.md",
        "the draw walks exact block sums of {KMEANS_BLOCK} points",
    ),
    (
        "docs/pictures-meshes.md",
        "A mesh past `--max-bytes` (default {MAX_BYTES_GIB} GiB, {DEFAULT export --max-bytes} \
         bytes)",
    ),
    ("docs/fidelity.md", "(default {FIDELITY_BUDGETS} bytes)"),
    (
        "docs/queries.md",
        "A point is then **occupied** within `--tolerance` (default {DEFAULT query --tolerance} m)",
    ),
    (
        "docs/fidelity.md",
        "Up to {DEFAULT map --surface-rounds} rounds of classification EM (each point moves to \
         whichever of its {SURFACE_CANDIDATES} nearest clusters' Gaussians explains it best:",
    ),
    ("docs/fidelity.md", "**B = {FIDELITY_BUDGET_1} bytes**"),
    ("docs/fidelity.md", "**B = {FIDELITY_BUDGET_0} bytes**"),
    ("docs/fidelity.md", "**B = {FIDELITY_BUDGET_2} bytes**"),
    (
        "docs/fidelity.md",
        "shells, K = B / {QUANTIZED_LEN} entities of {QUANTIZED_LEN} bytes; at most \
         {STREAM_MAX_CLUSTERS} entities, the host stream's bound, so at {FIDELITY_BUDGET_2} bytes",
    ),
    (
        "docs/map-format.md",
        "| 0..{MAGIC_END} | magic `MEMA` | | {MAGIC_END}..{VERSION_END} | version, u16: 1 or 2 | \
         | {VERSION_END}..{FLAGS_END} | flags, u16:",
    ),
    (
        "docs/map-format.md",
        "| {FLAGS_END}..{MAP_COUNT_START} | origin x, y, z as f64",
    ),
    (
        "docs/map-format.md",
        "| last {MAP_CRC_LEN} | CRC-32 (IEEE, as zip/PNG) of every byte before it |",
    ),
    (
        "docs/map-format.md",
        "row by row from the lowest elevation; {NO_RETURN} where no return fell,",
    ),
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
        "(nearer than their fine range images' nearest return, {CARVE_ROWS} rows and at most \
         {CARVE_COLUMNS} columns, none narrower than {CARVE_DEGREES} degrees, by {CARVE_MARGIN} m)",
    ),
    (
        "docs/queries.md",
        "each scan is held until {LAG_AFTER} more have arrived, judged by them and the {LAG_BEFORE} \
         before it,",
    ),
    (
        "docs/queries.md",
        "the map stays {LAG_AFTER} scans behind the sensor, and holds those scans' points (at most \
         {LAG_MOST_HELD} a scan;",
    ),
    (
        "docs/queries.md",
        "point within {REST_REACH} m of a carved point of its own scan goes when {REST_SCANS} other \
         scan saw through it by {REST_MARGIN} m, in its own pixel.",
    ),
    (
        "docs/performance.md",
        "Passes over the points run on rayon in fixed chunks of {ASSIGN_CHUNK},",
    ),
    (
        "docs/streaming.md",
        "free up to K/{MAX_MERGE_BATCH} slots at once",
    ),
    (
        "docs/streaming.md",
        "(plus {PLANAR_WARD_PERCENT} % of Ward's cost)",
    ),
    (
        "docs/tolerance.md",
        "Each cluster tries its {MERGE_NEIGHBOURS} nearest neighbours",
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
        "UNSIZED_GIB" => count((UNSIZED_LIMIT >> 30) as usize),
        "IDLE_TIMEOUT_S" => IDLE_TIMEOUT.as_secs().to_string(),
        "LOW_NOISE" => LOW_NOISE.to_string(),
        "HIGH_NOISE" => HIGH_NOISE.to_string(),
        "OUTLIER_NEIGHBOURS" => DEFAULT_NEIGHBOURS.to_string(),
        "OUTLIER_RATIO" => DEFAULT_RATIO.to_string(),
        // Centre and weights: a version-1 record less its kind byte.
        "PAPER_RECORD" => count(AXIS_ALIGNED_LEN - 1),
        "SURFACE_CANDIDATES" => CANDIDATES.to_string(),
        "KMEANS_BLOCK" => count(BLOCK),
        "MAX_BYTES_GIB" => {
            let bytes: u64 = cli_default("export", "--max-bytes")
                .replace(',', "")
                .parse()
                .expect("bytes");
            count((bytes >> 30) as usize)
        }
        "FIDELITY_BUDGET_0" => count(DEFAULT_BUDGETS[0]),
        "FIDELITY_BUDGET_1" => count(DEFAULT_BUDGETS[1]),
        "FIDELITY_BUDGET_2" => count(DEFAULT_BUDGETS[2]),
        "STREAM_MAX_CLUSTERS" => count(mema::link::stream::MAX_CLUSTERS),
        // The header's fields in order: magic, version u16, flags u16, origin 3 x f64, count.
        "MAGIC_END" => count(MAGIC.len()),
        "VERSION_END" => count(MAGIC.len() + 2),
        "FLAGS_END" => count(MAGIC.len() + 4),
        "MAP_CRC_LEN" => count(MAP_CRC_LEN),
        "NO_RETURN" => NO_RETURN.to_string(),
        "FIDELITY_BUDGETS" => {
            let b = DEFAULT_BUDGETS.map(count);
            format!("{}, {} and {}", b[0], b[1], b[2])
        }
        _ if name.starts_with("DEFAULT ") => {
            let (command, flag) = name["DEFAULT ".len()..]
                .split_once(' ')
                .expect("command flag");
            cli_default(command, flag)
        }
        // 8N1: ten bits on the line a byte.
        "BAUD" => count((LINK_BYTES_PER_S * 10.0) as usize),
        // Full frames: the most points in the fewest wire bytes.
        "WIRE_PER_POINT" => format!("{:.1}", MAX_FRAME_LEN as f64 / MAX_POINTS as f64),
        "POINTS_PER_S" => count(
            ((LINK_BYTES_PER_S * MAX_POINTS as f64 / MAX_FRAME_LEN as f64) / 50.0).round() as usize
                * 50,
        ),
        "HEADER_LEN" => count(HEADER_LEN),
        "HEADER_LEN_V1" => count(HEADER_LEN_V1),
        "V1_OVERHEAD" => count(HEADER_LEN_V1 + CRC_LEN),
        "V1_MAX_LEN" => count(HEADER_LEN_V1 + POINT_LEN * MAX_POINTS + CRC_LEN),
        // f32's 24-bit significand: a millimetre step up to 2^24 mm.
        "F32_MM_KM" => format!(
            "{:.0}",
            ((1u64 << f32::MANTISSA_DIGITS) as f64 / 1e6).floor()
        ),
        "I32_MM_KM" => count((i32::MAX as f64 / 1e6) as usize),
        "I32_TENTH_MM_KM" => count((i32::MAX as f64 / 1e7) as usize),
        "SETTLED_POSES" => SETTLED_POSES.to_string(),
        "QUATERNION_BITS" => QUATERNION_ONE.trailing_zeros().to_string(),
        "MAP_ENTITIES_BITS" => MAX_MAP_ENTITIES.trailing_zeros().to_string(),
        // The firmware's `PROGRESS_EVERY` (private): a tenth of the receive ring.
        "PROGRESS_EVERY" => count(RING_BYTES / 10),
        "MAX_RESEND" => MAX_RESEND.to_string(),
        "MAX_RESTARTS" => MAX_RESTARTS.to_string(),
        "MAX_ASKS" => MAX_ASKS.to_string(),
        "SILENCE_S" => SILENCE.as_secs().to_string(),
        "RAY_KM" => format!("{:.0}", RAY_REACH / 1e3),
        "MIN_RANGE_CM" => format!("{:.0}", NO_RETURN_RANGE * 100.0),
        "RAY_TOLERANCE" => DEFAULT_TOLERANCE.to_string(),
        "FS_ROWS" => ROWS.to_string(),
        "FS_COLUMNS" => COLUMNS.to_string(),
        "FS_IMAGE_BYTES" => count(GEOMETRY_LEN + usize::from(ROWS) * usize::from(COLUMNS)),
        "FREE_MARGIN" => FREE_MARGIN.to_string(),
        "CARVE_ROWS" => CARVE_SIZE[0].to_string(),
        "CARVE_COLUMNS" => CARVE_SIZE[1].to_string(),
        "CARVE_MARGIN" => CARVE_MARGIN.to_string(),
        "REST_REACH" => REST_REACH.to_string(),
        "REST_MARGIN" => REST_MARGIN.to_string(),
        "REST_SCANS" => word(REST_SEEN_THROUGH),
        "LAG_AFTER" => word(mema::link::lag::AFTER),
        "LAG_BEFORE" => word(mema::link::lag::BEFORE),
        "LAG_MOST_HELD" => count(mema::link::lag::MOST_HELD),
        "ASSIGN_CHUNK" => count(mema::mapping::pipeline::ASSIGN_CHUNK),
        "MAX_MERGE_BATCH" => mema_core::stream::MAX_MERGE_BATCH.to_string(),
        "PLANAR_WARD_PERCENT" => (f64::from(mema_core::stream::PLANAR_WARD) * 100.0)
            .round()
            .to_string(),
        "MERGE_NEIGHBOURS" => mema::mapping::tolerance::MERGE_NEIGHBOURS.to_string(),
        "CARVE_DEGREES" => format!("{:.3}", CARVE_COLUMN.to_degrees()),
        _ => panic!("no constant {name}"),
    }
}

#[test]
fn the_constants_the_guides_state_are_the_codes() {
    each_says(STATED, value, "the code's constants");
}
