//! A static kd-tree over the cloud, for the completeness half of the score (nearest cloud point
//! of each surface sample) and for tau (each point's nearest other point).
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

/// A kd-tree over f64 points, for nearest-point distances (the score's completeness and
/// point spacing).
#[derive(Clone, Debug)]
pub struct KdTree {
    /// The points, permuted so that every subtree owns a contiguous range.
    points: Vec<[f64; 3]>,
    /// `index[i]` is the caller's index of `points[i]`.
    index: Vec<u32>,
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

impl KdTree {
    /// Builds the tree; the caller's indices must fit in u32 (a cloud of at most 4 billion points).
    pub fn build(points: &[[f64; 3]]) -> Self {
        let mut tree = Self {
            points: points.to_vec(),
            index: (0..points.len() as u32).collect(),
            splits: Vec::new(),
        };
        let n = points.len();
        // Heap slots for a tree whose leaves hold at most LEAF points.
        let mut slots = 2usize;
        while n.div_ceil(slots / 2) > LEAF {
            slots *= 2;
        }
        tree.splits = vec![
            Split {
                axis: 0,
                value: 0.0
            };
            slots
        ];
        tree.split(1, 0, n);
        tree
    }

    /// Points in the tree.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the tree holds no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    fn split(&mut self, node: usize, lo: usize, hi: usize) {
        if hi - lo <= LEAF || node >= self.splits.len() {
            return;
        }
        let (mut min, mut max) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in &self.points[lo..hi] {
            for j in 0..3 {
                min[j] = min[j].min(p[j]);
                max[j] = max[j].max(p[j]);
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
        // Permute points and indices together through one order of the range.
        let mut order: Vec<usize> = (lo..hi).collect();
        let points = &self.points;
        order.select_nth_unstable_by(mid - lo, |&a, &b| {
            points[a][axis]
                .total_cmp(&points[b][axis])
                .then(self.index[a].cmp(&self.index[b]))
        });
        let moved: Vec<([f64; 3], u32)> = order
            .iter()
            .map(|&i| (self.points[i], self.index[i]))
            .collect();
        for (k, (p, i)) in moved.into_iter().enumerate() {
            self.points[lo + k] = p;
            self.index[lo + k] = i;
        }
        self.splits[node] = Split {
            axis: axis as u8,
            value: self.points[mid][axis],
        };
        self.split(2 * node, lo, mid);
        self.split(2 * node + 1, mid, hi);
    }

    /// The nearest point to `p`, skipping the caller's index `skip` (a point's own entry, when
    /// asking for its nearest other point). Ties go to the lower caller index.
    pub fn nearest(&self, p: [f64; 3], skip: Option<usize>) -> Option<NearestPoint> {
        let mut best = (f64::INFINITY, usize::MAX);
        self.search(1, 0, self.points.len(), p, skip, &mut best);
        (best.1 != usize::MAX).then(|| NearestPoint {
            index: best.1,
            distance: best.0.sqrt(),
        })
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
            for (q, &i) in self.points[lo..hi].iter().zip(&self.index[lo..hi]) {
                let i = i as usize;
                if Some(i) == skip {
                    continue;
                }
                let d2 = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2);
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
