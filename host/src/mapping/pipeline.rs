//! The batch pipeline of the paper: k-means++/Lloyd, one DE fit per cluster, eq. 13 per cluster.

use anyhow::{Context, Result, bail};
use mema_core::closest_point::SurfaceError;
use mema_core::fit::{Fit, FitParams, fit_ellipsoid_paper, fit_sphere_paper};
use mema_core::kmeans::accel::{
    AssignStep, CentreState, CentreStep, FastOutcome, PassCounts, Runner, Scratch, ScratchSizes,
    SeedList, kmeans_fast,
};
use mema_core::kmeans::tree::{TreeCentre, TreeNode};
use mema_core::kmeans::{CentroidSum, KMeansOutcome, KMeansParams, accumulate_range, kmeans};
use mema_core::moments::{CentralMoments, Moments};
use mema_core::rng::stream_rng;
use mema_core::{Entity, MapEntity, Point3};
use rayon::prelude::*;

use crate::io::mapfile::HostMap;

/// Clusters of a cloud: labels and per-cluster central moments.
pub struct Clusters {
    pub labels: Vec<u32>,
    pub moments: Vec<CentralMoments>,
    pub outcome: KMeansOutcome,
}

/// Both fits of every cluster, as the paper compares them (Section 4.5).
pub struct Fitted {
    pub ellipsoids: Vec<Fit>,
    pub spheres: Vec<Fit>,
}

/// Which k-means implementation runs; both give the same labels and centre bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KMeansEngine {
    /// The reference: every point against every centre, every iteration.
    Plain,
    /// Exact k-means++ over cluster lists, Hamerly's bounds, a kd-tree over the centres, and
    /// the assignment on all threads.
    Accelerated,
}

/// Points per parallel task. The result does not depend on the split; a fixed size keeps the
/// work identical for any thread count anyway.
pub const ASSIGN_CHUNK: usize = 4096;

/// Runs the accelerated assignment on the rayon pool in fixed chunks.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayonRunner;

impl Runner for RayonRunner {
    fn assign(
        &self,
        step: &AssignStep<'_>,
        points: &[Point3],
        labels: &mut [u32],
        bounds: &mut [f32],
        seconds: &mut [u32],
    ) -> PassCounts {
        points
            .par_chunks(ASSIGN_CHUNK)
            .zip(labels.par_chunks_mut(ASSIGN_CHUNK))
            .zip(bounds.par_chunks_mut(ASSIGN_CHUNK))
            .zip(seconds.par_chunks_mut(ASSIGN_CHUNK))
            .map(|(((p, l), u), lo)| step.run(p, l, u, lo))
            .sum()
    }

    fn accumulate(&self, points: &[Point3], labels: &[u32], sums: &mut [CentroidSum]) {
        // Each task reads every label but sums only its own clusters, in point order.
        let tasks = rayon::current_num_threads().max(1);
        let per_task = sums.len().div_ceil(tasks).max(1);
        sums.par_chunks_mut(per_task)
            .enumerate()
            .for_each(|(t, part)| accumulate_range(points, labels, (t * per_task) as u32, part));
    }

    fn centres(&self, step: &CentreStep<'_>, state: &mut [CentreState]) {
        const CHUNK: usize = 256;
        state
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(i, part)| step.run(i * CHUNK, part));
    }
}

/// k-means result: centres, one label per point, and how Lloyd ended.
pub struct KMeansRun {
    pub centres: Vec<Point3>,
    pub labels: Vec<u32>,
    pub outcome: KMeansOutcome,
    /// Accelerated only: point visits of the assignment passes and kd-tree searches among them.
    pub visits: u64,
    pub searches: u64,
}

