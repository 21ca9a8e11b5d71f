//! Isolated points in a file, and the precision a cloud needs.
//!
//! The statistic is PCL's and Open3D's statistical outlier removal: each point's mean distance
//! to its `k` nearest neighbours. PCL cuts it at its mean plus a multiple of its standard
//! deviation; on the shared real scans that cut drops 2 to 4 % of clean points at 2 sigma
//! (edges, sparse rims), and one point at 10^9 m widens the deviation itself so that a second
//! outlier at 100 km survives. mema cuts at a multiple of the statistic's median instead: a
//! scale the outliers cannot move, and one that leaves clean scans whole.
//!
//! Both run on the f64 coordinates a reader decoded, before the cloud is centred and cast to
//! f32: a far point must be gone before it places the centre that the rest are rounded around.

use std::fmt;
use std::str::FromStr;

use rayon::prelude::*;
use serde::Serialize;

use crate::kdtree::{Coordinate, Entry, KdTree};

/// Neighbours of the statistic unless `--outliers` says otherwise (Open3D's example's count).
pub const DEFAULT_NEIGHBOURS: usize = 20;
/// How many times the median mean-neighbour distance a point may be from its neighbours.
pub const DEFAULT_RATIO: f64 = 30.0;
/// The f32 step across the cloud may be at most this share of the typical point spacing:
/// past it, rounding about the cloud's centre moves points by a visible part of their
/// spacing, and the map is of the rounding.
pub const PRECISION_SHARE: f64 = 1.0 / 8.0;

/// What a read does about isolated points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outliers {
    /// As the file holds them, unchecked: the library's plain readers, which return what a
    /// file says (a reference cloud to score against, a file to convert).
    Unchecked,
    /// Kept (`--outliers off`), but a cloud whose span f32 cannot hold at its spacing is
    /// refused rather than mapped as its rounding.
    Kept,
    /// Dropped where the mean distance to the `neighbours` nearest exceeds `ratio` times its
    /// median over the cloud (`--outliers K,RATIO`); then checked as [`Outliers::Kept`] is.
    Dropped { neighbours: usize, ratio: f64 },
}

impl Outliers {
    /// The command line's and the Python package's default.
    pub const DEFAULT: Self = Self::Dropped {
        neighbours: DEFAULT_NEIGHBOURS,
        ratio: DEFAULT_RATIO,
    };
}

impl fmt::Display for Outliers {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Unchecked => f.write_str("unchecked"),
            Self::Kept => f.write_str("off"),
            Self::Dropped { neighbours, ratio } => write!(f, "{neighbours},{ratio}"),
        }
    }
}

impl FromStr for Outliers {
    type Err = String;

    /// `off`, or `K,RATIO` (neighbours, a whole number from 1 to 1,000, and a ratio above 1).
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if s == "off" {
            return Ok(Self::Kept);
        }
        let bad = || {
            format!(
                "'{s}' is not off or K,RATIO (neighbours 1-1000 and a ratio above 1, e.g. {DEFAULT_NEIGHBOURS},{DEFAULT_RATIO})"
            )
        };
        let (k, ratio) = s.split_once(',').ok_or_else(bad)?;
        let neighbours: usize = k.trim().parse().map_err(|_| bad())?;
        let ratio: f64 = ratio.trim().parse().map_err(|_| bad())?;
        if !((1..=1000).contains(&neighbours) && ratio.is_finite() && ratio > 1.0) {
            return Err(bad());
        }
        Ok(Self::Dropped { neighbours, ratio })
    }
}

/// The farthest-flung point a read dropped.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WorstOutlier {
    /// Where it was, in the cloud's coordinates (metres when read in metres).
    pub at: [f64; 3],
    /// Its mean distance to its nearest neighbours, in the same unit.
    pub distance: f64,
}

/// What the outlier statistic dropped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct OutlierDrops {
    /// Points dropped.
    pub dropped: usize,
    /// The distance past which points were dropped (the ratio times the median), in the
    /// cloud's unit; 0 where none was (a map's report then matches the Python package's, whose
    /// arrays carry no read's statistic).
    pub cut: f64,
    /// The dropped point farthest from its neighbours.
    pub worst: Option<WorstOutlier>,
}

