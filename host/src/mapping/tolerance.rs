//! `mema map --tolerance T`: the hierarchical clustering the paper's future work asks for. No k:
//! clusters split (2-means inside, moments recomputed) while their eq. 13 error is above T, then
//! neighbours merge while the merged fit stays at or under T, until every cluster meets T or the
//! capacity is reached. Each cluster's entity is the paper's DE fit or its oriented shell.
//!
//! A cluster's eq. 13 error is the RMS distance of its own points to its own entity, and each
//! point's distance to the map's nearest surface is at most that to its own entity: a map whose
//! clusters all meet T has `mema eval`'s accuracy RMS at or under T too.

use anyhow::{Result, bail};
use mema_core::Point3;
use mema_core::closest_point::SurfaceError;
use mema_core::fit::{FitParams, fit_ellipsoid_paper};
use mema_core::kmeans::{CentroidSum, KMeansParams, kmeans};
use mema_core::map::record::Quantization;
use mema_core::moments::Moments;
use mema_core::rng::stream_rng;
use mema_core::shell::{ShellParams, shell};
use mema_core::{Entity, MapEntity};
use rayon::prelude::*;

/// How a cluster becomes its entity.
#[derive(Clone, Copy, Debug)]
pub enum EntityFit {
    /// The paper's DE fit of eq. 12 (axis-aligned).
    Paper(FitParams),
    /// The oriented shell of the cluster's covariance, as stored on `grid`: a cluster's error
    /// is that of the entity its file reads back.
    Shells {
        params: ShellParams,
        grid: Quantization,
    },
}

impl EntityFit {
    /// Shells on a grid fixed by the cloud's extent: centres are means of points, and no
    /// cluster's standard deviation exceeds the cloud's largest distance from its origin.
    pub fn shells_for(points: &[Point3], params: ShellParams) -> Self {
        let far = points
            .iter()
            .flat_map(|p| p.to_f64())
            .filter(|v| v.is_finite())
            .fold(0.0f64, |m, v| m.max(v.abs()));
        let longest = params.tangent_scale.max(params.normal_scale) * far * 3f64.sqrt();
        Self::Shells {
            params,
            grid: Quantization::for_extent(far, longest * 1e-6, longest),
        }
    }
}

/// A cluster of the hierarchy: its points, its place in the tree (for seeds) and its entity.
#[derive(Clone, Debug)]
pub struct Node {
    pub members: Vec<u32>,
    /// Heap numbering of the split tree (root 1, children 2i and 2i+1; merges keep the lower):
    /// every random stream derives from it, so the result does not depend on processing order.
    pub id: u64,
    pub entity: Entity,
    /// Eq. 13 of `entity` over `members`.
    pub error: f64,
}

/// The hierarchy's clusters and what it took to make them.
#[derive(Clone, Debug)]
pub struct ToleranceOutcome {
    pub nodes: Vec<Node>,
    pub splits: usize,
    pub merges: usize,
    /// True if the capacity stopped the splitting before every cluster met the tolerance.
    pub capacity_reached: bool,
}

/// Clusters with fewer points cannot be split meaningfully (a 2-means of 3 points is noise).
const MIN_SPLIT: usize = 8;
/// Neighbours tried per cluster in the merge phase.
pub const MERGE_NEIGHBOURS: usize = 4;

fn evaluate(
    points: &[Point3],
    members: &[u32],
    id: u64,
    seed: u64,
    fit: &EntityFit,
) -> Option<Node> {
    let mut moments = Moments::new();
    for &i in members {
        moments.add(*points.get(i as usize)?);
    }
    let entity = match fit {
        EntityFit::Paper(params) => {
            let central = moments.central()?;
            fit_ellipsoid_paper(&central, params, &mut stream_rng(seed, id)).entity
        }
        EntityFit::Shells { params, grid } => {
            let (mean, covariance) = moments.covariance()?;
            let entity = shell(mean, covariance, params)?;
            let kind = entity.kind(params.degeneration.sphere_tolerance);
            grid.quantize(MapEntity { entity, kind }).entity
        }
    };
    let mut error = SurfaceError::default();
    for &i in members {
        error.add(&entity, points.get(i as usize)?.to_f64());
    }
    Some(Node {
        members: members.to_vec(),
        id,
        entity,
        error: error.rmse(),
    })
}

