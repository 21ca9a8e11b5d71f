use super::*;
use crate::shell::ShellParams;

fn params(max_clusters: usize) -> StreamParams {
    StreamParams {
        fit: FitParams::default(),
        seed: 0,
        max_clusters,
        max_frozen: 0,
        refit_interval: 64,
        tolerance: 0.0,
        model: StreamModel::Paper,
        pacing: Pacing::NONE,
        final_clusters: 0,
    }
}

fn shells() -> [Point3; 2000] {
    // Four separated ellipsoid shells, points interleaved as a sweeping scanner would not.
    let mut pts = [Point3::default(); 2000];
    for (i, p) in pts.iter_mut().enumerate() {
        let shell = (i % 4) as f32;
        let t = i as f32 * 0.618;
        let u = i as f32 * 0.377;
        *p = Point3::new(
            10.0 * shell + 0.5 * libm::cosf(t) * libm::sinf(u),
            0.3 * libm::sinf(t) * libm::sinf(u),
            0.2 * libm::cosf(u),
        );
    }
    pts
}

#[test]
fn fills_capacity_and_merges_exactly() {
    let pts = shells();
    let mut m = StreamMapper::<16, 64>::new(params(8));
    m.add_all(&pts);
    m.finish();
    assert_eq!(m.clusters().len(), 8);
    // Every point is in exactly one cluster: merged moments lose nothing.
    let total: u64 = m.clusters().iter().map(|c| c.moments.count()).sum();
    assert_eq!(total, 2000);
    // Clusters never straddle two shells 10 apart: each centre sits on one shell.
    for c in m.clusters() {
        let x = c.center.x / 10.0;
        assert!((x - libm::roundf(x)).abs() < 0.06, "{:?}", c.center);
    }
    assert!(m.stats().merges > 0 && m.radius() > 0.0);
}

#[test]
fn same_points_same_map_whatever_the_batching() {
    let pts = shells();
    let mut whole = StreamMapper::<16, 64>::new(params(12));
    whole.add_all(&pts);
    whole.finish();
    let mut pieces = StreamMapper::<16, 64>::new(params(12));
    for chunk in pts.chunks(7) {
        pieces.add_all(chunk);
    }
    pieces.finish();
    assert!(whole.entities().eq(pieces.entities()));
}

#[test]
fn tolerance_mode_lets_the_tolerance_choose_k() {
    let pts = shells();
    let run = |tolerance: f64| {
        let mut m = StreamMapper::<256, 512>::new(StreamParams {
            tolerance,
            ..params(256)
        });
        m.add_all(&pts);
        m.finish();
        (m.clusters().len(), m.stats().forced_merges)
    };
    let (coarse, coarse_forced) = run(0.1);
    let (fine, fine_forced) = run(0.03);
    // Capacity to spare: nothing forced, and k well under it, larger for the tighter tolerance.
    assert_eq!((coarse_forced, fine_forced), (0, 0));
    assert!(
        coarse < fine && fine < 256,
        "k = {coarse} at 0.1, {fine} at 0.03"
    );
    // Four shells 10 apart never share a cluster, however loose the tolerance.
    assert!(coarse >= 4);
}

#[test]
fn non_finite_points_are_counted_not_stored() {
    let mut m = StreamMapper::<4, 8>::new(params(4));
    m.add(Point3::new(f32::NAN, 0.0, 0.0));
    m.add(Point3::new(1.0, f32::INFINITY, 0.0));
    m.add(Point3::new(1.0, 2.0, 3.0));
    assert_eq!(m.stats().non_finite, 2);
    assert_eq!(m.stats().points, 1);
    assert_eq!(m.clusters().len(), 1);
}

/// The shells' points one shell after another, as a scanner sweeping along x would send them.
fn swept_shells() -> [Point3; 2000] {
    let mut pts = shells();
    // Stable: each shell keeps its own order; x (10 * shell) decides between shells.
    crate::num::insertion_sort_by(&mut pts, |a, b| {
        libm::roundf(a.x / 10.0) < libm::roundf(b.x / 10.0)
    });
    pts
}

fn frozen_params(working: usize, frozen: usize) -> StreamParams {
    StreamParams {
        max_frozen: frozen,
        ..params(working)
    }
}

