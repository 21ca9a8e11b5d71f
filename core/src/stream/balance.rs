//! The end of a device's stream: its working clusters made no finer than its frozen store.
//!
//! Why: coarsening keeps a full store at the resolution its capacity affords, while the working
//! clusters the stream ends with are as fine as the join radius made them. On office1 at the
//! board's layout the last eighth of the frame's rows held 141 entities against the batch map's
//! 70, and every other eighth fewer than the batch map's. A map is judged at its bytes, so
//! entities spent on the end of the stream are missing everywhere else. So at the finish of a stream whose store was coarsened, while more than
//! half of the working shells are smaller (by area, as coarsening weighs a shell) than the
//! store's median shell, the cheapest pairs of working shells merge, ranked by coarsening's
//! planar cost and joined from their moments exactly. The map ends with fewer entities, at
//! the store's resolution.
//!
//! A device's budget: each pass lists the cheapest [`LISTED`] pairs within reach among the
//! working shells kept at the finish (distances and single-precision costs, no eigen-solve), and
//! each merge makes one shell. A stream whose store was never coarsened (car6 and the demo
//! drive at the firmware's layouts) pays nothing; one whose working shells are no finer than
//! its store (bun000) pays for a sort of the store and one count.

use super::coarsen::{LISTED, Plane, area, cost};
use super::pairs::{ClosestPairs, Disjoint};
use super::shells::kept_shell;
use super::{Observer, StreamCluster, StreamMapper, StreamModel};

/// Candidates lie within this many join radii of each other, as coarsening's do at first.
const REACH_RADII: f32 = 2.0;

