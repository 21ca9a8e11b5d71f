//! A fixed-size spatial hash over cluster centres, so finding the centre near a point costs a few
//! bucket visits instead of a scan of all K centres.
//!
//! Cells are cubes of edge `cell`; a cell's coordinates hash into one of `G` buckets, and each
//! bucket chains its centres through `next`. With `cell >= 2 r`, every centre within `r` of a point
//! lies in one of the 8 cells around the point's corner of its own cell.

use crate::geometry::Point3;

const NONE: u16 = u16::MAX;

#[derive(Clone, Debug)]
pub struct CentreGrid<const K: usize, const G: usize> {
    cell: f32,
    heads: [u16; G],
    next: [u16; K],
    /// The cell each indexed centre was filed under.
    cells: [[i32; 3]; K],
    filed: [bool; K],
}

/// Whether `filed` is cell `c`: compared field by field, because `[i32; 3] ==` (and `Option`'s)
/// compiles to a call to `memcmp` at opt-level "s", which was 7% of the firmware's run.
#[inline(always)]
fn same_cell(filed: Option<&[i32; 3]>, c: &[i32; 3]) -> bool {
    filed.is_some_and(|f| f[0] == c[0] && f[1] == c[1] && f[2] == c[2])
}

// Large odd multipliers (Teschner et al.'s spatial hash) spread neighbouring cells: a cell's
// hash is the XOR of its coordinates' terms, so a query of cells that share coordinates
// multiplies each coordinate once.
const X: u32 = 73_856_093;
const Y: u32 = 19_349_663;
const Z: u32 = 83_492_791;

#[inline(always)]
fn term(coordinate: i32, multiplier: u32) -> u32 {
    (coordinate as u32).wrapping_mul(multiplier)
}

fn cell_coordinate(v: f32, cell: f32) -> i32 {
    // Saturating float-to-int: coordinates beyond i32 cells share the edge cell, still correct.
    floor_to_i32(v / cell)
}

/// `libm::floorf(q) as i32`, the same value for every `q` (NaN 0, saturating at the ends),
/// without libm's software floor: the hardware conversion truncates toward zero, which is the
/// floor unless it rounded a negative non-integer up. Below 2^23 the truncation and its
/// conversion back are exact; above, every f32 is an integer.
#[inline]
fn floor_to_i32(q: f32) -> i32 {
    let t = q as i32;
    if (t as f32) > q {
        t.saturating_sub(1)
    } else {
        t
    }
}

impl<const K: usize, const G: usize> CentreGrid<K, G> {
    #[inline(always)]
    pub const fn new(cell: f32) -> Self {
        const { assert!(K < NONE as usize, "indices are u16") };
        const { assert!(G > 0) };
        Self {
            cell,
            heads: [NONE; G],
            next: [NONE; K],
            cells: [[0; 3]; K],
            filed: [false; K],
        }
    }

    pub fn cell(&self) -> f32 {
        self.cell
    }

    fn cell_of(&self, p: Point3) -> [i32; 3] {
        [
            cell_coordinate(p.x, self.cell),
            cell_coordinate(p.y, self.cell),
            cell_coordinate(p.z, self.cell),
        ]
    }

    fn bucket(c: [i32; 3]) -> usize {
        Self::bucket_of(term(c[0], X), term(c[1], Y), term(c[2], Z))
    }

    /// The bucket of the cell whose coordinates have hash terms `x`, `y`, `z` ([`term`]).
    #[inline(always)]
    fn bucket_of(x: u32, y: u32, z: u32) -> usize {
        (x ^ y ^ z) as usize % G
    }

    /// Files centre `index` at `p`.
    pub fn insert(&mut self, index: usize, p: Point3) {
        let c = self.cell_of(p);
        let b = Self::bucket(c);
        if let (Some(head), Some(next), Some(cell), Some(filed)) = (
            self.heads.get_mut(b),
            self.next.get_mut(index),
            self.cells.get_mut(index),
            self.filed.get_mut(index),
        ) {
            *next = *head;
            *head = index as u16;
            *cell = c;
            *filed = true;
        }
    }

