//! The built-in scene that `mema demo` maps, and a simulated rangefinder scan of it.
//!
//! The demo must run without files or hardware, yet exercise the mapper on
//! something shaped like real data: several objects of paper-like size, one-sided
//! visibility, occlusion and range noise. Every primitive has an exact ray
//! intersection so the noise-free scan is a known ground truth, and all noise
//! comes from one seeded Pcg32, so a seed reproduces a scan bit for bit, on every
//! platform: `sin`, `cos` and `ln` come from the `libm` crate, not the platform's maths library.

use rand_core::{Rng, SeedableRng};
use rand_pcg::Pcg32;

type V3 = [f64; 3];
type V2 = [f64; 2];

/// The name every part of a walker ([`Scene::with_walker`]) begins with.
pub const WALKER: &str = "walker";

/// A simulated rangefinder scan of the built-in scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Scan {
    /// Noisy surface points in world coordinates (metres), in scan order.
    pub points: Vec<V3>,
    /// Rays cast.
    pub rays: usize,
    /// Rays that hit nothing within `max_range`.
    pub misses: usize,
}

/// Sensor position and a regular azimuth/elevation grid of rays.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanConfig {
    pub sensor: V3,
    pub azimuth_steps: usize,
    pub elevation_steps: usize,
    /// Radians about +z, measured from +x.
    pub azimuth_range: (f64, f64),
    /// Radians above the horizontal.
    pub elevation_range: (f64, f64),
    pub max_range: f64,
    /// Standard deviation of the Gaussian range error, metres.
    pub range_noise_sigma: f64,
    pub seed: u64,
}

impl Default for ScanConfig {
    /// Mimics a tilting 2D laser scanner of the Hokuyo UTM-30LX class (0.25°
    /// steps, range repeatability σ < 10 mm) at chest height, stepped at 0.2°
    /// over a field of view cropped to the objects, so that the cloud has the
    /// paper's 10-40k points and the smallest part, the head, a few hundred.
    fn default() -> Self {
        Self {
            sensor: [0.0, 0.0, 1.2],
            azimuth_steps: 225,
            elevation_steps: 220,
            azimuth_range: (-22.5f64.to_radians(), 22.5f64.to_radians()),
            elevation_range: (-32.5f64.to_radians(), 11.5f64.to_radians()),
            max_range: 10.0,
            range_noise_sigma: 0.005,
            seed: 0x6d65_6d61,
        }
    }
}

/// A solid (or, for `Rect`, two-sided) surface with an exact ray intersection.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Horizontal rectangle `min..=max` in x and y at height `z`.
    Rect { min: V2, max: V2, z: f64 },
    /// Axis-aligned box.
    Box { min: V3, max: V3 },
    /// Upright (z-axis) capped cylinder standing on `base`.
    Cylinder { base: V3, radius: f64, height: f64 },
    /// Axis-aligned ellipsoid.
    Ellipsoid { center: V3, semi_axes: V3 },
}

/// One shape of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Primitive {
    pub name: &'static str,
    pub shape: Shape,
}

/// A scene of simple shapes that a simulated rangefinder can scan ([`scan`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub primitives: Vec<Primitive>,
}

/// The nearest surface a ray meets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance from the origin along the normalised direction, metres.
    pub range: f64,
    /// Index into `Scene::primitives`.
    pub primitive: usize,
    pub point: V3,
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn at(o: V3, d: V3, t: f64) -> V3 {
    [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]]
}

/// Roots of `a t² + 2 hb t + c`, ascending. This form avoids the cancellation
/// of the textbook formula when `hb² ≫ a c`, as for grazing or distant rays.
fn quadratic(a: f64, hb: f64, c: f64) -> Option<(f64, f64)> {
    let disc = hb * hb - a * c;
    if disc < 0.0 || a == 0.0 {
        return None;
    }
    let q = -(hb + disc.sqrt().copysign(hb));
    let (t1, t2) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
    Some((t1.min(t2), t1.max(t2)))
}

/// Keeps the smaller of `best` and `t`, ignoring crossings behind the origin.
fn nearest(best: Option<f64>, t: f64) -> Option<f64> {
    (t > 0.0 && best.is_none_or(|b| t < b))
        .then_some(t)
        .or(best)
}

