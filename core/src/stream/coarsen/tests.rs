use super::*;
use crate::fit::FitParams;
use crate::geometry::Point3;
use crate::moments::{FixedMoments, Moments};
use crate::stream::{Pacing, StreamParams};
use crate::test_support::{OrFail, TestResult};

/// A uniform grid of `n x m` points spaced `step` on a plane through `center`, spanned by the
/// unit vectors `u` and `v`.
fn patch(
    center: [f64; 3],
    u: [f64; 3],
    v: [f64; 3],
    n: usize,
    m: usize,
    step: f64,
) -> heapless::Vec<[f64; 3], 1200> {
    let mut out = heapless::Vec::new();
    for i in 0..n {
        for j in 0..m {
            let (s, t) = (
                (i as f64 - (n - 1) as f64 / 2.0) * step,
                (j as f64 - (m - 1) as f64 / 2.0) * step,
            );
            let _ = out.push([0, 1, 2].map(|k| center[k] + s * u[k] + t * v[k]));
        }
    }
    out
}

fn frozen_shell(points: &[[f64; 3]]) -> Option<FrozenEntity> {
    let mut m = FixedMoments::new();
    for p in points {
        m.add(Point3::new(p[0] as f32, p[1] as f32, p[2] as f32));
    }
    let e = crate::stream::shells::shell_of(&m, &ShellParams::DEFAULT)?;
    Some(FrozenEntity::of(&e))
}

fn semi_axes(e: &Entity) -> [f64; 3] {
    e.weights.map(|w| 1.0 / libm::sqrt(f64::from(w)))
}

