//! `mema eval`'s two-way fidelity score against an independent brute-force computation on real
//! clouds, on a cloud drawn exactly on known entities, and under a moved entity (the triangle
//! inequality). The sampler's uniformity by area is checked in host's `fidelity::tests`.

use crate::util::{Dir, MemaCommand, shared};
use mema::analysis::fidelity;
use mema::io::load_cloud_in_metres;
use mema::io::mapfile::HostMap;
use mema_core::Entity;
use mema_core::closest_point::surface_distance;
use rayon::prelude::*;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn map_with_binary(dir: &Dir, cloud: &str, k: usize, model: &str) -> PathBuf {
    let out = dir.join(&format!("{cloud}.{k}.{model}.mema"));
    MemaCommand::new(dir)
        .arg("map")
        .arg(shared(cloud))
        .args(["-k", &k.to_string(), "--model", model, "-o"])
        .arg(&out)
        .run()
        .assert_ok();
    out
}

fn eval_json(dir: &Dir, cloud: &Path, map: &Path, extra: &[&str]) -> Value {
    MemaCommand::new(dir)
        .arg("eval")
        .arg(cloud)
        .arg(map)
        .arg("--json")
        .args(extra)
        .run()
        .assert_ok()
        .json()
}

/// The cloud's points in the map's frame, from the two f64 origins; in metres, as `mema map`
/// reads them.
fn points_and_entities(cloud: &Path, map: &Path) -> (Vec<[f64; 3]>, Vec<Entity>) {
    let (cloud, _) = load_cloud_in_metres(cloud, None).expect("cloud");
    let map = HostMap::read(map).expect("map");
    let points = cloud
        .points
        .iter()
        .map(|p| {
            let q = p.to_f64();
            [0, 1, 2].map(|j| q[j] + (cloud.origin[j] - map.origin[j]))
        })
        .collect();
    (points, map.entities.iter().map(|e| e.entity).collect())
}

