//! The streaming mapper: points arrive one at a time, the map lives in fixed memory (K clusters).
//!
//! Each point joins its nearest centre if one lies within the join radius `r`, else it opens a
//! new cluster. When all K slots are taken, the two closest clusters merge (their moments merge
//! exactly) and `r` grows to their distance, unless the smaller is a stray (`merge::STRAY_SHARE`):
//! the radius adapts to what K can cover, as in the doubling algorithm for incremental
//! clustering, so no scale has to be known in advance.
//! Semi-axes are refitted by DE under a per-point budget (one cluster every `refit_interval`
//! points), scheduled by points ingested and never by time: the same points give the same map
//! whatever the chunking or timing. [`StreamMapper::finish`] refits every cluster.
//!
//! With room for frozen entities (`F > 0`, `max_frozen > 0`), making room first tries to freeze
//! instead of merging; see [`freeze`]. A point that comes back to a frozen shell thaws it
//! ([`thaw`]).
//!
//! Two entity models ([`StreamModel`]): the paper's DE fit of eq. 12, kept per cluster and
//! refitted on the schedule above, or oriented shells, which are a function of the moments
//! alone and so are computed when the map is read, with no refits at all; see [`shells`].

use crate::fit::{FitParams, fit_entity_paper};
use crate::geometry::{AxisEntity, Entity, Point3};
use crate::grid::CentreGrid;
use crate::map::MapEntity;
use crate::moments::FixedMoments;
use crate::rng::stream_rng;
use crate::shell::ShellParams;

mod balance;
pub mod carve;
pub mod coarsen;
pub mod freeze;
mod merge;
mod observe;
pub mod pacing;
mod pairs;
pub mod shells;
mod slots;
mod stats;
mod sweep;
pub mod thaw;
pub use carve::Carver;
pub use coarsen::{MOST_MEASURED, MOST_RANKED, RADIUS_SHARE};
pub use freeze::FrozenEntity;
pub use merge::PLANAR_WARD;
pub use observe::Observer;
pub use pacing::{IDLE_SHRINK, PACED_GROWTH, PACED_REACH, Pacing};
pub use pairs::MAX_MERGE_BATCH;
pub use stats::StreamStats;

/// How a cluster becomes its entity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StreamModel {
    /// The paper's axis-aligned semi-axes, fitted by DE on eq. 12 (`params.fit`).
    Paper,
    /// The oriented shell of the cluster's mean and covariance (`crate::shell`).
    Shells(ShellParams),
}

impl StreamModel {
    /// Shells at the default scales, as `mema map` makes them: a shell spans its cluster's
    /// points, which are bounded, so no axis degenerates (an infinite one would only add
    /// surface where there are no points); `sphere_tolerance` names the kind.
    pub const fn shells(sphere_tolerance: f64) -> Self {
        Self::Shells(ShellParams {
            degeneration: crate::geometry::Degeneration {
                threshold: f64::INFINITY,
                sphere_tolerance,
            },
            ..ShellParams::DEFAULT
        })
    }
}

/// Working clusters per map entity where memory allows (a host's stream with every entity in
/// working memory): the stream keeps this many times the map's clusters, a finer summary of the
/// points, and merges them down to the map's at the end by a cost that follows the surfaces
/// ([`StreamParams::final_clusters`]). At k = 400 the streamed maps of the shared inputs then
/// score 0.8-1.2x the batch map's two-way Chamfer (docs/results.md, "Streamed maps").
pub const SUMMARY_FACTOR: usize = 8;

/// Most working clusters a summary keeps ([`summary_layout`]): 2.4 MB of clusters.
pub const MAX_SUMMARY: usize = 8192;

