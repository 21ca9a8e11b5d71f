use super::*;
use mema_core::query::brute_force;
use mema_core::{Degeneration, Entity, MapEntity, Point3};

/// A small generator, so the cases are the same on every run.
struct Lcg(u64);

impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The AUC from counts against the definition: over every (occupied, free) pair of samples,
/// 1 if the occupied one scores higher, 1/2 for a tie.
#[test]
fn auc_and_accuracy_agree_with_their_definitions() {
    let mut rng = Lcg(7);
    let states = [State::Free, State::Unknown, State::Occupied];
    for _ in 0..20 {
        let n = 50 + (rng.unit() * 200.0) as usize;
        let samples: Vec<Sample> = (0..n)
            .map(|_| Sample {
                point: [0.0; 3],
                occupied: rng.unit() < 0.3,
            })
            .collect();
        let said: Vec<State> = samples
            .iter()
            .map(|s| {
                // Better than chance, so the AUC is not trivially 1/2.
                let bias = if s.occupied { 0.4 } else { 0.0 };
                states[((rng.unit() + bias).min(0.999) * 3.0) as usize]
            })
            .collect();
        let o = occupancy_score(&samples, &said);
        let (mut wins, mut pairs) = (0.0, 0.0);
        for (a, sa) in samples.iter().zip(&said) {
            for (b, sb) in samples.iter().zip(&said) {
                if a.occupied && !b.occupied {
                    pairs += 1.0;
                    let (x, y) = (sa.occupancy(), sb.occupancy());
                    wins += if x > y {
                        1.0
                    } else if x == y {
                        0.5
                    } else {
                        0.0
                    };
                }
            }
        }
        assert!(
            (o.auc - wins / pairs).abs() < 1e-12,
            "{} {}",
            o.auc,
            wins / pairs
        );
        let right: f64 = samples
            .iter()
            .zip(&said)
            .map(|(s, st)| {
                let label = if s.occupied { 1.0 } else { 0.0 };
                match (st, s.occupied) {
                    (State::Unknown, _) => 0.5,
                    (State::Occupied, true) | (State::Free, false) => 1.0,
                    _ => 0.0 * label,
                }
            })
            .sum();
        assert!((o.accuracy - right / n as f64).abs() < 1e-12);
        assert_eq!(o.said_free + o.said_occupied + o.said_unknown, n);
    }
}

#[test]
fn outcomes_at_the_tolerance_edges() {
    let tol = 0.1;
    assert_eq!(outcome(None, 5.0, tol), Outcome::RunOn);
    assert_eq!(outcome(Some(4.85), 5.0, tol), Outcome::Early);
    assert_eq!(outcome(Some(4.95), 5.0, tol), Outcome::Agree);
    assert_eq!(outcome(Some(5.1), 5.0, tol), Outcome::Agree);
    assert_eq!(outcome(Some(5.2), 5.0, tol), Outcome::RunOn);
}

/// The first surface along a ray by sphere tracing with the brute-force nearest-surface
/// distance (Eberly's closest point, no ray-quadric algebra): a step of the distance to the
/// nearest surface can never cross one.
fn traced_hit(entities: &[Entity], ray: &Ray, t_max: f64) -> Option<f64> {
    let d = ray.direction()?;
    let mut t = 0.0;
    for _ in 0..100_000 {
        let p = std::array::from_fn(|j| ray.origin[j] + t * d[j]);
        let step = brute_force::nearest(entities, p)?.signed_distance.abs();
        if step < 1e-9 {
            return Some(t);
        }
        t += step;
        if t > t_max {
            return None;
        }
    }
    None
}

