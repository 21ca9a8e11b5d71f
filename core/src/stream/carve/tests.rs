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