/// Distance to the nearest surface by scanning every entity.
fn brute_accuracy(points: &[[f64; 3]], entities: &[Entity]) -> Vec<f64> {
    points
        .par_iter()
        .map(|&p| {
            entities
                .iter()
                .map(|e| surface_distance(e, p))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// Distance to the nearest cloud point (other than `skip`) by scanning every point.
fn brute_nearest(points: &[[f64; 3]], q: [f64; 3], skip: Option<usize>) -> f64 {
    points
        .iter()
        .enumerate()
        .filter(|(i, _)| Some(*i) != skip)
        .map(|(_, p)| (0..3).map(|j| (p[j] - q[j]).powi(2)).sum::<f64>())
        .fold(f64::INFINITY, f64::min)
        .sqrt()
}

fn get(v: &Value, path: &[&str]) -> f64 {
    path.iter()
        .fold(v, |v, k| &v[*k])
        .as_f64()
        .unwrap_or_else(|| panic!("{path:?} missing in {v}"))
}

fn close(got: f64, want: f64, what: &str) {
    assert!(
        (got - want).abs() <= 1e-9 * want.abs().max(1e-12),
        "{what}: eval says {got}, brute force {want}"
    );
}

#[test]
fn eval_score_equals_a_brute_force_computation_on_real_clouds() {
    let dir = Dir::new("fidelity-brute");
    // car6: all points; simple.las: a map of pseudocylinders and plane pairs, whose infinite
    // axes the sampler cuts to their points; car6 again in oriented, quantized shells.
    for (cloud, k, model) in [
        ("car6.pcd", 400, "paper"),
        ("simple.las", 100, "paper"),
        ("car6.pcd", 400, "shells"),
    ] {
        let map = map_with_binary(&dir, cloud, k, model);
        let (samples, seed) = (20_000, 5);
        let v = eval_json(
            &dir,
            &shared(cloud),
            &map,
            &["--samples", "20000", "--seed", "5"],
        );
        let (points, entities) = points_and_entities(&shared(cloud), &map);

        let mut accuracy = brute_accuracy(&points, &entities);
        let n = accuracy.len() as f64;
        let spacing: Vec<f64> = (0..points.len())
            .into_par_iter()
            .map(|i| brute_nearest(&points, points[i], Some(i)))
            .collect();
        let mut sorted = spacing.clone();
        sorted.sort_by(f64::total_cmp);
        let m = sorted.len() / 2;
        let tau = if sorted.len() % 2 == 1 {
            2.0 * sorted[m]
        } else {
            sorted[m - 1] + sorted[m]
        };

        let drawn = fidelity::surface_samples(&points, &entities, seed, samples);
        assert_eq!(drawn.len() as f64, get(&v, &["samples"]), "{cloud}");
        // Every sample lies on its own entity's surface.
        for s in drawn.iter().step_by(13) {
            let d = surface_distance(&entities[s.entity as usize], s.point);
            assert!(
                d < 1e-6,
                "{cloud}: sample {:?} is {d} off its surface",
                s.point
            );
        }
        let mut completeness: Vec<(f64, f64)> = drawn
            .par_iter()
            .map(|s| (brute_nearest(&points, s.point, None), s.weight))
            .collect();
        let area: f64 = completeness.iter().map(|c| c.1).sum();

        close(get(&v, &["tau"]), tau, "tau");
        close(get(&v, &["area"]), area, "area");
        close(
            get(&v, &["accuracy", "mean"]),
            accuracy.iter().sum::<f64>() / n,
            "accuracy mean",
        );
        close(
            get(&v, &["accuracy", "rms"]),
            (accuracy.iter().map(|d| d * d).sum::<f64>() / n).sqrt(),
            "accuracy rms",
        );
        accuracy.sort_by(f64::total_cmp);
        let rank = (0.95 * n).ceil() as usize - 1;
        close(
            get(&v, &["accuracy", "p95"]),
            accuracy[rank],
            "accuracy p95",
        );
        close(
            get(&v, &["accuracy", "max"]),
            accuracy[accuracy.len() - 1],
            "accuracy max",
        );
        let by_area = |f: &dyn Fn(f64) -> f64| {
            completeness.iter().map(|&(d, w)| w * f(d)).sum::<f64>() / area
        };
        let (c_mean, c_rms) = (by_area(&|d| d), by_area(&|d| d * d).sqrt());
        let precision = by_area(&|d| f64::from(u8::from(d <= tau)));
        close(
            get(&v, &["completeness", "mean"]),
            c_mean,
            "completeness mean",
        );
        close(get(&v, &["completeness", "rms"]), c_rms, "completeness rms");
        close(get(&v, &["precision"]), precision, "precision");
        close(get(&v, &["phantom"]), 1.0 - precision, "phantom");
        let recall = accuracy.iter().filter(|&&d| d <= tau).count() as f64 / n;
        close(get(&v, &["recall"]), recall, "recall");
        close(
            get(&v, &["f_score"]),
            2.0 * precision * recall / (precision + recall),
            "F-score",
        );
        close(
            get(&v, &["chamfer"]),
            0.5 * (accuracy.iter().sum::<f64>() / n + c_mean),
            "chamfer",
        );
        completeness.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut cumulative = 0.0;
        let p95 = completeness
            .iter()
            .find(|&&(_, w)| {
                cumulative += w;
                cumulative >= 0.95 * area
            })
            .map(|c| c.0)
            .expect("p95");
        close(get(&v, &["completeness", "p95"]), p95, "completeness p95");
        // What the file takes on disk, not a formula.
        let on_disk = std::fs::metadata(&map).expect("map").len() as f64;
        assert_eq!(get(&v, &["file_bytes"]), on_disk);
        close(
            get(&v, &["bytes_per_entity"]),
            (on_disk - get(&v, &["header_bytes"])) / entities.len() as f64,
            "bytes per entity",
        );
        eprintln!(
            "{cloud} k {k} {model}: accuracy mean {:.6}, completeness mean {c_mean:.6}, tau {tau:.6}, phantom {:.3}",
            get(&v, &["accuracy", "mean"]),
            1.0 - precision
        );
    }
}

#[test]
fn accuracy_equals_the_scan_of_every_entity_on_subsampled_points() {
    let dir = Dir::new("fidelity-subsampled");
    // Bunny scan, people in a room, an aerial LAZ (in feet, mapped in metres), and oriented
    // shells of the people.
    for (cloud, k, step, model) in [
        ("bun000.ply", 400, 23, "paper"),
        ("five_people.pcd", 700, 97, "paper"),
        ("autzen_trim.laz", 400, 61, "paper"),
        ("five_people.pcd", 700, 97, "shells"),
    ] {
        let map = map_with_binary(&dir, cloud, k, model);
        let (points, entities) = points_and_entities(&shared(cloud), &map);
        let fast = fidelity::accuracy_distances(&points, &entities);
        let subsample: Vec<[f64; 3]> = points.iter().copied().step_by(step).collect();
        let brute = brute_accuracy(&subsample, &entities);
        for (i, b) in brute.iter().enumerate() {
            // The same distances, so the same minimum to the bit.
            assert_eq!(
                fast[i * step].to_bits(),
                b.to_bits(),
                "{cloud} {model}: point {}",
                i * step
            );
        }
    }
}

/// A dense, roughly even cloud on the surface `|x / r|^2 = 1` in the entity's own axes
/// (Fibonacci lattice mapped from the sphere), an independent drawing from the scorer's
/// area-uniform sampler.
fn fibonacci_on_ellipsoid(r: [f64; 3], n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let rho = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            let u = [rho * t.cos(), rho * t.sin(), z];
            [0, 1, 2].map(|j| r[j] * u[j])
        })
        .collect()
}

/// An entity's semi-axes, kind, and the points drawn on it in its own axes.
type Drawn = ([f64; 3], &'static str, Vec<[f64; 3]>);

/// Three ellipsoids, a pseudocylinder and a plane pair, drawn densely in their own axes and
/// placed at georeferenced-sized centres (so both origins matter), turned by a quaternion each
/// when `turned`: the cloud as XYZ text and the map as CSV.
fn drawn_scene(turned: bool) -> (String, String, f64) {
    let inf = f64::INFINITY;
    let mut entities: Vec<Drawn> = Vec::new();
    for (r, kind) in [
        ([0.5, 0.3, 0.2], "ellipsoid"),
        ([0.25, 0.25, 0.25], "sphere"),
        ([0.6, 0.4, 0.05], "ellipsoid"),
    ] {
        entities.push((r, kind, fibonacci_on_ellipsoid(r, 20_000)));
    }
    // A pseudocylinder along y (radii 0.2 in x, 0.3 in z) drawn over y in [-0.8, 0.8].
    let mut tube = Vec::new();
    for i in 0..200 {
        for k in 0..200 {
            let t = std::f64::consts::TAU * k as f64 / 200.0;
            tube.push([0.2 * t.cos(), -0.8 + 1.6 * i as f64 / 199.0, 0.3 * t.sin()]);
        }
    }
    entities.push(([0.2, inf, 0.3], "pseudocylinder", tube));
    // Two planes z = +-0.1 drawn over x in [-0.5, 0.5], y in [-0.4, 0.4].
    let mut planes = Vec::new();
    for i in 0..125 {
        for k in 0..100 {
            for z in [-0.1, 0.1] {
                planes.push([-0.5 + i as f64 / 124.0, -0.4 + 0.8 * k as f64 / 99.0, z]);
            }
        }
    }
    entities.push(([inf, inf, 0.1], "plane_pair", planes));

    let quaternions = [
        [0.3, -0.2, 0.5, 0.78],
        [0.0, 0.0, 0.0, 1.0],
        [-0.6, 0.1, 0.2, 0.5],
        [0.4, 0.4, -0.1, 0.7],
        [0.1, -0.7, 0.3, 0.2],
    ];
    let (mut text, mut csv) = (String::new(), String::new());
    csv.push_str(if turned {
        "cx,cy,cz,rx,ry,rz,qx,qy,qz,qw,kind\n"
    } else {
        "cx,cy,cz,rx,ry,rz,kind\n"
    });
    let mut area = 0.0;
    for (i, (r, kind, local)) in entities.iter().enumerate() {
        let c = [631_000.0 + 3.0 * i as f64, 4_833_000.0, 120.0];
        let q = if turned {
            quaternions[i]
        } else {
            [0.0, 0.0, 0.0, 1.0]
        };
        let m = crate::util::quaternion_matrix(q);
        for p in local {
            let w = [0, 1, 2].map(|a| c[a] + (0..3).map(|b| m[a][b] * p[b]).sum::<f64>());
            text.push_str(&format!("{} {} {}\n", w[0], w[1], w[2]));
        }
        let row = format!("{},{},{},{},{},{}", c[0], c[1], c[2], r[0], r[1], r[2]);
        if turned {
            let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            let q = q.map(|v| v / n);
            csv.push_str(&format!(
                "{row},{},{},{},{},{kind}\n",
                q[0], q[1], q[2], q[3]
            ));
        } else {
            csv.push_str(&format!("{row},{kind}\n"));
        }
        area += match *kind {
            // The cut surfaces have the drawn areas: the tube's perimeter x 1.6, planes 2 x 0.8.
            "pseudocylinder" => 1.6 * fidelity::surface::ellipse_perimeter(r[0], r[2]),
            "plane_pair" => 2.0 * 0.8,
            _ => fidelity::surface::ellipsoid_area(r[0], r[1], r[2]),
        };
    }
    (text, csv, area)
}

#[test]
fn a_cloud_drawn_on_known_entities_scores_about_zero_both_ways() {
    let dir = Dir::new("fidelity-synthetic");
    for turned in [false, true] {
        let (text, csv, area) = drawn_scene(turned);
        let cloud_path = dir.write("drawn.xyz", text.as_bytes());
        let map_path = dir.write("known.csv", csv.as_bytes());
        let v = eval_json(&dir, &cloud_path, &map_path, &[]);
        let spacing = get(&v, &["tau"]) / 2.0;
        // Points are stored as f32 about a centre metres away: float precision is ~1e-6.
        assert!(get(&v, &["accuracy", "max"]) < 5e-6, "turned {turned}: {v}");
        assert!(
            get(&v, &["accuracy", "mean"]) < 1e-6,
            "turned {turned}: {v}"
        );
        // A surface sample is never farther from the drawn points than the spacing of their grid.
        assert!(
            get(&v, &["completeness", "mean"]) < 0.5 * spacing,
            "turned {turned}: {v}"
        );
        assert!(
            get(&v, &["completeness", "p95"]) < spacing,
            "turned {turned}: {v}"
        );
        assert_eq!(get(&v, &["phantom"]), 0.0, "turned {turned}: {v}");
        assert_eq!(get(&v, &["f_score"]), 1.0, "turned {turned}: {v}");
        assert!(
            (get(&v, &["area"]) / area - 1.0).abs() < 1e-5,
            "turned {turned}: area {} vs {area}",
            get(&v, &["area"])
        );
    }
}

#[test]
fn moving_one_entity_by_d_moves_each_points_accuracy_by_at_most_d() {
    let dir = Dir::new("fidelity-moved");
    let map_path = map_with_binary(&dir, "bun000.ply", 400, "paper");
    let (points, entities) = points_and_entities(&shared("bun000.ply"), &map_path);
    let before = fidelity::accuracy_distances(&points, &entities);
    // The entity nearest most points' centres, moved 2 mm (about its own thickness).
    let mut counts = vec![0usize; entities.len()];
    for p in &points {
        let nearest = (0..entities.len())
            .min_by(|&a, &b| {
                let d = |e: usize| {
                    let c = entities[e].center.to_f64();
                    (0..3).map(|j| (p[j] - c[j]).powi(2)).sum::<f64>()
                };
                d(a).total_cmp(&d(b))
            })
            .expect("entities");
        counts[nearest] += 1;
    }
    let moved_index = (0..entities.len()).max_by_key(|&e| counts[e]).expect("e");
    let mut moved = entities.clone();
    let step = [0.0012f32, -0.0006, 0.0014];
    let c = &mut moved[moved_index].center;
    let old = c.to_f64();
    *c = mema_core::Point3::new(c.x + step[0], c.y + step[1], c.z + step[2]);
    // The displacement the f32 centre really made.
    let new = c.to_f64();
    let d = (0..3)
        .map(|j| (new[j] - old[j]).powi(2))
        .sum::<f64>()
        .sqrt();
    let after = fidelity::accuracy_distances(&points, &moved);
    let mut worst_rise: f64 = 0.0;
    for (i, (a, b)) in before.iter().zip(&after).enumerate() {
        assert!(
            (b - a).abs() <= d * (1.0 + 1e-9),
            "point {i}: {a} -> {b}, d {d}"
        );
        worst_rise = worst_rise.max(b - a);
    }
    assert!(
        worst_rise > 0.3 * d,
        "the move changed nothing: {worst_rise} of {d}"
    );

    // The same through the binary: the moved map's mean and max rise by at most d.
    let mut map = HostMap::read(&map_path).expect("map");
    map.entities[moved_index].entity = moved[moved_index];
    let moved_path = dir.join("moved.mema");
    map.write(&moved_path).expect("write");
    let a = eval_json(&dir, &shared("bun000.ply"), &map_path, &[]);
    let b = eval_json(&dir, &shared("bun000.ply"), &moved_path, &[]);
    for key in ["mean", "max"] {
        let (x, y) = (get(&a, &["accuracy", key]), get(&b, &["accuracy", key]));
        assert!(
            y - x <= d * (1.0 + 1e-9),
            "accuracy {key}: {x} -> {y}, d {d}"
        );
    }
    assert_ne!(
        get(&a, &["accuracy", "mean"]),
        get(&b, &["accuracy", "mean"])
    );
}
