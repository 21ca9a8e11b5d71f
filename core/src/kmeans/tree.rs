//! A kd-tree over the k centres that finds the nearest and second-nearest centre of a point,
//! with the answer the plain scan gives: the smallest `fl(D^2)`, ties to the lowest index.
//!
//! Layout: a complete binary tree of depth `depth_for(k)` over a permutation of the centres.
//! Node `i` has children `2i + 1`, `2i + 2`; a node covering `order[lo..hi]` splits it at
//! `lo + (hi - lo) / 2` along its box's longest axis, so every leaf holds at most `LEAF`
//! centres and the ranges are recomputed while descending instead of stored. Each node keeps
//! the bounding box of its centres; a subtree is skipped only when `margin::box_beyond` proves
//! that none of its centres can reach the second place, ties included.

use super::margin::{box_beyond, squared};
use crate::geometry::Point3;

/// Centres per leaf at most.
pub const LEAF: usize = 8;

/// Deepest tree the traversal stack supports (2^32 leaves).
const MAX_DEPTH: u32 = 32;

/// Axis-aligned bounding box of a node's centres.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Aabb {
    pub lo: Point3,
    pub hi: Point3,
}

impl Aabb {
    /// The box's squared distance from `p`, computed like `fl(D^2)` (same error model).
    #[inline]
    fn squared_from(&self, p: Point3) -> f32 {
        let dx = (self.lo.x - p.x).max(p.x - self.hi.x).max(0.0);
        let dy = (self.lo.y - p.y).max(p.y - self.hi.y).max(0.0);
        let dz = (self.lo.z - p.z).max(p.z - self.hi.z).max(0.0);
        dx * dx + dy * dy + dz * dz
    }

    const EMPTY: Aabb = Aabb {
        lo: Point3::new(f32::INFINITY, f32::INFINITY, f32::INFINITY),
        hi: Point3::new(f32::NEG_INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY),
    };

    fn include(&mut self, p: Point3) {
        self.lo = Point3::new(self.lo.x.min(p.x), self.lo.y.min(p.y), self.lo.z.min(p.z));
        self.hi = Point3::new(self.hi.x.max(p.x), self.hi.y.max(p.y), self.hi.z.max(p.z));
    }

    fn longest_axis(&self) -> usize {
        let e = [
            self.hi.x - self.lo.x,
            self.hi.y - self.lo.y,
            self.hi.z - self.lo.z,
        ];
        if e[0] >= e[1] && e[0] >= e[2] {
            0
        } else if e[1] >= e[2] {
            1
        } else {
            2
        }
    }
}

/// Depth of the tree for `k` centres: the smallest with at most `LEAF` centres per leaf.
pub const fn depth_for(k: usize) -> u32 {
    let mut depth = 0;
    while depth < MAX_DEPTH && k.div_ceil(1 << depth) > LEAF {
        depth += 1;
    }
    depth
}

/// Number of nodes (`Aabb`s) the caller provides for `k` centres.
pub const fn nodes_for(k: usize) -> usize {
    (2usize << depth_for(k)) - 1
}

/// The nearest centre and the runner-up's computed squared distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearestTwo {
    pub index: u32,
    pub squared: f32,
    /// `fl(D^2)` of the second-nearest centre; infinite when there is a single centre.
    pub second_squared: f32,
}

/// The tree over caller-provided storage: `order` and `sorted` hold k entries each, `nodes`
/// `nodes_for(k)`.
#[derive(Debug)]
pub struct CentreTree<'a> {
    order: &'a mut [u32],
    sorted: &'a mut [Point3],
    nodes: &'a mut [Aabb],
    depth: u32,
}

fn axis_value(p: &Point3, axis: usize) -> f32 {
    match axis {
        0 => p.x,
        1 => p.y,
        _ => p.z,
    }
}

fn split(lo: usize, hi: usize) -> usize {
    lo + (hi - lo) / 2
}

