//! Accelerated k-means: the plain `kmeans` result, labels and centre bits, for far less work.
//!
//! Seeding is `seed::seed_plus_plus_fast` (same draws). Lloyd keeps Hamerly's two bounds per
//! point, on true distances: `upper` above the distance to its centre `a`, `lower` below the
//! distance to every other centre. After centres move by `drift`, `upper += drift[a]` and
//! `lower -= max drift of the others`; with `separation[a]` (a lower bound on the distance from
//! `c_a` to its nearest other centre), every other centre is at least
//! `max(lower, separation[a] - upper)` away. A point keeps its label only when
//! `margin::surely_nearer` proves the plain scan would pick `a` (strictly, so no tie can go to
//! a lower index); otherwise the upper bound is tightened, and if that is not enough the point
//! asks the kd-tree (`tree`) for its exact nearest and second-nearest centre.
//!
//! The update step is the plain one (same function, sums in point order), so equal labels give
//! equal centre bits. Work over points goes through a [`Runner`], which may split the points
//! into chunks and run them on any number of threads: each point's result depends only on the
//! shared step and its own slots, so the outcome does not depend on the split.

use super::margin::{add_up, lower, squared, sub_down, surely_nearer, upper};
pub use super::seed::{SeedList, seed_plus_plus_fast};
use super::tree::{Aabb, CentreTree, TreeView, nodes_for};
use super::weights::blocks_for;
use super::{
    CentroidSum, KMeansError, KMeansOutcome, KMeansParams, accumulate, check_len,
    mean_axis_variance, move_centres,
};
use crate::geometry::Point3;

/// What the accelerated k-means needs per centre between iterations.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CentreState {
    previous: Point3,
    /// Upper bound on how far the centre moved in the last update.
    drift: f32,
    /// Lower bound on the distance to the nearest other centre.
    separation: f32,
}

/// Caller-provided working memory; [`ScratchSizes`] gives every length.
#[derive(Debug)]
pub struct Scratch<'a> {
    /// One per point: Hamerly's lower bound.
    pub lower: &'a mut [f32],
    /// `blocks_for(n)`: the seeding's exact partial sums.
    pub blocks: &'a mut [u128],
    /// One per centre.
    pub lists: &'a mut [SeedList],
    /// One per centre.
    pub centres: &'a mut [CentreState],
    /// One per centre: the kd-tree's permutation and its centres in that order.
    pub order: &'a mut [u32],
    pub sorted: &'a mut [Point3],
    /// `nodes_for(k)`.
    pub nodes: &'a mut [Aabb],
}

/// Lengths of the [`Scratch`] slices for `n` points and `k` centres.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScratchSizes {
    pub points: usize,
    pub blocks: usize,
    pub centres: usize,
    pub nodes: usize,
}

impl ScratchSizes {
    pub const fn new(n: usize, k: usize) -> Self {
        Self {
            points: n,
            blocks: blocks_for(n),
            centres: k,
            nodes: nodes_for(k),
        }
    }

    /// Bytes of scratch on top of the plain version's slices.
    pub const fn bytes(&self) -> usize {
        self.points * size_of::<f32>()
            + self.blocks * size_of::<u128>()
            + self.centres
                * (size_of::<SeedList>()
                    + size_of::<CentreState>()
                    + size_of::<u32>()
                    + size_of::<Point3>())
            + self.nodes * size_of::<Aabb>()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    /// Lloyd's assignment: `upper` holds the upper bounds.
    Bounded,
    /// The last assignment: as `Bounded`, then `upper` gets the exact squared distances.
    Final,
    /// Labels stay; `upper` gets the squared distance to the labelled centre.
    Distances,
}

/// One pass over the points with everything it shares between them, read-only.
#[derive(Clone, Copy, Debug)]
pub struct AssignStep<'a> {
    centres: &'a [Point3],
    state: &'a [CentreState],
    tree: TreeView<'a>,
    /// Index and value of the largest drift, and the second largest.
    largest_drift: (usize, f32),
    second_drift: f32,
    mode: Mode,
}

