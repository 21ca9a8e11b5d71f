//! Shells shaped by the rays their points came down (issue 29, "the map agrees with the rays").
//!
//! A shell is made from its cluster's mean and covariance alone, so it knows nothing of the
//! space its sensor saw through. Measured on the Ouster sweeps (sweeps 0 and 2 mapped at 9,600
//! bytes, sweep 1's rays cast again), a quarter of the rays stopped early, mostly on fat shells
//! at 10 to 40 m (thickness a median 7 cm against 0.8 cm for the shells rays agree with), and the
//! input's own rays said the same as the held-out ones. So each shell's two tangent semi-axes,
//! its normal semi-axis, its place along its normal and its tilt about its two tangent axes are
//! chosen, one at a time from a few candidates, to make the most of the input's own rays agree
//! (`+1`) and the fewest stop early (`-1`), the other entities held as they are. A ray agrees when
//! the map's first surface along it lies within the tolerance of its end; the tolerance is two
//! median point spacings, the scale `mema eval` judges phantom surface on.
//!
//! Rounds update the even and the odd entities in turn: overlapping neighbours changed at once
//! would both give way for the same rays.

use mema_core::Entity;
use mema_core::query::ray_entity;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::pipeline::Members;
use crate::io::cloud::LocalCloud;

/// Rays taken from the input, evenly through it: enough for every entity of a 38,400-byte
/// map to meet hundreds, few enough to score every candidate in a fraction of a second.
pub const MAX_RAYS: usize = 60_000;
/// Rounds of the search: each tries one of the shape's six parameters for the even or the odd
/// entities, so 24 rounds try each parameter twice for every entity. Measured on the Ouster
/// sweeps, the score stops moving by then.
pub const ROUNDS: usize = 24;
/// The most (ray, shell) pairs shaping holds, 8 bytes each with the lists turned around: 256 MB.
/// The shared sweeps' 38,400-byte maps make about 350,000.
pub const MAX_PAIRS: usize = 32_000_000;
/// Points whose nearest-neighbour spacing sets the tolerance.
const SPACING_SAMPLE: usize = 4_000;

/// Scales of the two tangent semi-axes, of the normal semi-axis, moves along the normal (in
/// normal semi-axes) and tilts about the tangent axes (degrees) that are tried.
const TANGENT_SCALES: [f64; 8] = [1.0, 0.9, 0.8, 0.7, 0.6, 1.1, 1.2, 1.3];
const NORMAL_SCALES: [f64; 6] = [1.0, 0.7, 0.5, 0.3, 0.2, 0.1];
const NORMAL_MOVES: [f64; 5] = [0.0, -1.0, -0.5, 0.5, 1.0];
const TILTS: [f64; 5] = [0.0, -10.0, -5.0, 5.0, 10.0];
/// The reach of any candidate, in the shell's longest semi-axis plus its normal one: rays
/// that pass further from its centre meet none of its candidates.
const REACH: f64 = 1.3;

/// An entity's shape against its shell: tangent scales (longer axis first), normal scale,
/// move along the normal, tilts about the two tangent axes.
type Shape = [f64; 6];
const UNCHANGED: Shape = [1.0, 1.0, 1.0, 0.0, 0.0, 0.0];

/// The shaped entities and what shaping did.
#[derive(Clone, Debug, PartialEq)]
pub struct Shaped {
    pub entities: Vec<Entity>,
    /// Entities whose shape changed.
    pub changed: usize,
    /// Rays scored.
    pub rays: usize,
    /// The agreement tolerance (metres): two median point spacings.
    pub tolerance: f64,
    /// Rays whose first surface agreed with their end, and stopped early, before and after.
    pub agree: [usize; 2],
    pub early: [usize; 2],
}

/// A ray of the input in the map's frame: its origin, unit direction and measured range.
#[derive(Clone, Copy, Debug)]
struct Ray {
    origin: [f64; 3],
    direction: [f64; 3],
    range: f64,
}

