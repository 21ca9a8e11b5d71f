//! Close pairs by sort and sweep: the working centres sorted along the longest side of their
//! box, each meeting only those after it and near enough along that axis to matter.
//!
//! Why not the centre grid's neighbour queries: they visit 14 hashed cells a centre, and with
//! the pair costs they were most of a device's merge pass. On the 64 KiB image (car6 at its
//! layout, K = 400 with 150 working, under QEMU) the sweep brought a merge pass from 394,000
//! instructions to 299,000 in shells and from 490,000 to 406,000 with the paper's fits, at the
//! same prices and with the same pairs kept.

use super::pairs::ClosestPairs;
use crate::geometry::Point3;

/// A thousandth's margin on a cost's lower bound: a pair's computed cost is within a few f32
/// roundings of its floor times its squared gap or above it, so no pair that could be kept is
/// passed over.
const FLOOR_MARGIN: f32 = 1.0 - 1.0 / 1024.0;

/// Up to `K` centres' indices in order along one axis, with their places on it.
#[derive(Debug)]
pub(super) struct SortedCentres<const K: usize> {
    /// Each centre's place along the axis, by index: looked up at every comparison.
    keys: [f32; K],
    order: [u16; K],
    len: usize,
}

impl<const K: usize> SortedCentres<K> {
    /// The first `K` of `centres`, sorted along the longest side of their box; ties by index,
    /// a total order, so the same centres sort the same on every target.
    pub(super) fn new(centres: impl Iterator<Item = Point3> + Clone) -> Self {
        let axis = crate::geometry::longest_axis(centres.clone());
        let mut sorted = Self {
            keys: [0.0; K],
            order: [0; K],
            len: 0,
        };
        for ((key, slot), c) in sorted
            .keys
            .iter_mut()
            .zip(sorted.order.iter_mut())
            .zip(centres)
        {
            *key = c.coordinate(axis);
            // K is below u16::MAX (the grid asserts it).
            *slot = sorted.len as u16;
            sorted.len += 1;
        }
        let keys = &sorted.keys;
        let key = |i: u16| keys.get(usize::from(i)).copied().unwrap_or(0.0);
        if let Some(order) = sorted.order.get_mut(..sorted.len) {
            crate::num::heap_sort_by(order, |&a, &b| {
                let (ka, kb) = (key(a), key(b));
                ka < kb || (ka == kb && a < b)
            });
        }
        sorted
    }

    fn key(&self, i: u16) -> f32 {
        self.keys.get(usize::from(i)).copied().unwrap_or(0.0)
    }

    /// Offers `closest` each pair less than `within` apart along the axis whose `cost` (of the
    /// lower index and the higher) is `Some`, as (lower, higher). `floor(i)`: the least cost a
    /// squared unit of distance comes to in any pair of centre `i`'s (0 if none is known); a
    /// centre's sweep stops where its gap alone, at that floor, costs more than the dearest
    /// pair `closest` keeps, so the pairs kept are those of a search of every pair.
    pub(super) fn offer_pairs<const N: usize>(
        &self,
        closest: &mut ClosestPairs<N>,
        within: f32,
        floor: impl Fn(usize) -> f32,
        mut cost: impl FnMut(usize, usize) -> Option<f32>,
    ) {
        let order = self.order.get(..self.len).unwrap_or(&[]);
        let mut offer = |closest: &mut ClosestPairs<N>, a: usize, b: usize| {
            let (lo, hi) = if a < b { (a, b) } else { (b, a) };
            if let Some(c) = cost(lo, hi) {
                closest.offer(lo, hi, c);
            }
        };
        // Each centre's next in the order first: the cheapest pairs are mostly among them, and
        // the dearest pair kept then bounds the rest of the sweep early.
        for pair in order.windows(2) {
            if let [a, b] = *pair
                && self.key(b) - self.key(a) < within
            {
                offer(closest, usize::from(a), usize::from(b));
            }
        }
        for (at, &ia) in order.iter().enumerate() {
            let (a, ka) = (usize::from(ia), self.key(ia));
            let floor = floor(a) * FLOOR_MARGIN;
            // The next in the order was offered above.
            for &ib in order.get(at + 2..).unwrap_or(&[]) {
                // Sorted: every centre from here on is at least this far along the axis.
                let gap = self.key(ib) - ka;
                if !(gap < within) || (floor > 0.0 && floor * gap * gap > closest.bar()) {
                    break;
                }
                offer(closest, a, usize::from(ib));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sweep keeps what a search of every pair keeps, on centres with ties along the axis,
    /// costs that grow with distance at different rates, and a floor that prunes.
    #[test]
    fn the_sweep_keeps_the_pairs_of_a_search_of_every_pair() {
        let mut state = 12345u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        for round in 0..50 {
            let n = 2 + round * 3;
            let centres: [Point3; 150] = core::array::from_fn(|_| {
                // Coarse x, so centres tie along the longest axis.
                Point3::new((next() * 8.0).floor(), next() * 2.0, next())
            });
            let centres = &centres[..n];
            let counts: [f32; 150] = core::array::from_fn(|_| 1.0 + (next() * 20.0).floor());
            let ward = |a: usize, b: usize| {
                let (na, nb) = (counts[a], counts[b]);
                na * nb / (na + nb) * centres[a].distance_squared(centres[b])
            };
            let within = 1.0 + next() * 6.0;
            let close =
                |a: usize, b: usize| centres[a].distance_squared(centres[b]) < within * within;
            let fewest = counts[..n].iter().copied().fold(f32::INFINITY, f32::min);
            let floor = |i: usize| counts[i] * fewest / (counts[i] + fewest);
            let mut swept = ClosestPairs::<8>::new(1 + round % 8);
            SortedCentres::<150>::new(centres.iter().copied()).offer_pairs(
                &mut swept,
                within,
                floor,
                |a, b| close(a, b).then(|| ward(a, b)),
            );
            let mut every = ClosestPairs::<8>::new(1 + round % 8);
            for a in 0..n {
                for b in a + 1..n {
                    if close(a, b) {
                        every.offer(a, b, ward(a, b));
                    }
                }
            }
            assert!(
                every.len > 0 || n < 3,
                "round {round}: no pair within {within}"
            );
            assert_eq!(
                swept.iter().collect::<heapless::Vec<_, 8>>(),
                every.iter().collect::<heapless::Vec<_, 8>>(),
                "round {round}"
            );
        }
    }
}
