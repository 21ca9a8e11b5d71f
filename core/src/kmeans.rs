//! k-means++ seeding and Lloyd iterations (Section 2.3) over caller-provided slices.
//!
//! Nothing is allocated: the caller hands in the points, `k` centres to fill, one label and one
//! distance slot per point, and `k` centroid accumulators. Ties go to the lowest centre index and
//! sums run in point order, so a seed fixes the result bit for bit.
//!
//! This file is the plain reference, O(nk) per draw and per iteration. [`accel`] gives the same
//! labels and centre bits in far fewer distance evaluations (exact k-means++ over cluster lists,
//! Hamerly's bounds with a kd-tree over the centres); the tests hold the two to each other.

pub mod accel;
mod margin;
mod seed;
mod step;
pub mod tree;
mod weights;

use crate::geometry::Point3;
use crate::rng::{index_below, stream_rng};
pub use weights::{BLOCK, MAX_SQUARED, blocks_for};
use weights::{WeightScale, draw_target};

/// Why clustering could not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KMeansError {
    EmptyInput,
    ZeroClusters,
    /// k-means needs k distinct points to place k distinct centres.
    TooFewDistinctPoints {
        k: usize,
        distinct: usize,
    },
    NonFiniteCoordinate {
        index: usize,
    },
    /// Squared distances would come near f32 overflow (coordinates around 1e18).
    CoordinatesTooLarge,
    /// A caller-provided slice has the wrong length.
    SliceLength {
        what: &'static str,
        expected: usize,
        got: usize,
    },
}

impl core::fmt::Display for KMeansError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::EmptyInput => write!(f, "no points to cluster"),
            Self::ZeroClusters => write!(f, "k must be at least 1"),
            Self::TooFewDistinctPoints { k, distinct } => {
                write!(
                    f,
                    "k = {k} is larger than the number of distinct points ({distinct})"
                )
            }
            Self::NonFiniteCoordinate { index } => {
                write!(f, "point {index} has a non-finite coordinate")
            }
            Self::CoordinatesTooLarge => write!(
                f,
                "the cloud spans more than 1e18 units; squared distances would overflow f32"
            ),
            Self::SliceLength {
                what,
                expected,
                got,
            } => {
                write!(f, "{what} holds {got} entries, expected {expected}")
            }
        }
    }
}

impl core::error::Error for KMeansError {}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KMeansParams {
    pub max_iterations: u32,
    /// Stop when the summed squared centre shift falls to `tolerance` times the data's mean
    /// per-axis variance (scikit-learn's rule, so results compare); 0 waits for no label change.
    pub tolerance: f64,
    pub seed: u64,
}

impl Default for KMeansParams {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            tolerance: 1e-4,
            seed: 0,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KMeansOutcome {
    pub iterations: u32,
    pub converged: bool,
    /// Sum of squared distances from each point to its centre (eq. 6's objective).
    pub inertia: f64,
}

/// Running sum of one cluster's points, for the Lloyd update.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CentroidSum {
    pub sum: [f64; 3],
    pub count: u64,
}

/// The DE streams use ids from 0 up; k-means draws from its own.
const KMEANS_STREAM: u64 = u64::MAX;

/// Index of the nearest centre and its squared distance; ties go to the lower index.
pub fn nearest(point: Point3, centres: &[Point3]) -> (usize, f32) {
    let mut best = (0, f32::INFINITY);
    for (i, c) in centres.iter().enumerate() {
        let d = point.distance_squared(*c);
        if d < best.1 {
            best = (i, d);
        }
    }
    best
}

fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), KMeansError> {
    if expected == got {
        Ok(())
    } else {
        Err(KMeansError::SliceLength {
            what,
            expected,
            got,
        })
    }
}

/// Checks what every seeding needs and returns the first centre's index (drawn uniformly).
fn seeding_start(
    points: &[Point3],
    centres: &[Point3],
    distances: &[f32],
    rng: &mut crate::rng::Pcg32,
) -> Result<usize, KMeansError> {
    if points.is_empty() {
        return Err(KMeansError::EmptyInput);
    }
    if centres.is_empty() {
        return Err(KMeansError::ZeroClusters);
    }
    check_len("distances", points.len(), distances.len())?;
    if let Some(index) = points.iter().position(|p| !p.is_finite()) {
        return Err(KMeansError::NonFiniteCoordinate { index });
    }
    Ok(index_below(rng, points.len()))
}

