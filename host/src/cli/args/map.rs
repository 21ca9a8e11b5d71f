//! `map`, `eval`, `info`, `demo` and `ablation`.

use clap::{Args, ValueEnum};
use mema::mapping::{EntityChoice, Model};
use std::path::PathBuf;

use super::{FitArgs, UnitsArg};

/// `--model`: [`Model`] for the command line (its help text is the variants' docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ModelArg {
    /// The paper: axis-aligned semi-axes fitted by DE on eq. 12 (and a sphere beside it).
    Paper,
    /// Oriented shells of the clusters' covariances, quantized (`crate::shells`).
    Shells,
}

impl From<ModelArg> for Model {
    fn from(m: ModelArg) -> Self {
        match m {
            ModelArg::Paper => Model::Paper,
            ModelArg::Shells => Model::Shells,
        }
    }
}

/// `--entity`: [`EntityChoice`] for the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum EntityArg {
    Ellipsoid,
    Sphere,
}

impl From<EntityArg> for EntityChoice {
    fn from(e: EntityArg) -> Self {
        match e {
            EntityArg::Ellipsoid => EntityChoice::Ellipsoid,
            EntityArg::Sphere => EntityChoice::Sphere,
        }
    }
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
    #[arg(long, value_enum, default_value_t = ModelArg::Shells)]
    pub model: ModelArg,
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
    #[arg(long, value_name = "N", default_value_t = mema::mapping::surface_clusters::DEFAULT_ROUNDS)]
    pub surface_rounds: usize,
    /// The paper's method exactly: axis-aligned entities fitted by DE on eq. 12 (F 1.2, CR 0.7,
    /// 10 x 50, alpha 0.8), Tables 2 and 4 with the spherical comparison. Same as --model paper.
    #[arg(long)]
    pub paper: bool,
    /// Instead of k: split clusters until each one's eq. 13 error is at most T (metres),
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
    #[arg(long, value_enum, default_value_t = EntityArg::Ellipsoid)]
    pub entity: EntityArg,
    #[command(flatten)]
    pub fit: FitArgs,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Keep only the points inside this box, in metres in the file's frame (PCL's CropBox).
    #[arg(
        long,
        value_name = "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX",
        allow_hyphen_values = true
    )]
    pub crop: Option<mema::mapping::filter::CropBox>,
    /// Voxel-grid downsampling after the crop: one centroid per occupied cube of this edge
    /// (metres).
    #[arg(long, value_name = "SIZE")]
    pub voxel: Option<f64>,
    /// Map with the streaming mapper instead, exactly as `mema stream` maps what
    /// `mema scanner-sim` sends of the same file (the same bytes, so the same map): each scan
    /// of a .conf in its sensor frame after its pose, in the unit scanner-sim picks.
    #[arg(long, conflicts_with_all = ["tolerance", "bytes", "crop", "voxel", "labels"])]
    pub stream: bool,
    /// With --stream: at most W clusters in working memory, the rest frozen (as `stream`).
    #[arg(long, value_name = "W", requires = "stream")]
    pub working: Option<usize>,
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
    #[arg(long, default_value_t = mema::analysis::fidelity::DEFAULT_SAMPLES)]
    pub samples: usize,
    /// Seed of the surface samples.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub units: UnitsArg,
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
    #[command(flatten)]
    pub units: UnitsArg,
    #[arg(long)]
    pub json: bool,
}
