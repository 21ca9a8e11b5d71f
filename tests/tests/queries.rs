//! Map queries through the index against a brute-force scan of every entity, on maps of real
//! clouds, including one whose entities degenerate (pseudocylinders).

use crate::util::{Dir, MemaCommand, shared};
use mema::io::load_cloud;
use mema::io::mapfile::HostMap;
use mema::mapping::pipeline;
use mema::query::{build_index, random_queries, transform_map};
use mema_core::fit::SemiAxisBounds;
use mema_core::query::{brute_force, contains};
use mema_core::transform::RigidTransform;

fn map_of(cloud: &str, k: usize, threshold_box: bool) -> HostMap {
    let local = load_cloud(&shared(cloud)).expect("cloud");
    let mut config = mema::mapping::FitOptions::default()
        .config(k)
        .expect("config");
    if threshold_box {
        config.fit.bounds = SemiAxisBounds::Threshold { lower: 0.05 };
    }
    let clusters = pipeline::cluster(&local.points, k, &config.kmeans).expect("clusters");
    let fitted = pipeline::fit_all(&clusters.moments, 0, &config.fit);
    pipeline::to_map(local.origin, &fitted.ellipsoids, 0.01)
}

#[test]
fn index_answers_equal_the_brute_force_scan_on_100k_queries() {
    for (cloud, k, threshold_box, queries) in [
        ("car6.pcd", 150, false, 50_000),
        ("bun_zipper.ply", 350, true, 50_000),
    ] {
        let map = map_of(cloud, k, threshold_box);
        let degenerated = map
            .entities
            .iter()
            .filter(|e| e.entity.degenerated_axes() > 0)
            .count();
        if threshold_box {
            assert!(
                degenerated > 0,
                "{cloud}: the threshold box should degenerate some entities"
            );
        }
        let index = build_index(&map).expect("index");
        let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
        let (mut hits, mut inside) = (0, 0);
        for (p, d) in random_queries(&map, queries, 7) {
            let nearest = index.nearest(p);
            assert_eq!(
                nearest,
                brute_force::nearest(&entities, p),
                "{cloud}: nearest at {p:?}"
            );
            let occupied = index.occupied(p);
            assert_eq!(
                occupied,
                brute_force::occupied(&entities, p),
                "{cloud}: occupancy at {p:?}"
            );
            let ray = index.ray_cast(p, d, 1e9);
            assert_eq!(
                ray,
                brute_force::ray_cast(&entities, p, d, 1e9),
                "{cloud}: ray from {p:?}"
            );
            if let Some(hit) = ray {
                hits += 1;
                // The hit lies on the entity's surface: sum w (x - c)^2 = 1.
                let e = &entities[hit.entity];
                let c = e.center.to_f64();
                let s: f64 = (0..3)
                    .map(|j| e.weights[j] as f64 * (hit.point[j] - c[j]).powi(2))
                    .sum();
                assert!((s - 1.0).abs() < 1e-6, "{cloud}: hit off the surface ({s})");
            }
            if let Some(n) = nearest {
                // The sign agrees with an independent containment test over all entities.
                let any_inside = entities.iter().any(|e| contains(e, p));
                assert_eq!(
                    n.signed_distance < 0.0,
                    any_inside && n.signed_distance != 0.0
                );
                inside += usize::from(any_inside);
            }
        }
        eprintln!(
            "{cloud}: {queries} points x 3 queries agree; {hits} rays hit, {inside} points inside; {degenerated} degenerated entities"
        );
        assert!(
            hits > queries / 20 && inside > 0,
            "{cloud}: queries too easy ({hits} hits, {inside} inside)"
        );
    }
}

