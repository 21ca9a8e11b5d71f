//! The core against the f64 reference, cluster by cluster, on real clouds.
//!
//! Clusters: the streaming mapper (as the firmware runs it, `k` clusters) maps the cloud, and
//! every point then joins its nearest final centre, so each cluster is a set of points both
//! sides can see. Per cluster, the core fits from its moments (`fit_ellipsoid_paper`, eq. 13 by
//! Eberly's bisection on the stored f32 entity) and the reference from the points (direct sums,
//! its own DE on the same PCG32 stream, Newton for eq. 13). A comparison returns `Option<Diff>`:
//! `None` when every quantity is within its tolerance, else the entities that are not.

use std::path::{Path, PathBuf};

use mema_core::Point3;
use mema_core::closest_point::SurfaceError;
use mema_core::fit::{FitParams, fit_ellipsoid_paper};
use mema_core::moments::{FixedMoments, Moments};
use mema_core::rng::stream_rng;
use mema_core::stream::{StreamMapper, StreamParams};
use nalgebra::Vector3;
use rayon::prelude::*;

use crate::reference::{self, closest_point};

/// The tolerances (relative).
pub const FITNESS_TOLERANCE: f64 = 1e-4;
pub const SEMI_AXES_TOLERANCE: f64 = 1e-3;
pub const ERROR_TOLERANCE: f64 = 1e-3;
/// Eberly's bisection and Newton on the same entity: two solvers of one equation.
pub const SOLVER_TOLERANCE: f64 = 1e-9;
/// The moment form of eq. 12 sums O(1) terms into `E[g^2]`, so near a perfect fit its square
/// root carries an absolute error of about sqrt(1e-16) = 1e-8 (measured: 5e-9 on 2-point
/// clusters). Below that, agreement is checked in absolute terms.
pub const FITNESS_ABSOLUTE_FLOOR: f64 = 1e-8;
/// Absolute floor of the eq. 13 solver check (a distance, in the cloud's unit).
pub const SOLVER_ABSOLUTE_FLOOR: f64 = 1e-15;
/// A cluster needs this many points for its fit to be determined: with fewer, eq. 12 has a
/// family of equally good semi-axes (two points lie exactly on many ellipsoids), and DE's end
/// point, hence the semi-axes and eq. 13, depends on the last bits of every comparison.
/// Smaller clusters are still compared on fitness at the same semi-axes and on the solvers.
pub const MIN_POINTS: usize = 10;

/// What is compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// Eq. 12 at the core's semi-axes: core moments (O(1)) vs the direct per-point sum.
    FitnessAtCoreAxes,
    /// Eq. 12 at each side's own DE optimum.
    FitnessOptimum,
    /// The fitted semi-axes (largest relative difference over the three), or a mismatch of
    /// degeneration kind (reported as infinite).
    SemiAxes,
    /// Eq. 13's per-cluster error, each side with its own fit and its own solver.
    SurfaceError,
    /// Eq. 13 on the core's entity: Eberly's bisection vs Newton.
    SurfaceErrorSameEntity,
}