/// How the reach widens when no pair is within it, and at most how many times: a balance is
/// the best the working shells near each other allow, and each widening costs a pass.
const WIDEN: f32 = 1.25;
const MOST_WIDENINGS: u32 = 16;

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// Merges working shells while more than half of them are finer than the store's median
    /// shell. Runs after [`StreamMapper::keep_final_shells`], whose kept shells it ranks and
    /// keeps current. Out of line: its frame (a pair list and the merges' bookkeeping) is on
    /// the stack only while it runs, not in every caller's (the 64 KiB image's RAM is short).
    #[inline(never)]
    pub(super) fn balance_working(&mut self, observer: &mut impl Observer) {
        let StreamModel::Shells(params) = self.params.model else {
            return;
        };
        // Only a store that was coarsened holds shells coarser than they were made.
        if !self.final_shells || self.stats.coarsened == 0 {
            return;
        }
        let Some(target) = self.median_frozen_area() else {
            return;
        };
        let finer = |c: &StreamCluster| area(&kept_shell(c)).is_some_and(|a| a < target);
        let mut finer_count = self.clusters.iter().filter(|c| finer(c)).count();
        let mut reach = REACH_RADII * self.radius;
        let tangent_scale = params.tangent_scale as f32;
        let mut widenings = 0;
        while 2 * finer_count > self.clusters.len() {
            let reach2 = reach * reach;
            let pairs = self.working_pairs(reach2, tangent_scale);
            if pairs.len == 0 {
                // Nothing within reach (or the radius never grew).
                if widenings >= MOST_WIDENINGS || !(reach2 < f32::MAX) || !(reach > 0.0) {
                    break;
                }
                reach *= WIDEN;
                widenings += 1;
                continue;
            }
            let mut merged = Disjoint::<LISTED>::new();
            for (_, a, b) in pairs.iter() {
                if 2 * finer_count <= self.clusters.len() - merged.len() {
                    break;
                }
                if !merged.free(a, b) {
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
                merged.push(a, b);
            }
            if merged.len() == 0 {
                break;
            }
            self.stats.balanced += merged.len() as u64;
            self.remove_absorbed(merged.absorbed(), observer);
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

#[cfg(test)]
mod tests {
    use super::super::shells::shell_of;
    use super::super::tests::shells_params;
    use super::super::{FrozenEntity, StreamCluster, StreamMapper};
    use super::area;
    use crate::geometry::{AxisEntity, Entity, Point3};
    use crate::moments::FixedMoments;
    use crate::shell::ShellParams;
    use crate::test_support::{OrFail, TestResult};

    /// A square patch of the plane z = 0: `n` x `n` points `side` metres across at `(x, y)`.
    fn patch(x: f32, y: f32, side: f32, n: usize) -> FixedMoments {
        let mut m = FixedMoments::new();
        for i in 0..n {
            for j in 0..n {
                let step = side / (n - 1) as f32;
                m.add(Point3::new(x + i as f32 * step, y + j as f32 * step, 0.0));
            }
        }
        m
    }

    /// A mapper whose store holds twelve half-metre patches of one plane and whose working set holds
    /// sixteen patches `side` metres across, side by side in a 4 x 4 block, each of 25 points.
    fn mapper(side: f32) -> Result<StreamMapper<16, 64, 12>, &'static str> {
        let mut m = StreamMapper::<16, 64, 12>::new(shells_params(16, 12));
        for i in 0..12 {
            let shell = shell_of(&patch(2.0 * i as f32, 10.0, 0.5, 5), &ShellParams::DEFAULT)
                .or_fail("a store shell")?;
            m.frozen.push(FrozenEntity::of(&shell)).or_fail("room")?;
        }
        for i in 0..16 {
            let (x, y) = ((i % 4) as f32 * side, (i / 4) as f32 * side);
            let moments = patch(x, y, 0.8 * side, 5);
            let center = super::super::center_of(&moments);
            let cluster = StreamCluster {
                moments,
                center,
                entity: AxisEntity::of_axis_aligned(&Entity::sphere(center, 0.0)),
                stale: u32::MAX,
                last_point: 0,
                seen_through: 0,
            };
            m.clusters.push(cluster).or_fail("room")?;
        }
        m.radius = side;
        // As if coarsening had made the store: only then is it balanced against.
        m.stats.coarsened = 1;
        Ok(m)
    }

    #[test]
    fn working_shells_finer_than_the_store_merge_at_the_finish() -> TestResult {
        let mut m = mapper(0.25)?;
        let mut areas: heapless::Vec<f32, 12> = m.frozen().iter().filter_map(area).collect();
        areas.sort_unstable_by(f32::total_cmp);
        let median = *areas.get(areas.len() / 2).or_fail("a median")?;
        m.finish();
        let left = m.clusters().len();
        // Merged until at most half of the working shells are finer than the store's median.
        assert!(1 < left && left < 16, "{left} working clusters left");
        let frozen = m.frozen().len();
        let finer = m
            .entities()
            .skip(frozen)
            .filter(|e| area(&FrozenEntity::of(&e.entity)).is_some_and(|a| a < median))
            .count();
        assert!(2 * finer <= left, "{finer} of {left} finer than the store");
        assert_eq!(m.stats().merges, 16 - left as u64);
        assert_eq!(m.stats().balanced, 16 - left as u64);
        // Merged exactly, from their moments: every point is still counted, and each working
        // entity is its moments' shell as a finished mapper keeps it.
        let points: u64 = m.clusters().iter().map(|c| c.moments.count()).sum();
        assert_eq!(points, 16 * 25);
        for (e, c) in m.entities().skip(frozen).zip(m.clusters()) {
            let shell = shell_of(&c.moments, &ShellParams::DEFAULT).or_fail("a shell")?;
            assert_eq!(e.entity, FrozenEntity::of(&shell).to_entity());
        }
        Ok(())
    }

    #[test]
    fn working_shells_as_coarse_as_the_store_stay_as_they_are() -> TestResult {
        let mut m = mapper(1.5)?;
        m.finish();
        assert_eq!(m.clusters().len(), 16);
        assert_eq!(m.stats().merges, 0);
        assert_eq!(m.stats().balanced, 0);
        Ok(())
    }
}
