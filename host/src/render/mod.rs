//! Pictures and meshes of maps.
pub mod draw;
pub mod export;
