//! Held-out rays cast at a map (`mema eval --rays`, issue 29): does the map agree with what a
//! sensor saw along each ray, and does it tell occupied from free as occupancy maps are scored.
//!
//! Two scores, both from rays the map was not built from:
//! - **Range agreement.** Each ray is cast from its sensor origin at the map; its first hit
//!   *agrees* within the tolerance of the measured range, *stops early* before `range - tol`
//!   (surface standing in space the sensor saw through: a phantom), or *runs on* with no hit
//!   by `range + tol` (a hole).
//! - **Occupancy** as GMMap and Hilbert maps score it: points sampled along each ray, its end
//!   labelled occupied and the space before it free, each given the map's occupancy (free 0,
//!   occupied 1, unknown 0.5); accuracy and ROC AUC over the samples.
//!
//! The scoring takes the first hits and the states from outside ([`score`]), so a map with no
//! free space (today's: a sample within the tolerance of surface is occupied, any other is
//! unknown), a map with free-space states, and OctoMap (`mema bench --only free-space`) are
//! scored by one function.

use anyhow::Result;
use rayon::prelude::*;
use serde::Serialize;

use crate::io::cloud::LocalCloud;
use crate::io::mapfile::HostMap;
use crate::query::{HostIndex, build_index, local};

/// The default agreement tolerance: 10 cm, the issue's, about a lidar's range noise plus a
/// map's surface error.
pub const DEFAULT_TOLERANCE: f64 = 0.1;

/// Free samples per ray, at 1/5 .. 4/5 of its range: as many free as the space before an end
/// is long in few samples, and never within the tolerance of the end.
pub const FREE_SAMPLES: usize = 4;

/// One held-out ray: from its sensor origin to the point measured, in world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: [f64; 3],
    pub end: [f64; 3],
}

impl Ray {
    /// The measured range.
    pub fn range(&self) -> f64 {
        norm(sub(self.end, self.origin))
    }

    /// The unit direction (`None` for a ray of length 0, which no-returns never make).
    pub fn direction(&self) -> Option<[f64; 3]> {
        let r = self.range();
        (r > 0.0).then(|| sub(self.end, self.origin).map(|c| c / r))
    }

    /// The point `t` metres along the ray.
    pub fn at(&self, t: f64) -> [f64; 3] {
        let d = self.direction().unwrap_or_default();
        std::array::from_fn(|j| self.origin[j] + t * d[j])
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Every point of `cloud` that has a sensor origin, as the ray from it (world coordinates).
pub fn held_out_rays(cloud: &LocalCloud) -> Vec<Ray> {
    let o = cloud.origin;
    cloud
        .sensors
        .runs()
        .flat_map(|(range, origin)| {
            cloud
                .points
                .get(range)
                .unwrap_or_default()
                .iter()
                .map(move |p| {
                    let q = p.to_f64();
                    Ray {
                        origin,
                        end: [o[0] + q[0], o[1] + q[1], o[2] + q[2]],
                    }
                })
        })
        .filter(|r| r.range() > 0.0)
        .collect()
}

/// A point the occupancy score asks about, and what the held-out ray says it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub point: [f64; 3],
    /// The ray's end (true), or space the ray passed through (false).
    pub occupied: bool,
}

/// The samples along `rays`: each ray's free points at `j / (FREE_SAMPLES + 1)` of its range
/// that lie before `range - tolerance`, then its end.
pub fn samples(rays: &[Ray], tolerance: f64) -> Vec<Sample> {
    let mut out = Vec::with_capacity(rays.len() * (FREE_SAMPLES + 1));
    for ray in rays {
        let r = ray.range();
        for j in 1..=FREE_SAMPLES {
            let t = r * j as f64 / (FREE_SAMPLES + 1) as f64;
            if t < r - tolerance {
                out.push(Sample {
                    point: ray.at(t),
                    occupied: false,
                });
            }
        }
        out.push(Sample {
            point: ray.end,
            occupied: true,
        });
    }
    out
}

pub use crate::query::states::State;

/// Where a ray's first hit fell against its measured range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    Agree,
    /// Hit before `range - tolerance`: surface where the sensor saw through.
    Early,
    /// No hit by `range + tolerance`: a hole.
    RunOn,
}

/// Classifies a first hit `hit` (metres along the ray; `None`: no hit) against `range`.
pub fn outcome(hit: Option<f64>, range: f64, tolerance: f64) -> Outcome {
    match hit {
        Some(t) if t < range - tolerance => Outcome::Early,
        Some(t) if t <= range + tolerance => Outcome::Agree,
        _ => Outcome::RunOn,
    }
}

/// The scores of held-out rays against one map.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RayScores {
    pub tolerance: f64,
    pub rays: usize,
    pub agree: usize,
    pub early: usize,
    pub run_on: usize,
    pub agree_fraction: f64,
    pub early_fraction: f64,
    pub run_on_fraction: f64,
    pub occupancy: OccupancyScore,
}