impl Shape {
    /// Distance to the first surface crossing ahead of `o` along unit `d`.
    fn intersect(&self, o: V3, d: V3) -> Option<f64> {
        match *self {
            Shape::Rect { min, max, z } => {
                let t = (z - o[2]) / d[2];
                let p = at(o, d, t);
                let within = (0..2).all(|i| (min[i]..=max[i]).contains(&p[i]));
                (t > 0.0 && t.is_finite() && within).then_some(t)
            }
            Shape::Box { min, max } => {
                // A zero direction component gives the right infinite slab
                // bounds, or NaN for a ray in a face plane, which `min`/`max`
                // turn into a miss: acceptable for a measure-zero case.
                let (mut near, mut far) = (f64::NEG_INFINITY, f64::INFINITY);
                for i in 0..3 {
                    let (ta, tb) = ((min[i] - o[i]) / d[i], (max[i] - o[i]) / d[i]);
                    near = near.max(ta.min(tb));
                    far = far.min(ta.max(tb));
                }
                nearest(nearest(None, far), near).filter(|_| near <= far)
            }
            Shape::Cylinder {
                base,
                radius,
                height,
            } => {
                let (x, y) = (o[0] - base[0], o[1] - base[1]);
                let (a, hb) = (d[0] * d[0] + d[1] * d[1], x * d[0] + y * d[1]);
                let mut best = None;
                if let Some((t1, t2)) = quadratic(a, hb, x * x + y * y - radius * radius) {
                    for t in [t1, t2] {
                        if (base[2]..=base[2] + height).contains(&at(o, d, t)[2]) {
                            best = nearest(best, t);
                        }
                    }
                }
                for cap in [base[2], base[2] + height] {
                    let t = (cap - o[2]) / d[2];
                    let p = at(o, d, t);
                    let (px, py) = (p[0] - base[0], p[1] - base[1]);
                    if t.is_finite() && px * px + py * py <= radius * radius {
                        best = nearest(best, t);
                    }
                }
                best
            }
            Shape::Ellipsoid { center, semi_axes } => {
                // Scaling space by 1/semi_axes maps the ellipsoid to the unit
                // sphere and leaves t alone, so the roots are world ranges.
                let oc = sub(o, center);
                let os = [0, 1, 2].map(|i| oc[i] / semi_axes[i]);
                let ds = [0, 1, 2].map(|i| d[i] / semi_axes[i]);
                let (t1, t2) = quadratic(dot(ds, ds), dot(os, ds), dot(os, os) - 1.0)?;
                nearest(nearest(None, t2), t1)
            }
        }
    }
}

impl Scene {
    /// A 6 m x 6 m floor, trash can, box and 1.76 m person, all in view of the default sensor.
    pub fn demo() -> Self {
        let prim = |name, shape| Primitive { name, shape };
        let ell = |name, center, semi_axes| prim(name, Shape::Ellipsoid { center, semi_axes });
        let (min, max) = ([-1.0, -3.0], [5.0, 3.0]);
        let floor = Shape::Rect { min, max, z: 0.0 };
        let (base, radius, height) = ([2.5, -0.75, 0.0], 0.25, 0.7);
        let can = Shape::Cylinder {
            base,
            radius,
            height,
        };
        let (min, max) = ([2.4, 0.45, 0.0], [2.8, 1.05, 0.5]);
        let primitives = vec![
            prim("floor", floor),
            prim("trash can", can),
            prim("box", Shape::Box { min, max }),
            // The person faces the sensor (-x) with the arms hanging at the sides.
            ell("torso", [2.8, 0.0, 1.2], [0.13, 0.21, 0.35]),
            ell("head", [2.8, 0.0, 1.64], [0.1, 0.09, 0.12]),
            ell("left leg", [2.8, 0.1, 0.45], [0.08, 0.08, 0.45]),
            ell("right leg", [2.8, -0.1, 0.45], [0.08, 0.08, 0.45]),
            ell("left arm", [2.8, 0.28, 1.15], [0.05, 0.05, 0.32]),
            ell("right arm", [2.8, -0.28, 1.15], [0.05, 0.05, 0.32]),
        ];
        Self { primitives }
    }

