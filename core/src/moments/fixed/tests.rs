use super::*;
use crate::test_support::{OrFail, TestResult};

/// A noisy ellipsoidal shell of `n` f32 points about `centre`, from a fixed LCG.
fn shell_points(n: usize, seed: u64, centre: [f32; 3], axes: [f32; 3]) -> [Point3; 512] {
    let mut out = [Point3::new(0.0, 0.0, 0.0); 512];
    let mut s = seed;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    for p in out.iter_mut().take(n) {
        let (t, u) = (
            next() * core::f64::consts::TAU,
            next() * core::f64::consts::PI,
        );
        let noise = 1.0 + (next() - 0.5) * 0.02;
        let d = [
            libm::cos(t) * libm::sin(u),
            libm::sin(t) * libm::sin(u),
            libm::cos(u),
        ];
        *p = Point3::new(
            centre[0] + (d[0] * noise) as f32 * axes[0],
            centre[1] + (d[1] * noise) as f32 * axes[1],
            centre[2] + (d[2] * noise) as f32 * axes[2],
        );
    }
    out
}

/// Direct two-pass central moments in f64 of the f32 points: the independent check.
fn direct(points: &[Point3]) -> CentralMoments {
    crate::moments::tests::direct_of(points.iter().map(|p| p.to_f64()))
}

/// The grid's pitch is at most 2^-23 of an axis's largest offset, so rounding moves each
/// coordinate by up to about 6e-8 of the extent; over a few hundred points the moments then
/// move by well under 1e-7 relative, against 1e-16 for f64 sums of points already on the grid.
const GRID: f64 = 1e-7;

/// Relative differences of `got` from `want`: mean (in units of the spread), second, fourth.
fn worst(got: &CentralMoments, want: &CentralMoments) -> [f64; 3] {
    let spread = libm::sqrt(want.second.iter().sum::<f64>());
    let mut out = [0.0f64; 3];
    for j in 0..3 {
        out[0] = out[0].max(libm::fabs(got.mean[j] - want.mean[j]) / spread);
        out[1] = out[1].max(libm::fabs(got.second[j] - want.second[j]) / want.second[j]);
        for k in 0..3 {
            let (g, w) = (got.fourth[j][k], want.fourth[j][k]);
            out[2] = out[2].max(libm::fabs(g - w) / w);
        }
    }
    out
}

#[test]
fn matches_two_pass_sums_far_from_the_origin() -> TestResult {
    // 1 km out, a 30 cm shell: f32 holds the points to 61 micrometres there.
    let pts = shell_points(400, 3, [1000.0, -250.0, 30.0], [0.3, 0.2, 0.1]);
    let mut m = FixedMoments::new();
    for p in &pts[..400] {
        m.add(*p);
    }
    let got = m.central().or_fail("points")?;
    let [mean, second, fourth] = worst(&got, &direct(&pts[..400]));
    // The points are on the grid here (f32's spacing 1 km out is coarser): no rounding at all.
    if mean > 1e-11 || second > 1e-11 || fourth > 1e-11 {
        return Err("fixed-point moments differ from the two-pass f64 moments");
    }
    Ok(())
}

#[test]
fn coarsening_and_halving_keep_the_sums() -> TestResult {
    // The first offset is tiny (fine pitch), the later ones 10^6 times larger: the grid
    // coarsens by about 20 levels, and 5,000 points push the fourth-order sums past 2^62.
    let mut pts = [Point3::new(0.0, 0.0, 0.0); 512];
    pts[0] = Point3::new(5.0, 5.0, 5.0);
    pts[1] = Point3::new(5.000001, 5.0, 5.0);
    let far = shell_points(510, 9, [5.5, 4.5, 5.2], [2.0, 1.0, 0.5]);
    pts[2..].copy_from_slice(&far[..510]);
    let mut m = FixedMoments::new();
    let mut all = [Point3::new(0.0, 0.0, 0.0); 512];
    for round in 0..10 {
        for (i, p) in pts.iter().enumerate() {
            m.add(*p);
            if round == 0 {
                all[i] = *p;
            }
        }
    }
    if m.shift[3] == 0 {
        return Err("the test must push the fourth-order sums past 2^62");
    }
    let got = m.central().or_fail("points")?;
    // Ten copies of the same points have the same central moments.
    let [mean, second, fourth] = worst(&got, &direct(&all));
    if mean > GRID || second > GRID || fourth > GRID {
        return Err("sums drifted through coarsening and halving");
    }
    Ok(())
}

