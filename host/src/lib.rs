//! The `mema` host library: readers for real point clouds, the batch pipeline, map files,
//! evaluation and the command line.
pub mod analysis;
pub mod bench;
pub mod cli;
pub mod commands;
pub mod heap;
pub mod io;
pub mod link;
pub mod mapping;
pub mod progress;
pub mod query;
pub mod render;
pub mod toolbox;
