//! Pictures and meshes of maps: a headless renderer ([`draw`]) with its camera ([`camera`]) and
//! raster ([`raster`]), `mema draw`'s panels ([`picture`]) and what `--around` keeps
//! ([`crop`]), and tessellated meshes in PLY, OBJ and glTF ([`export`]).
pub mod camera;
pub mod crop;
pub mod draw;
pub mod export;
pub mod picture;
pub mod raster;