/// k-means with either engine, its working memory allocated here and freed on return.
pub fn run_kmeans(
    points: &[Point3],
    k: usize,
    params: &KMeansParams,
    engine: KMeansEngine,
) -> Result<KMeansRun> {
    if k == 0 {
        bail!("k must be at least 1");
    }
    if k > points.len() {
        bail!(
            "k = {k} is larger than the cloud ({} points); consider -k {}",
            points.len(),
            (points.len() / 100).max(1)
        );
    }
    let n = points.len();
    let mut centres = vec![Point3::default(); k];
    let mut labels = vec![0u32; n];
    let mut distances = vec![0f32; n];
    let mut sums = vec![CentroidSum::default(); k];
    let outcome = match engine {
        KMeansEngine::Plain => kmeans(
            points,
            &mut centres,
            &mut labels,
            &mut distances,
            &mut sums,
            params,
        )
        .map(|outcome| FastOutcome {
            outcome,
            visits: 0,
            searches: 0,
        }),
        KMeansEngine::Accelerated => {
            let size = ScratchSizes::new(n, k);
            let mut seconds = vec![0u32; size.points];
            let mut blocks = vec![0u128; size.blocks];
            let mut lists = vec![SeedList::default(); size.centres];
            let mut state = vec![CentreState::default(); size.centres];
            let mut order = vec![0u32; size.centres];
            let mut sorted = vec![TreeCentre::default(); size.centres];
            let mut nodes = vec![TreeNode::default(); size.nodes];
            let scratch = Scratch {
                seconds: &mut seconds,
                blocks: &mut blocks,
                lists: &mut lists,
                centres: &mut state,
                order: &mut order,
                sorted: &mut sorted,
                nodes: &mut nodes,
            };
            kmeans_fast(
                points,
                &mut centres,
                &mut labels,
                &mut distances,
                &mut sums,
                scratch,
                params,
                &RayonRunner,
            )
        }
    }
    .map_err(anyhow::Error::from)
    .context("k-means")?;
    Ok(KMeansRun {
        centres,
        labels,
        outcome: outcome.outcome,
        visits: outcome.visits,
        searches: outcome.searches,
    })
}

/// Runs k-means and gathers each cluster's moments.
pub fn cluster(points: &[Point3], k: usize, params: &KMeansParams) -> Result<Clusters> {
    cluster_with(points, k, params, KMeansEngine::Accelerated)
}

/// [`cluster`] with the k-means implementation chosen.
pub fn cluster_with(
    points: &[Point3],
    k: usize,
    params: &KMeansParams,
    engine: KMeansEngine,
) -> Result<Clusters> {
    let run = run_kmeans(points, k, params, engine)?;
    let moments = cluster_moments(points, &run.labels, &run.centres)?;
    Ok(Clusters {
        labels: run.labels,
        moments,
        outcome: run.outcome,
    })
}

/// Each cluster's central moments, its points added in point order (so in parallel over
/// clusters the bits are those of one pass over the points).
pub fn cluster_moments(
    points: &[Point3],
    labels: &[u32],
    centres: &[Point3],
) -> Result<Vec<CentralMoments>> {
    let members = Members::of(labels, centres.len());
    centres
        .par_iter()
        .enumerate()
        .map(|(i, c)| {
            // Shifting by the centroid keeps the moment conversion well conditioned.
            let mut m = Moments::with_shift(c.to_f64());
            for &p in members.of_cluster(i) {
                m.add(points[p as usize]);
            }
            m.central()
                .with_context(|| format!("cluster {i} is empty after k-means"))
        })
        .collect()
}

/// The points of each cluster in point order: a counting sort of the labels, 4 bytes a point.
pub(crate) struct Members {
    start: Vec<u32>,
    order: Vec<u32>,
}

impl Members {
    pub(crate) fn of(labels: &[u32], k: usize) -> Self {
        let mut start = vec![0u32; k + 1];
        for &l in labels {
            if let Some(s) = start.get_mut(l as usize + 1) {
                *s += 1;
            }
        }
        for i in 0..k {
            start[i + 1] += start[i];
        }
        let mut next = start.clone();
        let mut order = vec![0u32; start[k] as usize];
        for (i, &l) in labels.iter().enumerate() {
            if let Some(n) = next.get_mut(l as usize) {
                order[*n as usize] = i as u32;
                *n += 1;
            }
        }
        Self { start, order }
    }

    pub(crate) fn of_cluster(&self, c: usize) -> &[u32] {
        &self.order[self.start[c] as usize..self.start[c + 1] as usize]
    }
}

/// Fits an ellipsoid and a sphere to every cluster, in parallel. Each cluster draws from its
/// own random stream, so the result does not depend on the thread count or order.
pub fn fit_all(moments: &[CentralMoments], seed: u64, params: &FitParams) -> Fitted {
    let pairs: Vec<(Fit, Fit)> = moments
        .par_iter()
        .enumerate()
        .map(|(i, m)| {
            let e = fit_ellipsoid_paper(m, params, &mut stream_rng(seed, 2 * i as u64));
            let s = fit_sphere_paper(m, params, &mut stream_rng(seed, 2 * i as u64 + 1));
            (e, s)
        })
        .collect();
    let (ellipsoids, spheres) = pairs.into_iter().unzip();
    Fitted {
        ellipsoids,
        spheres,
    }
}

