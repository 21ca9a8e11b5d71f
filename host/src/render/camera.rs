//! Where `mema draw` looks from: the views, which world axis is up, the orthographic camera and
//! the frame that takes world points to pixels.
//!
//! The projection is the contract the tests use: with `p` a world point, `o` the frame's
//! origin, pixel column `x = offset[0] + scale ((p - o) · right)` and row
//! `y = offset[1] - scale ((p - o) · up)`; pixel (i, j) covers `[i, i+1) x [j, j+1)`.
//! Every camera keeps `right × up = -forward`.

use serde::Serialize;

use crate::error::ConfigError;

/// The direction a picture looks along. The world views are named for a z-up world and turn
/// with [`Up`]; `Sensor` looks along the sensor's own axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum View {
    /// Along (-1, 1, -1): x and y recede to the right and left, z up.
    Iso,
    /// Down the z axis: x right, y up.
    Top,
    /// Along +y: x right, z up.
    Front,
    /// Along -x: y right, z up.
    Side,
    /// Along +z from the sensor, as a depth camera sees: x right and y down (the camera-frame
    /// convention), or the `--up` axis up when one is given.
    Sensor,
    /// Along +x, a z-up lidar's forward (ROS's REP 103): y to the left, z up. A lidar's z is
    /// up, so the sensor view would look at its sky; this looks along its horizon.
    Horizon,
}

/// The world axis that points up in the picture (scans are z-up, many meshes and camera
/// frames y-up).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Up {
    X,
    Y,
    Z,
}

impl Up {
    /// The world axis's index.
    pub fn axis(self) -> usize {
        match self {
            Up::X => 0,
            Up::Y => 1,
            Up::Z => 2,
        }
    }

    /// A right-handed basis whose third vector is this axis: a z-up camera written in it looks
    /// at a world that has this axis up. For y up the first stays x, so `front` looks along -z
    /// with x right and y up, as a y-up renderer's default camera does.
    fn basis(self) -> [[f64; 3]; 3] {
        match self {
            Up::Z => [[1., 0., 0.], [0., 1., 0.], [0., 0., 1.]],
            Up::Y => [[1., 0., 0.], [0., 0., -1.], [0., 1., 0.]],
            Up::X => [[0., 1., 0.], [0., 0., 1.], [1., 0., 0.]],
        }
    }
}

/// An orthographic camera: unit screen axes and the viewing direction (into the screen).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Camera {
    pub right: [f64; 3],
    pub up: [f64; 3],
    pub forward: [f64; 3],
}

impl View {
    /// The view's name, as `--json` and the command line spell it.
    pub fn name(self) -> &'static str {
        match self {
            View::Iso => "iso",
            View::Top => "top",
            View::Front => "front",
            View::Side => "side",
            View::Sensor => "sensor",
            View::Horizon => "horizon",
        }
    }

    /// The view's orthographic camera in a z-up world (the sensor's with y down).
    pub fn camera(self) -> Camera {
        let (s2, s3, s6) = (2f64.sqrt(), 3f64.sqrt(), 6f64.sqrt());
        match self {
            View::Top => Camera {
                right: [1., 0., 0.],
                up: [0., 1., 0.],
                forward: [0., 0., -1.],
            },
            View::Front => Camera {
                right: [1., 0., 0.],
                up: [0., 0., 1.],
                forward: [0., 1., 0.],
            },
            View::Side => Camera {
                right: [0., 1., 0.],
                up: [0., 0., 1.],
                forward: [-1., 0., 0.],
            },
            View::Iso => Camera {
                right: [1. / s2, 1. / s2, 0.],
                up: [-1. / s6, 1. / s6, 2. / s6],
                forward: [-1. / s3, 1. / s3, -1. / s3],
            },
            View::Sensor => Camera {
                right: [1., 0., 0.],
                up: [0., -1., 0.],
                forward: [0., 0., 1.],
            },
            View::Horizon => Camera {
                right: [0., -1., 0.],
                up: [0., 0., 1.],
                forward: [1., 0., 0.],
            },
        }
    }

    /// The camera with `up` (if given) pointing up in the picture. The world views default to
    /// z; the sensor view to the camera frame's -y, and it cannot have z up, its own axis.
    pub fn camera_with(self, up: Option<Up>) -> Result<Camera, ConfigError> {
        match (self, up) {
            (View::Sensor, None) => Ok(self.camera()),
            (View::Sensor, Some(Up::Z)) => Err(ConfigError::UpAlongView),
            (View::Sensor, Some(up)) => {
                let forward = [0., 0., 1.];
                let mut upv = [0.; 3];
                upv[up.axis()] = 1.;
                // right = forward × up keeps right × up = -forward.
                Ok(Camera {
                    right: cross(forward, upv),
                    up: upv,
                    forward,
                })
            }
            (_, up) => {
                let [e1, e2, e3] = up.unwrap_or(Up::Z).basis();
                let turn =
                    |v: [f64; 3]| [0, 1, 2].map(|j| v[0] * e1[j] + v[1] * e2[j] + v[2] * e3[j]);
                let c = self.camera();
                Ok(Camera {
                    right: turn(c.right),
                    up: turn(c.up),
                    forward: turn(c.forward),
                })
            }
        }
    }
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The share of points at each end of a screen axis a dense frame may leave out.
pub const DENSE_TAIL: f64 = 0.005;
/// How many times wider than its dense part a cloud's whole range must be for the frame to
/// hold the dense part only.
pub const STRAY_SPAN: f64 = 2.5;

