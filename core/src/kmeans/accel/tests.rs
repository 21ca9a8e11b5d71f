use super::*;
use crate::kmeans::{kmeans, lloyd};
use crate::test_support::{OrFail, TestResult};

const N: usize = 4000;
const K: usize = 64;

/// Runs in uneven chunks, as a thread pool might split the points.
struct Chunked(usize);

impl Runner for Chunked {
    fn assign(
        &self,
        step: &AssignStep<'_>,
        points: &[Point3],
        labels: &mut [u32],
        bounds: &mut [f32],
        seconds: &mut [u32],
    ) -> PassCounts {
        let c = self.0;
        points
            .chunks(c)
            .zip(labels.chunks_mut(c))
            .zip(bounds.chunks_mut(c).zip(seconds.chunks_mut(c)))
            .map(|((p, l), (u, lo))| step.run(p, l, u, lo))
            .sum()
    }
}

struct Buffers {
    centres: [Point3; K],
    labels: [u32; N],
    distances: [f32; N],
    sums: [CentroidSum; K],
    seconds: [u32; N],
    blocks: [u128; blocks_for(N)],
    lists: [SeedList; K],
    state: [CentreState; K],
    order: [u32; K],
    sorted: [TreeCentre; K],
    nodes: [TreeNode; nodes_for(K)],
}

impl Buffers {
    fn new() -> Self {
        Self {
            centres: [Point3::default(); K],
            labels: [0; N],
            distances: [0.0; N],
            sums: [CentroidSum::default(); K],
            seconds: [0; N],
            blocks: [0; blocks_for(N)],
            lists: [SeedList::default(); K],
            state: [CentreState::default(); K],
            order: [0; K],
            sorted: [TreeCentre::default(); K],
            nodes: [TreeNode::default(); nodes_for(K)],
        }
    }

    fn split(
        &mut self,
        k: usize,
    ) -> (
        Scratch<'_>,
        &mut [Point3],
        &mut [u32],
        &mut [f32],
        &mut [CentroidSum],
    ) {
        (
            Scratch {
                seconds: &mut self.seconds,
                blocks: &mut self.blocks,
                lists: &mut self.lists[..k],
                centres: &mut self.state[..k],
                order: &mut self.order[..k],
                sorted: &mut self.sorted[..k],
                nodes: &mut self.nodes[..nodes_for(k)],
            },
            &mut self.centres[..k],
            &mut self.labels,
            &mut self.distances,
            &mut self.sums[..k],
        )
    }
}

/// Scans with stripes, a dense blob, duplicates and grid ties.
fn cloud(seed: u64) -> [Point3; N] {
    let mut pts = [Point3::default(); N];
    let mut s = seed;
    let mut r = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    for (i, p) in pts.iter_mut().enumerate() {
        *p = match i % 5 {
            0 => Point3::new((i % 17) as f32 * 0.5, (i % 11) as f32 * 0.5, 0.0),
            1 => Point3::new(r() * 0.2 + 3.0, r() * 0.2, r() * 0.2),
            2 => Point3::new(r() * 8.0, 2.0 + 0.01 * r(), r() * 3.0),
            3 => Point3::new(-1.0, -1.0, -1.0),
            _ => Point3::new(r() * 8.0, r() * 8.0, r() * 8.0),
        };
    }
    pts
}

fn same_bits(a: &[Point3], b: &[Point3]) -> bool {
    a.iter()
        .zip(b.iter())
        .all(|(p, q)| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits))
}

#[test]
fn same_result_as_plain_kmeans() -> TestResult {
    for (seed, k, tolerance, max_iterations) in [
        (0u64, K, 1e-4, 100),
        (1, K, 0.0, 300),
        (2, 1, 1e-4, 100),
        (3, 2, 0.0, 100),
        (4, 17, 1e-4, 3),
        (5, K, 1e-4, 0),
    ] {
        let pts = cloud(seed);
        let params = KMeansParams {
            max_iterations,
            tolerance,
            seed,
        };
        let mut plain = Buffers::new();
        let (_, c, l, d, s) = plain.split(k);
        let want = kmeans(&pts, c, l, d, s, &params).or_fail("plain")?;
        for runner in [&Sequential as &dyn Runner, &Chunked(333), &Chunked(1)] {
            let mut fast = Buffers::new();
            let (scratch, c, l, d, s) = fast.split(k);
            let got = kmeans_fast(&pts, c, l, d, s, scratch, &params, runner)
                .or_fail("fast")?
                .outcome;
            assert_eq!(got.iterations, want.iterations, "seed {seed}");
            assert_eq!(got.converged, want.converged);
            assert_eq!(got.inertia.to_bits(), want.inertia.to_bits());
            assert!(same_bits(&fast.centres[..k], &plain.centres[..k]));
            assert_eq!(fast.labels, plain.labels);
            assert!(
                fast.distances
                    .iter()
                    .zip(plain.distances.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
        }
    }
    Ok(())
}

#[test]
fn same_result_as_plain_lloyd_through_empty_clusters() -> TestResult {
    // Centres stacked in one corner, far from most points: most clusters empty at once.
    let pts = cloud(9);
    let mut start = [Point3::default(); K];
    for (i, c) in start.iter_mut().enumerate() {
        *c = Point3::new(-1.0 + 0.001 * i as f32, -1.0, -1.0 - 0.002 * (i % 3) as f32);
    }
    let params = KMeansParams {
        max_iterations: 200,
        tolerance: 0.0,
        seed: 0,
    };
    let mut plain = Buffers::new();
    plain.centres = start;
    let (_, c, l, d, s) = plain.split(K);
    let want = lloyd(&pts, c, l, d, s, &params);
    let mut fast = Buffers::new();
    fast.centres = start;
    let (scratch, c, l, d, s) = fast.split(K);
    let got = lloyd_fast(&pts, c, l, d, s, scratch, &params, &Chunked(100))
        .or_fail("fast")?
        .outcome;
    assert_eq!(got, want);
    assert!(same_bits(&fast.centres, &plain.centres));
    assert_eq!(fast.labels, plain.labels);
    // The test is only meaningful if the plain run had to refill clusters.
    let mut probe = [Point3::default(); K];
    probe.copy_from_slice(&start);
    let mut labels = [0u32; N];
    let mut distances = [0f32; N];
    crate::kmeans::assign(&pts, &probe, &mut labels, &mut distances);
    let owned = (0..K as u32).filter(|j| labels.contains(j)).count();
    assert!(owned < K / 2, "{owned} of {K} start clusters own points");
    Ok(())
}