#[test]
fn merge_equals_one_cluster_of_both() -> TestResult {
    let a = shell_points(300, 1, [10.0, 2.0, -3.0], [0.3, 0.3, 0.1]);
    let b = shell_points(200, 2, [10.4, 2.1, -3.0], [0.2, 0.3, 0.1]);
    let (mut ma, mut mb) = (FixedMoments::new(), FixedMoments::new());
    let mut all = [Point3::new(0.0, 0.0, 0.0); 500];
    for (i, p) in a[..300].iter().enumerate() {
        ma.add(*p);
        all[i] = *p;
    }
    for (i, p) in b[..200].iter().enumerate() {
        mb.add(*p);
        all[300 + i] = *p;
    }
    ma.merge(&mb);
    if ma.count() != 500 {
        return Err("merged count");
    }
    let [mean, second, fourth] = worst(&ma.central().or_fail("points")?, &direct(&all));
    if mean > GRID || second > GRID || fourth > GRID {
        return Err("merged moments differ from the two-pass moments of both");
    }
    // The merged sums keep growing correctly.
    let c = shell_points(100, 4, [10.2, 2.0, -3.1], [0.3, 0.2, 0.2]);
    let mut every = [Point3::new(0.0, 0.0, 0.0); 600];
    every[..500].copy_from_slice(&all);
    for (i, p) in c[..100].iter().enumerate() {
        ma.add(*p);
        every[500 + i] = *p;
    }
    let [mean, second, fourth] = worst(&ma.central().or_fail("points")?, &direct(&every));
    if mean > GRID || second > GRID || fourth > GRID {
        return Err("points added after a merge");
    }
    Ok(())
}

#[test]
fn mean32_is_the_mean_and_coincident_points_have_no_spread() -> TestResult {
    let pts = shell_points(64, 5, [-3.0, 7.0, 0.25], [0.05, 0.05, 0.05]);
    let mut m = FixedMoments::new();
    for p in &pts[..64] {
        m.add(*p);
    }
    let want = direct(&pts[..64]).mean;
    let got = m.mean32().or_fail("points")?;
    for j in 0..3 {
        if libm::fabs(f64::from(got[j]) - want[j]) > 1e-6 {
            return Err("mean32 differs from the two-pass mean");
        }
    }
    let mut same = FixedMoments::new();
    for _ in 0..5 {
        same.add(Point3::new(1.5, -2.0, 3.0));
    }
    let c = same.central().or_fail("points")?;
    if c.mean != [1.5, -2.0, 3.0] || c.second != [0.0; 3] || same.count() != 5 {
        return Err("coincident points");
    }
    if FixedMoments::new().central().is_some() || FixedMoments::new().mean32().is_some() {
        return Err("empty moments have no mean");
    }
    Ok(())
}

