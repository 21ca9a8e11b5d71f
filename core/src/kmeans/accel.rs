//! Accelerated k-means: the plain `kmeans` result, labels and centre bits, for far less work.
//!
//! Seeding is `seed::seed_plus_plus_fast` (same draws, and its lists are Lloyd's first
//! assignment). Each later assignment is a `step::AssignStep` pass (two distances per point
//! and a proof, or a kd-tree search), and the update step is the plain one (the same functions,
//! sums in point order), so equal labels give equal centre bits. Work over points goes through a
//! [`Runner`], which may split the points into chunks and run them on any number of threads:
//! each point's result depends only on the shared step and its own slots, so the outcome does
//! not depend on the split.

use super::margin::{lower, squared, upper};
pub use super::seed::{SeedList, seed_plus_plus_fast};
pub use super::step::{AssignStep, CentreState, PassCounts};
use super::step::{Mode, UNKNOWN};
use super::tree::{CentreTree, TreeCentre, TreeNode, TreeView, nodes_for};
use super::weights::blocks_for;
use super::{
    CentroidSum, KMeansError, KMeansOutcome, KMeansParams, accumulate, check_len,
    mean_axis_variance, move_centres,
};
use crate::geometry::Point3;

/// `reach = REACH * separation`. Only speed depends on it: wider makes `reach - |p - c_a|` a
/// stronger bound for far centres, narrower keeps `near_drift` local (measured: searches on
/// five_people k = 350 and cturtle k = 2000 are fewest at 2 among 1, 1.5, 2, 3, 6, 10).
const REACH: f32 = 2.0;

/// Caller-provided working memory; [`ScratchSizes`] gives every length.
#[derive(Debug)]
pub struct Scratch<'a> {
    /// One per point: the runner-up centre.
    pub seconds: &'a mut [u32],
    /// `blocks_for(n)`: the seeding's exact partial sums.
    pub blocks: &'a mut [u128],
    /// One per centre.
    pub lists: &'a mut [SeedList],
    /// One per centre.
    pub centres: &'a mut [CentreState],
    /// One per centre: the kd-tree's permutation and its centres in that order.
    pub order: &'a mut [u32],
    pub sorted: &'a mut [TreeCentre],
    /// `nodes_for(k)`.
    pub nodes: &'a mut [TreeNode],
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
        self.points * size_of::<u32>()
            + self.blocks * size_of::<u128>()
            + self.centres
                * (size_of::<SeedList>()
                    + size_of::<CentreState>()
                    + size_of::<u32>()
                    + size_of::<TreeCentre>())
            + self.nodes * size_of::<TreeNode>()
    }
}

/// The accelerated run's outcome (the plain one's fields) and how much searching it needed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FastOutcome {
    pub outcome: KMeansOutcome,
    /// Point visits over all assignment passes, and those that fell back to the kd-tree.
    pub visits: u64,
    pub searches: u64,
}

/// How passes over the points are executed: sequentially here, in parallel chunks on a host.
pub trait Runner {
    /// Applies `step.run` to all points, in one call or in chunks; returns the summed counts.
    fn assign(
        &self,
        step: &AssignStep<'_>,
        points: &[Point3],
        labels: &mut [u32],
        bounds: &mut [f32],
        seconds: &mut [u32],
    ) -> PassCounts;

    /// The update step's sums (`super::accumulate`); a runner may split the clusters into
    /// ranges with `accumulate_range`.
    fn accumulate(&self, points: &[Point3], labels: &[u32], sums: &mut [CentroidSum]) {
        accumulate(points, labels, sums);
    }

    /// Applies `step.run` to all centre states, in one call or in chunks.
    fn centres(&self, step: &CentreStep<'_>, state: &mut [CentreState]) {
        step.run(0, state);
    }
}

/// The per-centre part of a refresh: each centre's separation, reach and near drift, from the
/// tree over the centres. Like `AssignStep`, shared read-only and split freely.
#[derive(Clone, Copy, Debug)]
pub struct CentreStep<'a> {
    centres: &'a [Point3],
    tree: TreeView<'a>,
}

impl CentreStep<'_> {
    /// Refreshes `state`, the states of centres `first..first + state.len()`.
    pub fn run(&self, first: usize, state: &mut [CentreState]) {
        // The drift of a centre that did not move.
        let still = upper(0.0);
        for (a, s) in (first..).zip(state.iter_mut()) {
            let Some(&c) = self.centres.get(a) else {
                continue;
            };
            let hint = [(a as u32, 0.0), (u32::MAX, f32::INFINITY)];
            let nearest_other = self.tree.nearest(c, hint).map_or(f32::INFINITY, |t| {
                if t.index as usize == a {
                    t.second_squared
                } else {
                    t.squared
                }
            });
            s.separation = lower(nearest_other);
            s.reach = s.separation * REACH;
            s.near_drift = self.tree.max_drift_near(a as u32, c, s.reach, still);
        }
    }
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
        bounds: &mut [f32],
        seconds: &mut [u32],
    ) -> PassCounts {
        step.run(points, labels, bounds, seconds)
    }
}

/// Per-centre bookkeeping and the tree, refreshed after every update.
struct Centres<'a> {
    state: &'a mut [CentreState],
    tree: CentreTree<'a>,
    largest_drift: (usize, f32),
    second_drift: f32,
}

impl<'a> Centres<'a> {
    fn new<R: Runner + ?Sized>(
        scratch_state: &'a mut [CentreState],
        tree: CentreTree<'a>,
        centres: &[Point3],
        runner: &R,
    ) -> Self {
        for (s, &c) in scratch_state.iter_mut().zip(centres.iter()) {
            s.previous = c;
        }
        let mut this = Self {
            state: scratch_state,
            tree,
            largest_drift: (usize::MAX, 0.0),
            second_drift: 0.0,
        };
        this.refresh(centres, runner);
        this
    }

