//! Carving a stream (issue 29): a working cluster that later scans saw through, none of their
//! points joining it, leaves the map, as the batch map leaves out the points other scans saw
//! through. A person who walked on, or a ghost of a bad frame, does not stay as surface.
//!
//! A stream's points arrive scan by scan, each scan from one sensor origin. While a scan
//! arrives, its returns fill a range image ([`crate::free_space`]: each pixel keeps its nearest
//! return) in fixed memory; when the next scan begins (or the stream ends), the image judges
//! every working cluster the scan did not reach. The judgement is the cluster's, not a point's:
//! the mapper keeps moments, not points. A cluster is seen through when its centre, moved to the
//! cluster's far side along the ray (twice its spread along the ray), lies nearer than its
//! pixel's nearest return by [`CARVE_MARGIN`], and the ends of its two longest axes, moved the
//! same way, lie either so or where the scan had no return (the sky); each pixel is read with
//! its eight neighbours, the nearest return among them: a cluster on a surface
//! the scan saw has its own surface there (a pixel's nearest return is at or before it), and
//! one spanning a corner reaches past the corner.
//!
//! Frozen entities (a device's layout) are not carved: they may already be on the downlink.

use super::{Observer, StreamCluster, StreamMapper};
use crate::free_space::{Geometry, NO_RETURN, RangeImage, range_of};
use crate::geometry::Point3;

/// Scans that must see through a cluster, with none of their points joining it, for it to go:
/// one glance through a cluster may be a sensor's glitch; two are the space being empty.
pub const SEEN_THROUGH: u8 = 2;

/// How much nearer than its pixel's nearest return a cluster must lie to be seen through
/// (metres): a lidar's range noise and more.
pub const CARVE_MARGIN: f32 = 0.2;

/// Axis ends tested are this many standard deviations from the centre: inside the patch of a
/// uniform surface (whose edge is 1.73 deviations out), so a cluster at a surface's edge is
/// judged by where its points are.
const AXIS_REACH: f64 = 1.5;

/// The far side of a cluster along the ray is this many deviations past its centre.
const FAR_SIDE: f64 = 2.0;

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// Ends a scan whose points were the stream's points after `scan_start` (the
    /// [`super::StreamStats::points`] count when it began): every working cluster no point of
    /// the scan joined and that `seen_through` says the scan saw through gains a count, and one
    /// with [`SEEN_THROUGH`] counts leaves the working set; a cluster the scan's points joined
    /// starts its count again. Returns how many clusters left.
    pub fn carve(
        &mut self,
        scan_start: u64,
        seen_through: impl Fn(&StreamCluster) -> bool,
        observer: &mut impl Observer,
    ) -> usize {
        let all = self.clusters.len();
        self.carve_some(scan_start, all, usize::MAX, seen_through, observer)
            .1
    }

    /// [`StreamMapper::carve`] in steps, for a device that bounds each tick's work: judges at
    /// most `most` of the working clusters below index `below` (the first step's `below` is
    /// the working set's length), from the highest down, and returns the `below` of the next
    /// step (0: all judged) and how many clusters left. Steps with nothing mapped between
    /// them carve what one call would.
    pub fn carve_some(
        &mut self,
        scan_start: u64,
        below: usize,
        most: usize,
        seen_through: impl Fn(&StreamCluster) -> bool,
        observer: &mut impl Observer,
    ) -> (usize, usize) {
        let scan_points = self.stats.points.saturating_sub(scan_start);
        let scan_points = u32::try_from(scan_points).unwrap_or(u32::MAX);
        let below = below.min(self.clusters.len());
        let last = below.saturating_sub(most);
        let mut carved = 0;
        // From the highest down, so the cluster a swap-remove moves in has been judged already.
        for i in (last..below).rev() {
            let Some(c) = self.clusters.get(i) else {
                continue;
            };
            let count = if self.idle(c) < scan_points {
                0
            } else if seen_through(c) {
                c.seen_through.saturating_add(1)
            } else {
                c.seen_through
            };
            if count < SEEN_THROUGH {
                if let Some(c) = self.clusters.get_mut(i) {
                    c.seen_through = count;
                }
                continue;
            }
            self.remove_working(i, observer);
            carved += 1;
        }
        self.stats.carved += carved as u64;
        (last, carved)
    }
}