impl AssignStep<'_> {
    /// Runs the step over a run of points and their slots; returns how many labels changed.
    pub fn run(
        &self,
        points: &[Point3],
        labels: &mut [u32],
        upper_bounds: &mut [f32],
        lower_bounds: &mut [f32],
    ) -> usize {
        let mut changed = 0;
        let slots = labels
            .iter_mut()
            .zip(upper_bounds.iter_mut())
            .zip(lower_bounds.iter_mut());
        for (&p, ((label, up), low)) in points.iter().zip(slots) {
            let a = *label as usize;
            let own = self.centres.get(a).zip(self.state.get(a));
            if self.mode == Mode::Distances {
                *up = own.map_or(f32::INFINITY, |(&c, _)| squared(p, c));
                continue;
            }
            let kept = own.and_then(|(&c, s)| {
                let others_drift = if a == self.largest_drift.0 {
                    self.second_drift
                } else {
                    self.largest_drift.1
                };
                *low = sub_down(*low, others_drift);
                // Every other centre is at least separation[a] - |p - c_a| from p.
                let others = |near: f32| low.max(sub_down(s.separation, near));
                let drifted = add_up(*up, s.drift);
                if self.mode == Mode::Bounded && surely_nearer(drifted, others(drifted)) {
                    *up = drifted;
                    return Some(());
                }
                let sq = squared(p, c);
                let tight = upper(sq);
                surely_nearer(tight, others(tight)).then(|| {
                    *up = if self.mode == Mode::Final { sq } else { tight };
                })
            });
            if kept.is_some() {
                continue;
            }
            if let Some(found) = self.tree.nearest_two(p) {
                if found.index != *label {
                    changed += 1;
                    *label = found.index;
                }
                *up = if self.mode == Mode::Final {
                    found.squared
                } else {
                    upper(found.squared)
                };
                *low = lower(found.second_squared);
            }
        }
        changed
    }
}

/// How passes over the points are executed: sequentially here, in parallel chunks on a host.
pub trait Runner {
    /// Applies `step.run` to all points, in one call or in chunks; returns the summed count.
    fn assign(
        &self,
        step: &AssignStep<'_>,
        points: &[Point3],
        labels: &mut [u32],
        upper_bounds: &mut [f32],
        lower_bounds: &mut [f32],
    ) -> usize;
}

/// One pass, one thread.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sequential;

impl Runner for Sequential {
    fn assign(
        &self,
        step: &AssignStep<'_>,
        points: &[Point3],
        labels: &mut [u32],
        upper_bounds: &mut [f32],
        lower_bounds: &mut [f32],
    ) -> usize {
        step.run(points, labels, upper_bounds, lower_bounds)
    }
}

/// Drift bookkeeping and the tree after the centres changed.
struct Centres<'s, 'a> {
    state: &'s mut [CentreState],
    tree: CentreTree<'a>,
    largest_drift: (usize, f32),
    second_drift: f32,
}

impl Centres<'_, '_> {
    fn refresh(&mut self, centres: &[Point3]) {
        self.tree.build(centres);
        let view = self.tree.view();
        self.largest_drift = (usize::MAX, 0.0);
        self.second_drift = 0.0;
        for (a, (s, &c)) in self.state.iter_mut().zip(centres.iter()).enumerate() {
            s.drift = upper(squared(s.previous, c));
            if s.drift > self.largest_drift.1 {
                self.second_drift = self.largest_drift.1;
                self.largest_drift = (a, s.drift);
            } else if s.drift > self.second_drift {
                self.second_drift = s.drift;
            }
            let nearest_other = view.nearest_two(c).map_or(f32::INFINITY, |t| {
                if t.index as usize == a {
                    t.second_squared
                } else {
                    t.squared
                }
            });
            s.separation = lower(nearest_other);
            s.previous = c;
        }
    }

    fn step<'b>(&'b self, centres: &'b [Point3], mode: Mode) -> AssignStep<'b> {
        AssignStep {
            centres,
            state: self.state,
            tree: self.tree.view(),
            largest_drift: self.largest_drift,
            second_drift: self.second_drift,
            mode,
        }
    }
}

