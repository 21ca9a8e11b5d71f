//! Command-line arguments: what the user typed, checked only for syntax. Each subcommand's
//! handler in [`super::commands`] turns them into the library's configuration.

pub mod bag;
pub mod fit;
pub mod link;
pub mod map;
pub mod tools;
pub mod units;

pub use bag::BagArg;
pub use fit::FitArgs;
pub use link::{
    DeviceArgs, RecordArgs, ReplayArgs, ScannerSimArgs, StreamArgs, StreamBenchArgs,
    StreamShapeArgs,
};
pub use map::{AblationArgs, DemoArgs, EntityArg, EvalArgs, InfoArgs, MapArgs, ModelArg};
pub use tools::{
    BenchArgs, CompletionsArgs, DrawArgs, ExportArgs, ManArgs, QueryArgs, QueryBenchArgs,
    TransformArgs,
};
pub use units::UnitsArg;

use clap::{Parser, Subcommand};

/// The words the help texts use, defined once under `mema --help`.
const TERMS: &str = "\
Terms:
  cloud       3D points from a scanner (PLY, PCD, LAS/LAZ, XYZ/CSV, KITTI .bin, a ROS 2 bag's
              PointCloud2 messages), read in metres
  map         a few hundred entities standing for a cloud, in a .mema, .csv or .json file
  entity      one ellipsoid of the map, made from one cluster of the cloud's points; an axis
              past --threshold is infinite: one such axis gives a pseudocylinder, two a pair
              of planes
  shell       the default entity: a thin ellipsoid on a cluster's principal axes
  eq. 12      the paper's measure of how badly an ellipsoid fits its points (a residual and a
              volume term), minimised by Differential Evolution (DE) in --paper maps
  eq. 13      a cluster's error: the RMS distance from its points to its entity's surface (m)
  Table 2, 4  the paper's tables: the memory of cloud and map; eq. 13 over the clusters
  capture     the raw bytes a rangefinder sent over its serial link (PROTOCOL.md)

Start with `mema demo`.";

#[derive(Parser, Debug)]
#[command(
    name = "mema",
    version,
    propagate_version = true,
    about = "Multiellipsoidal maps of 3D point clouds",
    long_about = None,
    after_help = TERMS
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Map a point cloud with k entities; print the map's memory and error (Tables 2 and 4).
    ///
    /// Clusters the points (k-means, then surface following), makes one entity per cluster,
    /// writes the map and prints its memory beside the cloud's (the paper's Table 2) and each
    /// cluster's eq. 13 error, the RMS distance from its points to its entity's surface in
    /// metres (Table 4).
    Map(MapArgs),
    /// Score any map against any cloud: eq. 13, the two-way score and the bytes.
    ///
    /// Eq. 13: each point joins its nearest entity centre; a cluster's error is the RMS
    /// distance from its points to that entity's surface (m). The two-way score measures
    /// points to the map's nearest surface (accuracy) and the map's surface to the points
    /// (completeness).
    Eval(EvalArgs),
    /// Describe a map: entities per kind, bounds, bytes.
    Info(InfoArgs),
    /// Map a simulated scan of a built-in scene and explain the result; needs no files.
    ///
    /// Writes the scan, its map and a picture of both to --out-dir, and prints what to run
    /// next on them.
    Demo(DemoArgs),
    /// Measure the fit options the paper leaves open on one cloud (same clusters for all).
    Ablation(AblationArgs),
    /// Streaming mapper vs batch map on one cloud, and its ingest rate vs the SRI-500.
    ///
    /// The SRI-500 is the paper's scanner (800,000 points/s).
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
    /// Send points to a mapping device (a board running mema's firmware) and write the map it
    /// sends back, entity by entity, once it is whole and its CRC-32 agrees; or, with
    /// --listen, receive the map of a sensor wired to the device.
    Device(DeviceArgs),
    /// Ask a map: signed distance and occupancy at a point, first hit along a ray.
    Query(QueryArgs),
    /// Move a map rigidly: translation exact, a rotation turns each entity (docs/queries.md).
    Transform(TransformArgs),
    /// Queries per second with the index vs a brute-force scan; the demo scan re-cast at its map.
    QueryBench(QueryBenchArgs),
    /// Render a cloud and its map to PNG (headless): shaded entities by kind, legend, scale bar.
    Draw(DrawArgs),
    /// Tessellate a map's entities as a mesh: .ply, .obj or .glb (binary glTF).
    Export(ExportArgs),
    /// Print a shell completion script generated from these definitions.
    Completions(CompletionsArgs),
    /// Print the man page (roff), or write one page per command with --out-dir.
    Man(ManArgs),
    /// Time the pipeline on the shared clouds against in-process baselines (docs/performance.md).
    Bench(BenchArgs),
}

#[cfg(test)]
mod tests;
