//! Rotations are exact: turning a cloud and its map by the same rotation leaves the two-way score
//! unchanged (within 1e-5 relative), for a shells map and for the paper's axis-aligned map,
//! which the rotation turns into oriented entities.

use crate::util::{Dir, MemaCommand, shared};
use mema::analysis::fidelity::{FidelityScore, two_way_score};
use mema::io::load_cloud;
use mema::io::mapfile::HostMap;
use mema::query::transform_map;
use mema_core::transform::RigidTransform;

/// A rotation from a seeded uniform quaternion (Shoemake's method), as a matrix.
fn random_rotation(seed: u64) -> [[f64; 3]; 3] {
    let mut s = seed;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let (u1, u2, u3) = (next(), next(), next());
    let tau = std::f64::consts::TAU;
    crate::util::quaternion_matrix([
        (1.0 - u1).sqrt() * (tau * u2).sin(),
        (1.0 - u1).sqrt() * (tau * u2).cos(),
        u1.sqrt() * (tau * u3).sin(),
        u1.sqrt() * (tau * u3).cos(),
    ])
}

fn figures(s: &FidelityScore) -> [(&'static str, f64); 8] {
    [
        ("accuracy mean", s.accuracy.mean),
        ("accuracy rms", s.accuracy.rms),
        ("completeness mean", s.completeness.mean),
        ("completeness rms", s.completeness.rms),
        ("tau", s.tau),
        ("chamfer", s.chamfer),
        ("area", s.area),
        ("f_score", s.f_score),
    ]
}

#[test]
fn a_turned_cloud_and_map_score_as_the_originals() {
    let dir = Dir::new("rotation-invariance");
    let cloud = load_cloud(&shared("bun000.ply")).expect("cloud");
    for (seed, model) in [(1u64, "shells"), (2, "paper")] {
        let path = dir.join(&format!("{model}.mema"));
        MemaCommand::new(&dir)
            .arg("map")
            .arg(shared("bun000.ply"))
            .args(["--bytes", "9600", "--model", model, "-o"])
            .arg(&path)
            .run()
            .assert_ok();
        let map = HostMap::read(&path).expect("map");
        let shift: Vec<f64> = (0..3).map(|j| cloud.origin[j] - map.origin[j]).collect();
        let points: Vec<[f64; 3]> = cloud
            .points
            .iter()
            .map(|p| {
                let q = p.to_f64();
                [q[0] + shift[0], q[1] + shift[1], q[2] + shift[2]]
            })
            .collect();
        let rotation = random_rotation(seed);
        let turn = RigidTransform {
            rotation,
            translation: [0.0; 3],
        };
        // The map's frame turns about its own origin: local points go to R p.
        let turned_map = transform_map(&map, &turn).expect("a rotation");
        let turned_points: Vec<[f64; 3]> = points.iter().map(|p| turn.apply_point(*p)).collect();
        let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
        let turned: Vec<_> = turned_map.entities.iter().map(|e| e.entity).collect();
        assert!(turned.iter().all(|e| !e.rotation.is_identity()), "{model}");
        let before = two_way_score(&points, &entities, 0, 50_000).expect("score");
        let after = two_way_score(&turned_points, &turned, 0, 50_000).expect("score");
        for ((name, a), (_, b)) in figures(&before).into_iter().zip(figures(&after)) {
            let relative = (a - b).abs() / a.abs().max(1e-300);
            eprintln!("{model}: {name} {a:.9e} turned {b:.9e} ({relative:.1e})");
            assert!(relative < 1e-5, "{model}: {name} {a} turned {b}");
        }
    }
}
