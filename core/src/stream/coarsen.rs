//! Coarsening: when a cluster is due to freeze and the frozen store is full, two frozen shells
//! merge into one first, so the store keeps taking what the scan leaves behind.
//!
//! Why: the join radius starts at nothing and grows with the merges, so the first clusters a
//! stream freezes are its finest, and a device's store used to fill within the first quarter of
//! a frame (five_people at the board's layout: 630, 57, 35 and 26 entities nearest each quarter
//! of its rows, against the batch map's 232, 214, 193 and 182); the rest of the frame then had
//! only the working clusters, merged ever coarser. Merging the cheapest frozen pairs spreads the
//! store over the whole stream at the resolution its capacity can afford, as the working set's
//! merges do for the clusters.
//!
//! A frozen shell keeps no moments, so each stands for a patch whose mean is its centre and whose
//! covariance its axes give back ([`crate::shell`] made them from it), weighed by its area (the
//! product of its two longest semi-axes): a frozen entity keeps no point count, and one would
//! cost the 64 KiB image a thousand bytes. Pairs are ranked by how far the merged patch would
//! spread off its plane, as the final reduction ranks working clusters ([`PLANAR_WARD`]), so
//! patches of one surface merge first; only pairs within two join radii are candidates, since
//! the cost favours coplanar pairs, which would otherwise join patches of a floor far apart.
//!
//! A device's budget: a scan sorts the store along the longest side of its centres' box and
//! sweeps it, measuring at most [`MOST_MEASURED`] distances (and ranking at most
//! [`MOST_RANKED`] pairs) from the place in that order where the last scan stopped, and keeps the cheapest 32 pairs (`LISTED`); each freeze into a full store
//! merges the next of them whose slots no merge or carving has changed since, priced as a fit,
//! and a scan runs only once the list is spent, at its own price ([`super::Pacing::scan`]).
//! Sorted, the distances a scan measures are the pairs that can be within reach wherever in the
//! store they lie: a scan of rows in store order saw a slice of the store, and merged the
//! cheapest pair of that slice.

use super::pairs::ClosestPairs;
use super::{FrozenEntity, PLANAR_WARD, StreamMapper, StreamModel};
use crate::geometry::{Entity, Point3};
use crate::map::record::{rotation_column32, rotation_of_code};
use crate::num::square_root;
use crate::shell::{ShellParams, shell_single};

/// Most pair distances one scan measures, each pair within reach also ranked by its planar
/// cost (at most [`MOST_RANKED`]). Fewer see less of the store: with a shell's freeze priced
/// at 8, at 1,000 the board's maps scored a geometric mean of 1.14 times the batch map's
/// Chamfer distance over every shared input where 8,000 scored 1.07.
pub const MOST_MEASURED: usize = 8_000;

/// Most pairs one scan ranks by their planar cost (those within reach of the distances it
/// measures): a ranked pair costs the 64 KiB image some 700 instructions, a measured one some
/// 40, and a store has thousands in reach. At 800 the image's longest scan (bun000 in shells)
/// is 1.25 million instructions with its freezes, under a third of the receive ring's fill
/// time at the line's rate (3.8 million at 168 MHz); at 1,500 the demo drive's was 1.69
/// million. Over every shared input the board's maps scored a geometric mean of 1.19 times
/// the batch map's Chamfer distance either way (docs/design.md, "A device's layout").
pub const MOST_RANKED: usize = 800;

/// Candidates lie within this many join radii of each other.
const REACH_RADII: f32 = 2.0;

/// How the reach widens after a whole store's scan found no pair within it.
const WIDEN: f32 = 1.25;

/// The join radius grows to this share of a coarsening's merged distance: the working clusters
/// then keep to the resolution the frozen store has come to.
pub const RADIUS_SHARE: f32 = 0.5;

