//! `stream`, `record`, `replay`, `scanner-sim` and `stream-bench`: the rangefinder link.

use clap::Args;
use std::path::PathBuf;

use super::{BagArg, FitArgs, ModelArg, UnitsArg};

#[derive(Args, Debug)]
pub struct StreamArgs {
    /// Serial device or pty, e.g. /dev/ttyUSB0.
    #[arg(long)]
    pub port: PathBuf,
    /// Line speed in bits per second (a pty ignores it).
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
    /// End the stream when no frame has arrived for this many seconds (a lost end-of-stream
    /// frame, a sender that hung): the map of what arrived is written, exit status 4.
    #[arg(long, value_name = "SECONDS")]
    pub idle_timeout: Option<f64>,
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
    #[arg(long, value_enum, default_value_t = ModelArg::Shells)]
    pub model: ModelArg,
    /// Keep at most W clusters in working memory and freeze the rest into fitted entities once
    /// the scan has left them (W <= k): a device's memory for k ellipsoids (docs/streaming.md).
    #[arg(long, value_name = "W")]
    pub working: Option<usize>,
    /// Tolerance mode: merges keep each cluster's estimated eq. 13 error at or under T, and
    /// k follows from T, in metres (-k is then the capacity).
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Carve: a cluster that two later scans saw through, none of their points reaching it,
    /// leaves the map (a person who walked on, a ghost of a bad frame). Scans are the runs of
    /// frames under one pose; a single scan carves nothing.
    #[arg(long)]
    pub free_space: bool,
    /// Carve as --free-space does, with range images of ROWS x COLUMNS pixels around the whole
    /// sphere, and keep no free space in the map: a device's carving, whose map this replays
    /// (the STM32F405 board carves with 124x512). With --free-space, its images' size (512x1024
    /// by default; at most 524,288 pixels).
    #[arg(long, value_name = "ROWSxCOLUMNS", value_parser = parse_carve_image)]
    pub carve: Option<[u16; 2]>,
    /// With --carve or --free-space: the images take only every Nth return of a scan (its
    /// first, then each Nth after), as a device short of time carves (the STM32F405 board: 2).
    #[arg(long, value_name = "N", default_value_t = 1,
          value_parser = clap::value_parser!(u16).range(1..))]
    pub carve_every: u16,
    /// Refuse points and poses farther than this from the map's origin (its first point) on
    /// any axis, in metres: a corrupt frame that passed its CRC, or a wrong unit, is counted
    /// and never mapped. 100 km by default, where f32 still resolves 4 mm.
    #[arg(long, value_name = "METRES", default_value_t = mema_core::link::receiver::DEFAULT_REACH)]
    pub reach: f32,
}

