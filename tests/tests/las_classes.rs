//! LAS/LAZ classes (issue 23): noise (ASPRS 7, 18) and withheld points are left out of a map by
//! default and counted, and `--classes` brings them back, against laspy's own reading of the
//! classes of a file laspy wrote (tests/las/noisy_laz.py).

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::util::{Dir, MemaCommand, shared};

/// The Python with laspy that scripts/test.sh makes (or `MEMA_PY`).
fn python() -> PathBuf {
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/py-venv/bin/python");
    std::env::var_os("MEMA_PY").map_or(venv, PathBuf::from)
}

/// The map's highest entity centre, in metres.
fn top_of(dir: &Dir, map: &str) -> f64 {
    let info = MemaCommand::new(dir)
        .args(["info", map, "--json"])
        .run()
        .assert_ok()
        .json();
    info["center_max"][2].as_f64().expect("center_max")
}

#[test]
fn noise_and_withheld_points_stay_out_unless_asked_for() {
    let dir = Dir::new("las-classes");
    let noisy = dir.join("noisy.laz");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("las/noisy_laz.py");
    let ran = Command::new(python())
        .arg(&script)
        .arg(shared("autzen_trim.laz"))
        .arg(&noisy)
        .output()
        .expect("the LAZ writer runs");
    let said = String::from_utf8_lossy(&ran.stdout);
    assert!(
        ran.status.success(),
        "{} failed (scripts/test.sh installs laspy[lazrs] in target/py-venv): {}",
        script.display(),
        String::from_utf8_lossy(&ran.stderr)
    );
    // `noise N withheld W points P zmax Z`, as laspy reads the file.
    let words: Vec<&str> = said.split_whitespace().collect();
    let (noise, withheld, points, zmax): (usize, usize, u64, f64) = match words.as_slice() {
        ["noise", n, "withheld", w, "points", p, "zmax", z] => (
            n.parse().expect("n"),
            w.parse().expect("w"),
            p.parse().expect("p"),
            z.parse().expect("z"),
        ),
        _ => panic!("the writer said {said:?}"),
    };
    assert!(noise > 1_000 && withheld > 100, "{said}");
    let mapped = MemaCommand::new(&dir)
        .args(["map", "noisy.laz", "--bytes", "9600", "-o", "clean.mema"])
        .run()
        .assert_ok();
    let left = format!("left out {noise} noise points (ASPRS classes 7, 18), {withheld} withheld");
    assert!(mapped.stderr().contains(&left), "{}", mapped.stderr());
    let json = MemaCommand::new(&dir)
        .args([
            "map",
            "noisy.laz",
            "--bytes",
            "9600",
            "--json",
            "-o",
            "again.mema",
        ])
        .run()
        .assert_ok()
        .json();
    assert_eq!(json["dropped_by_class"]["noise"], noise, "{json}");
    assert_eq!(json["dropped_by_class"]["withheld"], withheld, "{json}");
    // Issue 33: what was read and every drop add up to laspy's count of the file's points.
    let count = |v: &serde_json::Value| v.as_u64().expect("a count");
    let sum = count(&json["filter"]["read"])
        + count(&json["dropped_non_finite"])
        + count(&json["outliers"]["dropped"])
        + ["noise", "withheld", "other_classes"]
            .iter()
            .map(|k| count(&json["dropped_by_class"][k]))
            .sum::<u64>();
    assert_eq!((sum, count(&json["slots"])), (points, points), "{json}");
    let line = mapped
        .stdout()
        .lines()
        .find(|l| l.starts_with("points: "))
        .map(str::to_owned)
        .expect("a points line");
    assert!(
        line.contains(&format!(
            "{} left out by class (--classes)",
            noise + withheld
        )) && line.contains(&format!(": {points} in the input")),
        "{line}"
    );
    // The file is in US feet; no entity of the default map reaches the noise 5,000 ft up.
    let top_ft = top_of(&dir, "clean.mema") / 0.3048;
    assert!(
        top_ft <= zmax,
        "the map reaches {top_ft} ft, the clean points {zmax} ft"
    );
    let all = MemaCommand::new(&dir)
        .args([
            "map",
            "noisy.laz",
            "--bytes",
            "9600",
            "--classes",
            "all",
            "-o",
            "all.mema",
        ])
        .run()
        .assert_ok();
    assert!(!all.stderr().contains("left out"), "{}", all.stderr());
    assert!(top_of(&dir, "all.mema") / 0.3048 > zmax + 1_000.0);
    MemaCommand::new(&dir)
        .args([
            "map",
            "noisy.laz",
            "-k",
            "5",
            "--classes",
            "seven",
            "-o",
            "x.mema",
        ])
        .run()
        .assert_error(2, "not an ASPRS class");
}
