//! What `map` and `eval` say of their input beside the tables (issue 15): the points dropped
//! for NaN coordinates, a map and a cloud that do not belong together, and fits whose axes
//! the search box chose rather than eq. 12.

use crate::util::{Dir, MemaCommand, shared};
use mema::io::load_cloud;

/// The number after `key` in a PCD header (`WIDTH 640`).
fn pcd_header(path: &std::path::Path, key: &str) -> u64 {
    let bytes = std::fs::read(path).expect("pcd");
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]).into_owned();
    head.lines()
        .find_map(|l| l.strip_prefix(key))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("{key} in the header"))
}

/// five_people.pcd is an organized 640 x 480 cloud whose empty returns are NaN: the text of
/// `map` and `eval` counts them, as their JSON does, and with the points read they make up
/// the header's slots.
#[test]
fn dropped_nan_points_are_counted_in_the_text_too() {
    let dir = Dir::new("reports-nan");
    let cloud = shared("five_people.pcd");
    let slots = pcd_header(&cloud, "WIDTH ") * pcd_header(&cloud, "HEIGHT ");
    let json = MemaCommand::new(&dir)
        .arg("map")
        .arg(&cloud)
        .args([
            "-k",
            "50",
            "--surface-rounds",
            "0",
            "--json",
            "-o",
            "m.mema",
        ])
        .run()
        .assert_ok()
        .json();
    let dropped = json["dropped_non_finite"].as_u64().expect("dropped");
    let read = json["filter"]["read"].as_u64().expect("read");
    let isolated = json["outliers"]["dropped"].as_u64().expect("outliers");
    assert!(
        dropped > 0 && read + dropped + isolated == slots,
        "{read} + {dropped} + {isolated} vs {slots}"
    );
    // eval takes the cloud as its file holds it: beside it, map keeps every point too.
    let read = read + isolated;
    let line =
        format!("points: {read} read, {dropped} more dropped for a NaN or infinite coordinate");
    let text = MemaCommand::new(&dir)
        .arg("map")
        .arg(&cloud)
        .args(["-k", "50", "--surface-rounds", "0", "-o", "m.mema"])
        .args(["--outliers", "off"])
        .run()
        .assert_ok()
        .stdout();
    assert!(text.contains(&line), "{text}");
    let text = MemaCommand::new(&dir)
        .arg("eval")
        .arg(&cloud)
        .args(["m.mema", "--samples", "20000"])
        .run()
        .assert_ok()
        .stdout();
    assert!(
        text.contains(&format!("cloud {line}")),
        "eval does not count them:\n{text}"
    );
    let json = MemaCommand::new(&dir)
        .arg("eval")
        .arg(&cloud)
        .args(["m.mema", "--samples", "20000", "--json"])
        .run()
        .assert_ok()
        .json();
    assert_eq!(json["dropped_non_finite"], dropped);
}

/// `eval` of a map against a cloud it was not made from says so on stderr, one line each: a
/// map moved 100 m away lies apart from the cloud; a whole bunny's map against a tenth of the
/// bunny has most entities nearest to none of its points. The bunny against its own map says
/// nothing.
#[test]
fn eval_warns_when_map_and_cloud_do_not_belong_together() {
    let dir = Dir::new("reports-apart");
    let bunny = shared("bun_zipper.ply");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&bunny)
        .args(["-k", "80", "-o", "bunny.mema"])
        .run()
        .assert_ok();
    let own = MemaCommand::new(&dir)
        .arg("eval")
        .arg(&bunny)
        .args(["bunny.mema", "--samples", "20000"])
        .run()
        .assert_ok();
    assert!(!own.stderr().contains("warning"), "{}", own.stderr());

    MemaCommand::new(&dir)
        .args([
            "transform",
            "bunny.mema",
            "-o",
            "far.mema",
            "--translate",
            "100,0,0",
        ])
        .run()
        .assert_ok();
    let far = MemaCommand::new(&dir)
        .arg("eval")
        .arg(&bunny)
        .args(["far.mema", "--samples", "20000"])
        .run()
        .assert_ok();
    let err = far.stderr();
    assert!(
        err.lines()
            .any(|l| l.contains("warning") && l.contains("lies apart from")),
        "{err}"
    );

    // The tenth of the bunny with the smallest x, written as XYZ text in world coordinates.
    let cloud = load_cloud(&bunny).expect("bunny");
    let mut world: Vec<[f64; 3]> = cloud
        .points
        .iter()
        .map(|p| {
            let q = p.to_f64();
            [0, 1, 2].map(|j| cloud.origin[j] + q[j])
        })
        .collect();
    world.sort_by(|a, b| a[0].total_cmp(&b[0]));
    world.truncate(world.len() / 10);
    let text: String = world
        .iter()
        .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
        .collect();
    dir.write("tenth.xyz", text.as_bytes());
    let part = MemaCommand::new(&dir)
        .args(["eval", "tenth.xyz", "bunny.mema", "--samples", "20000"])
        .run()
        .assert_ok();
    let json = MemaCommand::new(&dir)
        .args([
            "eval",
            "tenth.xyz",
            "bunny.mema",
            "--samples",
            "20000",
            "--json",
        ])
        .run()
        .assert_ok()
        .json();
    let empty = 80 - json["clusters"].as_u64().expect("clusters");
    assert!(empty > 40, "{json}");
    let err = part.stderr();
    let line = err
        .lines()
        .find(|l| l.contains("nearest to none"))
        .unwrap_or_else(|| panic!("no warning:\n{err}"));
    assert!(line.contains(&format!("{empty} of 80 entities")), "{line}");
    assert!(
        !err.contains("lies apart"),
        "the tenth lies inside the map:\n{err}"
    );
}

