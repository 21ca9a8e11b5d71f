use super::*;
use crate::stream::{Pacing, StreamModel, StreamParams};
use crate::test_support::{OrFail, TestResult};

type Mapper = StreamMapper<64, 128>;

fn mapper() -> Mapper {
    StreamMapper::new(StreamParams {
        fit: crate::fit::FitParams::default(),
        seed: 0,
        max_clusters: 32,
        max_frozen: 0,
        refit_interval: 0,
        tolerance: 0.0,
        model: StreamModel::shells(0.01),
        pacing: Pacing::NONE,
        final_clusters: 0,
    })
}

/// A wall across x = 10 m, 4 m wide and high, 10 cm apart.
fn wall() -> impl Iterator<Item = Point3> {
    (0..1600).map(|i| {
        Point3::new(
            10.0,
            -2.0 + (i % 40) as f32 * 0.1,
            -2.0 + (i / 40) as f32 * 0.1,
        )
    })
}

/// Someone standing at x = 5 m, 60 cm across, between the sensor and the wall.
fn person() -> impl Iterator<Item = Point3> {
    (0..144).map(|i| {
        Point3::new(
            5.0,
            -0.3 + (i % 12) as f32 * 0.05,
            -0.3 + (i / 12) as f32 * 0.05,
        )
    })
}

/// One scan from `sensor`: its points into the mapper and the carver.
fn scan(
    mapper: &mut Mapper,
    carver: &mut Carver<8192>,
    sensor: Point3,
    points: impl Iterator<Item = Point3>,
) -> usize {
    let carved = carver.sensor_at(sensor, mapper, &mut ());
    for p in points {
        mapper.add(p);
        carver.add_return(p);
    }
    carved
}

fn near_the_person(m: &Mapper) -> usize {
    m.clusters().iter().filter(|c| c.center.x < 8.0).count()
}

fn sensors() -> [Point3; 4] {
    [0.0, 0.1, 0.2, 0.3].map(|y| Point3::new(0.0, y, 0.0))
}

/// Seen once, then seen through by two scans that reach the wall behind: gone, and every point
/// of the wall is still in the map.
#[test]
fn a_person_seen_through_twice_leaves_and_the_wall_stays() -> TestResult {
    let mut m = mapper();
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    let [a, b, c, _] = sensors();
    scan(&mut m, &mut carver, a, wall().chain(person()));
    if near_the_person(&m) == 0 {
        return Err("the person's points formed no cluster of their own");
    }
    let first = scan(&mut m, &mut carver, b, wall());
    let second = scan(&mut m, &mut carver, c, wall());
    let last = carver.end_scan(&mut m, &mut ());
    assert_eq!(first, 0, "the first scan reached everything it saw");
    assert_eq!(first + second + last, m.stats().carved as usize);
    assert_eq!(near_the_person(&m), 0, "{:?}", m.clusters());
    let kept: u64 = m.clusters().iter().map(|c| c.moments.count()).sum();
    assert_eq!(kept, 3 * 1600, "every wall point is still mapped");
    Ok(())
}

/// One scan through it is not enough, and a scan that reaches it again starts the count over.
#[test]
fn a_person_seen_again_between_glances_stays() -> TestResult {
    let mut m = mapper();
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    let [a, b, c, d] = sensors();
    scan(&mut m, &mut carver, a, wall().chain(person()));
    scan(&mut m, &mut carver, b, wall());
    scan(&mut m, &mut carver, c, wall().chain(person()));
    scan(&mut m, &mut carver, d, wall());
    carver.end_scan(&mut m, &mut ());
    assert_eq!(m.stats().carved, 0);
    assert!(near_the_person(&m) > 0);
    Ok(())
}

/// Scans from one place are one scan: a static sensor's frames never see through each other.
#[test]
fn frames_from_one_sensor_origin_are_one_scan() -> TestResult {
    let mut m = mapper();
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    let [a, ..] = sensors();
    scan(&mut m, &mut carver, a, wall().chain(person()));
    scan(&mut m, &mut carver, a, wall());
    scan(&mut m, &mut carver, a, wall());
    carver.end_scan(&mut m, &mut ());
    assert_eq!(m.stats().carved, 0);
    Ok(())
}

/// Clusters the scans do not look at, and a scene where nothing moved, lose nothing.
#[test]
fn what_the_scans_did_not_see_through_stays() -> TestResult {
    let mut m = mapper();
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    let [a, b, c, _] = sensors();
    // A second wall behind the sensor, seen only by the first scan.
    let behind = || wall().map(|p| Point3::new(-p.x, p.y, p.z));
    scan(&mut m, &mut carver, a, wall().chain(behind()));
    scan(&mut m, &mut carver, b, wall());
    scan(&mut m, &mut carver, c, wall());
    carver.end_scan(&mut m, &mut ());
    assert_eq!(m.stats().carved, 0);
    let kept: u64 = m.clusters().iter().map(|c| c.moments.count()).sum();
    assert_eq!(kept, 4 * 1600);
    Ok(())
}

