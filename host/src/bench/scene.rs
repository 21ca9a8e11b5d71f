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

pub struct Member {
    pub name: &'static str,
    pub points: usize,
    /// Where the cloud's own x = 0 went in the scene.
    pub offset_x: f64,
}

pub struct Scene {
    pub points: Vec<Point3>,
    pub members: Vec<Member>,
}

/// Reads the members from `dir` and lays them out.
pub fn environment(dir: &Path) -> Result<Scene> {
    let mut clouds = Vec::with_capacity(MEMBERS.len());
    for name in MEMBERS {
        let path = dir.join(name);
        let cloud = crate::commands::load_cloud(&path)
            .with_context(|| format!("environment scene: {}", path.display()))?;
        clouds.push((name, cloud.points));
    }
    let extent = |pts: &[Point3]| {
        let (lo, hi) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.x as f64), hi.max(p.x as f64))
            });
        (lo, hi)
    };
    let mut cursor = 0.0;
    let mut placed = Vec::with_capacity(clouds.len());
    for (_, pts) in &clouds {
        let (lo, hi) = extent(pts);
        placed.push(cursor - lo);
        cursor += (hi - lo) + GAP;
    }
    let centre = (cursor - GAP) / 2.0;
    let total: usize = clouds.iter().map(|(_, p)| p.len()).sum();
    // Pages of the scene become resident only as they are written, and each member is freed
    // once copied, so assembling never holds much more than one copy of the scene.
    let mut points = Vec::with_capacity(total);
    let mut members = Vec::with_capacity(clouds.len());
    for ((name, pts), start) in clouds.into_iter().zip(placed) {
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