/// Writes the bunny scaled by `scale` as XYZ text: a scanner that wrote another unit.
fn scaled_bunny(dir: &Dir, name: &str, scale: f64) {
    let cloud = load_cloud(&shared("bun_zipper.ply")).expect("bunny");
    let text: String = cloud
        .points
        .iter()
        .map(|p| {
            let q = p.to_f64();
            let w = [0, 1, 2].map(|j| scale * (cloud.origin[j] + q[j]));
            format!("{} {} {}\n", w[0], w[1], w[2])
        })
        .collect();
    dir.write(name, text.as_bytes());
}

/// `map --paper` warns when most fitted semi-axes ended on a bound of DE's search box, which
/// then chose them rather than eq. 12. With `--alpha 0`, eq. 12 is its volume term alone and
/// every axis takes the lower bound; with `--bounds threshold` (an upper bound in metres) the
/// bunny in millimetres read as metres puts its axes on the upper bound, and `--units mm`
/// clears it. The bunny as it is, with the paper's settings, says nothing.
#[test]
fn map_warns_when_the_search_box_chose_the_axes() {
    let dir = Dir::new("reports-bounds");
    let bunny = shared("bun_zipper.ply");
    let map = |args: &[&str]| {
        let json = MemaCommand::new(&dir)
            .args(["map", "--paper", "-k", "60", "-o", "m.mema", "--json"])
            .args(args)
            .run()
            .assert_ok();
        let err = json.stderr();
        (json.json(), err)
    };
    let plain = bunny.to_str().expect("utf-8");
    let (json, err) = map(&[plain]);
    let on = &json["axes_on_bound"];
    let hits = on["lower"].as_u64().expect("lower") + on["upper"].as_u64().expect("upper");
    assert!(2 * hits < on["axes"].as_u64().expect("axes"), "{json}");
    assert!(!err.contains("warning"), "{err}");

    let (json, err) = map(&[plain, "--alpha", "0"]);
    assert_eq!(json["axes_on_bound"]["lower"], 180, "{json}");
    let line = err
        .lines()
        .find(|l| l.contains("ended on a bound"))
        .unwrap_or_else(|| panic!("no warning:\n{err}"));
    assert!(
        line.contains("180 of 180") && line.contains("180 on its lower"),
        "{line}"
    );
    assert_eq!(
        err.lines().filter(|l| l.contains("warning")).count(),
        1,
        "one warning, one line:\n{err}"
    );

    scaled_bunny(&dir, "bunny_mm.xyz", 1000.0);
    let (json, err) = map(&["bunny_mm.xyz", "--bounds", "threshold"]);
    let on = &json["axes_on_bound"];
    assert!(2 * on["upper"].as_u64().expect("upper") > 180, "{json}");
    assert!(
        err.lines()
            .any(|l| l.contains("warning") && l.contains("--units")),
        "{err}"
    );
    let (_, err) = map(&["bunny_mm.xyz", "--bounds", "threshold", "--units", "mm"]);
    assert!(!err.contains("warning"), "{err}");
}
