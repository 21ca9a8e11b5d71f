//! The library's error for a request that cannot work as asked.
//!
//! Failures of the data (a broken file, an empty cluster) come back as `anyhow` errors with
//! their context, as everywhere in this crate. A [`ConfigError`] is different: the caller asked
//! for something no data could satisfy (`k = 0`, an unknown map extension, a picture too small
//! for its plot). It travels inside those `anyhow` chains too, so a front end can find it with
//! `downcast_ref` and tell its user which of its own options to change; `mema`'s command line
//! exits with status 2 for it, as for its own usage errors.

use std::path::PathBuf;

/// A value that cannot work, found before any work is done (or as soon as it shows).
///
/// Each variant carries the offending values; `Display` names them in the library's terms.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// No clusters were asked for.
    #[error("k must be at least 1")]
    NoClusters,
    /// Eq. 12's weight outside `[0, 1]`.
    #[error("alpha {0} is outside [0, 1]; the paper uses 0.8")]
    Alpha(f64),
    /// The degeneration threshold is not a positive length.
    #[error("the degeneration threshold {0} must be a positive length")]
    Threshold(f64),
    /// The sphere tolerance is negative or not finite.
    #[error("the sphere tolerance {0} must be >= 0")]
    SphereTolerance(f64),
    /// A shell's tangent scale is not positive.
    #[error("the shells' tangent scale {0} must be positive")]
    TangentScale(f64),
    /// A shell's normal scale is not positive.
    #[error("the shells' normal scale {0} must be positive")]
    NormalScale(f64),
    /// A byte budget smaller than one entity.
    #[error("a budget of {bytes} bytes holds no entity; one takes {per} bytes in this model")]
    BudgetTooSmall {
        /// The budget asked for.
        bytes: usize,
        /// Bytes one entity takes in the model asked for.
        per: usize,
    },
    /// A byte budget that the free space of the input's scans leaves no entity of.
    #[error(
        "a budget of {bytes} bytes holds no entity beside the free space of {scans} scans ({free} bytes); one takes {per} bytes"
    )]
    BudgetTakenByFreeSpace {
        bytes: usize,
        scans: usize,
        free: usize,
        per: usize,
    },
    /// The tolerance mode's T is not a positive length.
    #[error("the tolerance {0} must be a positive length in the cloud's units")]
    Tolerance(f64),
    /// The tolerance mode may make no cluster at all.
    #[error("the tolerance mode's capacity must be at least 1")]
    ToleranceCapacity,
    /// The voxel grid's edge is not a positive length.
    #[error("the voxel size {0} must be a positive length")]
    Voxel(f64),
    /// A map path whose extension names no map format.
    #[error("{}: unknown map extension; consider .mema (binary), .csv or .json", .0.display())]
    MapExtension(PathBuf),
    /// A mesh path whose extension names no mesh format.
    #[error("{}: unknown mesh extension; consider .ply, .obj or .glb", .0.display())]
    MeshExtension(PathBuf),
    /// Tessellation counts outside what the meshes support.
    #[error(
        "{segments} segments and {rings} rings: need 3..=1024 segments and 2..=512 rings; the defaults are 24 and 12"
    )]
    Tessellation {
        /// Vertices around each ellipsoid and tube.
        segments: u32,
        /// Latitude bands of each ellipsoid.
        rings: u32,
    },
    /// A mesh too large for 32-bit vertex indices.
    #[error("{0} vertices exceed 32-bit indices")]
    TooManyVertices(usize),
    /// A picture too small for the plot, the title and the legend.
    #[error("a {width}x{height} picture leaves a {plot_width}x{plot_height} plot")]
    PictureTooSmall {
        /// The picture's size in pixels.
        width: u32,
        /// The picture's size in pixels.
        height: u32,
        /// The plot area that size leaves to each panel.
        plot_width: u32,
        /// The plot area that size leaves to each panel.
        plot_height: u32,
    },
    /// More clusters than the host's streaming mapper holds.
    #[error("k = {k} is over the streaming mapper's capacity of {max}")]
    StreamCapacity {
        /// The k asked for.
        k: usize,
        /// [`crate::link::stream::MAX_CLUSTERS`].
        max: usize,
    },
    /// A working set of no clusters, or of more than k.
    #[error("{working} working clusters must be between 1 and k ({k})")]
    Working {
        /// The working clusters asked for.
        working: usize,
        /// The k asked for.
        k: usize,
    },
    /// Frozen clusters asked for together with the tolerance mode.
    #[error("a working set below k and a tolerance do not combine: frozen clusters cannot merge")]
    WorkingWithTolerance,
    /// The sensor view asked to put z, the axis it looks along, up.
    #[error("the sensor view looks along z, so z cannot be up; choose x or y")]
    UpAlongView,
    /// A mesh past the output limit, found from the counts before any of it is made.
    #[error(
        "{entities} entities at {segments} segments and {rings} rings make {vertices} vertices and {triangles} triangles, {bytes} bytes of {format}, over the limit of {limit} bytes"
    )]
    MeshTooLarge {
        /// Entities in the map.
        entities: usize,
        /// Vertices around each ellipsoid and tube.
        segments: u32,
        /// Latitude bands of each ellipsoid.
        rings: u32,
        /// Vertices the mesh would have.
        vertices: u64,
        /// Triangles the mesh would have.
        triangles: u64,
        /// Bytes the file would take (an upper bound for OBJ's text).
        bytes: u64,
        /// The format's name.
        format: &'static str,
        /// The limit asked for.
        limit: u64,
        /// The finest (segments, rings) at the same ratio that fit the limit, if any does.
        fits: Option<(u32, u32)>,
    },
    /// A byte budget of zero for the fidelity benchmark.
    #[error("a budget of {0} bytes: a budget is at least 1 byte")]
    ZeroBudget(usize),
}
