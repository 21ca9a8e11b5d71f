//! The `mema` host library: multiellipsoidal maps of real point clouds.
//!
//! A cloud becomes a map of a few hundred ellipsoids (or their degenerations: spheres,
//! pseudocylinders, pairs of planes), which a robot can query for distance, occupancy and ray
//! hits in a fraction of the cloud's memory. The `mema` command line is built on this library
//! and adds only its arguments, printing and exit statuses; nothing here depends on it.
//!
//! The modules form layers, each using only those listed before it:
//!
//! - [`error`], [`progress`], [`heap`], [`kdtree`]: the library's [`ConfigError`], progress
//!   lines on stderr, the counting allocator `mema bench` reads, and the kd-tree of nearest
//!   points that reading (outliers), scoring and the scanner share;
//! - [`io`]: cloud readers ([`io::load_cloud`]), map files ([`io::HostMap`]), output checks,
//!   the built-in demo scene;
//! - [`mapping`]: the batch pipeline (k-means, fits, eq. 13), the shell model, surface
//!   following, the tolerance mode, crop and voxel filters, and their options;
//! - [`analysis`]: eq. 13 of any map against any cloud, the two-way fidelity score, the
//!   paper's tables;
//! - [`batch`]: `mema map`'s whole run as one call, with its report;
//! - [`render`], [`query`], [`link`]: pictures and meshes, the query index and transforms, the
//!   rangefinder link and the streaming mapper;
//! - [`bench`](mod@bench): the README's benchmarks.
//!
//! A test (`tests/tests/layering.rs`) keeps it so: it fails if a library module names the
//! command line or clap, if two modules import each other in a circle, or if a module uses one
//! of a layer not below its own.
//!
//! # Example
//!
//! Map a scan with the default model at 2,400 bytes, read the map back, score it against the
//! cloud and ask it the distance to a point:
//!
//! ```
//! use mema::analysis::{eval, fidelity};
//! use mema::io::{HostMap, load_cloud};
//! use mema::mapping::{EntityChoice, FitOptions, Model, ShellModel};
//!
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/car6.pcd");
//! let cloud = load_cloud(path.as_ref())?;
//! let k = Model::Shells.entities_in(2_400)?;
//! let config = FitOptions { seed: 1, ..FitOptions::default() }.config(k)?;
//! let output = std::env::temp_dir().join(format!("mema-example-{}.mema", std::process::id()));
//! let (model, shells, entity) = (Model::Shells, ShellModel::default(), EntityChoice::Ellipsoid);
//! mema::batch::map_cloud_with(&cloud, &config, model, shells, entity, &output, None)?;
//!
//! let map = HostMap::read(&output)?;
//! let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
//! let points = eval::points_in_map_frame(&cloud, &map);
//! let score = fidelity::two_way_score(&points, &entities, 0, 20_000)?;
//! assert!(score.chamfer > 0.0 && score.chamfer < 0.1);
//!
//! let index = mema::query::build_index(&map)?;
//! let nearest = index.nearest(mema::query::local(&map, map.origin)).expect("a map has entities");
//! assert!(nearest.signed_distance.is_finite());
//! # std::fs::remove_file(&output)?;
//! # Ok::<(), anyhow::Error>(())
//! ```
pub mod analysis;
pub mod batch;
pub mod bench;
pub mod error;
pub mod heap;
pub mod io;
pub mod kdtree;
pub mod link;
pub mod mapping;
pub mod progress;
pub mod query;
pub mod render;

pub use error::ConfigError;