/// Where coarsening stands: the last scan's candidates and where the next scan starts.
#[derive(Clone, Debug)]
pub(super) struct Coarsening {
    pending: ClosestPairs<LISTED>,
    /// The next candidate of `pending` to try.
    next: usize,
    /// The place in the sweep's order the next scan starts from.
    row: usize,
    /// Rows scanned since a scan last found a candidate.
    empty_rows: usize,
    /// The reach in join radii: [`REACH_RADII`], widened by [`WIDEN`] whenever a whole store
    /// had no pair within it.
    reach: f32,
}

/// Candidate pairs a scan lists. A list serves until its pairs are spent, each pair skipped
/// once a merge or carving has changed either slot (a bit in the slots' marks), so the more it
/// lists the fewer scans the freezes pay for; past 32 the board's maps gained nothing
/// (docs/design.md, "A device's layout"), and each pair costs the 64 KiB image 8 bytes.
pub const LISTED: usize = 32;

impl Coarsening {
    pub(super) const fn new() -> Self {
        Self {
            pending: ClosestPairs::new(LISTED),
            next: 0,
            row: 0,
            empty_rows: 0,
            reach: REACH_RADII,
        }
    }

    /// Whether the candidates of the last scan are spent (a freeze into a full store then
    /// scans first).
    pub(super) fn spent(&self) -> bool {
        self.next >= self.pending.len
    }
}

/// The area a frozen shell stands for, its two longest semi-axes' product; `None` for a shell
/// with an axis that does not close (never merged: it has no patch to weigh).
pub(super) fn area(e: &FrozenEntity) -> Option<f32> {
    let w = e.entity.weights;
    if !w.iter().all(|&w| w > 0.0 && w.is_finite()) {
        return None;
    }
    let (_, lo, mid) = thin_axis(w);
    let area = (1.0 / square_root(lo)) * (1.0 / square_root(mid));
    (area > 0.0 && area.is_finite()).then_some(area)
}

/// The shortest semi-axis (the largest weight), and the weights of the two longer ones.
fn thin_axis([a, b, c]: [f32; 3]) -> (usize, f32, f32) {
    if a >= b && a >= c {
        (0, b, c)
    } else if b >= c {
        (1, a, c)
    } else {
        (2, a, b)
    }
}

/// A frozen shell as its plane, in single precision: what ranking a pair needs.
pub(super) struct Plane {
    center: Point3,
    /// The unit normal: the direction of the shortest semi-axis.
    normal: [f32; 3],
    area: f32,
    /// The patch's variance along its plane (the mean of its two tangent variances).
    tangent: f32,
}