impl OutlierDrops {
    /// Another read's drops added to these (the scans of one registration file, the messages
    /// of a bag, each screened on its own as a file is): the counts add, the cut is the
    /// widest, and the worst point is the farthest from its neighbours, placed by `place`
    /// (its scan's pose) in the frame the reads are gathered in.
    pub fn add(&mut self, other: Self, place: impl Fn([f64; 3]) -> [f64; 3]) {
        self.dropped += other.dropped;
        self.cut = self.cut.max(other.cut);
        let farther = |w: &WorstOutlier| self.worst.is_none_or(|mine| w.distance > mine.distance);
        if let Some(w) = other.worst.filter(farther) {
            self.worst = Some(WorstOutlier {
                at: place(w.at),
                distance: w.distance,
            });
        }
    }
}

/// Why a cloud was refused for its precision (lengths in metres: only reads in metres are
/// screened).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrecisionLoss {
    /// Half the widest side of the cloud's box: the farthest a coordinate is from the centre.
    pub half_span: f64,
    /// The median mean distance of a point to its nearest neighbours.
    pub spacing: f64,
    /// The point farthest from its neighbours, and that distance.
    pub loneliest: WorstOutlier,
}

impl fmt::Display for PrecisionLoss {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let step = f32_step(self.half_span);
        let [x, y, z] = self.loneliest.at;
        write!(
            f,
            "the cloud spans {:.4e} m but its points are {:.3e} m apart: f32 about its centre \
             rounds by {step:.3e} m, more than {PRECISION_SHARE} of the spacing; the loneliest \
             point, at ({x:.6e}, {y:.6e}, {z:.6e}) m, is {:.3e} m from its neighbours (--outliers \
             {DEFAULT_NEIGHBOURS},{DEFAULT_RATIO} drops isolated points; crop or split a cloud \
             this wide)",
            2.0 * self.half_span,
            self.spacing,
            self.loneliest.distance,
        )
    }
}

/// The most an f32 coordinate up to `half_span` from the origin is rounded by.
fn f32_step(half_span: f64) -> f64 {
    half_span * f64::from(f32::EPSILON) / 2.0
}

/// The verdict on a cloud's points.
pub(crate) struct Screened {
    /// Bit `i` set: the caller's point `i` is dropped.
    pub dropped: Vec<u64>,
    pub drops: OutlierDrops,
}

