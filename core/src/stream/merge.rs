//! Merging: the stream's way to make room when no cluster can be frozen, and the tolerance
//! mode's last step. Pairs are ranked by Ward's criterion among those a sort and sweep of the
//! centres offers (`sweep.rs`), and a pass merges the cheapest disjoint ones at once, so the
//! search is paid once per batch of far points.

use super::pairs::{ClosestPairs, Disjoint, MAX_MERGE_BATCH};
use super::sweep::SortedCentres;
use super::{Observer, StreamCluster, StreamMapper, center_of, count32};
use crate::fit::surface_error_estimate;
use crate::moments::FixedMoments;

/// A merge pass merges up to one pair in this many working clusters (at most
/// [`MAX_MERGE_BATCH`]): five at the board's 150. With shells' merges in integers a pass of five
/// pairs costs the image less than one of four did through f64 (car6, the demo drive and
/// bun000: 263,000, 313,000 and 226,000 instructions against 274,000, 323,000 and 245,000),
/// so a pass pays its search for more room. Measured at the board's layout over the 21 shared
/// inputs against one in 32 (four pairs; docs/design.md, "A merge pass's share"): the sparse
/// `simple.las`, whose room comes from passes alone, 1.36 -> 1.23 times the batch map's
/// Chamfer distance; one in 24 or 20 mapped it finer still (1.17, 1.12) but kept 10.5 and
/// 8.5 % of `tests/walker.rs`'s walker (its bound is 10), one in 28 keeps 4.7 %.
pub const PASS_SHARE: usize = 28;

/// Ward's merge cost: the growth of the summed squared distances to the centres, so merging
/// favours small neighbours over big ones, as k-means' objective would.
fn ward(a: &FixedMoments, b: &FixedMoments, d2: f32) -> f32 {
    let (na, nb) = (count32(a), count32(b));
    na * nb / (na + nb) * d2
}

/// Ward's share in the final reduction's cost (the planes' cost, `planar`): enough to keep two
/// far, coplanar patches apart, small enough that the planes decide (tuned on the shared clouds
/// at k = 400: 0 lets coplanar ground patches of a lidar sweep merge across gaps, 0.1 and more
/// lose most of what the planes gain on office1 and the bunny; docs/design.md).
pub const PLANAR_WARD: f32 = 0.01;

/// The final reduction's merge cost: the growth of the summed squared distances from the points
/// to their cluster's best plane (a cluster's least covariance eigenvalue times its weight),
/// which a shell's error follows, plus a little of Ward's cost. Merging two patches of one
/// surface costs nothing but Ward's share, so the clusters the map keeps follow the surfaces
/// as the batch map's surface rounds make them.
///
/// A cluster weighs its points and its area: the two-way Chamfer distance is half the points'
/// mean distance to the map and half the map's mean distance to the points, taken over its
/// area. Weighed by points only, a few sparse, far returns merged into thick shells of tens of
/// square metres cost next to nothing, and that area is phantom surface (ouster_os1.conf at
/// k = 150: 16,700 m^2 of shells against the batch map's 6,300). `density` (points per square
/// metre of the summary) puts the two in one unit.
///
/// `spreads` holds the clusters' own [`spread`]s, which a pass computes once for all its pairs.
fn planar(a: &FixedMoments, b: &FixedMoments, d2: f32, density: f64, spreads: [f64; 2]) -> f32 {
    let mut merged = *a;
    merged.merge(b);
    (spread(&merged, density) - spreads[0] - spreads[1]) as f32 + PLANAR_WARD * ward(a, b, d2)
}

/// A cluster's summed squared distance to its best plane, weighed by its points and its area
/// at `density` ([`planar`]).
fn spread(m: &FixedMoments, density: f64) -> f64 {
    variances(m).map_or(0.0, |values| {
        values[2].max(0.0) * (m.count() as f64 + density * patch_area(values))
    })
}

/// A cluster's variances along its principal axes, largest first (`None` without a covariance).
fn variances(m: &FixedMoments) -> Option<[f64; 3]> {
    m.covariance()
        .map(|(_, c)| crate::shell::symmetric_eigen(c).0)
}