    pub fn remove(&mut self, index: usize) {
        let (Some(&c), Some(true)) = (self.cells.get(index), self.filed.get(index).copied()) else {
            return;
        };
        let b = Self::bucket(c);
        let after = self.next.get(index).copied().unwrap_or(NONE);
        let Some(mut at) = self.heads.get(b).copied() else {
            return;
        };
        if at as usize == index {
            if let Some(head) = self.heads.get_mut(b) {
                *head = after;
            }
        } else {
            // Chains are short (centres per bucket); walk to the predecessor.
            while at != NONE {
                let following = self.next.get(at as usize).copied().unwrap_or(NONE);
                if following as usize == index {
                    if let Some(link) = self.next.get_mut(at as usize) {
                        *link = after;
                    }
                    break;
                }
                at = following;
            }
        }
        if let Some(filed) = self.filed.get_mut(index) {
            *filed = false;
        }
    }

    /// Re-files centre `index` if it moved into another cell.
    pub fn update(&mut self, index: usize, p: Point3) {
        if !same_cell(self.cells.get(index), &self.cell_of(p))
            || self.filed.get(index) != Some(&true)
        {
            self.remove(index);
            self.insert(index, p);
        }
    }

    /// Empties the grid and files `centres` under a new cell size.
    pub fn rebuild(&mut self, cell: f32, centres: impl Iterator<Item = Point3>) {
        self.cell = cell;
        self.heads = [NONE; G];
        self.filed = [false; K];
        for (i, p) in centres.enumerate() {
            self.insert(i, p);
        }
    }

    /// Calls `f` for the centres filed in cell `c`, whose bucket is `bucket`.
    fn visit_bucket(&self, bucket: usize, c: [i32; 3], mut f: impl FnMut(usize)) {
        let mut at = self.heads.get(bucket).copied().unwrap_or(NONE);
        while at != NONE {
            if same_cell(self.cells.get(at as usize), &c) {
                f(at as usize);
            }
            at = self.next.get(at as usize).copied().unwrap_or(NONE);
        }
    }

    /// Where `v` lies along one axis: its cell, the neighbour on the side it is nearer, their
    /// hash terms, and a lower bound on the squared distance from `v` to that neighbour.
    #[inline(always)]
    fn axis(&self, v: f32, multiplier: u32) -> Axis {
        let q = v / self.cell;
        let c = floor_to_i32(q);
        let (other, gap) = if q - (c as f32) < 0.5 {
            (c.saturating_sub(1), v - c as f32 * self.cell)
        } else {
            (c.saturating_add(1), (c as f32 + 1.0) * self.cell - v)
        };
        // The true gap can be smaller than this f32 one: a centre is filed by its rounded
        // quotient, and the gap and the caller's distances are rounded too. Each error is
        // within a few f32 ulps of |v| + 2 cells; 2^-19 of that is ample. Beyond 2^22 cells
        // the cell index itself is inexact: no bound.
        let slack = (v.abs() + 2.0 * self.cell) * (1.0 / (1u32 << 19) as f32);
        let near = gap - slack;
        let bound = if near > 0.0 && c.unsigned_abs() < 1 << 22 {
            near * near
        } else {
            0.0
        };
        Axis {
            cell: [c, other],
            term: [term(c, multiplier), term(other, multiplier)],
            bound,
        }
    }