/// What a picture must hold, on the screen plane: the range of `p · right` (`s`) and of
/// `p · up` (`t`) over the points and the entities' silhouettes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extent {
    pub s: [f64; 2],
    pub t: [f64; 2],
}

impl Extent {
    /// Holds nothing yet.
    pub const EMPTY: Extent = Extent {
        s: [f64::INFINITY, f64::NEG_INFINITY],
        t: [f64::INFINITY, f64::NEG_INFINITY],
    };

    /// The extent of `points` (local to the frame's origin) seen by `camera`.
    pub fn of_points(camera: &Camera, points: &[[f64; 3]]) -> Self {
        let mut e = Self::EMPTY;
        for p in points {
            e.include(dot(*p, camera.right), dot(*p, camera.up));
        }
        e
    }

    /// The extent of where `points` are dense: on each screen axis, the range from the
    /// [`DENSE_TAIL`] quantile to its complement, widened by a twentieth on each side, in place
    /// of the whole range where that is over [`STRAY_SPAN`] times wider (a lidar sweep's few
    /// returns hundreds of metres out around a street tens of metres wide). A compact cloud
    /// keeps its whole range, so nothing of it is cut.
    pub fn of_dense_points(camera: &Camera, points: &[[f64; 3]]) -> Self {
        let whole = Self::of_points(camera, points);
        let axis = |v: [f64; 3], range: [f64; 2]| -> [f64; 2] {
            let mut values: Vec<f64> = points.iter().map(|p| dot(*p, v)).collect();
            values.retain(|x| x.is_finite());
            if values.len() < 100 {
                return range;
            }
            let at = |q: f64, values: &mut Vec<f64>| {
                let i = ((values.len() - 1) as f64 * q).round() as usize;
                *values.select_nth_unstable_by(i, f64::total_cmp).1
            };
            let (lo, hi) = (
                at(DENSE_TAIL, &mut values),
                at(1.0 - DENSE_TAIL, &mut values),
            );
            let pad = (hi - lo) / 20.0;
            let dense = [lo - pad, hi + pad];
            if range[1] - range[0] > STRAY_SPAN * (dense[1] - dense[0]) {
                dense
            } else {
                range
            }
        };
        Extent {
            s: axis(camera.right, whole.s),
            t: axis(camera.up, whole.t),
        }
    }

    /// Whether the screen point (s, t) lies in the extent.
    pub fn holds(&self, s: f64, t: f64) -> bool {
        (self.s[0]..=self.s[1]).contains(&s) && (self.t[0]..=self.t[1]).contains(&t)
    }

    /// Grows to hold the screen point (s, t); a non-finite one is left out.
    pub fn include(&mut self, s: f64, t: f64) {
        if s.is_finite() && t.is_finite() {
            self.s = [self.s[0].min(s), self.s[1].max(s)];
            self.t = [self.t[0].min(t), self.t[1].max(t)];
        }
    }

    /// The part of `other` inside this extent (empty where they do not meet).
    pub fn clamp(&self, other: &Extent) -> Extent {
        let cut = |a: [f64; 2], b: [f64; 2]| [b[0].max(a[0]), b[1].min(a[1])];
        let (s, t) = (cut(self.s, other.s), cut(self.t, other.t));
        if s[0] > s[1] || t[0] > t[1] {
            return Extent::EMPTY;
        }
        Extent { s, t }
    }