/// Eq. 13 for every cluster: RMS distance of its points to its entity's surface.
pub fn cluster_errors(points: &[Point3], labels: &[u32], entities: &[Entity]) -> Vec<f64> {
    // Each cluster summed on its own, its points in point order: the sums never depend on the
    // thread count, and the working memory is 4 bytes a point rather than a k-sized partial per
    // chunk of points.
    let members = Members::of(labels, entities.len());
    entities
        .par_iter()
        .enumerate()
        .map(|(c, e)| {
            let mut acc = SurfaceError::default();
            for &i in members.of_cluster(c) {
                acc.add(e, points[i as usize].to_f64());
            }
            acc.rmse()
        })
        .collect()
}

/// Labels each point with its nearest entity centre (ties: lowest index), as `mema eval` does.
///
/// The answer is the plain scan's (`mema_core::kmeans::nearest`) bit for bit, found through
/// the k-means kd-tree over the centres, so a map of 16,384 entities costs `N log k` rather
/// than `N k` (11 minutes of `mema draw` went to this scan).
pub fn nearest_centre_labels(points: &[Point3], centres: &[Point3]) -> Vec<u32> {
    use mema_core::kmeans::tree::{CentreTree, nodes_for};
    let k = centres.len();
    let mut order = vec![0u32; k];
    let mut sorted = vec![TreeCentre::default(); k];
    let mut nodes = vec![TreeNode::default(); nodes_for(k)];
    let Some(mut tree) = CentreTree::new(&mut order, &mut sorted, &mut nodes) else {
        // More centres than u32 indices: no map comes near, but the scan still answers.
        return points
            .par_iter()
            .map(|p| mema_core::kmeans::nearest(*p, centres).0 as u32)
            .collect();
    };
    tree.build(centres, |_| 0.0);
    let view = tree.view();
    let none = [(u32::MAX, f32::INFINITY); 2];
    // An empty tree (or a point the tree cannot rank, NaN) gets 0, as the scan gives it.
    points
        .par_iter()
        .map(|p| view.nearest(*p, none).map_or(0, |n| n.index))
        .collect()
}

/// The fits as a map around `origin`, each entity's kind told with `sphere_tolerance`.
pub fn to_map(origin: [f64; 3], fits: &[Fit], sphere_tolerance: f64) -> HostMap {
    HostMap {
        origin,
        entities: fits
            .iter()
            .map(|f| MapEntity {
                entity: f.entity,
                kind: f.entity.kind(sphere_tolerance),
            })
            .collect(),
        quantization: None,
        free_space: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// docs/performance.md's counting sort: every point once, in its cluster's run and in point
    /// order, and what the sort and the labels it sorts keep a point, as they are stored.
    #[test]
    fn the_counting_sort_keeps_each_point_once_at_the_bytes_the_guide_states() {
        use crate::io::read::testkit::guide_says;
        let k = 13;
        let labels: Vec<u32> = (0..1_000u32).map(|i| i * 7 % 13).collect();
        let members = Members::of(&labels, k);
        assert_eq!(members.order.len(), labels.len());
        for c in 0..k {
            let run = members.of_cluster(c);
            assert!(
                run.windows(2).all(|w| w[0] < w[1]),
                "cluster {c} out of order"
            );
            assert!(run.iter().all(|&p| labels[p as usize] as usize == c));
        }
        let sorted = size_of_val(members.order.as_slice()) / labels.len();
        let label = size_of_val(labels.as_slice()) / labels.len();
        guide_says(
            "docs/performance.md",
            &format!("each cluster with a counting sort ({sorted} bytes a point)"),
        );
        assert_eq!(label, sorted, "the guide says the same of labels and sort");
        guide_says(
            "docs/performance.md",
            &format!("the labels and a counting sort of them ({label} bytes a point each)"),
        );
    }

    /// The tree gives the plain scan's labels on a real cloud, ties included: centres drawn
    /// from the points themselves (so some points sit exactly on one) and duplicated (so two
    /// centres tie and the lower index must win), plus a NaN point and no centres at all.
    #[test]
    fn nearest_centre_labels_equal_the_plain_scan() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/car6.pcd");
        let cloud = crate::io::load_cloud(path.as_ref()).expect("car6");
        let mut points = cloud.points.clone();
        points.push(Point3::new(f32::NAN, 0.0, 0.0));
        for k in [1, 7, 150, 2_000] {
            let step = (cloud.points.len() / k).max(1);
            let mut centres: Vec<Point3> = cloud.points.iter().step_by(step).copied().collect();
            centres.extend_from_within(..centres.len() / 3);
            let plain: Vec<u32> = points
                .iter()
                .map(|p| mema_core::kmeans::nearest(*p, &centres).0 as u32)
                .collect();
            assert_eq!(nearest_centre_labels(&points, &centres), plain, "k = {k}");
        }
        assert!(nearest_centre_labels(&points, &[]).iter().all(|&l| l == 0));
    }
}