/// The area of a patch whose in-plane variances are the two largest of `values` (descending):
/// a uniform disc of variance `s^2` along a line has radius `2 s`, so `4 pi s1 s2`.
fn patch_area(values: [f64; 3]) -> f64 {
    4.0 * core::f64::consts::PI * libm::sqrt(values[0].max(0.0) * values[1].max(0.0))
}

/// A cluster's [`patch_area`] (0 without a covariance).
fn area_of(m: &FixedMoments) -> f64 {
    variances(m).map_or(0.0, patch_area)
}

/// The final reduction's pairs lie within this many of the summary's median nearest-centre
/// distances at first, and the reach widens by a quarter whenever none is left. Not the join
/// radius, the widest merge of the stream: before [`STRAY_SHARE`], strays merged across a gap
/// set it, and the reach followed them. On ouster_os1.conf at k = 100 to 300 the
/// worst ratio to the batch map was 1.45, 1.52, 1.19, 1.25 and 1.40 at 2, 3, 4, 6 and 8
/// spacings.
pub const REDUCE_SPACINGS: f32 = 4.0;

/// A merge widens the join radius only when its smaller cluster holds at least this share of
/// the mean working cluster's points (the final reduction's merges aside, whose reach is its
/// own). The cheapest merges by Ward's cost join a stray return or
/// two across metres of empty space, and the widest of them set the radius for the rest of the
/// stream, and with it where points open clusters (ouster_os1.conf at k = 150 in the summary's
/// layout: clusters of 4 and 3 points, 5.3 m apart, against 3.8 m at k = 180). On
/// ouster_os1.conf at k = 100 to 300 the streamed map's worst ratio to the batch map was 1.43
/// with every merge widening, 1.24, 1.20, 1.19 and 1.22 at shares 0.02, 0.04, 0.1 and 0.25
/// (docs/design.md). A device's layout had kept every merge, and on a lidar sweep its radius
/// grew to the far returns' spacing: its near ground, where most points are, was a quarter of
/// the batch map's entities, and the board's map of ouster_os1.conf scored 2.26 times the
/// batch map's Chamfer distance (1.17 gated; shares 0.01, 0.02, 0.05 and 0.2 over every shared
/// input: geometric means 1.27, 1.21, 1.19 and 1.18 against 1.18 at 0.1, the summary's value,
/// kept). In the tolerance mode its merges are gated too: cturtle's streamed k at the tolerance
/// of docs/tolerance.md went from 331 to 362.
pub const STRAY_SHARE: f32 = 0.1;

/// Where the final reduction stands: pairs within `limit2` (squared), and the summary's points
/// per square metre of area its cost weighs the two by ([`planar`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Reduction {
    limit2: f32,
    density: f32,
}

