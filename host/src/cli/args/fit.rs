//! The fit options every fitting command shares, and their value enums: CLI mirrors of the
//! core's, so the library's types need no clap.

use clap::{Args, ValueEnum};
use mema::mapping::{FitOptions, PipelineConfig};
use mema_core::de::OutOfBounds;
use mema_core::fit::{Initialisation, SemiAxisBounds};
use mema_core::fitness::VolumeTerm;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BoundsArg {
    /// r in [0.05 s, 3 s], s the cluster's RMS radius, searched linearly.
    Spread,
    /// r in [0.05 s, threshold], searched in ln r: axes can degenerate.
    Threshold,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OutOfBoundsArg {
    /// Move it onto the bound it crossed.
    Clamp,
    /// Mirror it back inside across that bound.
    Reflect,
    /// Draw it again, uniformly inside the box.
    Resample,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum VolumeArg {
    /// Eq. 12 as printed: (4/3) pi r_x r_y r_z / |S_i|, in the cloud's units.
    Exact,
    /// Unit-free: r_x r_y r_z / s^3 with s the cluster's RMS radius.
    Spread,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum InitArg {
    /// One moment-derived candidate (least-squares ellipsoid or optimal sphere) among the random ones.
    Seeded,
    /// All candidates random, as in the paper.
    Random,
}

/// Options shared by every command that fits.
#[derive(Args, Debug, Clone)]
pub struct FitArgs {
    /// Weight of eq. 12's residual term (how far the points lie from the surface) against its
    /// volume term (how large the ellipsoid is); the paper: 0.8.
    #[arg(long, default_value_t = 0.8)]
    pub alpha: f64,
    /// Seed of k-means++ and DE; the same seed gives the same map bytes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Semi-axis length in metres at which an axis degenerates: it becomes infinite, and one
    /// such axis makes a pseudocylinder, two a pair of planes; the paper: 4 m.
    #[arg(long, default_value_t = 4.0)]
    pub threshold: f64,
    /// Relative tolerance within which three semi-axes make a sphere.
    #[arg(long, default_value_t = 0.01)]
    pub sphere_tolerance: f64,
    /// The box DE (Differential Evolution, the paper's search) searches each semi-axis in; s
    /// is the cluster's RMS radius (the RMS distance of its points from their mean).
    #[arg(long, value_enum, default_value_t = BoundsArg::Spread)]
    pub bounds: BoundsArg,
    /// What DE does with a candidate semi-axis outside that box.
    #[arg(long, value_enum, default_value_t = OutOfBoundsArg::Clamp)]
    pub out_of_bounds: OutOfBoundsArg,
    /// Eq. 12's volume term, which keeps an ellipsoid from swelling to hold every point.
    #[arg(long, value_enum, default_value_t = VolumeArg::Exact)]
    pub volume: VolumeArg,
    /// How DE's first population of candidate semi-axes is drawn.
    #[arg(long, value_enum, default_value_t = InitArg::Seeded)]
    pub init: InitArg,
    /// DE generations, rounds of mutating and selecting candidates (the paper: 50).
    #[arg(long, default_value_t = 50)]
    pub generations: u32,
    /// Lloyd iteration cap: k-means rounds of moving each point to its nearest centre and
    /// each centre to its points' mean.
    #[arg(long, default_value_t = 100)]
    pub max_iterations: u32,
}

impl From<BoundsArg> for SemiAxisBounds {
    fn from(b: BoundsArg) -> Self {
        match b {
            BoundsArg::Spread => SemiAxisBounds::Spread {
                lower: 0.05,
                upper: 3.0,
            },
            BoundsArg::Threshold => SemiAxisBounds::Threshold { lower: 0.05 },
        }
    }
}

impl From<OutOfBoundsArg> for OutOfBounds {
    fn from(o: OutOfBoundsArg) -> Self {
        match o {
            OutOfBoundsArg::Clamp => OutOfBounds::Clamp,
            OutOfBoundsArg::Reflect => OutOfBounds::Reflect,
            OutOfBoundsArg::Resample => OutOfBounds::Resample,
        }
    }
}

impl From<VolumeArg> for VolumeTerm {
    fn from(v: VolumeArg) -> Self {
        match v {
            VolumeArg::Exact => VolumeTerm::Exact,
            VolumeArg::Spread => VolumeTerm::SpreadRelative,
        }
    }
}

impl From<InitArg> for Initialisation {
    fn from(i: InitArg) -> Self {
        match i {
            InitArg::Seeded => Initialisation::MomentSeeded,
            InitArg::Random => Initialisation::Random,
        }
    }
}

impl FitArgs {
    /// The library's options, unchecked.
    pub fn options(&self) -> FitOptions {
        FitOptions {
            alpha: self.alpha,
            seed: self.seed,
            threshold: self.threshold,
            sphere_tolerance: self.sphere_tolerance,
            bounds: self.bounds.into(),
            out_of_bounds: self.out_of_bounds.into(),
            volume: self.volume.into(),
            initialisation: self.init.into(),
            generations: self.generations,
            max_iterations: self.max_iterations,
        }
    }

    /// Checks the values and builds the pipeline configuration for `k` clusters.
    pub fn config(&self, k: usize) -> Result<PipelineConfig, mema::ConfigError> {
        self.options().config(k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::FromArgMatches;

    /// The library's defaults are what an empty command line gives, so commands that fit
    /// without exposing every flag (and the tests) can use `FitOptions::default()`.
    #[test]
    fn the_flags_default_to_the_librarys_defaults() {
        let command = FitArgs::augment_args(clap::Command::new("fit-defaults"));
        let matches = command
            .try_get_matches_from(["fit-defaults"])
            .expect("every fit option has a default");
        let args = FitArgs::from_arg_matches(&matches).expect("parses");
        assert_eq!(args.options(), FitOptions::default());
    }
}
