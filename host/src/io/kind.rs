//! What an input is: the one place that decides (every reader of inputs asks [`InputKind::of`]).

use std::path::Path;

/// What a path given as input names. Decided here, once per input, from what it holds (a
/// registration file's first line, a bag's MCAP magic or rosbag2 directory), never from its
/// name; `-` is standard input, which is read as a cloud.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputKind {
    /// `-`: a cloud on standard input.
    StandardInput,
    /// A registration file (`.conf`): scans and their poses.
    Registration,
    /// A ROS 2 bag: an MCAP file or a rosbag2 directory.
    Bag,
    /// Anything else, read as a cloud file (PLY, PCD, LAS/LAZ, XYZ, KITTI), which its reader
    /// recognises by content or refuses.
    Cloud,
}

impl InputKind {
    /// What `path` is.
    pub fn of(path: &Path) -> Self {
        if path == Path::new(crate::io::read::STDIN) {
            Self::StandardInput
        } else if crate::io::conf::is_registration(path) {
            Self::Registration
        } else if crate::io::bag::is_bag(path) {
            Self::Bag
        } else {
            Self::Cloud
        }
    }
}