#[test]
fn translations_and_axis_permutations_move_answers_exactly() {
    let map = map_of("car6.pcd", 150, false);
    let index = build_index(&map).expect("index");
    let quarter = RigidTransform::rotation_about(2, std::f64::consts::FRAC_PI_2);
    let permutation = RigidTransform {
        rotation: quarter.rotation.map(|r| r.map(f64::round)),
        ..quarter
    };
    let t = RigidTransform::translation([12.5, -3.25, 100.0]).after(&permutation);
    assert!(t.is_axis_permutation());
    let moved = transform_map(&map, &t).expect("a rotation");
    let moved_index = build_index(&moved).expect("index");
    for (p, d) in random_queries(&map, 2000, 3) {
        // Queries take map-local coordinates: world = origin + local.
        let world = [
            p[0] + map.origin[0],
            p[1] + map.origin[1],
            p[2] + map.origin[2],
        ];
        let w2 = t.apply_point(world);
        let q = [
            w2[0] - moved.origin[0],
            w2[1] - moved.origin[1],
            w2[2] - moved.origin[2],
        ];
        let (a, b) = (
            index.nearest(p).expect("nearest"),
            moved_index.nearest(q).expect("nearest"),
        );
        assert_eq!(a.entity, b.entity);
        assert!(
            (a.signed_distance - b.signed_distance).abs() < 1e-5,
            "{a:?} vs {b:?}"
        );
        let (ra, rb) = (
            index.ray_cast(p, d, 1e9),
            moved_index.ray_cast(q, t.rotate_vector(d), 1e9),
        );
        assert_eq!(ra.map(|h| h.entity), rb.map(|h| h.entity));
        if let (Some(ra), Some(rb)) = (ra, rb) {
            assert!((ra.t - rb.t).abs() < 1e-5 * (1.0 + ra.t));
        }
    }
}

#[test]
fn query_command_answers_in_world_coordinates() {
    let dir = Dir::new("query");
    let map_path = dir.join("car.mema");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(shared("car6.pcd"))
        .args(["-k", "150", "-o"])
        .arg(&map_path)
        .run()
        .assert_ok();
    let map = HostMap::read(&map_path).expect("map");
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    // The first entity's centre, in world coordinates: inside the map.
    let c = map.world_center(&entities[0]);
    let point = format!("--point={},{},{}", c[0], c[1], c[2]);
    let v = MemaCommand::new(&dir)
        .arg("query")
        .arg(&map_path)
        .arg(&point)
        .arg("--json")
        .run()
        .assert_ok()
        .json();
    let local = [
        c[0] - map.origin[0],
        c[1] - map.origin[1],
        c[2] - map.origin[2],
    ];
    let want = brute_force::nearest(&entities, local).expect("nearest");
    assert_eq!(v["nearest_entity"], want.entity);
    assert!(
        (v["signed_distance"].as_f64().expect("distance") - want.signed_distance).abs() < 1e-12
    );
    assert!(
        v["signed_distance"].as_f64().expect("distance") < 0.0,
        "a centre is inside its ellipsoid"
    );
    assert!(v["occupied_by"].as_u64().is_some());
    let ray = format!("--ray={},{},{},0,0,1", c[0], c[1], c[2] - 50.0);
    let r = MemaCommand::new(&dir)
        .arg("query")
        .arg(&map_path)
        .arg(&ray)
        .arg("--json")
        .run()
        .assert_ok()
        .json();
    assert_eq!(r["hit"], true);
    MemaCommand::new(&dir)
        .arg("query")
        .arg(&map_path)
        .arg("--point=1,2")
        .run()
        .assert_error(2, "--point");
}

