//! `map`, `eval`, `info`, `demo` and `ablation`.

use clap::{Args, ValueEnum};
use mema::mapping::{EntityChoice, Model};
use std::path::PathBuf;

use super::{BagArg, FitArgs, UnitsArg};

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
    /// Three semi-axes fitted independently (the paper's map).
    Ellipsoid,
    /// One radius (the paper's spherical comparison).
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
    /// The point cloud: PLY, PCD, LAS/LAZ, XYZ/CSV text or KITTI .bin, recognised by its
    /// content, a registration file (.conf) of several scans, or a ROS 2 bag (.mcap, or its
    /// rosbag2 directory) of PointCloud2 messages (--topic, --frame); `-` reads it from
    /// standard input (not a bag or a .conf).
    pub input: PathBuf,
    /// Number of clusters, each of which becomes one entity (an ellipsoid) of the map.
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
    /// Shells: keep the free space the input's scans saw through (inputs that say where their
    /// sensor was: a .conf, a bag, a PCD's VIEWPOINT, an organized frame): each scan's 8 x 64
    /// range image, within --bytes, so `mema query` tells free from unknown (docs/queries.md).
    #[arg(long)]
    pub free_space: bool,
    /// Shells: keep the shells as their clusters made them. By default, where the input says
    /// where its sensor was, each shell's axes, place along its normal and tilt are shaped so
    /// that the input's own rays meet the map where they ended, and the shaped map is kept if
    /// it scores no worse both ways against the points (docs/queries.md).
    #[arg(long)]
    pub no_ray_shaping: bool,
    /// The paper's method exactly: axis-aligned entities fitted by Differential Evolution (DE)
    /// on eq. 12, the paper's measure of how badly an ellipsoid fits its points (F 1.2, CR
    /// 0.7, 10 x 50, alpha 0.8), Tables 2 and 4 with the spherical comparison. Same as
    /// --model paper.
    #[arg(long)]
    pub paper: bool,
    /// Instead of k: split clusters until each one's eq. 13 error (the RMS distance from its
    /// points to its entity's surface) is at most T metres, then merge neighbours that stay
    /// under T.
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Tolerance mode: the most clusters it may make.
    #[arg(long, default_value_t = 16_384)]
    pub capacity: usize,
    /// Tolerance mode: rounds of re-checking T with nearest-centre membership (as `mema eval`
    /// assigns points), splitting clusters that fail; costs entities.
    #[arg(long, default_value_t = 0)]
    pub voronoi_rounds: usize,
    /// Also write each point's cluster index, one per line, in the cloud's order of finite points
    /// (less the isolated points --outliers drops).
    #[arg(long)]
    pub labels: Option<PathBuf>,
    /// Output map: .mema (binary), .csv or .json.
    #[arg(short, long)]
    pub output: PathBuf,
    /// With --paper: which entity the written map holds; both are fitted and reported.
    #[arg(long, value_enum, default_value_t = EntityArg::Ellipsoid)]
    pub entity: EntityArg,
    #[command(flatten)]
    pub fit: FitArgs,
    #[command(flatten)]
    pub units: UnitsArg,
    #[command(flatten)]
    pub bag: BagArg,
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
    /// Isolated points to drop from a cloud file before mapping: `K,RATIO` drops each point
    /// whose mean distance to its K nearest neighbours (PCL's and Open3D's statistic) is over
    /// RATIO times that distance's median over the cloud; `off` keeps them. Either way a
    /// cloud too wide for f32 at its point spacing is refused. Registrations and bags are read
    /// as they are.
    #[arg(long, value_name = "K,RATIO|off", default_value = "20,30", value_parser = parse_outliers)]
    pub outliers: mema::io::read::Outliers,
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
    /// The cloud to score the map against (any format `map` reads, a ROS 2 bag with --topic
    /// and --frame as `map` took it; `-` reads standard input).
    pub input: PathBuf,
    /// The map to score: .mema, .csv or .json.
    pub map: PathBuf,
    /// Points drawn uniformly by area over the map's surface for completeness (at least 8 per
    /// entity whatever this says).
    #[arg(long, default_value_t = mema::analysis::fidelity::DEFAULT_SAMPLES)]
    pub samples: usize,
    /// Seed of the surface samples.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Cast the cloud's points as held-out rays from their sensor origins (a .conf of frames
    /// with their poses, a frame that says where its sensor was) at the map instead: the
    /// fraction whose first hit agrees with the measured range, stops early or runs on, and
    /// the occupancy score of points sampled along them (docs/queries.md).
    #[arg(long)]
    pub rays: bool,
    /// With --rays: how far (metres) a first hit may fall from the measured range and agree,
    /// and how near map surface a sample is occupied.
    #[arg(long, value_name = "METRES", default_value_t = mema::query::held_out::DEFAULT_TOLERANCE, requires = "rays")]
    pub ray_tolerance: f64,
    #[command(flatten)]
    pub units: UnitsArg,
    #[command(flatten)]
    pub bag: BagArg,
    /// Print one JSON object instead of the tables (its keys: docs/command-line.md, "The commands").
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// The map to describe: .mema, .csv or .json.
    pub map: PathBuf,
    /// Print one JSON object instead of the text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Entities of the demo's map (one per cluster of the scan's points).
    #[arg(short, default_value_t = 250)]
    pub k: usize,
    /// Where the demo writes the scan (scan.ply), its map (map.mema) and a picture of both
    /// (picture.png); made if missing. Each file is written whole or not at all. [default:
    /// mema-demo, mema-demo-paper with --paper, mema-demo-moving with --moving]
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Map the scan with the paper's method (Tables 2 and 4 with the spherical comparison)
    /// instead of the default's oriented shells.
    #[arg(long)]
    pub paper: bool,
    /// A robot drives through the scene instead: its rangefinder scans at eight stops along an
    /// arc, each scan goes over the link's bytes in the sensor's frame after its pose (what
    /// `mema scanner-sim` sends), and the streaming mapper builds one map in the world frame.
    /// The scans' rays are then cast again at the map and at the scene.
    #[arg(long)]
    pub moving: bool,
    /// Print one JSON object (the map's report and the files written) instead of the text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct AblationArgs {
    /// The cloud to measure the fit options on (any format `map` reads).
    pub input: PathBuf,
    /// Number of clusters; every option is fitted to the same ones.
    #[arg(short)]
    pub k: usize,
    /// Seed of k-means++ and DE.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

fn parse_outliers(s: &str) -> Result<mema::io::read::Outliers, String> {
    s.parse()
}

impl DemoArgs {
    /// The demo's folder: `--out-dir`, else one per variant, so that running one variant
    /// after another leaves each one's files.
    pub fn out_dir(&self) -> PathBuf {
        self.out_dir.clone().unwrap_or_else(|| {
            PathBuf::from(if self.moving {
                "mema-demo-moving"
            } else if self.paper {
                "mema-demo-paper"
            } else {
                "mema-demo"
            })
        })
    }
}