/// `kmeans` with the same result, labels and centre bits, and the same outcome.
#[allow(clippy::too_many_arguments)]
pub fn kmeans_fast<R: Runner + ?Sized>(
    points: &[Point3],
    centres: &mut [Point3],
    labels: &mut [u32],
    distances: &mut [f32],
    sums: &mut [CentroidSum],
    scratch: Scratch<'_>,
    params: &KMeansParams,
    runner: &R,
) -> Result<KMeansOutcome, KMeansError> {
    check_scratch(points.len(), centres.len(), labels, sums, &scratch)?;
    seed_plus_plus_fast(
        points,
        centres,
        distances,
        labels,
        scratch.blocks,
        scratch.lists,
        params.seed,
    )?;
    let mut lloyd = Lloyd::new(scratch, centres)?;
    // The seeding's lists are Lloyd's first assignment; the second-nearest is not known yet.
    for (u, l) in distances.iter_mut().zip(lloyd.lower.iter_mut()) {
        *u = upper(*u);
        *l = 0.0;
    }
    Ok(lloyd.run(points, centres, labels, distances, sums, params, runner, true))
}

/// `lloyd` (from the given centres) with the same result; `points` non-empty and finite.
#[allow(clippy::too_many_arguments)]
pub fn lloyd_fast<R: Runner + ?Sized>(
    points: &[Point3],
    centres: &mut [Point3],
    labels: &mut [u32],
    distances: &mut [f32],
    sums: &mut [CentroidSum],
    scratch: Scratch<'_>,
    params: &KMeansParams,
    runner: &R,
) -> Result<KMeansOutcome, KMeansError> {
    check_scratch(points.len(), centres.len(), labels, sums, &scratch)?;
    check_len("distances", points.len(), distances.len())?;
    let mut lloyd = Lloyd::new(scratch, centres)?;
    labels.fill(u32::MAX);
    distances.fill(f32::INFINITY);
    lloyd.lower.fill(0.0);
    Ok(lloyd.run(points, centres, labels, distances, sums, params, runner, false))
}

fn check_scratch(
    n: usize,
    k: usize,
    labels: &[u32],
    sums: &[CentroidSum],
    scratch: &Scratch<'_>,
) -> Result<(), KMeansError> {
    check_len("labels", n, labels.len())?;
    check_len("centroid sums", k, sums.len())?;
    check_len("lower bounds", n, scratch.lower.len())?;
    check_len("block sums", blocks_for(n), scratch.blocks.len())?;
    check_len("seed lists", k, scratch.lists.len())?;
    check_len("centre states", k, scratch.centres.len())?;
    check_len("tree order", k, scratch.order.len())?;
    check_len("tree centres", k, scratch.sorted.len())?;
    check_len("tree nodes", nodes_for(k), scratch.nodes.len())
}

/// Lloyd's loop over the bounds.
struct Lloyd<'s, 'a> {
    lower: &'s mut [f32],
    centres: Centres<'s, 'a>,
}