    /// Calls `f` for the centres of the 8 cells that can hold a centre within `cell / 2` of `p`,
    /// `p`'s own cell first, and skips a cell that lies farther from `p` than the squared
    /// distance `f` last returned (`limit` before it is called): a nearest-centre search
    /// returns its best so far and so never walks a cell that cannot hold a better centre.
    pub fn for_each_within_half_cell(
        &self,
        p: Point3,
        limit: f32,
        mut f: impl FnMut(usize) -> f32,
    ) {
        let [x, y, z] = [self.axis(p.x, X), self.axis(p.y, Y), self.axis(p.z, Z)];
        // Each cell's bound, by its mask: bit j set, the neighbour along axis j.
        let (xy, xz, yz) = (x.bound + y.bound, x.bound + z.bound, y.bound + z.bound);
        let bounds = [0.0, x.bound, y.bound, xy, z.bound, xz, yz, xy + z.bound];
        let mut best = limit;
        for (mask, &bound) in bounds.iter().enumerate() {
            if bound > best {
                continue;
            }
            let [i, j, k] = [0, 1, 2].map(|bit| mask >> bit & 1 != 0);
            let cell = [x.cell_if(i), y.cell_if(j), z.cell_if(k)];
            let bucket = Self::bucket_of(x.term_if(i), y.term_if(j), z.term_if(k));
            self.visit_bucket(bucket, cell, |c| best = f(c));
        }
    }
}

/// One axis of a half-cell query ([`CentreGrid::axis`]): p's cell and the neighbour.
struct Axis {
    cell: [i32; 2],
    term: [u32; 2],
    /// At most the squared distance from p to the neighbour's side.
    bound: f32,
}

impl Axis {
    #[inline(always)]
    fn cell_if(&self, neighbour: bool) -> i32 {
        let [own, other] = self.cell;
        if neighbour { other } else { own }
    }

