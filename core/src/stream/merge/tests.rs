use crate::fit::FitParams;
use crate::geometry::Point3;
use crate::stream::{Pacing, StreamMapper, StreamModel, StreamParams};

fn params(max_clusters: usize, final_clusters: usize) -> StreamParams {
    StreamParams {
        fit: FitParams::default(),
        seed: 0,
        max_clusters,
        max_frozen: 0,
        refit_interval: 0,
        tolerance: 0.0,
        model: StreamModel::Shells(crate::shell::ShellParams::DEFAULT),
        pacing: Pacing::NONE,
        final_clusters,
    }
}

#[test]
fn median_spacing_is_the_median_nearest_centre_distance() {
    // Nine centres at uneven spacings; the join radius stays 0, so each point is a cluster.
    let xs = [0.0f32, 0.3, 0.35, 1.0, 1.7, 2.9, 3.0, 4.4, 7.0];
    let mut m = StreamMapper::<16, 64>::new(params(16, 0));
    for (i, &x) in xs.iter().enumerate() {
        m.add(Point3::new(x, 0.1 * i as f32, 0.0));
    }
    assert_eq!(m.clusters().len(), xs.len());
    // Brute force in f64: every centre's nearest other centre, sorted, the middle one.
    let mut nearest = [0.0f64; 9];
    for (i, slot) in nearest.iter_mut().enumerate() {
        *slot = (0..xs.len())
            .filter(|&j| j != i)
            .map(|j| {
                let dx = f64::from(xs[i]) - f64::from(xs[j]);
                let dy = 0.1 * (i as f64 - j as f64);
                libm::sqrt(dx * dx + dy * dy)
            })
            .fold(f64::INFINITY, f64::min);
    }
    crate::num::insertion_sort_by(&mut nearest, |a, b| a < b);
    let median = m.median_spacing();
    assert!(
        libm::fabs(f64::from(median) - nearest[4]) < 1e-5,
        "{median} vs {}",
        nearest[4]
    );
}

/// Eight dense blobs of 125 points 3 m apart, then two stray returns 5 m apart, 39 m past the
/// last blob, and a third far beyond that asks for room: the strays' clusters are then the
/// cheapest pair by Ward's cost within the grid's reach.
fn blobs_then_strays(m: &mut StreamMapper<16, 64>) {
    for blob in 0..8 {
        for i in 0..125 {
            let (a, b, c) = (i % 5, (i / 5) % 5, i / 25);
            m.add(Point3::new(
                3.0 * blob as f32 + 0.002 * a as f32,
                0.002 * b as f32,
                0.002 * c as f32,
            ));
        }
    }
    m.add(Point3::new(60.0, 0.0, 0.0));
    m.add(Point3::new(65.0, 0.0, 0.0));
    m.add(Point3::new(200.0, 0.0, 0.0));
}

#[test]
fn strays_merged_across_a_gap_leave_the_radius_alone() {
    // The summary's layout, and a plain one: the radius stays the blobs' spacing.
    let mut summary = StreamMapper::<16, 64>::new(params(8, 4));
    blobs_then_strays(&mut summary);
    assert!(summary.radius() < 3.5, "{}", summary.radius());
    let mut plain = StreamMapper::<16, 64>::new(params(8, 0));
    blobs_then_strays(&mut plain);
    assert!(plain.radius() < 3.5, "{}", plain.radius());
    // Every point is still counted.
    for m in [&summary, &plain] {
        let total: u64 = m.clusters().iter().map(|c| c.moments.count()).sum();
        assert_eq!(total, 1003);
    }
}