impl<'a> Lloyd<'a, 'a> {
    fn new(scratch: Scratch<'a>, centres: &[Point3]) -> Result<Self, KMeansError> {
        let k = centres.len();
        let tree = CentreTree::new(scratch.order, scratch.sorted, scratch.nodes).ok_or(
            KMeansError::SliceLength {
                what: "centres (at most 2^32)",
                expected: u32::MAX as usize,
                got: k,
            },
        )?;
        let mut state = Centres {
            state: scratch.centres,
            tree,
            largest_drift: (usize::MAX, 0.0),
            second_drift: 0.0,
        };
        for (s, &c) in state.state.iter_mut().zip(centres.iter()) {
            s.previous = c;
        }
        state.refresh(centres);
        Ok(Self {
            lower: scratch.lower,
            centres: state,
        })
    }

    /// The plain `lloyd` loop, step for step. `seeded`: the first assignment is already in
    /// `labels` (every label counts as changed, as from the plain version's "none").
    #[allow(clippy::too_many_arguments)]
    fn run<R: Runner + ?Sized>(
        &mut self,
        points: &[Point3],
        centres: &mut [Point3],
        labels: &mut [u32],
        distances: &mut [f32],
        sums: &mut [CentroidSum],
        params: &KMeansParams,
        runner: &R,
        seeded: bool,
    ) -> KMeansOutcome {
        let threshold = params.tolerance * mean_axis_variance(points);
        let mut iterations = 0;
        let mut converged = false;
        let mut last = Mode::Final;
        while iterations < params.max_iterations {
            let changed = if iterations == 0 && seeded {
                points.len()
            } else {
                let step = self.centres.step(centres, Mode::Bounded);
                runner.assign(&step, points, labels, distances, self.lower)
            };
            iterations += 1;
            if changed == 0 {
                converged = true;
                last = Mode::Distances;
                break;
            }
            accumulate(points, labels, sums);
            let shift = if sums.iter().any(|s| s.count == 0) {
                // The plain update reads exact distances to find the farthest points; rare.
                let step = self.centres.step(centres, Mode::Distances);
                runner.assign(&step, points, labels, distances, self.lower);
                let shift = move_centres(points, labels, distances, centres, sums);
                distances.fill(f32::INFINITY);
                self.lower.fill(0.0);
                shift
            } else {
                move_centres(points, labels, distances, centres, sums)
            };
            self.centres.refresh(centres);
            if shift <= threshold {
                converged = true;
                break;
            }
        }
        let step = self.centres.step(centres, last);
        runner.assign(&step, points, labels, distances, self.lower);
        let inertia = distances.iter().map(|&d| d as f64).sum();
        KMeansOutcome {
            iterations,
            converged,
            inertia,
        }
    }
}

#[cfg(test)]
mod tests {
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
            upper_bounds: &mut [f32],
            lower_bounds: &mut [f32],
        ) -> usize {
            let c = self.0;
            points
                .chunks(c)
                .zip(labels.chunks_mut(c))
                .zip(upper_bounds.chunks_mut(c).zip(lower_bounds.chunks_mut(c)))
                .map(|((p, l), (u, lo))| step.run(p, l, u, lo))
                .sum()
        }
    }

    struct Buffers {
        centres: [Point3; K],
        labels: [u32; N],
        distances: [f32; N],
        sums: [CentroidSum; K],
        lower: [f32; N],
        blocks: [u128; blocks_for(N)],
        lists: [SeedList; K],
        state: [CentreState; K],
        order: [u32; K],
        sorted: [Point3; K],
        nodes: [Aabb; nodes_for(K)],
    }

    impl Buffers {
        fn new() -> Self {
            Self {
                centres: [Point3::default(); K],
                labels: [0; N],
                distances: [0.0; N],
                sums: [CentroidSum::default(); K],
                lower: [0.0; N],
                blocks: [0; blocks_for(N)],
                lists: [SeedList::default(); K],
                state: [CentreState::default(); K],
                order: [0; K],
                sorted: [Point3::default(); K],
                nodes: [Aabb::default(); nodes_for(K)],
            }
        }

        fn split(&mut self, k: usize) -> (Scratch<'_>, &mut [Point3], &mut [u32], &mut [f32], &mut [CentroidSum]) {
            (
                Scratch {
                    lower: &mut self.lower,
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
                let got = kmeans_fast(&pts, c, l, d, s, scratch, &params, runner).or_fail("fast")?;
                assert_eq!(got.iterations, want.iterations, "seed {seed}");
                assert_eq!(got.converged, want.converged);
                assert_eq!(got.inertia.to_bits(), want.inertia.to_bits());
                assert!(same_bits(&fast.centres[..k], &plain.centres[..k]));
                assert_eq!(fast.labels, plain.labels);
                assert!(fast.distances.iter().zip(plain.distances.iter()).all(|(a, b)| a.to_bits() == b.to_bits()));
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
        let got = lloyd_fast(&pts, c, l, d, s, scratch, &params, &Chunked(100)).or_fail("fast")?;
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
}
