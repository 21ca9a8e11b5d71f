use super::*;

/// Every shared cloud and both registered sets, each set read as its scans in one frame
/// with a sensor origin per scan (what the streamed map is sent from).
#[test]
fn the_benchmark_takes_the_shared_clouds_and_sets() {
    let data = Path::new(crate::io::read::testkit::DATA);
    let names = cloud_files(data, &[]).expect("lists the shared data");
    for name in ["car6.pcd", "autzen_trim.laz", "bun.conf", "ouster_os1.conf"] {
        assert!(
            names.iter().any(|n| n == name),
            "{name} missing from {names:?}"
        );
    }
    assert!(
        names
            .iter()
            .all(|n| !n.ends_with(".md") && !n.ends_with(".txt"))
    );
    let (set, _) = load_cloud_in_metres(&data.join("bun.conf"), None).expect("reads");
    assert_eq!(
        set.sensors.origins.len(),
        5,
        "bun.conf registers five scans"
    );
    let only = cloud_files(data, &["bun.conf".to_string()]).expect("keeps one");
    assert_eq!(only, ["bun.conf"]);
}

/// The maps are made of the points `mema map` keeps: a few isolated returns fewer than the
/// finite points they are scored against, in the same order and place; a cloud with no
/// isolated point is mapped whole.
#[test]
fn maps_are_made_of_the_points_mema_map_keeps() {
    let data = Path::new(crate::io::read::testkit::DATA);
    let (scored, mapped) =
        scored_and_mapped(&data.join("ouster_os1_1.pcd")).expect("reads the sweep");
    let left_out = scored.points.len() - mapped.points.len();
    assert!(
        left_out > 0 && left_out * 200 < scored.points.len(),
        "{left_out} left out"
    );
    let world = |c: &LocalCloud, p: &mema_core::Point3| {
        let p = p.to_f64();
        [0, 1, 2].map(|j| c.origin[j] + p[j])
    };
    // Every mapped point is one of the file's finite points, in the file's order.
    let mut rest = scored.points.iter().map(|p| world(&scored, p));
    for p in mapped.points.iter().map(|p| world(&mapped, p)) {
        assert!(
            rest.any(|q| (0..3).all(|j| (q[j] - p[j]).abs() < 1e-4)),
            "{p:?} is not one of the file's points, in order"
        );
    }
    let (scored, mapped) = scored_and_mapped(&data.join("car6.pcd")).expect("reads car6");
    assert_eq!(scored.points, mapped.points);
}

#[test]
fn geometric_means() {
    assert_eq!(geometric_mean(&[0.5, 2.0]), Some(1.0));
    assert_eq!(geometric_mean(&[]), None);
    assert_eq!(geometric_mean(&[0.0, 1.0]), None);
}