/// Shapes `entities` (the map's frame, `cloud.origin`'s) to the rays of `cloud`, whose points'
/// clusters are `labels`; `None` when the cloud has no sensor origins, no entities, no point
/// spacing to judge on, or more ray and shell pairs than [`MAX_PAIRS`].
pub fn shape(cloud: &LocalCloud, labels: &[u32], entities: &[Entity]) -> Option<Shaped> {
    if cloud.sensors.is_empty() || entities.is_empty() {
        return None;
    }
    let rays = rays_of(cloud);
    let tolerance = 2.0 * median_spacing(cloud, labels);
    if rays.is_empty() || !(tolerance > 0.0 && tolerance.is_finite()) {
        return None;
    }
    let near = rays_near(entities, &rays, tolerance, MAX_PAIRS)?;
    let through = Through::of(&near, rays.len());
    let mut shapes = vec![UNCHANGED; entities.len()];
    let first = first_hits(entities, &shapes, &through, &rays, tolerance);
    let before = tally(&first, &rays, tolerance);
    for round in 0..ROUNDS {
        let hits = first_hits(entities, &shapes, &through, &rays, tolerance);
        let parameter = round % UNCHANGED.len();
        let parity = (round / UNCHANGED.len()) % 2;
        let chosen: Vec<Shape> = (0..entities.len())
            .into_par_iter()
            .map(|i| {
                if i % 2 != parity {
                    return shapes[i];
                }
                best_shape(
                    i,
                    entities[i],
                    shapes[i],
                    parameter,
                    &near[i],
                    &hits,
                    &rays,
                    tolerance,
                )
            })
            .collect();
        shapes = chosen;
    }
    let last = first_hits(entities, &shapes, &through, &rays, tolerance);
    let after = tally(&last, &rays, tolerance);
    Some(Shaped {
        entities: entities
            .iter()
            .zip(&shapes)
            .map(|(e, s)| shaped(e, *s))
            .collect(),
        changed: shapes.iter().filter(|s| **s != UNCHANGED).count(),
        rays: rays.len(),
        tolerance,
        agree: [before.0, after.0],
        early: [before.1, after.1],
    })
}

/// The candidates for one parameter of entity `i`, the others kept; the best scoring one,
/// the current shape on ties.
#[allow(clippy::too_many_arguments)]
fn best_shape(
    i: usize,
    entity: Entity,
    current: Shape,
    parameter: usize,
    near: &[u32],
    hits: &[[(f64, u32); 2]],
    rays: &[Ray],
    tolerance: f64,
) -> Shape {
    let candidates: &[f64] = match parameter {
        0 | 1 => &TANGENT_SCALES,
        2 => &NORMAL_SCALES,
        3 => &NORMAL_MOVES,
        _ => &TILTS,
    };
    let score = |s: Shape| {
        let e = shaped(&entity, s);
        near.iter()
            .map(|&r| {
                let ray = &rays[r as usize];
                let [a, b] = hits[r as usize];
                let others = if a.1 == i as u32 { b.0 } else { a.0 };
                let t = ray_entity(&e, ray.origin, ray.direction, ray.range + tolerance)
                    .unwrap_or(f64::INFINITY)
                    .min(others);
                value(t, ray.range, tolerance)
            })
            .sum::<i64>()
    };
    let mut best = (score(current), current);
    for &c in candidates {
        let mut s = current;
        s[parameter] = c;
        if s != current {
            let v = score(s);
            if v > best.0 {
                best = (v, s);
            }
        }
    }
    best.1
}

/// +1 for a first surface within the tolerance of the ray's end, -1 for one before it.
fn value(t: f64, range: f64, tolerance: f64) -> i64 {
    if t < range - tolerance {
        -1
    } else if t <= range + tolerance {
        1
    } else {
        0
    }
}

/// (agree, early) over the rays.
fn tally(hits: &[[(f64, u32); 2]], rays: &[Ray], tolerance: f64) -> (usize, usize) {
    let mut out = (0, 0);
    for (h, r) in hits.iter().zip(rays) {
        match value(h[0].0, r.range, tolerance) {
            1 => out.0 += 1,
            -1 => out.1 += 1,
            _ => {}
        }
    }
    out
}

