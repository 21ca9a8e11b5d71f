//! The cheapest merge candidates, kept in a fixed array so a search for room allocates nothing.
//! Indices are kept in 16 bits (the grid's, [`crate::grid`], are too): a coarsening's list of
//! 48 pairs then costs the 64 KiB image 384 bytes, not 576.

/// Most pairs merged per search for room: one search frees up to this many slots.
pub const MAX_MERGE_BATCH: usize = 32;

/// The closest centre pairs seen so far, sorted by distance, ties by index pair, so the choice
/// is independent of visiting order.
#[derive(Clone, Debug)]
pub(super) struct ClosestPairs<const N: usize = MAX_MERGE_BATCH> {
    pairs: [(f32, u16, u16); N],
    pub(super) len: usize,
    wanted: usize,
}

impl<const N: usize> ClosestPairs<N> {
    /// A `const fn`: a mapper built in a static holds one.
    pub(super) const fn new(wanted: usize) -> Self {
        let wanted = if wanted < 1 {
            1
        } else if wanted > N {
            N
        } else {
            wanted
        };
        Self {
            pairs: [(0.0, 0, 0); N],
            len: 0,
            wanted,
        }
    }

    pub(super) fn offer(&mut self, a: usize, b: usize, d: f32) {
        if a >= b {
            return; // each pair once, as (low, high)
        }
        // Capacities are below u16::MAX (the grid asserts it for K, the mapper for F).
        let (Ok(a), Ok(b)) = (u16::try_from(a), u16::try_from(b)) else {
            return;
        };
        let item = (d, a, b);
        let before = |x: &(f32, u16, u16), y: &(f32, u16, u16)| {
            x.0 < y.0 || (x.0 == y.0 && (x.1, x.2) < (y.1, y.2))
        };
        if self.len == self.wanted
            && self
                .pairs
                .get(self.len - 1)
                .is_none_or(|worst| !before(&item, worst))
        {
            return;
        }
        // Into the last slot (appending, or replacing the worst), then bubbled into order.
        let mut at = self.len.min(self.wanted - 1);
        if let Some(slot) = self.pairs.get_mut(at) {
            *slot = item;
        }
        while at > 0
            && self
                .pairs
                .get(at - 1)
                .is_some_and(|prev| before(&item, prev))
        {
            if let Some([prev, cur]) = self.pairs.get_mut(at - 1..=at) {
                core::mem::swap(prev, cur);
            }
            at -= 1;
        }
        self.len = (self.len + 1).min(self.wanted);
    }

    /// The cost a pair must come under to be kept: the dearest kept once the list is full.
    pub(super) fn bar(&self) -> f32 {
        if self.len < self.wanted {
            return f32::INFINITY;
        }
        self.pairs
            .get(self.len.wrapping_sub(1))
            .map_or(f32::INFINITY, |worst| worst.0)
    }

    /// Pair `i` in order, cheapest first: (cost, lower index, higher index).
    pub(super) fn get(&self, i: usize) -> Option<(f32, usize, usize)> {
        self.pairs
            .get(..self.len)
            .and_then(|p| p.get(i))
            .map(|&(d, a, b)| (d, a.into(), b.into()))
    }

    /// The pairs in order, cheapest first.
    pub(super) fn iter(&self) -> impl Iterator<Item = (f32, usize, usize)> + '_ {
        (0..self.len).filter_map(|i| self.get(i))
    }
}

/// The pairs one pass merges: each cluster in at most one of them, and the absorbed side of
/// each to remove once the pass is over (indices move at every removal).
pub(super) struct Disjoint<const N: usize = MAX_MERGE_BATCH> {
    absorbed: [usize; N],
    touched: [usize; N],
    touched_too: [usize; N],
    len: usize,
}

impl<const N: usize> Disjoint<N> {
    pub(super) const fn new() -> Self {
        Self {
            absorbed: [0; N],
            touched: [usize::MAX; N],
            touched_too: [usize::MAX; N],
            len: 0,
        }
    }

    /// Whether neither cluster is in a pair already.
    pub(super) fn free(&self, a: usize, b: usize) -> bool {
        let taken = |i: &usize| self.touched.contains(i) || self.touched_too.contains(i);
        !taken(&a) && !taken(&b)
    }

    /// Notes `b` merged into `a` (dropped when the pass is full).
    pub(super) fn push(&mut self, a: usize, b: usize) {
        if let (Some(slot), Some(ta), Some(tb)) = (
            self.absorbed.get_mut(self.len),
            self.touched.get_mut(self.len),
            self.touched_too.get_mut(self.len),
        ) {
            *slot = b;
            *ta = a;
            *tb = b;
            self.len += 1;
        }
    }

    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// The absorbed clusters, to remove.
    pub(super) fn absorbed(&mut self) -> &mut [usize] {
        self.absorbed.get_mut(..self.len).unwrap_or(&mut [])
    }
}