/// A stream's scans, one at a time, as range images in fixed memory (`N` pixels at most), and
/// the carving each one does when it ends: of the working clusters, and of the frozen
/// entities ([`frozen`]).
#[derive(Clone, Debug)]
pub struct Carver<const N: usize> {
    image: RangeImage<N>,
    /// The range each code stands for in the image ([`range_of`] at its `near`): a return's
    /// code is found among them by bisection, and a pixel's range read from them, where
    /// [`crate::free_space::code`]'s logarithm and its check's power cost a device more than
    /// the rest of the pixel.
    ranges: [f32; CODES],
    /// The mapper's point count when the scan began; `None` before the first scan.
    scan_start: Option<u64>,
    /// An ended scan's judgement under way ([`Carver::step`]).
    judging: Option<Judging>,
    /// Returns a scan's image takes: each one (1), or every so many ([`Carver::sample`]).
    every: u16,
    /// Returns of the scan since the last one the image took.
    passed: u16,
}

/// Where an ended scan's judgement stands: the working clusters, then the frozen entities,
/// below these indices are still to be judged, from the highest down.
#[derive(Clone, Copy, Debug)]
struct Judging {
    working_below: usize,
    frozen_below: usize,
}

impl Judging {
    const ALL: Self = Self {
        working_below: usize::MAX,
        frozen_below: usize::MAX,
    };
}

impl<const N: usize> Carver<N> {
    /// A carver whose images look as `geometry` says from each scan's sensor origin (its
    /// `origin` is replaced); `None` if the image has more than `N` pixels.
    pub fn new(geometry: Geometry) -> Option<Self> {
        let mut carver = Self::empty();
        if !carver.image.reset(geometry) {
            return None;
        }
        carver.ranges = ranges_from(geometry.near);
        Some(carver)
    }

    /// Images of `rows` x `columns` pixels around the whole sphere, ranges from 1/8 m to 128 m
    /// (nearer returns leave nothing free, farther ones are free to 128 m): what a carver needs
    /// who does not know the sensor.
    pub fn whole_sphere(rows: u16, columns: u16) -> Option<Self> {
        Self::new(whole_sphere(rows, columns))
    }

    /// A carver whose images have no pixels, to be given them by [`Carver::look`]: a
    /// `const fn`, so a device builds its carver in place in a static.
    #[inline(always)]
    pub const fn empty() -> Self {
        Self {
            image: RangeImage::empty(),
            ranges: [0.0; CODES],
            scan_start: None,
            judging: None,
            every: 1,
            passed: 0,
        }
    }

    /// Gives the carver whole-sphere images of `rows` x `columns` pixels ([`Carver::whole_sphere`])
    /// and forgets any scan under way; false, and nothing changed, if they have more than `N`
    /// pixels.
    pub fn look(&mut self, rows: u16, columns: u16) -> bool {
        let geometry = whole_sphere(rows, columns);
        if !self.image.reset(geometry) {
            return false;
        }
        self.ranges = ranges_from(geometry.near);
        self.restart();
        true
    }

    /// The points that follow were seen from `sensor` (the map's frame): if the scan so far was
    /// seen from elsewhere, it ends (it carves `mapper`) and a new scan begins. Returns how many
    /// clusters the ended scan carved.
    pub fn sensor_at<const K: usize, const G: usize, const F: usize>(
        &mut self,
        sensor: Point3,
        mapper: &mut StreamMapper<K, G, F>,
        observer: &mut impl Observer,
    ) -> usize {
        if !self.begins_scan(sensor) {
            return 0;
        }
        let carved = self.end_scan(mapper, observer);
        self.begin_scan(sensor, mapper);
        carved
    }

    /// [`Carver::sensor_at`] in steps that judge at most `most` clusters each, for a device
    /// that bounds each tick's work: true once the points seen from `sensor` may be added (the
    /// scan before, if any, judged in full and the new one begun); false while the ended scan's
    /// judgement goes on (step again with the same `sensor`, nothing mapped in between). The
    /// steps carve what one [`Carver::sensor_at`] does.
    pub fn step<const K: usize, const G: usize, const F: usize>(
        &mut self,
        sensor: Point3,
        most: usize,
        mapper: &mut StreamMapper<K, G, F>,
        observer: &mut impl Observer,
    ) -> bool {
        if self.judging.is_none() && !self.begins_scan(sensor) {
            return true;
        }
        if let Some(start) = self.scan_start {
            let judging = self.judging.unwrap_or(Judging::ALL);
            self.judging = self.judge(start, judging, most, mapper, observer);
            if self.judging.is_some() {
                return false;
            }
        }
        self.begin_scan(sensor, mapper);
        true
    }

