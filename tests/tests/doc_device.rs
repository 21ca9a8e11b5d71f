//! The layouts, budgets, clocks and defaults the firmware, board, streaming and design guides
//! state (issue 32: no guide states a K, a byte count or an instruction count the code does not
//! have), as doc_constants.rs holds the link's and the map file's: each is written in a template
//! here, `{NAME}` standing for the code's value. And every `K = N`, `N working` and `N frozen` in
//! the guides is one of the code's layouts.

use mema::analysis::stats::{CLOUD_BYTES_PER_POINT, MAP_BYTES_PER_ENTITY};
use mema::bench::gmm::{BYTES_PER_COMPONENT, SIGMAS};
use mema::link::stream::GRID_BUCKETS;
use mema::render::camera::{DENSE_TAIL, STRAY_SPAN};
use mema_core::de::{DeParams, PAPER_POPULATION};
use mema_core::fitness::PAPER_ALPHA;
use mema_core::kmeans::KMeansParams;
use mema_core::link::receiver::DEFAULT_REACH;
use mema_core::link::wire::{MAX_POINTS, MAX_UNIT_EXPONENT, MIN_UNIT_EXPONENT, QUATERNION_ONE};
use mema_core::map::record::{AXIS_ALIGNED_LEN, ORIENTED_LEN, QUANTIZED_LEN};
use mema_core::moments::fixed::OFFSET_LIMIT;
use mema_core::shell::ShellParams;
use mema_core::stream::freeze::IDLE_TURNOVERS;
use mema_core::stream::{MAX_SUMMARY, MOST_MEASURED, MOST_RANKED, Pacing, SUMMARY_FACTOR};
use mema_firmware::{
    BOARD_CARVE_EVERY, BOARD_CARVE_IMAGE, BOARD_FROZEN, BOARD_WORKING, IMAGE_BUCKETS, IMAGE_FROZEN,
    IMAGE_WORKING,
};
use mema_firmware::{REFIT_INTERVAL, TICK_POINTS};
use mema_firmware_sim::board::TARGET_BOARD;
use mema_firmware_sim::budget::{BOARD_FLASH, BOARD_SRAM};
use mema_firmware_sim::compare::{
    FITNESS_ABSOLUTE_FLOOR, FITNESS_TOLERANCE, MIN_POINTS, SEMI_AXES_TOLERANCE,
};
use mema_firmware_sim::harness::RunConfig;
use mema_firmware_sim::pacing::{CPU_HZ, LINK_BYTES_PER_S};

use crate::guides::{documents, each_says, repository, thousands};