impl Quantity {
    pub const ALL: [Quantity; 5] = [
        Self::FitnessAtCoreAxes,
        Self::FitnessOptimum,
        Self::SemiAxes,
        Self::SurfaceError,
        Self::SurfaceErrorSameEntity,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Self::FitnessAtCoreAxes => "fitness_at_core_axes",
            Self::FitnessOptimum => "fitness_optimum",
            Self::SemiAxes => "semi_axes",
            Self::SurfaceError => "surface_error",
            Self::SurfaceErrorSameEntity => "surface_error_same_entity",
        }
    }

    /// Whether a deviation is within this quantity's tolerance (with its floor, and only for
    /// determined clusters where the quantity depends on the DE's end point).
    pub fn accepts(self, d: &Deviation) -> bool {
        let delta = (d.core - d.reference).abs();
        match self {
            Self::FitnessAtCoreAxes => {
                d.relative <= self.tolerance() || delta <= FITNESS_ABSOLUTE_FLOOR
            }
            Self::SurfaceErrorSameEntity => {
                d.relative <= self.tolerance() || delta <= SOLVER_ABSOLUTE_FLOOR
            }
            Self::FitnessOptimum => d.cluster_points < MIN_POINTS || d.relative <= self.tolerance(),
            // At a flat optimum the objective cannot tell the fits apart, whatever their axes:
            // even whether a long axis is past the degeneration threshold (a street's strip of
            // 11,443 points in the Ouster sweeps: one fit's axis just under it, the other's
            // just over, both at the optimum's eq. 12 value within its tolerance).
            Self::SemiAxes | Self::SurfaceError => {
                d.cluster_points < MIN_POINTS || d.relative <= self.tolerance() || d.flat
            }
        }
    }

    /// Whether the deviation counts towards the reported worst case.
    pub fn counts(self, d: &Deviation) -> bool {
        match self {
            Self::FitnessAtCoreAxes | Self::SurfaceErrorSameEntity => true,
            // A flat optimum's semi-axes are judged on the objective (column `flat`).
            _ => d.cluster_points >= MIN_POINTS && !(d.flat && d.relative > self.tolerance()),
        }
    }

    pub fn tolerance(self) -> f64 {
        match self {
            Self::FitnessAtCoreAxes | Self::FitnessOptimum => FITNESS_TOLERANCE,
            Self::SemiAxes => SEMI_AXES_TOLERANCE,
            Self::SurfaceError => ERROR_TOLERANCE,
            Self::SurfaceErrorSameEntity => SOLVER_TOLERANCE,
        }
    }
}

/// One deviation: which entity, both values, and their relative difference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Deviation {
    pub quantity: Quantity,
    pub entity: usize,
    /// Points in that entity's cluster.
    pub cluster_points: usize,
    pub core: f64,
    pub reference: f64,
    pub relative: f64,
    /// The optimum is flat here: the reference's own eq. 12 (direct sum) at the core's semi-axes
    /// and at its own agree within [`FITNESS_TOLERANCE`], so the two end points are equally good
    /// and their distance measures the optimum's flatness, not an error. Semi-axes and eq. 13
    /// are then judged by that objective comparison instead (and counted in `flat`).
    pub flat: bool,
}

/// The entities beyond tolerance, and the worst deviation among them.
#[derive(Clone, Debug, PartialEq)]
pub struct Diff {
    pub over: Vec<Deviation>,
    pub worst: Deviation,
}

/// One cloud's comparison: the worst deviation per quantity, and the diff if any.
#[derive(Clone, Debug, PartialEq)]
pub struct CloudComparison {
    pub cloud: String,
    pub points: usize,
    pub clusters: usize,
    /// Clusters under [`MIN_POINTS`]: compared on fitness at the same axes and on the solvers only.
    pub small_clusters: usize,
    /// Determined clusters whose semi-axes or eq. 13 differ beyond tolerance at a flat optimum
    /// (see [`Deviation::flat`]), accepted on the objective.
    pub flat: usize,
    pub worst: Vec<Deviation>,
    pub diff: Option<Diff>,
}

fn relative(core: f64, reference: f64) -> f64 {
    if core == reference {
        0.0
    } else {
        (core - reference).abs() / reference.abs().max(f64::MIN_POSITIVE)
    }
}

/// What a comparison runs: the streaming map's `k`, the seed, and how many significant bits the
/// core's moment sums keep between updates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setup {
    pub k: usize,
    pub seed: u64,
    /// 53 is the f64 the core stores. Fewer rounds the sums after every point, as a narrower
    /// store would: the price of a compact cluster in agreement, measured before building one.
    pub sum_bits: u32,
    /// Working clusters of the streaming map (the rest of `k` frozen); `k` keeps all working.
    pub working: usize,
}

impl Setup {
    pub const F64_SUM_BITS: u32 = 53;

    pub fn new(k: usize, seed: u64) -> Self {
        Self {
            k,
            seed,
            sum_bits: Self::F64_SUM_BITS,
            working: k,
        }
    }
}

