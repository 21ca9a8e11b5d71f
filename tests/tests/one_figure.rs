//! One figure per name (issue 33): one map made, evaluated, drawn and read by `map`, `eval`,
//! `draw`, `info` and the Python package gives each shared figure the same value under the
//! same name. Two figures bear eq. 13's name, each under its own: "as fitted" (each cluster's
//! error on its own points: `map`, Python's `Map.report`) and "by nearest centre" (each point
//! to the entity of its nearest centre: `eval`, `draw`, Python's `Map.eval`). Bytes: "in the
//! file" (measured here on disk), "map bytes" (Table 2: the entities' records, checked here as
//! the file less its version-2 header and checksum) and the paper's 24 per entity.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::util::{Dir, MemaCommand, shared};

/// The Python with the package (`MEMA_PY`, else `target/py-venv`, as scripts/test.sh makes it).
fn python() -> PathBuf {
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/py-venv/bin/python");
    let python = std::env::var_os("MEMA_PY").map_or(venv, PathBuf::from);
    assert!(
        python.exists(),
        "{}: no Python with the mema package; run scripts/test.sh or set MEMA_PY",
        python.display()
    );
    python
}

fn json(dir: &Dir, args: &[&str]) -> serde_json::Value {
    MemaCommand::new(dir).args(args).run().assert_ok().json()
}

fn text(dir: &Dir, args: &[&str]) -> String {
    MemaCommand::new(dir).args(args).run().assert_ok().stdout()
}

fn f(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("{v} is not a number"))
}

/// A figure as the text prints it: 6 decimals.
fn six(x: f64) -> String {
    format!("{x:.6}")
}

fn check(cloud: &str, size: &[&str], python_size: &str) {
    let dir = Dir::new("one-figure");
    let cloud = shared(cloud);
    let cloud = cloud.to_str().expect("utf8");
    let mut args = vec!["map", cloud, "-o", "m.mema", "--json"];
    args.extend_from_slice(size);
    let map = json(&dir, &args);
    let eval = json(&dir, &["eval", cloud, "m.mema", "--json"]);
    let info = json(&dir, &["info", "m.mema", "--json"]);
    let draw = json(&dir, &["draw", cloud, "m.mema", "-o", "m.png", "--json"]);

    // Bytes in the file: measured here.
    let on_disk = std::fs::metadata(dir.join("m.mema")).expect("map").len();
    assert_eq!(eval["file_bytes"], on_disk);
    assert_eq!(info["file_bytes"], on_disk);
    // Map bytes: the records, the file less its version-2 header (48) and CRC (4), the same in
    // map's Table 2, eval's and info.
    let entities = map["memory"]["entities"].as_u64().expect("entities");
    let records = on_disk - 52;
    assert_eq!(map["memory"]["map_bytes"], records, "{map}");
    assert_eq!(eval["map_bytes"], records, "{eval}");
    assert_eq!(info["map_bytes"], records, "{info}");
    assert_eq!(info["paper_bytes"], entities * 24);
    assert_eq!(info["entities"], entities);
    assert_eq!(eval["percent"], map["memory"]["percent"]);

    // Eq. 13 by nearest centre: eval and draw.
    let nearest = f(&eval["mean"]);
    assert_eq!(f(&draw["panels"][0]["mean_error"]), nearest);
    let fitted = f(&map["ellipsoidal"]["mean"]);

    // The text gives each under its name.
    let mut args = vec!["map", cloud, "-o", "t.mema"];
    args.extend_from_slice(size);
    let map_text = text(&dir, &args);
    assert!(
        map_text.contains("eq. 13 as fitted") && map_text.contains(&six(fitted)),
        "{map_text}"
    );
    let eval_text = text(&dir, &["eval", cloud, "m.mema"]);
    assert!(
        eval_text.contains("eq. 13 by nearest centre") && eval_text.contains(&six(nearest)),
        "{eval_text}"
    );
    let draw_text = text(&dir, &["draw", cloud, "m.mema", "-o", "t.png"]);
    assert!(
        draw_text.contains(&format!("eq. 13 by nearest centre {}", six(nearest))),
        "{draw_text}"
    );
    let records_text = format!("map bytes (Table 2, 14 per entity) {records}");
    let info_text = text(&dir, &["info", "m.mema"]);
    assert!(
        info_text.contains(&format!("{on_disk} in the file")) && info_text.contains(&records_text),
        "{info_text}"
    );
    for (what, out) in [("map", &map_text), ("eval", &eval_text)] {
        let row = out
            .lines()
            .skip_while(|l| !l.starts_with("Table 2"))
            .nth(2)
            .unwrap_or_else(|| panic!("{what}: no Table 2:\n{out}"));
        assert!(
            row.split_whitespace().nth(3) == Some(&records.to_string()),
            "{what}'s map bytes: {row}"
        );
    }

    // The Python package: the same map from the same cloud and options, its report as fitted,
    // and Map.eval of the written map by nearest centre, with the same bytes.
    let script = format!(
        "import json, mema\n\
         points = mema.read_cloud({cloud:?})\n\
         made = mema.map(points, {python_size})\n\
         m = mema.load('m.mema')\n\
         e = m.eval(points)\n\
         print(json.dumps({{'fitted': made.report['ellipsoidal']['mean'],\n\
             'map_bytes': made.report['memory']['map_bytes'], 'nearest': e['mean'],\n\
             'eval_map_bytes': e['map_bytes'], 'file_bytes': e['file_bytes']}}))\n"
    );
    let ran = Command::new(python())
        .arg("-c")
        .arg(&script)
        .current_dir(&dir.path)
        .env("MEMA_BIN", crate::util::mema_bin())
        .output()
        .expect("python runs");
    assert!(
        ran.status.success(),
        "{}",
        String::from_utf8_lossy(&ran.stderr)
    );
    let py: serde_json::Value = serde_json::from_slice(&ran.stdout).expect("JSON");
    assert_eq!(f(&py["fitted"]), fitted, "{py}");
    assert_eq!(f(&py["nearest"]), nearest, "{py}");
    assert_eq!(py["map_bytes"], records, "{py}");
    assert_eq!(py["eval_map_bytes"], records, "{py}");
    assert_eq!(py["file_bytes"], on_disk, "{py}");
    eprintln!(
        "{cloud} {size:?}: eq. 13 as fitted {fitted:.6}, by nearest centre {nearest:.6}; \
         {on_disk} bytes in the file, {records} map bytes, {} paper bytes",
        entities * 24
    );
}

/// Acceptance 1: bun_zipper at k = 150.
#[test]
fn the_bunny_at_k_150_has_one_figure_per_name() {
    check("bun_zipper.ply", &["-k", "150"], "k=150");
}

/// Acceptance 1: car6 at --bytes 2400.
#[test]
fn car6_at_2400_bytes_has_one_figure_per_name() {
    check("car6.pcd", &["--bytes", "2400"], "bytes=2400");
}