/// Splits a node's points in two by 2-means; `None` if they cannot be split.
fn split(points: &[Point3], node: &Node, seed: u64) -> Option<[Vec<u32>; 2]> {
    if node.members.len() < MIN_SPLIT {
        return None;
    }
    let subset: Vec<Point3> = node
        .members
        .iter()
        .filter_map(|&i| points.get(i as usize).copied())
        .collect();
    let mut centres = [Point3::default(); 2];
    let mut labels = vec![0u32; subset.len()];
    let mut distances = vec![0f32; subset.len()];
    let mut sums = [CentroidSum::default(); 2];
    let params = KMeansParams {
        seed: seed ^ node.id.wrapping_mul(0x9E37_79B9_7F4A_7C15),
        ..KMeansParams::default()
    };
    kmeans(
        &subset,
        &mut centres,
        &mut labels,
        &mut distances,
        &mut sums,
        &params,
    )
    .ok()?;
    let mut halves = [Vec::new(), Vec::new()];
    for (&i, &l) in node.members.iter().zip(labels.iter()) {
        halves.get_mut(l as usize)?.push(i);
    }
    (!halves[0].is_empty() && !halves[1].is_empty()).then_some(halves)
}

/// Builds the hierarchy for tolerance `t` with at most `capacity` clusters.
///
/// Every cluster of the result meets `t` over its own points (eq. 13's `S_i`). With
/// `voronoi_rounds` > 0 the map is then checked the way `mema eval` judges any map: each point
/// joins its nearest centre, clusters are refitted, and any cluster now over `t` is split again;
/// this costs entities (docs/tolerance.md).
pub fn build(
    points: &[Point3],
    t: f64,
    capacity: usize,
    voronoi_rounds: usize,
    seed: u64,
    fit: &EntityFit,
) -> Result<ToleranceOutcome> {
    if !(t > 0.0 && t.is_finite()) {
        bail!("the tolerance must be a positive length");
    }
    if points.is_empty() {
        bail!("no points");
    }
    let all: Vec<u32> = (0..points.len() as u32).collect();
    let Some(root) = evaluate(points, &all, 1, seed, fit) else {
        bail!("cannot fit the cloud");
    };
    let mut outcome = ToleranceOutcome {
        nodes: Vec::new(),
        splits: 0,
        merges: 0,
        capacity_reached: false,
    };
    split_until(points, vec![root], t, capacity, seed, fit, &mut outcome);
    outcome.merges += merge_neighbours(points, &mut outcome.nodes, t, seed, fit);
    for _ in 0..voronoi_rounds {
        outcome.nodes = nearest_centre_refit(points, &outcome.nodes, seed, fit);
        let (over, fine): (Vec<Node>, Vec<Node>) = std::mem::take(&mut outcome.nodes)
            .into_iter()
            .partition(|n| n.error > t);
        outcome.nodes = fine;
        if over.is_empty() || outcome.capacity_reached {
            outcome.nodes.extend(over);
            break;
        }
        split_until(points, over, t, capacity, seed, fit, &mut outcome);
    }
    outcome.nodes.sort_by_key(|n| n.id);
    Ok(outcome)
}

/// Splits the `open` nodes (worst first when the capacity runs short) until each meets `t`,
/// adding the results to `outcome.nodes`.
fn split_until(
    points: &[Point3],
    mut open: Vec<Node>,
    t: f64,
    capacity: usize,
    seed: u64,
    fit: &EntityFit,
    outcome: &mut ToleranceOutcome,
) {
    while !open.is_empty() {
        let (fine, mut over): (Vec<Node>, Vec<Node>) = open.into_iter().partition(|n| n.error <= t);
        outcome.nodes.extend(fine);
        over.sort_by(|a, b| b.error.total_cmp(&a.error).then(a.id.cmp(&b.id)));
        let room = capacity.saturating_sub(outcome.nodes.len() + over.len());
        let (to_split, rest) = over.split_at(over.len().min(room));
        if !rest.is_empty() {
            outcome.capacity_reached = true;
            outcome.nodes.extend(rest.iter().cloned());
        }
        let results: Vec<(Node, Option<[Node; 2]>)> = to_split
            .par_iter()
            .map(|node| {
                let children = split(points, node, seed).and_then(|[a, b]| {
                    Some([
                        evaluate(points, &a, 2 * node.id, seed, fit)?,
                        evaluate(points, &b, 2 * node.id + 1, seed, fit)?,
                    ])
                });
                (node.clone(), children)
            })
            .collect();
        open = Vec::new();
        for (node, children) in results {
            match children {
                Some([a, b]) => {
                    outcome.splits += 1;
                    open.push(a);
                    open.push(b);
                }
                // Unsplittable (too few or coincident points): kept as it is.
                None => outcome.nodes.push(node),
            }
        }
    }
}

