//! Points spread uniformly by area over each entity's surface, and the areas that weight them.
//!
//! Everything here works in the entity's local frame, where the semi-axes lie along the
//! coordinate axes; `Entity::to_world` (`c + R(q) x`) places a sample in the map.
//!
//! **Ellipsoid.** A point `u` uniform on the unit sphere, mapped by `D = diag(a, b, c)`, is not
//! uniform on the ellipsoid: the linear map scales the area element at `u` by
//! `|det D| |D^-T n| = abc sqrt((u_x/a)^2 + (u_y/b)^2 + (u_z/c)^2) = g(u)`, the sphere's normal
//! at `u` being `u` itself. Keeping `D u` with probability `g(u) / g_max`, where
//! `g_max = abc / min(a, b, c)` (all of `|u|` on the shortest axis), makes the accepted points
//! uniform by area. The acceptance rate is `area / (4 pi g_max)`, at least 1/2 since the
//! surface covers its projection on the plane of the two longest axes twice.
//!
//! **Pseudocylinder.** The infinite axis is cut to `[lo, hi]`; the lateral surface is sampled by
//! a position uniform along the axis times a point uniform by arc length on the ellipse (the
//! same rejection in 2D: `(a cos t, b sin t)` kept with probability
//! `sqrt(a^2 sin^2 t + b^2 cos^2 t) / max(a, b)`). There are no caps: they are no part of the
//! surface whose distance eq. 13 and the queries measure.
//!
//! **Plane pair.** Both infinite axes are cut; a point uniform on the rectangle, on either plane.
//!
//! **Areas.** Exact, through Carlson's symmetric integral `R_G`: an ellipsoid's area is
//! `4 pi abc R_G(a^-2, b^-2, c^-2)` (the mean of `sqrt(u . diag(a^-2, b^-2, c^-2) u)` over the
//! sphere is `R_G` by definition) and an ellipse's perimeter `8 R_G(0, a^2, b^2)`. The weights
//! therefore agree with the sampler's density (they integrate the same `g`).

use mema_core::Entity;
use rand_core::Rng;
use rand_pcg::Pcg32;

/// The part of an entity whose surface is sampled, in its local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Patch {
    Ellipsoid {
        semi_axes: [f64; 3],
    },
    /// Finite semi-axes along `axes[0]` and `axes[1]`; `axis` is cut to `extent`.
    Cylinder {
        axes: [usize; 2],
        semi_axes: [f64; 2],
        axis: usize,
        extent: [f64; 2],
    },
    /// Planes at `+-semi_axis` along `normal`; the other two axes cut to their extents.
    PlanePair {
        normal: usize,
        semi_axis: f64,
        axes: [usize; 2],
        extents: [[f64; 2]; 2],
    },
}

impl Patch {
    /// The entity's surface, with each infinite axis cut to `extents[axis]` (local coordinates).
    pub fn of(entity: &Entity, extents: [[f64; 2]; 3]) -> Self {
        let r = entity.semi_axes_f64();
        let finite: Vec<usize> = (0..3).filter(|&j| r[j].is_finite()).collect();
        let infinite: Vec<usize> = (0..3).filter(|&j| !r[j].is_finite()).collect();
        match (finite.as_slice(), infinite.as_slice()) {
            (&[i, j], &[k]) => Patch::Cylinder {
                axes: [i, j],
                semi_axes: [r[i], r[j]],
                axis: k,
                extent: extents[k],
            },
            (&[k], &[i, j]) => Patch::PlanePair {
                normal: k,
                semi_axis: r[k],
                axes: [i, j],
                extents: [extents[i], extents[j]],
            },
            // Three finite axes; the core never stores three infinite ones.
            _ => Patch::Ellipsoid {
                semi_axes: r.map(|v| if v.is_finite() { v } else { 0.0 }),
            },
        }
    }