/// A map of turned ellipsoids, and rays whose ends lie on, before and behind its surfaces:
/// the counts of agree, early and run-on equal those of a brute-force trace, the fractions sum
/// to 1, and the index's hits equal the core's brute-force ray cast.
#[test]
fn counts_agree_with_a_brute_force_trace() {
    let mut rng = Lcg(29);
    let deg = Degeneration::default();
    let mut entities = Vec::new();
    // Around the sensor, 3 to 10 m out, so that about half the rays meet one.
    for _ in 0..60 {
        let (r, a) = (3.0 + 7.0 * rng.unit(), rng.unit() * std::f64::consts::TAU);
        let c = Point3::new(
            (r * a.cos()) as f32,
            (r * a.sin()) as f32,
            (rng.unit() * 2.0 - 1.0) as f32,
        );
        let axes = [0.5 + rng.unit(), 0.5 + rng.unit(), 0.05 + 0.5 * rng.unit()];
        let mut e = Entity::from_semi_axes(c, axes, &deg);
        let q = [rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5, 1.0];
        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        e.rotation = mema_core::Rotation::from_quaternion(q.map(|v| v / n)).unwrap();
        entities.push(MapEntity {
            entity: e,
            kind: e.kind(0.01),
        });
    }
    let map = HostMap::new([100.0, -50.0, 3.0], entities);
    let plain: Vec<Entity> = map.entities.iter().map(|e| e.entity).collect();
    let tol = 0.1;
    let model = MapRays::new(&map, tol).unwrap();
    let origin = [100.5, -50.2, 3.1];
    let mut rays = Vec::new();
    for _ in 0..400 {
        let z = rng.unit() * 0.6 - 0.3;
        let a = rng.unit() * std::f64::consts::TAU;
        let s = (1.0 - z * z).sqrt();
        let d = [s * a.cos(), s * a.sin(), z];
        // The end: at the map's first hit moved by -0.5..+0.5 m (agree, early or run on
        // alike), or anywhere out to 15 m where the ray hits nothing.
        let local_o = local(&map, origin);
        let hit = brute_force::ray_cast(&plain, local_o, d, 15.0).map(|h| h.t);
        let range = match hit {
            Some(t) => (t + rng.unit() - 0.5).max(0.3),
            None => 1.0 + 14.0 * rng.unit(),
        };
        rays.push(Ray {
            origin,
            end: std::array::from_fn(|j| origin[j] + range * d[j]),
        });
    }
    let scores = model.score(&rays);
    let (mut agree, mut early, mut run_on) = (0, 0, 0);
    for ray in &rays {
        let local_ray = Ray {
            origin: local(&map, ray.origin),
            end: local(&map, ray.end),
        };
        let traced = traced_hit(&plain, &local_ray, ray.range() + tol);
        let cast = model.first_hit(ray);
        let brute = brute_force::ray_cast(
            &plain,
            local_ray.origin,
            local_ray.direction().unwrap(),
            ray.range() + tol,
        )
        .map(|h| h.t);
        assert_eq!(cast, brute, "the index and the brute-force cast");
        match (traced, cast) {
            (Some(a), Some(b)) => assert!((a - b).abs() < 1e-4, "{a} {b}"),
            (a, b) => assert_eq!(a.is_some(), b.is_some(), "{a:?} {b:?}"),
        }
        match outcome(traced, ray.range(), tol) {
            Outcome::Agree => agree += 1,
            Outcome::Early => early += 1,
            Outcome::RunOn => run_on += 1,
        }
    }
    assert_eq!(
        (scores.agree, scores.early, scores.run_on),
        (agree, early, run_on)
    );
    assert!(agree > 20 && early > 20 && run_on > 20, "{scores:?}");
    let sum = scores.agree_fraction + scores.early_fraction + scores.run_on_fraction;
    assert!((sum - 1.0).abs() < 1e-12);
    // Each sample's state against the brute-force nearest surface: occupied within the
    // tolerance of a surface or inside an entity.
    let samples = samples(&rays, tol);
    assert_eq!(scores.occupancy.samples, samples.len());
    let occupied = samples
        .iter()
        .filter(|s| {
            let p = local(&map, s.point);
            brute_force::nearest(&plain, p).unwrap().signed_distance <= tol
        })
        .count();
    assert_eq!(scores.occupancy.said_occupied, occupied);
    assert_eq!(
        scores.occupancy.said_unknown,
        samples.len() - occupied,
        "a map without free space calls nothing free"
    );
}