impl<'a> CentreTree<'a> {
    /// Wraps storage; `None` if the slices do not match `k = order.len()`.
    pub fn new(
        order: &'a mut [u32],
        sorted: &'a mut [Point3],
        nodes: &'a mut [Aabb],
    ) -> Option<Self> {
        let k = order.len();
        if sorted.len() != k || nodes.len() != nodes_for(k) || k > u32::MAX as usize {
            return None;
        }
        Some(Self {
            order,
            sorted,
            nodes,
            depth: depth_for(k),
        })
    }

    /// Rebuilds the tree over `centres` (as many as the storage was made for).
    pub fn build(&mut self, centres: &[Point3]) {
        for (i, o) in self.order.iter_mut().enumerate() {
            *o = i as u32;
        }
        let k = self.order.len().min(centres.len());
        let mut stack = [(0usize, 0usize, 0usize, 0u32); MAX_DEPTH as usize + 2];
        let mut top = 1;
        stack[0] = (0, 0, k, 0);
        while top > 0 {
            top -= 1;
            let (node, lo, hi, depth) = stack[top];
            let Some(range) = self.order.get_mut(lo..hi) else {
                continue;
            };
            let mut b = Aabb::EMPTY;
            for &i in range.iter() {
                if let Some(c) = centres.get(i as usize) {
                    b.include(*c);
                }
            }
            if let Some(slot) = self.nodes.get_mut(node) {
                *slot = b;
            }
            if depth >= self.depth || hi - lo <= 1 || top + 2 > stack.len() {
                continue;
            }
            let axis = b.longest_axis();
            let mid = split(lo, hi);
            let key = |i: &u32| {
                centres
                    .get(*i as usize)
                    .map_or(0.0, |c| axis_value(c, axis))
            };
            range.select_nth_unstable_by(mid - lo, |a, b| key(a).total_cmp(&key(b)));
            stack[top] = (2 * node + 1, lo, mid, depth + 1);
            stack[top + 1] = (2 * node + 2, mid, hi, depth + 1);
            top += 2;
        }
        for (s, &i) in self.sorted.iter_mut().zip(self.order.iter()) {
            *s = centres.get(i as usize).copied().unwrap_or_default();
        }
    }

    /// Read-only view for queries (shareable between threads).
    pub fn view(&self) -> TreeView<'_> {
        TreeView {
            order: self.order,
            sorted: self.sorted,
            nodes: self.nodes,
            depth: self.depth,
        }
    }
}

/// A built tree, ready for queries.
#[derive(Clone, Copy, Debug)]
pub struct TreeView<'a> {
    order: &'a [u32],
    sorted: &'a [Point3],
    nodes: &'a [Aabb],
    depth: u32,
}

/// `(squared, index)` ordered lexicographically: the plain scan's preference.
#[inline]
fn before(sq: f32, index: u32, than_sq: f32, than_index: u32) -> bool {
    sq < than_sq || (sq == than_sq && index < than_index)
}