/// The largest squared distance to the first centre, refused near f32 overflow. A single
/// cluster needs it too: its centroid sum and the fit's moments would overflow just the same.
fn check_extent(distances: &[f32]) -> Result<f32, KMeansError> {
    let max = distances.iter().fold(0.0f32, |m, &d| m.max(d));
    if !(max <= MAX_SQUARED) {
        return Err(KMeansError::CoordinatesTooLarge);
    }
    Ok(max)
}

/// The integer weights of the draws, fixed by the distances to the first centre (the largest
/// any point will have).
fn seeding_scale(distances: &[f32], k: usize) -> Result<WeightScale, KMeansError> {
    let max = check_extent(distances)?;
    if !(max > 0.0) {
        return Err(KMeansError::TooFewDistinctPoints { k, distinct: 1 });
    }
    Ok(WeightScale::new(max, distances.len()))
}

/// k-means++: the first centre uniformly, each next one with probability proportional to its
/// squared distance from the centres so far (as integer weights, see `weights`). `distances`
/// ends holding those squared distances.
pub fn seed_plus_plus(
    points: &[Point3],
    centres: &mut [Point3],
    distances: &mut [f32],
    seed: u64,
) -> Result<(), KMeansError> {
    let mut rng = stream_rng(seed, KMEANS_STREAM);
    let first = seeding_start(points, centres, distances, &mut rng)?;
    let k = centres.len();
    let mut chosen = points.get(first).copied().unwrap_or_default();
    for (d, p) in distances.iter_mut().zip(points.iter()) {
        *d = p.distance_squared(chosen);
    }
    let scale = if k > 1 {
        Some(seeding_scale(distances, k)?)
    } else {
        check_extent(distances)?;
        None
    };
    for (placed, centre) in centres.iter_mut().enumerate() {
        if let (true, Some(scale)) = (placed > 0, scale) {
            let total: u128 = distances.iter().map(|&d| scale.weight(d)).sum();
            if total == 0 {
                return Err(KMeansError::TooFewDistinctPoints {
                    k,
                    distinct: placed,
                });
            }
            let target = draw_target(&mut rng, total);
            let mut cumulative = 0u128;
            let mut pick = 0;
            for (i, &d) in distances.iter().enumerate() {
                cumulative += scale.weight(d);
                if cumulative > target {
                    pick = i;
                    break;
                }
            }
            chosen = points.get(pick).copied().unwrap_or_default();
            for (d, p) in distances.iter_mut().zip(points.iter()) {
                *d = d.min(p.distance_squared(chosen));
            }
        }
        *centre = chosen;
    }
    Ok(())
}

/// Lloyd's assignment step: labels each point with its nearest centre, returns how many changed.
pub fn assign(
    points: &[Point3],
    centres: &[Point3],
    labels: &mut [u32],
    distances: &mut [f32],
) -> usize {
    let mut changed = 0;
    for ((p, label), distance) in points
        .iter()
        .zip(labels.iter_mut())
        .zip(distances.iter_mut())
    {
        let (index, d) = nearest(*p, centres);
        if *label != index as u32 {
            changed += 1;
            *label = index as u32;
        }
        *distance = d;
    }
    changed
}

/// Lloyd's update step: each centre moves to its points' mean. An emptied cluster takes the point
/// farthest from its own centre, so k clusters stay k. Returns the summed squared centre shift.
pub fn update_centres(
    points: &[Point3],
    labels: &mut [u32],
    distances: &mut [f32],
    centres: &mut [Point3],
    sums: &mut [CentroidSum],
) -> f64 {
    accumulate(points, labels, sums);
    move_centres(points, labels, distances, centres, sums)
}

/// The per-cluster sums of the update step, in point order.
pub fn accumulate(points: &[Point3], labels: &[u32], sums: &mut [CentroidSum]) {
    accumulate_range(points, labels, 0, sums);
}

