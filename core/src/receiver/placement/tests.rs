use super::*;

/// `v` as `m 2^k` with `m` an integer (sign included).
fn parts(v: f32) -> (i128, i32) {
    let bits = v.to_bits();
    let field = ((bits >> 23) & 0xFF) as i32;
    let fraction = i128::from(bits & 0x7F_FFFF);
    let (m, k) = if field == 0 {
        (fraction, -149)
    } else {
        (fraction | 1 << 23, field - 150)
    };
    (if bits >> 31 == 1 { -m } else { m }, k)
}

/// `|c - n 10^e|` scaled by `2^64 10^max(0, -e)`, exactly, for `c` of at least 2^-64.
fn distance(c: f32, n: i64, e: i8) -> i128 {
    let d = u32::from((-e).max(0).unsigned_abs());
    let up = u32::from(e.max(0).unsigned_abs());
    let (m, k) = parts(c);
    let c_scaled = (m * 10i128.pow(d)) << (k + 64);
    let target = (i128::from(n) * 10i128.pow(up)) << 64;
    (c_scaled - target).abs()
}

/// Whether `v` is the f32 nearest to `n 10^e` (ties to the even mantissa), by exact integers:
/// an independent check of the one-operation rounding the placement does.
fn is_nearest(v: f32, n: i64, e: i8) -> bool {
    let here = distance(v, n, e);
    let next = [v.next_up(), v.next_down()].map(|c| distance(c, n, e));
    next.iter()
        .all(|&d| here < d || (here == d && parts(v).0 % 2 == 0))
}

fn xorshift(mut s: u64) -> impl Iterator<Item = u64> {
    core::iter::repeat_with(move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    })
}

#[test]
fn points_below_2_24_units_are_the_nearest_f32_and_the_f64_bits() {
    for e in crate::wire::MIN_UNIT_EXPONENT..=crate::wire::MAX_UNIT_EXPONENT {
        let p = Placement::new([0.0; 3], e, &Pose::START);
        let scale = crate::wire::unit_scale(e).unwrap_or(f64::NAN);
        let small = -70_000..=70_000;
        let wide = xorshift((i64::from(e) + 99) as u64)
            .take(20_000)
            .map(|r| (r % (2 * EXACT32 - 1)) as i64 - (EXACT32 as i64 - 1));
        let edges = [
            1 - EXACT32 as i64,
            EXACT32 as i64 - 1,
            8_388_607,
            -8_388_609,
        ];
        for n in small.chain(wide).chain(edges) {
            let v = p.metres(n as i32, 0);
            assert!(is_nearest(v, n, e), "{n} 10^{e}: {v:e}");
            // The bits the f64 computation gave before (exhaustively the same on the host).
            assert_eq!(v.to_bits(), ((n as f64 * scale) as f32).to_bits());
        }
        // Beyond 2^24 units, f64: within an f32 ulp of the value.
        for (x, shift) in [
            (1 << 24, 0),
            (-(1 << 24), 0),
            (i32::MAX, 0),
            (i32::MAX, i32::MAX),
        ] {
            let (n, v) = (i64::from(x) + i64::from(shift), p.metres(x, shift));
            let ulp = v.next_up() - v;
            assert!(distance(v, n, e) <= distance(v + ulp, n, e).max(distance(v - ulp, n, e)));
        }
    }
}

#[test]
fn whole_offsets_are_exact_in_units_and_others_are_not_whole() {
    let pose = |t: [i32; 3], exponent: i8| Pose {
        wire_translation: t,
        exponent,
        translation: t.map(|v| v as f64 * crate::wire::unit_scale(exponent).unwrap_or(0.0)),
        ..Pose::START
    };
    // Centimetre poses, millimetre points, origin 2,048 m out: whole millimetres.
    let p = pose([-3700, 12, 5], -2);
    assert_eq!(
        whole_offset([2048.0, 0.0, -1024.0], -3, &p),
        Some([-37_000 - 2_048_000, 120, 50 + 1_024_000])
    );
    // Poses finer than the points, metres finer than an i32 of units, origins not whole metres
    // or beyond i32 metres: not whole.
    assert_eq!(whole_offset([0.0; 3], -2, &pose([10, -20, 0], -3)), None);
    assert_eq!(whole_offset([1024.0, 0.0, 0.0], -9, &Pose::START), None);
    assert_eq!(whole_offset([0.5, 0.0, 0.0], -3, &Pose::START), None);
    assert_eq!(whole_offset([f64::NAN, 0.0, 0.0], -3, &Pose::START), None);
    assert_eq!(whole_offset([1e18, 0.0, 0.0], -3, &Pose::START), None);
    // Kilometre points: metres are not whole units.
    assert_eq!(whole_offset([0.0; 3], 3, &Pose::START), None);
    // The point placed through a whole offset is the nearest f32 to its units.
    let placement = Placement::new([2048.0, 0.0, -1024.0], -3, &p);
    for (x, shift) in [(123_456, -2_085_000), (-1, -2_085_000), (7, 120)] {
        let n = i64::from(x) + i64::from(shift);
        assert!(is_nearest(placement.metres(x, shift), n, -3));
    }
}

/// The turned path's sum: the f32 nearest to `r + offset` with f64's rounding of that sum in
/// between, on a fixed sample of points and offsets up to 16 km.
#[test]
fn offsets_add_in_f32_as_in_f64() {
    let mut random = xorshift(7).map(|r| (r >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
    for _ in 0..200_000 {
        let r = (random.next().unwrap_or(0.0) * 200.0) as f32;
        let offset = random.next().unwrap_or(0.0) * 32_000.0;
        let hi = offset as f32;
        let got = add_offset(r, [hi, (offset - hi as f64) as f32]);
        assert_eq!(
            got.to_bits(),
            ((r as f64 + offset) as f32).to_bits(),
            "{r} + {offset}"
        );
    }
    // No offset leaves the point alone (a -0 becomes 0, as adding 0 in f64 did).
    assert_eq!(add_offset(1.5, [0.0, 0.0]), 1.5);
    assert_eq!(add_offset(-0.0, [0.0, 0.0]).to_bits(), 0.0f32.to_bits());
}
