//! Pacing: the stream's costly steps paid for in points, so a device that keeps up with the
//! points keeps up with the whole stream.
//!
//! Making room for a point far from every centre costs a freeze (one DE fit) or a merge pass,
//! each the price of tens of points that join a cluster (docs/results.md's pacing table has
//! the firmware's measured prices). Entering new ground, a scanner can ask for room at
//! every point: a DE fit per point outruns a 921,600-baud link whatever the processor's
//! average, and the receive ring overflows (issue 13). So each ingested point earns one credit,
//! a freeze or merge pass spends its price in credits, and saved credit is capped: over any
//! stretch of `n` points the stream runs at most `(n + burst) / price` of them. When the credit
//! is short, the point joins its nearest centre however far it is (a coarser cluster there, as
//! if the join radius had grown), so no point is dropped and the cost of a point is bounded.
//!
//! Credit is counted in points, never in time: the same points give the same map on every
//! target, at any speed, and the host's replay of a capture is the device's map.

use super::{Observer, StreamMapper};
use crate::geometry::Point3;

/// In a layout that freezes, the join radius grows by this factor at every point the pacing
/// could not make room for: the radius then settles where the room the points ask for is the
/// room the credit pays for. Freezes make room without the merges that grow the radius, so
/// without this it kept its first, finest value; a layout that only merges grows it by its
/// merges (and a drive's map mapped that way, `mema demo --moving`, lost range accuracy to it:
/// its 95th percentile range error tripled).
pub const PACED_GROWTH: f32 = 1.005;

/// A point the pacing's credit cannot pay room for joins its nearest centre within this many
/// join radii, and is shed beyond: a single point far from its cluster's surface tilts the
/// cluster's plane and thickens its shell, a phantom surface across the gap (docs/design.md, "A
/// device's layout", has what each choice scored). A shed point is counted
/// ([`super::StreamStats::paced_shed`]) and a carver still takes its ray.
pub const PACED_REACH: f32 = 3.0;

/// In a layout that freezes, the join radius shrinks by this factor at every point that finds
/// the pacing's credit at its cap, unspent: room is affordable there, so the map may be finer.
/// With [`PACED_GROWTH`] the radius follows what the credit pays for both ways; growing only,
/// it kept the widest it had needed (bun000 at the board's layout: 1.54 times the batch map's
/// Chamfer distance, 1.31 with the shrink; five_people 1.52 and 1.30). Twice this shrink left
/// finer frozen pieces of a walker than two scans' carving finds (`tests/walker.rs`).
pub const IDLE_SHRINK: f32 = 0.99995;

/// Prices in points of credit, and the most credit that can be saved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pacing {
    /// Credits a freeze spends.
    pub freeze: u32,
    /// Credits a merge pass spends.
    pub merge_pass: u32,
    /// Credits a scan of the frozen store for pairs to coarsen spends, on top of its freeze
    /// into a full store (two fits' worth: the freeze, and the merge of a frozen pair it makes
    /// room by, [`super::coarsen`]).
    pub scan: u32,
    /// The cap on saved credit: the largest burst of costly steps back to back. At least the
    /// dearer price, or that step never runs (every point short of room then joins).
    pub burst: u32,
}

impl Pacing {
    /// No pacing: every freeze and merge pass runs when room is needed.
    pub const NONE: Self = Self {
        freeze: 0,
        merge_pass: 0,
        scan: 0,
        burst: 0,
    };

    /// The firmware's (and the host's stream, so a replay is the device's map): prices in
    /// proportion to what each step costs the Cortex-M4F (the prices of the pacing test,
    /// `tests/tests/pacing.rs`, on its six captures), so a point costs on average its own work
    /// and at most a credit's worth of a fit, merge pass or scan, about 6,000 to 7,000
    /// instructions (docs/firmware.md, "Longest tick, the link and pacing"). A scan with its two
    /// fits (1.1 million instructions on the image, the demo drive's and bun000's mean) is the
    /// dearest step, and the burst pays for one.
    pub const DEVICE: Self = Self {
        freeze: 24,
        merge_pass: 80,
        scan: 112,
        burst: 160,
    };

    /// [`Self::DEVICE`] for shells: a shell's freeze is its cluster's moments, no DE fit, and
    /// costs the image half what the paper's fit does (51,000 and 83,000 instructions on the
    /// demo drive and bun000 against 107,000 to 149,000), so it is priced at half. A scan with
    /// its two fits is 148 credits, some 7,500 instructions each (1.1 million on the image): at
    /// 160 the walking drive's board map kept twice the walker it keeps at 148, across its
    /// test's bound (`tests/walker.rs`; at 136 and at 148 it stayed under: the measure is
    /// chaotic). A merge pass, its pair search a sort and sweep (`core/src/stream/sweep.rs`) and
    /// its shells' merges in integers, costs the image 226,000 to 313,000 instructions on
    /// bun000, car6 and the demo drive, and is priced at 40 credits, 5,700 to 7,800
    /// instructions each, the dearest credit of any step: where no cluster idles long enough to
    /// freeze (a sparse cloud's), room comes from passes alone. At 44 (about the scan's credit)
    /// and 48 the board kept more of the walker, 6 and 15 % (`tests/walker.rs`'s bound is 10),
    /// and its maps were farther from the batch maps. With the coarsening's
    /// [`super::coarsen::THICKENING`] bound the board's maps scored a geometric mean of 1.01
    /// times the batch map's Chamfer distance over every shared input, 1.18 at the paper's
    /// prices (docs/design.md, "A device's layout").
    pub const DEVICE_SHELLS: Self = Self {
        freeze: 12,
        merge_pass: 40,
        scan: 124,
        ..Self::DEVICE
    };

