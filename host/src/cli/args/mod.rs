//! Command-line arguments: what the user typed, checked only for syntax. Each subcommand's
//! handler in [`super::commands`] turns them into the library's configuration.

pub mod fit;
pub mod link;
pub mod map;
pub mod tools;
pub mod units;

pub use fit::FitArgs;
pub use link::{
    RecordArgs, ReplayArgs, ScannerSimArgs, StreamArgs, StreamBenchArgs, StreamShapeArgs,
};
pub use map::{AblationArgs, DemoArgs, EntityArg, EvalArgs, InfoArgs, MapArgs, ModelArg};
pub use tools::{
    BenchArgs, CompletionsArgs, DrawArgs, ExportArgs, QueryArgs, QueryBenchArgs, TransformArgs,
};
pub use units::UnitsArg;

use clap::{Parser, Subcommand};

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
    Draw(DrawArgs),
    /// Tessellate a map's entities as a mesh: .ply, .obj or .glb (binary glTF).
    Export(ExportArgs),
    /// Print a shell completion script generated from these definitions.
    Completions(CompletionsArgs),
    /// Print the man page (roff) generated from these definitions.
    Man,
    /// Time the pipeline on the shared clouds against in-process baselines (README "Performance").
    Bench(BenchArgs),
}