/// `accumulate` for the clusters `first..first + sums.len()` only: each cluster's sum still runs
/// over its points in point order, so splitting the clusters between threads changes no bit.
pub fn accumulate_range(points: &[Point3], labels: &[u32], first: u32, sums: &mut [CentroidSum]) {
    for s in sums.iter_mut() {
        *s = CentroidSum::default();
    }
    // Runs of one label (the norm in a scan) add into a local copy: the same additions in the
    // same order, without a store-to-load round trip per point.
    let mut run: Option<(usize, CentroidSum)> = None;
    for (p, &label) in points.iter().zip(labels.iter()) {
        let slot = label.wrapping_sub(first) as usize;
        if slot >= sums.len() {
            continue;
        }
        let acc = match &mut run {
            Some((current, acc)) if *current == slot => acc,
            _ => {
                if let Some((done, acc)) = run
                    && let Some(s) = sums.get_mut(done)
                {
                    *s = acc;
                }
                let start = sums.get(slot).copied().unwrap_or_default();
                &mut run.insert((slot, start)).1
            }
        };
        let q = p.to_f64();
        acc.sum[0] += q[0];
        acc.sum[1] += q[1];
        acc.sum[2] += q[2];
        acc.count += 1;
    }
    if let Some((done, acc)) = run
        && let Some(s) = sums.get_mut(done)
    {
        *s = acc;
    }
}

/// The rest of the update step once `sums` are known. `distances` (squared distances to the
/// assigned centres) is read, and one slot cleared per emptied cluster, only if a cluster is
/// empty.
pub fn move_centres(
    points: &[Point3],
    labels: &mut [u32],
    distances: &mut [f32],
    centres: &mut [Point3],
    sums: &[CentroidSum],
) -> f64 {
    let mut shift = 0.0;
    for (i, (centre, s)) in centres.iter_mut().zip(sums.iter()).enumerate() {
        let moved = if s.count > 0 {
            let n = s.count as f64;
            Point3::new(
                (s.sum[0] / n) as f32,
                (s.sum[1] / n) as f32,
                (s.sum[2] / n) as f32,
            )
        } else {
            let mut far = None;
            let mut far_distance = 0.0f32;
            for (j, &d) in distances.iter().enumerate() {
                if d > far_distance {
                    far_distance = d;
                    far = Some(j);
                }
            }
            match far {
                Some(j) => {
                    // Taken: it now sits on a centre, and another empty cluster must not take it.
                    if let (Some(d), Some(l)) = (distances.get_mut(j), labels.get_mut(j)) {
                        *d = 0.0;
                        *l = i as u32;
                    }
                    points.get(j).copied().unwrap_or(*centre)
                }
                None => *centre,
            }
        };
        shift += centre.distance_squared(moved) as f64;
        *centre = moved;
    }
    shift
}

/// k-means++ then Lloyd until convergence or `max_iterations`. `centres.len()` is k; `labels`
/// and `distances` have one slot per point, `sums` one per centre. On return every label is the
/// index of the point's nearest centre.
pub fn kmeans(
    points: &[Point3],
    centres: &mut [Point3],
    labels: &mut [u32],
    distances: &mut [f32],
    sums: &mut [CentroidSum],
    params: &KMeansParams,
) -> Result<KMeansOutcome, KMeansError> {
    check_len("labels", points.len(), labels.len())?;
    check_len("centroid sums", centres.len(), sums.len())?;
    seed_plus_plus(points, centres, distances, params.seed)?;
    Ok(lloyd(points, centres, labels, distances, sums, params))
}

/// Lloyd iterations from the given centres (slice lengths as for `kmeans`; `points` non-empty
/// and finite). The plain reference: every iteration scans all centres for every point.
pub fn lloyd(
    points: &[Point3],
    centres: &mut [Point3],
    labels: &mut [u32],
    distances: &mut [f32],
    sums: &mut [CentroidSum],
    params: &KMeansParams,
) -> KMeansOutcome {
    let threshold = params.tolerance * mean_axis_variance(points);
    labels.fill(u32::MAX);
    let mut iterations = 0;
    let mut converged = false;
    while iterations < params.max_iterations {
        let changed = assign(points, centres, labels, distances);
        iterations += 1;
        if changed == 0 {
            converged = true;
            break;
        }
        let shift = update_centres(points, labels, distances, centres, sums);
        if shift <= threshold {
            converged = true;
            assign(points, centres, labels, distances);
            break;
        }
    }
    if !converged {
        assign(points, centres, labels, distances);
    }
    let inertia = distances.iter().map(|&d| d as f64).sum();
    KMeansOutcome {
        iterations,
        converged,
        inertia,
    }
}

