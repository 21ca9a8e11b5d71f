//! Input and output: point clouds from files, map files, and the built-in demo scene.
//!
//! Nothing here depends on the rest of the crate but [`crate::error`]: every other layer reads
//! and writes through it.
pub mod atomic;
pub mod bag;
pub mod cloud;
pub mod conf;
pub mod drive;
pub mod free_space;
pub mod input;
pub mod kind;
pub mod mapfile;
pub mod output;
pub mod read;
pub mod scene;
pub mod sensors;
pub mod units;
pub mod write_cloud;

pub use cloud::{LocalCloud, load_cloud, load_cloud_in_metres};
pub use mapfile::{HostMap, MapFormat};
pub use units::{FileUnit, LengthUnit, Units};
