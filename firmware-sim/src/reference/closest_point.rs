//! Distance to an axis-aligned ellipsoid's surface by Newton's method on the Lagrange condition.
//!
//! The closest point `x` to `y` on `sum_j x_j^2 / a_j^2 = 1` satisfies
//! `x_j = a_j^2 y_j / (a_j^2 + t)` for the multiplier `t`, the largest root of
//! `F(t) = sum_j a_j^2 y_j^2 / (a_j^2 + t)^2 - 1` on `(-a_min^2, inf)`, where `F` is convex and
//! decreasing. Newton from the left of the root climbs to it monotonically; a bracket keeps
//! every step inside. When the coordinate on the shortest axis is zero the root may not exist in
//! that interval (the point is inside the evolute): then `t = -a_min^2` and the closest point
//! leaves the coordinate plane. Infinite (degenerated) axes are dropped, so the same code does
//! ellipses and plane pairs.

/// Distance from `offset` (point minus centre, axis frame) to the surface with `semi_axes`.
pub fn distance(semi_axes: [f64; 3], offset: [f64; 3]) -> f64 {
    let axes: Vec<(f64, f64)> = semi_axes
        .iter()
        .zip(offset.iter())
        .filter(|(a, _)| a.is_finite() && **a > 0.0)
        .map(|(&a, &y)| (a, y.abs()))
        .collect();
    if axes.is_empty() {
        return 0.0;
    }
    let a_min = axes.iter().fold(f64::INFINITY, |m, &(a, _)| m.min(a));
    // The offset's length within the shortest axis (or axes, if several tie for shortest).
    let y_min = axes
        .iter()
        .filter(|(a, _)| *a == a_min)
        .map(|(_, y)| y * y)
        .sum::<f64>()
        .sqrt();
    let f = |t: f64| -> (f64, f64) {
        axes.iter().fold((-1.0, 0.0), |(v, d), &(a, y)| {
            // A zero coordinate contributes nothing, also at t = -a^2 (no 0/0).
            let u = if y == 0.0 { 0.0 } else { a * y / (a * a + t) };
            (v + u * u, d - 2.0 * u * u / (a * a + t))
        })
    };
    let lower = -a_min * a_min;
    let t = if y_min > 0.0 {
        // There the shortest axes' terms alone sum to 1, so F >= 0: left of the root.
        lower + a_min * y_min
    } else {
        // On the plane of the longer axes. With `t -> -a_min^2` the longer axes give
        // `x_j = a_j^2 y_j / (a_j^2 - a_min^2)`; if that point is inside the ellipse they span,
        // the closest point leaves the plane along the shortest axes (y inside the evolute).
        let inside: f64 = axes
            .iter()
            .filter(|(a, _)| *a > a_min)
            .map(|&(a, y)| (a * y / (a * a + lower)).powi(2))
            .sum();
        if inside <= 1.0 {
            let d2: f64 = axes
                .iter()
                .filter(|(a, _)| *a > a_min)
                .map(|&(a, y)| (a * a * y / (a * a + lower) - y).powi(2))
                .sum::<f64>()
                + a_min * a_min * (1.0 - inside);
            return d2.sqrt();
        }
        // Otherwise F(-a_min^2) = inside - 1 > 0 and the root lies to the right.
        lower
    };
    let mut t = t;
    let mut hi = f64::INFINITY;
    let mut lo = t;
    for _ in 0..200 {
        let (v, d) = f(t);
        if v > 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        if v == 0.0 || d == 0.0 {
            break;
        }
        let mut next = t - v / d;
        if !(next > lo && next < hi) {
            // A step out of the bracket: bisect (or double, while unbounded above).
            next = if hi.is_finite() {
                0.5 * (lo + hi)
            } else {
                lo + 2.0 * (lo - lower).max(1.0)
            };
        }
        if (next - t).abs() <= 1e-16 * t.abs().max(a_min * a_min) {
            t = next;
            break;
        }
        t = next;
    }
    axes.iter()
        .map(|&(a, y)| {
            let x = a * a * y / (a * a + t);
            (x - y) * (x - y)
        })
        .sum::<f64>()
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_forms() {
        let inf = f64::INFINITY;
        // Sphere of radius 2, point at distance sqrt(3): gap 2 - sqrt(3).
        assert!((distance([2.0; 3], [1.0, 1.0, 1.0]) - (2.0 - 3f64.sqrt())).abs() < 1e-14);
        // Outside along an axis.
        assert!((distance([3.0, 2.0, 1.0], [5.0, 0.0, 0.0]) - 2.0).abs() < 1e-14);
        // Centre of an ellipsoid: the shortest semi-axis.
        assert!((distance([3.0, 2.0, 1.0], [0.0, 0.0, 0.0]) - 1.0).abs() < 1e-14);
        // Pseudocylinder and plane pair.
        assert!((distance([1.0, 1.0, inf], [3.0, 0.0, 100.0]) - 2.0).abs() < 1e-14);
        assert!((distance([inf, inf, 0.5], [7.0, -3.0, -0.2]) - 0.3).abs() < 1e-14);
    }

    #[test]
    fn agrees_with_the_core_on_random_points() {
        let mut s = 1u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut worst = 0.0f64;
        for _ in 0..20_000 {
            let a = [0.1 + 2.0 * next(), 0.1 + 2.0 * next(), 0.1 + 2.0 * next()];
            let y = [4.0 * next() - 2.0, 4.0 * next() - 2.0, 4.0 * next() - 2.0];
            let core = mema_core::closest_point::distance_to_surface(a, y);
            let reference = distance(a, y);
            worst = worst.max((core - reference).abs() / reference.max(1e-12));
        }
        assert!(worst < 1e-9, "worst relative difference {worst:e}");
    }
}