    /// The device's prices for `model`'s fits.
    pub const fn device(model: &super::StreamModel) -> Self {
        match model {
            super::StreamModel::Paper => Self::DEVICE,
            super::StreamModel::Shells(_) => Self::DEVICE_SHELLS,
        }
    }

    /// Whether the radius may follow the credit ([`PACED_GROWTH`],
    /// [`IDLE_SHRINK`]): a paced layout that freezes, whose freezes make room without
    /// the merges that set the radius.
    pub(super) fn follows_credit(&self, frozen: usize) -> bool {
        self.burst > 0 && frozen > 0
    }

    /// The credit after one more point.
    pub(super) fn earn(&self, credit: u32) -> u32 {
        credit.saturating_add(1).min(self.burst)
    }
}

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// Where a point goes that wants room the credit cannot pay for: its nearest centre within
    /// [`PACED_REACH`] join radii, else nowhere (shed, counted). Either way, in a layout whose
    /// radius follows the credit, the radius widens.
    pub(super) fn paced_join(&mut self, p: Point3, observer: &mut impl Observer) -> Option<usize> {
        if self
            .params
            .pacing
            .follows_credit(self.params.max_frozen.min(F))
        {
            self.widen_radius(self.radius * PACED_GROWTH);
        }
        let reach = PACED_REACH * self.radius;
        let near = self.nearest_within(p, reach * reach);
        if near.is_some() {
            self.stats.paced_joins += 1;
        } else {
            self.stats.paced_shed += 1;
            observer.shed();
        }
        near
    }

    /// Whether this point found the credit at its cap, unspent, in a layout whose radius follows
    /// the credit.
    pub(super) fn credit_idle(&self) -> bool {
        let pacing = self.params.pacing;
        pacing.follows_credit(self.params.max_frozen.min(F)) && self.credit >= pacing.burst
    }

    /// Frees a working slot by a freeze, else a merge pass, as far as the pacing's credit
    /// pays; false if it could not. Out of line: at most once a point, and the image's flash
    /// is short.
    #[inline(never)]
    pub(super) fn make_room(&mut self, observer: &mut impl Observer) -> bool {
        let pacing = self.params.pacing;
        // A freeze into a full store of shells first merges two frozen shells, a shell's fit
        // like the freeze's own, and scans for candidates when the last scan's are spent: a
        // sort of the store and up to [`super::MOST_MEASURED`] distances, at its own price.
        let scan = pacing.scan;
        let freeze = match (
            self.store_full() && self.coarsens(),
            self.coarsening.spent(),
        ) {
            (false, _) => pacing.freeze,
            (true, false) => pacing.freeze.saturating_mul(2),
            (true, true) => pacing.freeze.saturating_mul(2).saturating_add(scan),
        };
        if self.credit >= freeze {
            let scans = self.stats.scans;
            if self.freeze_one(observer) {
                self.credit -= freeze;
                return true;
            }
            if self.stats.scans != scans {
                self.credit -= scan.min(self.credit);
            }
        }
        // A merge pass widens the join radius to its widest merge for good, so it does not
        // stand in for a freeze the credit is short of: where a full store's freeze with a scan
        // is dearer than a pass, a point that finds the credit between the two joins near
        // (paced) while the freeze waits. At the device's prices (24 a freeze, 96 into a full
        // store with a scan) bun000's board map ran two passes in that gap as its store filled,
        // and the radius went from 2.6 to 4.1 mm for the rest of the scan (1.27 times the batch
        // map's Chamfer distance at K = 700; 1.19 waiting). Only that gap waits: a freeze tried
        // whose list turned out spent on changed slots still gives way to a pass (waiting there
        // too took office1 from 1.18 to 1.35: its store churned). A freeze that could not be
        // made says so (`freeze_failed`), and one the burst can never pay for is not waited for.
        let waits =
            self.freezes() && !self.freeze_failed && self.credit < freeze && freeze <= pacing.burst;
        if !waits && self.credit >= pacing.merge_pass {
            self.credit -= pacing.merge_pass;
            self.freeze_failed = false;
            self.merge_closest_pairs(observer);
            return true;
        }
        false
    }
}