#[test]
fn index_answers_equal_the_brute_force_scan_on_oriented_maps() {
    // Shells of car6 (every entity turned), and the bunny's threshold-box map (pseudocylinders)
    // turned by a general rotation, so degenerated axes point off the world axes.
    let car = {
        let local = load_cloud(&shared("car6.pcd")).expect("cloud");
        let config = mema::mapping::FitOptions::default()
            .config(150)
            .expect("config");
        let clusters = pipeline::cluster(&local.points, 150, &config.kmeans).expect("clusters");
        let centres: Vec<_> = clusters
            .moments
            .iter()
            .map(|m| mema_core::Point3::new(m.mean[0] as f32, m.mean[1] as f32, m.mean[2] as f32))
            .collect();
        mema::mapping::shells::shell_map(
            local.origin,
            &local.points,
            &clusters.labels,
            &centres,
            &mema_core::shell::ShellParams::default(),
        )
    };
    let turn = RigidTransform::rotation_about(0, 0.3)
        .after(&RigidTransform::rotation_about(1, -1.1))
        .after(&RigidTransform::rotation_about(2, 0.7));
    let bunny = transform_map(&map_of("bun_zipper.ply", 350, true), &turn).expect("a rotation");
    for (name, map) in [("car6 shells", car), ("turned bunny", bunny)] {
        let turned = map
            .entities
            .iter()
            .filter(|e| !e.entity.rotation.is_identity())
            .count();
        assert!(
            turned * 10 > map.entities.len() * 9,
            "{name}: {turned} turned"
        );
        let index = build_index(&map).expect("index");
        let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
        let mut hits = 0;
        for (p, d) in random_queries(&map, 20_000, 11) {
            assert_eq!(
                index.nearest(p),
                brute_force::nearest(&entities, p),
                "{name}: nearest at {p:?}"
            );
            assert_eq!(
                index.occupied(p),
                brute_force::occupied(&entities, p),
                "{name}: occupancy at {p:?}"
            );
            let ray = index.ray_cast(p, d, 1e9);
            assert_eq!(
                ray,
                brute_force::ray_cast(&entities, p, d, 1e9),
                "{name}: ray from {p:?}"
            );
            if let Some(hit) = ray {
                hits += 1;
                // On the surface in the entity's own frame: sum w (R^T (x - c))^2 = 1.
                let e = &entities[hit.entity];
                let (c, m) = (
                    e.center.to_f64(),
                    crate::util::quaternion_matrix(e.rotation.to_array().map(f64::from)),
                );
                let d = [0, 1, 2].map(|j| hit.point[j] - c[j]);
                let s: f64 = (0..3)
                    .map(|j| {
                        let local: f64 = (0..3).map(|i| m[i][j] * d[i]).sum();
                        e.weights[j] as f64 * local * local
                    })
                    .sum();
                assert!((s - 1.0).abs() < 1e-5, "{name}: hit off the surface ({s})");
            }
        }
        assert!(hits > 1000, "{name}: queries too easy ({hits} hits)");
    }
}

/// `transform` labels each moved entity by its infinite axes, as the kinds are defined (one a
/// pseudocylinder, two a pair of planes), even where the map it read was labelled otherwise
/// (written by another tool, or by hand); a finite entity keeps its ellipsoid or sphere.
#[test]
fn transform_labels_kinds_by_their_infinite_axes() {
    let dir = Dir::new("transform-kinds");
    let bunny = shared("bun_zipper.ply");
    let mut rows = Vec::new();
    // Thresholds at which the bunny's clusters degenerate: one infinite axis, then two.
    for threshold in ["0.02", "0.012"] {
        MemaCommand::new(&dir)
            .arg("map")
            .arg(&bunny)
            .args(["--paper", "-k", "40", "--bounds", "threshold"])
            .args(["--threshold", threshold, "-o", "deg.csv"])
            .run()
            .assert_ok();
        let csv = std::fs::read_to_string(dir.join("deg.csv")).expect("csv");
        rows.extend(csv.lines().skip(1).map(str::to_owned));
    }
    let infinite = |row: &str| {
        let fields: Vec<&str> = row.split(',').collect();
        fields[3..6].iter().filter(|r| **r == "inf").count()
    };
    let counts = |rows: &[String], n| rows.iter().filter(|r| infinite(r) == n).count();
    assert!(counts(&rows, 1) > 0 && counts(&rows, 2) > 0, "{rows:?}");
    // Every entity labelled an ellipsoid, whatever its axes.
    let mislabelled: String = rows
        .iter()
        .map(|r| {
            let keep = r.rsplit_once(',').expect("kind column").0;
            format!("{keep},ellipsoid\n")
        })
        .collect();
    dir.write(
        "labelled.csv",
        format!("cx,cy,cz,rx,ry,rz,qx,qy,qz,qw,kind\n{mislabelled}").as_bytes(),
    );
    for rotate in ["30,20,10", "90,0,0", "0,0,0"] {
        MemaCommand::new(&dir)
            .args([
                "transform",
                "labelled.csv",
                "-o",
                "moved.csv",
                "--rotate",
                rotate,
            ])
            .run()
            .assert_ok();
        let moved = std::fs::read_to_string(dir.join("moved.csv")).expect("moved");
        let moved: Vec<&str> = moved.lines().skip(1).collect();
        assert_eq!(moved.len(), rows.len());
        for row in moved {
            let kind = row.rsplit(',').next().expect("kind");
            let want = match infinite(row) {
                0 => "ellipsoid",
                1 => "pseudocylinder",
                _ => "plane_pair",
            };
            assert_eq!(kind, want, "--rotate {rotate}: {row}");
        }
    }
}