/// Working clusters and the final count for a map of `k` entities of which `frozen` are frozen
/// entities: with none frozen, the finer summary of [`SUMMARY_FACTOR`] clusters per entity (at
/// most [`MAX_SUMMARY`]) merged down to `k` at the end; with frozen entities, a device's
/// layout, `k - frozen` working clusters kept as they are. A mapper whose capacity `K` is
/// smaller works within it ([`StreamMapper`] clamps), so a device sized for its k maps as it
/// always did.
pub const fn summary_layout(k: usize, frozen: usize) -> (usize, usize) {
    let working = k.saturating_sub(frozen);
    if frozen > 0 {
        return (working, 0);
    }
    let summary = SUMMARY_FACTOR.saturating_mul(k);
    let summary = if summary > MAX_SUMMARY {
        MAX_SUMMARY
    } else {
        summary
    };
    (if summary > k { summary } else { k }, k)
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamParams {
    pub fit: FitParams,
    pub seed: u64,
    /// At most this many clusters in working memory (<= K); lets a host pick k at run time
    /// under a fixed K.
    pub max_clusters: usize,
    /// At most this many clusters frozen out of working memory into fitted entities (<= F);
    /// the map then holds up to `max_clusters + max_frozen` entities. 0: none are frozen.
    pub max_frozen: usize,
    /// Refit one cluster every this many points (0: only at `finish`).
    pub refit_interval: u32,
    /// Tolerance mode when > 0: merges must keep the merged cluster's estimated eq. 13 error
    /// (`fit::surface_error_estimate`) at or under this length, and `finish` keeps merging
    /// neighbours while they stay under it, so k follows from the tolerance. 0: fixed capacity.
    pub tolerance: f64,
    pub model: StreamModel,
    /// What freezes and merge passes cost in points of credit ([`pacing`]).
    pub pacing: Pacing,
    /// At the end, merge the working clusters down to this many (0: keep them all): with more
    /// working clusters than the map's entities, the working set is a finer summary of the
    /// points, and the final merges choose the clusters the map keeps ([`SUMMARY_FACTOR`]).
    pub final_clusters: usize,
}

/// One cluster: its moments, running centre and latest fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamCluster {
    pub moments: FixedMoments,
    pub center: Point3,
    /// The latest fit: the paper's axis-aligned entity, kept in its 24 bytes (shells are
    /// computed from the moments instead, and leave the sphere the cluster opened with).
    pub entity: AxisEntity,
    /// Points added since the last fit; `u32::MAX` when never fitted. Shells, never refitted,
    /// keep their final shell's rotation code here at the finish (`entity` the rest of it).
    pub stale: u32,
    /// The stream's point count (mod 2^32) when the cluster last received a point.
    pub last_point: u32,
    /// Scans in a row that saw through the cluster without reaching it ([`carve`]).
    pub seen_through: u8,
}

/// The streaming mapper with capacity `K`, a `G`-bucket spatial hash over the centres, and room
/// for `F` frozen entities.
#[derive(Clone, Debug)]
pub struct StreamMapper<const K: usize, const G: usize, const F: usize = 0> {
    clusters: heapless::Vec<StreamCluster, K>,
    frozen: heapless::Vec<FrozenEntity, F>,
    /// Each frozen slot's marks, moved with its entity.
    marks: slots::SlotMarks<F>,
    coarsening: coarsen::Coarsening,
    /// The frozen slots in the coarsening's sweep order, sorted again at each scan.
    sweep: [u16; F],
    grid: CentreGrid<K, G>,
    radius: f32,
    /// The cluster the last point went to: a scan's next point is likely nearest to it, and
    /// offered first it lets the grid query skip the cells that cannot hold a nearer one.
    /// Only a hint (indices move), so the nearest centre never depends on it.
    recent: usize,
    /// Pacing credit saved, in points.
    credit: u32,
    /// Whether the last freeze tried could not be made (no cluster idle long enough, a fit
    /// that failed, no pair to coarsen within the whole store's reach, or none that merged):
    /// a merge pass then need not wait for the freeze's credit.
    freeze_failed: bool,
    /// While the final reduction runs, merges are ranked by [`merge`]'s planar cost and kept
    /// within a distance.
    reduction: merge::Reduction,
    /// Whether the working clusters hold their final shells ([`StreamMapper::finish`]).
    final_shells: bool,
    /// The finest unit (metres) the points mapped so far were rounded to on their wire; 0 when
    /// no wire said ([`StreamMapper::note_resolution`]).
    resolution: f32,
    params: StreamParams,
    stats: StreamStats,
}

