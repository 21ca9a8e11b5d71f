//! `query`, `transform`, `query-bench`, `draw`, `export`, `completions` and `bench`.

use clap::{Args, ValueEnum};
use mema::bench::{BenchOptions, Which};
use mema::render::draw::{Style, Up, View};
use mema::render::picture::Size;
use std::path::PathBuf;

use super::UnitsArg;

#[derive(Args, Debug)]
pub struct QueryArgs {
    /// The map to ask: .mema, .csv or .json.
    pub map: PathBuf,
    /// x,y,z in the map's world coordinates (metres).
    #[arg(long, allow_hyphen_values = true)]
    pub point: Option<String>,
    /// ox,oy,oz,dx,dy,dz: origin (metres) and direction (any length).
    #[arg(long, allow_hyphen_values = true)]
    pub ray: Option<String>,
    /// A cloud file (any format `mema map` reads, or x,y,z CSV) of points to ask, in the map's
    /// world coordinates: one answer a point, its state (free, occupied, unknown) and signed
    /// distance, as CSV lines (or JSON lines with --json).
    #[arg(long, value_name = "FILE")]
    pub points: Option<PathBuf>,
    /// How near a surface (metres) a point is occupied.
    #[arg(long, value_name = "METRES", default_value_t = 0.1)]
    pub tolerance: f64,
    /// How far a ray looks (metres).
    #[arg(long, default_value_t = 1e6)]
    pub max_range: f64,
    /// Print each answer as one JSON object per line.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct TransformArgs {
    /// The map to move: .mema, .csv or .json.
    pub map: PathBuf,
    /// The moved map: .mema, .csv or .json (written atomically).
    #[arg(short, long)]
    pub output: PathBuf,
    /// tx,ty,tz in metres, applied after the rotation.
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
    /// Print one JSON object instead of the text.
    #[arg(long)]
    pub json: bool,
}

/// `--view`: [`View`] for the command line (its help text is the variants' docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ViewArg {
    /// Along (-1, 1, -1): x and y recede to the right and left, z up.
    Iso,
    /// Down the z axis: x right, y up.
    Top,
    /// Along +y: x right, z up.
    Front,
    /// Along -x: y right, z up.
    Side,
    /// Along a camera's axis, +z from its origin: x right, y down (a depth camera's frame), or
    /// the --up axis up.
    Sensor,
    /// Along a z-up lidar's horizon, +x (its forward, as ROS's REP 103 has it): y to the left,
    /// z up.
    Horizon,
}

/// `--up`: [`Up`] for the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum UpArg {
    /// x up.
    X,
    /// y up (meshes such as the Stanford bunny, y-up camera frames).
    Y,
    /// z up (most scans and lidar).
    Z,
}

impl From<UpArg> for Up {
    fn from(u: UpArg) -> Self {
        match u {
            UpArg::X => Up::X,
            UpArg::Y => Up::Y,
            UpArg::Z => Up::Z,
        }
    }
}

/// `--style`: [`Style`] for the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum StyleArg {
    /// Lambert-shaded solids in the kind's colour.
    Shaded,
    /// Silhouettes only, over the points.
    Outline,
}

impl From<ViewArg> for View {
    fn from(v: ViewArg) -> Self {
        match v {
            ViewArg::Iso => View::Iso,
            ViewArg::Top => View::Top,
            ViewArg::Front => View::Front,
            ViewArg::Side => View::Side,
            ViewArg::Sensor => View::Sensor,
            ViewArg::Horizon => View::Horizon,
        }
    }
}

impl From<StyleArg> for Style {
    fn from(s: StyleArg) -> Self {
        match s {
            StyleArg::Shaded => Style::Shaded,
            StyleArg::Outline => Style::Outline,
        }
    }
}