impl TreeView<'_> {
    pub fn len(&self) -> usize {
        self.order.len()
    }

    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// The nearest and second-nearest centre of `p`, exactly as a scan in index order finds
    /// them. `None` only for an empty tree.
    pub fn nearest_two(&self, p: Point3) -> Option<NearestTwo> {
        let root = self.nodes.first()?;
        let mut best = (u32::MAX, f32::INFINITY);
        let mut second = (u32::MAX, f32::INFINITY);
        let mut stack = [(0usize, 0usize, 0usize, 0u32, 0f32); MAX_DEPTH as usize + 2];
        stack[0] = (0, 0, self.order.len(), 0, root.squared_from(p));
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (node, lo, hi, depth, box_sq) = stack[top];
            if box_beyond(box_sq, second.1) {
                continue;
            }
            if depth >= self.depth || hi - lo <= 1 {
                let (Some(ids), Some(cs)) = (self.order.get(lo..hi), self.sorted.get(lo..hi))
                else {
                    continue;
                };
                for (&i, &c) in ids.iter().zip(cs.iter()) {
                    let sq = squared(p, c);
                    if before(sq, i, second.1, second.0) {
                        if before(sq, i, best.1, best.0) {
                            second = best;
                            best = (i, sq);
                        } else {
                            second = (i, sq);
                        }
                    }
                }
                continue;
            }
            let mid = split(lo, hi);
            let (left, right) = (2 * node + 1, 2 * node + 2);
            let (Some(lb), Some(rb)) = (self.nodes.get(left), self.nodes.get(right)) else {
                continue;
            };
            let (l_sq, r_sq) = (lb.squared_from(p), rb.squared_from(p));
            if top + 2 > stack.len() {
                continue;
            }
            // The nearer child goes on top, so it is searched first and tightens the bound.
            let l = (left, lo, mid, depth + 1, l_sq);
            let r = (right, mid, hi, depth + 1, r_sq);
            let (far, near) = if l_sq <= r_sq { (r, l) } else { (l, r) };
            stack[top] = far;
            stack[top + 1] = near;
            top += 2;
        }
        (best.0 != u32::MAX).then_some(NearestTwo {
            index: best.0,
            squared: best.1,
            second_squared: second.1,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kmeans::nearest;
    use crate::test_support::{OrFail, TestResult};

    fn lcg(s: &mut u64) -> f32 {
        *s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*s >> 40) as f32 / (1u64 << 24) as f32
    }

    /// The tree against the plain scan, including duplicated centres and grid ties.
    #[test]
    fn matches_the_plain_scan_with_ties() -> TestResult {
        let mut s = 5u64;
        for k in [1usize, 2, 3, 8, 9, 17, 100, 333] {
            let mut centres = [Point3::default(); 333];
            for (i, c) in centres.iter_mut().take(k).enumerate() {
                *c = if i % 5 == 4 {
                    // Integer grid: many exact ties in fl(D^2), and some duplicates.
                    Point3::new((i % 7) as f32, (i % 3) as f32, 0.0)
                } else {
                    Point3::new(lcg(&mut s) * 10.0, lcg(&mut s) * 10.0, lcg(&mut s))
                };
            }
            let centres = &centres[..k];
            let mut order = [0u32; 333];
            let mut sorted = [Point3::default(); 333];
            let mut nodes = [Aabb::default(); 255];
            let mut tree = CentreTree::new(
                &mut order[..k],
                &mut sorted[..k],
                &mut nodes[..nodes_for(k)],
            )
            .or_fail("storage sized by nodes_for")?;
            tree.build(centres);
            let view = tree.view();
            for q in 0..3000 {
                let p = if q % 3 == 0 {
                    Point3::new((q % 7) as f32 + 0.5, (q % 3) as f32, 0.0)
                } else {
                    Point3::new(lcg(&mut s) * 12.0 - 1.0, lcg(&mut s) * 12.0 - 1.0, 0.5)
                };
                let got = view.nearest_two(p).or_fail("non-empty")?;
                let want = nearest(p, centres);
                assert_eq!((got.index as usize, got.squared), want, "k {k} point {p:?}");
                let mut second = f32::INFINITY;
                for (i, c) in centres.iter().enumerate() {
                    if i != want.0 {
                        second = second.min(p.distance_squared(*c));
                    }
                }
                assert_eq!(got.second_squared, second, "k {k} point {p:?}");
            }
        }
        Ok(())
    }

    #[test]
    fn storage_sizes() {
        assert_eq!(depth_for(1), 0);
        assert_eq!(depth_for(8), 0);
        assert_eq!(depth_for(9), 1);
        assert_eq!(depth_for(8880), 11);
        assert_eq!(nodes_for(8), 1);
        assert_eq!(nodes_for(8880), 4095);
        let mut o = [0u32; 3];
        let mut s = [Point3::default(); 3];
        let mut n = [Aabb::default(); 2];
        assert!(CentreTree::new(&mut o, &mut s, &mut n).is_none());
    }
}