impl Reduction {
    /// Not reducing: the stream's merges, ranked by Ward's cost.
    pub(super) const IDLE: Self = Self {
        limit2: f32::INFINITY,
        density: 0.0,
    };
}

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// The `wanted` cheapest pairs by Ward's criterion.
    fn candidate_pairs(&self, wanted: usize) -> ClosestPairs {
        // Ward's cost grows with either count: a cluster of `n` points merges with any other at
        // no less than `n m / (n + m)` a squared unit of distance, `m` the fewest points of any.
        let fewest = self
            .clusters
            .iter()
            .map(|c| count32(&c.moments))
            .fold(f32::INFINITY, f32::min);
        let floor = |c: &StreamCluster| {
            let n = count32(&c.moments);
            if fewest.is_finite() && n + fewest > 0.0 {
                n * fewest / (n + fewest)
            } else {
                0.0
            }
        };
        self.cheapest_pairs(wanted, floor, |_, ca, _, cb, d| {
            ward(&ca.moments, &cb.moments, d)
        })
    }

    /// The final reduction's candidates: the `wanted` cheapest pairs within its reach by
    /// [`planar`] cost, each cluster's own [`spread`] from `spreads` (by index). Out of line, so
    /// its frame is not on a device's stack, which never reduces.
    #[inline(never)]
    fn reduction_pairs(&self, wanted: usize, spreads: &[f64]) -> ClosestPairs {
        let density = f64::from(self.reduction.density);
        let own = |i: usize, m: &FixedMoments| {
            spreads
                .get(i)
                .copied()
                .unwrap_or_else(|| spread(m, density))
        };
        // No floor: two coplanar patches merge at Ward's share of their cost, however far.
        self.cheapest_pairs(
            wanted,
            |_| 0.0,
            |a, ca, b, cb, d| {
                let spreads = [own(a, &ca.moments), own(b, &cb.moments)];
                planar(&ca.moments, &cb.moments, d, density, spreads)
            },
        )
    }

    /// The `wanted` cheapest pairs by `cost` (of each pair's indices, clusters and squared
    /// distance) among those closer than a grid cell, within the reduction's reach while it
    /// runs; among every pair when none is that close, unless a reach is what kept them out.
    /// `floor`: the least cost a squared unit of distance comes to in any pair of a cluster's
    /// (0 if none is known), which lets the sweep ([`SortedCentres`]) stop early.
    #[inline(always)]
    fn cheapest_pairs(
        &self,
        wanted: usize,
        floor: impl Fn(&StreamCluster) -> f32,
        cost: impl Fn(usize, &StreamCluster, usize, &StreamCluster, f32) -> f32,
    ) -> ClosestPairs {
        let mut closest = ClosestPairs::new(wanted);
        let centres = self.clusters.as_slice();
        let sorted = SortedCentres::<K>::new(centres.iter().map(|c| c.center));
        let floor = |i: usize| centres.get(i).map_or(0.0, &floor);
        // A pair's cost, if its squared distance passes `near`.
        let priced = |a: usize, b: usize, near: &dyn Fn(f32) -> bool| {
            let (ca, cb) = (centres.get(a)?, centres.get(b)?);
            let d = ca.center.distance_squared(cb.center);
            near(d).then(|| cost(a, ca, b, cb, d))
        };
        let cell = self.grid.cell();
        let cell2 = cell * cell;
        // Before the join radius has grown, the cell is so small that its square is 0 and no
        // pair qualifies.
        if cell2 > 0.0 {
            let limit2 = self.reduction.limit2;
            let near = |d: f32| d < cell2 && d <= limit2;
            sorted.offer_pairs(&mut closest, cell, floor, |a, b| priced(a, b, &near));
        }
        // While reducing within a reach, an empty answer widens the reach (`reduce_to`).
        if closest.len == 0 && !(self.reducing() && self.reduction.limit2 < f32::MAX) {
            // Centres sparser than the cells (the stream's first pass): every pair.
            sorted.offer_pairs(&mut closest, f32::INFINITY, floor, |a, b| {
                priced(a, b, &|_| true)
            });
        }
        closest
    }

    /// Whether the final reduction is running ([`StreamMapper::reduce_to`]).
    fn reducing(&self) -> bool {
        self.reduction.limit2 < f32::INFINITY
    }

    /// Whether merging clusters `a` and `b` respects the tolerance (always, without one).
    fn within_tolerance(&self, a: usize, b: usize) -> bool {
        if self.params.tolerance <= 0.0 {
            return true;
        }
        let (Some(ca), Some(cb)) = (self.clusters.get(a), self.clusters.get(b)) else {
            return false;
        };
        let mut merged = ca.moments;
        merged.merge(&cb.moments);
        merged
            .central()
            .is_some_and(|m| surface_error_estimate(&m, &self.params.fit) <= self.params.tolerance)
    }

    /// Merges the disjoint pairs of `pairs` that respect the tolerance, cheapest first; with
    /// `force`, the cheapest pair merges even if none does (the capacity must give way).
    fn merge_pairs(
        &mut self,
        pairs: &ClosestPairs,
        force: bool,
        observer: &mut impl Observer,
    ) -> usize {
        let mut merged = Disjoint::<MAX_MERGE_BATCH>::new();
        let stray_below = if self.reducing() {
            0.0
        } else {
            STRAY_SHARE * self.mean_working_count()
        };
        // Each pair's tolerance check once (each costs a small solve).
        let mut allowed = [false; MAX_MERGE_BATCH];
        for (ok, (_, a, b)) in allowed.iter_mut().zip(pairs.iter()) {
            *ok = self.within_tolerance(a, b);
        }
        let forced = if force && !allowed.iter().any(|&ok| ok) {
            self.stats.forced_merges += u64::from(self.params.tolerance > 0.0);
            pairs.get(0).map(|(_, a, b)| (a, b))
        } else {
            None
        };
        for ((_, a, b), &ok) in pairs.iter().zip(allowed.iter()) {
            if !merged.free(a, b) || !(ok || forced == Some((a, b))) {
                continue;
            }
            let (d2, smaller) = match (self.clusters.get(a), self.clusters.get(b)) {
                (Some(ca), Some(cb)) => (
                    ca.center.distance_squared(cb.center),
                    count32(&ca.moments).min(count32(&cb.moments)),
                ),
                _ => continue,
            };
            if !self.absorb(a, b, observer) {
                continue;
            }
            merged.push(a, b);
            if smaller >= stray_below {
                self.radius = self.radius.max(libm::sqrtf(d2));
            }
        }
        self.remove_absorbed(merged.absorbed(), observer);
        merged.len()
    }

    /// The mean point count of the working clusters, [`STRAY_SHARE`]'s yardstick. The summary's
    /// layout takes the points so far over the clusters (shed and carved points counted too),
    /// as it did when the rule was tuned on it, so its maps stay as they were; every other
    /// layout sums its working clusters' counts, a loop over K once a merge pass, which costs
    /// far more.
    fn mean_working_count(&self) -> f32 {
        let clusters = self.clusters.len().max(1) as f32;
        if self.params.final_clusters > 0 {
            self.stats.points as f32 / clusters
        } else {
            self.clusters
                .iter()
                .map(|c| count32(&c.moments))
                .sum::<f32>()
                / clusters
        }
    }

    /// Cluster `b`'s points join cluster `a` (`b` stays until [`Self::remove_absorbed`]).
    /// False if either is missing. Inlined: out of line, its copy of the moments is a frame
    /// of its own on the stack of every merge pass.
    #[inline(always)]
    pub(super) fn absorb(&mut self, a: usize, b: usize, observer: &mut impl Observer) -> bool {
        let (Some(ca), Some(cb)) = (self.clusters.get(a), self.clusters.get(b)) else {
            return false;
        };
        let moments = cb.moments;
        // Either cluster reached by a scan is evidence the merged one is there.
        let seen_through = ca.seen_through.min(cb.seen_through);
        let last_point = if self.idle(cb) < self.idle(ca) {
            cb.last_point
        } else {
            ca.last_point
        };
        observer.merged(a, b);
        if let Some(ca) = self.clusters.get_mut(a) {
            ca.moments.merge(&moments);
            ca.center = center_of(&ca.moments);
            ca.stale = u32::MAX;
            ca.last_point = last_point;
            ca.seen_through = seen_through;
        }
        true
    }

    /// Removes the clusters `absorbed` (each merged into another), counts the merges and
    /// refiles every centre.
    pub(super) fn remove_absorbed(&mut self, absorbed: &mut [usize], observer: &mut impl Observer) {
        // Remove from the highest index down, so swap_remove never moves a slot still to go.
        crate::num::insertion_sort_by(absorbed, |x, y| x > y);
        for &b in absorbed.iter() {
            // In range by construction.
            if b < self.clusters.len() {
                observer.removed(b);
                crate::num::swap_remove(&mut self.clusters, b);
            }
        }
        self.stats.merges += absorbed.len() as u64;
        let cell = self.outgrown_cell().unwrap_or(self.grid.cell());
        // Indices moved and the radius may have outgrown the cells: refile every centre.
        self.grid
            .rebuild(cell, self.clusters.iter().map(|c| c.center));
    }

    /// Makes room: merges the cheapest pair of clusters by Ward's criterion, and with it the next
    /// cheapest disjoint pairs up to [`PASS_SHARE`] of the capacity, so the search is paid once
    /// per batch of far points. The join radius widens to the largest merged distance of a pair
    /// that is not a stray ([`STRAY_SHARE`]).
    pub(super) fn merge_closest_pairs(&mut self, observer: &mut impl Observer) {
        let pairs = self.candidate_pairs(self.limit() / PASS_SHARE);
        self.merge_pairs(&pairs, true, observer);
    }

    /// Pairs within `reach` are the reduction's candidates; the centres are refiled in cells
    /// that hold it, since the pair search takes only pairs closer than a cell.
    fn reach_to(&mut self, reach: f32) {
        let finite = reach > 0.0 && (reach * reach).is_finite();
        self.reduction.limit2 = if finite { reach * reach } else { f32::MAX };
        if finite && reach > self.grid.cell() {
            self.stats.grid_rebuilds += 1;
            self.grid
                .rebuild(reach, self.clusters.iter().map(|c| c.center));
        }
    }

    /// The median distance from a working centre to its nearest other centre (0 with fewer than
    /// two). Brute force, once at the end: a summary of 8,192 clusters is 67 million distances
    /// (each pair from both ends), a small share of the reduction that follows.
    pub(super) fn median_spacing(&self) -> f32 {
        let mut nearest = [0.0f32; K];
        let centres = self.clusters.as_slice();
        for (slot, (i, a)) in nearest.iter_mut().zip(centres.iter().enumerate()) {
            let d2 = centres
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, b)| a.center.distance_squared(b.center))
                .fold(f32::INFINITY, f32::min);
            *slot = libm::sqrtf(d2);
        }
        let Some(found) = nearest.get_mut(..centres.len()) else {
            return 0.0;
        };
        crate::num::insertion_sort_by(found, |x, y| x < y);
        found
            .get(found.len() / 2)
            .copied()
            .filter(|d| d.is_finite())
            .unwrap_or(0.0)
    }

    /// The final reduction: merges the cheapest pairs by [`planar`] cost until at most `n`
    /// clusters remain. Pairs are taken within [`REDUCE_SPACINGS`] of the summary's spacings,
    /// and the reach widens by a quarter only when no pair is left within it: a cost that
    /// favours coplanar pairs would otherwise join patches of a ground plane far apart. Out of
    /// line: its arrays would otherwise sit in every frame of a device's main, which never
    /// reduces.
    #[inline(never)]
    pub(super) fn reduce_to(&mut self, n: usize, observer: &mut impl Observer) {
        let (points, area) = self.clusters.iter().fold((0.0, 0.0), |(n, a), c| {
            (n + c.moments.count() as f64, a + area_of(&c.moments))
        });
        self.reduction.density = if area > 0.0 {
            (points / area) as f32
        } else {
            0.0
        };
        let spacing = REDUCE_SPACINGS * self.median_spacing();
        // Centres all coincide at the median: the stream's own reach, twice the join radius.
        let mut reach = if spacing > 0.0 {
            spacing
        } else {
            2.0 * self.radius
        };
        self.reach_to(reach);
        // Each cluster's own spread, once a pass rather than once a pair.
        let mut spreads = [0.0f64; K];
        while self.clusters.len() > n.max(1) {
            let density = f64::from(self.reduction.density);
            for (slot, c) in spreads.iter_mut().zip(self.clusters.iter()) {
                *slot = spread(&c.moments, density);
            }
            let own = spreads.get(..self.clusters.len()).unwrap_or(&[]);
            let pairs = self.reduction_pairs((self.clusters.len() - n).min(MAX_MERGE_BATCH), own);
            if pairs.len == 0 {
                // Past f32, or before any merge (radius 0): every pair is a candidate.
                if self.reduction.limit2 == f32::MAX {
                    break;
                }
                reach *= 1.25;
                self.reach_to(reach);
                continue;
            }
            if self.merge_pairs(&pairs, true, observer) == 0 {
                break;
            }
        }
        self.reduction = Reduction::IDLE;
    }

    /// Tolerance mode's last step: neighbours keep merging while the merged estimate stays
    /// under the tolerance, so the final k is what the tolerance needs, not the capacity.
    pub(super) fn consolidate(&mut self, observer: &mut impl Observer) {
        if self.params.tolerance <= 0.0 {
            return;
        }
        while self.clusters.len() > 1 {
            let pairs = self.candidate_pairs(MAX_MERGE_BATCH);
            if self.merge_pairs(&pairs, false, observer) == 0 {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests;
