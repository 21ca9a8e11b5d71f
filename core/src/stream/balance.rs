//! The end of a device's stream: its working clusters made no finer than its frozen store.
//!
//! Why: coarsening keeps a full store at the resolution its capacity affords, while the working
//! clusters the stream ends with are as fine as the join radius made them. On office1 at the
//! board's layout the last eighth of the frame's rows held 181 entities against the batch map's
//! 70, and the first three-eighths half the batch map's count, coarsened over and over. A map
//! is judged at its bytes, so entities spent on the end of the stream are entities missing
//! everywhere else. At the finish, therefore, while more than half of the working shells are
//! smaller (by area, as coarsening weighs a shell) than the store's median shell, the cheapest
//! pairs of working shells merge, ranked by coarsening's planar cost and joined from their
//! moments exactly. The map then ends with fewer entities, each at the store's resolution.
//!
//! A device's budget: each pass lists the cheapest [`LISTED`] pairs within reach among the
//! working shells kept at the finish (distances and single-precision costs, no eigen-solve), and
//! each merge makes one shell. A stream whose working shells are no finer than its store (car6,
//! bun000, the demo drive) pays for the median and one count only.

use super::coarsen::{LISTED, Plane, area, cost};
use super::pairs::ClosestPairs;
use super::shells::kept_shell;
use super::{Observer, StreamCluster, StreamMapper, StreamModel};

/// Candidates lie within this many join radii of each other, as coarsening's do at first.
const REACH_RADII: f32 = 2.0;

/// How the reach widens when no pair is within it.
const WIDEN: f32 = 1.25;

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// Merges working shells while more than half of them are finer than the store's median
    /// shell. Runs after [`StreamMapper::keep_final_shells`], whose kept shells it ranks and
    /// keeps current.
    pub(super) fn balance_working(&mut self, observer: &mut impl Observer) {
        let StreamModel::Shells(params) = self.params.model else {
            return;
        };
        if !self.final_shells {
            return;
        }
        let Some(target) = self.median_frozen_area() else {
            return;
        };
        let finer = |c: &StreamCluster| area(&kept_shell(c)).is_some_and(|a| a < target);
        let mut finer_count = self.clusters.iter().filter(|c| finer(c)).count();
        let mut reach = REACH_RADII * self.radius;
        let tangent_scale = params.tangent_scale as f32;
        while 2 * finer_count > self.clusters.len() {
            let reach2 = reach * reach;
            let pairs = self.working_pairs(reach2, tangent_scale);
            if pairs.len == 0 {
                // Nothing within reach (or the radius never grew): widen, up to every pair.
                if !(reach2 < f32::MAX) || !(reach > 0.0) {
                    break;
                }
                reach *= WIDEN;
                continue;
            }
            let mut absorbed = [0usize; LISTED];
            let mut count = 0;
            let mut touched = [usize::MAX; 2 * LISTED];
            for (_, a, b) in pairs.iter() {
                if 2 * finer_count <= self.clusters.len() - count {
                    break;
                }
                if touched.contains(&a) || touched.contains(&b) {
                    continue;
                }
                let was = usize::from(self.clusters.get(a).is_some_and(finer))
                    + usize::from(self.clusters.get(b).is_some_and(finer));
                if !self.absorb(a, b, observer) {
                    continue;
                }
                self.keep_shell(a, &params);
                let now = usize::from(self.clusters.get(a).is_some_and(finer));
                finer_count = finer_count.saturating_sub(was) + now;
                if let (Some(slot), Some(pair)) = (
                    absorbed.get_mut(count),
                    touched.get_mut(2 * count..2 * count + 2),
                ) {
                    *slot = b;
                    pair.copy_from_slice(&[a, b]);
                    count += 1;
                }
            }
            if count == 0 {
                break;
            }
            self.remove_absorbed(absorbed.get_mut(..count).unwrap_or(&mut []), observer);
        }
    }

    /// The median area of the frozen shells (those whose axes all close), sorting the store's
    /// slots in the sweep's buffer, which the next coarsening scan sorts again.
    fn median_frozen_area(&mut self) -> Option<f32> {
        let len = self.frozen.len();
        let order = self.sweep.get_mut(..len)?;
        for (i, slot) in order.iter_mut().enumerate() {
            *slot = i as u16;
        }
        let frozen = &self.frozen;
        let area_of = |i: u16| {
            frozen
                .get(usize::from(i))
                .and_then(area)
                .unwrap_or(f32::INFINITY)
        };
        crate::num::heap_sort_by(order, |&a, &b| {
            let (x, y) = (area_of(a), area_of(b));
            x < y || (x == y && a < b)
        });
        let closed = order.iter().filter(|&&i| area_of(i).is_finite()).count();
        let median = area_of(*order.get(closed / 2)?);
        median.is_finite().then_some(median)
    }

    /// The cheapest [`LISTED`] pairs of working shells within `reach2` (squared), by
    /// coarsening's planar cost.
    fn working_pairs(&self, reach2: f32, tangent_scale: f32) -> ClosestPairs<LISTED> {
        let mut pairs = ClosestPairs::<LISTED>::new(LISTED);
        for (a, ca) in self.clusters.iter().enumerate() {
            let ea = kept_shell(ca);
            let mut plane_a = None;
            for (b, cb) in self.clusters.iter().enumerate().skip(a + 1) {
                let eb = kept_shell(cb);
                let d2 = ea.entity.center.distance_squared(eb.entity.center);
                if !(d2 <= reach2) {
                    continue;
                }
                if plane_a.is_none() {
                    plane_a = Some(Plane::of(&ea, tangent_scale));
                }
                let (Some(Some(pa)), Some(pb)) = (&plane_a, Plane::of(&eb, tangent_scale)) else {
                    continue;
                };
                if let Some(c) = cost(pa, &pb, d2) {
                    pairs.offer(a, b, c);
                }
            }
        }
        pairs
    }
}
