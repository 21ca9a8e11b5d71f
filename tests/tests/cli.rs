use crate::util::{Dir, MemaCommand, shared};
use mema::io::mapfile::HostMap;

#[test]
fn same_seed_same_bytes_and_exactly_k_finite_entities() {
    let dir = Dir::new("determinism");
    let car = shared("car6.pcd");
    let run = |name: &str, seed: &str| {
        let out = dir.join(name);
        MemaCommand::new(&dir)
            .arg("map")
            .arg(&car)
            .args(["-k", "150", "--seed", seed, "-o"])
            .arg(&out)
            .run()
            .assert_ok();
        std::fs::read(out).expect("map written")
    };
    let first = run("a.mema", "7");
    let second = run("b.mema", "7");
    assert_eq!(first, second, "same seed, different bytes");
    assert_ne!(first, run("c.mema", "8"), "the seed has no effect");
    let map = HostMap::from_mema(&first).expect("valid map");
    assert_eq!(map.entities.len(), 150);
    assert!(map.origin.iter().all(|v| v.is_finite()));
    for e in &map.entities {
        assert!(e.entity.center.is_finite());
        assert!(
            e.entity.weights.iter().all(|w| w.is_finite() && *w >= 0.0),
            "{e:?}"
        );
        assert!(e.entity.degenerated_axes() < 3);
    }
}

#[test]
fn csv_and_json_maps_carry_the_same_entities() {
    let dir = Dir::new("formats");
    let bunny = shared("bun_zipper.ply");
    for name in ["m.mema", "m.csv", "m.json"] {
        MemaCommand::new(&dir)
            .arg("map")
            .arg(&bunny)
            .args(["-k", "60", "-o"])
            .arg(dir.join(name))
            .run()
            .assert_ok();
    }
    let csv = std::fs::read_to_string(dir.join("m.csv")).expect("csv");
    assert_eq!(
        csv.lines().next(),
        Some("cx,cy,cz,rx,ry,rz,qx,qy,qz,qw,kind")
    );
    assert_eq!(csv.lines().count(), 61);
    let mema = HostMap::read(&dir.join("m.mema")).expect("mema");
    let json = HostMap::read(&dir.join("m.json")).expect("json");
    // JSON keeps the exact stored values; the quantization grid is how .mema stores them.
    assert_eq!(
        (mema.origin, &mema.entities),
        (json.origin, &json.entities),
        "json keeps the exact stored values"
    );
    let from_csv = HostMap::read(&dir.join("m.csv")).expect("csv map");
    for (a, b) in from_csv.entities.iter().zip(mema.entities.iter()) {
        let (wa, wb) = (
            from_csv.world_center(&a.entity),
            mema.world_center(&b.entity),
        );
        for j in 0..3 {
            assert!((wa[j] - wb[j]).abs() < 1e-6, "{wa:?} vs {wb:?}");
        }
        assert_eq!(a.kind, b.kind);
    }
    // The world centres lie inside the bunny's bounding box (x about -0.095..0.061 m).
    for e in &mema.entities {
        let c = mema.world_center(&e.entity);
        assert!((-0.1..0.07).contains(&c[0]), "{c:?}");
    }
}

