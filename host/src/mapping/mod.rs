//! Making maps: the batch pipeline, the shell model, surface following, the tolerance mode and
//! the point filters.
pub mod filter;
pub mod pipeline;
pub mod shells;
pub mod surface_clusters;
pub mod tolerance;