/// A cluster spanning an inside corner has its centre in front of the walls, in space the
/// scans saw through; its far side reaches the corner, so it stays.
#[test]
fn a_cluster_across_a_corner_stays() -> TestResult {
    let mut m = StreamMapper::<64, 128>::new(StreamParams {
        final_clusters: 1,
        ..mapper().params
    });
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    // Two walls meeting at (6, 6) at a right angle, seen from near the origin.
    let corner = (0..200).map(|i| {
        let t = (i % 100) as f32 * 0.03;
        if i < 100 {
            Point3::new(6.0 - t, 6.0, 0.0)
        } else {
            Point3::new(6.0, 6.0 - t, 0.0)
        }
    });
    let [a, b, c, _] = sensors();
    scan(&mut m, &mut carver, a, corner);
    // One cluster of both walls: the final reduction's merges, before the next scans.
    m.finish();
    let centre = m.clusters().first().or_fail("a cluster")?.center;
    if !(centre.x < 5.5 && centre.y < 5.5) {
        return Err(if m.clusters().len() > 1 {
            "more than one cluster"
        } else {
            "the centre"
        });
    }
    // Later scans see the walls but from elsewhere; none of their points is given to the
    // mapper, so only the image judges the cluster.
    for sensor in [b, c] {
        carver.sensor_at(sensor, &mut m, &mut ());
        for i in 0..200 {
            let t = (i % 100) as f32 * 0.03;
            carver.add_return(if i < 100 {
                Point3::new(6.0 - t, 6.0, 0.0)
            } else {
                Point3::new(6.0, 6.0 - t, 0.0)
            });
        }
    }
    carver.end_scan(&mut m, &mut ());
    assert_eq!(m.stats().carved, 0);
    Ok(())
}

/// A device judges an ended scan a few clusters a tick ([`Carver::step`]): one cluster a step
/// carves what the whole judgement at once does, cluster for cluster.
#[test]
fn steps_of_one_cluster_carve_what_one_judgement_does() -> TestResult {
    let [a, b, c, d] = sensors();
    let scans = [(a, true), (b, false), (c, false), (d, true)];
    let mut whole = mapper();
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    for (sensor, with_person) in scans {
        let person = person().filter(|_| with_person);
        scan(&mut whole, &mut carver, sensor, wall().chain(person));
    }
    carver.end_scan(&mut whole, &mut ());

    let mut stepped = mapper();
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    let mut steps = 0;
    for (sensor, with_person) in scans {
        while !carver.step(sensor, 1, &mut stepped, &mut ()) {
            steps += 1;
        }
        for p in wall().chain(person().filter(|_| with_person)) {
            stepped.add(p);
            carver.add_return(p);
        }
    }
    carver.end_scan(&mut stepped, &mut ());
    assert!(whole.stats().carved > 0, "the person was carved");
    assert!(
        steps > 3 * 8,
        "each ended scan took a step a cluster: {steps} steps"
    );
    assert_eq!(stepped.stats(), whole.stats());
    assert_eq!(stepped.clusters(), whole.clusters());
    Ok(())
}

/// A return's code, found among the image's ranges, is the largest whose range is at most the
/// return's (so the image never claims free space past it), as `free_space::code` means it;
/// code's logarithm lands on it or one below.
#[test]
fn codes_by_bisection_are_the_largest_not_past_the_return() -> TestResult {
    let carver = Carver::<64>::whole_sphere(4, 8).or_fail("carver")?;
    let near = carver.image().geometry().near;
    let mut r = 1e-3_f32;
    let mut seen_below = 0;
    while r < 400.0 {
        let c = carver.code_of(r);
        assert!(range_of(c, near) <= r, "{r}: code {c}");
        assert!(
            c == NO_RETURN - 1 || range_of(c + 1, near) > r,
            "{r}: code {c} is not the largest"
        );
        let logarithm = crate::free_space::code(r, near);
        assert!(
            logarithm == c || logarithm + 1 == c,
            "{r}: {logarithm} and {c}"
        );
        seen_below += usize::from(logarithm != c);
        r *= 1.0007;
    }
    assert_eq!(carver.code_of(f32::NAN), 0);
    assert_eq!(carver.code_of(-1.0), 0);
    assert!(seen_below < 100, "{seen_below} codes differ");
    Ok(())
}