#[test]
fn eval_json_has_the_documented_keys_and_consistent_figures() {
    let dir = Dir::new("eval");
    let car = shared("car6.pcd");
    let map = dir.join("car.mema");
    // k-means cells (no surface following): eval's eq. 13 takes each point to its nearest
    // centre, which is a k-means cell's membership up to its borders.
    let mapped = MemaCommand::new(&dir)
        .arg("map")
        .arg(&car)
        .args(["-k", "150", "--surface-rounds", "0", "--json", "-o"])
        .arg(&map)
        .run()
        .assert_ok();
    let m = mapped.json();
    let ran = MemaCommand::new(&dir)
        .arg("eval")
        .arg(&car)
        .arg(&map)
        .arg("--json")
        .run()
        .assert_ok();
    let v = ran.json();
    let keys: Vec<&str> = v
        .as_object()
        .expect("object")
        .keys()
        .map(String::as_str)
        .collect();
    let mut want = vec![
        "points",
        "clusters",
        "mean",
        "std",
        "max",
        "min",
        "total",
        "cloud_bytes",
        "map_bytes",
        "percent",
        // The two-way fidelity score and the file's bytes (issue 11), beside eq. 13.
        "accuracy",
        "completeness",
        "tau",
        "phantom",
        "precision",
        "recall",
        "f_score",
        "chamfer",
        "samples",
        "area",
        "file_bytes",
        "header_bytes",
        "bytes_per_entity",
        // The unit the cloud was read in, and the points dropped for NaN coordinates (issue 15).
        "unit",
        "dropped_non_finite",
    ];
    let mut got = keys.clone();
    want.sort();
    got.sort();
    assert_eq!(got, want);
    assert_eq!(v["points"], 10_031);
    assert_eq!(v["cloud_bytes"], 10_031 * 12);
    // Table 2's map bytes as map counts them (issue 33): the quantized records, the file less
    // its 52-byte header and checksum.
    let on_disk = std::fs::metadata(&map).expect("map file").len();
    assert_eq!(v["map_bytes"], on_disk - 52);
    assert_eq!(v["map_bytes"], m["memory"]["map_bytes"]);
    let clusters = v["clusters"].as_u64().expect("clusters");
    assert!(clusters > 140 && clusters <= 150, "{clusters}");
    let (mean, total) = (
        v["mean"].as_f64().expect("mean"),
        v["total"].as_f64().expect("total"),
    );
    assert!((mean * clusters as f64 - total).abs() < 1e-9 * total);
    // Nearest-centre membership differs from k-means' labels only at cluster borders.
    let map_mean = m["ellipsoidal"]["mean"].as_f64().expect("map mean");
    assert!(
        (mean / map_mean - 1.0).abs() < 0.15,
        "eval {mean} vs map {map_mean}"
    );
}

#[test]
fn info_counts_kinds_that_sum_to_the_entities() {
    let dir = Dir::new("info");
    let map = dir.join("p.mema");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(shared("five_people.pcd"))
        .args(["-k", "120", "-o"])
        .arg(&map)
        .run()
        .assert_ok();
    let v = MemaCommand::new(&dir)
        .arg("info")
        .arg(&map)
        .arg("--json")
        .run()
        .assert_ok()
        .json();
    let kinds = &v["kinds"];
    let sum: u64 = ["ellipsoid", "sphere", "pseudocylinder", "plane_pair"]
        .iter()
        .map(|k| kinds[k].as_u64().expect("count"))
        .sum();
    assert_eq!(sum, 120);
    assert_eq!(v["entities"], 120);
    // The default model's file: a 48-byte header, 14 bytes an entity, the checksum.
    assert_eq!(v["file_bytes"], 48 + 14 * 120 + 4);
    assert_eq!(v["record_bytes"], 14);
}

#[test]
fn demo_needs_no_files_and_writes_its_map() {
    let dir = Dir::new("demo");
    // The default: oriented shells on the quantized grid.
    let ran = MemaCommand::new(&dir).arg("demo").run().assert_ok();
    assert!(
        ran.stdout().contains("Table 2") && ran.stdout().contains("shells"),
        "{}",
        ran.stdout()
    );
    let map = HostMap::read(&dir.join("mema-demo/map.mema")).expect("demo map");
    assert_eq!(map.entities.len(), 250);
    assert!(
        map.quantization.is_some(),
        "the default demo map is quantized"
    );
    assert!(
        map.entities
            .iter()
            .any(|e| e.entity.rotation != mema_core::Rotation::IDENTITY),
        "no shell of the demo turned"
    );
    assert_eq!(dir.listing(), vec!["mema-demo".to_string()]);
    // The paper's method, one flag away, with its spherical comparison.
    let ran = MemaCommand::new(&dir)
        .args(["demo", "--paper"])
        .run()
        .assert_ok();
    assert!(
        ran.stdout().contains("ellipsoidal") && ran.stdout().contains("spherical"),
        "{}",
        ran.stdout()
    );
    // In a folder of its own (issue 33): the default's files stay.
    let map = HostMap::read(&dir.join("mema-demo-paper/map.mema")).expect("paper demo map");
    assert_eq!(map.entities.len(), 250);
    assert!(map.quantization.is_none());
    assert_eq!(dir.listing(), ["mema-demo", "mema-demo-paper"]);
    assert!(
        HostMap::read(&dir.join("mema-demo/map.mema"))
            .expect("the default demo's map")
            .quantization
            .is_some()
    );
    assert!(
        map.entities
            .iter()
            .all(|e| e.entity.rotation == mema_core::Rotation::IDENTITY)
    );
}
