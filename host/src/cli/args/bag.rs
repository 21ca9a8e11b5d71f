//! `--topic` and `--frame`: which messages of a ROS 2 bag make the cloud, and in which frame.

use clap::Args;
use mema::io::bag::BagOptions;

/// A ROS 2 bag's topic and frame, for every command that takes one (`map`, `replay`,
/// `stream-bench`).
#[derive(Args, Debug, Clone, Default)]
pub struct BagArg {
    /// ROS 2 bag (.mcap): the sensor_msgs/msg/PointCloud2 topic to read; default: the bag's
    /// only one.
    #[arg(long, value_name = "TOPIC")]
    pub topic: Option<String>,
    /// ROS 2 bag: put each message's points in this frame (e.g. world, map, odom) through the
    /// bag's /tf and /tf_static at the message's stamp (the latest transform at or before
    /// it); default: each message's points as they are.
    #[arg(long, value_name = "FRAME")]
    pub frame: Option<String>,
}

impl BagArg {
    /// The library's options.
    pub fn options(&self) -> BagOptions {
        BagOptions {
            topic: self.topic.clone(),
            frame: self.frame.clone(),
        }
    }

    /// Whether either was given.
    pub fn given(&self) -> bool {
        self.topic.is_some() || self.frame.is_some()
    }
}
