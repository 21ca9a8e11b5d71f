use super::*;
use crate::link::receiver::DEFAULT_REACH;

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
    // Below 2^-64 (zero's neighbours, when `n` is 0), rounded down to the scale: every such
    // `c` is nearer 0 than any other `n 10^e`, which the ordering keeps. (Shifted by a
    // negative amount, debug builds stopped here and release builds compared garbage.)
    let scaled = m * 10i128.pow(d);
    let c_scaled = if k + 64 >= 0 {
        scaled << (k + 64)
    } else {
        scaled >> (-(k + 64)).min(127)
    };
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
    for e in crate::link::wire::MIN_UNIT_EXPONENT..=crate::link::wire::MAX_UNIT_EXPONENT {
        let p = Placement::new([0; 3], e, &Pose::START, DEFAULT_REACH);
        assert!(p.is_some(), "a placement at 0");
        let Some(p) = p else { return };
        let scale = crate::link::wire::unit_scale(e).unwrap_or(f64::NAN);
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
    let pose = |t: [i32; 3], exponent: i8| {
        Pose::of_wire(
            1,
            &WirePose {
                translation: t.map(i64::from),
                rotation: [0, 0, 0, crate::link::wire::QUATERNION_ONE],
            },
            exponent,
        )
    };
    // Centimetre poses, millimetre points, origin 2,048.001 m out: whole millimetres.
    let p = pose([-3700, 12, 5], -2);
    let origin = [2_048_001_000_000, 0, -1_024_000_000_000];
    let t = p.translation_nm.unwrap_or([0; 3]);
    let offset = [0, 1, 2].map(|j| t[j] - origin[j]);
    assert_eq!(
        whole_offset(offset, -3),
        Some([-37_000 - 2_048_001, 120, 50 + 1_024_000])
    );
    // Offsets finer than the points' unit, or past an i32 of units: not whole.
    assert_eq!(whole_offset([5_000, 0, 0], -3), None);
    assert_eq!(whole_offset([1 << 62, 0, 0], -9), None);
    // Kilometre points: an offset of whole kilometres only.
    assert_eq!(whole_offset([1_000_000_000_000, 0, 0], 3), Some([1, 0, 0]));
    assert_eq!(whole_offset([1_000_000_000, 0, 0], 3), None);
    // The point placed through a whole offset is the nearest f32 to its units.
    let placement = Placement::new(origin, -3, &p, DEFAULT_REACH);
    assert!(placement.is_some(), "a placement");
    let Some(placement) = placement else { return };
    for (x, shift) in [(123_456, -2_085_001), (-1, -2_085_001), (7, 120)] {
        let n = i64::from(x) + i64::from(shift);
        assert!(is_nearest(placement.metres(x, shift), n, -3));
    }
}

/// The same scene anywhere in the world frame reaches the mapper with the same bits: the
/// origin (its first point) and the pose move together, and their difference is exact.
#[test]
fn a_scene_moved_anywhere_places_its_points_with_the_same_bits() {
    let half = libm::sqrt(0.5);
    let q = (half * crate::link::wire::QUATERNION_ONE as f64).round() as i32;
    let raw = [[1234, -5678, 910], [-3, 7, 100_000], [0, 0, 1]];
    let placed = |shift_mm: [i32; 3], rotation: [i32; 4]| {
        let pose = Pose::of_wire(
            1,
            &WirePose {
                translation: [500 + shift_mm[0], -20 + shift_mm[1], 7 + shift_mm[2]].map(i64::from),
                rotation,
            },
            -3,
        );
        let origin = Placement::world_nm(raw[0], -3, &pose).unwrap_or([0; 3]);
        let placement = Placement::new(origin, -3, &pose, DEFAULT_REACH);
        raw.map(|r| {
            placement
                .and_then(|p| p.placed(r))
                .map(|p| p.to_array().map(f32::to_bits))
        })
    };
    for rotation in [[0, 0, 0, crate::link::wire::QUATERNION_ONE], [0, 0, q, q]] {
        let home = placed([0; 3], rotation);
        assert!(home.iter().all(Option::is_some));
        // 2,000 km, the middle of the old 1,024 m cell, and odd millimetres.
        for shift in [
            [2_000_000_000, -1_999_999_999, 1],
            [512_400, -512_600, 511_999],
            [1, 2, 3],
        ] {
            assert_eq!(placed(shift, rotation), home, "{shift:?}");
        }
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
