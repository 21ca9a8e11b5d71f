use super::*;
use crate::rng::{stream_rng, uniform};
use crate::test_support::{OrFail, TestResult};

/// Codes never stand for more than the range they code, and lose at most one code's step
/// (2.8 %) of it, from the shortest range to the longest.
#[test]
fn a_code_never_claims_past_its_range() {
    let near = 0.25;
    let mut r = 0.001;
    while r < 300.0 {
        let c = code(r, near);
        assert!(
            range_of(c, near) <= r,
            "{r} m codes as {c}, {} m",
            range_of(c, near)
        );
        if c < NO_RETURN - 1 && r >= near {
            assert!(
                r < range_of(c + 1, near) * 1.0001,
                "{r} m codes as {c}: one short"
            );
        }
        r *= 1.0007;
    }
    assert_eq!(code(f32::NAN, near), 0);
    assert_eq!(code(0.0, near), 0);
}

/// A wall 10 m ahead of the sensor, seen across a 40-degree cone: points before it are free,
/// points behind it and points in directions no return came from are not.
#[test]
fn a_wall_leaves_free_before_it_and_unknown_behind() -> TestResult {
    let mut image = RangeImage::<2048>::new(Geometry {
        origin: Point3::new(0.0, 0.0, 0.0),
        near: 0.25,
        elevation: [-0.4, 0.4],
        azimuth: [-core::f32::consts::PI, core::f32::consts::TAU],
        rows: 16,
        columns: 128,
    })
    .or_fail("fits")?;
    for i in -40..=40 {
        for j in -40..=40 {
            image.add_return(Point3::new(10.0, i as f32 * 0.1, j as f32 * 0.1));
        }
    }
    assert!(image.sees_free(Point3::new(5.0, 1.0, -1.0), 0.2));
    assert!(image.sees_free(Point3::new(9.0, 0.0, 0.0), 0.2));
    assert!(!image.sees_free(Point3::new(12.0, 0.0, 0.0), 0.2));
    assert!(!image.sees_free(Point3::new(10.0, 0.0, 0.0), 0.2));
    // Behind the sensor and above its beams nothing was seen.
    assert!(!image.sees_free(Point3::new(-5.0, 0.0, 0.0), 0.2));
    assert!(!image.sees_free(Point3::new(3.0, 0.0, 3.0), 0.2));
    assert!(!image.sees_free(Point3::new(f32::NAN, 0.0, 0.0), 0.2));
    Ok(())
}

/// Against the returns themselves: a point is free exactly when it lies nearer, by the margin,
/// than the nearest return in its pixel, the pixels and the nearest return worked out here for
/// each query by scanning every return (no image).
#[test]
fn free_is_nearer_than_every_return_of_its_pixel() -> TestResult {
    let origin = Point3::new(1.0, -2.0, 0.5);
    // A sector of a turn that starts past +pi/2 and wraps through -pi.
    let geometry = Geometry {
        origin,
        near: 0.5,
        elevation: [-0.5, 0.3],
        azimuth: [2.0, 4.0],
        rows: 8,
        columns: 32,
    };
    let mut image = RangeImage::<256>::new(geometry).or_fail("fits")?;
    let mut rng = stream_rng(7, 0);
    let mut unit = || uniform(&mut rng) as f32;
    let mut returns = [Point3::new(0.0, 0.0, 0.0); 400];
    for p in returns.iter_mut() {
        *p = Point3::new(
            origin.x + 40.0 * unit() - 20.0,
            origin.y + 40.0 * unit() - 20.0,
            origin.z + 12.0 * unit() - 8.0,
        );
        image.add_return(*p);
    }
    let margin = 0.2;
    let (mut free, mut queried) = (0, 0);
    for _ in 0..4000 {
        let q = Point3::new(
            origin.x + 50.0 * unit() - 25.0,
            origin.y + 50.0 * unit() - 25.0,
            origin.z + 16.0 * unit() - 9.0,
        );
        let Some((pixel, r)) = geometry.pixel(q) else {
            assert!(!image.sees_free(q, margin));
            continue;
        };
        let nearest = returns
            .iter()
            .filter_map(|p| geometry.pixel(*p))
            .filter(|(other, _)| *other == pixel)
            .map(|(_, pr)| pr)
            .fold(f32::INFINITY, f32::min);
        let expected = nearest.is_finite() && r < range_of(code(nearest, 0.5), 0.5) - margin;
        assert_eq!(image.sees_free(q, margin), expected, "{q:?}");
        queried += 1;
        free += usize::from(expected);
    }
    // The sector's own pixel arithmetic, checked on its edges: azimuth 2.0 is column 0, 6.0
    // (2.0 + 4.0, past +pi) the last; 1.9 and 6.1 are outside.
    let at = |azimuth: f32| {
        geometry.pixel(Point3::new(
            origin.x + 10.0 * libm::cosf(azimuth),
            origin.y + 10.0 * libm::sinf(azimuth),
            origin.z,
        ))
    };
    assert_eq!(at(2.0 + 1e-4).map(|(p, _)| p % 32), Some(0));
    assert_eq!(at(6.0 - 1e-4).map(|(p, _)| p % 32), Some(31));
    assert_eq!(at(1.9), None);
    assert_eq!(at(6.1), None);
    assert!(
        queried > 1000 && free > 100,
        "{queried} queried, {free} free"
    );
    Ok(())
}