    /// Judges at most `most` clusters and entities of the scan that began at `start` from
    /// where `judging` stands: where it stands after, or `None` once all are judged.
    fn judge<const K: usize, const G: usize, const F: usize>(
        &mut self,
        start: u64,
        mut judging: Judging,
        most: usize,
        mapper: &mut StreamMapper<K, G, F>,
        observer: &mut impl Observer,
    ) -> Option<Judging> {
        let mut left = most;
        if judging.working_below > 0 {
            let below = judging.working_below.min(mapper.clusters().len());
            let (next, _) =
                mapper.carve_some(start, below, left, |c| self.sees_through(c), observer);
            left -= (below - next).min(left);
            judging.working_below = next;
            if next > 0 {
                return Some(judging);
            }
        }
        let below = judging.frozen_below.min(mapper.frozen().len());
        let last = below.saturating_sub(left);
        for i in (last..below).rev() {
            self.judge_frozen(i, mapper);
        }
        judging.frozen_below = last;
        (last > 0).then_some(judging)
    }

    /// Notes only every `every`-th return of a scan in its image (the first, then each
    /// `every`-th after it; 0 counts as 1): a device short of time carves from a measured
    /// subset of its rays.
    pub fn sample(&mut self, every: u16) {
        self.every = every.max(1);
        self.passed = 0;
    }

    /// Whether points seen from `sensor` begin a new scan: none is under way, or it was seen
    /// from elsewhere.
    pub fn begins_scan(&self, sensor: Point3) -> bool {
        self.scan_start.is_none() || self.image.geometry().origin != sensor
    }

    /// Begins a scan seen from `sensor` (the current one, if any, ends without carving: call
    /// [`Carver::end_scan`] first).
    pub fn begin_scan<const K: usize, const G: usize, const F: usize>(
        &mut self,
        sensor: Point3,
        mapper: &StreamMapper<K, G, F>,
    ) {
        let geometry = Geometry {
            origin: sensor,
            ..*self.image.geometry()
        };
        self.image.reset(geometry);
        self.scan_start = Some(mapper.stats().points);
        self.passed = 0;
    }

    /// Whether a scan is under way.
    pub fn scanning(&self) -> bool {
        self.scan_start.is_some()
    }

    /// The current scan's image (or the last scan's, once it ended).
    pub fn image(&self) -> &RangeImage<N> {
        &self.image
    }

    /// Notes a return of the current scan.
    pub fn add_return(&mut self, p: Point3) {
        if self.scan_start.is_none() {
            return;
        }
        let taken = self.passed == 0;
        self.passed = if self.passed + 1 >= self.every {
            0
        } else {
            self.passed + 1
        };
        if taken && let Some((index, r)) = direction::pixel(self.image.geometry(), p) {
            // Most returns are not their pixel's nearest: only a nearer one is coded.
            let held = self.image.cells().get(index).copied().unwrap_or(0);
            if r < self
                .ranges
                .get(usize::from(held))
                .copied()
                .unwrap_or(f32::INFINITY)
            {
                let code = self.code_of(r);
                self.image.lower(index, code);
            }
        }
    }

    /// The largest code whose range is at most `r` (0 for none, or NaN): what
    /// [`crate::free_space::code`] means, found among the image's ranges.
    fn code_of(&self, r: f32) -> u8 {
        // `ranges[low] <= r` holds throughout (ranges[0] is 0), `ranges[high]` is past r.
        let (mut low, mut high) = (0, CODES);
        while high - low > 1 {
            let middle = (low + high) / 2;
            if self.ranges.get(middle).is_some_and(|&m| m <= r) {
                low = middle;
            } else {
                high = middle;
            }
        }
        low as u8
    }

    /// Ends the current scan (the stream ended, or the next points have no sensor origin): it
    /// carves `mapper`. Returns how many clusters it carved.
    pub fn end_scan<const K: usize, const G: usize, const F: usize>(
        &mut self,
        mapper: &mut StreamMapper<K, G, F>,
        observer: &mut impl Observer,
    ) -> usize {
        let judging = self.judging.take().unwrap_or(Judging::ALL);
        let Some(start) = self.scan_start.take() else {
            return 0;
        };
        let before = mapper.stats().carved;
        self.judge(start, judging, usize::MAX, mapper, observer);
        (mapper.stats().carved - before) as usize
    }

    /// Forgets the current scan without carving (the map started again).
    pub fn restart(&mut self) {
        self.scan_start = None;
        self.judging = None;
    }