    /// Grows to hold `other`.
    pub fn union(&mut self, other: &Extent) {
        self.include(other.s[0], other.t[0]);
        self.include(other.s[1], other.t[1]);
    }
}

/// World to pixel for one panel (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Frame {
    pub origin: [f64; 3],
    #[serde(flatten)]
    pub camera: Camera,
    /// Pixels per metre.
    pub scale: f64,
    pub offset: [f64; 2],
}

impl Frame {
    /// Fits the projections of `points` (local to `origin`) into `plot` = [x, y, w, h].
    pub fn fit(origin: [f64; 3], camera: Camera, points: &[[f64; 3]], plot: [u32; 4]) -> Self {
        Self::fit_extent(origin, camera, &Extent::of_points(&camera, points), plot)
    }

    /// Fits `extent` into `plot` = [x, y, w, h], centred, as large as the plot allows.
    pub fn fit_extent(origin: [f64; 3], camera: Camera, extent: &Extent, plot: [u32; 4]) -> Self {
        let (mut e, [x, y, w, h]) = (*extent, plot.map(f64::from));
        if e.s[0] > e.s[1] {
            e = Extent {
                s: [0.0; 2],
                t: [0.0; 2],
            };
        }
        let ([s0, s1], [t0, t1]) = (e.s, e.t);
        let scale = (w / (s1 - s0).max(1e-12)).min(h / (t1 - t0).max(1e-12));
        let offset = [
            x + w / 2.0 - scale * (s0 + s1) / 2.0,
            y + h / 2.0 + scale * (t0 + t1) / 2.0,
        ];
        Frame {
            origin,
            camera,
            scale,
            offset,
        }
    }

    /// Pixel coordinates and depth of a point local to the frame's origin.
    pub fn project(&self, p: [f64; 3]) -> (f64, f64, f64) {
        let c = &self.camera;
        let x = self.offset[0] + self.scale * dot(p, c.right);
        let y = self.offset[1] - self.scale * dot(p, c.up);
        (x, y, dot(p, c.forward))
    }

    /// The local point on the screen plane (depth 0) under pixel coordinates (x, y).
    pub(crate) fn unproject(&self, x: f64, y: f64) -> [f64; 3] {
        let (s, t) = (
            (x - self.offset[0]) / self.scale,
            (self.offset[1] - y) / self.scale,
        );
        let c = &self.camera;
        [0, 1, 2].map(|j| s * c.right[j] + t * c.up[j])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every view, turned to every up axis, is a right-handed orthonormal camera
    /// (`right × up = -forward`) whose up is the axis asked for where the view looks
    /// level (front and side), and whose top view looks straight down that axis.
    #[test]
    fn cameras_turn_with_the_up_axis() {
        let views = [
            View::Iso,
            View::Top,
            View::Front,
            View::Side,
            View::Sensor,
            View::Horizon,
        ];
        for view in views {
            for up in [None, Some(Up::X), Some(Up::Y), Some(Up::Z)] {
                let Ok(c) = view.camera_with(up) else {
                    assert_eq!((view, up), (View::Sensor, Some(Up::Z)));
                    continue;
                };
                let rxu = cross(c.right, c.up);
                for (a, f) in rxu.iter().zip(c.forward) {
                    assert!((a + f).abs() < 1e-12, "{view:?} {up:?}");
                }
                for v in [c.right, c.up, c.forward] {
                    assert!((dot(v, v) - 1.0).abs() < 1e-12, "{view:?} {up:?}");
                }
                let axis = up.unwrap_or(Up::Z).axis();
                match view {
                    View::Front | View::Side | View::Horizon => {
                        assert_eq!(c.up[axis], 1.0, "{view:?} {up:?}")
                    }
                    View::Top => assert_eq!(c.forward[axis], -1.0, "{view:?} {up:?}"),
                    View::Iso => assert!(c.up[axis] > 0.8, "{view:?} {up:?}"),
                    View::Sensor => {
                        assert_eq!(c.forward, [0., 0., 1.]);
                        let want = if up.is_some() { 1.0 } else { -1.0 };
                        assert_eq!(c.up[if up.is_some() { axis } else { 1 }], want);
                    }
                }
            }
        }
        // A y-up world seen from the front is what a y-up renderer shows: x right, y up.
        let c = View::Front.camera_with(Some(Up::Y)).unwrap();
        assert_eq!((c.right, c.up), ([1., 0., 0.], [0., 1., 0.]));
    }
}
