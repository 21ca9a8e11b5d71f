//! The two-way fidelity score of a map against a cloud (issue 11), beside eq. 13.
//!
//! - **accuracy**, cloud to map: each point's distance to the nearest entity surface of the
//!   whole map, exact (the query index over every entity, not the nearest centre's entity);
//! - **completeness**, map to cloud: points spread uniformly by area over every entity's surface
//!   ([`surface`]), each one's distance to the nearest cloud point ([`crate::kdtree`]), weighted by area;
//! - **tau** = 2 x the cloud's median nearest-other-point spacing, and at tau the **phantom**
//!   area fraction (surface farther than tau from any point), **precision** (surface within
//!   tau), **recall** (points within tau of the surface) and their **F-score**, as SOGMM reports
//!   them; **Chamfer** = (accuracy mean + completeness mean) / 2.
//!
//! Everything is in the map's frame and the cloud's units. The result depends on the seed and
//! the sample count only: samples are drawn per entity from that entity's own generator and all
//! sums run in a fixed order, so the thread count never changes a bit.

pub mod surface;

use anyhow::{Result, bail};
use mema_core::closest_point::surface_distance;
use mema_core::{Entity, Point3};
use rand_core::SeedableRng;
use rand_pcg::Pcg32;
use rayon::prelude::*;
use serde::Serialize;

use crate::kdtree::KdTree;
use surface::Patch;

/// Samples every entity's surface gets at least, however small its share of the area.
pub const MIN_SAMPLES_PER_ENTITY: usize = 8;
/// The default total of surface samples.
pub const DEFAULT_SAMPLES: usize = 200_000;

/// Cloud to map: statistics of every point's distance to the nearest surface.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Accuracy {
    pub mean: f64,
    pub rms: f64,
    /// 95th percentile, nearest rank.
    pub p95: f64,
    pub max: f64,
}

/// Map to cloud: area-weighted statistics of the surface samples' distance to the cloud.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Completeness {
    pub mean: f64,
    pub rms: f64,
    /// The smallest distance within which 95% of the sampled area lies.
    pub p95: f64,
}

/// The two-way score of a map against a cloud (`mema eval`'s JSON keys; docs/command-line.md, "The commands").
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FidelityScore {
    pub accuracy: Accuracy,
    pub completeness: Completeness,
    pub tau: f64,
    pub phantom: f64,
    pub precision: f64,
    pub recall: f64,
    pub f_score: f64,
    pub chamfer: f64,
    /// Surface samples drawn (at least [`MIN_SAMPLES_PER_ENTITY`] per entity).
    pub samples: usize,
    /// Total sampled surface area (degenerated axes cut as described at [`surface_samples`]).
    pub area: f64,
}

/// One surface sample in the map frame; `weight` is its share of its entity's area.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    pub point: [f64; 3],
    pub weight: f64,
    pub entity: u32,
}

/// The score of `entities` against `points` (both in the map's frame), with `samples` surface
/// samples drawn from `seed`.
///
/// Accuracy is how far the points lie from the map's surface, completeness how far the map's
/// surface lies from the points; a cloud drawn on its map scores about zero both ways:
///
/// ```
/// use mema_core::{Entity, Point3};
///
/// // Points on the unit sphere, and the sphere.
/// let points: Vec<[f64; 3]> = (0..2_000)
///     .map(|i| {
///         let z = 1.0 - 2.0 * (i as f64 + 0.5) / 2_000.0;
///         let a = i as f64 * 2.399_963;
///         let r = (1.0 - z * z).sqrt();
///         [r * a.cos(), r * a.sin(), z]
///     })
///     .collect();
/// let sphere = Entity::sphere(Point3::new(0.0, 0.0, 0.0), 1.0);
/// let score = mema::analysis::fidelity::two_way_score(&points, &[sphere], 0, 5_000)?;
/// assert!(score.accuracy.max < 1e-5);
/// assert!(score.completeness.mean < score.tau);
/// # Ok::<(), anyhow::Error>(())
/// ```
pub fn two_way_score(
    points: &[[f64; 3]],
    entities: &[Entity],
    seed: u64,
    samples: usize,
) -> Result<FidelityScore> {
    if points.is_empty() {
        bail!("the cloud has no points to score");
    }
    if entities.is_empty() {
        bail!("the map has no entities to score");
    }
    let labels = eq13_labels(points, entities);
    let accuracy_d = accuracy_with_labels(points, entities, &labels);
    let tree = KdTree::build(points);
    let tau = 2.0 * median(&nearest_spacings(&tree, points));
    let drawn = samples_of(
        &patches_with_labels(points, entities, &labels),
        entities,
        seed,
        samples,
    );
    let completeness_d: Vec<f64> = drawn
        .par_iter()
        .map(|s| tree.nearest(s.point, None).map_or(0.0, |n| n.distance))
        .collect();
    Ok(score_from_distances(
        &accuracy_d,
        &completeness_d,
        &drawn.iter().map(|s| s.weight).collect::<Vec<_>>(),
        tau,
    ))
}