/// The carver's square root and arctangent are within their stated errors of the library's
/// over every octant, and its pixels are [`Geometry::pixel`]'s but for directions at an edge.
#[test]
fn a_carver_pixel_is_the_geometry_pixel_but_at_edges() -> TestResult {
    use super::direction::{arctangent, pixel};
    use crate::num::square_root;
    let mut worst_angle = 0.0_f32;
    for i in 0..20_000 {
        let turn = i as f32 / 20_000.0 * core::f32::consts::TAU;
        for radius in [1e-3_f32, 0.7, 30.0, 2.0e4] {
            let (y, x) = (radius * libm::sinf(turn), radius * libm::cosf(turn));
            worst_angle = worst_angle.max((arctangent(y, x) - libm::atan2f(y, x)).abs());
        }
    }
    assert!(worst_angle < 1e-5, "arctangent off by {worst_angle}");
    assert_eq!(arctangent(0.0, 0.0), 0.0);
    assert!(arctangent(f32::NAN, 1.0).is_nan());
    let mut worst_root = 0.0_f32;
    let mut x = 1e-6_f32;
    while x < 1e9 {
        let exact = libm::sqrtf(x);
        worst_root = worst_root.max((square_root(x) - exact).abs() / exact);
        x *= 1.013;
    }
    assert!(worst_root < 1e-6, "square root off by {worst_root} of it");
    assert_eq!(square_root(0.0), 0.0);
    assert!(square_root(-1.0).is_nan());

    let carver = Carver::<{ 124 * 512 }>::whole_sphere(124, 512).or_fail("carver")?;
    let geometry = *carver.image().geometry();
    let (mut same, mut all) = (0, 0);
    for i in 0..200_000_u32 {
        // A spiral over the sphere at ranges from 0.3 m to 90 m.
        let z = -1.0 + 2.0 * (i as f32 + 0.5) / 200_000.0;
        let turn = i as f32 * 2.399_963;
        let across = libm::sqrtf(1.0 - z * z);
        let r = 0.3 + (i % 997) as f32 * 0.09;
        let p = Point3::new(
            r * across * libm::cosf(turn),
            r * across * libm::sinf(turn),
            r * z,
        );
        let (fast, exact) = (pixel(&geometry, p), geometry.pixel(p));
        let (Some((a, ra)), Some((b, rb))) = (fast, exact) else {
            return Err("a point on the sphere is outside a whole-sphere image");
        };
        assert!((ra - rb).abs() <= 1e-6 * rb, "{ra} and {rb}");
        all += 1;
        same += usize::from(a == b);
    }
    assert!(same * 1000 >= all * 999, "{same} of {all} pixels the same");
    Ok(())
}

/// A device's layout: the person's cluster freezes once the scan has left it, before any scan
/// saw through it. Two later scans that do take it out of the frozen entities too, the wall's
/// frozen entities stay, and the carving marks changed only the slots the last frozen entities
/// moved into (a downlink that sent them sends them again).
#[test]
fn a_frozen_person_seen_through_twice_leaves_and_the_frozen_wall_stays() -> TestResult {
    type Small = StreamMapper<8, 16, 64>;
    let mut m = Small::new(StreamParams {
        fit: crate::fit::FitParams::default(),
        seed: 0,
        max_clusters: 8,
        max_frozen: 64,
        refit_interval: 0,
        tolerance: 0.0,
        model: StreamModel::shells(0.01),
        pacing: Pacing::NONE,
        final_clusters: 0,
    });
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    let [a, b, c, _] = sensors();
    let mut scan = |m: &mut Small, sensor: Point3, with_person: bool| {
        carver.sensor_at(sensor, m, &mut ());
        for p in person().filter(|_| with_person).chain(wall()) {
            m.add(p);
            carver.add_return(p);
        }
    };
    scan(&mut m, a, true);
    let near = |m: &Small| {
        m.frozen()
            .iter()
            .filter(|e| e.entity.center.x < 8.0)
            .count()
    };
    let person_entities = near(&m);
    if person_entities == 0 {
        return Err("the person's cluster did not freeze");
    }
    let wall_before = m.frozen().len() - person_entities;
    scan(&mut m, b, false);
    scan(&mut m, c, false);
    // The wall's points come back each scan and thaw its shells, which freeze again: slots
    // changed before the carving that takes the person out are not its doing.
    while m.take_changed(m.frozen().len()).is_some() {}
    carver.end_scan(&mut m, &mut ());
    assert_eq!(near(&m), 0, "{:?}", m.frozen());
    assert!(m.clusters().iter().all(|c| c.center.x > 8.0));
    assert!(m.frozen().len() >= wall_before, "a wall entity was carved");
    assert!(m.stats().carved >= person_entities as u64);
    let mut changed = 0;
    while m.take_changed(m.frozen().len()).is_some() {
        changed += 1;
    }
    assert!(changed <= person_entities, "{changed} slots changed");
    Ok(())
}

