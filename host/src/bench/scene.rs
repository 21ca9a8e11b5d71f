//! The environment-scale case: every shared PLY/PCD cloud side by side in one scene, as the
//! paper's Experiment 8 maps 714,446 points of an environment with 8,880 ellipsoids.
//!
//! Layout: each cloud keeps its own frame (bounding-box centre at 0, as the readers return it)
//! and is translated along x only. Cloud i occupies `[x_i, x_i + w_i]` with `w_i` its x extent,
//! `x_0 = 0` and `x_{i+1} = x_i + w_i + GAP`; then the whole row is centred on x = 0. So no two
//! clouds overlap, each keeps its shape and density, and the scene is one cloud of about
//! 0.8 M points that k-means must split among all of them.

use anyhow::{Context, Result};
use mema_core::Point3;
use std::path::Path;

/// The shared clouds that make the scene, in this order (LAS/LAZ are the toolbox issue's).
pub const MEMBERS: [&str; 9] = [
    "bun000.ply",
    "bun_zipper.ply",
    "car6.pcd",
    "cturtle.pcd",
    "five_people.pcd",
    "lamppost.pcd",
    "milk.pcd",
    "office1.pcd",
    "rops_cloud.pcd",
];

/// Space between neighbouring clouds, in the clouds' units (metres for most).
pub const GAP: f64 = 1.0;

/// One cloud of the scene.
pub struct Member {
    pub name: &'static str,
    pub points: usize,
    /// Where the cloud's own x = 0 went in the scene.
    pub offset_x: f64,
}

/// The scene's points and where each member went.
pub struct Scene {
    pub points: Vec<Point3>,
    pub members: Vec<Member>,
}

/// Reads the members from `dir` and lays them out.
///
/// Each member is read twice: once for its extent, then straight into the scene at its place.
/// Holding every member while the scene is built would double the peak memory of the largest
/// case, and the allocator rarely hands freed pages back, so the second read is the cheaper way.
pub fn environment(dir: &Path) -> Result<Scene> {
    let read = |name: &str| {
        let path = dir.join(name);
        crate::io::cloud::load_cloud_in_metres(&path, None)
            .map(|(c, _)| c.points)
            .with_context(|| format!("environment scene: {}", path.display()))
    };
    let mut cursor = 0.0;
    let mut placed = Vec::with_capacity(MEMBERS.len());
    let mut total = 0;
    for name in MEMBERS {
        let pts = read(name)?;
        let (lo, hi) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.x as f64), hi.max(p.x as f64))
            });
        placed.push(cursor - lo);
        cursor += (hi - lo) + GAP;
        total += pts.len();
    }
    let centre = (cursor - GAP) / 2.0;
    let mut points = Vec::with_capacity(total);
    let mut members = Vec::with_capacity(MEMBERS.len());
    for (name, start) in MEMBERS.into_iter().zip(placed) {
        let pts = read(name)?;
        let offset_x = start - centre;
        points.extend(
            pts.iter()
                .map(|p| Point3::new((p.x as f64 + offset_x) as f32, p.y, p.z)),
        );
        members.push(Member {
            name,
            points: pts.len(),
            offset_x,
        });
    }
    Ok(Scene { points, members })
}