    /// The scene with someone else standing at `at` (feet on the floor, metres), facing +y as
    /// if walking that way: torso, head and legs, each named [`WALKER`]` ...`.
    pub fn with_walker(&self, at: [f64; 2]) -> Self {
        let [x, y] = at;
        let ell = |name, center: V3, semi_axes| Primitive {
            name,
            shape: Shape::Ellipsoid { center, semi_axes },
        };
        let mut scene = self.clone();
        scene.primitives.extend([
            ell("walker torso", [x, y, 1.2], [0.21, 0.13, 0.35]),
            ell("walker head", [x, y, 1.64], [0.09, 0.1, 0.12]),
            ell(
                "walker left leg",
                [x - 0.1, y + 0.1, 0.45],
                [0.08, 0.08, 0.45],
            ),
            ell(
                "walker right leg",
                [x + 0.1, y - 0.1, 0.45],
                [0.08, 0.08, 0.45],
            ),
        ]);
        scene
    }

    /// The scene as a room: walls along the floor's far edge and its sides, and a ceiling,
    /// 2.6 m high. Behind anyone standing in it there is then a surface, so the rays that pass
    /// where they stood end on something (the open scene's rays past the objects return
    /// nothing, and say nothing about the space they crossed).
    pub fn with_walls(&self) -> Self {
        let wall = |name, min, max| Primitive {
            name,
            shape: Shape::Box { min, max },
        };
        let mut scene = self.clone();
        scene.primitives.extend([
            wall("back wall", [5.0, -3.05, 0.0], [5.05, 3.05, 2.6]),
            wall("left wall", [-1.0, 3.0, 0.0], [5.0, 3.05, 2.6]),
            wall("right wall", [-1.0, -3.05, 0.0], [5.0, -3.0, 2.6]),
            Primitive {
                name: "ceiling",
                shape: Shape::Rect {
                    min: [-1.0, -3.0],
                    max: [5.0, 3.0],
                    z: 2.6,
                },
            },
        ]);
        scene
    }

    /// Whether primitive `index` is part of a walker ([`Scene::with_walker`]).
    pub fn is_walker(&self, index: usize) -> bool {
        self.primitives
            .get(index)
            .is_some_and(|p| p.name.starts_with(WALKER))
    }

    /// The nearest surface within `max_range` along `direction` (any nonzero length).
    pub fn ray_cast(&self, origin: V3, direction: V3, max_range: f64) -> Option<Hit> {
        let len = dot(direction, direction).sqrt();
        if len == 0.0 || !len.is_finite() {
            return None;
        }
        self.cast_unit(origin, direction.map(|c| c / len), max_range)
    }

    fn cast_unit(&self, origin: V3, d: V3, max_range: f64) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for (primitive, prim) in self.primitives.iter().enumerate() {
            if let Some(range) = prim.shape.intersect(origin, d)
                && range <= max_range
                && best.is_none_or(|b| range < b.range)
            {
                best = Some(Hit {
                    range,
                    primitive,
                    point: at(origin, d, range),
                });
            }
        }
        best
    }
}

/// Standard normal deviate by Box-Muller from two 53-bit uniforms; `u1` is
/// kept in (0, 1] so the logarithm stays finite.
fn gaussian(rng: &mut Pcg32) -> f64 {
    const SCALE: f64 = 1.0 / (1u64 << 53) as f64;
    let u1 = ((rng.next_u64() >> 11) + 1) as f64 * SCALE;
    let u2 = (rng.next_u64() >> 11) as f64 * SCALE;
    libm::sqrt(-2.0 * libm::log(u1)) * libm::cos(std::f64::consts::TAU * u2)
}

/// Centre of cell `i` of `n` equal cells spanning `range`, so `n = 1` looks at the middle.
fn cell(range: (f64, f64), i: usize, n: usize) -> f64 {
    range.0 + (i as f64 + 0.5) * (range.1 - range.0) / n as f64
}

impl ScanConfig {
    /// The unit ray directions of the scan, row by row (elevation outer, azimuth inner), each
    /// through the centre of its grid cell.
    pub fn ray_directions(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        (0..self.elevation_steps).flat_map(move |e| {
            let el = cell(self.elevation_range, e, self.elevation_steps);
            (0..self.azimuth_steps).map(move |a| {
                let az = cell(self.azimuth_range, a, self.azimuth_steps);
                [
                    libm::cos(el) * libm::cos(az),
                    libm::cos(el) * libm::sin(az),
                    libm::sin(el),
                ]
            })
        })
    }
}

