//! The `mema` host library: readers for real point clouds, the batch pipeline, map files,
//! evaluation and the command line.
pub mod ablation;
pub mod bench;
pub mod cli;
pub mod commands;
pub mod draw;
pub mod eval;
pub mod export;
pub mod fidelity;
pub mod filter;
pub mod heap;
pub mod mapfile;
pub mod pipeline;
pub mod progress;
pub mod query;
pub mod read;
pub mod scene;
pub mod serial;
pub mod shells;
pub mod stats;
pub mod stream_bench;
pub mod surface_clusters;
pub mod tolerance;
pub mod toolbox;