/// The statistics of the score from the two sets of distances: the arithmetic shared by
/// [`two_way_score`] and anything that computes the distances another way.
pub fn score_from_distances(
    accuracy_d: &[f64],
    completeness_d: &[f64],
    weights: &[f64],
    tau: f64,
) -> FidelityScore {
    let n = accuracy_d.len().max(1) as f64;
    let accuracy = Accuracy {
        mean: accuracy_d.iter().sum::<f64>() / n,
        rms: (accuracy_d.iter().map(|d| d * d).sum::<f64>() / n).sqrt(),
        p95: weighted_quantile(accuracy_d.iter().map(|&d| (d, 1.0)).collect(), 0.95),
        max: accuracy_d.iter().fold(0.0, |m, &d| m.max(d)),
    };
    let area: f64 = weights.iter().sum();
    let per_area = |f: &dyn Fn(f64) -> f64| {
        if area > 0.0 {
            completeness_d
                .iter()
                .zip(weights)
                .map(|(&d, &w)| w * f(d))
                .sum::<f64>()
                / area
        } else {
            0.0
        }
    };
    let completeness = Completeness {
        mean: per_area(&|d| d),
        rms: per_area(&|d| d * d).sqrt(),
        p95: weighted_quantile(
            completeness_d
                .iter()
                .copied()
                .zip(weights.iter().copied())
                .collect(),
            0.95,
        ),
    };
    let precision = per_area(&|d| if d <= tau { 1.0 } else { 0.0 });
    let phantom = per_area(&|d| if d > tau { 1.0 } else { 0.0 });
    let recall = accuracy_d.iter().filter(|&&d| d <= tau).count() as f64 / n;
    let f_score = if precision + recall > 0.0 {
        2.0 * precision * recall / (precision + recall)
    } else {
        0.0
    };
    FidelityScore {
        accuracy,
        completeness,
        tau,
        phantom,
        precision,
        recall,
        f_score,
        chamfer: 0.5 * (accuracy.mean + completeness.mean),
        samples: completeness_d.len(),
        area,
    }
}

/// Each point's distance to the nearest entity surface over the whole map: the minimum of
/// `closest_point::surface_distance` over every entity, found without evaluating every one.
///
/// No surface of an entity is nearer to `p` than `|p - c| - r_max` (it lies in the ball of its
/// largest semi-axis, however the entity is turned). Each point starts from the entity of its
/// nearest centre; the largest such start over a cluster of points bounds, through the
/// cluster's bounding box, which entities can beat it, and each point then evaluates only those
/// of that list its own bound cannot rule out. Entities with a degenerated axis have no ball
/// and are always evaluated. The query index (`MapIndex::nearest`) gives the same minimum but
/// took 4.4 s for 239k points on a 700-entity map, its traversal starting far from the answer;
/// this takes a fraction of that.
pub fn accuracy_distances(points: &[[f64; 3]], entities: &[Entity]) -> Vec<f64> {
    accuracy_with_labels(points, entities, &eq13_labels(points, entities))
}