    /// The patch's surface area.
    pub fn area(&self) -> f64 {
        match *self {
            Patch::Ellipsoid {
                semi_axes: [a, b, c],
            } => ellipsoid_area(a, b, c),
            Patch::Cylinder {
                semi_axes: [a, b],
                extent,
                ..
            } => ellipse_perimeter(a, b) * (extent[1] - extent[0]).max(0.0),
            Patch::PlanePair { extents, .. } => {
                2.0 * (extents[0][1] - extents[0][0]).max(0.0)
                    * (extents[1][1] - extents[1][0]).max(0.0)
            }
        }
    }

    /// `n` points uniform by area, local frame. Rejection is bounded: after `64 n` candidates
    /// (acceptance is at least 1/2, so never in practice) the remaining samples are taken
    /// unweighted rather than looping on a hostile entity.
    pub fn sample(&self, n: usize, rng: &mut Pcg32) -> Vec<[f64; 3]> {
        let mut out = Vec::with_capacity(n);
        let mut budget = 64 * n + 64;
        while out.len() < n {
            let reject = budget > 0;
            budget = budget.saturating_sub(1);
            match *self {
                Patch::Ellipsoid { semi_axes: r } => {
                    let u = unit_sphere(rng);
                    let shortest = r[0].min(r[1]).min(r[2]);
                    let g = shortest
                        * ((u[0] / r[0]).powi(2) + (u[1] / r[1]).powi(2) + (u[2] / r[2]).powi(2))
                            .sqrt();
                    let keep = uniform(rng) < g;
                    if reject && !keep {
                        continue;
                    }
                    out.push([r[0] * u[0], r[1] * u[1], r[2] * u[2]]);
                }
                Patch::Cylinder {
                    axes,
                    semi_axes: [a, b],
                    axis,
                    extent,
                } => {
                    let t = std::f64::consts::TAU * uniform(rng);
                    let (s, c) = t.sin_cos();
                    let g = (a * a * s * s + b * b * c * c).sqrt() / a.max(b);
                    let keep = uniform(rng) < g;
                    if reject && !keep {
                        continue;
                    }
                    let mut p = [0.0; 3];
                    p[axes[0]] = a * c;
                    p[axes[1]] = b * s;
                    p[axis] = lerp(extent, uniform(rng));
                    out.push(p);
                }
                Patch::PlanePair {
                    normal,
                    semi_axis,
                    axes,
                    extents,
                } => {
                    let mut p = [0.0; 3];
                    p[axes[0]] = lerp(extents[0], uniform(rng));
                    p[axes[1]] = lerp(extents[1], uniform(rng));
                    p[normal] = if rng.next_u32() & 1 == 0 {
                        semi_axis
                    } else {
                        -semi_axis
                    };
                    out.push(p);
                }
            }
        }
        out
    }
}

fn lerp(range: [f64; 2], t: f64) -> f64 {
    range[0] + t * (range[1] - range[0])
}

/// Uniform in [0, 1) from the top 53 bits.
pub fn uniform(rng: &mut Pcg32) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Uniform on the unit sphere: by Archimedes' hat-box theorem z is uniform in [-1, 1].
fn unit_sphere(rng: &mut Pcg32) -> [f64; 3] {
    let z = 2.0 * uniform(rng) - 1.0;
    let t = std::f64::consts::TAU * uniform(rng);
    let rho = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = t.sin_cos();
    [rho * c, rho * s, z]
}

/// Surface area of the ellipsoid with semi-axes `a, b, c` (all positive).
pub fn ellipsoid_area(a: f64, b: f64, c: f64) -> f64 {
    4.0 * std::f64::consts::PI * a * b * c * carlson_rg(1.0 / (a * a), 1.0 / (b * b), 1.0 / (c * c))
}

/// Perimeter of the ellipse with semi-axes `a, b`.
pub fn ellipse_perimeter(a: f64, b: f64) -> f64 {
    8.0 * carlson_rg(0.0, a * a, b * b)
}