/// Casts the grid row by row (elevation outer, azimuth inner) and moves each
/// hit along its ray by Gaussian noise.
pub fn scan(scene: &Scene, config: &ScanConfig) -> Scan {
    scan_labelled(scene, config).0
}

/// `scan`, plus the index of the primitive each point came from.
pub fn scan_labelled(scene: &Scene, config: &ScanConfig) -> (Scan, Vec<usize>) {
    let mut rng = Pcg32::seed_from_u64(config.seed);
    let (mut points, mut labels, mut misses) = (Vec::new(), Vec::new(), 0);
    for d in config.ray_directions() {
        let Some(hit) = scene.cast_unit(config.sensor, d, config.max_range) else {
            misses += 1;
            continue;
        };
        let range = hit.range + config.range_noise_sigma * gaussian(&mut rng);
        points.push(at(config.sensor, d, range));
        labels.push(hit.primitive);
    }
    let rays = config.azimuth_steps * config.elevation_steps;
    let scan = Scan {
        points,
        misses,
        rays,
    };
    (scan, labels)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Implicit function: negative inside, zero on the surface. A rectangle's
    /// inside is the half-space below it; points off its footprint are
    /// infinitely far outside, so they are neither inside nor on it.
    fn implicit(shape: &Shape, p: V3) -> f64 {
        match *shape {
            Shape::Rect { min, max, z } => {
                let over = (0..2).all(|i| (min[i]..=max[i]).contains(&p[i]));
                if over { p[2] - z } else { f64::INFINITY }
            }
            Shape::Box { min, max } => (0..3)
                .map(|i| (p[i] - 0.5 * (min[i] + max[i])).abs() - 0.5 * (max[i] - min[i]))
                .fold(f64::NEG_INFINITY, f64::max),
            Shape::Cylinder {
                base,
                radius,
                height,
            } => {
                let r = (p[0] - base[0]).hypot(p[1] - base[1]) - radius;
                r.max((p[2] - base[2] - 0.5 * height).abs() - 0.5 * height)
            }
            Shape::Ellipsoid { center, semi_axes } => {
                let q = [0, 1, 2].map(|i| (p[i] - center[i]) / semi_axes[i]);
                dot(q, q) - 1.0
            }
        }
    }

    fn noise_free() -> ScanConfig {
        ScanConfig {
            range_noise_sigma: 0.0,
            ..ScanConfig::default()
        }
    }

    fn bits(scan: Scan) -> Vec<[u64; 3]> {
        scan.points.iter().map(|p| p.map(f64::to_bits)).collect()
    }

    fn uniform(rng: &mut Pcg32, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn noise_free_points_lie_on_the_hit_surface() {
        let scene = Scene::demo();
        let (scan, labels) = scan_labelled(&scene, &noise_free());
        assert!(!scan.points.is_empty());
        for (&p, &l) in scan.points.iter().zip(&labels) {
            let res = implicit(&scene.primitives[l].shape, p).abs();
            assert!(res < 1e-9, "{p:?} off primitive {l} by {res}");
        }
    }

    #[test]
    fn ray_cast_agrees_with_brute_force_march() {
        const STEP: f64 = 1e-3;
        const MAX: f64 = 8.0;
        const RAYS: usize = 3000;
        let scene = Scene::demo();
        let shapes: Vec<&Shape> = scene.primitives.iter().map(|p| &p.shape).collect();
        let inside_any = |p| shapes.iter().any(|s| implicit(s, p) < 0.0);
        let (scan, labels) = scan_labelled(&scene, &noise_free());
        let mut on_each = vec![Vec::new(); shapes.len()];
        for (&p, &l) in scan.points.iter().zip(&labels) {
            on_each[l].push(p);
        }
        let mut rng = Pcg32::seed_from_u64(7);
        let (mut checked, mut grazes) = (vec![0usize; shapes.len()], 0);
        for _ in 0..RAYS {
            // Origins above the floor and over its footprint: a ray can then
            // enter the floor's half-space only through the rectangle itself.
            let o = loop {
                let (lo, hi) = ([-0.9, -2.9, 0.05], [4.9, 2.9, 2.0]);
                let o = [0, 1, 2].map(|i| uniform(&mut rng, lo[i], hi[i]));
                if !inside_any(o) {
                    break o;
                }
            };
            // Half the rays aim at a scanned point of a random primitive so
            // that small parts get tested; the rest go anywhere.
            let target = if rng.next_u32() % 2 == 0 {
                let on = &on_each[rng.next_u32() as usize % on_each.len()];
                on[rng.next_u32() as usize % on.len()]
            } else {
                o.map(|c| c + uniform(&mut rng, -1.0, 1.0))
            };
            let d = sub(target, o);
            let d = d.map(|c| c / dot(d, d).sqrt());
            let entry = (1..=((MAX + STEP) / STEP) as u32)
                .map(|k| k as f64 * STEP)
                .find(|&t| inside_any(at(o, d, t)));
            let Some(hit) = scene.ray_cast(o, d, MAX) else {
                // Only an entry beyond MAX may go unreported.
                assert!(entry.is_none_or(|t| t - STEP > MAX - 1e-9), "{entry:?}");
                continue;
            };
            let inside_hit = |t| implicit(shapes[hit.primitive], at(o, d, t)) < 0.0;
            if let Some(t) = entry
                && (t - STEP - 1e-9..=t + 1e-9).contains(&hit.range)
                && inside_hit(t)
            {
                checked[hit.primitive] += 1;
                continue;
            }
            // Otherwise the ray must cross the primitive entirely between two
            // samples, no later than whatever the march found.
            let next_sample = (hit.range / STEP).ceil() * STEP;
            assert!(
                entry.is_none_or(|t| hit.range <= t + 1e-9) && !inside_hit(next_sample),
                "cast {hit:?} vs march entry {entry:?} from {o:?}"
            );
            grazes += 1;
        }
        assert!(grazes <= RAYS / 100, "{grazes} grazing rays");
        for (prim, &n) in scene.primitives.iter().zip(&checked) {
            assert!(n >= 20, "{} checked on only {n} rays", prim.name);
        }
    }

    #[test]
    fn range_noise_has_the_configured_sigma() {
        let scene = Scene::demo();
        let config = ScanConfig::default();
        let (noisy, exact) = (scan(&scene, &config), scan(&scene, &noise_free()));
        assert_eq!(noisy.points.len(), exact.points.len());
        let range = |p| dot(sub(p, config.sensor), sub(p, config.sensor)).sqrt();
        let res: Vec<f64> = std::iter::zip(&noisy.points, &exact.points)
            .map(|(&p, &e)| range(p) - range(e))
            .collect();
        let n = res.len() as f64;
        let mean = res.iter().sum::<f64>() / n;
        let sd = (res.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let sigma = config.range_noise_sigma;
        assert!((sd / sigma - 1.0).abs() < 0.1, "sd {sd} vs sigma {sigma}");
        assert!(mean.abs() < 5.0 * sigma / n.sqrt(), "mean {mean}");
    }

    #[test]
    fn same_seed_same_points_different_seed_differs() {
        let scene = Scene::demo();
        let config = ScanConfig::default();
        let a = bits(scan(&scene, &config));
        assert_eq!(a, bits(scan(&scene, &config)));
        let mut other = config.clone();
        other.seed += 1;
        let b = bits(scan(&scene, &other));
        assert_eq!(a.len(), b.len());
        assert_ne!(a, b);
    }

    #[test]
    fn default_scan_covers_every_primitive() {
        let scene = Scene::demo();
        let scan = scan(&scene, &noise_free());
        assert_eq!(scan.rays, scan.points.len() + scan.misses);
        let n = scan.points.len();
        assert!((25_000..=40_000).contains(&n), "{n} points");
        // Attribute points by surface residual, independently of the caster.
        let mut counts = vec![0usize; scene.primitives.len()];
        for &p in &scan.points {
            let on: Vec<usize> = (0..counts.len())
                .filter(|&i| implicit(&scene.primitives[i].shape, p).abs() < 1e-9)
                .collect();
            assert_eq!(on.len(), 1, "{p:?} on {on:?}");
            counts[on[0]] += 1;
        }
        for (prim, &count) in scene.primitives.iter().zip(&counts) {
            assert!(count >= 300, "{} has only {count} points", prim.name);
        }
    }
}
