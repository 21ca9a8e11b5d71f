//! A robot driving through the demo scene: the rangefinder of [`super::scene`] on a moving base,
//! scanning at poses along a path. Each scan is kept in its sensor's frame with the pose that
//! takes it to the world, as a robot's sensor delivers it; `mema scanner-sim` without a cloud
//! sends these, and `mema demo --moving` maps them.
//!
//! The path is an arc around the person, the sensor always turned towards them, so the scans see
//! the objects from the front and from both sides: no single view covers what the map holds,
//! and a map that put a view in the wrong place would show it twice.

use super::scene::{Scan, ScanConfig, Scene, scan_labelled};

type V3 = [f64; 3];

/// Where the robot drives and what its rangefinder sees at each stop.
#[derive(Clone, Debug, PartialEq)]
pub struct DriveConfig {
    /// The point the arc turns around and the sensor looks at (metres, world frame).
    pub centre: [f64; 2],
    /// The arc's radius (metres).
    pub radius: f64,
    /// The first and last bearing of the robot as seen from `centre` (radians about +z, from +x).
    pub bearings: (f64, f64),
    /// Scans along the arc, equally spaced in bearing.
    pub stops: usize,
    /// The sensor's height above the floor (metres).
    pub height: f64,
    /// The rangefinder at each stop: its azimuth range is taken about the sensor's heading; its
    /// seed is offset by the stop's index.
    pub rangefinder: ScanConfig,
    /// Someone walking across the robot's path: where they stand at the first stop and at the
    /// last (metres on the floor), evenly between at the others. `None`: nobody moves.
    pub walker: Option<[[f64; 2]; 2]>,
}

impl Default for DriveConfig {
    /// Eight stops on a 2.2 m arc from 125 to 235 degrees around the person: the first looks at
    /// the scene from the left front, the last from the right front. The rangefinder is the
    /// static demo's Hokuyo-class scanner (5 mm range noise, 10 m range) over a 50 x 48 degree
    /// field at 0.6 degree steps, about 3,500 points a stop, 27,000 in all like the static scan.
    fn default() -> Self {
        let half_width = 25f64.to_radians();
        Self {
            centre: [2.6, 0.0],
            radius: 2.2,
            bearings: (125f64.to_radians(), 235f64.to_radians()),
            stops: 8,
            height: 1.2,
            rangefinder: ScanConfig {
                azimuth_steps: 84,
                elevation_steps: 80,
                azimuth_range: (-half_width, half_width),
                elevation_range: (-36f64.to_radians(), 12f64.to_radians()),
                ..ScanConfig::default()
            },
            walker: None,
        }
    }
}

/// A drive with someone walking across the robot's line of sight, in a room
/// ([`Scene::with_walls`]): from beside the box towards the right wall, so each place they
/// stood in view is seen through by two stops after it and the last stops no longer see them;
/// the rangefinder looks 24 degrees up (not 12), so the stops after still see the walker's
/// whole height. The scene is [`room`].
pub fn walking() -> DriveConfig {
    let mut config = DriveConfig {
        walker: Some([[1.9, 0.3], [1.9, -2.1]]),
        ..DriveConfig::default()
    };
    config.rangefinder.elevation_steps = 100;
    config.rangefinder.elevation_range = (-36f64.to_radians(), 24f64.to_radians());
    config
}

/// The scene of the walking drive ([`walking`]): the demo scene in a room.
pub fn room() -> Scene {
    Scene::demo().with_walls()
}

/// One stop of the drive.
#[derive(Clone, Debug, PartialEq)]
pub struct DriveScan {
    /// The sensor's position in the world (metres).
    pub translation: V3,
    /// The sensor's heading: radians about +z from +x. Sensor to world is the turn by `yaw`
    /// about z, then `translation`.
    pub yaw: f64,
    /// The points in the sensor's frame (x ahead, z up, metres), in scan order.
    pub points: Vec<V3>,
    /// The world-frame scan they came from: the rays it cast and what it hit.
    pub world: Scan,
    /// Whether each point fell on the walker.
    pub on_walker: Vec<bool>,
    /// The rangefinder as it was set at this stop (world-frame azimuths, sensor position).
    pub config: ScanConfig,
}