impl Plane {
    pub(super) fn of(e: &FrozenEntity, tangent_scale: f32) -> Option<Self> {
        let area = area(e)?;
        let (thin, lo, mid) = thin_axis(e.entity.weights);
        let tangent = 0.5 * (lo.recip() + mid.recip()) / (tangent_scale * tangent_scale);
        tangent.is_finite().then_some(Self {
            center: e.entity.center,
            normal: rotation_column32(e.rotation, thin),
            area,
            tangent,
        })
    }
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The cost of merging two frozen shells: how far the merged patch spreads off its plane
/// beyond the two patches (area-weighted, as the final reduction's planar cost counts points:
/// each patch's offset from the merged plane, and its tilt against it times its spread along
/// its own plane), plus [`PLANAR_WARD`] of Ward's cost. Two patches of one surface cost next to
/// nothing, two walls across a corner a great deal. `None` if either shell has no area or the
/// cost is not finite.
pub(super) fn cost(a: &Plane, b: &Plane, d2: f32) -> Option<f32> {
    let (wa, wb) = (a.area, b.area);
    let total = wa + wb;
    let nb = if dot(a.normal, b.normal) < 0.0 {
        b.normal.map(|v| -v)
    } else {
        b.normal
    };
    let sum = [0, 1, 2].map(|j| {
        wa * a.normal.get(j).copied().unwrap_or(0.0) + wb * nb.get(j).copied().unwrap_or(0.0)
    });
    // The merged plane's normal is `sum` over its length; the cost wants only squares of its
    // dot products, so the length is never taken.
    let length2 = dot(sum, sum);
    let (normal, length2) = if length2 > 0.0 {
        (sum, length2)
    } else {
        (a.normal, 1.0)
    };
    let d = [
        b.center.x - a.center.x,
        b.center.y - a.center.y,
        b.center.z - a.center.z,
    ];
    let off = dot(normal, d);
    let tilt = |n: [f32; 3]| {
        let c = dot(normal, n);
        (1.0 - c * c / length2).max(0.0)
    };
    let ward = wa * wb / total;
    let cost = ward * off * off / length2
        + wa * a.tangent * tilt(a.normal)
        + wb * b.tangent * tilt(nb)
        + PLANAR_WARD * ward * d2;
    cost.is_finite().then_some(cost)
}

/// A frozen shell's patch: its centre, the covariance its axes give back, and its area.
struct Patch {
    center: [f64; 3],
    covariance: [[f64; 3]; 3],
    area: f64,
}

impl Patch {
    fn of(e: &FrozenEntity, params: &ShellParams) -> Option<Self> {
        let area = f64::from(area(e)?);
        let scales = [
            params.tangent_scale,
            params.tangent_scale,
            params.normal_scale,
        ];
        let r = rotation_of_code(e.rotation).matrix();
        let mut covariance = [[0.0; 3]; 3];
        for (j, (&w, &scale)) in e.entity.weights.iter().zip(scales.iter()).enumerate() {
            // The shell's semi-axis is `scale sqrt(variance)`, and its weight 1 / semi-axis^2.
            let variance = 1.0 / (f64::from(w) * scale * scale);
            for (row, out) in r.iter().zip(covariance.iter_mut()) {
                for (col, v) in r.iter().zip(out.iter_mut()) {
                    *v += variance
                        * row.get(j).copied().unwrap_or(0.0)
                        * col.get(j).copied().unwrap_or(0.0);
                }
            }
        }
        Some(Self {
            center: e.entity.center.to_array().map(f64::from),
            covariance,
            area,
        })
    }
}

/// A coarsening's merged shell may be at most this many times as thick (its thinnest semi-axis)
/// as the thicker of the two it replaces, unless it stays flat ([`FLATNESS`]). Two patches that
/// are not one plane (a table's top and its edge, two walls at a corner) merge into a slab as
/// thick as they are apart, and a store that coarsens thousands of times stacks such merges:
/// office1 at the board's layout had its shells' median thinnest semi-axis at 9.9 mm against
/// the batch map's 5.8, and 1.33 times the batch map's Chamfer distance (1.08 with the bounds
/// and shells' freezes at [`super::Pacing::DEVICE_SHELLS`]). At 1.5 the bunny scans, curved
/// everywhere, lost more than office1 gained (docs/design.md, "A device's layout").
pub const THICKENING: f32 = 3.0;

/// A merged shell whose thinnest semi-axis is at most this share of its longest is a sheet,
/// whatever its parts' thickness: shells with none (a lone point's, below the shells' floor)
/// would otherwise never merge, and a curved surface's patches, whose thickness is their sag,
/// grow four times as thick as they double in size. At 0.03 the board's maps scored a geometric
/// mean of 1.06 times the batch map's Chamfer distance over every shared input, at 0.12 1.07
/// (office1 1.29).
pub const FLATNESS: f32 = 0.03;

/// A shell's thinnest and longest semi-axes, from its largest and smallest weights
/// (`w = 1 / r^2`); an axis of no weight (a plane pair's) is unbounded.
fn thinnest_and_longest(weights: &[f32; 3]) -> (f32, f32) {
    let semi_axis = |w: f32| {
        if w > 0.0 {
            1.0 / square_root(w)
        } else {
            f32::MAX
        }
    };
    let (thin, lo, mid) = thin_axis(*weights);
    let heaviest = weights.get(thin).copied().unwrap_or(0.0);
    (semi_axis(heaviest), semi_axis(lo.min(mid)))
}

/// [`merged`], unless the merged shell is more than [`THICKENING`] times as thick as the thicker
/// of the two and not flat ([`FLATNESS`]).
pub(super) fn merged_thin(
    a: &FrozenEntity,
    b: &FrozenEntity,
    params: &ShellParams,
) -> Option<Entity> {
    let entity = merged(a, b, params)?;
    let thicker = thinnest_and_longest(&a.entity.weights)
        .0
        .max(thinnest_and_longest(&b.entity.weights).0);
    let (thin, longest) = thinnest_and_longest(&entity.weights);
    (thin <= THICKENING * thicker || thin <= FLATNESS * longest).then_some(entity)
}

/// The shell of two frozen shells' patches together: their area-weighted mean and covariance.
pub(super) fn merged(a: &FrozenEntity, b: &FrozenEntity, params: &ShellParams) -> Option<Entity> {
    let (pa, pb) = (Patch::of(a, params)?, Patch::of(b, params)?);
    let total = pa.area + pb.area;
    // About a's centre: the world frame may be far from 0.
    let apart = [0, 1, 2].map(|j| {
        pb.center.get(j).copied().unwrap_or(0.0) - pa.center.get(j).copied().unwrap_or(0.0)
    });
    let shift = apart.map(|d| d * pb.area / total);
    let mut covariance = [[0.0; 3]; 3];
    for (i, out) in covariance.iter_mut().enumerate() {
        for (j, v) in out.iter_mut().enumerate() {
            let at = |m: &[[f64; 3]; 3]| m.get(i).and_then(|r| r.get(j)).copied().unwrap_or(0.0);
            let of = |d: &[f64; 3], k: usize| d.get(k).copied().unwrap_or(0.0);
            let from_b = [0, 1, 2].map(|k| of(&apart, k) - of(&shift, k));
            *v = (pa.area * (at(&pa.covariance) + of(&shift, i) * of(&shift, j))
                + pb.area * (at(&pb.covariance) + of(&from_b, i) * of(&from_b, j)))
                / total;
        }
    }
    let mean = [0, 1, 2]
        .map(|j| pa.center.get(j).copied().unwrap_or(0.0) + shift.get(j).copied().unwrap_or(0.0));
    shell_single(mean, covariance, params)
}

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// Whether the frozen store has no room for another entity.
    pub(super) fn store_full(&self) -> bool {
        self.frozen.len() >= self.params.max_frozen.min(F)
    }

