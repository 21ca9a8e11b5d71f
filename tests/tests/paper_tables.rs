//! Acceptance 5 of the foundation issue: the paper's comparison (Table 4) on the shared clouds.

use crate::util::{Dir, MemaCommand, shared};

#[test]
fn ellipsoids_beat_spheres_on_the_shared_objects() {
    let dir = Dir::new("tables");
    for (cloud, k) in [
        ("car6.pcd", 150),
        ("bun_zipper.ply", 100),
        ("bun_zipper.ply", 350),
        ("five_people.pcd", 350),
    ] {
        let out = dir.join("m.mema");
        let v = MemaCommand::new(&dir)
            .arg("map")
            .arg(shared(cloud))
            .args(["--paper", "-k", &k.to_string(), "--json", "-o"])
            .arg(&out)
            .run()
            .assert_ok()
            .json();
        let (e, s) = (&v["ellipsoidal"], &v["spherical"]);
        let (et, st) = (
            e["total"].as_f64().expect("total"),
            s["total"].as_f64().expect("total"),
        );
        eprintln!("{cloud} k={k}: ellipsoidal total {et:.6}, spherical total {st:.6}");
        assert!(
            et < st,
            "{cloud} k={k}: ellipsoids {et} not below spheres {st}"
        );
        assert_eq!(v["memory"]["entities"], k);
        assert_eq!(e["clusters"], k);
        let points = v["memory"]["points"].as_f64().expect("points");
        let percent = v["memory"]["percent"].as_f64().expect("percent");
        assert!((percent - 100.0 * 24.0 * k as f64 / (12.0 * points)).abs() < 1e-9);
    }
}
