//! The map as a robot uses it: signed distance, occupancy and ray casts through the core's
//! index ([`HostIndex`]), and rigid transforms of a whole map.
//!
//! The index works in the map's local frame; [`local`] and [`world`] convert.
//!
//! ```
//! use mema::io::HostMap;
//! use mema_core::{Entity, MapEntity, Point3};
//!
//! // A map of one sphere of radius 1 at (10, 0, 0) in world coordinates.
//! let sphere = Entity::sphere(Point3::new(0.0, 0.0, 0.0), 1.0);
//! let entity = MapEntity { entity: sphere, kind: sphere.kind(0.01) };
//! let map = HostMap::new([10.0, 0.0, 0.0], vec![entity]);
//! let index = mema::query::build_index(&map)?;
//!
//! let nearest = index.nearest(mema::query::local(&map, [13.0, 0.0, 0.0])).expect("a map entity");
//! assert_eq!(nearest.entity, 0);
//! assert!((nearest.signed_distance - 2.0).abs() < 1e-3);
//! assert_eq!(index.occupied(mema::query::local(&map, [10.5, 0.0, 0.0])), Some(0));
//!
//! let hit = index.ray_cast(mema::query::local(&map, [0.0, 0.0, 0.0]), [1.0, 0.0, 0.0], 100.0);
//! let point = mema::query::world(&map, hit.expect("the ray hits").point);
//! assert!((point[0] - 9.0).abs() < 1e-3);
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod held_out;
pub mod recast;
pub mod states;

use anyhow::{Context, Result};
use mema_core::query::MapIndex;
use mema_core::transform::RigidTransform;
use mema_core::{Degeneration, Entity, EntityKind, MapEntity};

use crate::io::mapfile::HostMap;

/// Entities an index can hold on the host (the paper's largest map has 8,880).
pub const INDEX_CAPACITY: usize = 16_384;
/// The core's query index at the host's capacity.
pub type HostIndex = MapIndex<INDEX_CAPACITY>;

/// Builds the index on a thread with a large stack: at 16,384 entities the value is 2.6 MB.
pub fn build_index(map: &HostMap) -> Result<Box<HostIndex>> {
    let entities: Vec<MapEntity> = map.entities.clone();
    std::thread::Builder::new()
        .stack_size(64 << 20)
        .spawn(move || HostIndex::build(entities).map(Box::new))
        .context("index thread")?
        .join()
        .map_err(|_| anyhow::anyhow!("index thread failed"))?
        .map_err(|e| anyhow::anyhow!("{e}; the map has too many entities for the query index"))
}

/// A world point in `map`'s local frame, where the index answers.
pub fn local(map: &HostMap, p: [f64; 3]) -> [f64; 3] {
    [
        p[0] - map.origin[0],
        p[1] - map.origin[1],
        p[2] - map.origin[2],
    ]
}

/// A point of `map`'s local frame in world coordinates.
pub fn world(map: &HostMap, p: [f64; 3]) -> [f64; 3] {
    [
        p[0] + map.origin[0],
        p[1] + map.origin[1],
        p[2] + map.origin[2],
    ]
}

/// Applies `transform` to a whole map: the origin moves exactly in f64, shapes per entity
/// (`None` if `transform` is not a rigid rotation), each labelled by [`kind_after`]. The
/// result is not quantized: a rotated grid entity is no longer on the grid, and rounding it
/// again would make the rotation lossy.
pub fn transform_map(map: &HostMap, transform: &RigidTransform) -> Option<HostMap> {
    // x' = R (origin + local) + t = (R origin + t) + R local.
    let origin = transform.apply_point(map.origin);
    let rotation_only = RigidTransform {
        translation: [0.0; 3],
        ..*transform
    };
    let entities = map
        .entities
        .iter()
        .map(|e| {
            let entity = rotation_only.apply_entity(&e.entity)?;
            Some(MapEntity {
                entity,
                kind: kind_after(&entity, e.kind),
            })
        })
        .collect::<Option<Vec<_>>>()?;
    Some(HostMap::new(origin, entities))
}

/// The kind of a moved `entity` that was stored as `stored`. Its infinite axes decide, as
/// [`Entity::kind`] defines the kinds (one a pseudocylinder, two a pair of planes), whatever
/// the stored label said: a map written by another tool, or by hand, may carry one that does
/// not fit. A finite entity keeps its ellipsoid or sphere, which its fit's sphere tolerance
/// decided and a rotation does not change; one labelled degenerate is judged at the default
/// tolerance.
pub fn kind_after(entity: &Entity, stored: EntityKind) -> EntityKind {
    match (entity.degenerated_axes(), stored) {
        (0, EntityKind::Ellipsoid | EntityKind::Sphere) => stored,
        (0, _) => entity.kind(Degeneration::default().sphere_tolerance),
        (1, _) => EntityKind::Pseudocylinder,
        _ => EntityKind::PlanePair,
    }
}

/// Seeded random queries over the map's box (10% margin): points for nearest/occupancy, rays
/// from those points in random directions.
pub fn random_queries(map: &HostMap, count: usize, seed: u64) -> Vec<([f64; 3], [f64; 3])> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for e in &map.entities {
        let c = e.entity.center.to_f64();
        for j in 0..3 {
            lo[j] = lo[j].min(c[j]);
            hi[j] = hi[j].max(c[j]);
        }
    }
    let mut s = seed | 1;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..count)
        .map(|_| {
            let p = [0, 1, 2].map(|j| {
                let margin = 0.1 * (hi[j] - lo[j]);
                lo[j] - margin + next() * (hi[j] - lo[j] + 2.0 * margin)
            });
            let d = [next() - 0.5, next() - 0.5, next() - 0.5];
            (p, d)
        })
        .collect()
}

/// Rotations about x, then y, then z, by these angles in degrees (`mema transform --rotate`).
/// Multiples of 90 degrees are axis permutations: they are snapped so they stay exact.
pub fn rotation_degrees(degrees: [f64; 3]) -> RigidTransform {
    let mut t = RigidTransform::IDENTITY;
    for (axis, angle) in degrees.iter().enumerate() {
        let step = RigidTransform::rotation_about(axis, angle.to_radians());
        let step = if angle.rem_euclid(90.0) == 0.0 {
            RigidTransform {
                rotation: step.rotation.map(|r| r.map(f64::round)),
                ..step
            }
        } else {
            step
        };
        t = step.after(&t);
    }
    t
}