#[test]
fn wide_products_are_exact() {
    // Against u128 arithmetic: products up to 2^96, every shift from the needed one up, and
    // the rounding bit's edges.
    let mut state = 11u64;
    let mut draw = |i: u64| {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
        match i % 4 {
            0 => state >> 16,
            1 => (1u64 << 48) - 1 - (state >> 50),
            2 => state >> (16 + i % 48),
            _ => (state >> 33) | 1,
        }
    };
    for i in 0..20_000u64 {
        let (a, b) = (draw(i), draw(i / 3));
        let exact = u128::from(a) * u128::from(b);
        let (high, low) = wide_product(a, b);
        assert_eq!((u128::from(high) << 64) | u128::from(low), exact, "{a} {b}");
        let needed = shift_for(high, low);
        assert!(exact >> needed < 1 << 60 && (needed == 0 || exact >> (needed - 1) >= 1 << 59));
        for s in needed..64 {
            let rounded = if s == 0 {
                exact
            } else {
                (exact >> s) + ((exact >> (s - 1)) & 1)
            };
            assert_eq!(
                u128::from(wide_shifted(high, low, s)),
                rounded,
                "{a} {b} {s}"
            );
        }
    }
}

#[test]
fn merging_single_points_keeps_their_offsets() -> TestResult {
    // Each cluster alone has no pitch (no non-zero offset); merged, their offsets must be
    // represented, not rounded to whole units.
    let pts = [
        Point3::new(0.5476, 3.0514, -0.3480),
        Point3::new(0.5467, 3.0499, -0.3467),
        Point3::new(0.5472, 3.0506, -0.3474),
    ];
    let mut merged = FixedMoments::new();
    for p in pts {
        let mut one = FixedMoments::new();
        one.add(p);
        merged.merge(&one);
    }
    let got = merged.central().or_fail("points")?;
    let want = direct(&pts);
    for j in 0..3 {
        if libm::fabs(got.mean[j] - want.mean[j]) > 1e-7 * libm::fabs(want.mean[j]) {
            return Err("merged single points lost their offsets");
        }
    }
    let [_, second, _] = worst(&got, &want);
    if second > 1e-6 {
        return Err("merged single points lost their spread");
    }
    Ok(())
}

#[test]
fn merging_far_clusters_keeps_their_spread() -> TestResult {
    for (ca, cb) in [
        ([0.0f32, 0.0, 0.0], [10.0f32, 0.0, 0.0]),
        ([5.0, 1.0, 0.0], [-5.0, 1.0, 0.0]),
    ] {
        let a = shell_points(100, 7, ca, [1.0, 1.0, 1.0]);
        let b = shell_points(100, 8, cb, [1.0, 1.0, 1.0]);
        let (mut ma, mut mb) = (FixedMoments::new(), FixedMoments::new());
        let mut all = [Point3::new(0.0, 0.0, 0.0); 200];
        for (i, p) in a[..100].iter().enumerate() {
            ma.add(*p);
            all[i] = *p;
        }
        for (i, p) in b[..100].iter().enumerate() {
            mb.add(*p);
            all[100 + i] = *p;
        }
        ma.merge(&mb);
        let [mean, second, fourth] = worst(&ma.central().or_fail("points")?, &direct(&all));
        if mean > GRID || second > GRID || fourth > GRID {
            return Err("far clusters merged wrongly");
        }
    }
    Ok(())
}

