//! A kd-tree over the k centres that finds the nearest and second-nearest centre of a point,
//! with the answer the plain scan gives: the smallest `fl(D^2)`, ties to the lowest index.
//!
//! Layout: a complete binary tree of depth `depth_for(k)` over a permutation of the centres.
//! Node `i` has children `2i + 1`, `2i + 2`; a node covering `order[lo..hi]` splits it at
//! `lo + (hi - lo) / 2` along its box's longest axis, so every leaf holds at most `LEAF`
//! centres and the ranges are recomputed while descending instead of stored. Each node keeps
//! the bounding box of its centres and the largest drift among them; a subtree is skipped only
//! when `margin::box_beyond` (or `lower`) proves none of its centres can matter, ties included.

use super::margin::{box_beyond, lower, squared};
use crate::geometry::Point3;

/// Centres per leaf at most.
pub const LEAF: usize = 8;

/// Deepest tree the traversal stack supports (2^32 leaves).
const MAX_DEPTH: u32 = 32;

/// One node: the bounding box of its centres and the largest drift among them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TreeNode {
    lo: Point3,
    hi: Point3,
    drift: f32,
}

impl TreeNode {
    /// The box's squared distance from `p`, computed like `fl(D^2)` (same error model).
    #[inline]
    fn squared_from(&self, p: Point3) -> f32 {
        let dx = (self.lo.x - p.x).max(p.x - self.hi.x).max(0.0);
        let dy = (self.lo.y - p.y).max(p.y - self.hi.y).max(0.0);
        let dz = (self.lo.z - p.z).max(p.z - self.hi.z).max(0.0);
        dx * dx + dy * dy + dz * dz
    }

    const EMPTY: TreeNode = TreeNode {
        lo: Point3::new(f32::INFINITY, f32::INFINITY, f32::INFINITY),
        hi: Point3::new(f32::NEG_INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY),
        drift: 0.0,
    };

    fn include(&mut self, p: Point3, drift: f32) {
        self.lo = Point3::new(self.lo.x.min(p.x), self.lo.y.min(p.y), self.lo.z.min(p.z));
        self.hi = Point3::new(self.hi.x.max(p.x), self.hi.y.max(p.y), self.hi.z.max(p.z));
        self.drift = self.drift.max(drift);
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

/// Number of nodes the caller provides for `k` centres.
pub const fn nodes_for(k: usize) -> usize {
    (2usize << depth_for(k)) - 1
}

/// The two nearest centres in the plain scan's order (`fl(D^2)`, then index); a missing place
/// (a single centre) has index `u32::MAX` and an infinite distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    pub index: u32,
    pub squared: f32,
    pub second: u32,
    pub second_squared: f32,
    /// A lower bound on the true distance of every centre but these two.
    pub rest: f32,
}

/// A centre in tree order, with its last drift.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TreeCentre {
    point: Point3,
    drift: f32,
}