fn accuracy_with_labels(points: &[[f64; 3]], entities: &[Entity], labels: &[u32]) -> Vec<f64> {
    let centres: Vec<[f64; 3]> = entities.iter().map(|e| e.center.to_f64()).collect();
    let reach: Vec<f64> = entities
        .iter()
        .map(|e| e.semi_axes_f64().into_iter().fold(0.0, f64::max))
        .collect();
    let start: Vec<f64> = points
        .par_iter()
        .zip(labels.par_iter())
        .map(|(&p, &l)| surface_distance(&entities[l as usize], p))
        .collect();
    // Per cluster: the bounding box of its points and their largest starting distance.
    let mut boxes = vec![([f64::INFINITY; 3], [f64::NEG_INFINITY; 3], 0.0f64); entities.len()];
    for ((p, &l), &d) in points.iter().zip(labels).zip(&start) {
        let (lo, hi, worst) = &mut boxes[l as usize];
        for j in 0..3 {
            lo[j] = lo[j].min(p[j]);
            hi[j] = hi[j].max(p[j]);
        }
        *worst = worst.max(d);
    }
    let candidates: Vec<Vec<u32>> = boxes
        .par_iter()
        .map(|(lo, hi, worst)| {
            if lo[0] > hi[0] {
                return Vec::new();
            }
            (0..entities.len() as u32)
                .filter(|&e| {
                    let c = centres[e as usize];
                    let gap = (0..3)
                        .map(|j| (lo[j] - c[j]).max(c[j] - hi[j]).max(0.0).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    // NaN anywhere keeps the entity: the bound rules out only what it can.
                    let ruled_out = below_bound(gap, reach[e as usize]) > *worst;
                    !ruled_out
                })
                .collect()
        })
        .collect();
    points
        .par_iter()
        .zip(labels.par_iter())
        .zip(start.par_iter())
        .map(|((&p, &l), &d)| {
            let mut best = d;
            for &e in &candidates[l as usize] {
                let e = e as usize;
                let c = centres[e];
                let gap =
                    ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
                if below_bound(gap, reach[e]) < best {
                    best = best.min(surface_distance(&entities[e], p));
                }
            }
            best
        })
        .collect()
}

/// A lower bound of the distance to a surface inside the ball of radius `reach` about a centre
/// `gap` away, lowered by a relative 1e-9 so that rounding in it or in the exact distance never
/// rules out the nearest entity. `-inf` for an unbounded entity.
fn below_bound(gap: f64, reach: f64) -> f64 {
    if reach.is_finite() {
        gap - reach - 1e-9 * (gap + reach)
    } else {
        f64::NEG_INFINITY
    }
}

/// Each point's cluster as eq. 13 forms them: its nearest entity centre, on the f32 points.
fn eq13_labels(points: &[[f64; 3]], entities: &[Entity]) -> Vec<u32> {
    let f32_points: Vec<Point3> = points
        .iter()
        .map(|p| Point3::new(p[0] as f32, p[1] as f32, p[2] as f32))
        .collect();
    let centres: Vec<Point3> = entities.iter().map(|e| e.center).collect();
    crate::mapping::pipeline::nearest_centre_labels(&f32_points, &centres)
}

/// Each point's distance to its nearest other point (0 for a duplicate; infinite alone).
pub fn nearest_spacings(tree: &KdTree, points: &[[f64; 3]]) -> Vec<f64> {
    points
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            tree.nearest(p, Some(i))
                .map_or(f64::INFINITY, |n| n.distance)
        })
        .collect()
}