/// (guide, template)
const STATED: &[(&str, &str)] = &[
    ("README.md", "and on a {IMAGE_RAM_KIB} KiB Cortex-M4F"),
    ("README.md", "stored in {QUANTIZED_LEN} bytes, after the"),
    (
        "README.md",
        "{IMAGE_FROZEN} frozen entities, in {IMAGE_RAM_KIB} KiB) runs under QEMU",
    ),
    (
        "README.md",
        "where a cloud's map fills K = {IMAGE_K}, closer to the points than at {IMAGE_K}",
    ),
    ("README.md", "RX, {BAUD} baud) through a"),
    (
        "docs/firmware.md",
        "Every {SNAPSHOT_EVERY} accepted frames by default.",
    ),
    (
        "docs/firmware.md",
        "a whole {IMAGE_K}-entity map would be {IMAGE_MAP_KB} KB of RAM",
    ),
    (
        "docs/firmware.md",
        "so agreement there is checked to {FITNESS_FLOOR} absolute. - A cluster of fewer than \
         {MIN_POINTS} points does not determine its ellipsoid.",
    ),
    (
        "docs/firmware.md",
        "compared only on clusters of {MIN_POINTS} or more points (the column \"under \
         {MIN_POINTS} points\" counts the others).",
    ),
    (
        "docs/firmware.md",
        "then differ by more than {SEMI_AXES_TOLERANCE}.",
    ),
    (
        "docs/firmware.md",
        "within {FITNESS_TOLERANCE} of the reference's optimum",
    ),
    (
        "docs/firmware.md",
        "The image is the row K = {IMAGE_K}, {IMAGE_WORKING} working and {IMAGE_FROZEN} frozen; \
         the board the row K = {BOARD_K}. The image's stack needs less than {STACK_KIB} KiB \
         (its high-water mark is below), so it fits {IMAGE_RAM_KIB} KiB.",
    ),
    (
        "docs/firmware.md",
        "the centre hash has {IMAGE_BUCKETS} buckets:",
    ),
    (
        "docs/firmware.md",
        "Parts with {IMAGE_RAM_KIB} KiB of RAM carry 128 KiB of flash or more (the STM32F405 \
         {BOARD_FLASH_MIB} MiB).",
    ),
    (
        "docs/firmware.md",
        "**K = {IMAGE_K} in under {IMAGE_RAM_KIB} KiB**",
    ),
    (
        "docs/firmware.md",
        "K = {BOARD_K}), likewise, of its {BOARD_FLASH_MIB} MiB of flash and {BOARD_SRAM_KIB} KiB",
    ),
    (
        "docs/firmware.md",
        "Per ingested point at K = {IMAGE_K} ({IMAGE_WORKING} + {IMAGE_FROZEN});",
    ),
    (
        "docs/firmware.md",
        "a table of the {DE_TRIPLES} ordered triples",
    ),
    ("docs/firmware.md", "plus 1/{REFIT_INTERVAL} of a refit."),
    (
        "docs/firmware.md",
        "asserts no byte lost at {M4F_MIPS} M instructions/s ({CPU_MHZ} MHz at 1.5 cycles an \
         instruction)",
    ),
    (
        "docs/firmware.md",
        "With every cluster working, K = {IMAGE_K} needs the budget's second row, and far fewer \
         clusters than {IMAGE_K} fit in {IMAGE_RAM_KIB} KiB beside an {STACK_KIB} KiB stack",
    ),
    (
        "docs/firmware.md",
        "At f64 that is {F64_SUMS_BYTES} bytes, and {IMAGE_K} of them are {F64_SUMS_KIB} KiB",
    ),
    (
        "docs/firmware.md",
        "Narrower sums lose the {FITNESS_TOLERANCE} agreement",
    ),
    (
        "docs/firmware.md",
        "longest, points only (at most {TICK_POINTS})",
    ),
    (
        "docs/board.md",
        "is the same `Firmware` as the {IMAGE_RAM_KIB} KiB image's",
    ),
    ("docs/board.md", "PA10 RX, {BAUD} baud 8N1)"),
    ("docs/board.md", "A sensor at {BAUD} baud keeps"),
    (
        "docs/board.md",
        "stays within the part's {BOARD_SRAM_KIB} KiB of SRAM",
    ),
    (
        "docs/board.md",
        "The {IMAGE_RAM_KIB} KiB image keeps K = {IMAGE_K}.",
    ),
    (
        "docs/board.md",
        "Where a cloud's map fills K = {IMAGE_K}, K = {BOARD_K} lowers the Chamfer distance",
    ),
    (
        "docs/board.md",
        "take at {CPU_MHZ} MHz and 1.5 cycles an instruction:",
    ),
    (
        "docs/board.md",
        "K = {BOARD_K} also freezes more entities than K = {IMAGE_K}",
    ),
    ("docs/board.md", "fill time at {BAUD} baud"),
    ("docs/board.md", "so the USART runs at {BAUD} either way."),
    (
        "docs/firmware.md",
        "point earns one credit, saved up to {PACING_BURST}; a freeze spends {PACING_FREEZE}, a \
         merge pass {PACING_MERGE} (`Pacing::DEVICE`,",
    ),
    (
        "docs/firmware.md",
        "a shell's freeze, which costs the image half the paper's fit, spends \
         {PACING_SHELLS_FREEZE} and a merge pass among shells {PACING_SHELLS_MERGE} \
         (`Pacing::DEVICE_SHELLS`;",
    ),
    (
        "docs/firmware.md",
        "a stretch of `n` points runs at most `(n + {PACING_BURST}) / {PACING_FREEZE}` freezes of \
         the paper's fits",
    ),
    (
        "docs/firmware.md",
        "when it must scan for pairs (a sort of the store, at most {MOST_MEASURED} distances \
         measured and {MOST_RANKED} pairs in reach ranked) {PACING_SHELLS_SCAN} credits more: the scan \
         with its two fits, {PACING_SCAN_STEP} credits, is the dearest step",
    ),
    (
        "docs/design.md",
        "a scan ranks at most {MOST_RANKED} pairs (`MOST_RANKED`)",
    ),
    (
        "docs/design.md",
        "(the scan and its two fits {PACING_SCAN_STEP} credits together, a burst of {PACING_BURST})",
    ),
    (
        "docs/streaming.md",
        "its distances (at most {MOST_MEASURED}) are the pairs that could be within reach wherever \
         in the store they lie, and it lists the cheapest {LISTED};",
    ),
    (
        "docs/streaming.md",
        "each point earns a credit, a freeze costs {PACING_FREEZE}, a shell's \
         {PACING_SHELLS_FREEZE} (twice that when it coarsens, and {PACING_SHELLS_SCAN} more when \
         it must also scan for a pair) and a merge pass {PACING_MERGE} ({PACING_SHELLS_MERGE} \
         among shells)",
    ),
    (
        "docs/streaming.md",
        "provided no point has joined it for {IDLE_TURNOVERS} turnovers of the working set \
         ({IDLE_TURNOVERS} W points)",
    ),
    (
        "docs/streaming.md",
        "(principal axes; {TANGENT_SCALE}, {TANGENT_SCALE} and {NORMAL_SCALE} standard \
         deviations;",
    ),
    (
        "docs/streaming.md",
        "(version 2, {QUANTIZED_LEN} bytes an entity)",
    ),
    (
        "docs/streaming.md",
        "is written in f32 ({ORIENTED_LEN} bytes an entity) instead",
    ),
    (
        "docs/streaming.md",
        "therefore cannot keep {IMAGE_K} of them.",
    ),
    (
        "docs/streaming.md",
        "centre and weights (the paper's {PAPER_RECORD} bytes)",
    ),
    (
        "docs/streaming.md",
        "shells cost no DE and store {QUANTIZED_LEN} bytes an entity instead of {AXIS_ALIGNED_LEN}",
    ),
    (
        "docs/streaming.md",
        "({MAX_SUMMARY} working clusters are {SUMMARY_MB} MB)",
    ),
    (
        "docs/design.md",
        "({MAX_SUMMARY} working clusters are {SUMMARY_MB} MB)",
    ),
    (
        "docs/design.md",
        "The stream therefore keeps {SUMMARY_FACTOR} clusters an entity",
    ),
    (
        "docs/design.md",
        "(up to 2^{OFFSET_BITS} steps, as fine as f32 holds the offset itself)",
    ),
    (
        "docs/design.md",
        "**DE/rand/1/bin**: F = {DE_F}, CR = {DE_CR} and {DE_GENERATIONS} generations by default.",
    ),
    ("docs/design.md", "The iteration cap is {KMEANS_CAP}."),
    (
        "docs/board.md",
        "Here the PLL is set for {CPU_MHZ} MHz from the internal oscillator and its lock is polled \
         a bounded number of times; on silicon it locks and the part runs at {CPU_MHZ} MHz (APB2 \
         at {APB2_MHZ} MHz)",
    ),
    ("README.md", "one copy for the {IMAGE_RAM_KIB} KiB image"),
    (
        "docs/streaming.md",
        "COBS-framed frames of up to {MAX_POINTS} points",
    ),
    (
        "docs/streaming.md",
        "refuses unit exponents outside {MIN_UNIT_EXPONENT}..={MAX_UNIT_EXPONENT},",
    ),
    (
        "docs/streaming.md",
        "Points and poses farther than `--reach` ({REACH_KM} km) from the origin",
    ),
    (
        "docs/streaming.md",
        "units of 2^-{QUATERNION_BITS}. The points frames after it name that pose",
    ),
    (
        "docs/streaming.md",
        "(so its grid is the map's own extent over {I16_MAX},",
    ),
    (
        "docs/firmware.md",
        "the host maps to the same bytes with {HOST_BUCKETS})",
    ),
    (
        "docs/testing.md",
        "in both models, under {CHECK_PER_POINT} instructions a point, and answers {CHECK_QUERIES} \
         queries on car6 as the host does",
    ),
    (
        "docs/board.md",
        "`firmware-sim/check.sh` holds the board under {CHECK_PER_POINT} instructions a point",
    ),
    (
        "docs/board.md",
        "and check.sh asserts only that each is under {CHECK_PER_POINT}:",
    ),
    ("docs/board.md", "`check.sh` asks {CHECK_QUERIES} on car6"),
    (
        "docs/fidelity.md",
        "oriented shells of surface-following clusters, {QUANTIZED_LEN} bytes an entity); - the \
         paper's map (`--bytes B --paper`: axis-aligned DE fits of eq. 12, {AXIS_ALIGNED_LEN} \
         bytes an entity);",
    ),
    (
        "docs/fidelity.md",
        "B / {GMM_BYTES} components at {GMM_BYTES} bytes each, drawn as {GMM_SIGMAS}-sigma shells",
    ),
    (
        "docs/fidelity.md",
        "A shell lies along its patch of surface, {TANGENT_SCALE} standard deviations across it \
         and {NORMAL_SCALE} through it",
    ),
    (
        "docs/fidelity.md",
        "The quantized record is {QUANTIZED_LEN} bytes against the paper's {AXIS_ALIGNED_LEN} and \
         the GMM's {GMM_BYTES}, so a budget buys {PAPER_RATIO} times the paper's entities and \
         {GMM_RATIO} times the GMM's components.",
    ),
    (
        "docs/fidelity.md",
        "Defaults apply: seed {KMEANS_SEED}, alpha {ALPHA}, threshold {THRESHOLD}, DE with F \
         {DE_F}, CR {DE_CR}, population {DE_POPULATION} and {DE_GENERATIONS} generations.",
    ),
    (
        "docs/fidelity.md",
        "Table 2 (memory; {CLOUD_POINT_BYTES} bytes per point, {MAP_ENTITY_BYTES} bytes per entity \
         as in the paper):",
    ),
    (
        "docs/pictures-meshes.md",
        "from the {DENSE_LOW} % quantile to the {DENSE_HIGH} %, widened by a twentieth, in place \
         of the whole range where that is over {STRAY_SPAN} times wider.",
    ),
    (
        "docs/performance.md",
        "A fit ({DE_GENERATIONS} generations, population {DE_POPULATION}, {DE_EVALUATIONS} \
         evaluations)",
    ),
    (
        "docs/performance.md",
        "(population {DE_POPULATION}, {DE_GENERATIONS} generations, F {DE_F}, CR {DE_CR},",
    ),
    (
        "docs/design.md",
        "is at most {KMEANS_TOLERANCE} times the mean per-axis variance.",
    ),
    (
        "docs/queries.md",
        "with images of {CARVE_ROWS} x {CARVE_COLUMNS} pixels ({CARVE_ROW_DEGREES} by \
         {CARVE_COLUMN_DEGREES} degrees) that take every other return of a scan, and judges an \
         ended scan {JUDGED_PER_TICK} clusters a tick; its map is `mema replay -k {BOARD_K} \
         --working {BOARD_WORKING} --carve {CARVE_ROWS}x{CARVE_COLUMNS} --carve-every \
         {CARVE_EVERY}`'s,",
    ),
    (
        "docs/queries.md",
        "400 instructions a point, over the board's {CHECK_PER_POINT};",
    ),
];