/// Screens `entries` (the points with their indices, in the file's unit; `scale` takes them
/// to the unit they will be mapped in, by which every length reported is given) by `rule`,
/// then checks the kept ones' span against their spacing. `rule` must not be
/// [`Outliers::Unchecked`]; a cloud of fewer than two points has no statistic and passes.
///
/// The tree is the largest part of a read's memory here: f32 coordinates (an exact copy of
/// a binary float cloud's) keep it at 16 bytes a point, and the statistic is held as f32.
pub(crate) fn screen<C: Coordinate>(
    entries: Vec<Entry<C>>,
    scale: f64,
    rule: Outliers,
) -> Result<Screened, PrecisionLoss> {
    let n = entries.len();
    let mut dropped = vec![0u64; n.div_ceil(64)];
    let neighbours = match rule {
        Outliers::Dropped { neighbours, .. } => neighbours,
        Outliers::Kept | Outliers::Unchecked => DEFAULT_NEIGHBOURS,
    }
    .min(n.saturating_sub(1));
    if neighbours == 0 {
        let drops = OutlierDrops::default();
        return Ok(Screened { dropped, drops });
    }
    let tree = KdTree::from_entries(entries);
    let spread = tree.entries();
    let at = |e: &Entry<C>| e.point.map(|c| c.into() * scale);
    // Each point's statistic, in the tree's order; every answer is a function of the points,
    // so the threads change nothing.
    let mean_distances: Vec<f32> = spread
        .par_iter()
        .map_init(Vec::new, |found, e| {
            let p = e.point.map(Into::into);
            tree.k_nearest(p, Some(e.index as usize), neighbours, found);
            let sum: f64 = found.iter().map(|&(d2, _)| d2.sqrt()).sum();
            (sum / found.len() as f64 * scale) as f32
        })
        .collect();
    let median_of = |kept: &mut dyn Iterator<Item = f32>| {
        let mut sorted: Vec<f32> = kept.collect();
        let middle = sorted.len() / 2;
        f64::from(*sorted.select_nth_unstable_by(middle, f32::total_cmp).1)
    };
    let mut drops = OutlierDrops::default();
    if let Outliers::Dropped { ratio, .. } = rule {
        let cut = ratio * median_of(&mut mean_distances.iter().copied());
        for (e, &d) in spread.iter().zip(&mean_distances) {
            let d = f64::from(d);
            if d > cut {
                drops.cut = cut;
                drops.dropped += 1;
                if let Some(word) = dropped.get_mut(e.index as usize / 64) {
                    *word |= 1 << (e.index % 64);
                }
                if drops.worst.is_none_or(|w| d > w.distance) {
                    drops.worst = Some(WorstOutlier {
                        at: at(e),
                        distance: d,
                    });
                }
            }
        }
    }
    let kept = |&(e, _): &(&Entry<C>, &f32)| is_kept(&dropped, e.index);
    let pairs = || spread.iter().zip(&mean_distances).filter(kept);
    let spacing = median_of(&mut pairs().map(|(_, &d)| d));
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let mut loneliest = WorstOutlier {
        at: [0.0; 3],
        distance: f64::NEG_INFINITY,
    };
    for (e, &d) in pairs() {
        let p = at(e);
        for j in 0..3 {
            lo[j] = lo[j].min(p[j]);
            hi[j] = hi[j].max(p[j]);
        }
        if f64::from(d) > loneliest.distance {
            loneliest = WorstOutlier {
                at: p,
                distance: f64::from(d),
            };
        }
    }
    let half_span = (0..3).map(|j| (hi[j] - lo[j]) / 2.0).fold(0.0, f64::max);
    // A spacing of 0 (most points stacked on their neighbours) has no resolution to lose.
    if spacing > 0.0 && f32_step(half_span) > PRECISION_SHARE * spacing {
        return Err(PrecisionLoss {
            half_span,
            spacing,
            loneliest,
        });
    }
    Ok(Screened { dropped, drops })
}

/// Whether the caller's point `index` survived.
fn is_kept(dropped: &[u64], index: u32) -> bool {
    dropped
        .get(index as usize / 64)
        .is_none_or(|word| word >> (index % 64) & 1 == 0)
}