#[test]
fn a_sweep_freezes_the_clusters_it_leaves_behind() {
    let pts = swept_shells();
    let mut m = StreamMapper::<6, 64, 12>::new(frozen_params(6, 12));
    m.add_all(&pts);
    m.finish();
    let frozen = m.frozen();
    assert!(!frozen.is_empty(), "nothing frozen on a sweep");
    assert_eq!(m.stats().frozen, frozen.len() as u64);
    assert!(m.entities().count() <= 6 + 12);
    // Frozen clusters are whole fits of one shell each, and of the shells the sweep has left.
    for e in frozen.iter().map(|f| f.entity) {
        let x = e.center.x / 10.0;
        assert!((x - libm::roundf(x)).abs() < 0.06, "{:?}", e.center);
        assert!(
            libm::roundf(x) < 3.0,
            "the last shell is still under the sweep: {:?}",
            e.center
        );
        assert!(e.weights.iter().all(|w| w.is_finite() && *w >= 0.0));
    }
    // The entities come frozen first, then the working clusters.
    assert!(
        m.entities()
            .zip(frozen)
            .all(|(a, b)| a.entity == b.to_entity() && b.rotation == 0)
    );
}

#[test]
fn clusters_the_stream_keeps_visiting_are_never_frozen() {
    // Interleaved shells: every cluster gets points every few dozen, never idle for 8 turnovers.
    let mut m = StreamMapper::<6, 64, 12>::new(frozen_params(6, 12));
    m.add_all(&shells());
    m.finish();
    assert!(m.frozen().is_empty(), "{} frozen", m.frozen().len());
}

#[test]
fn no_room_to_freeze_is_the_plain_mapper_bit_for_bit() {
    let pts = swept_shells();
    let mut plain = StreamMapper::<8, 64>::new(params(8));
    let mut roomy = StreamMapper::<8, 64, 12>::new(frozen_params(8, 0));
    plain.add_all(&pts);
    roomy.add_all(&pts);
    plain.finish();
    roomy.finish();
    assert!(plain.entities().eq(roomy.entities()));
}

#[test]
fn freezing_gives_the_same_map_whatever_the_batching() {
    let pts = swept_shells();
    let mut whole = StreamMapper::<6, 64, 12>::new(frozen_params(6, 12));
    whole.add_all(&pts);
    whole.finish();
    let mut pieces = StreamMapper::<6, 64, 12>::new(frozen_params(6, 12));
    for chunk in pts.chunks(13) {
        pieces.add_all(chunk);
    }
    pieces.finish();
    assert!(!whole.frozen().is_empty());
    assert!(whole.entities().eq(pieces.entities()));
}

pub(crate) fn shells_params(working: usize, frozen: usize) -> StreamParams {
    StreamParams {
        model: StreamModel::Shells(ShellParams::DEFAULT),
        ..frozen_params(working, frozen)
    }
}

/// Tilted, so a shell must turn to follow each one: x and y mixed.
fn tilted_swept_shells() -> [Point3; 2000] {
    let mut pts = swept_shells();
    for p in pts.iter_mut() {
        *p = Point3::new(
            p.x + 0.4 * p.y,
            p.y - 0.4 * p.x + 4.0 * libm::roundf(p.x / 10.0),
            p.z,
        );
    }
    pts
}

#[test]
fn shells_are_the_shells_of_the_moments_with_no_refit() -> crate::test_support::TestResult {
    use crate::test_support::OrFail;
    let mut m = StreamMapper::<6, 64, 12>::new(shells_params(6, 12));
    let points = tilted_swept_shells();
    let (last, most) = points.split_last().or_fail("points")?;
    m.add_all(most);
    // Mid-stream, working entities are the shells of the moments as they stand, to the bit.
    let shells_now = |m: &StreamMapper<6, 64, 12>| -> crate::test_support::TestResult {
        let frozen = m.frozen().len();
        for (e, c) in m.entities().skip(frozen).zip(m.clusters()) {
            let want = shells::shell_of(&c.moments, &ShellParams::DEFAULT).or_fail("finite")?;
            assert_eq!(e.entity, want);
        }
        Ok(())
    };
    shells_now(&m)?;
    // Finished, they are the final moments' shells kept as a frozen entity is: the rotation to
    // its code, all else to the bit; a point after the finish makes them from the moments again.
    m.finish();
    let frozen = m.frozen().len();
    let kept: heapless::Vec<_, 6> = m
        .clusters()
        .iter()
        .map(|c| shells::shell_of(&c.moments, &ShellParams::DEFAULT).map(|s| FrozenEntity::of(&s)))
        .collect();
    for (e, k) in m.entities().skip(frozen).zip(&kept) {
        assert_eq!(Some(e.entity), k.map(|k| k.to_entity()));
    }
    assert!(kept.iter().flatten().any(|k| k.rotation != 0));
    let mut again = m.clone();
    again.add(*last);
    shells_now(&again)?;
    m.add(*last);
    m.finish();
    assert_eq!(m.stats().refits, 0);
    assert!(frozen > 0 && m.entities().count() == m.frozen().len() + m.clusters().len());
    // The shells turn: the sweep's clusters are tilted in x-y.
    assert!(m.entities().any(|e| !e.entity.rotation.is_identity()));
    // Frozen ones keep their rotation to the code's quarter degree, and it survives the file.
    assert!(m.frozen().iter().any(|f| f.rotation != 0));
    let mut file = [0u8; 48 + 14 * 18 + 4];
    let len = m.encode_into([0.0; 3], &mut file).or_fail("fits")?;
    let read =
        crate::map::MapFile::new_checked(file.get(..len).or_fail("len")?).or_fail("reads")?;
    let layout = m.layout();
    assert!(matches!(layout, crate::map::Layout::Quantized(_)));
    assert!(read.entities().eq(m.stored_entities(layout)));
    Ok(())
}

