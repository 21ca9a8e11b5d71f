//! Pictures and meshes of maps: a headless renderer ([`draw`]), `mema draw`'s panels
//! ([`picture`]) and tessellated meshes in PLY, OBJ and glTF ([`export`]).
pub mod draw;
pub mod export;
pub mod picture;