impl Screened {
    /// Whether the caller's point `index` is kept.
    pub fn keeps(&self, index: usize) -> bool {
        u32::try_from(index).is_ok_and(|i| is_kept(&self.dropped, i))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::read::{Screening, read_cloud_in_metres, read_cloud_in_metres_keeping};
    use std::path::PathBuf;

    fn shared(name: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../shared/data")
            .join(name)
    }

    fn entries(points: &[[f64; 3]]) -> Vec<Entry> {
        points
            .iter()
            .zip(0u32..)
            .map(|(&point, index)| Entry { point, index })
            .collect()
    }

    /// The statistic by its definition: every distance, sorted, the first `k` averaged; the
    /// cut at `ratio` times the median.
    fn brute_force_drops(points: &[[f64; 3]], k: usize, ratio: f64) -> Vec<usize> {
        let mean: Vec<f32> = points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut d: Vec<(f64, usize)> = points
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(j, q)| ((0..3).map(|a| (p[a] - q[a]).powi(2)).sum::<f64>(), j))
                    .collect();
                d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                // Held as f32, as the filter holds it.
                (d.iter().take(k).map(|e| e.0.sqrt()).sum::<f64>() / k as f64) as f32
            })
            .collect();
        let mut sorted = mean.clone();
        sorted.sort_by(f32::total_cmp);
        let cut = ratio * f64::from(sorted[sorted.len() / 2]);
        (0..points.len())
            .filter(|&i| f64::from(mean[i]) > cut)
            .collect()
    }

    #[test]
    fn the_drops_are_the_statistics_by_brute_force_on_a_real_cloud() {
        let cloud = read_cloud_in_metres(&shared("lamppost.pcd"), None).expect("lamppost");
        let mut points: Vec<[f64; 3]> = cloud
            .points
            .iter()
            .map(|p| std::array::from_fn(|a| cloud.origin[a] + f64::from(p[a])))
            .collect();
        // Two strays of the kind the filter is for, besides the scan's own sparse points.
        points.push([cloud.origin[0] + 40.0, cloud.origin[1], cloud.origin[2]]);
        points.push([
            cloud.origin[0],
            cloud.origin[1] - 3.0,
            cloud.origin[2] + 2.0,
        ]);
        for (k, ratio) in [(20, 30.0), (8, 2.0), (20, 1.5), (3, 4.0)] {
            let rule = Outliers::Dropped {
                neighbours: k,
                ratio,
            };
            let screened = screen(entries(&points), 1.0, rule).expect("a narrow cloud");
            let dropped: Vec<usize> = (0..points.len()).filter(|&i| !screened.keeps(i)).collect();
            assert_eq!(
                dropped,
                brute_force_drops(&points, k, ratio),
                "k {k}, ratio {ratio}"
            );
            assert_eq!(screened.drops.dropped, dropped.len());
            assert!(dropped.contains(&(points.len() - 2)), "the far stray stays");
        }
    }

    #[test]
    fn clean_real_scans_lose_almost_nothing_by_default() {
        for name in [
            "bun000.ply",
            "bun_zipper.ply",
            "office1.pcd",
            "five_people.pcd",
            "autzen_trim.laz",
            "car6.pcd",
            "vegetation_1_3.las",
        ] {
            let plain = read_cloud_in_metres(&shared(name), None).expect("reads");
            let screened = read_cloud_in_metres_keeping(&shared(name), None, Screening::MAPPING)
                .expect("screens");
            let n = plain.points.len();
            assert_eq!(
                screened.points.len() + screened.outliers.dropped,
                n,
                "{name}"
            );
            // One point in ten thousand at most: strays, never a scan's rim.
            assert!(
                screened.outliers.dropped * 10_000 <= n,
                "{name}: {:?}",
                screened.outliers
            );
        }
    }

    #[test]
    fn a_span_f32_cannot_hold_at_the_spacing_is_refused_and_a_narrow_one_passes() {
        // A 1 mm grid of 20 x 20 points, and one point `far` metres off.
        let grid = |far: f64| {
            let mut p: Vec<[f64; 3]> = (0..400)
                .map(|i| [f64::from(i % 20) * 1e-3, f64::from(i / 20) * 1e-3, 0.0])
                .collect();
            p.push([far, 0.0, 0.0]);
            p
        };
        // f32 rounds by far / 2 * 2^-24: 1.5e-5 m at 500 m, an eighth of 1.2 mm spacing is 1.5e-4.
        assert!(screen(entries(&grid(500.0)), 1.0, Outliers::Kept).is_ok());
        let loss = screen(entries(&grid(1e5)), 1.0, Outliers::Kept)
            .err()
            .expect("refused");
        assert_eq!(loss.loneliest.at, [1e5, 0.0, 0.0]);
        assert!((loss.half_span - 5e4).abs() < 1.0, "{loss:?}");
        assert!(loss.to_string().contains("f32"), "{loss}");
        // Dropped first, the stray leaves a cloud f32 holds.
        let screened = screen(entries(&grid(1e9)), 1.0, Outliers::DEFAULT).expect("kept narrow");
        assert_eq!(screened.drops.dropped, 1);
        assert!(!screened.keeps(400));
        assert_eq!(screened.drops.worst.map(|w| w.at), Some([1e9, 0.0, 0.0]));
    }

    #[test]
    fn the_rule_parses_as_documented() {
        assert_eq!("off".parse::<Outliers>(), Ok(Outliers::Kept));
        assert_eq!(" 20, 30 ".parse::<Outliers>(), Ok(Outliers::DEFAULT));
        assert_eq!(Outliers::DEFAULT.to_string().parse(), Ok(Outliers::DEFAULT));
        for bad in [
            "", "20", "0,30", "20,1", "20,nan", "1001,3", "x,y", "20,30,1",
        ] {
            assert!(bad.parse::<Outliers>().is_err(), "{bad}");
        }
    }
}