#[test]
fn shells_give_the_same_map_whatever_the_batching() {
    let pts = tilted_swept_shells();
    let mut whole = StreamMapper::<6, 64, 12>::new(shells_params(6, 12));
    whole.add_all(&pts);
    whole.finish();
    let mut pieces = StreamMapper::<6, 64, 12>::new(shells_params(6, 12));
    for chunk in pts.chunks(11) {
        pieces.add_all(chunk);
    }
    pieces.finish();
    assert!(!whole.frozen().is_empty());
    assert!(whole.entities().eq(pieces.entities()));
}

/// What became of each point: joined, opened a cluster, or shed by the pacing.
#[derive(Default)]
struct Fates {
    joined: u64,
    opened: u64,
    shed: u64,
}

impl Observer for Fates {
    fn joined(&mut self, _: usize) {
        self.joined += 1;
    }
    fn opened(&mut self, _: usize) {
        self.opened += 1;
    }
    fn shed(&mut self) {
        self.shed += 1;
    }
}

/// Points that are all new ground: along a line, each step 1% longer than the last, so no
/// point lies within the join radius that merging the earlier ones gave.
fn receding_line() -> [Point3; 3000] {
    let mut pts = [Point3::default(); 3000];
    let (mut x, mut step) = (0.0f32, 0.01f32);
    for (i, p) in pts.iter_mut().enumerate() {
        x += step;
        step *= 1.01;
        *p = Point3::new(x, 0.1 * (i % 7) as f32, 0.0);
    }
    pts
}

#[test]
fn pacing_bounds_the_costly_steps_by_the_points() {
    let pts = receding_line();
    let run = |pacing: Pacing| {
        let mut m = StreamMapper::<8, 64, 64>::new(StreamParams {
            pacing,
            ..frozen_params(8, 64)
        });
        let mut passes = 0u64;
        let mut worst = 0u64;
        let (mut window, mut window_points) = (0u64, 0u64);
        let mut fates = Fates::default();
        for &p in &pts {
            let (frozen, merges) = (m.stats().frozen, m.stats().merges);
            m.add_observed(p, &mut fates);
            let pass = u64::from(m.stats().merges > merges);
            passes += pass;
            // Credits spent in each stretch of 100 points, against what it earned plus the burst.
            window += (m.stats().frozen - frozen) * u64::from(pacing.freeze)
                + pass * u64::from(pacing.merge_pass);
            window_points += 1;
            if window_points == 100 {
                worst = worst.max(window);
                (window, window_points) = (0, 0);
            }
        }
        // Every point joined a cluster, opened one or was shed, and the shed ones are counted.
        assert_eq!(fates.joined + fates.opened + fates.shed, pts.len() as u64);
        assert_eq!(fates.shed, m.stats().paced_shed);
        (
            m.stats().frozen,
            passes,
            m.stats().paced_joins + m.stats().paced_shed,
            worst,
            m.stats().points,
        )
    };
    let (frozen, passes, joins, _, _) = run(Pacing::NONE);
    // Unpaced, the new ground asks for more freezes and merge passes than the points pay for.
    let demanded =
        frozen * u64::from(Pacing::DEVICE.freeze) + passes * u64::from(Pacing::DEVICE.merge_pass);
    assert!(
        demanded > 3 * pts.len() as u64 && joins == 0,
        "{frozen} {passes}"
    );
    let device = Pacing::DEVICE;
    let (frozen, passes, joins, worst, points) = run(device);
    let spent = frozen * u64::from(device.freeze) + passes * u64::from(device.merge_pass);
    assert!(
        spent <= pts.len() as u64 + u64::from(device.burst),
        "{spent}"
    );
    assert!(worst <= 100 + u64::from(device.burst), "{worst}");
    // The points the credit could not make room for joined a cluster within reach or were shed.
    assert!(joins > 100, "{joins}");
    assert_eq!(points, pts.len() as u64);
}

