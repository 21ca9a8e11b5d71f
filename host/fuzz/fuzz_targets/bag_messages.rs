//! Any bytes, decoded as the CDR of a ROS 2 message a bag holds (the first byte picks a
//! `sensor_msgs/msg/PointCloud2` or a `tf2_msgs/msg/TFMessage`; the MCAP container around them
//! is the `mcap` crate's): never a panic, and a point cloud whose layout checks yields exactly
//! height x width points.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mema::io::bag::pointcloud2::PointCloud2;
use mema::io::bag::tf::parse_tf_message;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, bytes)) = data.split_first() else {
        return;
    };
    if pick % 2 == 0 {
        let _ = parse_tf_message(bytes);
        return;
    }
    if let Ok(cloud) = PointCloud2::parse(bytes)
        && let Ok(layout) = cloud.layout()
    {
        let n = cloud.points(layout).count() as u64;
        assert_eq!(n, cloud.slots());
    }
});