#[test]
fn random_adds_and_merges_match_f64_sums() -> TestResult {
    // Small clusters of every kind merged in random order: single points, coincident points,
    // points on a line (axes without a pitch), far apart and close, against f64 sums. Each
    // merge puts every point on the merged cluster's grid (2^-23 of its reach), so a point
    // moves by up to 2^-23 of the cluster's extent `e`: the second moment by `2^-22 e^2`, the
    // fourth by `2^-21 e^4`, at most.
    let mut state = 99u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as u32
    };
    for round in 0..300 {
        let mut fixed = [FixedMoments::new(); 6];
        let mut exact = [Moments::new(); 6];
        let (mut low, mut high) = ([f64::MAX; 3], [f64::MIN; 3]);
        for (f, e) in fixed.iter_mut().zip(exact.iter_mut()) {
            let n = 1 + next() % if round % 5 == 0 { 200 } else { 4 };
            let centre = [(next() % 21) as f32 - 10.0, (next() % 3) as f32, 0.0];
            for _ in 0..n {
                let jitter = |v: u32| {
                    if round % 3 == 0 {
                        0.0
                    } else {
                        // Every seventh round tight clusters (fine grids) far apart.
                        let scale = if round % 7 == 0 { 1e-4 } else { 1.0 };
                        ((v % 1000) as f32 * 1e-3 - 0.5) * scale
                    }
                };
                let p = Point3::new(
                    centre[0] + jitter(next()),
                    centre[1] + if round % 2 == 0 { 0.0 } else { jitter(next()) },
                    centre[2],
                );
                f.add(p);
                e.add(p);
                for (j, v) in p.to_f64().iter().enumerate() {
                    low[j] = low[j].min(*v);
                    high[j] = high[j].max(*v);
                }
            }
        }
        for i in 1..6 {
            let (f, e) = (fixed[i], exact[i]);
            fixed[0].merge(&f);
            exact[0].merge(&e);
        }
        let (got, want) = (
            fixed[0].central().or_fail("points")?,
            exact[0].central().or_fail("points")?,
        );
        let step = 1.0 / (1u64 << 23) as f64;
        for j in 0..3 {
            let e = high[j] - low[j];
            if libm::fabs(got.mean[j] - want.mean[j]) > step * e + 1e-12
                || libm::fabs(got.second[j] - want.second[j]) > 2.0 * step * e * e + 1e-24
                || libm::fabs(got.fourth[j][j] - want.fourth[j][j])
                    > 4.0 * step * e * e * e * e + 1e-48
            {
                return Err("merged moments differ from f64 sums beyond the grid");
            }
        }
    }
    Ok(())
}

#[test]
fn exponent_moves_are_the_multiplications_they_replace() {
    // Random bit patterns (every class: zeros, subnormals, normals, infinities, NaNs) against
    // the plain product and the plain search they stand in for, over the exponents a unit takes.
    let mut s = 0x9e37_79b9_7f4a_7c15u64;
    for _ in 0..200_000 {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        let x = f64::from_bits(s);
        let e = ((s >> 5) % 2046) as i32 - 1022;
        let want = x * pow2_64(e);
        let got = scaled_by_pow2(x, e);
        assert!(
            got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
            "{x:e} * 2^{e}: {got:e} != {want:e}"
        );
        let mut shift = 0u8;
        while shift < 63 && libm::fabs(x) >= pow2_64(61 + i32::from(shift)) {
            shift += 1;
        }
        assert_eq!(shift_below_2_61(x), shift, "{x:e}");
    }
    for x in [
        0.0,
        -0.0,
        f64::INFINITY,
        f64::NEG_INFINITY,
        2f64.powi(61),
        2f64.powi(61) - 512.0,
    ] {
        let mut shift = 0u8;
        while shift < 63 && libm::fabs(x) >= pow2_64(61 + i32::from(shift)) {
            shift += 1;
        }
        assert_eq!(shift_below_2_61(x), shift, "{x:e}");
    }
}

/// A stream of shells keeps the sums of orders 1 and 2 only: through adds and merges of tilted
/// clusters far from the origin, its mean and covariance are the two-pass f64 ones of the same
/// points (the independent check) and the full sums' bit for bit, and it has no central
/// moments to give.
#[test]
fn second_order_sums_keep_the_covariance() -> TestResult {
    let tilt = |p: Point3| Point3::new(p.x + 0.5 * p.y, p.y - 0.3 * p.z, p.z + 0.2 * p.x);
    let a = shell_points(300, 5, [1000.0, -250.0, 30.0], [0.3, 0.2, 0.05]);
    let b = shell_points(200, 6, [1000.6, -250.2, 30.1], [0.2, 0.3, 0.02]);
    let (mut full, mut second) = (FixedMoments::new(), FixedMoments::second_order());
    let (mut full_b, mut second_b) = (FixedMoments::new(), FixedMoments::second_order());
    let mut all = [[0.0f64; 3]; 500];
    for (i, p) in a[..300].iter().map(|&p| tilt(p)).enumerate() {
        full.add(p);
        second.add(p);
        all[i] = p.to_f64();
    }
    for (i, p) in b[..200].iter().map(|&p| tilt(p)).enumerate() {
        full_b.add(p);
        second_b.add(p);
        all[300 + i] = p.to_f64();
    }
    full.merge(&full_b);
    second.merge(&second_b);
    let (mean, covariance) = second.covariance().or_fail("points")?;
    assert_eq!(Some((mean, covariance)), full.covariance());
    assert!(second.central().is_none() && full.central().is_some());
    let (m, c) = covariance_error(&second, &all)?;
    assert!(m <= GRID && c <= GRID, "{m} {c}");
    Ok(())
}

