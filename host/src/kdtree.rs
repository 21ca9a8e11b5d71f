//! A static kd-tree over a cloud, for the completeness half of the score (nearest cloud point
//! of each surface sample), for tau (each point's nearest other point), and for the outlier
//! statistic a read computes (each point's k nearest).
//!
//! Median splits along the widest extent, so the tree is balanced and its shape is a pure
//! function of the points: queries give the same answers whatever the thread count.

/// Points per leaf: a leaf is scanned in full, so small leaves keep the scans short while the
/// tree stays shallow.
const LEAF: usize = 8;

#[derive(Clone, Copy, Debug)]
struct Split {
    axis: u8,
    value: f64,
}

/// A point of the tree and the caller's index of it. Coordinates are f64, or f32 for a cloud
/// whose coordinates are all exact f32 values (half the memory; distances are still f64).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Entry<C = f64> {
    pub point: [C; 3],
    pub index: u32,
}

/// A kd-tree over f64 points, for nearest-point distances (the score's completeness, point
/// spacing, and the outlier statistic of reading).
#[derive(Clone, Debug)]
pub struct KdTree<C = f64> {
    /// The points, permuted so that every subtree owns a contiguous range.
    entries: Vec<Entry<C>>,
    /// Splits in heap order (root 1, children 2n and 2n + 1); a node owns the range
    /// `lo..hi` and its children `lo..mid` and `mid..hi` with `mid = (lo + hi) / 2`, so ranges
    /// need no storage.
    splits: Vec<Split>,
}

/// The nearest point: the caller's index and the Euclidean distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearestPoint {
    pub index: usize,
    pub distance: f64,
}

/// A coordinate type of the tree: f64, or f32 converted exactly.
pub trait Coordinate: Copy + Into<f64> + Send + Sync {}
impl Coordinate for f64 {}
impl Coordinate for f32 {}

impl KdTree<f64> {
    /// Builds the tree; the caller's indices must fit in u32 (a cloud of at most 4 billion points).
    pub fn build(points: &[[f64; 3]]) -> Self {
        Self::from_entries(
            points
                .iter()
                .zip(0u32..)
                .map(|(&point, index)| Entry { point, index })
                .collect(),
        )
    }
}

impl<C: Coordinate> KdTree<C> {
    /// Builds the tree in the caller's allocation (which a reader reserves fallibly): the
    /// entries are permuted in place, and only the splits, at most 8 bytes a point, are new.
    pub fn from_entries(entries: Vec<Entry<C>>) -> Self {
        let n = entries.len();
        // Heap slots for a tree whose leaves hold at most LEAF points.
        let mut slots = 2usize;
        while n.div_ceil(slots / 2) > LEAF {
            slots *= 2;
        }
        let mut tree = Self {
            entries,
            splits: vec![
                Split {
                    axis: 0,
                    value: 0.0
                };
                slots
            ],
        };
        tree.split(1, 0, n);
        tree
    }

    /// The entries in the tree's order (each subtree a contiguous range): visiting them in it
    /// keeps neighbouring queries on neighbouring memory.
    pub fn entries(&self) -> &[Entry<C>] {
        &self.entries
    }

