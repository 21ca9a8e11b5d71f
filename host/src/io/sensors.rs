//! Where each point was seen from: the sensor origins of a cloud's scans, so every point is a
//! ray (issue 29). The whole segment from the sensor to a point was seen empty, which a map of
//! endpoints alone throws away.
//!
//! A cloud's points come scan by scan (a registration file's lines, a bag's messages, one
//! frame), each scan from one sensor position, so the origins are kept as runs: one origin and
//! the index one past its scan's last point, 32 bytes a scan rather than 24 bytes a point.

use std::ops::Range;

/// The sensor origins of a cloud's points, as runs over the point indices; empty where the
/// input says nowhere where its sensor was (then no free space is recorded).
///
/// ```
/// use mema::io::sensors::Sensors;
///
/// let mut sensors = Sensors::default();
/// sensors.push_run([0.0, 0.0, 0.0], 3);
/// sensors.push_run([1.0, 0.0, 0.0], 2);
/// assert_eq!(sensors.origin_of(2), Some([0.0, 0.0, 0.0]));
/// assert_eq!(sensors.origin_of(3), Some([1.0, 0.0, 0.0]));
/// assert_eq!(sensors.origin_of(5), None);
/// assert_eq!(sensors.points(), 5);
/// ```
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sensors {
    /// Each run's sensor origin, in world coordinates (the cloud's own frame, f64, metres for a
    /// cloud in metres), so moving the cloud's local origin leaves them as they are.
    pub origins: Vec<[f64; 3]>,
    /// One past each run's last point index: increasing, the last the cloud's point count.
    pub ends: Vec<usize>,
}

impl Sensors {
    /// One run: every one of `points` points seen from `origin`.
    pub fn single(origin: [f64; 3], points: usize) -> Self {
        let mut s = Self::default();
        s.push_run(origin, points);
        s
    }

    /// Whether no point has a sensor origin.
    pub fn is_empty(&self) -> bool {
        self.origins.is_empty()
    }

    /// The points the runs cover.
    pub fn points(&self) -> usize {
        self.ends.last().copied().unwrap_or(0)
    }

    /// Appends a run of `len` points seen from `origin` (an empty run is kept out: it would
    /// name an origin no point was seen from).
    pub fn push_run(&mut self, origin: [f64; 3], len: usize) {
        if len > 0 {
            self.ends.push(self.points() + len);
            self.origins.push(origin);
        }
    }

    /// The runs: each origin with the range of point indices seen from it.
    pub fn runs(&self) -> impl Iterator<Item = (Range<usize>, [f64; 3])> + '_ {
        let starts = std::iter::once(0).chain(self.ends.iter().copied());
        starts
            .zip(&self.ends)
            .zip(&self.origins)
            .map(|((start, &end), &origin)| (start..end, origin))
    }

    /// The sensor origin point `i` was seen from.
    pub fn origin_of(&self, i: usize) -> Option<[f64; 3]> {
        let run = self.ends.partition_point(|&end| end <= i);
        self.origins.get(run).copied()
    }

    /// The runs after keeping only the points `keep` says (by index, in order): each run
    /// shrinks to its kept points, as a filter that keeps the order (a crop) leaves them.
    pub fn retain(&self, mut keep: impl FnMut(usize) -> bool) -> Self {
        let mut out = Self::default();
        for (range, origin) in self.runs() {
            let kept = range.filter(|&i| keep(i)).count();
            out.push_run(origin, kept);
        }
        out
    }
}

/// Leaves out of `points` (one scan, in its sensor's frame) those within `min_range` of
/// `sensor`, the no-returns; returns how many.
pub fn drop_no_returns(points: &mut Vec<[f64; 3]>, sensor: [f64; 3], min_range: f64) -> usize {
    let before = points.len();
    points.retain(|p| {
        let d2: f64 = (0..3)
            .map(|j| (p[j] - sensor[j]) * (p[j] - sensor[j]))
            .sum();
        d2.sqrt() > min_range
    });
    before - points.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against a direct per-point list of origins.
    #[test]
    fn runs_agree_with_a_list_per_point() {
        let mut sensors = Sensors::default();
        let mut per_point = Vec::new();
        for (k, len) in [4usize, 0, 7, 1, 3].into_iter().enumerate() {
            let origin = [k as f64, -(k as f64), 0.5];
            sensors.push_run(origin, len);
            per_point.extend(std::iter::repeat_n(origin, len));
        }
        assert_eq!(sensors.points(), per_point.len());
        assert_eq!(sensors.origins.len(), 4, "the empty run is kept out");
        for (i, o) in per_point.iter().enumerate() {
            assert_eq!(sensors.origin_of(i), Some(*o), "point {i}");
        }
        let kept = sensors.retain(|i| i % 3 != 0);
        let want: Vec<_> = (0..per_point.len())
            .filter(|i| i % 3 != 0)
            .map(|i| per_point[i])
            .collect();
        assert_eq!(kept.points(), want.len());
        for (i, o) in want.iter().enumerate() {
            assert_eq!(kept.origin_of(i), Some(*o));
        }
    }

    #[test]
    fn no_returns_are_the_points_at_the_sensor() {
        let mut points = vec![
            [0.0; 3],
            [1.0, 2.0, 2.0],
            [1.0, 2.0, 2.005],
            [5.0, 0.0, 0.0],
        ];
        assert_eq!(drop_no_returns(&mut points, [1.0, 2.0, 2.0], 0.01), 2);
        assert_eq!(points, vec![[0.0; 3], [5.0, 0.0, 0.0]]);
    }
}
