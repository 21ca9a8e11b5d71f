//! Command-line arguments (what the user typed) and their validation into a pipeline config.

use crate::mapping::pipeline::{EntityChoice, PipelineConfig};
use clap::{Args, Parser, Subcommand, ValueEnum};
use mema_core::Degeneration;
use mema_core::de::{DeParams, OutOfBounds};
use mema_core::fit::{FitParams, Initialisation, SemiAxisBounds};
use mema_core::fitness::VolumeTerm;
use mema_core::kmeans::KMeansParams;
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(name = "mema", version, about = "Multiellipsoidal maps of 3D point clouds", long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Map a point cloud (PLY, PCD, LAS/LAZ, XYZ/CSV, KITTI .bin) with k ellipsoids and print Tables 2 and 4.
    Map(MapArgs),
    /// Evaluate any map against any cloud: eq. 13 statistics and memory.
    Eval(EvalArgs),
    /// Describe a map: entities per kind, bounds, bytes.
    Info(InfoArgs),
    /// Map the built-in scene (a simulated rangefinder scan); needs no files.
    Demo(DemoArgs),
    /// Measure the fit options the paper leaves open on one cloud (same clusters for all).
    Ablation(AblationArgs),
    /// Streaming mapper vs batch map on one cloud, and its ingest rate vs the SRI-500.
    StreamBench(StreamBenchArgs),
    /// Map points arriving from a serial rangefinder (PROTOCOL.md) until end of stream, Ctrl-C
    /// or the port vanishing; the map so far is always written. Exit 3: link lost before the
    /// end-of-stream frame.
    Stream(StreamArgs),
    /// Save a rangefinder's raw byte stream to a capture file.
    Record(RecordArgs),
    /// Feed a capture through the same decoder and mapper as `stream`.
    Replay(ReplayArgs),
    /// Play a cloud (or the built-in scene) as a rangefinder would, to a port or a capture file.
    ScannerSim(ScannerSimArgs),
    /// Ask a map: signed distance and occupancy at a point, first hit along a ray.
    Query(QueryArgs),
    /// Move a map rigidly (translation exact; rotations see README).
    Transform(TransformArgs),
    /// Queries per second with the index vs a brute-force scan; the demo scan re-cast at its map.
    QueryBench(QueryBenchArgs),
    /// Render a cloud and its map to PNG (headless): shaded entities by kind, legend, scale bar.
    Draw(crate::toolbox::DrawArgs),
    /// Tessellate a map's entities as a mesh: .ply, .obj or .glb (binary glTF).
    Export(crate::toolbox::ExportArgs),
    /// Print a shell completion script generated from these definitions.
    Completions(crate::toolbox::CompletionsArgs),
    /// Print the man page (roff) generated from these definitions.
    Man,
    /// Time the pipeline on the shared clouds against in-process baselines (README "Performance").
    Bench(crate::bench::BenchArgs),
}