/// Each ray's two nearest surfaces (distance, entity) at the current shapes; `through` lists,
/// for each ray, the entities it passes near.
fn first_hits(
    entities: &[Entity],
    shapes: &[Shape],
    through: &Through,
    rays: &[Ray],
    tolerance: f64,
) -> Vec<[(f64, u32); 2]> {
    let current: Vec<Entity> = entities
        .iter()
        .zip(shapes)
        .map(|(e, s)| shaped(e, *s))
        .collect();
    rays.par_iter()
        .enumerate()
        .map(|(r, ray)| {
            let mut h = [(f64::INFINITY, u32::MAX); 2];
            for &i in through.entities_of(r) {
                let Some(t) = ray_entity(
                    &current[i as usize],
                    ray.origin,
                    ray.direction,
                    ray.range + tolerance,
                ) else {
                    continue;
                };
                if (t, i) < h[0] {
                    h[1] = h[0];
                    h[0] = (t, i);
                } else if (t, i) < h[1] {
                    h[1] = (t, i);
                }
            }
            h
        })
        .collect()
}

/// For each ray, the entities it passes near: [`rays_near`] turned around, in one allocation.
struct Through {
    starts: Vec<u32>,
    entities: Vec<u32>,
}

impl Through {
    fn of(near: &[Vec<u32>], rays: usize) -> Self {
        let mut starts = vec![0u32; rays + 1];
        for list in near {
            for &r in list {
                starts[r as usize + 1] += 1;
            }
        }
        for r in 1..starts.len() {
            starts[r] += starts[r - 1];
        }
        let mut fill = starts.clone();
        let mut entities = vec![0u32; starts[rays] as usize];
        for (i, list) in near.iter().enumerate() {
            for &r in list {
                entities[fill[r as usize] as usize] = i as u32;
                fill[r as usize] += 1;
            }
        }
        Self { starts, entities }
    }

    fn entities_of(&self, ray: usize) -> &[u32] {
        &self.entities[self.starts[ray] as usize..self.starts[ray + 1] as usize]
    }
}

/// The entity with shape `s`: semi-axes scaled, moved along its normal, tilted.
fn shaped(e: &Entity, s: Shape) -> Entity {
    if s == UNCHANGED {
        return *e;
    }
    // Axes by weight: the two tangent axes (longest first), then the normal.
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| e.weights[a].total_cmp(&e.weights[b]).then(a.cmp(&b)));
    let mut out = *e;
    for (k, &j) in order.iter().enumerate() {
        out.weights[j] = (e.weights[j] as f64 / (s[k] * s[k])) as f32;
    }
    let normal = order[2];
    for (k, &degrees) in [s[4], s[5]].iter().enumerate() {
        if degrees != 0.0 {
            let half = degrees.to_radians() / 2.0;
            let mut q = [0.0, 0.0, 0.0, half.cos()];
            q[order[k]] = half.sin();
            if let Some(tilt) = mema_core::Rotation::from_quaternion(q) {
                out.rotation = out.rotation.after(&tilt);
            }
        }
    }
    if s[3] != 0.0 && e.weights[normal] > 0.0 {
        let along = s[3] / (e.weights[normal] as f64).sqrt();
        let mut axis = [0.0; 3];
        axis[normal] = 1.0;
        let a = e.rotation.rotate(axis);
        let c = e.center.to_f64();
        out.center = mema_core::Point3::new(
            (c[0] + along * a[0]) as f32,
            (c[1] + along * a[1]) as f32,
            (c[2] + along * a[2]) as f32,
        );
    }
    out
}

/// Up to [`MAX_RAYS`] rays, every n-th point of every scan, in the map's frame.
fn rays_of(cloud: &LocalCloud) -> Vec<Ray> {
    let step = cloud.sensors.points().div_ceil(MAX_RAYS).max(1);
    let mut rays = Vec::new();
    for (range, origin) in cloud.sensors.runs() {
        let o = [0, 1, 2].map(|j| origin[j] - cloud.origin[j]);
        for p in cloud
            .points
            .get(range)
            .unwrap_or_default()
            .iter()
            .step_by(step)
        {
            let p = p.to_f64();
            let v = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
            let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if r > 0.0 && r.is_finite() {
                rays.push(Ray {
                    origin: o,
                    direction: v.map(|c| c / r),
                    range: r,
                });
            }
        }
    }
    rays
}