/// The code's value of a constant, as the guides write it.
fn value(name: &str) -> String {
    let count = |n: usize| thousands(n as u64);
    let de = DeParams::default();
    match name {
        "IMAGE_K" => count(IMAGE_WORKING + IMAGE_FROZEN),
        "IMAGE_WORKING" => count(IMAGE_WORKING),
        "IMAGE_FROZEN" => count(IMAGE_FROZEN),
        "IMAGE_BUCKETS" => count(IMAGE_BUCKETS),
        "BOARD_K" => count(BOARD_WORKING + BOARD_FROZEN),
        "BOARD_WORKING" => count(BOARD_WORKING),
        "CARVE_ROWS" => BOARD_CARVE_IMAGE[0].to_string(),
        "CARVE_COLUMNS" => BOARD_CARVE_IMAGE[1].to_string(),
        "CARVE_ROW_DEGREES" => format!("{:.2}", 180.0 / f64::from(BOARD_CARVE_IMAGE[0])),
        "CARVE_COLUMN_DEGREES" => format!("{:.2}", 360.0 / f64::from(BOARD_CARVE_IMAGE[1])),
        "CARVE_EVERY" => BOARD_CARVE_EVERY.to_string(),
        "JUDGED_PER_TICK" => mema_firmware::carving::JUDGED_PER_TICK.to_string(),
        "IMAGE_RAM_KIB" => count(TARGET_BOARD.ram_bytes >> 10),
        "STACK_KIB" => count(TARGET_BOARD.stack_bytes >> 10),
        "BOARD_FLASH_MIB" => count((BOARD_FLASH >> 20) as usize),
        "BOARD_SRAM_KIB" => count((BOARD_SRAM >> 10) as usize),
        // 8N1: ten bits on the line a byte.
        "BAUD" => count((LINK_BYTES_PER_S * 10.0) as usize),
        "CPU_MHZ" => format!("{:.0}", CPU_HZ / 1e6),
        // APB2 at half the core clock, its most on the STM32F405.
        "APB2_MHZ" => format!("{:.0}", CPU_HZ / 2e6),
        "M4F_MIPS" => format!("{:.0}", CPU_HZ / 1.5 / 1e6),
        "QUANTIZED_LEN" => count(QUANTIZED_LEN),
        "ORIENTED_LEN" => count(ORIENTED_LEN),
        "AXIS_ALIGNED_LEN" => count(AXIS_ALIGNED_LEN),
        // Centre and weights, the kind byte aside.
        "PAPER_RECORD" => count(AXIS_ALIGNED_LEN - 1),
        "IMAGE_MAP_KB" => format!(
            "{:.0}",
            ((IMAGE_WORKING + IMAGE_FROZEN) * AXIS_ALIGNED_LEN) as f64 / 1e3
        ),
        "SNAPSHOT_EVERY" => RunConfig::default().snapshot_every.to_string(),
        "FITNESS_FLOOR" => format!("{FITNESS_ABSOLUTE_FLOOR:e}"),
        "FITNESS_TOLERANCE" => format!("{FITNESS_TOLERANCE:e}"),
        "SEMI_AXES_TOLERANCE" => format!("{SEMI_AXES_TOLERANCE:e}"),
        "MIN_POINTS" => count(MIN_POINTS),
        // Donors r1, r2, r3: three distinct members besides the target.
        "DE_TRIPLES" => {
            count((PAPER_POPULATION - 1) * (PAPER_POPULATION - 2) * (PAPER_POPULATION - 3))
        }
        "REFIT_INTERVAL" => count(REFIT_INTERVAL as usize),
        "TICK_POINTS" => count(TICK_POINTS),
        // Eq. 12's moments: 24 sums of f64 a cluster.
        "F64_SUMS_BYTES" => count(24 * size_of::<f64>()),
        "F64_SUMS_KIB" => format!(
            "{:.1}",
            ((IMAGE_WORKING + IMAGE_FROZEN) * 24 * size_of::<f64>()) as f64 / 1024.0
        ),
        "PACING_FREEZE" => Pacing::DEVICE.freeze.to_string(),
        "PACING_SCAN_STEP" => {
            let shells = Pacing::DEVICE_SHELLS;
            (shells.scan + 2 * shells.freeze).to_string()
        }
        "PACING_BURST" => Pacing::DEVICE.burst.to_string(),
        "MOST_RANKED" => count(MOST_RANKED),
        "MOST_MEASURED" => count(MOST_MEASURED),
        "LISTED" => mema_core::stream::coarsen::LISTED.to_string(),
        "PACING_SHELLS_FREEZE" => Pacing::DEVICE_SHELLS.freeze.to_string(),
        "PACING_SHELLS_SCAN" => Pacing::DEVICE_SHELLS.scan.to_string(),
        "PACING_MERGE" => Pacing::DEVICE.merge_pass.to_string(),
        "PACING_SHELLS_MERGE" => Pacing::DEVICE_SHELLS.merge_pass.to_string(),
        "IDLE_TURNOVERS" => IDLE_TURNOVERS.to_string(),
        "TANGENT_SCALE" => format!("{:.1}", ShellParams::DEFAULT.tangent_scale),
        "NORMAL_SCALE" => format!("{:.1}", ShellParams::DEFAULT.normal_scale),
        "MAX_SUMMARY" => count(MAX_SUMMARY),
        "SUMMARY_FACTOR" => count(SUMMARY_FACTOR),
        "SUMMARY_MB" => format!(
            "{:.1}",
            (MAX_SUMMARY * size_of::<mema_core::stream::StreamCluster>()) as f64 / 1e6
        ),
        "OFFSET_BITS" => OFFSET_LIMIT.trailing_zeros().to_string(),
        "DE_F" => de.mutation.to_string(),
        "DE_CR" => de.crossover.to_string(),
        "DE_GENERATIONS" => de.generations.to_string(),
        "DE_POPULATION" => PAPER_POPULATION.to_string(),
        "MAX_POINTS" => count(MAX_POINTS),
        "MIN_UNIT_EXPONENT" => MIN_UNIT_EXPONENT.to_string(),
        "MAX_UNIT_EXPONENT" => MAX_UNIT_EXPONENT.to_string(),
        "REACH_KM" => count((DEFAULT_REACH / 1000.0) as usize),
        "QUATERNION_BITS" => QUATERNION_ONE.trailing_zeros().to_string(),
        "I16_MAX" => count(i16::MAX as usize),
        "HOST_BUCKETS" => count(GRID_BUCKETS),
        "CHECK_PER_POINT" => thousands(check_sh("p < ").parse().expect("a bound")),
        "CHECK_QUERIES" => check_sh("queries="),
        "GMM_BYTES" => BYTES_PER_COMPONENT.to_string(),
        "GMM_SIGMAS" => format!("{SIGMAS}"),
        "PAPER_RATIO" => format!("{:.1}", AXIS_ALIGNED_LEN as f64 / QUANTIZED_LEN as f64),
        "GMM_RATIO" => format!("{:.1}", BYTES_PER_COMPONENT as f64 / QUANTIZED_LEN as f64),
        "KMEANS_SEED" => KMeansParams::default().seed.to_string(),
        "ALPHA" => PAPER_ALPHA.to_string(),
        "THRESHOLD" => mema_core::Degeneration::default().threshold.to_string(),
        "CLOUD_POINT_BYTES" => CLOUD_BYTES_PER_POINT.to_string(),
        "MAP_ENTITY_BYTES" => MAP_BYTES_PER_ENTITY.to_string(),
        "DENSE_LOW" => format!("{}", DENSE_TAIL * 100.0),
        "DENSE_HIGH" => format!("{}", (1.0 - DENSE_TAIL) * 100.0),
        "STRAY_SPAN" => STRAY_SPAN.to_string(),
        // The first population, then one trial a member each generation.
        "DE_EVALUATIONS" => (PAPER_POPULATION * (1 + de.generations as usize)).to_string(),
        "KMEANS_CAP" => KMeansParams::default().max_iterations.to_string(),
        "KMEANS_TOLERANCE" => format!("{:e}", KMeansParams::default().tolerance),
        _ => panic!("no constant {name}"),
    }
}