impl DriveScan {
    /// The pose's rotation as a unit quaternion `[x, y, z, w]` (scalar last), sensor to world.
    pub fn rotation(&self) -> [f64; 4] {
        let h = 0.5 * self.yaw;
        [0.0, 0.0, libm::sin(h), libm::cos(h)]
    }
}

/// The scans of the drive, stop by stop.
pub fn drive(scene: &Scene, config: &DriveConfig) -> Vec<DriveScan> {
    (0..config.stops)
        .map(|i| {
            let t = if config.stops > 1 {
                i as f64 / (config.stops - 1) as f64
            } else {
                0.5
            };
            let bearing = config.bearings.0 + t * (config.bearings.1 - config.bearings.0);
            let position = [
                config.centre[0] + config.radius * libm::cos(bearing),
                config.centre[1] + config.radius * libm::sin(bearing),
                config.height,
            ];
            // Facing the centre: the bearing turned half a turn.
            let yaw = bearing - std::f64::consts::PI;
            let (lo, hi) = config.rangefinder.azimuth_range;
            let stop = ScanConfig {
                sensor: position,
                azimuth_range: (yaw + lo, yaw + hi),
                seed: config.rangefinder.seed.wrapping_add(i as u64),
                ..config.rangefinder.clone()
            };
            let here = config.walker.map(|[from, to]| {
                scene.with_walker([0, 1].map(|j| from[j] + t * (to[j] - from[j])))
            });
            let seen = here.as_ref().unwrap_or(scene);
            let (world, labels) = scan_labelled(seen, &stop);
            let on_walker = labels.iter().map(|&l| seen.is_walker(l)).collect();
            let (s, c) = (libm::sin(yaw), libm::cos(yaw));
            // R(yaw)^T (p - t): the world point in the sensor's frame.
            let points = world
                .points
                .iter()
                .map(|p| {
                    let d = [p[0] - position[0], p[1] - position[1], p[2] - position[2]];
                    [c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]]
                })
                .collect();
            DriveScan {
                translation: position,
                yaw,
                points,
                world,
                on_walker,
                config: stop,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sensor-frame points, turned by the pose's quaternion and moved by its translation,
    /// are the world scan's points again.
    #[test]
    fn the_pose_takes_each_scan_back_to_the_world() {
        let scans = drive(&Scene::demo(), &DriveConfig::default());
        assert_eq!(scans.len(), 8);
        let total: usize = scans.iter().map(|s| s.points.len()).sum();
        assert!((20_000..40_000).contains(&total), "{total} points");
        for s in &scans {
            assert!(s.points.len() > 1_000, "{} points", s.points.len());
            let [x, y, z, w] = s.rotation();
            // The rotation matrix of q, written out.
            let m = [
                [
                    1.0 - 2.0 * (y * y + z * z),
                    2.0 * (x * y - z * w),
                    2.0 * (x * z + y * w),
                ],
                [
                    2.0 * (x * y + z * w),
                    1.0 - 2.0 * (x * x + z * z),
                    2.0 * (y * z - x * w),
                ],
                [
                    2.0 * (x * z - y * w),
                    2.0 * (y * z + x * w),
                    1.0 - 2.0 * (x * x + y * y),
                ],
            ];
            for (p, q) in s.points.iter().zip(&s.world.points) {
                for i in 0..3 {
                    let back = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + s.translation[i];
                    assert!((back - q[i]).abs() < 1e-12, "{back} vs {}", q[i]);
                }
            }
            // Ahead of the sensor: every point has x > 0 in its frame.
            assert!(s.points.iter().all(|p| p[0] > 0.0));
        }
    }
}