/// The median distance from a sample of points to their nearest other point of the same
/// cluster: a point's nearest neighbour is nearly always in its own cluster, a median does not
/// see the few at borders that are not, and a search in clusters needs no tree beside the cloud.
fn median_spacing(cloud: &LocalCloud, labels: &[u32]) -> f64 {
    let clusters = labels.iter().map(|&l| l as usize + 1).max().unwrap_or(0);
    let members = Members::of(labels, clusters);
    let n = labels.len().min(cloud.points.len());
    let step = n.div_ceil(SPACING_SAMPLE).max(1);
    let mut spacings: Vec<f64> = (0..n)
        .step_by(step)
        .collect::<Vec<_>>()
        .par_iter()
        .filter_map(|&i| {
            let l = labels[i] as usize;
            let p = cloud.points[i].to_f64();
            members
                .of_cluster(l)
                .iter()
                .filter(|&&j| j as usize != i)
                .map(|&j| {
                    let q = cloud.points[j as usize].to_f64();
                    (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)
                })
                .min_by(f64::total_cmp)
                .map(f64::sqrt)
        })
        .collect();
    spacings.sort_by(f64::total_cmp);
    spacings.get(spacings.len() / 2).copied().unwrap_or(0.0)
}

/// For each entity, the rays whose segment (to its end and the tolerance past it) passes
/// within the reach of every candidate shape: directions binned per scan, so an entity reads
/// only the bins its reach subtends.
fn rays_near(
    entities: &[Entity],
    rays: &[Ray],
    tolerance: f64,
    max_pairs: usize,
) -> Option<Vec<Vec<u32>>> {
    let bins = DirectionBins::of(rays);
    // Shells that each reach across most of the rays (a map of a few huge shells around its
    // sensor) would make rays x shells pairs; past `max_pairs` the map is left unshaped.
    let pairs = AtomicUsize::new(0);
    let near: Vec<Vec<u32>> = entities
        .par_iter()
        .map(|e| {
            if pairs.load(Ordering::Relaxed) > max_pairs {
                return Vec::new();
            }
            let c = e.center.to_f64();
            let reach = reach_of(e);
            let mut near = Vec::new();
            bins.visit_cone(c, reach, |r| {
                let ray = &rays[r as usize];
                if segment_within(ray, tolerance, c, reach) {
                    near.push(r);
                }
            });
            near.sort_unstable();
            pairs.fetch_add(near.len(), Ordering::Relaxed);
            near
        })
        .collect();
    (pairs.into_inner() <= max_pairs).then_some(near)
}

fn reach_of(e: &Entity) -> f64 {
    let axes = e.weights.map(|w| {
        if w > 0.0 {
            1.0 / (w as f64).sqrt()
        } else {
            0.0
        }
    });
    let longest = axes.iter().copied().fold(0.0, f64::max);
    let shortest = axes
        .iter()
        .copied()
        .filter(|a| *a > 0.0)
        .fold(longest, f64::min);
    REACH * longest + shortest
}

/// Whether the ray's segment `[0, range + tolerance]` passes within `radius` of `c`.
fn segment_within(ray: &Ray, tolerance: f64, c: [f64; 3], radius: f64) -> bool {
    let v = [0, 1, 2].map(|j| c[j] - ray.origin[j]);
    let along = (v[0] * ray.direction[0] + v[1] * ray.direction[1] + v[2] * ray.direction[2])
        .clamp(0.0, ray.range + tolerance);
    let q = [0, 1, 2].map(|j| ray.origin[j] + along * ray.direction[j] - c[j]);
    q[0] * q[0] + q[1] * q[1] + q[2] * q[2] <= radius * radius
}

mod bins;
use bins::DirectionBins;

#[cfg(test)]
mod tests;