/// A point the credit cannot make room for joins a centre within [`PACED_REACH`] join radii,
/// and is shed beyond them, counted, leaving every cluster as it was.
#[test]
fn a_point_past_the_paced_reach_is_shed_and_counted() -> crate::test_support::TestResult {
    use crate::test_support::OrFail;
    let mut m = StreamMapper::<2, 64>::new(StreamParams {
        pacing: Pacing::DEVICE,
        ..params(2)
    });
    m.add(Point3::new(0.0, 0.0, 0.0));
    m.add(Point3::new(10.0, 0.0, 0.0));
    m.radius = 1.0;
    let mut fates = Fates::default();
    // 2.5 radii from the first centre, and the credit (3 points) short of a merge pass.
    m.add_observed(Point3::new(2.5, 0.0, 0.0), &mut fates);
    assert_eq!((fates.joined, m.stats().paced_joins), (1, 1));
    let before = *m.clusters().first().or_fail("cluster")?;
    // 3.5 radii from both: shed.
    m.add_observed(Point3::new(6.5, 0.0, 0.0), &mut fates);
    assert_eq!((fates.shed, m.stats().paced_shed), (1, 1));
    assert_eq!(m.clusters().len(), 2);
    assert_eq!(m.clusters().first(), Some(&before));
    assert_eq!(m.stats().points, 4);
    Ok(())
}

/// A mapper started again in place (a device's, when a glitched first pose is outvoted) maps
/// what follows exactly as a new mapper does: nothing of the points before is left, frozen
/// entities, pacing credit and counters included.
#[test]
fn a_mapper_started_again_is_a_new_mapper() {
    for params in [frozen_params(6, 12), shells_params(6, 12)] {
        let before = tilted_swept_shells();
        let after = swept_shells();
        let mut again = StreamMapper::<6, 64, 12>::new(params);
        again.add_all(&before);
        assert!(!again.frozen().is_empty());
        again.restart();
        again.add_all(&after);
        again.finish();
        let mut new = StreamMapper::<6, 64, 12>::new(params);
        new.add_all(&after);
        new.finish();
        assert!(again.entities().eq(new.entities()));
        assert_eq!(again.stats(), new.stats());
    }
}

/// Points on a coarse wire lattice (10 m units) over kilometres, on one layer of it: their
/// shells are thinner than four of the grid's steps (the lattice flattens them), so without the
/// wire's unit the map is kept in f32, and with it, quantized; the finest unit noted holds, and
/// a restart forgets it.
#[test]
fn shells_thinner_than_their_wire_unit_are_quantized() {
    let lattice = |i: u32| {
        let (a, b) = (i % 37, i / 37);
        Point3::new(
            10.0 * (a * 17 % 41) as f32 + 400.0 * (b % 5) as f32,
            10.0 * (a * 5 % 13) as f32 + 300.0 * (b / 5) as f32,
            0.0,
        )
    };
    let streamed = |unit: Option<f32>| {
        let mut m = StreamMapper::<64, 128, 64>::new(shells_params(16, 48));
        if let Some(unit) = unit {
            m.note_resolution(unit);
        }
        for i in 0..1_000 {
            m.add(lattice(i));
        }
        m.finish();
        m
    };
    assert!(!matches!(
        streamed(None).layout(),
        crate::map::Layout::Quantized(_)
    ));
    assert!(matches!(
        streamed(Some(10.0)).layout(),
        crate::map::Layout::Quantized(_)
    ));
    let mut m = streamed(Some(10.0));
    // A finer unit noted later holds; a coarser one or nonsense does not.
    for unit in [1e-3, 100.0, f32::NAN, -1.0, 0.0] {
        m.note_resolution(unit);
    }
    assert!(!matches!(m.layout(), crate::map::Layout::Quantized(_)));
    m.restart();
    assert_eq!(m.resolution, 0.0);
}
