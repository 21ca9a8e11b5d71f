//! Making maps: the batch pipeline, the shell model, surface following, the tolerance mode and
//! the point filters, with the configuration they take ([`options`]).
//!
//! Built on [`crate::io`] only; [`crate::batch`] puts these steps together the way `mema map`
//! runs them.
pub mod carve;
pub mod filter;
pub mod options;
pub mod pipeline;
pub mod ray_shaping;
pub mod shells;
pub mod surface_clusters;
pub mod tolerance;

pub use options::{
    EntityChoice, FitOptions, MIN_POINTS_PER_ENTITY, Model, PipelineConfig, ShellModel,
    most_entities,
};