/// A cluster's count as f32, the same value as `count as f32`: through u32 when it fits, which the
/// FPU converts in one instruction where u64 takes a software routine. The compiler sees that
/// both arms agree and folds them back into the routine (a software conversion every point on
/// the firmware): `black_box` hides the u32 from it.
#[inline]
fn count32(m: &FixedMoments) -> f32 {
    match u32::try_from(m.count()) {
        Ok(n) => core::hint::black_box(n) as f32,
        Err(_) => m.count() as f32,
    }
}

/// The centre the clustering uses (nearest-centre search, merges): the f32 mean, computed in f32
/// ([`FixedMoments::mean32`]); the map's entities take theirs from the f64 fit.
fn center_of(m: &FixedMoments) -> Point3 {
    let c = m.mean32().unwrap_or([0.0; 3]);
    Point3::new(c[0], c[1], c[2])
}

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// A `const fn`, so firmware can place the mapper in a `static`.
    // Inlined so a caller can build the mapper in place (the firmware image, in a static).
    #[inline(always)]
    pub const fn new(params: StreamParams) -> Self {
        const { assert!(F < u16::MAX as usize, "frozen indices are u16") };
        Self {
            clusters: heapless::Vec::new(),
            frozen: heapless::Vec::new(),
            marks: slots::SlotMarks::new(),
            coarsening: coarsen::Coarsening::new(),
            sweep: [0; F],
            grid: CentreGrid::new(f32::MIN_POSITIVE),
            radius: 0.0,
            recent: 0,
            credit: 0,
            freeze_failed: false,
            reduction: merge::Reduction::IDLE,
            final_shells: false,
            resolution: 0.0,
            params,
            stats: StreamStats {
                points: 0,
                non_finite: 0,
                merges: 0,
                refits: 0,
                grid_rebuilds: 0,
                forced_merges: 0,
                frozen: 0,
                paced_joins: 0,
                paced_shed: 0,
                coarsened: 0,
                scans: 0,
                carved: 0,
                balanced: 0,
                thawed: 0,
            },
        }
    }

    /// Empties the mapper in place, as [`StreamMapper::new`] with its parameters would make it
    /// (a device has no room for a second mapper): what was mapped is gone, and the points that
    /// follow map exactly as they would into a new mapper.
    pub fn restart(&mut self) {
        self.clusters.clear();
        self.frozen.clear();
        self.marks.clear();
        self.coarsening = coarsen::Coarsening::new();
        self.grid.rebuild(f32::MIN_POSITIVE, core::iter::empty());
        self.radius = 0.0;
        self.recent = 0;
        self.credit = 0;
        self.freeze_failed = false;
        self.reduction = merge::Reduction::IDLE;
        self.final_shells = false;
        self.resolution = 0.0;
        self.stats = StreamStats::default();
    }

    pub fn stats(&self) -> &StreamStats {
        &self.stats
    }

    pub fn clusters(&self) -> &[StreamCluster] {
        &self.clusters
    }

    /// The current join radius.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    fn limit(&self) -> usize {
        self.params.max_clusters.clamp(1, K)
    }

    /// Adds one point; non-finite points are counted and skipped, never stored.
    pub fn add(&mut self, p: Point3) {
        self.add_observed(p, &mut ());
    }

    /// [`StreamMapper::add`], telling `observer` where the point went and what moved.
    pub fn add_observed(&mut self, p: Point3, observer: &mut impl Observer) {
        if self.ingest_observed(p, observer) {
            self.refit_stalest();
        }
    }

    /// [`StreamMapper::add_observed`] without the periodic refit it may end with: returns whether
    /// that refit is due, for a caller that spreads its work over time (the firmware's tick) and
    /// runs it by [`StreamMapper::refit_stalest`] before the next point. The map is the same: a
    /// refit writes one cluster's entity and staleness, which no clustering decision reads.
    pub fn ingest_observed(&mut self, p: Point3, observer: &mut impl Observer) -> bool {
        if !p.is_finite() {
            self.stats.non_finite += 1;
            return false;
        }
        self.stats.points += 1;
        self.final_shells = false;
        self.credit = self.params.pacing.earn(self.credit);
        if self.credit_idle() {
            self.radius *= IDLE_SHRINK;
        }
        let full = self.clusters.len() >= self.limit();
        let join = match self.nearest_within_radius(p) {
            Some(i) => Some(i),
            None if full && !self.make_room(observer) => match self.paced_join(p, observer) {
                Some(i) => Some(i),
                None => return false,
            },
            None => self.thaw_near(p, observer),
        };
        match join {
            Some(i) => {
                observer.joined(i);
                self.grow(i, p);
                self.recent = i;
            }
            None => {
                self.open(p, observer);
                self.recent = self.clusters.len().saturating_sub(1);
            }
        }
        // In u32 while the count fits: a u64 remainder is a software routine on a device.
        let interval = self.params.refit_interval;
        match u32::try_from(self.stats.points) {
            Ok(points) => interval > 0 && points.is_multiple_of(interval),
            Err(_) => interval > 0 && self.stats.points.is_multiple_of(interval.into()),
        }
    }

    pub fn add_all(&mut self, points: &[Point3]) {
        for &p in points {
            self.add(p);
        }
    }

    /// Grows the join radius to `r` if that is wider, with the grid's cells (a cell is two
    /// radii, so the nearest centre within the radius is found within half a cell).
    pub(super) fn widen_radius(&mut self, r: f32) {
        if !(r > self.radius) {
            return;
        }
        self.radius = r;
        if let Some(cell) = self.outgrown_cell() {
            self.grid
                .rebuild(cell, self.clusters.iter().map(|c| c.center));
        }
    }

    /// The cell two join radii need, counted as a grid rebuild, once the radius has outgrown
    /// the grid's cells; `None` while they still hold it.
    fn outgrown_cell(&mut self) -> Option<f32> {
        (self.radius * 2.0 > self.grid.cell()).then(|| {
            self.stats.grid_rebuilds += 1;
            (self.radius * 2.0).max(f32::MIN_POSITIVE)
        })
    }

    fn nearest_within_radius(&self, p: Point3) -> Option<usize> {
        self.nearest_within(p, self.radius * self.radius)
    }

    /// The nearest centre within `sqrt(r2)` (ties: the lowest index): within the join radius,
    /// or within [`PACED_REACH`] radii for a point the pacing could not make room for, which is
    /// past the grid's half cell.
    #[inline(never)]
    pub(super) fn nearest_within(&self, p: Point3, r2: f32) -> Option<usize> {
        // The best so far, (index, squared distance); starting from (none, r2) makes "within
        // r, and nearer, or as near at a lower index" one comparison.
        let mut best = (usize::MAX, r2);
        // Offers centre `i`; returns the squared distance a centre must not exceed to matter.
        let mut offer = |i: usize, c: &StreamCluster| {
            let d = p.distance_squared(c.center);
            if d < best.1 || (d == best.1 && i < best.0) {
                best = (i, d);
            }
            best.1
        };
        let half_cell = 0.5 * self.grid.cell();
        if r2 == 0.0 || r2 > half_cell * half_cell {
            // Until the first merge the radius is 0 and the cells so small that every centre
            // is filed in one saturated cell: the grid would walk that whole chain 8 times, so
            // one pass over the centres is cheaper, and finds the same (coincident) centres.
            // Past half a cell, the cells do not bound the search: the same pass.
            for (i, c) in self.clusters.iter().enumerate() {
                offer(i, c);
            }
        } else {
            let limit = match self.clusters.get(self.recent) {
                Some(c) => offer(self.recent, c),
                None => r2,
            };
            self.grid
                .for_each_within_half_cell(p, limit, |i| match self.clusters.get(i) {
                    Some(c) => offer(i, c),
                    None => r2,
                });
        }
        (best.0 != usize::MAX).then_some(best.0)
    }

    fn grow(&mut self, i: usize, p: Point3) {
        if let Some(c) = self.clusters.get_mut(i) {
            c.moments.add(p);
            c.center = center_of(&c.moments);
            c.stale = c.stale.saturating_add(1);
            c.last_point = self.stats.points as u32;
            let center = c.center;
            self.grid.update(i, center);
        }
    }

    /// Takes working cluster `i` out by swap-remove, telling `observer`: the last cluster takes
    /// slot `i`, unfiled and refiled under its new index (a rebuild of every working centre at
    /// each freeze would cost the firmware far more; the merge candidates are ordered by
    /// distance and index, not by the grid's chains).
    fn remove_working(&mut self, i: usize, observer: &mut impl Observer) {
        observer.removed(i);
        let last = self.clusters.len().saturating_sub(1);
        self.grid.remove(i);
        self.grid.remove(last);
        crate::num::swap_remove(&mut self.clusters, i);
        if let Some(moved) = self.clusters.get(i) {
            self.grid.insert(i, moved.center);
        }
    }

    /// A new cluster of `p` at the end (dropped, as the point is, if no room was made).
    fn open(&mut self, p: Point3, observer: &mut impl Observer) {
        // Shells read the mean and covariance only; the tolerance mode's merges read eq. 12.
        let mut moments = if self.is_shells() && self.params.tolerance <= 0.0 {
            FixedMoments::second_order()
        } else {
            FixedMoments::new()
        };
        moments.add(p);
        let cluster = StreamCluster {
            moments,
            center: p,
            entity: AxisEntity::of_axis_aligned(&Entity::sphere(p, 0.0)),
            stale: u32::MAX,
            last_point: self.stats.points as u32,
            seen_through: 0,
        };
        let index = self.clusters.len();
        if self.clusters.push(cluster).is_ok() {
            observer.opened(index);
            self.grid.insert(index, p);
        }
    }

    fn fit(&self, index: usize, cluster: &StreamCluster) -> Option<Entity> {
        let central = cluster.moments.central()?;
        let stream = (index as u64) << 32 | (self.stats.points & 0xFFFF_FFFF);
        Some(fit_entity_paper(
            &central,
            &self.params.fit,
            &mut stream_rng(self.params.seed, stream),
        ))
    }

    /// Refits the cluster with the most points added since its last fit (ties: lowest index).
    /// Shells need no refit: they are read off the moments whenever the map is.
    pub fn refit_stalest(&mut self) {
        if self.is_shells() {
            return;
        }
        let mut pick: Option<(usize, u32)> = None;
        for (i, c) in self.clusters.iter().enumerate() {
            if c.stale > 0 && pick.is_none_or(|(_, s)| c.stale > s) {
                pick = Some((i, c.stale));
            }
        }
        let Some((i, _)) = pick else {
            return;
        };
        let entity = self.clusters.get(i).and_then(|c| self.fit(i, c));
        if let (Some(entity), Some(c)) = (entity, self.clusters.get_mut(i)) {
            c.entity = AxisEntity::of_axis_aligned(&entity);
            c.stale = 0;
            self.stats.refits += 1;
        }
    }

    /// Refits every cluster changed since its last fit, so the entities describe all points so far.
    pub fn refit_stale(&mut self) {
        if self.is_shells() {
            return;
        }
        for i in 0..self.clusters.len() {
            if self.clusters.get(i).is_some_and(|c| c.stale > 0) {
                let entity = self.clusters.get(i).and_then(|c| self.fit(i, c));
                if let (Some(entity), Some(c)) = (entity, self.clusters.get_mut(i)) {
                    c.entity = AxisEntity::of_axis_aligned(&entity);
                    c.stale = 0;
                    self.stats.refits += 1;
                }
            }
        }
    }

    /// The entities as they stand, frozen ones first (for the paper's model, call
    /// [`StreamMapper::refit_stale`] first for a snapshot; shells are always current).
    pub fn entities(&self) -> impl Iterator<Item = MapEntity> + Clone + '_ {
        let tolerance = self.sphere_tolerance();
        let working = self.clusters.iter().map(|c| self.working_entity(c));
        self.frozen
            .iter()
            .map(FrozenEntity::to_entity)
            .chain(working)
            .map(move |entity| MapEntity {
                entity,
                kind: entity.kind(tolerance),
            })
    }

    /// Frozen entity `index` as [`StreamMapper::entities`] gives it (the map's entity
    /// `index`), without decoding the ones before it.
    pub fn frozen_entity(&self, index: usize) -> Option<MapEntity> {
        let entity = self.frozen.get(index)?.to_entity();
        Some(MapEntity {
            entity,
            kind: entity.kind(self.sphere_tolerance()),
        })
    }

    /// Entities frozen out of working memory so far.
    pub fn frozen(&self) -> &[FrozenEntity] {
        &self.frozen
    }

    /// Removes frozen entity `index` by swap-remove (the last takes its slot), a carving's
    /// removal: counted in [`StreamStats::carved`]. False if there is none.
    pub(crate) fn remove_frozen(&mut self, index: usize) -> bool {
        let removed = self.take_frozen(index);
        self.stats.carved += u64::from(removed);
        removed
    }

    /// Takes frozen entity `index` out of the store by swap-remove, marking both slots changed.
    fn take_frozen(&mut self, index: usize) -> bool {
        let last = self.frozen.len().saturating_sub(1);
        let removed = crate::num::swap_remove(&mut self.frozen, index);
        if removed {
            self.marks.swap_removed(index, last);
            // The coarsening's listed pairs with either slot now name other entities.
            self.marks.touch(index);
            self.marks.touch(last);
        }
        removed
    }

    /// Scans in a row that saw through frozen entity `index` ([`carve`]).
    pub(crate) fn seen_through_count(&self, index: usize) -> u8 {
        self.marks.count(index)
    }

    pub(crate) fn set_seen_through_count(&mut self, index: usize, count: u8) {
        self.marks.set_count(index, count);
    }

    /// The lowest frozen slot below `below` that holds another entity than a downlink last sent
    /// from it (a carving or a coarsening changed it), its mark taken: a downlink that had sent
    /// the slot sends what it holds now.
    pub fn take_changed(&mut self, below: usize) -> Option<usize> {
        self.marks.take_changed(below)
    }

    /// Ends the stream: every cluster refitted from its final moments, with seeds that depend on
    /// the cluster's index only, so the final map is a function of the points alone.
    pub fn finish(&mut self) {
        self.finish_observed(&mut ());
    }

    /// [`StreamMapper::finish`], telling `observer` of the tolerance mode's last merges.
    pub fn finish_observed(&mut self, observer: &mut impl Observer) {
        self.consolidate(observer);
        if self.params.final_clusters > 0 {
            self.reduce_to(self.params.final_clusters, observer);
        }
        if self.is_shells() {
            self.keep_final_shells();
            self.balance_working(observer);
            return;
        }
        for i in 0..self.clusters.len() {
            let central = self.clusters.get(i).and_then(|c| c.moments.central());
            if let Some(central) = central {
                let entity = fit_entity_paper(
                    &central,
                    &self.params.fit,
                    &mut stream_rng(self.params.seed, i as u64),
                );
                if let Some(c) = self.clusters.get_mut(i) {
                    c.entity = AxisEntity::of_axis_aligned(&entity);
                    c.stale = 0;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
