//! The figures the guides quote in prose (issue 32): each is written in a template here, with
//! the cell of docs/results.md it comes from, and the guide must say exactly what the template
//! makes of today's results file. A figure changed in a guide, or a results file regenerated with
//! a new one, fails here until the two agree again.
//!
//! A placeholder is `{block|row|column}`: the block, the row whose first cell is `row`
//! (backticks aside), and the column counted from 1; `row` may be `a+b+c`, the sum of those
//! rows' counts, and a fourth field `|n` takes the n-th (from 1) of a cell's comma-separated
//! parts, or `|bare` the count without separators, as a command prints it. Text is compared with every run of white space made one space, so a template does not
//! care where the guide breaks its lines.

use std::collections::BTreeMap;

use crate::guides::{RESULTS, each_says, expand, results, says, table_rows, thousands};

/// (guide, template)
const QUOTED: &[(&str, &str)] = &[
    (
        "docs/board.md",
        "K = 700, a firmware state of {firmware-memory|700|7};",
    ),
    (
        "docs/fidelity.md",
        "on bun000 at 9,600 bytes, {fidelity-9600|bun000.ply|4|4} of their area lies farther than \
         tau from any point, against {fidelity-9600|bun000.ply|3|4} for the default",
    ),
    (
        "docs/performance.md",
        "so five_people is its {clouds|five_people.pcd|5} finite points here, of which `map` maps \
         {clouds|five_people.pcd|7}",
    ),
    (
        "docs/performance.md",
        "(five_people's {clouds|five_people.pcd|2} slots hold {clouds|five_people.pcd|5} points)",
    ),
    (
        "docs/command-line.md",
        "an organized scan's empty returns: {clouds|five_people.pcd|3} of `five_people.pcd`'s \
         {clouds|five_people.pcd|2}; {clouds|ouster_os1_0.pcd+ouster_os1_1.pcd+ouster_os1_2.pcd|3} \
         of the three Ouster sweeps' {clouds|ouster_os1_0.pcd+ouster_os1_1.pcd+ouster_os1_2.pcd|2} \
         in `ouster_os1.conf`",
    ),
    (
        "docs/command-line.md",
        "`points: {clouds|five_people.pcd|7|bare} read, {clouds|five_people.pcd|3|bare} more \
         dropped for a NaN or infinite coordinate, {clouds|five_people.pcd|6|bare} as isolated \
         (--outliers): {clouds|five_people.pcd|2|bare} in the input`",
    ),
    (
        "docs/command-line.md",
        "`ouster_os1.conf` drops {clouds|ouster_os1_0.pcd|6} + {clouds|ouster_os1_1.pcd|6} + \
         {clouds|ouster_os1_2.pcd|6} = {clouds|ouster_os1_0.pcd+ouster_os1_1.pcd+ouster_os1_2.pcd|6}",
    ),
    (
        "docs/firmware.md",
        "a frozen entity is {firmware-sizes|a frozen entity|2} bytes (the paper's 24 and a 4-byte \
         rotation code)",
    ),
    (
        "docs/streaming.md",
        "A working cluster costs {firmware-sizes|a working cluster|2} bytes",
    ),
    (
        "docs/streaming.md",
        "up to K - W *frozen* entities of {firmware-sizes|a frozen entity|2} bytes each",
    ),
    (
        "docs/performance.md",
        "`five_people.pcd`, `lamppost.pcd`, `milk.pcd`, `office1.pcd`, `rops_cloud.pcd`, in that \
         order, their finite points, {clouds|bun000.ply+bun_zipper.ply+car6.pcd+cturtle.pcd+\
         five_people.pcd+lamppost.pcd+milk.pcd+office1.pcd+rops_cloud.pcd|5} in all.",
    ),
    (
        "docs/fidelity.md",
        "a 640 x 480 depth frame of {clouds|office1.pcd|2} points, of which \
         {clouds|office1.pcd|5} are finite",
    ),
    (
        "docs/performance.md",
        "(car6's {bench-pipeline|car6.pcd|2} points are {bench-pipeline|car6.pcd|4})",
    ),
    (
        "docs/performance.md",
        "about the same at 500 entities as at {draw-office1|office1, k = 16,384|2}.",
    ),
];

fn count(cell: &str) -> u64 {
    cell.replace(',', "")
        .parse()
        .unwrap_or_else(|_| panic!("`{cell}` is not a count"))
}

/// What a placeholder `block|row|column[|part]` stands for in today's results file.
fn value(results: &BTreeMap<String, String>, placeholder: &str) -> String {
    let fields: Vec<&str> = placeholder.split('|').collect();
    let (block, row, column) = (fields[0], fields[1], fields[2]);
    let column: usize = column.parse().expect("a column");
    let body = results
        .get(block)
        .unwrap_or_else(|| panic!("{RESULTS}: no block `{block}`"));
    let table = table_rows(body);
    let cell = |name: &str| -> String {
        let cells = table
            .iter()
            .find(|cells| cells[0] == name)
            .unwrap_or_else(|| panic!("{RESULTS}: no row `{name}` in `{block}`"));
        let cell = cells[column - 1].clone();
        match fields.get(3) {
            Some(&"bare") => cell.replace(',', ""),
            Some(part) => {
                let part: usize = part.parse().expect("a part");
                cell.split(", ")
                    .nth(part - 1)
                    .expect("the part")
                    .to_string()
            }
            None => cell,
        }
    };
    if row.contains('+') {
        thousands(row.split('+').map(|r| count(&cell(r))).sum())
    } else {
        cell(row)
    }
}