/// Two patches of one sampling density (a scanner's, at one range): the merged shell of their
/// frozen shells is the shell of all their points, from direct f64 sums over the points.
#[test]
fn a_merged_pair_is_the_shell_of_both_patches_points() -> TestResult {
    let tilt = libm::sqrt(0.5);
    let a = patch(
        [1000.0, -20.0, 3.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        40,
        20,
        0.01,
    );
    let b = patch(
        [1000.3, -19.9, 3.05],
        [tilt, tilt, 0.0],
        [0.0, 0.0, 1.0],
        30,
        30,
        0.01,
    );
    let (fa, fb) = (
        frozen_shell(&a).or_fail("a")?,
        frozen_shell(&b).or_fail("b")?,
    );
    let merged = merged(&fa, &fb, &ShellParams::DEFAULT).or_fail("merged")?;
    let mut direct = Moments::with_shift([1000.0, -20.0, 3.0]);
    for p in a.iter().chain(b.iter()) {
        direct.add_f64(*p);
    }
    let (mean, covariance) = direct.covariance().or_fail("covariance")?;
    let expected = crate::shell::shell(mean, covariance, &ShellParams::DEFAULT).or_fail("shell")?;
    let extent = semi_axes(&expected)[0];
    for (got, want) in merged
        .center
        .to_array()
        .iter()
        .zip(expected.center.to_array())
    {
        assert!(
            libm::fabs(f64::from(*got) - f64::from(want)) < 1e-3 * extent,
            "{:?} {:?}",
            merged.center,
            expected.center
        );
    }
    for (got, want) in semi_axes(&merged).iter().zip(semi_axes(&expected)) {
        assert!(
            libm::fabs(got - want) < 0.01 * want.max(0.05 * extent),
            "{got} {want}"
        );
    }
    // The same principal axes (each up to its sign).
    let (rm, re) = (merged.rotation.matrix(), expected.rotation.matrix());
    for j in 0..2 {
        let dot: f64 = (0..3).map(|i| rm[i][j] * re[i][j]).sum();
        assert!(libm::fabs(dot) > 0.999, "axis {j}: {dot}");
    }
    Ok(())
}

/// Two walls meeting at a corner are not one plane: their merged shell would be a slab as thick
/// as the walls are wide, so coarsening leaves them apart ([`THICKENING`]); two halves of one
/// wall merge into a shell as thin as theirs, and two lone points (shells of no thickness to
/// bound by) merge into a segment ([`FLATNESS`]).
#[test]
fn a_corner_is_not_coarsened_into_a_slab() -> TestResult {
    let wall = |center: [f64; 3], v: [f64; 3]| patch(center, [0.0, 0.0, 1.0], v, 20, 20, 0.01);
    let (x, y) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    // Each 19 cm square, about 1 mm thick as a scanner's noise would leave it.
    let noisy = |mut pts: heapless::Vec<[f64; 3], 1200>, across: usize| {
        for (i, p) in pts.iter_mut().enumerate() {
            p[across] += if i % 2 == 0 { 0.001 } else { -0.001 };
        }
        pts
    };
    let left = frozen_shell(&noisy(wall([0.0, 0.1, 0.0], y), 0)).or_fail("left")?;
    let right = frozen_shell(&noisy(wall([0.1, 0.0, 0.0], x), 1)).or_fail("right")?;
    let further = frozen_shell(&noisy(wall([0.0, 0.3, 0.0], y), 0)).or_fail("further")?;
    let thin = |e: &Entity| semi_axes(e).iter().fold(f64::MAX, |m, &r| m.min(r));
    let params = ShellParams::DEFAULT;
    // The merge itself is a slab: the bound, not the merge, keeps the corner apart.
    let slab = merged(&left, &right, &params).or_fail("slab")?;
    let walls = [left, right].map(|e| thin(&e.to_entity()));
    assert!(
        thin(&slab) > f64::from(THICKENING) * walls[0].max(walls[1]),
        "{} {walls:?}",
        thin(&slab)
    );
    assert!(merged_thin(&left, &right, &params).is_none());
    let wall = merged_thin(&left, &further, &params).or_fail("one wall")?;
    assert!(thin(&wall) < 2.0 * walls[0], "{} {walls:?}", thin(&wall));
    let lone = [0.0, 0.2].map(|x| frozen_shell(&[[x, 0.0, 0.0]]));
    let [Some(near), Some(far)] = lone else {
        return Err("lone points");
    };
    assert!(merged_thin(&near, &far, &params).is_some());
    Ok(())
}

fn params(model: StreamModel, working: usize, frozen: usize) -> StreamParams {
    StreamParams {
        fit: FitParams::default(),
        seed: 0,
        max_clusters: working,
        max_frozen: frozen,
        refit_interval: 64,
        tolerance: 0.0,
        model,
        pacing: Pacing::NONE,
        final_clusters: 0,
    }
}

/// A scanner sweeping a 30 m strip of ground once, 12,000 points, rows across it.
fn long_sweep() -> heapless::Vec<Point3, 12_000> {
    let mut out = heapless::Vec::new();
    for row in 0..600 {
        for col in 0..20 {
            let x = row as f32 * 0.05;
            let y = col as f32 * 0.05;
            let _ = out.push(Point3::new(x, y, 0.01 * libm::sinf(x)));
        }
    }
    out
}

type Small = StreamMapper<8, 64, 16>;

/// A small store on a long sweep: the first clusters frozen are coarsened as the sweep goes on,
/// so the map keeps every third of the strip (without it, the store is full early on and
/// the rest of the strip has only the working clusters).
#[test]
fn a_long_sweep_keeps_every_third_of_it() {
    let mut m = Small::new(params(StreamModel::Shells(ShellParams::DEFAULT), 8, 16));
    for &p in &long_sweep() {
        m.add(p);
    }
    m.finish();
    let mut thirds = [0usize; 3];
    for f in m.frozen() {
        let third = (f.entity.center.x / 10.0) as usize;
        if let Some(t) = thirds.get_mut(third) {
            *t += 1;
        }
    }
    assert!(thirds.iter().all(|&t| t > 0), "{thirds:?}");
    assert!(m.stats().coarsened > 0);
    assert_eq!(m.frozen().len(), 16);
}

/// The paper's model freezes axis-aligned fits, which stand for no covariance: never coarsened.
#[test]
fn the_papers_model_never_coarsens() {
    let mut m = Small::new(params(StreamModel::Paper, 8, 16));
    for &p in &long_sweep() {
        m.add(p);
    }
    assert_eq!(m.stats().coarsened, 0);
    assert!(m.stats().frozen > 0 && m.frozen().len() <= 16);
}

/// A downlink's copy of the frozen store, kept as the firmware keeps it (retract what the
/// store no longer has, resend each slot marked changed, send the new ones), equals the store
/// after every point while coarsening merges and moves its slots.
#[test]
fn a_copy_that_follows_the_changed_slots_is_the_store() -> TestResult {
    let mut m = Small::new(params(StreamModel::Shells(ShellParams::DEFAULT), 8, 16));
    let mut copy: heapless::Vec<FrozenEntity, 16> = heapless::Vec::new();
    for &p in &long_sweep() {
        m.add(p);
        copy.truncate(m.frozen().len());
        while let Some(i) = m.take_changed(copy.len()) {
            *copy.get_mut(i).or_fail("sent slot")? = *m.frozen().get(i).or_fail("slot")?;
        }
        copy.extend_from_slice(m.frozen().get(copy.len()..).or_fail("new")?)
            .or_fail("room")?;
        assert_eq!(copy.as_slice(), m.frozen());
    }
    assert!(m.stats().coarsened > 0);
    Ok(())
}

#[test]
fn coarsening_gives_the_same_map_whatever_the_batching() {
    let pts = long_sweep();
    let model = StreamModel::Shells(ShellParams::DEFAULT);
    let mut whole = Small::new(params(model, 8, 16));
    whole.add_all(&pts);
    whole.finish();
    let mut pieces = Small::new(params(model, 8, 16));
    for chunk in pts.chunks(17) {
        pieces.add_all(chunk);
    }
    pieces.finish();
    assert!(whole.stats().coarsened > 0);
    assert!(whole.entities().eq(pieces.entities()));
}

/// The sweep lists the pairs a search of every pair lists: the same cheapest candidates within
/// reach, in the same order, from a store scattered in 3D with shells of every orientation
/// (the three axes each in turn the thin one) and centres in no order along any axis, spread
/// along y so that one scan's distances take in the whole store.
#[test]
fn the_sweep_lists_what_a_search_of_every_pair_lists() -> TestResult {
    let mut m = StreamMapper::<8, 64, 600>::new(params(StreamModel::shells(0.01), 8, 600));
    let mut rng = crate::rng::stream_rng(7, 0);
    let mut next = move || crate::rng::uniform(&mut rng) as f32;
    for i in 0..550 {
        let center = Point3::new(5.0 * next(), 100.0 * next(), 2.0 * next());
        let mut weights = [
            1.0 / (0.3 + next()).powi(2),
            1.0 / (0.3 + next()).powi(2),
            0.0,
        ];
        weights[2] = 1.0 / (0.01 + 0.05 * next()).powi(2);
        weights.rotate_left(i % 3);
        let e = FrozenEntity {
            entity: crate::geometry::AxisEntity { center, weights },
            rotation: 0,
        };
        m.frozen.push(e).map_err(|_| "room")?;
    }
    m.radius = 0.4;
    m.scan_frozen_pairs(2.0);
    // The whole store in one scan, along y, the longest side.
    assert_eq!(m.coarsening.row, 550);
    let reach = m.coarsening.reach * m.radius;
    let mut every = ClosestPairs::<LISTED>::new(LISTED);
    for (a, ea) in m.frozen.iter().enumerate() {
        for (b, eb) in m.frozen.iter().enumerate().skip(a + 1) {
            let d2 = ea.entity.center.distance_squared(eb.entity.center);
            if d2 > reach * reach {
                continue;
            }
            let (Some(pa), Some(pb)) = (Plane::of(ea, 2.0), Plane::of(eb, 2.0)) else {
                continue;
            };
            if let Some(c) = cost(&pa, &pb, d2) {
                every.offer(a, b, c);
            }
        }
    }
    assert_eq!(every.len, LISTED);
    assert!(m.coarsening.pending.iter().eq(every.iter()));
    Ok(())
}

/// Once the store is full, a freeze that must scan for pairs first is dearer than a merge pass.
/// A point that wants room with its credit between the two waits for the freeze (it joins near,
/// paced) rather than run the merge pass, which would widen the join radius for good.
#[test]
fn a_merge_pass_never_stands_in_for_a_freeze_short_of_credit() {
    let pacing = Pacing::DEVICE_SHELLS;
    let mut m = Small::new(StreamParams {
        pacing,
        ..params(StreamModel::Shells(ShellParams::DEFAULT), 8, 16)
    });
    let dearest = 2 * pacing.freeze + pacing.scan;
    assert!(dearest > pacing.merge_pass && dearest <= pacing.burst);
    let mut waited = 0;
    let pts = long_sweep();
    let pts_len = pts.len() as u64;
    for &p in &pts {
        let credit = pacing.earn(m.credit);
        let in_gap = m.store_full()
            && !m.freeze_failed
            && m.coarsening.spent()
            && (pacing.merge_pass..dearest).contains(&credit);
        let (merges, paced) = (
            m.stats().merges,
            m.stats().paced_joins + m.stats().paced_shed,
        );
        m.add(p);
        if in_gap {
            assert_eq!(m.stats().merges, merges, "a merge pass at credit {credit}");
            waited += m.stats().paced_joins + m.stats().paced_shed - paced;
        }
    }
    assert!(waited > 0, "no point wanted room in the gap");
    // A freeze that cannot be made still gives way to a merge pass: the radius, nothing at the
    // start, grows, and the points keep finding clusters (waiting for good, every point after
    // the store filled was shed).
    assert!(
        m.stats().coarsened > 0 && m.stats().merges > 0,
        "{:?}",
        m.stats()
    );
    assert!(m.stats().paced_shed < pts_len / 10, "{:?}", m.stats());
}

/// Prices whose burst can never pay for a full store's freeze with a scan: that freeze is not
/// waited for, and a point that wants room gets a merge pass (waiting, none would ever run).
#[test]
fn a_freeze_the_burst_cannot_pay_for_is_not_waited_for() -> TestResult {
    let pacing = Pacing {
        freeze: 24,
        merge_pass: 80,
        scan: 48,
        burst: 90,
    };
    let mut m = Small::new(StreamParams {
        pacing,
        ..params(StreamModel::Shells(ShellParams::DEFAULT), 8, 16)
    });
    let pts = long_sweep();
    let mut rest = pts.iter();
    for &p in rest.by_ref() {
        m.add(p);
        if m.store_full() && m.coarsening.spent() {
            break;
        }
    }
    rest.next()
        .or_fail("the store filled before the sweep's end")?;
    // The most credit there can be, and no failed freeze to fall back on.
    m.credit = pacing.burst - 1;
    m.freeze_failed = false;
    let merges = m.stats().merges;
    m.add(Point3::new(1_000.0, 0.0, 0.0));
    assert_eq!(m.stats().merges, merges + 1);
    Ok(())
}
