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
        // Large odd multipliers (Teschner et al.'s spatial hash) spread neighbouring cells.
        let h = (c[0] as u32).wrapping_mul(73_856_093)
            ^ (c[1] as u32).wrapping_mul(19_349_663)
            ^ (c[2] as u32).wrapping_mul(83_492_791);
        h as usize % G
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

    fn visit_cell(&self, c: [i32; 3], mut f: impl FnMut(usize)) {
        let mut at = self.heads.get(Self::bucket(c)).copied().unwrap_or(NONE);
        while at != NONE {
            if same_cell(self.cells.get(at as usize), &c) {
                f(at as usize);
            }
            at = self.next.get(at as usize).copied().unwrap_or(NONE);
        }
    }

    /// Calls `f` for every filed centre whose cell is within one cell of `p`'s on each axis
    /// (27 cells): all centres closer to `p` than `cell`, and possibly some farther.
    pub fn for_each_near(&self, p: Point3, mut f: impl FnMut(usize)) {
        let c = self.cell_of(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let n = [
                        c[0].saturating_add(dx),
                        c[1].saturating_add(dy),
                        c[2].saturating_add(dz),
                    ];
                    self.visit_cell(n, &mut f);
                }
            }
        }
    }

    /// Calls `f` for the centres of the 8 cells that can hold a centre within `cell / 2` of `p`.
    pub fn for_each_within_half_cell(&self, p: Point3, mut f: impl FnMut(usize)) {
        let c = self.cell_of(p);
        let side = |v: f32, ci: i32| {
            // Which neighbour along this axis: the one on the side of the cell p is nearer.
            let frac = v / self.cell - ci as f32;
            if frac < 0.5 {
                ci.saturating_sub(1)
            } else {
                ci.saturating_add(1)
            }
        };
        let other = [side(p.x, c[0]), side(p.y, c[1]), side(p.z, c[2])];
        for mask in 0..8u8 {
            let pick = |axis: usize| {
                if mask & (1 << axis) != 0 {
                    other.get(axis)
                } else {
                    c.get(axis)
                }
            };
            if let (Some(&x), Some(&y), Some(&z)) = (pick(0), pick(1), pick(2)) {
                self.visit_cell([x, y, z], &mut f);
            }
        }
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
                grid.for_each_within_half_cell(p, |i| seen[i] = true);
                let mut near = [false; 64];
                grid.for_each_near(p, |i| near[i] = true);
                for (i, c) in centres.iter().enumerate() {
                    let d = libm::sqrtf(p.distance_squared(*c));
                    if d <= 0.5 * grid.cell() {
                        assert!(seen[i], "round {round}: centre {i} at {d} missed");
                    }
                    if d < grid.cell() {
                        assert!(
                            near[i],
                            "round {round}: centre {i} at {d} missed by the 27-cell query"
                        );
                    }
                }
            }
            // Move half the centres, remove one, then continue checking.
            for (i, c) in centres.iter_mut().enumerate().step_by(2) {
                *c = Point3::new(c.x + 0.7, c.y - 1.3, c.z);
                grid.update(i, *c);
            }
        }
        grid.rebuild(2.5, centres.iter().copied());
        let mut count = 0;
        grid.for_each_near(Point3::default(), |_| count += 1);
        assert!(count > 0);
    }
}