#[test]
fn the_figures_quoted_in_prose_are_the_results_files() {
    let results = results();
    each_says(QUOTED, |p| value(&results, p), RESULTS);
}

#[test]
fn a_template_reads_cells_parts_and_sums() {
    let mut results = BTreeMap::new();
    results.insert(
        "b".to_string(),
        "| a | b | c |\n|---|---|---|\n| `x.pcd` | 1,500 | 7, 9 |\n| y | 2,500 | 8, 10 |"
            .to_string(),
    );
    assert_eq!(
        expand("{b|x.pcd|2} and {b|y|3|2}", |p| value(&results, p)),
        "1,500 and 10"
    );
    assert_eq!(expand("{b|x.pcd+y|2}", |p| value(&results, p)), "4,000");
    assert_eq!(expand("{b|y|2|bare}", |p| value(&results, p)), "2500");
}

/// The README's first claim, "in under 3% of the cloud's memory", against Table 2's maps.
#[test]
fn the_readme_memory_claim_is_table_2s() {
    let results = results();
    let bound = 3.0;
    says(
        "README.md",
        &format!("in under {bound}% of the cloud's memory (the paper's Table 2)"),
    );
    let table = table_rows(&results["paper-table-2"]);
    assert!(
        table.len() >= 4,
        "{RESULTS}: Table 2 has {} rows",
        table.len()
    );
    for cells in table {
        let percent: f64 = cells[6]
            .trim_end_matches('%')
            .parse()
            .expect("a percentage");
        assert!(
            percent < bound,
            "{RESULTS}: Table 2's {cells:?} is not under {bound}%"
        );
    }
}

/// firmware.md's two claims on the firmware's measured cost: car6's whole run under a round
/// bound with either model (`firmware-cost`), and the most a pacing credit costs, a fit's, a merge
/// pass's or a scan's price over the credits it spends (`pacing`, `Pacing::DEVICE`, and
/// `Pacing::DEVICE_SHELLS` on the rows in shells; a scan spends its own and its two fits').
#[test]
fn the_firmware_guides_claims_are_the_measured_costs() {
    let results = results();
    let cost = table_rows(&results["firmware-cost"]);
    let bound = 10_000;
    for model in ["paper", "shells"] {
        let row = cost
            .iter()
            .find(|r| r[1] == model)
            .expect("a row for each model");
        assert!(
            count(&row[4]) < bound,
            "{RESULTS}: car6 costs {} a point with {model}",
            row[4]
        );
    }
    says(
        "docs/firmware.md",
        &format!(
            "Both models stay under {} instructions a point over the whole run.",
            thousands(bound)
        ),
    );
    let most = table_rows(&results["pacing"])
        .iter()
        .flat_map(|r| {
            let pacing = if r[0].ends_with("shells") {
                mema_core::stream::Pacing::DEVICE_SHELLS
            } else {
                mema_core::stream::Pacing::DEVICE
            };
            // The paper's captures never scan: their scan price is `none`.
            let prices: Vec<u64> = r[1]
                .split(", ")
                .map(|p| if p == "none" { 0 } else { count(p) })
                .collect();
            [
                prices[1] / u64::from(pacing.freeze),
                prices[2] / u64::from(pacing.merge_pass),
                prices[3] / u64::from(pacing.scan + 2 * pacing.freeze),
            ]
        })
        .max()
        .expect("prices");
    let about = thousands((most + 50) / 100 * 100);
    says(
        "docs/firmware.md",
        &format!("at most ~{about} instructions a credit)"),
    );
    says(
        "docs/firmware.md",
        &format!("plus ~{about} for the credit it earns"),
    );
}

/// board.md's reading of its `board-fidelity` table: the clouds whose map does not fill K = 400
/// (K = 700 scores the same), and those further behind the batch map than a quarter.
#[test]
fn the_board_guides_reading_is_its_fidelity_table() {
    let results = results();
    let rows = table_rows(&results["board-fidelity"]);
    let names = |keep: &dyn Fn(&Vec<String>) -> bool| -> String {
        let picked: Vec<&str> = rows
            .iter()
            .filter(|r| keep(r))
            .map(|r| r[0].as_str())
            .collect();
        picked.join(", ")
    };
    let ratio = |cell: &str| cell.parse::<f64>().expect("a ratio");
    says(
        "docs/board.md",
        &format!(
            "those that do not fill it ({}) map alike.",
            names(&|r| ratio(&r[7]) == 1.0)
        ),
    );
    let behind = names(&|r| ratio(&r[6]) > 1.25);
    says(
        "docs/board.md",
        &if behind.is_empty() {
            "No map is further behind than a quarter of the batch map's Chamfer distance.".into()
        } else {
            format!(
                "Maps further behind than a quarter of the batch map's Chamfer distance: {behind}."
            )
        },
    );
}