    /// Only shells coarsen: the paper's axis-aligned fits stand for no covariance to merge.
    pub(super) fn coarsens(&self) -> bool {
        matches!(self.params.model, StreamModel::Shells(_)) && self.params.tolerance <= 0.0
    }

    /// Frees a frozen slot by merging the cheapest candidate pair: the next unchanged one of the
    /// last scan's, else one a new scan finds. False if there is none within reach. Out of
    /// line: its frame is not on the stack of every freeze (the 64 KiB image's RAM is short).
    #[inline(never)]
    pub(super) fn coarsen_one(&mut self, observer: &mut impl super::Observer) -> bool {
        let StreamModel::Shells(params) = self.params.model else {
            return false;
        };
        if !self.coarsens() {
            return false;
        }
        let scanned = self.coarsening.spent();
        let widened = scanned && self.scan_frozen_pairs(params.tangent_scale as f32);
        while let Some((_, a, b)) = self.coarsening.pending.get(self.coarsening.next) {
            self.coarsening.next += 1;
            let last = self.frozen.len().saturating_sub(1);
            if self.marks.touched(a) || self.marks.touched(b) {
                continue;
            }
            let (Some(ea), Some(eb)) = (self.frozen.get(a), self.frozen.get(b)) else {
                continue;
            };
            let Some(entity) = merged_thin(ea, eb, &params) else {
                continue;
            };
            let d2 = ea.entity.center.distance_squared(eb.entity.center);
            if let Some(slot) = self.frozen.get_mut(a) {
                *slot = FrozenEntity::of(&entity);
            }
            self.marks.replaced(a);
            if crate::num::swap_remove(&mut self.frozen, b) {
                self.marks.swap_removed(b, last);
            }
            // After the marks moved: the listed pairs name these slots as they were.
            for slot in [a, b, last] {
                self.marks.touch(slot);
            }
            observer.coarsened(a, b);
            self.stats.coarsened += 1;
            self.widen_radius(RADIUS_SHARE * square_root(d2));
            return true;
        }
        // A list spent on changed slots, or a scan of part of the store that found nothing in
        // reach, is no reason to merge working clusters: the next scan (from the next rows, or
        // wider once a whole store had nothing) may well find a pair.
        self.freeze_failed = scanned && (widened || self.coarsening.pending.len > 0);
        false
    }

