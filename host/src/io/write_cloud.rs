//! A cloud written as a file the readers take back: binary little-endian PLY, coordinates in
//! f64. Reading it gives the same local frame and the same f32 points as
//! [`crate::io::LocalCloud::from_world`] of the points written, so a map of the file is the map
//! of the points (`mema demo`'s scan maps to `mema demo`'s map, byte for byte).

use anyhow::Result;
use std::path::Path;

use super::mapfile::write_file_atomically;

/// The PLY file of `points` (world coordinates, metres).
///
/// ```
/// let bytes = mema::io::write_cloud::ply_bytes(&[[1.0, 2.0, 3.0], [4.0, 5.0, 6.5]]);
/// let cloud = mema::io::read::read_cloud_bytes("two.ply", &bytes)?;
/// assert_eq!(cloud.points.len(), 2);
/// assert_eq!(cloud.origin, [2.5, 3.5, 4.75]);
/// # Ok::<(), mema::io::read::ReadError>(())
/// ```
pub fn ply_bytes(points: &[[f64; 3]]) -> Vec<u8> {
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by mema, coordinates in metres\n\
         element vertex {}\nproperty double x\nproperty double y\nproperty double z\nend_header\n",
        points.len()
    );
    let mut bytes = Vec::with_capacity(header.len() + 24 * points.len());
    bytes.extend_from_slice(header.as_bytes());
    for p in points {
        for c in p {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    bytes
}

/// Writes `points` to `path` as [`ply_bytes`], atomically (whole or not at all).
pub fn write_ply(path: &Path, points: &[[f64; 3]]) -> Result<()> {
    write_file_atomically(path, &ply_bytes(points), "cloud")
}