/// The tree over caller-provided storage: `order` and `sorted` hold k entries each, `nodes`
/// `nodes_for(k)`.
#[derive(Debug)]
pub struct CentreTree<'a> {
    order: &'a mut [u32],
    sorted: &'a mut [TreeCentre],
    nodes: &'a mut [TreeNode],
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
        sorted: &'a mut [TreeCentre],
        nodes: &'a mut [TreeNode],
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

    /// Rebuilds the tree over `centres` (as many as the storage was made for); `drift(i)` is
    /// centre i's last drift, for `max_drift_near`.
    pub fn build(&mut self, centres: &[Point3], drift: impl Fn(usize) -> f32) {
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
            let mut b = TreeNode::EMPTY;
            for &i in range.iter() {
                if let Some(c) = centres.get(i as usize) {
                    b.include(*c, drift(i as usize));
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
            *s = TreeCentre {
                point: centres.get(i as usize).copied().unwrap_or_default(),
                drift: drift(i as usize),
            };
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
    sorted: &'a [TreeCentre],
    nodes: &'a [TreeNode],
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

    /// The two nearest centres of `p`, exactly as a scan in index order ranks them, and a lower
    /// bound on `fl(D^2)` of every other centre. `known` are centres whose `fl(D^2)` the caller
    /// already computed (index `u32::MAX` for none); they only speed the search up. `None` only
    /// for an empty tree.
    pub fn nearest(&self, p: Point3, known: [(u32, f32); 2]) -> Option<Nearest> {
        let root = self.nodes.first()?;
        let none = (u32::MAX, f32::INFINITY);
        let mut places = [none; 3];
        let insert = |places: &mut [(u32, f32); 3], i: u32, sq: f32| {
            if before(sq, i, places[2].1, places[2].0) {
                if before(sq, i, places[1].1, places[1].0) {
                    places[2] = places[1];
                    if before(sq, i, places[0].1, places[0].0) {
                        places[1] = places[0];
                        places[0] = (i, sq);
                    } else {
                        places[1] = (i, sq);
                    }
                } else {
                    places[2] = (i, sq);
                }
            }
        };
        let [first, second] = known;
        let second = if second.0 == first.0 { none } else { second };
        for (i, sq) in [first, second] {
            if (i as usize) < self.order.len() {
                insert(&mut places, i, sq);
            }
        }
        // Lowest box distance among the subtrees skipped; their centres are at least that far.
        let mut skipped = f32::INFINITY;
        let mut stack = [(0usize, 0usize, 0usize, 0u32, 0f32); MAX_DEPTH as usize + 2];
        stack[0] = (0, 0, self.order.len(), 0, root.squared_from(p));
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (node, lo, hi, depth, box_sq) = stack[top];
            if box_beyond(box_sq, places[1].1) {
                skipped = skipped.min(box_sq);
                continue;
            }
            if depth >= self.depth || hi - lo <= 1 {
                let (Some(ids), Some(cs)) = (self.order.get(lo..hi), self.sorted.get(lo..hi))
                else {
                    continue;
                };
                for (&i, c) in ids.iter().zip(cs.iter()) {
                    if i != first.0 && i != second.0 {
                        insert(&mut places, i, squared(p, c.point));
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
        (places[0].0 != u32::MAX).then_some(Nearest {
            index: places[0].0,
            squared: places[0].1,
            second: places[1].0,
            second_squared: places[1].1,
            rest: lower(places[2].1).min(lower(skipped)),
        })
    }
}

impl TreeView<'_> {
    /// The largest drift among the centres other than `own` that may lie closer than `reach`
    /// to `c` (true distance), or `floor` if larger: centres left out are surely at least
    /// `reach` away. A floor equal to the drift of a centre that did not move skips whole
    /// subtrees of still centres, the common case late in a run.
    pub fn max_drift_near(&self, own: u32, c: Point3, reach: f32, floor: f32) -> f32 {
        let mut found = floor;
        let mut stack = [(0usize, 0usize, 0usize, 0u32); MAX_DEPTH as usize + 2];
        stack[0] = (0, 0, self.order.len(), 0);
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (index, lo, hi, depth) = stack[top];
            let Some(node) = self.nodes.get(index) else {
                continue;
            };
            if !(node.drift > found && lower(node.squared_from(c)) < reach) {
                continue;
            }
            if depth >= self.depth || hi - lo <= 1 {
                let (Some(ids), Some(cs)) = (self.order.get(lo..hi), self.sorted.get(lo..hi))
                else {
                    continue;
                };
                for (&i, q) in ids.iter().zip(cs.iter()) {
                    if i != own && q.drift > found && lower(squared(c, q.point)) < reach {
                        found = q.drift;
                    }
                }
            } else if top + 2 <= stack.len() {
                let mid = split(lo, hi);
                stack[top] = (2 * index + 1, lo, mid, depth + 1);
                stack[top + 1] = (2 * index + 2, mid, hi, depth + 1);
                top += 2;
            }
        }
        found
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
            let mut sorted = [TreeCentre::default(); 333];
            let mut nodes = [TreeNode::default(); 255];
            let mut tree = CentreTree::new(
                &mut order[..k],
                &mut sorted[..k],
                &mut nodes[..nodes_for(k)],
            )
            .or_fail("storage sized by nodes_for")?;
            tree.build(centres, |i| i as f32);
            let view = tree.view();
            for q in 0..3000 {
                let p = if q % 3 == 0 {
                    Point3::new((q % 7) as f32 + 0.5, (q % 3) as f32, 0.0)
                } else {
                    Point3::new(lcg(&mut s) * 12.0 - 1.0, lcg(&mut s) * 12.0 - 1.0, 0.5)
                };
                // Hints (true distances of two centres) must not change the answer.
                let h = (q % k) as u32;
                let hints = [
                    [(u32::MAX, f32::INFINITY); 2],
                    [
                        (h, p.distance_squared(centres[h as usize])),
                        (u32::MAX, f32::INFINITY),
                    ],
                    [
                        (h, p.distance_squared(centres[h as usize])),
                        (
                            (h + 1) % k as u32,
                            p.distance_squared(centres[(h as usize + 1) % k]),
                        ),
                    ],
                ];
                let got = view.nearest(p, hints[q % 3]).or_fail("non-empty")?;
                let want = nearest(p, centres);
                assert_eq!((got.index as usize, got.squared), want, "k {k} point {p:?}");
                // The runner-up by the same rule, from a scan without the winner.
                let mut rest = [Point3::default(); 333];
                rest[..k].copy_from_slice(centres);
                let far = Point3::new(1e30, 1e30, 1e30);
                rest[want.0] = far;
                if k > 1 {
                    let second = nearest(p, &rest[..k]);
                    assert_eq!((got.second as usize, got.second_squared), second);
                    rest[second.0] = far;
                } else {
                    assert_eq!((got.second, got.second_squared), (u32::MAX, f32::INFINITY));
                }
                // `rest` bounds the others from below, and not far below the runner-up.
                let third = if k > 2 {
                    nearest(p, &rest[..k]).1
                } else {
                    f32::INFINITY
                };
                assert!(
                    got.rest as f64 <= (third as f64).sqrt(),
                    "k {k} point {p:?}"
                );
                assert!(
                    got.rest >= 0.9999 * got.second_squared.sqrt(),
                    "k {k} {p:?}"
                );
                // Drifts are i as f32: the largest index among centres that may be near.
                let reach = 1.5;
                let near = view.max_drift_near(want.0 as u32, p, reach, 0.0);
                let mut lo = 0.0f32;
                let mut hi = 0.0f32;
                for (i, c) in centres.iter().enumerate() {
                    let d = (p.distance_squared(*c) as f64).sqrt();
                    if i != want.0 && d < reach as f64 * 0.999 {
                        lo = lo.max(i as f32);
                    }
                    if i != want.0 && d < reach as f64 * 1.001 {
                        hi = hi.max(i as f32);
                    }
                }
                assert!(
                    near >= lo && near <= hi,
                    "k {k}: {near} not in [{lo}, {hi}]"
                );
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
        let mut s = [TreeCentre::default(); 3];
        let mut n = [TreeNode::default(); 2];
        assert!(CentreTree::new(&mut o, &mut s, &mut n).is_none());
    }
}