/// Mean and covariance of `m` against the two-pass f64 ones of `all`: the largest error of
/// the mean in units of the spread, and of the covariance in units of its trace.
fn covariance_error(m: &FixedMoments, all: &[[f64; 3]]) -> Result<(f64, f64), &'static str> {
    let (mean, covariance) = m.covariance().or_fail("points")?;
    let n = all.len() as f64;
    let want_mean = [0, 1, 2].map(|j| all.iter().map(|p| p[j]).sum::<f64>() / n);
    let trace = covariance[0][0] + covariance[1][1] + covariance[2][2];
    let (mut mean_off, mut cov_off) = (0.0f64, 0.0f64);
    for j in 0..3 {
        mean_off = mean_off.max(libm::fabs(mean[j] - want_mean[j]) / libm::sqrt(trace));
        for k in 0..3 {
            let want = all
                .iter()
                .map(|p| (p[j] - want_mean[j]) * (p[k] - want_mean[k]))
                .sum::<f64>()
                / n;
            cov_off = cov_off.max(libm::fabs(covariance[j][k] - want) / trace);
        }
    }
    Ok((mean_off, cov_off))
}

/// Shells merge in integers: pieces near the origin (anchors between the grid's steps), a
/// kilometre out, a flat piece (one axis without a pitch) and a chain of forty merges of
/// small pieces each give the two-pass f64 mean and covariance of all their points, agree
/// with the f64 route's merge, and keep taking points after.
#[test]
fn shells_merge_in_integers_as_their_points_sum() -> TestResult {
    let tilt = |p: Point3| Point3::new(p.x + 0.5 * p.y, p.y - 0.3 * p.z, p.z + 0.2 * p.x);
    let flat = |p: Point3| Point3::new(p.x, p.y, 0.75);
    let cases = [
        ("near the origin", [0.1, 0.7, -0.2], [0.43, 0.61, -0.19]),
        (
            "a kilometre out",
            [1000.0, -250.0, 30.0],
            [1000.6, -250.2, 30.1],
        ),
        ("flat and tilted", [3.0, 4.0, 0.0], [3.3, 4.1, 0.0]),
    ];
    for (case, (name, ca, cb)) in cases.into_iter().enumerate() {
        let a = shell_points(300, 20 + case as u64, ca, [0.3, 0.2, 0.05]);
        let b = shell_points(200, 30 + case as u64, cb, [0.2, 0.3, 0.02]);
        let (mut ma, mut mb) = (FixedMoments::second_order(), FixedMoments::second_order());
        let mut all = [[0.0f64; 3]; 600];
        for (i, p) in a[..300].iter().map(|&p| tilt(p)).enumerate() {
            let p = if case == 2 { flat(p) } else { p };
            ma.add(p);
            all[i] = p.to_f64();
        }
        for (i, p) in b[..200].iter().map(|&p| tilt(p)).enumerate() {
            mb.add(p);
            all[300 + i] = p.to_f64();
        }
        let mut through_f64 = ma.to_moments();
        through_f64.merge_second_order(&mb.to_moments());
        ma.merge(&mb);
        let (mean, covariance) = ma.covariance().or_fail("points")?;
        let (f64_mean, f64_covariance) = through_f64.covariance().or_fail("points")?;
        // Both routes take the anchors' difference exactly and round each sum to the merged
        // grid: they differ by f64's rounding of the sums (the covariance, a difference of
        // sums, by more), far below the grid's.
        let trace = covariance[0][0] + covariance[1][1] + covariance[2][2];
        for j in 0..3 {
            let off = libm::fabs(mean[j] - f64_mean[j]) / libm::sqrt(trace);
            assert!(off <= 1e-9, "{name}: mean {off}");
            for k in 0..3 {
                let off = libm::fabs(covariance[j][k] - f64_covariance[j][k]) / trace;
                assert!(off <= 1e-9, "{name}: covariance {off}");
            }
        }
        let (m, c) = covariance_error(&ma, &all[..500])?;
        assert!(m <= GRID && c <= GRID, "{name}: {m} {c}");
        let c_points = shell_points(100, 40 + case as u64, ca, [0.1, 0.1, 0.1]);
        for (i, &p) in c_points[..100].iter().enumerate() {
            ma.add(p);
            all[500 + i] = p.to_f64();
        }
        let (m, c) = covariance_error(&ma, &all)?;
        assert!(m <= GRID && c <= GRID, "{name}, points after: {m} {c}");
    }
    // Forty pieces of twelve points along a curve, merged one by one into the first.
    let mut chain = FixedMoments::second_order();
    let mut all = [[0.0f64; 3]; 480];
    for piece in 0..40 {
        let t = piece as f32 * 0.05;
        let centre = [5.0 + t, -2.0 + t * t, 0.3 * t];
        let pts = shell_points(12, 60 + piece as u64, centre, [0.02, 0.03, 0.01]);
        let mut m = FixedMoments::second_order();
        for (i, &p) in pts[..12].iter().enumerate() {
            m.add(p);
            all[12 * piece + i] = p.to_f64();
        }
        chain.merge(&m);
    }
    if chain.count() != 480 {
        return Err("chained count");
    }
    let (m, c) = covariance_error(&chain, &all)?;
    assert!(m <= GRID && c <= GRID, "forty merges: {m} {c}");
    Ok(())
}