    /// Points in the tree.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether the tree holds no point.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    fn split(&mut self, node: usize, lo: usize, hi: usize) {
        if hi - lo <= LEAF || node >= self.splits.len() {
            return;
        }
        let (mut min, mut max) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for e in &self.entries[lo..hi] {
            for j in 0..3 {
                let c: f64 = e.point[j].into();
                min[j] = min[j].min(c);
                max[j] = max[j].max(c);
            }
        }
        let axis = (0..3).fold(0, |a, j| {
            if max[j] - min[j] > max[a] - min[a] {
                j
            } else {
                a
            }
        });
        let mid = (lo + hi) / 2;
        // The index breaks ties, so the order, and the tree, is a function of the points.
        self.entries[lo..hi].select_nth_unstable_by(mid - lo, |a, b| {
            let (a_c, b_c): (f64, f64) = (a.point[axis].into(), b.point[axis].into());
            a_c.total_cmp(&b_c).then(a.index.cmp(&b.index))
        });
        self.splits[node] = Split {
            axis: axis as u8,
            value: self.entries[mid].point[axis].into(),
        };
        self.split(2 * node, lo, mid);
        self.split(2 * node + 1, mid, hi);
    }

    /// The nearest point to `p`, skipping the caller's index `skip` (a point's own entry, when
    /// asking for its nearest other point). Ties go to the lower caller index.
    pub fn nearest(&self, p: [f64; 3], skip: Option<usize>) -> Option<NearestPoint> {
        let mut best = (f64::INFINITY, usize::MAX);
        self.search(1, 0, self.entries.len(), p, skip, &mut best);
        (best.1 != usize::MAX).then(|| NearestPoint {
            index: best.1,
            distance: best.0.sqrt(),
        })
    }

    /// The `k` nearest points to `p` other than the caller's index `skip`, nearest first, as
    /// (squared distance, caller's index) in `out` (cleared first); ties go to the lower index,
    /// so the answer is a function of the points alone.
    pub fn k_nearest(&self, p: [f64; 3], skip: Option<usize>, k: usize, out: &mut Vec<(f64, u32)>) {
        out.clear();
        if k > 0 {
            self.search_k(1, 0, self.entries.len(), p, skip, k, out);
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn search_k(
        &self,
        node: usize,
        lo: usize,
        hi: usize,
        p: [f64; 3],
        skip: Option<usize>,
        k: usize,
        out: &mut Vec<(f64, u32)>,
    ) {
        if hi - lo <= LEAF || node >= self.splits.len() {
            for &Entry { point: q, index: i } in &self.entries[lo..hi] {
                if Some(i as usize) == skip {
                    continue;
                }
                let d2 = squared_distance(q, p);
                let entry = (d2, i);
                let before = |e: &(f64, u32)| e.0 < d2 || (e.0 == d2 && e.1 < i);
                if out.len() == k && out.last().is_none_or(&before) {
                    continue;
                }
                // k is small (tens): an insertion into the sorted list beats a heap.
                let at = out.partition_point(before);
                if out.len() == k {
                    out.pop();
                }
                out.insert(at, entry);
            }
            return;
        }
        let split = self.splits[node];
        let mid = (lo + hi) / 2;
        let gap = p[split.axis as usize] - split.value;
        let (near, far) = if gap < 0.0 {
            ((2 * node, lo, mid), (2 * node + 1, mid, hi))
        } else {
            ((2 * node + 1, mid, hi), (2 * node, lo, mid))
        };
        self.search_k(near.0, near.1, near.2, p, skip, k, out);
        let worst = if out.len() == k {
            out.last().map_or(f64::INFINITY, |e| e.0)
        } else {
            f64::INFINITY
        };
        if gap * gap <= worst {
            self.search_k(far.0, far.1, far.2, p, skip, k, out);
        }
    }

    fn search(
        &self,
        node: usize,
        lo: usize,
        hi: usize,
        p: [f64; 3],
        skip: Option<usize>,
        best: &mut (f64, usize),
    ) {
        if hi - lo <= LEAF || node >= self.splits.len() {
            for &Entry { point: q, index } in &self.entries[lo..hi] {
                let i = index as usize;
                if Some(i) == skip {
                    continue;
                }
                let d2 = squared_distance(q, p);
                if d2 < best.0 || (d2 == best.0 && i < best.1) {
                    *best = (d2, i);
                }
            }
            return;
        }
        let split = self.splits[node];
        let mid = (lo + hi) / 2;
        let gap = p[split.axis as usize] - split.value;
        let (near, far) = if gap < 0.0 {
            ((2 * node, lo, mid), (2 * node + 1, mid, hi))
        } else {
            ((2 * node + 1, mid, hi), (2 * node, lo, mid))
        };
        self.search(near.0, near.1, near.2, p, skip, best);
        // `<=` keeps equal-distance points on the far side in play for the index tie-break.
        if gap * gap <= best.0 {
            self.search(far.0, far.1, far.2, p, skip, best);
        }
    }
}

/// `|q - p|^2` in f64 (exact for f32 coordinates' conversion).
#[inline]
fn squared_distance<C: Coordinate>(q: [C; 3], p: [f64; 3]) -> f64 {
    let d = |j: usize| q[j].into() - p[j];
    d(0) * d(0) + d(1) * d(1) + d(2) * d(2)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(points: &[[f64; 3]], p: [f64; 3], skip: Option<usize>) -> Option<NearestPoint> {
        let mut best: Option<NearestPoint> = None;
        for (i, q) in points.iter().enumerate() {
            if Some(i) == skip {
                continue;
            }
            let d = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2)).sqrt();
            if best.is_none_or(|b| d < b.distance) {
                best = Some(NearestPoint {
                    index: i,
                    distance: d,
                });
            }
        }
        best
    }

    #[test]
    fn agrees_with_brute_force_including_duplicates_and_skips() {
        // A lattice with repeated points (ties) and scattered ones.
        let mut s = 0x1234_5678_9abc_def1u64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut points = Vec::new();
        for i in 0..500 {
            points.push([(i % 7) as f64, (i % 11) as f64 * 0.5, (i % 3) as f64]);
            points.push([next() * 6.0, next() * 5.0, next() * 2.0]);
        }
        let tree = KdTree::build(&points);
        for (k, q) in points.iter().enumerate().step_by(7) {
            let got = tree.nearest(*q, Some(k)).expect("non-empty");
            let want = brute(&points, *q, Some(k)).expect("non-empty");
            assert_eq!(got.distance, want.distance, "point {k}");
        }
        for _ in 0..500 {
            let q = [next() * 8.0 - 1.0, next() * 7.0 - 1.0, next() * 4.0 - 1.0];
            let got = tree.nearest(q, None).expect("non-empty");
            let want = brute(&points, q, None).expect("non-empty");
            assert_eq!(got, want);
        }
    }

    #[test]
    fn k_nearest_agrees_with_a_sorted_brute_force() {
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut points = Vec::new();
        for i in 0..400 {
            points.push([(i % 5) as f64, (i % 9) as f64 * 0.5, 0.0]);
            points.push([next() * 4.0, next() * 4.0, next()]);
        }
        let tree = KdTree::build(&points);
        let mut got = Vec::new();
        for (j, q) in points.iter().enumerate().step_by(5) {
            for k in [1, 7, 20] {
                tree.k_nearest(*q, Some(j), k, &mut got);
                let mut want: Vec<(f64, u32)> = points
                    .iter()
                    .enumerate()
                    .filter(|&(i, _)| i != j)
                    .map(|(i, r)| {
                        let d2 =
                            (r[0] - q[0]).powi(2) + (r[1] - q[1]).powi(2) + (r[2] - q[2]).powi(2);
                        (d2, i as u32)
                    })
                    .collect();
                want.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                want.truncate(k);
                assert_eq!(got, want, "point {j}, k {k}");
            }
        }
        tree.k_nearest([0.0; 3], None, 5000, &mut got);
        assert_eq!(got.len(), points.len());
    }

    #[test]
    fn tiny_and_empty_trees() {
        assert_eq!(KdTree::build(&[]).nearest([0.0; 3], None), None);
        let one = KdTree::build(&[[1.0, 2.0, 3.0]]);
        assert_eq!(one.nearest([1.0, 2.0, 3.0], Some(0)), None);
        assert_eq!(
            one.nearest([1.0, 2.0, 4.0], None).map(|n| n.distance),
            Some(1.0)
        );
    }
}
