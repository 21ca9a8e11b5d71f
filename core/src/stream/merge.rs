//! Merging: the stream's way to make room when no cluster can be frozen, and the tolerance
//! mode's last step. Pairs are ranked by Ward's criterion among the neighbours the centre grid
//! offers, and a pass merges the cheapest disjoint ones at once, so the search is paid once
//! per batch of far points.

use super::pairs::{ClosestPairs, Disjoint, MAX_MERGE_BATCH};
use super::{Observer, StreamMapper, center_of, count32};
use crate::fit::surface_error_estimate;
use crate::moments::FixedMoments;

/// Ward's merge cost: the growth of the summed squared distances to the centres, so merging
/// favours small neighbours over big ones, as k-means' objective would.
fn ward(a: &FixedMoments, b: &FixedMoments, d2: f32) -> f32 {
    ward_of(count32(a), count32(b), d2)
}

/// Ward's share in the final reduction's cost (the planes' cost, `planar`): enough to keep two
/// far, coplanar patches apart, small enough that the planes decide (tuned on the shared clouds
/// at k = 400: 0 lets coplanar ground patches of a lidar sweep merge across gaps, 0.1 and more
/// lose most of what the planes gain on office1 and the bunny; docs/design.md).
pub const PLANAR_WARD: f32 = 0.01;

/// The final reduction's merge cost: the growth of the summed squared distances from the points
/// to their cluster's best plane (a cluster's least covariance eigenvalue times its count),
/// which a shell's error follows, plus a little of Ward's cost. Merging two patches of one
/// surface costs nothing but Ward's share, so the clusters the map keeps follow the surfaces
/// as the batch map's surface rounds make them.
fn planar(a: &FixedMoments, b: &FixedMoments, d2: f32) -> f32 {
    let spread = |m: &FixedMoments| {
        m.covariance().map_or(0.0, |(_, c)| {
            let (values, _) = crate::shell::symmetric_eigen(c);
            values[2].max(0.0) * m.count() as f64
        })
    };
    let mut merged = *a;
    merged.merge(b);
    (spread(&merged) - spread(a) - spread(b)) as f32 + PLANAR_WARD * ward(a, b, d2)
}

/// [`ward`] from the clusters' counts (as f32), the same in either order.
fn ward_of(na: f32, nb: f32, d2: f32) -> f32 {
    na * nb / (na + nb) * d2
}

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// The `wanted` cheapest neighbour pairs by Ward's criterion.
    fn candidate_pairs(&self, wanted: usize) -> ClosestPairs {
        let mut closest = ClosestPairs::new(wanted);
        let cell2 = self.grid.cell() * self.grid.cell();
        // Before the join radius has grown, the cell is so small that its square is 0 and no
        // pair can qualify: skip the 27-cell queries, which then walk every centre filed in one
        // saturated cell (27 K^2 steps, the firmware's longest tick).
        let near = if cell2 > 0.0 {
            self.clusters.as_slice()
        } else {
            &[]
        };
        for (a, ca) in near.iter().enumerate() {
            let na = count32(&ca.moments);
            self.grid.for_each_ahead(ca.center, |b, own| {
                // Pairs in one cell come up from both centres: take them once, as (a, b > a).
                if own && b <= a {
                    return;
                }
                let Some(cb) = self.clusters.get(b) else {
                    return;
                };
                // Each pair once, as (lower index, higher): the distance and the cost are
                // the same either way round.
                let d = ca.center.distance_squared(cb.center);
                // Only pairs closer than a cell are all seen by the neighbour queries.
                if d < cell2 && d <= self.reduce_limit2 {
                    let cost = if self.reducing() {
                        planar(&ca.moments, &cb.moments, d)
                    } else {
                        ward_of(na, count32(&cb.moments), d)
                    };
                    closest.offer(a.min(b), a.max(b), cost);
                }
            });
        }
        // While reducing within a reach, an empty answer widens the reach (`reduce_to`).
        if closest.len == 0 && !(self.reducing() && self.reduce_limit2 < f32::MAX) {
            // Centres sparser than the grid: the exhaustive search, rare by construction.
            for (a, ca) in self.clusters.iter().enumerate() {
                for (b, cb) in self.clusters.iter().enumerate().skip(a + 1) {
                    let d = ca.center.distance_squared(cb.center);
                    let cost = if self.reducing() {
                        planar(&ca.moments, &cb.moments, d)
                    } else {
                        ward(&ca.moments, &cb.moments, d)
                    };
                    closest.offer(a, b, cost);
                }
            }
        }
        closest
    }

    /// Whether the final reduction is running ([`StreamMapper::reduce_to`]).
    fn reducing(&self) -> bool {
        self.reduce_limit2 < f32::INFINITY
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
            let d2 = match (self.clusters.get(a), self.clusters.get(b)) {
                (Some(ca), Some(cb)) => ca.center.distance_squared(cb.center),
                _ => continue,
            };
            if !self.absorb(a, b, observer) {
                continue;
            }
            merged.push(a, b);
            self.radius = self.radius.max(libm::sqrtf(d2));
        }
        self.remove_absorbed(merged.absorbed(), observer);
        merged.len()
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
    /// cheapest disjoint pairs up to 1/32 of the capacity, so the search is paid once per batch
    /// of far points. The join radius widens to the largest merged distance.
    pub(super) fn merge_closest_pairs(&mut self, observer: &mut impl Observer) {
        let pairs = self.candidate_pairs(self.limit() / MAX_MERGE_BATCH);
        self.merge_pairs(&pairs, true, observer);
    }

    /// The final reduction: merges the cheapest pairs by [`planar`] cost until at most `n`
    /// clusters remain. Pairs are taken within twice the join radius, as the stream's own merges
    /// are, and the reach widens by a quarter only when no pair is left within it: a cost that
    /// favours coplanar pairs would otherwise join patches of a ground plane far apart.
    pub(super) fn reduce_to(&mut self, n: usize, observer: &mut impl Observer) {
        let mut reach = 2.0 * self.radius;
        self.reduce_limit2 = if reach > 0.0 && (reach * reach).is_finite() {
            reach * reach
        } else {
            f32::MAX
        };
        while self.clusters.len() > n.max(1) {
            let pairs = self.candidate_pairs((self.clusters.len() - n).min(MAX_MERGE_BATCH));
            if pairs.len == 0 {
                // Past f32, or before any merge (radius 0): every pair is a candidate.
                if self.reduce_limit2 == f32::MAX {
                    break;
                }
                reach *= 1.25;
                self.reduce_limit2 = if reach > 0.0 && (reach * reach).is_finite() {
                    reach * reach
                } else {
                    f32::MAX
                };
                continue;
            }
            if self.merge_pairs(&pairs, true, observer) == 0 {
                break;
            }
        }
        self.reduce_limit2 = f32::INFINITY;
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
