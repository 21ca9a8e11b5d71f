//! Outliers in files (issue 23): one point 100 km or 10^9 m from a real scan costs nothing of
//! the map, the run says what it dropped and where, and with the filter off the precision
//! check refuses the cloud instead of mapping its rounding.

use std::path::{Path, PathBuf};

use crate::util::{Dir, MemaCommand, eval_chamfer, shared};

/// bun000's points as its ASCII PLY lists them (read here, not by mema), as XYZ text lines.
fn bun000_lines() -> Vec<String> {
    let text = std::fs::read_to_string(shared("bun000.ply")).expect("bun000.ply");
    let (header, body) = text.split_once("end_header\n").expect("a PLY header");
    let vertices: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .and_then(|n| n.trim().parse().ok())
        .expect("element vertex N");
    body.lines().take(vertices).map(str::to_owned).collect()
}

/// The scan with `extra` points after its own, as an XYZ file in `dir`.
fn scan_with(dir: &Dir, name: &str, extra: &[[f64; 3]]) -> PathBuf {
    let mut lines = bun000_lines();
    lines.extend(extra.iter().map(|p| format!("{} {} {}", p[0], p[1], p[2])));
    dir.write(name, (lines.join("\n") + "\n").as_bytes())
}

fn map(dir: &Dir, input: &Path, output: &str, more: &[&str]) -> crate::util::Ran {
    MemaCommand::new(dir)
        .arg("map")
        .arg(input)
        .args(["--bytes", "9600", "-o", output])
        .args(more)
        .run()
}

#[test]
fn one_far_point_costs_nothing_of_the_map_and_is_reported() {
    let dir = Dir::new("outliers");
    let clean = scan_with(&dir, "clean.xyz", &[]);
    map(&dir, &clean, "clean.mema", &[]).assert_ok();
    let clean_chamfer = eval_chamfer(&dir, &clean, "clean.mema");
    let clean_bytes = std::fs::read(dir.join("clean.mema")).expect("clean map");
    for (name, far) in [
        ("far-100km", vec![[1e5, 0.0, 0.0]]),
        ("far-1e9m", vec![[1e9, 0.0, 0.0]]),
        ("far-both", vec![[0.0, -1e9, 0.0], [0.0, 0.0, 1e5]]),
    ] {
        let input = scan_with(&dir, &format!("{name}.xyz"), &far);
        let output = format!("{name}.mema");
        let ran = map(&dir, &input, &output, &[]).assert_ok();
        let chamfer = eval_chamfer(&dir, &clean, &output);
        assert!(
            chamfer <= 1.05 * clean_chamfer,
            "{name}: Chamfer {chamfer} m against the clean map's {clean_chamfer} m"
        );
        // Dropped before the cloud was centred, the outlier leaves the clean scan, bit for bit.
        assert_eq!(
            std::fs::read(dir.join(&output)).expect("map"),
            clean_bytes,
            "{name}"
        );
        let said = ran.stderr();
        let worst = far
            .iter()
            .copied()
            .max_by(|a, b| {
                a.iter()
                    .sum::<f64>()
                    .abs()
                    .total_cmp(&b.iter().sum::<f64>().abs())
            })
            .expect("a far point");
        let at = format!("({:.3}, {:.3}, {:.3}) m", worst[0], worst[1], worst[2]);
        assert!(
            said.contains(&format!("dropped {} isolated points", far.len())) && said.contains(&at),
            "{name}: {said}"
        );
        assert!(
            ran.stdout()
                .contains(&format!("{} as isolated (--outliers)", far.len())),
            "{name}: {}",
            ran.stdout()
        );
        let json = map(&dir, &input, &output, &["--json"]).assert_ok().json();
        let outliers = &json["outliers"];
        assert_eq!(
            outliers["dropped"].as_u64(),
            Some(far.len() as u64),
            "{json}"
        );
        let reported: Vec<f64> = (0..3)
            .map(|j| outliers["worst"]["at"][j].as_f64().expect("worst.at"))
            .collect();
        assert_eq!(reported, worst.to_vec(), "{json}");
    }
}

#[test]
fn with_the_filter_off_the_precision_check_speaks() {
    let dir = Dir::new("outliers-off");
    for (name, far) in [("far-100km", 1e5), ("far-1e9m", 1e9)] {
        let input = scan_with(&dir, &format!("{name}.xyz"), &[[far, 0.0, 0.0]]);
        let output = format!("{name}.mema");
        let ran = map(&dir, &input, &output, &["--outliers", "off"])
            .assert_error(1, "f32 about its centre rounds by");
        let said = ran.stderr();
        assert!(
            said.contains(&format!(
                "loneliest point, at ({far:.6e}, 0.000000e0, 0.000000e0) m"
            )),
            "{name}: {said}"
        );
        assert!(!dir.join(&output).exists(), "{name}: a map was written");
    }
    // The scan alone passes the check with the filter off, and maps as it does with it on.
    let clean = scan_with(&dir, "clean.xyz", &[]);
    map(&dir, &clean, "off.mema", &["--outliers", "off"]).assert_ok();
    map(&dir, &clean, "on.mema", &[]).assert_ok();
    assert_eq!(
        std::fs::read(dir.join("off.mema")).expect("off"),
        std::fs::read(dir.join("on.mema")).expect("on")
    );
    MemaCommand::new(&dir)
        .args([
            "map",
            "clean.xyz",
            "-k",
            "10",
            "-o",
            "x.mema",
            "--outliers",
            "20",
        ])
        .run()
        .assert_error(2, "K,RATIO");
}
