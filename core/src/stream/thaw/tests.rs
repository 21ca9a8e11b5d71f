use super::*;
use crate::stream::tests::shells_params;
use crate::test_support::{OrFail, TestResult};

/// A frozen shell made from `covariance` about `mean`, as a freeze makes one.
fn frozen_of(mean: [f64; 3], covariance: [[f64; 3]; 3]) -> Option<FrozenEntity> {
    crate::shell::shell_single(mean, covariance, &ShellParams::DEFAULT)
        .map(|e| FrozenEntity::of(&e))
}

/// The f64 mean and covariance of `points`, two passes.
fn mean_and_covariance(points: &[Point3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let n = points.len() as f64;
    let mut mean = [0.0; 3];
    for p in points {
        for (m, v) in mean.iter_mut().zip(p.to_f64()) {
            *m += v / n;
        }
    }
    let mut covariance = [[0.0; 3]; 3];
    for p in points {
        let d = [0, 1, 2].map(|j| p.to_f64()[j] - mean[j]);
        for (i, row) in covariance.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += d[i] * d[j] / n;
            }
        }
    }
    (mean, covariance)
}

/// A symmetric covariance from its three axes' standard deviations and a rotation by `turn`
/// radians about the axis `(1, 2, 2) / 3`.
fn turned_covariance(sigmas: [f64; 3], turn: f64) -> [[f64; 3]; 3] {
    let u = [1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0];
    let (s, c) = (libm::sin(turn), libm::cos(turn));
    // Rodrigues: R = c I + s [u]x + (1 - c) u u^T.
    let cross = [[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]];
    let r = |i: usize, j: usize| {
        let identity = if i == j { c } else { 0.0 };
        identity + s * cross[i][j] + (1.0 - c) * u[i] * u[j]
    };
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3)
                .map(|k| r(i, k) * sigmas[k] * sigmas[k] * r(j, k))
                .sum();
        }
    }
    out
}

/// A thawed shell comes back with the mean and covariance it was frozen from: its six points'
/// direct sums agree with the covariance the shell was made of, within the frozen rotation's
/// quarter of a degree, near the origin and a kilometre out.
#[test]
fn a_thawed_shell_has_the_covariance_it_froze_with() -> TestResult {
    for (mean, sigmas, turn) in [
        ([0.5, -0.2, 0.1], [0.3, 0.1, 0.004], 0.7),
        ([1000.0, -2000.0, 30.0], [2.0, 1.5, 0.05], 2.1),
        ([-3.0, 4.0, 5.0], [0.02, 0.5, 0.2], -1.2),
    ] {
        let covariance = turned_covariance(sigmas, turn);
        let frozen = frozen_of(mean, covariance).or_fail("a shell")?;
        let patch = patch_points(&frozen, &ShellParams::DEFAULT).or_fail("a patch")?;
        let (m, c) = mean_and_covariance(&patch);
        let largest = sigmas.iter().fold(0.0f64, |a, &s| a.max(s * s));
        // f32 points: a coordinate's rounding, relative to the patch's spread.
        let ulp = mean.iter().fold(0.0f64, |a, &v| a.max(v.abs())) * f64::from(f32::EPSILON);
        for j in 0..3 {
            assert!(
                (m[j] - mean[j]).abs() <= 2.0 * ulp + 1e-9,
                "mean {m:?} of {mean:?}"
            );
        }
        // A quarter of a degree turns the largest variance into the others by about
        // 2 * 0.0044 of it.
        let bound = 0.01 * largest + 4.0 * ulp * libm::sqrt(largest);
        for i in 0..3 {
            for j in 0..3 {
                assert!(
                    (c[i][j] - covariance[i][j]).abs() <= bound,
                    "covariance {c:?} against {covariance:?}"
                );
            }
        }
    }
    Ok(())
}

/// A shell with an axis of no weight has no covariance to come back with.
#[test]
fn a_shell_without_a_closed_axis_does_not_thaw() -> TestResult {
    let mut frozen =
        frozen_of([0.0; 3], turned_covariance([1.0, 0.5, 0.1], 0.3)).or_fail("a shell")?;
    frozen.entity.weights[0] = 0.0;
    assert!(patch_points(&frozen, &ShellParams::DEFAULT).is_none());
    Ok(())
}

/// `n` points of a flat square `side` metres wide at `x0`, row by row, each row's points
/// shifted by `shift` of a step.
fn square(x0: f32, side: f32, n: usize, shift: f32) -> impl Iterator<Item = Point3> {
    let step = side / n as f32;
    (0..n * n).map(move |i| {
        let (row, col) = ((i / n) as f32, (i % n) as f32);
        Point3::new(x0 + (row + shift) * step, (col + shift) * step, 0.0)
    })
}

type Device = StreamMapper<8, 64, 64>;

/// Entities whose centre lies over the square at the origin.
fn over_first_square(m: &Device) -> usize {
    m.entities()
        .filter(|e| e.entity.center.x < 2.0 && e.entity.center.x >= 0.0)
        .count()
}

/// A scan that comes back to ground it left frozen: its points thaw the shells there and grow
/// them, rather than opening clusters over the same surface, so the square keeps about as many
/// entities as its first visit left it.
#[test]
fn a_return_to_frozen_ground_grows_its_shells() -> TestResult {
    let mut m = Device::new(shells_params(8, 64));
    m.add_all(&square(0.0, 2.0, 40, 0.0).collect::<heapless::Vec<_, 1600>>());
    // Far enough along for the square's clusters to freeze.
    for x0 in [100.0, 103.0] {
        m.add_all(&square(x0, 2.0, 40, 0.0).collect::<heapless::Vec<_, 1600>>());
    }
    let first = over_first_square(&m);
    let frozen_over = m
        .frozen()
        .iter()
        .filter(|e| e.entity.center.x < 2.0)
        .count();
    assert!(frozen_over > 0, "the square did not freeze");
    m.add_all(&square(0.0, 2.0, 40, 0.5).collect::<heapless::Vec<_, 1600>>());
    m.finish();
    let again = over_first_square(&m);
    assert!(m.stats().thawed > 0);
    // Without thawing, 45 against the first visit's 34.
    assert!(
        again * 10 <= first * 11,
        "{again} entities over the square, {first} after the first visit"
    );
    Ok(())
}