    fn refresh<R: Runner + ?Sized>(&mut self, centres: &[Point3], runner: &R) {
        self.largest_drift = (usize::MAX, 0.0);
        self.second_drift = 0.0;
        for (a, (s, &c)) in self.state.iter_mut().zip(centres.iter()).enumerate() {
            s.drift = upper(squared(s.previous, c));
            s.previous = c;
            if s.drift > self.largest_drift.1 {
                self.second_drift = self.largest_drift.1;
                self.largest_drift = (a, s.drift);
            } else if s.drift > self.second_drift {
                self.second_drift = s.drift;
            }
        }
        let state = &*self.state;
        self.tree
            .build(centres, |i| state.get(i).map_or(0.0, |s| s.drift));
        let step = CentreStep {
            centres,
            tree: self.tree.view(),
        };
        runner.centres(&step, self.state);
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
) -> Result<FastOutcome, KMeansError> {
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
    // The seeding's lists are Lloyd's first assignment; no runner-up is known yet.
    distances.fill(0.0);
    scratch.seconds.fill(UNKNOWN);
    let mut lloyd = Lloyd::new(
        scratch.seconds,
        scratch.centres,
        scratch.order,
        scratch.sorted,
        scratch.nodes,
        centres,
        runner,
    )?;
    Ok(lloyd.run(
        points, centres, labels, distances, sums, params, runner, true,
    ))
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
) -> Result<FastOutcome, KMeansError> {
    check_scratch(points.len(), centres.len(), labels, sums, &scratch)?;
    check_len("distances", points.len(), distances.len())?;
    labels.fill(u32::MAX);
    distances.fill(0.0);
    scratch.seconds.fill(UNKNOWN);
    let mut lloyd = Lloyd::new(
        scratch.seconds,
        scratch.centres,
        scratch.order,
        scratch.sorted,
        scratch.nodes,
        centres,
        runner,
    )?;
    Ok(lloyd.run(
        points, centres, labels, distances, sums, params, runner, false,
    ))
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
    check_len("runner-ups", n, scratch.seconds.len())?;
    check_len("block sums", blocks_for(n), scratch.blocks.len())?;
    check_len("seed lists", k, scratch.lists.len())?;
    check_len("centre states", k, scratch.centres.len())?;
    check_len("tree order", k, scratch.order.len())?;
    check_len("tree centres", k, scratch.sorted.len())?;
    check_len("tree nodes", nodes_for(k), scratch.nodes.len())
}

/// Lloyd's loop over the bounds.
struct Lloyd<'a> {
    seconds: &'a mut [u32],
    centres: Centres<'a>,
}

impl<'a> Lloyd<'a> {
    fn new<R: Runner + ?Sized>(
        seconds: &'a mut [u32],
        state: &'a mut [CentreState],
        order: &'a mut [u32],
        sorted: &'a mut [TreeCentre],
        nodes: &'a mut [TreeNode],
        centres: &[Point3],
        runner: &R,
    ) -> Result<Self, KMeansError> {
        let k = centres.len();
        let tree = CentreTree::new(order, sorted, nodes).ok_or(KMeansError::SliceLength {
            what: "centres (at most 2^32)",
            expected: u32::MAX as usize,
            got: k,
        })?;
        Ok(Self {
            seconds,
            centres: Centres::new(state, tree, centres, runner),
        })
    }

    /// The plain `lloyd` loop, step for step; `distances` holds the bounds until the last pass.
    /// `seeded`: the first assignment is already in `labels` (every label counts as changed,
    /// as from the plain version's "none").
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
    ) -> FastOutcome {
        let mut visits = 0u64;
        let mut searches = 0u64;
        let mut pass = |step: &AssignStep<'_>,
                        labels: &mut [u32],
                        distances: &mut [f32],
                        seconds: &mut [u32]| {
            let counts = runner.assign(step, points, labels, distances, seconds);
            visits += points.len() as u64;
            searches += counts.searched as u64;
            counts.changed
        };
        let threshold = params.tolerance * mean_axis_variance(points);
        let mut iterations = 0;
        let mut converged = false;
        let mut last = Mode::Final;
        while iterations < params.max_iterations {
            let changed = if iterations == 0 && seeded {
                points.len()
            } else {
                let step = self.centres.step(centres, Mode::Bounded);
                pass(&step, labels, distances, self.seconds)
            };
            iterations += 1;
            if changed == 0 {
                converged = true;
                last = Mode::Distances;
                break;
            }
            runner.accumulate(points, labels, sums);
            let shift = if sums.iter().any(|s| s.count == 0) {
                // The plain update reads exact distances to find the farthest points; rare.
                let step = self.centres.step(centres, Mode::Distances);
                pass(&step, labels, distances, self.seconds);
                let shift = move_centres(points, labels, distances, centres, sums);
                distances.fill(0.0);
                self.seconds.fill(UNKNOWN);
                shift
            } else {
                move_centres(points, labels, distances, centres, sums)
            };
            self.centres.refresh(centres, runner);
            if shift <= threshold {
                converged = true;
                break;
            }
        }
        let step = self.centres.step(centres, last);
        pass(&step, labels, distances, self.seconds);
        let inertia = distances.iter().map(|&d| d as f64).sum();
        FastOutcome {
            outcome: KMeansOutcome {
                iterations,
                converged,
                inertia,
            },
            visits,
            searches,
        }
    }
}

#[cfg(test)]
mod tests;