/// Compares every cluster of `points` (local-frame f32, as mapped).
pub fn compare_points(name: &str, points: &[Point3], setup: &Setup) -> CloudComparison {
    let Setup { k, seed, .. } = *setup;
    let working = setup.working.clamp(1, k.max(1));
    let params = FitParams::default();
    let mut mapper: Box<StreamMapper<1024, 2048, 1024>> =
        Box::new(StreamMapper::new(StreamParams {
            fit: params,
            seed,
            max_clusters: working.min(1024),
            max_frozen: k.saturating_sub(working).min(1024),
            refit_interval: 0,
            tolerance: 0.0,
            model: mema_core::stream::StreamModel::Paper,
            // The fits are compared here, not the device's timing: every cluster as k-means
            // would make it, never a paced join.
            pacing: mema_core::stream::Pacing::NONE,
            final_clusters: 0,
        }));
    mapper.add_all(points);
    mapper.finish();
    let centres: Vec<Vector3<f64>> = mapper
        .entities()
        .map(|e| e.entity.center)
        .map(|c| Vector3::new(c.x as f64, c.y as f64, c.z as f64))
        .collect();
    let mut members: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); centres.len()];
    for p in points.iter().filter(|p| p.is_finite()) {
        let v = Vector3::new(p.x as f64, p.y as f64, p.z as f64);
        let nearest = (0..centres.len()).min_by(|&a, &b| {
            (v - centres[a])
                .norm_squared()
                .total_cmp(&(v - centres[b]).norm_squared())
        });
        if let Some(i) = nearest {
            members[i].push(v);
        }
    }
    let deviations: Vec<Vec<Deviation>> = members
        .par_iter()
        .enumerate()
        .filter(|(_, m)| !m.is_empty())
        .map(|(i, m)| compare_cluster(i, m, &params, setup))
        .collect();
    let all: Vec<Deviation> = deviations.into_iter().flatten().collect();
    let worst: Vec<Deviation> = Quantity::ALL
        .iter()
        .filter_map(|&q| {
            all.iter()
                .filter(|d| d.quantity == q && q.counts(d))
                .max_by(|a, b| a.relative.total_cmp(&b.relative))
                .copied()
        })
        .collect();
    let over: Vec<Deviation> = all
        .iter()
        .filter(|d| !d.quantity.accepts(d))
        .copied()
        .collect();
    let diff = over
        .iter()
        .max_by(|a, b| {
            (a.relative / a.quantity.tolerance()).total_cmp(&(b.relative / b.quantity.tolerance()))
        })
        .copied()
        .map(|worst| Diff {
            over: over.clone(),
            worst,
        });
    CloudComparison {
        cloud: name.to_string(),
        points: points.len(),
        clusters: members.iter().filter(|m| !m.is_empty()).count(),
        small_clusters: members
            .iter()
            .filter(|m| !m.is_empty() && m.len() < MIN_POINTS)
            .count(),
        flat: {
            let mut flat: Vec<usize> = all
                .iter()
                .filter(|d| {
                    d.flat && d.cluster_points >= MIN_POINTS && d.relative > d.quantity.tolerance()
                })
                .map(|d| d.entity)
                .collect();
            flat.dedup();
            flat.len()
        },
        worst,
        diff,
    }
}