    /// Lists the cheapest candidate pairs within reach, sweeping the store sorted along the
    /// longest side of its centres' box: each entity meets only those after it in that order
    /// and no farther along it than the reach, so the distances a scan measures are the pairs
    /// that could be candidates, wherever in the store they lie. At most [`MOST_MEASURED`]
    /// distances, from the place in the order where the last scan stopped.
    fn scan_frozen_pairs(&mut self, tangent_scale: f32) -> bool {
        let len = self.frozen.len();
        let axis = crate::geometry::longest_axis(self.frozen.iter().map(|e| e.entity.center));
        let key = |e: &FrozenEntity| e.entity.center.coordinate(axis);
        let order = self.sweep.get_mut(..len).unwrap_or(&mut []);
        for (i, slot) in order.iter_mut().enumerate() {
            *slot = i as u16;
        }
        let frozen = &self.frozen;
        let key_of = |i: u16| frozen.get(usize::from(i)).map_or(0.0, key);
        // Ties by index: a total order, so the same store sorts the same on every target.
        crate::num::heap_sort_by(order, |&a, &b| {
            let (ka, kb) = (key_of(a), key_of(b));
            ka < kb || (ka == kb && a < b)
        });
        let mut pending = ClosestPairs::<LISTED>::new(LISTED);
        let reach = self.coarsening.reach * self.radius;
        // Before the radius has grown (coincident points merged first), nothing is in reach.
        let reach2 = reach * reach;
        let (mut at, mut rows, mut measured, mut ranked) = (self.coarsening.row, 0, 0, 0);
        while rows < len && measured < MOST_MEASURED && ranked < MOST_RANKED {
            at = if at >= len { 0 } else { at };
            let Some((&ia, after)) = order.get(at..).and_then(|s| s.split_first()) else {
                break;
            };
            let a = usize::from(ia);
            if let Some(ea) = frozen.get(a) {
                let ka = key(ea);
                // Its plane once, when a first pair is within reach.
                let mut plane_a = None;
                for &ib in after {
                    let b = usize::from(ib);
                    let Some(eb) = frozen.get(b) else {
                        continue;
                    };
                    measured += 1;
                    // Sorted: every entity from here on is farther along the axis.
                    if !(key(eb) - ka <= reach) {
                        break;
                    }
                    let d2 = ea.entity.center.distance_squared(eb.entity.center);
                    if d2 > reach2 {
                        continue;
                    }
                    ranked += 1;
                    if plane_a.is_none() {
                        plane_a = Some(Plane::of(ea, tangent_scale));
                    }
                    let (Some(Some(pa)), Some(pb)) = (&plane_a, Plane::of(eb, tangent_scale))
                    else {
                        continue;
                    };
                    if let Some(c) = cost(pa, &pb, d2) {
                        pending.offer(a.min(b), a.max(b), c);
                    }
                }
            }
            at += 1;
            rows += 1;
        }
        self.coarsening.row = at;
        let mut widened = false;
        if pending.len == 0 {
            self.coarsening.empty_rows += rows;
            if self.coarsening.empty_rows >= len {
                self.coarsening.reach *= WIDEN;
                self.coarsening.empty_rows = 0;
                widened = true;
            }
        } else {
            self.coarsening.empty_rows = 0;
        }
        self.coarsening.pending = pending;
        self.coarsening.next = 0;
        self.marks.untouch_all();
        self.stats.scans += 1;
        widened
    }
}

#[cfg(test)]
mod tests;
