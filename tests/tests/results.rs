//! The figures the guides quote (issue 32). `scripts/results.sh` writes them, from one run, into
//! docs/results.md, each table in a block between `<!-- result NAME -->` and `<!-- /result -->`;
//! a guide quotes a table by copying its block. These tests hold every copy to the results file
//! (one digit changed in a guide fails), every `<cloud> (N points` in a guide to the points the
//! results file says are read of it (its finite points, what `eval` and the benchmarks read, or
//! those `map` maps once it has left out the isolated ones), and the results file to the code: car6's rows are
//! computed again here, with the binary under test, so the file cannot drift from what the code
//! makes. Regenerating the whole file is the script's job; this stays fast (car6 maps in tens of
//! milliseconds).

use crate::guides::{RESULTS, blocks, documents, results, thousands};
use crate::util::{Dir, MemaCommand, shared};

/// The rows of a results block whose first cell is `` `cloud` ``, and the rows that follow it
/// with an empty first cell.
fn rows_of<'a>(block: &'a str, cloud: &str) -> Vec<&'a str> {
    let head = format!("| `{cloud}` |");
    let mut rows = Vec::new();
    let mut inside = false;
    for line in block.lines() {
        if line.starts_with(&head) {
            inside = true;
        } else if !line.starts_with("| |") {
            inside = false;
        }
        if inside {
            rows.push(line);
        }
    }
    rows
}

#[test]
fn the_guides_copy_the_results_file() {
    let results = results();
    let mut copies = 0;
    for (file, text) in documents() {
        for block in blocks(&text, &file) {
            let (name, line) = (&block.name, block.line);
            let want = results
                .get(name)
                .unwrap_or_else(|| panic!("{file}:{line}: no block `{name}` in {RESULTS}"));
            assert!(
                block.body == *want,
                "{file}:{line}: the block `{name}` differs from {RESULTS}'s; copy it again:\n{want}"
            );
            copies += 1;
        }
    }
    // The tables fidelity.md quotes from the results file (Tables 2 and 4, the clouds).
    assert!(copies >= 3, "{copies} result blocks in the guides");
}

#[test]
fn every_cloud_quoted_with_its_points_has_the_results_files_count() {
    let results = results();
    let clouds = results.get("clouds").expect("the block `clouds`");
    let mut checked = 0;
    for row in clouds.lines().skip(2) {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let (cloud, finite, mapped) = (cells[1].trim_matches('`'), cells[5], cells[7]);
        let stem = cloud.rsplit_once('.').map_or(cloud, |(s, _)| s);
        for (file, text) in documents() {
            for name in [cloud, stem] {
                for quote in [format!("{name}` ("), format!("{name} (")] {
                    for (at, _) in text.match_indices(&quote) {
                        let rest = &text[at + quote.len()..];
                        let figure: String = rest
                            .chars()
                            .take_while(|c| c.is_ascii_digit() || *c == ',')
                            .collect();
                        let after = &rest[figure.len()..];
                        if figure.is_empty() || !after.starts_with(" points") {
                            continue;
                        }
                        // A command's output writes the count bare, prose with separators.
                        let bare = |f: &str| f.replace(',', "");
                        assert!(
                            bare(&figure) == bare(finite) || bare(&figure) == bare(mapped),
                            "{file}: `{quote}{figure} points`, but {cloud} has {finite} finite \
                             points, of which `mema map` maps {mapped} ({RESULTS})"
                        );
                        checked += 1;
                    }
                }
            }
        }
    }
    assert!(checked >= 3, "{checked} quotes of a cloud's points checked");
}

/// car6's rows of the results file, computed again: Tables 2 and 4 of `mema map --paper`, and
/// the cloud's counts and default map at 2,400 bytes.
#[test]
fn the_results_file_is_what_the_code_makes_of_car6() {
    let results = results();
    let dir = Dir::new("results-car6");
    let car6 = shared("car6.pcd");
    let paper = MemaCommand::new(&dir)
        .arg("map")
        .arg(&car6)
        .args(["-k", "150", "--paper", "-o", "paper.mema", "--json"])
        .run()
        .assert_ok()
        .json();
    let m = &paper["memory"];
    let u = |v: &serde_json::Value| v.as_u64().expect("a count");
    let table_2 = format!(
        "| `car6.pcd` | 150 | {} | {} | {} | {} | {:.4}% |",
        thousands(u(&m["points"])),
        thousands(u(&m["cloud_bytes"])),
        thousands(u(&m["entities"])),
        thousands(u(&m["map_bytes"])),
        m["percent"].as_f64().expect("percent")
    );
    assert_eq!(
        rows_of(&results["paper-table-2"], "car6.pcd"),
        [table_2.as_str()],
        "{RESULTS}: Table 2's car6 row against `mema map --paper`"
    );
    let table_4: Vec<String> = ["ellipsoidal", "spherical"]
        .iter()
        .enumerate()
        .map(|(i, fit)| {
            let e = &paper[*fit];
            let f = |k: &str| e[k].as_f64().expect("an error");
            format!(
                "{} {fit} | {:.6} | {:.6} | {:.6} | {:.6} | {:.6} |",
                if i == 0 {
                    "| `car6.pcd` | 150 |"
                } else {
                    "| | |"
                },
                f("mean"),
                f("std"),
                f("max"),
                f("min"),
                f("total")
            )
        })
        .collect();
    assert_eq!(
        rows_of(&results["paper-table-4"], "car6.pcd"),
        table_4,
        "{RESULTS}: Table 4's car6 rows against `mema map --paper`"
    );

    let map = MemaCommand::new(&dir)
        .arg("map")
        .arg(&car6)
        .args(["--bytes", "2400", "-o", "bytes.mema", "--json"])
        .run()
        .assert_ok()
        .json();
    let info = MemaCommand::new(&dir)
        .args(["info", "bytes.mema", "--json"])
        .run()
        .assert_ok()
        .json();
    let by_class: u64 = map["dropped_by_class"]
        .as_object()
        .expect("classes")
        .values()
        .map(u)
        .sum();
    let finite = u(&map["slots"]) - u(&map["dropped_non_finite"]) - by_class;
    let row = format!(
        "| `car6.pcd` | {} | {} | {} | {} | {} | {} | {} | {} |",
        thousands(u(&map["slots"])),
        thousands(u(&map["dropped_non_finite"])),
        thousands(by_class),
        thousands(finite),
        thousands(u(&map["outliers"]["dropped"])),
        thousands(u(&map["memory"]["points"])),
        thousands(u(&map["memory"]["entities"])),
        thousands(u(&info["file_bytes"]))
    );
    assert_eq!(
        rows_of(&results["clouds"], "car6.pcd"),
        [row.as_str()],
        "{RESULTS}: car6's counts and 2,400-byte map against `mema map` and `mema info`"
    );
    // The file's size is what the format gives 171 shells: 52 bytes of header and 14 a record.
    let file = std::fs::metadata(dir.join("bytes.mema"))
        .expect("map")
        .len();
    assert_eq!(file, 52 + 14 * u(&map["memory"]["entities"]));
    assert_eq!(thousands(file), thousands(u(&info["file_bytes"])));
}