/// A device's layout holding `frozen` alone in its store.
fn holding(frozen: crate::stream::FrozenEntity) -> Result<StreamMapper<4, 8, 16>, &'static str> {
    let mut m = StreamMapper::new(StreamParams {
        max_clusters: 4,
        max_frozen: 16,
        ..mapper().params
    });
    m.frozen.push(frozen).or_fail("room")?;
    Ok(m)
}

/// A frozen entity across an inside corner has its centre in free space: later scans that see
/// both walls from elsewhere see through its centre, but not past its axis ends, on the walls,
/// and it stays.
#[test]
fn a_frozen_entity_across_a_corner_stays() -> TestResult {
    let corner = |i: usize| {
        let t = (i % 100) as f32 * 0.03;
        if i < 100 {
            Point3::new(6.0 - t, 6.0, 0.0)
        } else {
            Point3::new(6.0, 6.0 - t, 0.0)
        }
    };
    // The corner's one cluster (the final reduction's merges), as it would freeze.
    let mut whole = StreamMapper::<64, 128>::new(StreamParams {
        final_clusters: 1,
        ..mapper().params
    });
    for i in 0..200 {
        whole.add(corner(i));
    }
    whole.finish();
    let entity = whole
        .entities()
        .next()
        .or_fail("the corner's entity")?
        .entity;
    let frozen = crate::stream::FrozenEntity::of(&entity);
    let centre = frozen.entity.center;
    if !(centre.x < 5.5 && centre.y < 5.5 && whole.clusters().len() == 1) {
        return Err("not one entity centred in the corner's free space");
    }
    let mut m = holding(frozen)?;
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    for sensor in sensors() {
        carver.sensor_at(sensor, &mut m, &mut ());
        for i in 0..200 {
            carver.add_return(corner(i));
        }
    }
    carver.end_scan(&mut m, &mut ());
    assert_eq!(m.frozen(), &[frozen], "the corner was carved");
    // And the same entity where no wall stands behind it is seen through and carved.
    let mut open = holding(frozen)?;
    let mut carver = Carver::<8192>::whole_sphere(64, 128).or_fail("carver")?;
    for sensor in sensors() {
        carver.sensor_at(sensor, &mut open, &mut ());
        for i in 0..200 {
            let p = corner(i);
            carver.add_return(Point3::new(p.x * 3.0, p.y * 3.0, 0.0));
        }
    }
    carver.end_scan(&mut open, &mut ());
    assert!(
        open.frozen().is_empty(),
        "seen through with walls behind it, it stays"
    );
    Ok(())
}

/// A frozen piece of someone standing on the floor (a leg, 70 cm tall) has the lower end of its
/// long axis at the floor: at the board's pixels (1.45 degrees a row) the row below that end
/// meets the floor nearer than it, so that one end always looks seen. Two scans that see
/// through the rest of it, to the floor and the wall behind, take it out (with every end asked,
/// it stayed).
#[test]
fn a_frozen_piece_standing_on_the_floor_is_carved() -> TestResult {
    let leg = crate::stream::FrozenEntity::of(&crate::geometry::Entity::from_semi_axes(
        Point3::new(5.0, 0.0, 0.35),
        [0.03, 0.1, 0.35],
        &crate::geometry::Degeneration::default(),
    ));
    let floor_and_wall = || {
        let floor = (0..90 * 60).map(|i| {
            Point3::new(
                1.0 + (i / 60) as f32 * 0.1,
                -3.0 + (i % 60) as f32 * 0.1,
                0.0,
            )
        });
        let wall = (0..60 * 20)
            .map(|i| Point3::new(10.0, -3.0 + (i % 60) as f32 * 0.1, (i / 60) as f32 * 0.1));
        floor.chain(wall)
    };
    let mut m = holding(leg)?;
    let mut carver = Carver::<{ 124 * 512 }>::whole_sphere(124, 512).or_fail("carver")?;
    let [a, b, _, _] = sensors();
    for sensor in [a, b] {
        carver.sensor_at(Point3::new(sensor.x, sensor.y, 0.6), &mut m, &mut ());
        for p in floor_and_wall() {
            carver.add_return(p);
        }
    }
    carver.end_scan(&mut m, &mut ());
    assert!(m.frozen().is_empty(), "the leg stayed: {:?}", m.frozen());
    Ok(())
}