/// The tolerance's scale: scikit-learn's mean per-axis variance.
pub(crate) fn mean_axis_variance(points: &[Point3]) -> f64 {
    let n = points.len() as f64;
    let mut mean = [0.0f64; 3];
    for p in points {
        let q = p.to_f64();
        for j in 0..3 {
            mean[j] += q[j];
        }
    }
    let mean = mean.map(|m| m / n);
    let mut var = 0.0;
    for p in points {
        let q = p.to_f64();
        for j in 0..3 {
            var += (q[j] - mean[j]) * (q[j] - mean[j]);
        }
    }
    var / (3.0 * n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{OrFail, TestResult};

    fn blobs() -> [Point3; 300] {
        let mut pts = [Point3::default(); 300];
        let centres = [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [0.0, 5.0, 1.0]];
        let mut s = 1u64;
        for (i, p) in pts.iter_mut().enumerate() {
            let c = centres[i % 3];
            let mut next = || {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 40) as f32 / (1u64 << 24) as f32) - 0.5
            };
            *p = Point3::new(c[0] + next(), c[1] + next(), c[2] + next());
        }
        pts
    }

    #[test]
    fn separates_blobs_and_labels_are_nearest_centres() -> TestResult {
        // k-means++ is a randomised guarantee: a run can still put two seeds in one blob (about
        // 1% here), so require the blobs split in nearly every seed, and the Lloyd fixed point in all.
        let pts = blobs();
        let mut separated = 0;
        for seed in 0..20 {
            let mut centres = [Point3::default(); 3];
            let mut labels = [0u32; 300];
            let mut distances = [0f32; 300];
            let mut sums = [CentroidSum::default(); 3];
            let params = KMeansParams {
                tolerance: 0.0,
                seed,
                ..KMeansParams::default()
            };
            let out = kmeans(
                &pts,
                &mut centres,
                &mut labels,
                &mut distances,
                &mut sums,
                &params,
            )
            .or_fail("clusters")?;
            assert!(out.converged);
            for (p, &label) in pts.iter().zip(labels.iter()) {
                assert_eq!(label as usize, nearest(*p, &centres).0);
            }
            let blob_labels = [labels[0], labels[1], labels[2]];
            let split = (0..300).all(|i| labels[i] == blob_labels[i % 3])
                && blob_labels[0] != blob_labels[1]
                && blob_labels[1] != blob_labels[2]
                && blob_labels[0] != blob_labels[2];
            separated += usize::from(split);
        }
        assert!(separated >= 18, "{separated} of 20 seeds split the blobs");
        Ok(())
    }

    #[test]
    fn rejects_bad_input_with_typed_errors() {
        let mut centres = [Point3::default(); 4];
        let mut sums = [CentroidSum::default(); 4];
        let params = KMeansParams::default();
        let same = [Point3::new(1.0, 2.0, 3.0); 10];
        let (mut labels, mut distances) = ([0u32; 10], [0f32; 10]);
        let err = kmeans(
            &same,
            &mut centres,
            &mut labels,
            &mut distances,
            &mut sums,
            &params,
        );
        assert_eq!(
            err,
            Err(KMeansError::TooFewDistinctPoints { k: 4, distinct: 1 })
        );
        let mut bad = same;
        bad[3].y = f32::NAN;
        let err = kmeans(
            &bad,
            &mut centres,
            &mut labels,
            &mut distances,
            &mut sums,
            &params,
        );
        assert_eq!(err, Err(KMeansError::NonFiniteCoordinate { index: 3 }));
        let err = kmeans(&[], &mut centres, &mut [], &mut [], &mut sums, &params);
        assert_eq!(err, Err(KMeansError::EmptyInput));
        let err = kmeans(
            &same,
            &mut [],
            &mut labels,
            &mut distances,
            &mut [],
            &params,
        );
        assert_eq!(err, Err(KMeansError::ZeroClusters));
        let err = kmeans(
            &same,
            &mut centres,
            &mut labels[..5],
            &mut distances,
            &mut sums,
            &params,
        );
        assert!(matches!(err, Err(KMeansError::SliceLength { .. })));
    }

    #[test]
    fn exactly_k_distinct_points_give_k_clusters() -> TestResult {
        let pts = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        let mut centres = [Point3::default(); 3];
        let (mut labels, mut distances) = ([0u32; 4], [0f32; 4]);
        let mut sums = [CentroidSum::default(); 3];
        let out = kmeans(
            &pts,
            &mut centres,
            &mut labels,
            &mut distances,
            &mut sums,
            &KMeansParams::default(),
        )
        .or_fail("3 distinct points suffice for k = 3")?;
        assert_eq!(out.inertia, 0.0);
        let mut seen = [false; 3];
        for l in labels {
            seen[l as usize] = true;
        }
        assert!(seen.iter().all(|&s| s));
        Ok(())
    }
}