/// The number after the last `key` in `firmware-sim/check.sh`, the board's bounds living there
/// (`p < 10000`: instructions a point; `queries=32`).
fn check_sh(key: &str) -> String {
    let script =
        std::fs::read_to_string(repository().join("firmware-sim/check.sh")).expect("check.sh");
    let at = script
        .rfind(key)
        .unwrap_or_else(|| panic!("check.sh: no `{key}`"))
        + key.len();
    script[at..]
        .chars()
        .take_while(char::is_ascii_digit)
        .collect()
}

#[test]
fn the_layouts_budgets_and_defaults_the_guides_state_are_the_codes() {
    each_says(STATED, value, "the code's constants");
}

/// A layout a guide names, `K = N`, `N working` or `N frozen`, outside the result blocks (which
/// results.rs holds): each is one the code has.
#[test]
fn every_k_the_guides_state_is_a_layout_of_the_code() {
    let ks = [IMAGE_WORKING + IMAGE_FROZEN, BOARD_WORKING + BOARD_FROZEN];
    // And the fuzz seeds' tiny device, 12 working and 4 frozen (`SEED_WORKING`, `SEED_FROZEN`,
    // private to mema_firmware_sim::fuzz_checks).
    let working = [IMAGE_WORKING, BOARD_WORKING, MAX_SUMMARY, 12];
    let frozen = [IMAGE_FROZEN, BOARD_FROZEN, 4];
    let mut seen = 0;
    for (file, text) in documents() {
        // The text outside result blocks, as words: a layout may break across lines.
        let mut in_block = false;
        let mut words = Vec::new();
        for line in text.lines() {
            match line.trim() {
                l if l.starts_with("<!-- result ") => in_block = true,
                "<!-- /result -->" => in_block = false,
                _ if !in_block => words.extend(line.split_whitespace()),
                _ => {}
            }
        }
        for (i, w) in words.iter().enumerate() {
            let (allowed, what): (&[usize], &str) = if i >= 2 && words[i - 2..i] == ["K", "="] {
                (&ks, "K")
            } else if words.get(i + 1).is_some_and(|n| n.starts_with("working")) {
                (&working, "working")
            } else if words.get(i + 1).is_some_and(|n| n.starts_with("frozen")) {
                (&frozen, "frozen")
            } else {
                continue;
            };
            let digits = w
                .trim_matches(|c: char| !c.is_ascii_digit())
                .replace(',', "");
            let Ok(k) = digits.parse::<usize>() else {
                continue;
            };
            let context = words[i.saturating_sub(6)..(i + 3).min(words.len())].join(" ");
            assert!(
                allowed.contains(&k),
                "{file}: `{context}`: {what} {k}, which no layout of the code has ({allowed:?})"
            );
            seen += 1;
        }
    }
    assert!(seen >= 30, "{seen} layouts named");
}

/// check.sh replays the board's map carving as the board carves (its images and sampling).
#[test]
fn check_sh_replays_the_board_as_it_carves() {
    let script =
        std::fs::read_to_string(repository().join("firmware-sim/check.sh")).expect("check.sh");
    let [rows, columns] = BOARD_CARVE_IMAGE;
    let flags = format!("--carve {rows}x{columns} --carve-every {BOARD_CARVE_EVERY}");
    assert!(
        script.contains(&flags),
        "check.sh does not replay with {flags}"
    );
}
