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

/// The maps are made of what `mema map` reads (its `points:` line on ouster_os1_1.pcd:
/// 107,253 read, 104 as isolated) and scored against every finite point.
#[test]
fn maps_are_made_of_the_points_mema_map_keeps() {
    let data = Path::new(crate::io::read::testkit::DATA);
    let (scored, mapped) =
        scored_and_mapped(&data.join("ouster_os1_1.pcd")).expect("reads the sweep");
    assert_eq!(
        (scored.points.len(), mapped.points.len()),
        (107_357, 107_253)
    );
    let (scored, mapped) = scored_and_mapped(&data.join("car6.pcd")).expect("reads car6");
    assert_eq!(scored.points, mapped.points);
}

#[test]
fn geometric_means() {
    assert_eq!(geometric_mean(&[0.5, 2.0]), Some(1.0));
    assert_eq!(geometric_mean(&[]), None);
    assert_eq!(geometric_mean(&[0.0, 1.0]), None);
}