/// The occupancy score over the samples along the rays.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct OccupancyScore {
    pub samples: usize,
    /// Samples that are rays' ends (labelled occupied); the rest are free.
    pub occupied_samples: usize,
    /// What the map said of the samples.
    pub said_occupied: usize,
    pub said_free: usize,
    pub said_unknown: usize,
    /// Free samples the map said occupied (phantom surface in seen-through space).
    pub free_said_occupied: usize,
    /// Mean of `1 - |label - occupancy|`: an unknown sample is half right.
    pub accuracy: f64,
    /// ROC AUC of the occupancy against the labels, ties counted half (Mann-Whitney).
    pub auc: f64,
}

/// Scores `rays` from each ray's first hit (`hits[i]`, metres along ray `i`, `None` for none
/// within `range + tolerance`) and the state of each of `samples` (`states[i]`).
pub fn score(
    rays: &[Ray],
    hits: &[Option<f64>],
    samples: &[Sample],
    states: &[State],
    tolerance: f64,
) -> RayScores {
    let mut s = RayScores {
        tolerance,
        rays: rays.len(),
        ..RayScores::default()
    };
    for (ray, hit) in rays.iter().zip(hits) {
        match outcome(*hit, ray.range(), tolerance) {
            Outcome::Agree => s.agree += 1,
            Outcome::Early => s.early += 1,
            Outcome::RunOn => s.run_on += 1,
        }
    }
    let n = s.rays.max(1) as f64;
    (s.agree_fraction, s.early_fraction, s.run_on_fraction) =
        (s.agree as f64 / n, s.early as f64 / n, s.run_on as f64 / n);
    s.occupancy = occupancy_score(samples, states);
    s
}

fn occupancy_score(samples: &[Sample], states: &[State]) -> OccupancyScore {
    let mut o = OccupancyScore {
        samples: samples.len().min(states.len()),
        ..OccupancyScore::default()
    };
    let mut right = 0.0;
    // Three scores only: the AUC from counts of (label, state), ties counted half.
    let mut counts = [[0usize; 3]; 2];
    for (sample, state) in samples.iter().zip(states) {
        let label = if sample.occupied { 1.0 } else { 0.0 };
        right += 1.0 - (label - state.occupancy()).abs();
        let column = match state {
            State::Free => 0,
            State::Unknown => 1,
            State::Occupied => 2,
        };
        counts[usize::from(sample.occupied)][column] += 1;
        match state {
            State::Free => o.said_free += 1,
            State::Occupied => o.said_occupied += 1,
            State::Unknown => o.said_unknown += 1,
        }
        if !sample.occupied && *state == State::Occupied {
            o.free_said_occupied += 1;
        }
    }
    o.occupied_samples = counts[1].iter().sum();
    o.accuracy = right / o.samples.max(1) as f64;
    let (neg, pos) = (counts[0], counts[1]);
    let (n_neg, n_pos) = (neg.iter().sum::<usize>(), pos.iter().sum::<usize>());
    let mut wins = 0.0;
    for (p, &np) in pos.iter().enumerate() {
        for (q, &nq) in neg.iter().enumerate() {
            let pairs = (np * nq) as f64;
            wins += match p.cmp(&q) {
                std::cmp::Ordering::Greater => pairs,
                std::cmp::Ordering::Equal => 0.5 * pairs,
                std::cmp::Ordering::Less => 0.0,
            };
        }
    }
    o.auc = if n_neg == 0 || n_pos == 0 {
        0.5
    } else {
        wins / (n_pos as f64 * n_neg as f64)
    };
    o
}

/// A map as the rays see it: its first surface along a ray through the core's index, and the
/// state of a point ([`crate::query::states`]).
pub struct MapRays<'m> {
    map: &'m HostMap,
    index: Box<HostIndex>,
    tolerance: f64,
}

impl<'m> MapRays<'m> {
    pub fn new(map: &'m HostMap, tolerance: f64) -> Result<Self> {
        Ok(Self {
            map,
            index: build_index(map)?,
            tolerance,
        })
    }

    /// The first hit along `ray` up to `range + tolerance` (metres from its origin).
    pub fn first_hit(&self, ray: &Ray) -> Option<f64> {
        let d = ray.direction()?;
        let t_max = ray.range() + self.tolerance;
        self.index
            .ray_cast(local(self.map, ray.origin), d, t_max)
            .map(|h| h.t)
    }

    /// What the map says of `p`.
    pub fn state(&self, p: [f64; 3]) -> State {
        crate::query::states::state_of(self.map, &self.index, p, self.tolerance).state
    }

    /// Scores `rays` against the map.
    pub fn score(&self, rays: &[Ray]) -> RayScores {
        let hits: Vec<Option<f64>> = rays.par_iter().map(|r| self.first_hit(r)).collect();
        let samples = samples(rays, self.tolerance);
        let states: Vec<State> = samples.par_iter().map(|s| self.state(s.point)).collect();
        score(rays, &hits, &samples, &states, self.tolerance)
    }
}

#[cfg(test)]
mod tests;