    #[inline(always)]
    fn term_if(&self, neighbour: bool) -> u32 {
        let [own, other] = self.term;
        if neighbour { other } else { own }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_to_i32_is_libm_floor() {
        let fixed = [
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.5,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            2_147_483_520.0,
            -2_147_483_648.0,
            3e9,
            -3e9,
            1e30,
            -1e30,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut s = 7u32;
        let random = core::iter::repeat_with(move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            f32::from_bits(s)
        });
        for q in fixed.into_iter().chain(random.take(100_000)) {
            assert_eq!(floor_to_i32(q), libm::floorf(q) as i32, "{q:e}");
        }
    }

    /// The nearest centre within half a cell (ties: the lowest index) by the pruned query, as
    /// the mapper searches, against a scan of every centre: on random points, on points and
    /// centres a few ulps either side of cell boundaries, near 0 and far from it.
    #[test]
    fn the_pruned_query_finds_the_nearest_centre() {
        let mut s = 11u32;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        };
        for (cell, at) in [
            (1.0f32, 0.0f32),
            (0.37, 1000.0),
            (2.5e-3, -20.0),
            (64.0, 1e5),
        ] {
            // Coordinates on a grid of eighth cells, some nudged by a few ulps.
            let coordinate = |next: &mut dyn FnMut() -> u32| {
                let v = at + (next() % 48) as f32 * cell / 8.0 - 3.0 * cell;
                match next() % 4 {
                    0 => (0..next() % 4).fold(v, |v, _| v.next_up()),
                    1 => (0..next() % 4).fold(v, |v, _| v.next_down()),
                    2 => v + (next() % 1000) as f32 * cell / 8000.0,
                    _ => v,
                }
            };
            let mut grid = CentreGrid::<64, 16>::new(cell);
            let mut centres = [Point3::default(); 64];
            for (i, c) in centres.iter_mut().enumerate() {
                *c = Point3::new(
                    coordinate(&mut next),
                    coordinate(&mut next),
                    coordinate(&mut next),
                );
                grid.insert(i, *c);
            }
            let r2 = (0.5 * cell) * (0.5 * cell);
            let better = |i: usize, d: f32, best: Option<(usize, f32)>| {
                d <= r2 && best.is_none_or(|(bi, bd)| d < bd || (d == bd && i < bi))
            };
            for _ in 0..20_000 {
                let p = Point3::new(
                    coordinate(&mut next),
                    coordinate(&mut next),
                    coordinate(&mut next),
                );
                let mut scanned = None;
                for (i, c) in centres.iter().enumerate() {
                    let d = p.distance_squared(*c);
                    if better(i, d, scanned) {
                        scanned = Some((i, d));
                    }
                }
                let mut searched = None;
                grid.for_each_within_half_cell(p, r2, |i| {
                    let d = p.distance_squared(centres[i]);
                    if better(i, d, searched) {
                        searched = Some((i, d));
                    }
                    searched.map_or(r2, |(_, d)| d)
                });
                assert_eq!(searched, scanned, "cell {cell} at {at}: {p:?}");
            }
            // The cases pruning decides: a centre just across a cell boundary from `p` and
            // another in `p`'s cell at about the same distance, a few ulps either way.
            let ulps = |v: f32, n: u32| match n % 7 {
                k @ 0..3 => (0..=k).fold(v, |v, _| v.next_down()),
                k @ 3..6 => (3..=k).fold(v, |v, _| v.next_up()),
                _ => v,
            };
            let base = (at / cell).floor() * cell;
            for _ in 0..20_000 {
                let b = base + ((next() % 7) as f32 - 3.0) * cell;
                let g = (1 + next() % 999) as f32 / 2000.0 * cell;
                let below = next() % 2 == 0;
                let x = if below { b - g } else { b + g };
                let (y, z) = (base + 0.5 * cell, base - 1.5 * cell);
                let across = Point3::new(ulps(b, next()), y, z);
                let along = Point3::new(x, y + ulps((b - x).abs(), next()), z);
                let mut grid = CentreGrid::<4, 4>::new(cell);
                let pair = if next() % 2 == 0 {
                    [across, along]
                } else {
                    [along, across]
                };
                for (i, c) in pair.iter().enumerate() {
                    grid.insert(i, *c);
                }
                let p = Point3::new(x, y, z);
                let mut scanned = None;
                for (i, c) in pair.iter().enumerate() {
                    let d = p.distance_squared(*c);
                    if better(i, d, scanned) {
                        scanned = Some((i, d));
                    }
                }
                let mut searched = None;
                grid.for_each_within_half_cell(p, r2, |i| {
                    let d = p.distance_squared(pair[i]);
                    if better(i, d, searched) {
                        searched = Some((i, d));
                    }
                    searched.map_or(r2, |(_, d)| d)
                });
                assert_eq!(searched, scanned, "cell {cell} at {at}: {p:?} {pair:?}");
            }
        }
    }

    #[test]
    fn finds_every_centre_within_half_a_cell_and_survives_moves() {
        let mut grid = CentreGrid::<64, 16>::new(1.0);
        let mut centres = [Point3::default(); 64];
        let mut s = 3u32;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s % 10_000) as f32 / 1000.0 - 5.0
        };
        for (i, c) in centres.iter_mut().enumerate() {
            *c = Point3::new(next(), next(), next());
            grid.insert(i, *c);
        }
        for round in 0..3 {
            for _ in 0..2000 {
                let p = Point3::new(next(), next(), next());
                let mut seen = [false; 64];
                grid.for_each_within_half_cell(p, f32::INFINITY, |i| {
                    seen[i] = true;
                    f32::INFINITY
                });
                for (i, c) in centres.iter().enumerate() {
                    let d = libm::sqrtf(p.distance_squared(*c));
                    if d <= 0.5 * grid.cell() {
                        assert!(seen[i], "round {round}: centre {i} at {d} missed");
                    }
                }
            }
            // Move half the centres, remove one, then continue checking.
            for (i, c) in centres.iter_mut().enumerate().step_by(2) {
                *c = Point3::new(c.x + 0.7, c.y - 1.3, c.z);
                grid.update(i, *c);
            }
        }
    }
}
