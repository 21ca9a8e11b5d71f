use mema_core::query::brute_force;
use mema_core::{Degeneration, Entity, Point3};

use super::*;
use crate::io::cloud::LocalCloud;

/// A wall 5 m in front of a sensor at the origin: points on x = 5, |y|, |z| <= 1, 2 cm apart.
fn wall() -> LocalCloud {
    let mut points = Vec::new();
    for i in -50..=50 {
        for j in -50..=50 {
            points.push([5.0, i as f64 * 0.02, j as f64 * 0.02]);
        }
    }
    let mut cloud = LocalCloud::from_world(&points);
    let n = cloud.points.len();
    cloud.sensors.push_run([0.0, 0.0, 0.0], n);
    cloud
}

/// The wall's shell made 0.3 m thick: every ray meets its near face 0.3 m before its end.
fn thick_shell(cloud: &LocalCloud) -> Entity {
    let c = [5.0 - cloud.origin[0], -cloud.origin[1], -cloud.origin[2]];
    let centre = Point3::new(c[0] as f32, c[1] as f32, c[2] as f32);
    let degeneration = Degeneration {
        threshold: f64::INFINITY,
        ..Degeneration::default()
    };
    Entity::from_semi_axes(centre, [0.3, 1.2, 1.2], &degeneration)
}

/// Agree and early over the rays, cast by the core's brute force, not the shaping's own sums.
fn cast(entities: &[Entity], rays: &[Ray], tolerance: f64) -> (usize, usize) {
    let mut out = (0, 0);
    for r in rays {
        let t = brute_force::ray_cast(entities, r.origin, r.direction, r.range + tolerance)
            .map_or(f64::INFINITY, |h| h.t);
        if t < r.range - tolerance {
            out.1 += 1;
        } else if t <= r.range + tolerance {
            out.0 += 1;
        }
    }
    out
}

#[test]
fn a_shell_that_stops_its_rays_early_is_thinned_onto_their_ends() {
    let cloud = wall();
    let shell = thick_shell(&cloud);
    let shaped = shape(&cloud, &vec![0; cloud.points.len()], &[shell]).expect("the wall's rays");
    let rays = rays_of(&cloud);
    // Two spacings of 2 cm.
    assert!(
        (shaped.tolerance - 0.04).abs() < 1e-6,
        "{}",
        shaped.tolerance
    );
    let before = cast(&[shell], &rays, shaped.tolerance);
    let after = cast(&shaped.entities, &rays, shaped.tolerance);
    assert_eq!((shaped.agree[0], shaped.early[0]), before);
    assert_eq!((shaped.agree[1], shaped.early[1]), after);
    // Most rays stop early; the wall's corners lie outside its rim, and only a few rays where
    // the rim curves back meet it within the tolerance.
    assert!(
        before.1 * 10 >= rays.len() * 9,
        "{before:?} of {}",
        rays.len()
    );
    assert!(before.0 * 100 <= rays.len(), "{before:?} of {}", rays.len());
    assert!(
        after.0 * 10 >= rays.len() * 9,
        "{after:?} of {}",
        rays.len()
    );
    assert_eq!(shaped.changed, 1);
}

#[test]
fn rays_that_meet_a_shell_where_they_end_leave_it_as_it_was() {
    let cloud = wall();
    let c = thick_shell(&cloud).center;
    let degeneration = Degeneration {
        threshold: f64::INFINITY,
        ..Degeneration::default()
    };
    // 1 mm thick, inside the tolerance, and wide enough for the wall's corners (1.41 m out).
    let shell = Entity::from_semi_axes(c, [0.001, 1.5, 1.5], &degeneration);
    let shaped = shape(&cloud, &vec![0; cloud.points.len()], &[shell]).expect("the wall's rays");
    assert_eq!(shaped.entities, vec![shell]);
    assert_eq!(shaped.early, [0, 0]);
    assert_eq!(shaped.agree[0], shaped.rays);
}

#[test]
fn no_sensor_origins_no_shaping() {
    let mut cloud = wall();
    cloud.sensors = Default::default();
    assert_eq!(
        shape(&cloud, &vec![0; cloud.points.len()], &[thick_shell(&cloud)]),
        None
    );
}

/// The rays the direction bins give an entity are exactly those whose segment passes within
/// its reach, found by testing every ray: scans from two origins, spheres near, far, around
/// an origin and straddling the azimuth's seam.
#[test]
fn the_bins_miss_no_ray_near_an_entity() {
    let mut rays = Vec::new();
    for origin in [[0.0, 0.0, 0.0], [3.0, -2.0, 1.0]] {
        // Directions on a golden spiral over the sphere, ranges 1 to 31 m.
        for i in 0..4_000 {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / 4_000.0;
            let a = i as f64 * 2.399_963_229_728_653;
            let r = (1.0 - z * z).sqrt();
            rays.push(Ray {
                origin,
                direction: [r * a.cos(), r * a.sin(), z],
                range: 1.0 + (i * 7919 % 30) as f64,
            });
        }
    }
    let degeneration = Degeneration {
        threshold: f64::INFINITY,
        ..Degeneration::default()
    };
    let entities: Vec<Entity> = [
        ([5.0, 0.0, 0.0], [0.1, 1.0, 2.0]),
        ([-8.0, 0.2, 0.0], [0.05, 0.5, 0.5]),
        ([-20.0, -0.5, 3.0], [0.2, 2.0, 3.0]),
        ([0.5, 0.5, 0.5], [0.3, 0.3, 0.3]),
        ([0.0, 0.0, 25.0], [0.1, 1.0, 1.0]),
        ([4.0, -2.0, -9.0], [0.1, 0.4, 0.8]),
    ]
    .iter()
    .map(|&(c, axes)| {
        let c = Point3::new(c[0] as f32, c[1] as f32, c[2] as f32);
        Entity::from_semi_axes(c, axes, &degeneration)
    })
    .collect();
    let tolerance = 0.1;
    let near = rays_near(&entities, &rays, tolerance, usize::MAX).expect("no bound");
    for (e, found) in entities.iter().zip(&near) {
        let (c, reach) = (e.center.to_f64(), reach_of(e));
        let every: Vec<u32> = (0..rays.len() as u32)
            .filter(|&r| segment_within(&rays[r as usize], tolerance, c, reach))
            .collect();
        assert!(!every.is_empty(), "a sphere no ray passes tests nothing");
        assert_eq!(found, &every);
    }
}

/// Shells that each reach every ray (spheres around the sensor) make rays x shells pairs: past
/// the bound, no lists and no shaping, rather than memory in proportion to their product.
#[test]
fn shells_around_the_sensor_past_the_pair_bound_are_not_shaped() {
    let cloud = wall();
    let rays = rays_of(&cloud);
    let degeneration = Degeneration {
        threshold: f64::INFINITY,
        ..Degeneration::default()
    };
    let o = cloud.origin;
    let around = Point3::new(-o[0] as f32, -o[1] as f32, -o[2] as f32);
    let shells = vec![Entity::from_semi_axes(around, [20.0, 20.0, 20.0], &degeneration); 8];
    let every = rays_near(&shells, &rays, 0.04, usize::MAX).expect("no bound");
    assert!(every.iter().all(|near| near.len() == rays.len()));
    assert_eq!(rays_near(&shells, &rays, 0.04, 3 * rays.len()), None);
}