/// The median; the mean of the two middle values for an even count, 0 for none.
pub fn median(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|d| d.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// The smallest value whose cumulative weight (values ascending) reaches `q` of the total:
/// with equal weights, the nearest-rank percentile.
pub fn weighted_quantile(mut pairs: Vec<(f64, f64)>, q: f64) -> f64 {
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = pairs.iter().map(|p| p.1).sum();
    let mut cumulative = 0.0;
    for &(d, w) in &pairs {
        cumulative += w;
        if cumulative >= q * total && w > 0.0 {
            return d;
        }
    }
    pairs.iter().rev().find(|p| p.1 > 0.0).map_or(0.0, |p| p.0)
}

/// The extent, along each local axis, of the points whose nearest entity centre is this
/// entity's (the clusters eq. 13 scores); `None` for an entity no point is nearest to.
pub fn own_point_extents(points: &[[f64; 3]], entities: &[Entity]) -> Vec<Option<[[f64; 2]; 3]>> {
    extents_with_labels(points, entities, &eq13_labels(points, entities))
}

fn extents_with_labels(
    points: &[[f64; 3]],
    entities: &[Entity],
    labels: &[u32],
) -> Vec<Option<[[f64; 2]; 3]>> {
    let mut extents: Vec<Option<[[f64; 2]; 3]>> = vec![None; entities.len()];
    for (p, &l) in points.iter().zip(labels) {
        let Some(entity) = entities.get(l as usize) else {
            continue;
        };
        let local = entity.to_local(*p);
        let slot = extents[l as usize].get_or_insert([[f64::INFINITY, f64::NEG_INFINITY]; 3]);
        for j in 0..3 {
            slot[j][0] = slot[j][0].min(local[j]);
            slot[j][1] = slot[j][1].max(local[j]);
        }
    }
    extents
}

/// The surface each entity offers to sampling: a degenerated (infinite) axis is cut to the
/// extent of the entity's own points ([`own_point_extents`]), or, with no points of its own,
/// to +- its largest finite semi-axis.
pub fn patches(points: &[[f64; 3]], entities: &[Entity]) -> Vec<Patch> {
    patches_with_labels(points, entities, &eq13_labels(points, entities))
}

fn patches_with_labels(points: &[[f64; 3]], entities: &[Entity], labels: &[u32]) -> Vec<Patch> {
    extents_with_labels(points, entities, labels)
        .into_iter()
        .zip(entities)
        .map(|(extent, e)| {
            let largest = e
                .semi_axes_f64()
                .into_iter()
                .filter(|r| r.is_finite())
                .fold(0.0, f64::max);
            Patch::of(e, extent.unwrap_or([[-largest, largest]; 3]))
        })
        .collect()
}

/// About `total` points uniform by area over the map's surface (see [`patches`]), at least
/// [`MIN_SAMPLES_PER_ENTITY`] per entity, each weighted by its entity's area over its count.
/// Entity `i` draws from its own generator, seeded from `seed` and `i`.
pub fn surface_samples(
    points: &[[f64; 3]],
    entities: &[Entity],
    seed: u64,
    total: usize,
) -> Vec<SurfaceSample> {
    samples_of(&patches(points, entities), entities, seed, total)
}

fn samples_of(
    patches: &[Patch],
    entities: &[Entity],
    seed: u64,
    total: usize,
) -> Vec<SurfaceSample> {
    let areas: Vec<f64> = patches.iter().map(Patch::area).collect();
    let sum: f64 = areas.iter().filter(|a| a.is_finite()).sum();
    let per_entity: Vec<(Patch, f64, usize)> = patches
        .iter()
        .copied()
        .zip(areas)
        .map(|(patch, area)| {
            let area = if area.is_finite() { area } else { 0.0 };
            let share = if sum > 0.0 {
                (total as f64 * area / sum).round() as usize
            } else {
                0
            };
            (patch, area, share.max(MIN_SAMPLES_PER_ENTITY))
        })
        .collect();
    per_entity
        .par_iter()
        .zip(entities.par_iter())
        .enumerate()
        .map(|(i, ((patch, area, n), entity))| {
            let mut rng = Pcg32::seed_from_u64(splitmix64(seed ^ splitmix64(i as u64)));
            let weight = area / *n as f64;
            patch
                .sample(*n, &mut rng)
                .into_iter()
                .map(|local| SurfaceSample {
                    point: entity.to_world(local),
                    weight,
                    entity: i as u32,
                })
                .collect::<Vec<_>>()
        })
        .collect::<Vec<_>>()
        .concat()
}

/// SplitMix64's finaliser: nearby seeds and indices give unrelated generator states.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests;