#[derive(Args, Debug)]
pub struct RecordArgs {
    /// Serial device or pty to listen on, e.g. /dev/ttyUSB0.
    #[arg(long)]
    pub port: PathBuf,
    /// Line speed in bits per second (a pty ignores it).
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// The capture file: every byte received, as it arrived.
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(Args, Debug)]
pub struct ReplayArgs {
    /// A capture file (`mema record`, `stream --record` or `scanner-sim` to a file), or a ROS
    /// 2 bag (.mcap), whose PointCloud2 messages are sent as `scanner-sim` sends scans
    /// (--topic, --frame).
    pub capture: PathBuf,
    /// Most ellipsoids the map may hold (at most 2,048).
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
    pub bag: BagArg,
    #[command(flatten)]
    pub shape: StreamShapeArgs,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Print the summary as JSON on stdout (instead of the map path).
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct ScannerSimArgs {
    /// Serial device or pty to write to; a path that is not a device becomes a capture file.
    #[arg(long)]
    pub port: PathBuf,
    /// The cloud to play (PLY, PCD, LAS/LAZ, XYZ/CSV), in its file's frame, or a ROS 2 bag's
    /// PointCloud2 messages (--topic; with --frame each one in its sensor frame after its
    /// pose, as `replay BAG` sends them); default: a robot
    /// driving through the built-in demo scene, its rangefinder's scan at each of eight stops
    /// sent in the sensor's frame after the stop's pose.
    pub cloud: Option<PathBuf>,
    /// Play the scans of a registration file (`bmesh FILE tx ty tz qx qy qz qw` lines, as
    /// Stanford's bun.conf): each in its own sensor frame after its pose frame.
    #[arg(long, value_name = "SCANS.conf", conflicts_with = "cloud")]
    pub conf: Option<PathBuf>,
    /// The built-in drive in a walled room while someone walks across the robot's line of
    /// sight: what carving (`--free-space`, `--carve`) takes out of the map again.
    #[arg(long, conflicts_with_all = ["cloud", "conf"])]
    pub walker: bool,
    /// Points per second (default: as fast as the port takes them).
    #[arg(long)]
    pub rate: Option<f64>,
    /// Bytes per write.
    #[arg(long, default_value_t = 256)]
    pub chunk_bytes: usize,
    /// Line speed in bits per second (a pty or a file ignores it).
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    #[command(flatten)]
    pub units: UnitsArg,
    #[command(flatten)]
    pub bag: BagArg,
}

#[derive(Args, Debug)]
pub struct StreamBenchArgs {
    /// The cloud to stream (any format `map` reads, a ROS 2 bag included).
    pub input: PathBuf,
    /// Most ellipsoids the streaming map may hold (at most 2,048).
    #[arg(short)]
    pub k: usize,
    /// Timed repetitions of the ingest (the best is reported).
    #[arg(long, default_value_t = 3)]
    pub repetitions: usize,
    #[command(flatten)]
    pub shape: StreamShapeArgs,
    #[command(flatten)]
    pub units: UnitsArg,
    #[command(flatten)]
    pub bag: BagArg,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Print one JSON object instead of the text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct DeviceArgs {
    /// The device's serial port or pty (a board, or the board image under QEMU).
    #[arg(long, required_unless_present = "listen")]
    pub port: Option<PathBuf>,
    /// Receive the map of a sensor wired to the device, on its map's own line (the board's
    /// USART2), sending no stream: only requests for what was lost on the way.
    #[arg(long, value_name = "PORT", conflicts_with_all = ["port", "input"])]
    pub listen: Option<PathBuf>,
    /// Line speed in bits per second (a pty ignores it).
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// What to send: a capture (`mema record`, `scanner-sim` to a file; it starts with the
    /// protocol's 0x00), or a cloud, a ROS 2 bag (--topic, --frame) or a registration file
    /// (.conf), encoded as `mema scanner-sim` encodes them.
    #[arg(required_unless_present = "listen")]
    pub input: Option<PathBuf>,
    /// The map the device sends back, written atomically once it is whole and checked.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub bag: BagArg,
    /// After the map, ask the device this many questions of it (nearest surface and ray cast,
    /// alternately, near its entities), check each answer against the host's and report what
    /// one costs the device.
    #[arg(long, default_value_t = 0)]
    pub queries: u32,
    /// Give up when the device has said nothing new (an acknowledgement, an entity, its end;
    /// with --listen, any frame) for this many seconds: exit status 1, no map written.
    #[arg(long, value_name = "SECONDS", default_value_t = 30.0)]
    pub idle_timeout: f64,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `ROWSxCOLUMNS`, each at least 1, at most the host carver's pixels in all.
fn parse_carve_image(text: &str) -> Result<[u16; 2], String> {
    let parsed = text
        .split_once(['x', 'X'])
        .and_then(|(r, c)| Some([r.trim().parse::<u16>().ok()?, c.trim().parse::<u16>().ok()?]));
    let [max_rows, max_columns] = mema::link::carving::CARVE_IMAGE;
    let most = usize::from(max_rows) * usize::from(max_columns);
    match parsed {
        Some([rows, columns])
            if rows > 0 && columns > 0 && usize::from(rows) * usize::from(columns) <= most =>
        {
            Ok([rows, columns])
        }
        _ => Err(format!(
            "'{text}' is not ROWSxCOLUMNS with each at least 1 and at most {most} pixels in all \
             (e.g. 128x512)"
        )),
    }
}
