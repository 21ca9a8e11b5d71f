//! Input and output: point clouds from files, map files, and the built-in demo scene.
pub mod mapfile;
pub mod read;
pub mod scene;