fn compare_cluster(
    i: usize,
    points: &[Vector3<f64>],
    params: &FitParams,
    setup: &Setup,
) -> Vec<Deviation> {
    let seed = setup.seed;
    let dev = |quantity, core: f64, reference: f64| Deviation {
        quantity,
        entity: i,
        cluster_points: points.len(),
        core,
        reference,
        relative: relative(core, reference),
        flat: false,
    };
    // The stream's integer sums, fed the f32 points as the mapper is; narrower f64 sums only
    // when `--sum-bits` asks what a cheaper store would lose.
    let central = if setup.sum_bits >= 53 {
        let mut moments = FixedMoments::new();
        for p in points {
            moments.add(Point3::new(p.x as f32, p.y as f32, p.z as f32));
        }
        moments.central()
    } else {
        let mut moments = Moments::new();
        for p in points {
            moments.add_f64([p.x, p.y, p.z]);
            moments = moments.with_significand_bits(setup.sum_bits);
        }
        moments.central()
    };
    let Some(central) = central else {
        return Vec::new();
    };
    let core = fit_ellipsoid_paper(&central, params, &mut stream_rng(seed, i as u64));
    let Some(reference) = reference::fit_cluster(points, params, &mut stream_rng(seed, i as u64))
    else {
        return Vec::new();
    };
    let Some(m) = reference::moments::direct_moments(points) else {
        return Vec::new();
    };
    let direct = reference::fitness::DirectFitness::new(points, &m, params.alpha);
    let at_core_axes = direct.eval(&Vector3::from(core.semi_axes));
    let flat = relative(at_core_axes, reference.fitness) <= FITNESS_TOLERANCE;
    let mut out = vec![
        dev(Quantity::FitnessAtCoreAxes, core.fitness, at_core_axes),
        dev(Quantity::FitnessOptimum, core.fitness, reference.fitness),
    ];
    // Semi-axes: the same degeneration kind, then each finite axis within tolerance.
    // The stored weights, as the core's eq. 13 reads them (f64 of the f32 `w`).
    let core_axes = core.entity.weights.map(|w| {
        if w > 0.0 {
            1.0 / f64::from(w).sqrt()
        } else {
            f64::INFINITY
        }
    });
    let kinds_agree = core.entity.degenerated_axes() == reference.degenerated_axes();
    let (worst_axis, c, r) = (0..3)
        .filter(|&j| reference.stored_axes[j].is_finite())
        .map(|j| {
            (
                relative(core.semi_axes[j], reference.semi_axes[j]),
                core.semi_axes[j],
                reference.semi_axes[j],
            )
        })
        .fold((0.0, 0.0, 0.0), |w, x| if x.0 > w.0 { x } else { w });
    out.push(if kinds_agree {
        Deviation {
            quantity: Quantity::SemiAxes,
            entity: i,
            cluster_points: points.len(),
            core: c,
            reference: r,
            relative: worst_axis,
            flat,
        }
    } else {
        Deviation {
            quantity: Quantity::SemiAxes,
            entity: i,
            cluster_points: points.len(),
            core: core.entity.degenerated_axes() as f64,
            reference: reference.degenerated_axes() as f64,
            relative: f64::INFINITY,
            flat,
        }
    });
    // Eq. 13 each side with its own fit; and both solvers on the core's stored entity.
    let centre = core.entity.center.to_f64();
    let mut core_error = SurfaceError::default();
    let (mut ref_sum, mut same_sum) = (0.0, 0.0);
    for p in points {
        core_error.add(&core.entity, [p.x, p.y, p.z]);
        let d = closest_point::distance(
            reference.stored_axes,
            [p.x - m.mean.x, p.y - m.mean.y, p.z - m.mean.z],
        );
        ref_sum += d * d;
        let e = closest_point::distance(
            core_axes,
            [p.x - centre[0], p.y - centre[1], p.z - centre[2]],
        );
        same_sum += e * e;
    }
    let n = points.len() as f64;
    out.push(Deviation {
        flat,
        ..dev(
            Quantity::SurfaceError,
            core_error.rmse(),
            (ref_sum / n).sqrt(),
        )
    });
    out.push(dev(
        Quantity::SurfaceErrorSameEntity,
        core_error.rmse(),
        (same_sum / n).sqrt(),
    ));
    out
}

/// Every file in the shared data directory (`../shared/data` beside the checkout).
pub fn shared_clouds() -> std::io::Result<Vec<PathBuf>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e != "md"))
        .collect();
    files.sort();
    Ok(files)
}

/// All clouds: those read, and those the host's readers do not read (with the reason).
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    pub setup: Setup,
    pub clouds: Vec<CloudComparison>,
    pub unread: Vec<(String, String)>,
}

pub fn compare_clouds(paths: &[PathBuf], setup: &Setup) -> Summary {
    let mut clouds = Vec::new();
    let mut unread = Vec::new();
    for path in paths {
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        match mema::io::load_cloud(path) {
            Ok(cloud) => clouds.push(compare_points(&name, &cloud.points, setup)),
            Err(e) => unread.push((name, format!("{e:#}"))),
        }
    }
    Summary {
        setup: *setup,
        clouds,
        unread,
    }
}

impl Summary {
    pub fn passed(&self) -> bool {
        !self.clouds.is_empty() && self.clouds.iter().all(|c| c.diff.is_none())
    }