/// Small pieces with coordinates in common (a floor at one height, a wall at one x), merged
/// in every order: the integer merge's mean and covariance are the f64 route's.
#[test]
fn shells_merge_pieces_with_shared_coordinates() -> TestResult {
    let mut s = 7u64;
    let mut next = |n: u64| {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 33) % n
    };
    for round in 0..400 {
        let mut pieces = [FixedMoments::second_order(); 3];
        let mut all = [[0.0f64; 3]; 12];
        let mut count = 0;
        for piece in pieces.iter_mut() {
            for _ in 0..1 + next(4) {
                let grid =
                    |v: u64| -2.0 + v as f32 * 0.0625 + if round % 2 == 0 { 0.0 } else { 0.01 };
                let p = Point3::new(grid(next(64)), grid(next(64)), -0.75);
                let p = if round % 3 == 0 {
                    Point3::new(1.5, p.y, p.x)
                } else {
                    p
                };
                piece.add(p);
                all[count] = p.to_f64();
                count += 1;
            }
        }
        let mut through_f64 = pieces[0].to_moments();
        let mut merged = pieces[0];
        for piece in &pieces[1..] {
            through_f64.merge_second_order(&piece.to_moments());
            merged.merge(piece);
        }
        let (mean, _) = merged.covariance().or_fail("points")?;
        let (want, _) = through_f64.covariance().or_fail("points")?;
        let n = count as f64;
        for j in 0..3 {
            let direct = all[..count].iter().map(|p| p[j]).sum::<f64>() / n;
            assert!(
                libm::fabs(mean[j] - want[j]) <= 1e-7 && libm::fabs(mean[j] - direct) <= 1e-7,
                "round {round}, axis {j}: {} against {} (f64 route), {direct} (direct)",
                mean[j],
                want[j]
            );
        }
    }
    Ok(())
}
