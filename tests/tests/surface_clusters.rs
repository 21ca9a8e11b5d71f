//! Surface following after k-means (the shell model's default): on real scans it lowers the
//! two-way distance, the labels `--labels` writes are the clusters the map was built from
//! (each entity checked against its labelled points' covariance, decomposed by nalgebra), and
//! the labels do not depend on the thread count.

use crate::util::{Dir, MemaCommand, shared};
use mema::io::load_cloud;
use mema::io::mapfile::HostMap;
use mema::mapping::surface_clusters::follow_surfaces;
use mema_core::kmeans::KMeansParams;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use serde_json::Value;
use std::path::PathBuf;

fn map_and_eval(dir: &Dir, cloud: &str, rounds: usize) -> (PathBuf, Value, Value) {
    let out = dir.join(&format!("{cloud}.{rounds}.mema"));
    let labels = dir.join(&format!("{cloud}.{rounds}.labels"));
    let report = MemaCommand::new(dir)
        .arg("map")
        .arg(shared(cloud))
        .args([
            "--bytes",
            "9600",
            "--json",
            "--surface-rounds",
            &rounds.to_string(),
        ])
        .arg("--labels")
        .arg(&labels)
        .arg("-o")
        .arg(&out)
        .run()
        .assert_ok()
        .json();
    let score = MemaCommand::new(dir)
        .arg("eval")
        .arg(shared(cloud))
        .arg(&out)
        .arg("--json")
        .run()
        .assert_ok()
        .json();
    (labels, report, score)
}

fn number(v: &Value, path: &[&str]) -> f64 {
    path.iter()
        .fold(v, |v, k| &v[*k])
        .as_f64()
        .unwrap_or_else(|| panic!("{path:?} missing in {v}"))
}

#[test]
fn surface_following_brings_the_map_closer_to_real_scans_both_ways() {
    let dir = Dir::new("surface-following");
    // An indoor scan (walls meeting at edges, far-range layers) and a bunny scan.
    for (cloud, at_least) in [("office1.pcd", 0.15), ("bun_zipper.ply", 0.08)] {
        let (_, plain_report, plain) = map_and_eval(&dir, cloud, 0);
        let (_, report, followed) = map_and_eval(&dir, cloud, 30);
        assert!(
            plain_report["surface_rounds"].is_null(),
            "{cloud}: {plain_report}"
        );
        let rounds = number(&report, &["surface_rounds"]);
        assert!((1.0..=30.0).contains(&rounds), "{cloud}: {rounds} rounds");
        let gain = 1.0 - number(&followed, &["chamfer"]) / number(&plain, &["chamfer"]);
        assert!(
            gain >= at_least,
            "{cloud}: Chamfer {} with surface following, {} without ({:.1}% lower, want {:.0}%)",
            followed["chamfer"],
            plain["chamfer"],
            100.0 * gain,
            100.0 * at_least
        );
        for side in ["accuracy", "completeness"] {
            assert!(
                number(&followed, &[side, "mean"]) < number(&plain, &[side, "mean"]),
                "{cloud}: {side} {} with, {} without",
                followed[side],
                plain[side]
            );
        }
        assert_eq!(followed["clusters"], plain["clusters"], "{cloud}: entities");
    }
}

#[test]
fn the_labels_are_the_clusters_each_shell_was_made_from() {
    let dir = Dir::new("surface-labels");
    let cloud_name = "bun000.ply";
    let (labels_path, _, _) = map_and_eval(&dir, cloud_name, 30);
    let labels: Vec<usize> = std::fs::read_to_string(&labels_path)
        .expect("labels")
        .lines()
        .map(|l| l.parse().expect("a label"))
        .collect();
    let cloud = load_cloud(&shared(cloud_name)).expect("cloud");
    let map = HostMap::read(&dir.join(&format!("{cloud_name}.30.mema"))).expect("map");
    let grid = map.quantization.expect("shell maps are quantized");
    assert_eq!(labels.len(), cloud.points.len());
    let k = map.entities.len();
    assert_eq!(labels.iter().max().map(|m| m + 1), Some(k), "labels 0..k");

    // Direct per-point sums in f64, in the map's frame.
    let mut count = vec![0usize; k];
    let mut sum = vec![Vector3::<f64>::zeros(); k];
    let mut points = Vec::with_capacity(labels.len());
    for (p, &l) in cloud.points.iter().zip(&labels) {
        let q = p.to_f64();
        let v = Vector3::from_fn(|j, _| q[j] + (cloud.origin[j] - map.origin[j]));
        count[l] += 1;
        sum[l] += v;
        points.push(v);
    }
    let mean: Vec<Vector3<f64>> = sum.iter().zip(&count).map(|(s, &n)| s / n as f64).collect();
    let mut cov = vec![Matrix3::<f64>::zeros(); k];
    for (v, &l) in points.iter().zip(&labels) {
        let d = v - mean[l];
        cov[l] += d * d.transpose() / count[l] as f64;
    }
    let mut checked = 0;
    for (i, e) in map.entities.iter().enumerate() {
        assert!(count[i] > 0, "entity {i} has no labelled point");
        let c = e.entity.center.to_f64();
        let off = (0..3)
            .map(|j| (c[j] - mean[i][j]).abs())
            .fold(0.0, f64::max);
        assert!(
            off <= grid.centre_step as f64,
            "entity {i}: centre {c:?} is {off} from its points' mean {:?}",
            mean[i]
        );
        if count[i] < 8 {
            continue;
        }
        // The shell's semi-axes are 2 and 0.7 standard deviations along the principal axes.
        let eigen = SymmetricEigen::new(cov[i]);
        let mut sd: Vec<f64> = eigen
            .eigenvalues
            .iter()
            .map(|v| v.max(0.0).sqrt())
            .collect();
        sd.sort_by(|a, b| b.total_cmp(a));
        let mut axes = e.entity.semi_axes_f64();
        axes.sort_by(|a, b| b.total_cmp(a));
        let want = [2.0 * sd[0], 2.0 * sd[1], 0.7 * sd[2]];
        for j in 0..3 {
            if want[j] < 1e-3 * want[0] {
                continue; // floored at min_ratio of the longest
            }
            let rel = (axes[j] / want[j] - 1.0).abs();
            assert!(
                rel < 0.02,
                "entity {i} axis {j}: {} vs {}",
                axes[j],
                want[j]
            );
        }
        checked += 1;
    }
    assert!(
        checked * 10 >= k * 9,
        "only {checked} of {k} shells checked"
    );
}

#[test]
fn surface_following_gives_the_same_labels_on_one_and_two_threads() {
    let cloud = load_cloud(&shared("car6.pcd")).expect("cloud");
    let clusters = mema::mapping::pipeline::cluster(&cloud.points, 300, &KMeansParams::default())
        .expect("k-means");
    let centres: Vec<mema_core::Point3> = clusters
        .moments
        .iter()
        .map(|m| mema_core::Point3::new(m.mean[0] as f32, m.mean[1] as f32, m.mean[2] as f32))
        .collect();
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| follow_surfaces(&cloud.points, &clusters.labels, &centres, 30))
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.labels, two.labels);
    assert_eq!(one.rounds, two.rounds);
    assert!(one.labels != clusters.labels, "no point moved");
}