#[derive(Args, Debug)]
pub struct QueryArgs {
    pub map: PathBuf,
    /// x,y,z in the map's world coordinates.
    #[arg(long, allow_hyphen_values = true)]
    pub point: Option<String>,
    /// ox,oy,oz,dx,dy,dz: origin and direction (any length).
    #[arg(long, allow_hyphen_values = true)]
    pub ray: Option<String>,
    #[arg(long, default_value_t = 1e6)]
    pub max_range: f64,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct TransformArgs {
    pub map: PathBuf,
    #[arg(short, long)]
    pub output: PathBuf,
    /// tx,ty,tz, applied after the rotation.
    #[arg(long, allow_hyphen_values = true)]
    pub translate: Option<String>,
    /// Degrees about x, then y, then z.
    #[arg(long, allow_hyphen_values = true)]
    pub rotate: Option<String>,
}

#[derive(Args, Debug)]
pub struct QueryBenchArgs {
    /// A map to query; default: the demo scene's map, with its scan re-cast against it.
    pub map: Option<PathBuf>,
    /// Entities of the demo map.
    #[arg(short, default_value_t = 250)]
    pub k: usize,
    /// Random points (each asked nearest and occupancy, and a ray from it).
    #[arg(long, default_value_t = 100_000)]
    pub queries: usize,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct StreamArgs {
    /// Serial device or pty, e.g. /dev/ttyUSB0.
    #[arg(long)]
    pub port: PathBuf,
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// Most ellipsoids the map may hold (at most 2,048).
    #[arg(short)]
    pub k: usize,
    /// Map file (.mema, .csv or .json), written atomically at each snapshot and at the end.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Write the map so far every this many seconds.
    #[arg(long)]
    pub snapshot_every: Option<f64>,
    #[command(flatten)]
    pub shape: StreamShapeArgs,
    /// Also save the raw bytes received, as `mema record` would.
    #[arg(long)]
    pub record: Option<PathBuf>,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Print the summary as JSON on stdout (instead of the map path).
    #[arg(long)]
    pub json: bool,
}

/// How a streaming mapper holds its k ellipsoids (`stream`, `replay`, `stream-bench`).
#[derive(Args, Debug)]
pub struct StreamShapeArgs {
    /// The entity model: `shells` (each cluster's oriented covariance shell, as `mema map`
    /// makes them; written quantized, 14 bytes an entity) or `paper` (the paper's axis-aligned
    /// DE fit of eq. 12, refitted as points arrive; written as version 1).
    #[arg(long, value_enum, default_value_t = crate::mapping::pipeline::Model::Shells)]
    pub model: crate::mapping::pipeline::Model,
    /// Keep at most W clusters in working memory and freeze the rest into fitted entities once
    /// the scan has left them (W <= k): a device's memory for k ellipsoids (README, "Streaming").
    #[arg(long, value_name = "W")]
    pub working: Option<usize>,
    /// Tolerance mode: merges keep each cluster's estimated eq. 13 error at or under T, and
    /// k follows from T (-k is then the capacity).
    #[arg(long)]
    pub tolerance: Option<f64>,
}

#[derive(Args, Debug)]
pub struct RecordArgs {
    #[arg(long)]
    pub port: PathBuf,
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(Args, Debug)]
pub struct ReplayArgs {
    pub capture: PathBuf,
    #[arg(short, default_value_t = 150)]
    pub k: usize,
    /// Map file; default: the capture's path with the extension .mema.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Deliver at most this many points per second (default: as fast as possible).
    #[arg(long)]
    pub rate: Option<f64>,
    /// Bytes per delivery, as a UART would hand them over.
    #[arg(long, default_value_t = 4096)]
    pub chunk_bytes: usize,
    #[command(flatten)]
    pub shape: StreamShapeArgs,
    #[command(flatten)]
    pub fit: FitArgs,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct ScannerSimArgs {
    /// Serial device or pty to write to; a path that is not a device becomes a capture file.
    #[arg(long)]
    pub port: PathBuf,
    /// The cloud to play (PLY, PCD, XYZ/CSV); default: the built-in demo scene's scan.
    pub cloud: Option<PathBuf>,
    /// Points per second (default: as fast as the port takes them).
    #[arg(long)]
    pub rate: Option<f64>,
    /// Bytes per write.
    #[arg(long, default_value_t = 256)]
    pub chunk_bytes: usize,
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
}

#[derive(Args, Debug)]
pub struct StreamBenchArgs {
    pub input: PathBuf,
    #[arg(short)]
    pub k: usize,
    /// Timed repetitions of the ingest (the best is reported).
    #[arg(long, default_value_t = 3)]
    pub repetitions: usize,
    #[command(flatten)]
    pub shape: StreamShapeArgs,
    #[command(flatten)]
    pub fit: FitArgs,
    #[arg(long)]
    pub json: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BoundsArg {
    /// r in [0.05 s, 3 s], s the cluster's RMS radius, searched linearly.
    Spread,
    /// r in [0.05 s, threshold], searched in ln r: axes can degenerate.
    Threshold,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OutOfBoundsArg {
    Clamp,
    Reflect,
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
    /// Weight of the residual term of eq. 12 (the paper: 0.8).
    #[arg(long, default_value_t = 0.8)]
    pub alpha: f64,
    /// Seed of k-means++ and DE; the same seed gives the same map bytes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Semi-axis length at which an axis degenerates (infinite); the paper: 4 m.
    #[arg(long, default_value_t = 4.0)]
    pub threshold: f64,
    /// Relative tolerance within which three semi-axes make a sphere.
    #[arg(long, default_value_t = 0.01)]
    pub sphere_tolerance: f64,
    #[arg(long, value_enum, default_value_t = BoundsArg::Spread)]
    pub bounds: BoundsArg,
    #[arg(long, value_enum, default_value_t = OutOfBoundsArg::Clamp)]
    pub out_of_bounds: OutOfBoundsArg,
    #[arg(long, value_enum, default_value_t = VolumeArg::Exact)]
    pub volume: VolumeArg,
    #[arg(long, value_enum, default_value_t = InitArg::Seeded)]
    pub init: InitArg,
    /// DE generations (the paper: 50).
    #[arg(long, default_value_t = 50)]
    pub generations: u32,
    /// Lloyd iteration cap.
    #[arg(long, default_value_t = 100)]
    pub max_iterations: u32,
}

#[derive(Args, Debug)]
pub struct MapArgs {
    pub input: PathBuf,
    /// Number of clusters (entities).
    #[arg(
        short,
        required_unless_present_any = ["tolerance", "bytes"],
        conflicts_with_all = ["tolerance", "bytes"]
    )]
    pub k: Option<usize>,
    /// Instead of k: as many entities as B bytes of map file hold, its header and checksum
    /// aside (14 bytes an entity for shells, 25 for the paper's entities).
    #[arg(long, value_name = "B", conflicts_with = "tolerance")]
    pub bytes: Option<usize>,
    /// The entity model: `shells` (oriented shells of each cluster's covariance, stored on a
    /// quantized grid) or `paper` (the paper's axis-aligned DE fit of eq. 12).
    #[arg(long, value_enum, default_value_t = crate::mapping::pipeline::Model::Shells)]
    pub model: crate::mapping::pipeline::Model,
    /// Shells: semi-axes along a cluster's two largest principal axes are this many standard
    /// deviations (the patch's extent).
    #[arg(long, default_value_t = mema_core::shell::ShellParams::default().tangent_scale)]
    pub tangent_scale: f64,
    /// Shells: the semi-axis along the smallest principal axis is this many standard
    /// deviations (the patch's thickness).
    #[arg(long, default_value_t = mema_core::shell::ShellParams::default().normal_scale)]
    pub normal_scale: f64,
    /// Shells: rounds of surface following after k-means, which moves each point to the
    /// neighbouring cluster whose Gaussian explains it best (stops early once at most one point
    /// in a thousand moves); 0 keeps the k-means cells.
    #[arg(long, value_name = "N", default_value_t = crate::mapping::surface_clusters::DEFAULT_ROUNDS)]
    pub surface_rounds: usize,
    /// The paper's method exactly: axis-aligned entities fitted by DE on eq. 12 (F 1.2, CR 0.7,
    /// 10 x 50, alpha 0.8), Tables 2 and 4 with the spherical comparison. Same as --model paper.
    #[arg(long)]
    pub paper: bool,
    /// Instead of k: split clusters until each one's eq. 13 error is at most T (cloud units),
    /// then merge neighbours that stay under T.
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Most clusters the tolerance mode may make.
    #[arg(long, default_value_t = 16_384)]
    pub capacity: usize,
    /// Tolerance mode: rounds of re-checking T with nearest-centre membership (as `mema eval`
    /// assigns points), splitting clusters that fail; costs entities.
    #[arg(long, default_value_t = 0)]
    pub voronoi_rounds: usize,
    /// Also write each point's cluster index, one per line, in the cloud's order of finite points.
    #[arg(long)]
    pub labels: Option<PathBuf>,
    /// Output map: .mema (binary), .csv or .json.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Which entity the written map holds; both are fitted and reported.
    #[arg(long, value_enum, default_value_t = EntityChoice::Ellipsoid)]
    pub entity: EntityChoice,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Keep only the points inside this box, in the file's coordinates (PCL's CropBox).
    #[arg(
        long,
        value_name = "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX",
        allow_hyphen_values = true
    )]
    pub crop: Option<crate::mapping::filter::CropBox>,
    /// Voxel-grid downsampling after the crop: one centroid per occupied cube of this edge.
    #[arg(long, value_name = "SIZE")]
    pub voxel: Option<f64>,
    /// Print one JSON object instead of the tables.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    pub input: PathBuf,
    pub map: PathBuf,
    /// Points drawn uniformly by area over the map's surface for completeness (at least 8 per
    /// entity whatever this says).
    #[arg(long, default_value_t = crate::analysis::fidelity::DEFAULT_SAMPLES)]
    pub samples: usize,
    /// Seed of the surface samples.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct InfoArgs {
    pub map: PathBuf,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct DemoArgs {
    #[arg(short, default_value_t = 250)]
    pub k: usize,
    #[arg(short, long, default_value = "mema-demo.mema")]
    pub output: PathBuf,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Map the scan with the paper's method (Tables 2 and 4 with the spherical comparison)
    /// instead of the default's oriented shells.
    #[arg(long)]
    pub paper: bool,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct AblationArgs {
    pub input: PathBuf,
    #[arg(short)]
    pub k: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[arg(long)]
    pub json: bool,
}

/// A value the user gave that cannot work; reported with exit status 2, like clap's own errors.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

impl FitArgs {
    /// Checks the values and builds the pipeline configuration.
    pub fn config(&self, k: usize) -> Result<PipelineConfig, UsageError> {
        if k == 0 {
            return Err(UsageError(
                "k must be at least 1; consider -k 150 (about one entity per 100 points)".into(),
            ));
        }
        if !(self.alpha >= 0.0 && self.alpha <= 1.0) {
            return Err(UsageError(format!(
                "--alpha {} is outside [0, 1]; the paper uses 0.8",
                self.alpha
            )));
        }
        if !(self.threshold > 0.0 && self.threshold.is_finite()) {
            return Err(UsageError(format!(
                "--threshold {} must be a positive length",
                self.threshold
            )));
        }
        if !(self.sphere_tolerance >= 0.0 && self.sphere_tolerance.is_finite()) {
            return Err(UsageError(format!(
                "--sphere-tolerance {} must be >= 0",
                self.sphere_tolerance
            )));
        }
        let degeneration = Degeneration {
            threshold: self.threshold,
            sphere_tolerance: self.sphere_tolerance,
        };
        let fit = FitParams {
            alpha: self.alpha,
            volume: match self.volume {
                VolumeArg::Exact => VolumeTerm::Exact,
                VolumeArg::Spread => VolumeTerm::SpreadRelative,
            },
            de: DeParams {
                generations: self.generations,
                ..DeParams::default()
            },
            bounds: match self.bounds {
                BoundsArg::Spread => SemiAxisBounds::Spread {
                    lower: 0.05,
                    upper: 3.0,
                },
                BoundsArg::Threshold => SemiAxisBounds::Threshold { lower: 0.05 },
            },
            out_of_bounds: match self.out_of_bounds {
                OutOfBoundsArg::Clamp => OutOfBounds::Clamp,
                OutOfBoundsArg::Reflect => OutOfBounds::Reflect,
                OutOfBoundsArg::Resample => OutOfBounds::Resample,
            },
            initialisation: match self.init {
                InitArg::Seeded => Initialisation::MomentSeeded,
                InitArg::Random => Initialisation::Random,
            },
            degeneration,
        };
        Ok(PipelineConfig {
            k,
            seed: self.seed,
            kmeans: KMeansParams {
                max_iterations: self.max_iterations,
                seed: self.seed,
                ..KMeansParams::default()
            },
            fit,
        })
    }
}

/// The fit options as their defaults, for commands that fit without exposing every flag.
pub fn default_fit_args() -> FitArgs {
    use clap::FromArgMatches;
    let command = FitArgs::augment_args(clap::Command::new("fit-defaults"));
    // Every fit option has a default, so an empty command line always parses (tested below).
    command
        .try_get_matches_from(["fit-defaults"])
        .ok()
        .and_then(|m| FitArgs::from_arg_matches(&m).ok())
        .expect("the fit options' defaults parse")
}

#[cfg(test)]
mod tests {
    #[test]
    fn fit_defaults_are_the_papers_settings() {
        let config = super::default_fit_args().config(10).expect("valid");
        assert_eq!(config.fit, mema_core::fit::FitParams::default());
        assert_eq!(config.kmeans.max_iterations, 100);
    }
}