    /// Whether the current scan saw through `cluster` (see the module's documentation).
    pub fn sees_through(&self, cluster: &StreamCluster) -> bool {
        let Some((mean, covariance)) = cluster.moments.covariance() else {
            return false;
        };
        let o = self.image.geometry().origin;
        let d = [
            mean[0] - f64::from(o.x),
            mean[1] - f64::from(o.y),
            mean[2] - f64::from(o.z),
        ];
        let r = libm::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if !(r > 0.0 && r.is_finite()) {
            return false;
        }
        let u = d.map(|v| v / r);
        let mut along = 0.0;
        for (i, row) in covariance.iter().enumerate() {
            for (j, c) in row.iter().enumerate() {
                along += u.get(i).copied().unwrap_or(0.0) * c * u.get(j).copied().unwrap_or(0.0);
            }
        }
        let push = FAR_SIDE * libm::sqrt(along.max(0.0));
        let far = |offset: [f64; 3]| {
            let p = [0, 1, 2].map(|j| {
                mean.get(j).copied().unwrap_or(0.0)
                    + offset.get(j).copied().unwrap_or(0.0)
                    + push * u.get(j).copied().unwrap_or(0.0)
            });
            Point3::new(p[0] as f32, p[1] as f32, p[2] as f32)
        };
        // The centre first: most clusters a scan did not reach, it did not see through either,
        // and their axes (an eigendecomposition, costly on a device) are not needed.
        if self.sight(far([0.0; 3])) != Sight::Through {
            return false;
        }
        let (values, vectors) = crate::shell::symmetric_eigen_single(covariance);
        let axis = |k: usize, sign: f64| {
            let reach =
                sign * AXIS_REACH * libm::sqrt(values.get(k).copied().unwrap_or(0.0).max(0.0));
            [0, 1, 2].map(|j| {
                reach
                    * vectors
                        .get(j)
                        .and_then(|row| row.get(k))
                        .copied()
                        .unwrap_or(0.0)
            })
        };
        let ends = [axis(0, 1.0), axis(0, -1.0), axis(1, 1.0), axis(1, -1.0)];
        ends.iter().all(|&end| self.sight(far(end)) != Sight::Short)
    }

    /// What the current scan saw of `p`: through it, short of it, or nothing near its pixel.
    /// A pixel is judged by the nearest return in it and the eight around it: finer pixels
    /// than the sensor's spacing leave gaps between its rays (the sampling, not open space),
    /// and the nearest of the neighbourhood never claims more free space than a return allows.
    fn sight(&self, p: Point3) -> Sight {
        let Some((index, r)) = direction::pixel(self.image.geometry(), p) else {
            return Sight::Nothing;
        };
        let Some(c) = self.nearest_around(index) else {
            return Sight::Nothing;
        };
        let range = self.ranges.get(usize::from(c)).copied().unwrap_or(0.0);
        if r < range - CARVE_MARGIN {
            Sight::Through
        } else {
            Sight::Short
        }
    }

    /// The least code of pixel `index` and its eight neighbours (across the ends of a whole
    /// turn, the first and last columns are neighbours); `None` if none has a return.
    fn nearest_around(&self, index: usize) -> Option<u8> {
        let cells = self.image.cells();
        let geometry = self.image.geometry();
        let (rows, columns) = (usize::from(geometry.rows), usize::from(geometry.columns));
        let (row, column) = (index / columns.max(1), index % columns.max(1));
        let whole_turn = geometry.azimuth[1] >= core::f32::consts::TAU;
        let mut nearest = NO_RETURN;
        for r in row.saturating_sub(1)..(row + 2).min(rows) {
            for step in [columns.wrapping_sub(1), 0, 1] {
                let c = column.wrapping_add(step);
                let c = if c < columns {
                    c
                } else if whole_turn {
                    c.wrapping_add(columns) % columns.max(1)
                } else {
                    continue;
                };
                if let Some(&code) = cells.get(r * columns + c) {
                    nearest = nearest.min(code);
                }
            }
        }
        (nearest != NO_RETURN).then_some(nearest)
    }
}

/// Codes a pixel can hold for a return (all but [`NO_RETURN`]).
const CODES: usize = NO_RETURN as usize;

/// The range of each code at `near` ([`range_of`]).
fn ranges_from(near: f32) -> [f32; CODES] {
    let mut ranges = [0.0; CODES];
    for (c, range) in ranges.iter_mut().enumerate() {
        *range = range_of(c as u8, near);
    }
    ranges
}

/// A whole-sphere image's geometry around the origin ([`Carver::whole_sphere`]).
fn whole_sphere(rows: u16, columns: u16) -> Geometry {
    use core::f32::consts::{FRAC_PI_2, PI, TAU};
    Geometry {
        origin: Point3::new(0.0, 0.0, 0.0),
        near: 0.125,
        elevation: [-FRAC_PI_2, FRAC_PI_2],
        azimuth: [-PI, TAU],
        rows,
        columns,
    }
}

/// What a scan saw along the ray to a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sight {
    /// A return lies past the point, by the margin: the point is in space seen empty.
    Through,
    /// The pixel's nearest return lies at or before the point: it may be surface.
    Short,
    /// No return along its pixel (the sky, outside the view): nothing is known.
    Nothing,
}

mod direction;
pub mod frozen;
#[cfg(test)]
mod tests;
