//! One assignment pass of the accelerated Lloyd, point by point.
//!
//! Each point keeps its centre `a` (the label), a runner-up `b` and one bound `rest`: a lower
//! bound on the true distance to every centre other than `a` and `b`. A pass computes the two
//! distances to `a` and `b` exactly, orders them by the plain scan's rule (`fl(D^2)`, then
//! index), and keeps the winner if `margin::surely_nearer` proves that every other centre is
//! strictly farther. Points on the border between two clusters, the usual trouble for bound-based
//! k-means, then cost two distances per pass rather than a search, even when they change sides.
//!
//! `rest` was valid before the centres moved. Centres within `reach[a]` of `c_a` may have come
//! closer by at most `near_drift[a]` (their largest drift, found in the kd-tree); any centre may
//! have come closer by the largest drift of all; and those beyond `reach[a]` are at least
//! `reach[a] - |p - c_a|` away whatever they did. Hamerly's single largest drift would, late in a
//! run, let one restless centre among thousands of still ones spoil every bound (measured on
//! five_people at k = 350: median drift 0, largest 5-8 mm). `separation[a] - |p - c_a|` bounds
//! every other centre too. When the proof fails, the kd-tree gives the exact three nearest.

use super::margin::{squared, sub_down, surely_nearer, upper};
use super::tree::TreeView;
use crate::geometry::Point3;

/// No runner-up known yet (after seeding or an emptied cluster).
pub const UNKNOWN: u32 = u32::MAX;

/// What the accelerated k-means needs per centre between passes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CentreState {
    pub(super) previous: Point3,
    /// Upper bound on how far the centre moved in the last update.
    pub(super) drift: f32,
    /// Lower bound on the distance to the nearest other centre.
    pub(super) separation: f32,
    /// The radius splitting the other centres into near and far ones.
    pub(super) reach: f32,
    /// Largest drift among the centres that may lie within `reach`.
    pub(super) near_drift: f32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Mode {
    /// Lloyd's assignment: the bound slot holds `rest`.
    Bounded,
    /// The last assignment: as `Bounded`, then the bound slot gets the exact squared distance.
    Final,
    /// Labels stay; the bound slot gets the squared distance to the labelled centre.
    Distances,
}

/// What one pass did: labels changed, and points that needed the kd-tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PassCounts {
    pub changed: usize,
    pub searched: usize,
}

impl core::ops::Add for PassCounts {
    type Output = Self;
    fn add(self, other: Self) -> Self {
        Self {
            changed: self.changed + other.changed,
            searched: self.searched + other.searched,
        }
    }
}

impl core::iter::Sum for PassCounts {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::default(), |a, b| a + b)
    }
}

/// One pass over the points with everything it shares between them, read-only.
#[derive(Clone, Copy, Debug)]
pub struct AssignStep<'a> {
    pub(super) centres: &'a [Point3],
    pub(super) state: &'a [CentreState],
    pub(super) tree: TreeView<'a>,
    /// Index and value of the largest drift, and the second largest.
    pub(super) largest_drift: (usize, f32),
    pub(super) second_drift: f32,
    pub(super) mode: Mode,
}

/// `(squared, index)` ordered lexicographically: the plain scan's preference.
#[inline]
fn before(sq: f32, index: u32, than_sq: f32, than_index: u32) -> bool {
    sq < than_sq || (sq == than_sq && index < than_index)
}

/// A decision without search: the winner, the runner-up, the winner's `fl(D^2)`, and `rest`.
struct Kept {
    winner: u32,
    runner_up: u32,
    squared: f32,
    rest: f32,
}

impl AssignStep<'_> {
    /// The decision if it can be proved, else the distances computed (hints for the search).
    fn keep(&self, p: Point3, a: u32, b: u32, rest: f32) -> Result<Kept, [(u32, f32); 2]> {
        let none = [(u32::MAX, f32::INFINITY); 2];
        let (Some(&ca), Some(sa)) = (self.centres.get(a as usize), self.state.get(a as usize))
        else {
            return Err(none);
        };
        let sq_a = squared(p, ca);
        let sq_b = self
            .centres
            .get(b as usize)
            .map_or(f32::INFINITY, |&cb| squared(p, cb));
        let to_a = upper(sq_a);
        let others_drift = if a as usize == self.largest_drift.0 {
            self.second_drift
        } else {
            self.largest_drift.1
        };
        let moved = sub_down(rest, sa.near_drift)
            .min(sub_down(rest, others_drift).max(sub_down(sa.reach, to_a)));
        // Without a runner-up, `rest` covered b's place too, so it still bounds every centre
        // but a; with one, both bounds cover every centre but a and b.
        let rest = moved.max(sub_down(sa.separation, to_a));
        let (winner, runner_up, sq_w) = if before(sq_b, b, sq_a, a) {
            (b, a, sq_b)
        } else {
            (a, b, sq_a)
        };
        let to_winner = if winner == a { to_a } else { upper(sq_w) };
        if surely_nearer(to_winner, rest) {
            Ok(Kept {
                winner,
                runner_up,
                squared: sq_w,
                rest,
            })
        } else {
            Err([(a, sq_a), (b, sq_b)])
        }
    }

    /// Runs the step over a run of points and their slots (`bounds` holds `rest`, `seconds`
    /// the runner-ups).
    pub fn run(
        &self,
        points: &[Point3],
        labels: &mut [u32],
        bounds: &mut [f32],
        seconds: &mut [u32],
    ) -> PassCounts {
        let mut counts = PassCounts::default();
        let slots = labels
            .iter_mut()
            .zip(bounds.iter_mut())
            .zip(seconds.iter_mut());
        for (&p, ((label, bound), second)) in points.iter().zip(slots) {
            if self.mode == Mode::Distances {
                *bound = self
                    .centres
                    .get(*label as usize)
                    .map_or(f32::INFINITY, |&c| squared(p, c));
                continue;
            }
            let (winner, runner_up, sq, rest) = match self.keep(p, *label, *second, *bound) {
                Ok(k) => (k.winner, k.runner_up, k.squared, k.rest),
                Err(known) => {
                    counts.searched += 1;
                    match self.tree.nearest(p, known) {
                        Some(f) => (f.index, f.second, f.squared, f.rest),
                        None => continue,
                    }
                }
            };
            if winner != *label {
                counts.changed += 1;
                *label = winner;
            }
            *second = runner_up;
            *bound = if self.mode == Mode::Final { sq } else { rest };
        }
        counts
    }
}