#[derive(Args, Debug)]
pub struct DrawArgs {
    /// The cloud the map was made from (any format `map` reads; `-` reads standard input).
    pub input: PathBuf,
    /// The map to draw over the cloud: .mema, .csv or .json.
    pub map: PathBuf,
    /// The picture to write (.png).
    #[arg(short, long)]
    pub output: PathBuf,
    /// The direction the picture looks along; the views name a z-up world, turned by --up.
    #[arg(long, value_enum, default_value_t = ViewArg::Iso)]
    pub view: ViewArg,
    /// The world axis that points up in the picture [default: z; for --view sensor, the
    /// sensor's -y, as camera frames point y down].
    #[arg(long, value_enum)]
    pub up: Option<UpArg>,
    /// Picture size in pixels; with --compare, the two panels share it side by side.
    #[arg(long, default_value = "1200x900")]
    pub size: Size,
    /// How entities are drawn.
    #[arg(long, value_enum, default_value_t = StyleArg::Shaded)]
    pub style: StyleArg,
    /// A second map drawn beside the first on the same scale (the paper's Figure 12:
    /// `mema map --entity sphere` writes the spherical one).
    #[arg(long, value_name = "MAP")]
    pub compare: Option<PathBuf>,
    /// Draw only the points within --radius of this world point (metres) and the entities
    /// centred there, framed to them: a lidar sweep's street rather than its farthest strays.
    #[arg(
        long,
        value_name = "X,Y,Z",
        requires = "radius",
        allow_hyphen_values = true
    )]
    pub around: Option<String>,
    /// The radius of --around, in metres.
    #[arg(long, value_name = "R", requires = "around")]
    pub radius: Option<f64>,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print the picture's geometry (frames, legends) as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// The map to mesh: .mema, .csv or .json.
    pub map: PathBuf,
    /// The mesh to write: .ply, .obj or .glb.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Clip degenerated entities to this cloud's bounding box (default: the map's own extent).
    #[arg(long, value_name = "CLOUD")]
    pub cloud: Option<PathBuf>,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Vertices around each ellipsoid and tube.
    #[arg(long, default_value_t = 24)]
    pub segments: u32,
    /// Latitude bands of each ellipsoid.
    #[arg(long, default_value_t = 12)]
    pub rings: u32,
    /// The most bytes the mesh may take. Its size is counted from the map before any work
    /// (PLY: 27 bytes a vertex and 13 a triangle; glTF: 12 and 12; OBJ: at most 101 and 35),
    /// and a larger mesh is refused, naming the --segments and --rings that fit.
    #[arg(long, value_name = "BYTES", default_value_t = mema::render::export::DEFAULT_MAX_BYTES)]
    pub max_bytes: u64,
    /// Print one JSON object instead of the text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct CompletionsArgs {
    /// The shell to print the script for.
    pub shell: clap_complete::Shell,
}

#[derive(Args, Debug)]
pub struct ManArgs {
    /// Write one page per command here (mema.1, mema-map.1, ...) instead of printing the
    /// main page; the directory must exist.
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
}

/// `--only`: [`Which`] for the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum WhichArg {
    /// Eq. 12 from moments against the direct sum over points, and the f32 fit against f64.
    Fitness,
    /// Accelerated k-means against the plain algorithm.
    Kmeans,
    /// The whole map command per cloud: time and peak memory, on 1 and 2 threads.
    Pipeline,
    /// The same steps in Python (numpy and scikit-learn), with --python.
    Python,
    /// Map fidelity at fixed byte budgets against a Gaussian mixture (about an hour).
    Fidelity,
    /// Held-out rays of the shared Ouster sweeps at mema's maps and OctoMap's at equal bytes
    /// (pyoctomap in --python).
    FreeSpace,
}

impl From<WhichArg> for Which {
    fn from(w: WhichArg) -> Self {
        match w {
            WhichArg::Fitness => Which::Fitness,
            WhichArg::Kmeans => Which::Kmeans,
            WhichArg::Pipeline => Which::Pipeline,
            WhichArg::Python => Which::Python,
            WhichArg::Fidelity => Which::Fidelity,
            WhichArg::FreeSpace => Which::FreeSpace,
        }
    }
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Directory holding the shared clouds.
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Benchmarks to run, comma-separated (default: fitness,kmeans,pipeline, plus python when
    /// --python is given; fidelity, which takes about an hour, only when named).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub only: Vec<WhichArg>,
    /// A Python with numpy and scikit-learn (scripts/bench.sh installs one) for benchmarks 4
    /// and 5.
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// Only these clouds, comma-separated file names (`environment` for the scene): the
    /// fidelity benchmark's of --data (default: every PLY, PCD, LAS and LAZ file there), the
    /// timing benchmarks' among their own cases (default: all of them).
    #[arg(long, value_delimiter = ',')]
    pub clouds: Vec<String>,
    /// Fidelity: map budgets in bytes, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = mema::bench::fidelity::DEFAULT_BUDGETS)]
    pub budgets: Vec<usize>,
    /// Fidelity: keep each GMM fit in this directory and reuse it for the same points and
    /// components (the fits take most of the run).
    #[arg(long, value_name = "DIR")]
    pub gmm_cache: Option<PathBuf>,
    /// Fidelity: print the results as one JSON object on stdout instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Iteration cap of the plain k-means on the environment case, and of the accelerated run
    /// it is compared with (uncapped, the plain run would take hours).
    #[arg(long, default_value_t = 3)]
    pub plain_cap: u32,
    /// Timed runs per measurement; the fastest is reported (the machine is shared).
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Internal: run one pipeline case (`NAME:K:THREADS`) in this process and print it as JSON.
    /// Each case runs in a fresh process so that its peak memory is its own.
    #[arg(long, hide = true)]
    pub case: Option<String>,
}

impl BenchArgs {
    /// The library's options.
    pub fn options(&self) -> BenchOptions {
        BenchOptions {
            data: self.data.clone(),
            only: self.only.iter().map(|&w| w.into()).collect(),
            python: self.python.clone(),
            clouds: self.clouds.clone(),
            budgets: self.budgets.clone(),
            gmm_cache: self.gmm_cache.clone(),
            json: self.json,
            plain_cap: self.plain_cap,
            repeat: self.repeat,
            case: self.case.clone(),
        }
    }
}
