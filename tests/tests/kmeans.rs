//! Accelerated k-means against the plain reference on the real clouds: the same labels, the
//! same centre bits, the same outcome, on any number of threads; and the scene and memory facts
//! the benchmarks rely on.

use crate::util::{shared, shared_data};
use mema::bench::environment;
use mema::io::load_cloud;
use mema::mapping::pipeline::{self, KMeansEngine, KMeansRun, run_kmeans};
use mema_core::Point3;
use mema_core::kmeans::accel::{SeedList, seed_plus_plus_fast};
use mema_core::kmeans::{BLOCK, KMeansParams, seed_plus_plus};

fn bits(points: &[Point3]) -> Vec<[u32; 3]> {
    points
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

fn assert_same_run(what: &str, a: &KMeansRun, b: &KMeansRun) {
    assert_eq!(a.labels, b.labels, "{what}: labels");
    assert_eq!(bits(&a.centres), bits(&b.centres), "{what}: centre bits");
    assert_eq!(a.outcome.iterations, b.outcome.iterations, "{what}");
    assert_eq!(a.outcome.converged, b.outcome.converged, "{what}");
    assert_eq!(
        a.outcome.inertia.to_bits(),
        b.outcome.inertia.to_bits(),
        "{what}: inertia"
    );
}

#[test]
fn accelerated_equals_plain_on_real_clouds() {
    // (cloud, k, iteration cap): converged runs and capped ones, small k and large.
    let cases = [
        ("car6.pcd", 150, 100),
        ("lamppost.pcd", 40, 100),
        ("milk.pcd", 120, 100),
        ("bun_zipper.ply", 350, 100),
        ("rops_cloud.pcd", 300, 100),
        ("five_people.pcd", 350, 100),
        ("cturtle.pcd", 600, 25),
        ("office1.pcd", 1000, 8),
    ];
    for (name, k, cap) in cases {
        let cloud = load_cloud(&shared(name)).expect(name);
        for seed in [0, 1] {
            let params = KMeansParams {
                max_iterations: cap,
                seed,
                ..KMeansParams::default()
            };
            let plain = run_kmeans(&cloud.points, k, &params, KMeansEngine::Plain).expect(name);
            let fast =
                run_kmeans(&cloud.points, k, &params, KMeansEngine::Accelerated).expect(name);
            assert_same_run(&format!("{name} k={k} seed={seed}"), &plain, &fast);
            // The bounds must do the work: most point visits are decided without a search.
            assert!(
                fast.searches * 4 < fast.visits,
                "{name}: {} searches in {} visits",
                fast.searches,
                fast.visits
            );
        }
    }
}

#[test]
fn accelerated_seeding_draws_the_plain_centres_on_cturtle_at_k_2000() {
    let cloud = load_cloud(&shared("cturtle.pcd")).expect("cturtle");
    let n = cloud.points.len();
    let k = 2000;
    let mut plain = vec![Point3::default(); k];
    let mut plain_d = vec![0f32; n];
    seed_plus_plus(&cloud.points, &mut plain, &mut plain_d, 3).expect("plain");
    let mut fast = vec![Point3::default(); k];
    let mut fast_d = vec![0f32; n];
    let mut labels = vec![0u32; n];
    let mut blocks = vec![0u128; n.div_ceil(BLOCK)];
    let mut lists = vec![SeedList::default(); k];
    seed_plus_plus_fast(
        &cloud.points,
        &mut fast,
        &mut fast_d,
        &mut labels,
        &mut blocks,
        &mut lists,
        3,
    )
    .expect("fast");
    assert_eq!(bits(&plain), bits(&fast));
    assert_eq!(
        plain_d.iter().map(|d| d.to_bits()).collect::<Vec<_>>(),
        fast_d.iter().map(|d| d.to_bits()).collect::<Vec<_>>()
    );
    // The lists it returns are the nearest seeds, by an independent f64 scan of a sample.
    for (i, p) in cloud.points.iter().enumerate().step_by(97) {
        let q = p.to_f64();
        let d = |c: &Point3| {
            let c = c.to_f64();
            (0..3).map(|j| (q[j] - c[j]).powi(2)).sum::<f64>()
        };
        let best = fast.iter().map(d).fold(f64::INFINITY, f64::min);
        let mine = d(&fast[labels[i] as usize]);
        assert!(
            mine <= best * (1.0 + 1e-6) + 1e-12,
            "point {i}: {mine} vs {best}"
        );
    }
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool")
        .install(f)
}

#[test]
fn one_thread_and_two_give_the_same_bits() {
    let cloud = load_cloud(&shared("five_people.pcd")).expect("five_people");
    let params = KMeansParams::default();
    let run = |threads| {
        in_pool(threads, || {
            let clusters = pipeline::cluster(&cloud.points, 350, &params).expect("clusters");
            let fitted = pipeline::fit_all(&clusters.moments, 0, &Default::default());
            let entities: Vec<_> = fitted.ellipsoids.iter().map(|f| f.entity).collect();
            let errors = pipeline::cluster_errors(&cloud.points, &clusters.labels, &entities);
            let entity_bits: Vec<_> = entities
                .iter()
                .map(|e| {
                    (
                        e.center.to_array().map(f32::to_bits),
                        e.weights.map(f32::to_bits),
                    )
                })
                .collect();
            let error_bits: Vec<_> = errors.iter().map(|e| e.to_bits()).collect();
            (clusters.labels, entity_bits, error_bits)
        })
    };
    assert!(run(1) == run(2), "five_people: 1 and 2 threads differ");
    // The environment scene at the paper's k, k-means alone.
    let scene = environment(&shared_data()).expect("scene");
    let km = |threads| {
        in_pool(threads, || {
            run_kmeans(&scene.points, 8880, &params, KMeansEngine::Accelerated).expect("km")
        })
    };
    assert_same_run("environment k=8880", &km(1), &km(2));
}

#[test]
fn the_environment_scene_lays_every_cloud_out_without_overlap() {
    let scene = environment(&shared_data()).expect("scene");
    let total: usize = scene.members.iter().map(|m| m.points).sum();
    assert_eq!(scene.points.len(), total);
    assert!((700_000..900_000).contains(&total), "{total} points");
    let mut start = 0;
    let mut previous_hi = f32::NEG_INFINITY;
    for m in &scene.members {
        let part = &scene.points[start..start + m.points];
        let lo = part.iter().map(|p| p.x).fold(f32::INFINITY, f32::min);
        let hi = part.iter().map(|p| p.x).fold(f32::NEG_INFINITY, f32::max);
        // Neighbours sit GAP apart (to f32 rounding of the shifted coordinates).
        if previous_hi.is_finite() {
            assert!(
                (lo - previous_hi - mema::bench::GAP as f32).abs() < 1e-3,
                "{}",
                m.name
            );
        }
        // Each member keeps its own points, only shifted along x.
        let own = load_cloud(&shared(m.name)).expect(m.name);
        assert_eq!(own.points.len(), m.points);
        for (p, q) in part.iter().zip(own.points.iter()).step_by(101) {
            assert_eq!((p.y, p.z), (q.y, q.z));
            assert!((p.x as f64 - (q.x as f64 + m.offset_x)).abs() < 1e-5);
        }
        previous_hi = hi;
        start += m.points;
    }
}

#[test]
fn reader_points_become_core_points_without_a_copy() {
    // `load_cloud` turns the reader's Vec<[f32; 3]> into Vec<Point3>; the peak-memory figures
    // in the README rely on that reusing the allocation (same size and alignment).
    let raw: Vec<[f32; 3]> = (0..100_000).map(|i| [i as f32, 0.0, 1.0]).collect();
    let before = raw.as_ptr() as usize;
    let points: Vec<Point3> = raw.into_iter().map(Point3::from).collect();
    assert_eq!(points.as_ptr() as usize, before);
    assert_eq!(points[99_999], Point3::new(99_999.0, 0.0, 1.0));
}
