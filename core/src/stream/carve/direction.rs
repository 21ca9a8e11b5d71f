//! A return's pixel in a carver's image without the library's square root, arcsine and
//! arctangent, which on a Cortex-M4F cost more than the rest of a point's mapping: the same
//! pixels but at their edges (a direction within 10^-5 radians of an edge may fall on its
//! other side, where pixels are 0.7 degrees wide), the same on every target (IEEE single
//! precision operations only, none fused), so a device's image is its host's replay's.

use crate::free_space::Geometry;
use crate::geometry::Point3;
use crate::num::square_root;
use core::f32::consts::{FRAC_PI_2, PI};

/// The pixel of `p` in an image of `geometry` and its range (metres), as [`Geometry::pixel`]
/// gives them but for the approximations; `None` outside the image, at the origin, or
/// non-finite.
pub(super) fn pixel(geometry: &Geometry, p: Point3) -> Option<(usize, f32)> {
    let o = geometry.origin;
    let d = [p.x - o.x, p.y - o.y, p.z - o.z];
    let across = d[0] * d[0] + d[1] * d[1];
    let r = square_root(across + d[2] * d[2]);
    if !(r.is_finite() && r > 0.0) {
        return None;
    }
    let elevation = arctangent(d[2], square_root(across));
    let index = geometry.pixel_of(elevation, arctangent(d[1], d[0]))?;
    Some((index, r))
}

/// `atan2(y, x)` within 10^-5 radians: a polynomial on the first octant, the others by
/// symmetry; 0 at the origin, NaN for a NaN argument.
pub(super) fn arctangent(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let steep = ay > ax;
    let (small, large) = if steep { (ax, ay) } else { (ay, ax) };
    if large == 0.0 {
        return 0.0;
    }
    let t = small / large;
    let t2 = t * t;
    // Minimax on [0, 1] (Abramowitz and Stegun 4.4.49's form, degree 11).
    let mut a = t
        * (0.999_977_3
            + t2 * (-0.332_623_5
                + t2 * (0.193_543_5
                    + t2 * (-0.116_432_9 + t2 * (0.052_653_3 - t2 * 0.011_721_2)))));
    if steep {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    if y < 0.0 { -a } else { a }
}
