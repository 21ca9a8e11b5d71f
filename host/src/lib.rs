//! The `mema` host library: readers for real point clouds, map files, evaluation and the CLI.
pub mod read;
