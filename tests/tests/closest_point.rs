//! Acceptance 2: eq. 13's closest-point distance against a brute-force search on the surface.

use mema_core::closest_point::distance_to_surface;
use std::f64::consts::PI;

struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Minimum over a dense (theta, phi) grid of the surface, then a shrinking pattern search.
fn brute_force(e: [f64; 3], y: [f64; 3]) -> f64 {
    let dist = |t: f64, p: f64| {
        let x = [
            e[0] * p.sin() * t.cos(),
            e[1] * p.sin() * t.sin(),
            e[2] * p.cos(),
        ];
        ((x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2) + (x[2] - y[2]).powi(2)).sqrt()
    };
    let n = 180;
    let mut starts = Vec::new();
    for i in 0..=n {
        for k in 0..2 * n {
            let p = PI * i as f64 / n as f64;
            let t = PI * k as f64 / n as f64;
            starts.push((dist(t, p), t, p));
        }
    }
    starts.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Refine the few best grid cells: near-ties (points near the centre) have several minima.
    let mut best = f64::INFINITY;
    for &(d0, t0, p0) in starts.iter().take(8) {
        let (mut d, mut t, mut p) = (d0, t0, p0);
        let mut step = PI / n as f64;
        while step > 1e-12 {
            let mut improved = false;
            for (dt, dp) in [
                (step, 0.0),
                (-step, 0.0),
                (0.0, step),
                (0.0, -step),
                (step, step),
                (-step, -step),
                (step, -step),
                (-step, step),
            ] {
                let c = dist(t + dt, p + dp);
                if c < d {
                    (d, t, p, improved) = (c, t + dt, p + dp, true);
                }
            }
            if !improved {
                step *= 0.5;
            }
        }
        best = best.min(d);
    }
    best
}

fn random_axes(rng: &mut Lcg) -> [f64; 3] {
    // Ratios up to 1:20, as thin clusters give.
    [
        0.05 + rng.next() * 0.95,
        0.05 + rng.next() * 0.95,
        0.05 + rng.next() * 0.95,
    ]
}

#[test]
fn closest_point_agrees_with_brute_force() {
    let mut rng = Lcg(2024);
    let mut worst = 0.0f64;
    let mut cases = 0;
    for case in 0..240 {
        let e = random_axes(&mut rng);
        let dir = {
            let (t, p) = (rng.next() * 2.0 * PI, rng.next() * PI);
            [p.sin() * t.cos(), p.sin() * t.sin(), p.cos()]
        };
        // A surface point in that parametric direction, then scaled in or out.
        let surface = [e[0] * dir[0], e[1] * dir[1], e[2] * dir[2]];
        let scale = |f: f64| surface.map(|v| v * f);
        let y = match case % 6 {
            0 => scale(0.2 + 0.75 * rng.next()), // inside
            1 => scale(1.05 + 2.0 * rng.next()), // outside
            2 => scale(1e-3 * rng.next()),       // near the centre
            3 => {
                // On an axis: two coordinates exactly zero.
                let mut y = [0.0; 3];
                let j = (rng.next() * 3.0) as usize % 3;
                y[j] = (rng.next() * 2.0 - 1.0) * 2.0 * e[j];
                y
            }
            4 => {
                // On a coordinate plane: one coordinate exactly zero.
                let mut y = scale(0.3 + 1.4 * rng.next());
                y[(rng.next() * 3.0) as usize % 3] = 0.0;
                y
            }
            _ => scale(1.0 + (rng.next() - 0.5) * 2e-3), // within 0.1% of the surface
        };
        let want = brute_force(e, y);
        let got = distance_to_surface(e, y);
        // Points on the surface have distance ~0: compare against the ellipsoid's scale there.
        let scale_of = want.max(1e-3 * e.iter().cloned().fold(f64::INFINITY, f64::min));
        let rel = (got - want).abs() / scale_of;
        worst = worst.max(rel);
        assert!(
            rel <= 1e-4,
            "case {case}: axes {e:?} point {y:?}: {got} vs brute force {want}"
        );
        assert!(
            got <= want * (1.0 + 1e-9),
            "case {case}: bisection {got} is farther than a surface point at {want}"
        );
        cases += 1;
    }
    eprintln!("closest point: {cases} cases, worst relative error {worst:.2e}");
}

#[test]
fn degenerated_entities_drop_their_infinite_axes() {
    let mut rng = Lcg(7);
    for _ in 0..50 {
        let (a, b) = (0.1 + rng.next(), 0.1 + rng.next());
        let y = [
            (rng.next() - 0.5) * 3.0,
            (rng.next() - 0.5) * 3.0,
            (rng.next() - 0.5) * 100.0,
        ];
        // Pseudocylinder along z: brute force over the ellipse in x-y.
        let mut want = f64::INFINITY;
        for i in 0..200_000 {
            let t = 2.0 * PI * i as f64 / 200_000.0;
            want = want.min(((a * t.cos() - y[0]).powi(2) + (b * t.sin() - y[1]).powi(2)).sqrt());
        }
        let got = distance_to_surface([a, b, f64::INFINITY], y);
        assert!(
            (got - want).abs() <= 1e-4 * want.max(1e-3) + 1e-5 * a.max(b),
            "{a} {b} {y:?}: {got} vs {want}"
        );
        // Pair of planes z = +-b.
        let planes = distance_to_surface([f64::INFINITY, f64::INFINITY, b], y);
        assert!((planes - (y[2].abs() - b).abs()).abs() < 1e-12);
    }
}