/// Knud Thomsen's approximation of an ellipsoid's area (p = 1.6075, within 1.061%): only a
/// cross-check of [`ellipsoid_area`] in the tests.
pub fn thomsen_area(a: f64, b: f64, c: f64) -> f64 {
    const P: f64 = 1.6075;
    let m = ((a * b).powf(P) + (a * c).powf(P) + (b * c).powf(P)) / 3.0;
    4.0 * std::f64::consts::PI * m.powf(1.0 / P)
}

/// Carlson's `R_F(x, y, z)` by duplication (Carlson 1995, Numerical Recipes' `rf`), to about
/// 1e-15 relative; at most one argument may be zero.
fn carlson_rf(mut x: f64, mut y: f64, mut z: f64) -> f64 {
    for _ in 0..64 {
        let mu = (x + y + z) / 3.0;
        let (dx, dy, dz) = (1.0 - x / mu, 1.0 - y / mu, 1.0 - z / mu);
        if dx.abs().max(dy.abs()).max(dz.abs()) < 1e-4 {
            let e2 = dx * dy - dz * dz;
            let e3 = dx * dy * dz;
            return (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0)
                / mu.sqrt();
        }
        let (sx, sy, sz) = (x.sqrt(), y.sqrt(), z.sqrt());
        let lambda = sx * sy + sx * sz + sy * sz;
        x = 0.25 * (x + lambda);
        y = 0.25 * (y + lambda);
        z = 0.25 * (z + lambda);
    }
    1.0 / ((x + y + z) / 3.0).sqrt()
}

/// Carlson's `R_D(x, y, z)` by duplication; `z` positive, at most one of `x, y` zero.
fn carlson_rd(mut x: f64, mut y: f64, mut z: f64) -> f64 {
    let (mut sum, mut scale) = (0.0, 1.0);
    for _ in 0..64 {
        let mu = (x + y + 3.0 * z) / 5.0;
        let (dx, dy, dz) = (1.0 - x / mu, 1.0 - y / mu, 1.0 - z / mu);
        if dx.abs().max(dy.abs()).max(dz.abs()) < 1e-4 {
            let ea = dx * dy;
            let eb = dz * dz;
            let ec = ea - eb;
            let ed = ea - 6.0 * eb;
            let ee = ed + ec + ec;
            let series = 1.0
                + ed * (-3.0 / 14.0 + 9.0 / 88.0 * ed - 4.5 / 26.0 * dz * ee)
                + dz * (ee / 6.0 + dz * (-9.0 / 22.0 * ec + dz * 3.0 / 26.0 * ea));
            return 3.0 * sum + scale * series / (mu * mu.sqrt());
        }
        let (sx, sy, sz) = (x.sqrt(), y.sqrt(), z.sqrt());
        let lambda = sx * sy + sx * sz + sy * sz;
        sum += scale / (sz * (z + lambda));
        scale *= 0.25;
        x = 0.25 * (x + lambda);
        y = 0.25 * (y + lambda);
        z = 0.25 * (z + lambda);
    }
    3.0 * sum + scale / (z * z.sqrt())
}

/// Carlson's `R_G(x, y, z)`, the mean of `sqrt(x u_x^2 + y u_y^2 + z u_z^2)` over the unit
/// sphere, from `2 R_G = z R_F - (x - z)(y - z) R_D / 3 + sqrt(x y / z)` with the arguments
/// ordered so `z` is the middle one (the product `(x - z)(y - z)` is then not positive and
/// nothing cancels).
pub fn carlson_rg(x: f64, y: f64, z: f64) -> f64 {
    let mut v = [x, y, z];
    v.sort_by(f64::total_cmp);
    let [x, z, y] = v;
    if z == 0.0 {
        // Two zero arguments: R_G(0, 0, y) = sqrt(y) / 2.
        return 0.5 * y.sqrt();
    }
    0.5 * (z * carlson_rf(x, y, z) - (x - z) * (y - z) * carlson_rd(x, y, z) / 3.0
        + (x * y / z).sqrt())
}