/// Reassigns every point to its nearest entity centre and refits each non-empty cluster.
fn nearest_centre_refit(
    points: &[Point3],
    nodes: &[Node],
    seed: u64,
    fit: &EntityFit,
) -> Vec<Node> {
    let centres: Vec<Point3> = nodes.iter().map(|n| n.entity.center).collect();
    let labels = super::pipeline::nearest_centre_labels(points, &centres);
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); nodes.len()];
    for (i, &l) in labels.iter().enumerate() {
        if let Some(m) = members.get_mut(l as usize) {
            m.push(i as u32);
        }
    }
    nodes
        .par_iter()
        .zip(members.par_iter())
        .filter(|(_, m)| !m.is_empty())
        .filter_map(|(n, m)| evaluate(points, m, n.id, seed, fit))
        .collect()
}

/// Merges neighbouring clusters whose merged fit stays at or under `t`, cheapest first, until
/// no pair qualifies. Returns the number of merges.
fn merge_neighbours(
    points: &[Point3],
    nodes: &mut Vec<Node>,
    t: f64,
    seed: u64,
    fit: &EntityFit,
) -> usize {
    let mut merges = 0;
    loop {
        let centres: Vec<Point3> = nodes.iter().map(|n| n.entity.center).collect();
        let mut pairs: Vec<(f32, usize, usize)> = Vec::new();
        for (a, ca) in centres.iter().enumerate() {
            let mut near: Vec<(f32, usize)> = centres
                .iter()
                .enumerate()
                .filter(|(b, _)| *b != a)
                .map(|(b, cb)| (ca.distance_squared(*cb), b))
                .collect();
            near.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            for &(d, b) in near.iter().take(MERGE_NEIGHBOURS) {
                let (lo, hi) = (a.min(b), a.max(b));
                let (na, nb) = (
                    nodes[lo].members.len() as f32,
                    nodes[hi].members.len() as f32,
                );
                pairs.push((na * nb / (na + nb) * d, lo, hi));
            }
        }
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0).then((x.1, x.2).cmp(&(y.1, y.2))));
        pairs.dedup_by(|x, y| (x.1, x.2) == (y.1, y.2));
        // Try all candidates in parallel, then accept in cost order, each cluster at most once.
        let tried: Vec<Option<Node>> = pairs
            .par_iter()
            .map(|&(_, a, b)| {
                let members: Vec<u32> = nodes[a]
                    .members
                    .iter()
                    .chain(nodes[b].members.iter())
                    .copied()
                    .collect();
                evaluate(points, &members, nodes[a].id.min(nodes[b].id), seed, fit)
                    .filter(|n| n.error <= t)
            })
            .collect();
        let mut used = vec![false; nodes.len()];
        let mut merged: Vec<Node> = Vec::new();
        for (&(_, a, b), candidate) in pairs.iter().zip(tried) {
            if let Some(node) = candidate
                && !used[a]
                && !used[b]
            {
                used[a] = true;
                used[b] = true;
                merged.push(node);
            }
        }
        if merged.is_empty() {
            return merges;
        }
        merges += merged.len();
        let mut next: Vec<Node> = nodes
            .iter()
            .zip(used.iter())
            .filter(|(_, u)| !**u)
            .map(|(n, _)| n.clone())
            .collect();
        next.extend(merged);
        next.sort_by_key(|n| n.id);
        *nodes = next;
    }
}