    /// The worst deviation of each quantity over all clouds, with its cloud.
    pub fn worst(&self) -> Vec<(&str, Deviation)> {
        Quantity::ALL
            .iter()
            .filter_map(|&q| {
                self.clouds
                    .iter()
                    .flat_map(|c| c.worst.iter().map(move |d| (c.cloud.as_str(), *d)))
                    .filter(|(_, d)| d.quantity == q)
                    .max_by(|a, b| a.1.relative.total_cmp(&b.1.relative))
            })
            .collect()
    }

    pub fn text(&self) -> String {
        let mut s =
            String::from("core vs f64 reference (nalgebra), worst relative deviation per cloud\n");
        if self.setup.sum_bits < Setup::F64_SUM_BITS {
            s += &format!(
                "(the core's moment sums kept to {} significant bits after every point; f64 keeps 53)\n",
                self.setup.sum_bits
            );
        }
        s += &format!(
            "{:<22} {:>8} {:>5} {:>6} {:>5}",
            "cloud", "points", "k", "small", "flat"
        );
        for q in Quantity::ALL {
            s += &format!(" {:>26}", q.name());
        }
        s += "  verdict\n";
        for c in &self.clouds {
            s += &format!(
                "{:<22} {:>8} {:>5} {:>6} {:>5}",
                c.cloud, c.points, c.clusters, c.small_clusters, c.flat
            );
            for q in Quantity::ALL {
                let w = c
                    .worst
                    .iter()
                    .find(|d| d.quantity == q)
                    .map_or(0.0, |d| d.relative);
                s += &format!(" {:>26.2e}", w);
            }
            s += match &c.diff {
                None => "  ok\n".to_string(),
                Some(d) => format!(
                    "  {} over; worst {} entity {} ({} points): core {} vs reference {}\n",
                    d.over.len(),
                    d.worst.quantity.name(),
                    d.worst.entity,
                    d.worst.cluster_points,
                    d.worst.core,
                    d.worst.reference
                ),
            }
            .as_str();
        }
        for (name, why) in &self.unread {
            s += &format!("{name:<22} not read: {why}\n");
        }
        s += "tolerances (relative):";
        for q in Quantity::ALL {
            s += &format!(" {} {:e};", q.name(), q.tolerance());
        }
        s += &format!(
            "\n  floors: fitness at the same axes {FITNESS_ABSOLUTE_FLOOR:e} absolute, solvers {SOLVER_ABSOLUTE_FLOOR:e} absolute; \
             optimum, semi-axes and eq. 13 on clusters of >= {MIN_POINTS} points (column 'small': fewer);\n  \
             flat optima (column 'flat'): semi-axes or eq. 13 beyond tolerance where the reference's own eq. 12 \
             at the core's semi-axes is within {FITNESS_TOLERANCE:e} of its optimum, judged on that objective"
        );
        s += "\nworst overall:";
        for (cloud, d) in self.worst() {
            s += &format!(
                "\n  {:<26} {:.2e} ({cloud}, entity {})",
                d.quantity.name(),
                d.relative,
                d.entity
            );
        }
        s + "\n"
    }

    pub fn json(&self) -> String {
        let clouds: Vec<String> = self
            .clouds
            .iter()
            .map(|c| {
                let worst: Vec<String> = c
                    .worst
                    .iter()
                    .map(|d| format!("\"{}\":{{\"relative\":{:e},\"entity\":{}}}", d.quantity.name(), finite(d.relative), d.entity))
                    .collect();
                format!(
                    "{{\"cloud\":\"{}\",\"points\":{},\"clusters\":{},\"small_clusters\":{},\"flat\":{},\"over\":{},\"worst\":{{{}}}}}",
                    c.cloud,
                    c.points,
                    c.clusters,
                    c.small_clusters,
                    c.flat,
                    c.diff.as_ref().map_or(0, |d| d.over.len()),
                    worst.join(",")
                )
            })
            .collect();
        let unread: Vec<String> = self
            .unread
            .iter()
            .map(|(n, _)| format!("\"{n}\""))
            .collect();
        format!(
            "{{\"passed\":{},\"sum_bits\":{},\"clouds\":[{}],\"unread\":[{}]}}",
            self.passed(),
            self.setup.sum_bits,
            clouds.join(","),
            unread.join(",")
        )
    }
}

/// JSON has no infinity: a kind mismatch is written as 1e308.
fn finite(x: f64) -> f64 {
    if x.is_finite() { x } else { 1e308 }
}
