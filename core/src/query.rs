//! Queries a robot asks of its map: distance to the nearest surface (signed), occupancy, and the
//! first entity a ray hits, through a bounding-volume hierarchy in fixed memory.
//!
//! The index keeps a copy of up to `N` entities and a tree of at most `2N - 1` boxes; building
//! it sorts nothing outside its own arrays. A degenerated axis has an infinite box extent, so
//! pseudocylinders and plane pairs are found like any other entity. Ties between entities go to
//! the lower index, in the index and in the brute-force versions alike, so both answer the same.

use crate::closest_point::surface_distance;
use crate::geometry::Entity;
use crate::map::{CapacityExceeded, MapEntity};

/// Entities per leaf: small leaves keep the exact tests few.
const LEAF_SIZE: usize = 4;
/// Depth bound of the traversal stacks: a median-split tree of 65,535 entities is 15 deep.
const STACK: usize = 64;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: [f64::INFINITY; 3],
        max: [f64::NEG_INFINITY; 3],
    };

    /// The box of an entity: centre +- its half extent along each world axis, infinite along a
    /// degenerated axis (or any world axis a degenerated axis is turned onto).
    pub fn of(e: &Entity) -> Self {
        let c = e.center.to_f64();
        let r = half_extents(e);
        Self {
            min: [c[0] - r[0], c[1] - r[1], c[2] - r[2]],
            max: [c[0] + r[0], c[1] + r[1], c[2] + r[2]],
        }
    }

    fn union(&self, o: &Aabb) -> Aabb {
        let mut u = *self;
        for j in 0..3 {
            u.min[j] = u.min[j].min(o.min[j]);
            u.max[j] = u.max[j].max(o.max[j]);
        }
        u
    }

    /// Euclidean distance from `p` to the box (0 inside): a lower bound of any surface in it.
    fn distance(&self, p: [f64; 3]) -> f64 {
        let mut s = 0.0;
        for j in 0..3 {
            let d = (self.min[j] - p[j]).max(p[j] - self.max[j]).max(0.0);
            s += d * d;
        }
        libm::sqrt(s)
    }

    fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|j| p[j] >= self.min[j] && p[j] <= self.max[j])
    }

    /// Entry and exit parameters of the ray through the box, if it meets it.
    fn ray_interval(&self, o: [f64; 3], inv_d: [f64; 3], t_max: f64) -> Option<f64> {
        let (mut t0, mut t1) = (0.0f64, t_max);
        for j in 0..3 {
            let (a, b) = (
                (self.min[j] - o[j]) * inv_d[j],
                (self.max[j] - o[j]) * inv_d[j],
            );
            // 0 * inf is NaN for a ray in the slab's plane: max/min skip NaN, keeping the slab open.
            let (near, far) = if a <= b { (a, b) } else { (b, a) };
            t0 = t0.max(near);
            t1 = t1.min(far);
        }
        (t0 <= t1).then_some(t0)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    bounds: Aabb,
    /// Leaf: first slot in `order`; inner: index of the left child (the right one follows).
    first: u32,
    /// Entities in a leaf; 0 for an inner node.
    count: u32,
}

/// The answer to a distance query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Distance to the nearest entity surface, negative if the point is inside any entity.
    pub signed_distance: f64,
    pub entity: usize,
}

/// The first surface along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Distance along the (normalised) direction.
    pub t: f64,
    pub entity: usize,
    pub point: [f64; 3],
}

/// Half extents of an entity's world box: `sqrt(sum_k R_jk^2 r_k^2)` along world axis j, the
/// support of the ellipsoid, exactly `r_j` when axis-aligned.
pub fn half_extents(e: &Entity) -> [f64; 3] {
    let r = e.semi_axes_f64();
    if e.rotation.is_identity() {
        return r;
    }
    let m = e.rotation.matrix();
    [0, 1, 2].map(|j| {
        let mut s = 0.0;
        for k in 0..3 {
            let a = m[j][k] * m[j][k];
            if a == 0.0 {
                continue;
            }
            if r[k].is_infinite() {
                return f64::INFINITY;
            }
            s += a * r[k] * r[k];
        }
        libm::sqrt(s)
    })
}

/// True if `p` is inside or on the entity: `psi1(X) . psi2(E) >= 0`.
pub fn contains(e: &Entity, p: [f64; 3]) -> bool {
    let q = e.to_local(p);
    let s: f64 = (0..3).map(|j| e.weights[j] as f64 * q[j] * q[j]).sum();
    s <= 1.0
}

/// The first `t` in `[0, t_max]` where the ray meets the entity's surface.
pub fn ray_entity(e: &Entity, o: [f64; 3], d: [f64; 3], t_max: f64) -> Option<f64> {
    let local_o = e.to_local(o);
    let d = e.rotation.inverse_rotate(d);
    let (mut a, mut b, mut k) = (0.0, 0.0, -1.0);
    for j in 0..3 {
        let w = e.weights[j] as f64;
        let q = local_o[j];
        a += w * d[j] * d[j];
        b += 2.0 * w * d[j] * q;
        k += w * q * q;
    }
    let accept = |t: f64| (t >= 0.0 && t <= t_max).then_some(t);
    if a == 0.0 {
        // Along every finite axis the ray does not move: a constant quadratic, or linear.
        return if b != 0.0 { accept(-k / b) } else { None };
    }
    let disc = b * b - 4.0 * a * k;
    if disc < 0.0 {
        return None;
    }
    // The stable pair of roots (no cancellation between b and the root).
    let q = -0.5 * (b + libm::copysign(libm::sqrt(disc), b));
    let (r1, r2) = if q != 0.0 { (q / a, k / q) } else { (0.0, 0.0) };
    let (t1, t2) = if r1 <= r2 { (r1, r2) } else { (r2, r1) };
    accept(t1).or_else(|| accept(t2))
}

fn normalised(d: [f64; 3]) -> Option<[f64; 3]> {
    let n = libm::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    (n > 0.0 && n.is_finite()).then(|| d.map(|v| v / n))
}

fn closer(candidate: (f64, usize), best: Option<(f64, usize)>) -> bool {
    best.is_none_or(|(bd, bi)| candidate.0 < bd || (candidate.0 == bd && candidate.1 < bi))
}

/// A bounding-volume hierarchy over at most `N` entities.
#[derive(Clone, Debug)]
pub struct MapIndex<const N: usize> {
    entities: heapless::Vec<Entity, N>,
    order: [u32; N],
    nodes: heapless::Vec<Node, N>,
    leaves: heapless::Vec<Node, N>,
}

impl<const N: usize> MapIndex<N> {
    /// Builds the tree: median splits along the widest spread of entity centres.
    pub fn build(entities: impl IntoIterator<Item = MapEntity>) -> Result<Self, CapacityExceeded> {
        let mut index = Self {
            entities: heapless::Vec::new(),
            order: [0; N],
            nodes: heapless::Vec::new(),
            leaves: heapless::Vec::new(),
        };
        for e in entities {
            index
                .entities
                .push(e.entity)
                .map_err(|_| CapacityExceeded { capacity: N })?;
        }
        let n = index.entities.len();
        for (i, slot) in index.order.iter_mut().enumerate().take(n) {
            *slot = i as u32;
        }
        if n > 0 {
            index.split(0, n);
        }
        Ok(index)
    }

    pub fn entities(&self) -> &[Entity] {
        &self.entities
    }

    fn bounds_of(&self, start: usize, end: usize) -> Aabb {
        let mut b = Aabb::EMPTY;
        for &i in self.order.get(start..end).unwrap_or(&[]) {
            if let Some(e) = self.entities.get(i as usize) {
                b = b.union(&Aabb::of(e));
            }
        }
        b
    }

    /// Inner nodes live in `nodes` (index i), leaves in `leaves` (index tagged with the high bit).
    fn split(&mut self, start: usize, end: usize) -> u32 {
        const LEAF_TAG: u32 = 1 << 31;
        let bounds = self.bounds_of(start, end);
        if end - start <= LEAF_SIZE {
            let at = self.leaves.len() as u32;
            let _ = self.leaves.push(Node {
                bounds,
                first: start as u32,
                count: (end - start) as u32,
            });
            return at | LEAF_TAG;
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &i in self.order.get(start..end).unwrap_or(&[]) {
            if let Some(e) = self.entities.get(i as usize) {
                let c = e.center.to_f64();
                for j in 0..3 {
                    lo[j] = lo[j].min(c[j]);
                    hi[j] = hi[j].max(c[j]);
                }
            }
        }
        let axis = (0..3).fold(0, |a, j| if hi[j] - lo[j] > hi[a] - lo[a] { j } else { a });
        let mid = start + (end - start) / 2;
        let entities = &self.entities;
        let key = |i: &u32| {
            (
                entities
                    .get(*i as usize)
                    .map_or(0.0, |e| e.center.to_array()[axis]),
                *i,
            )
        };
        if let Some(slice) = self.order.get_mut(start..end) {
            slice.select_nth_unstable_by(mid - start, |a, b| {
                let (ka, kb) = (key(a), key(b));
                ka.0.total_cmp(&kb.0).then(ka.1.cmp(&kb.1))
            });
        }
        let at = self.nodes.len();
        if self
            .nodes
            .push(Node {
                bounds,
                first: 0,
                count: 0,
            })
            .is_err()
        {
            // Cannot happen (fewer inner nodes than entities); a leaf keeps the index valid.
            let at = self.leaves.len() as u32;
            let _ = self.leaves.push(Node {
                bounds,
                first: start as u32,
                count: (end - start) as u32,
            });
            return at | LEAF_TAG;
        }
        let left = self.split(start, mid);
        let right = self.split(mid, end);
        if let Some(node) = self.nodes.get_mut(at) {
            // Children are stored as tagged references: `first` = left, `count` = right.
            node.first = left;
            node.count = right;
        }
        at as u32
    }

    /// Visits the tree depth-first; `enter` decides whether a box is worth opening and
    /// `leaf` handles the entities of a reached leaf.
    fn walk(&self, mut enter: impl FnMut(&Aabb) -> bool, mut leaf: impl FnMut(&[u32])) {
        const LEAF_TAG: u32 = 1 << 31;
        if self.entities.is_empty() {
            return;
        }
        let root = if self.nodes.is_empty() { LEAF_TAG } else { 0 };
        let mut stack = [0u32; STACK];
        let mut top = 1;
        stack[0] = root;
        while top > 0 {
            top -= 1;
            let Some(&reference) = stack.get(top) else {
                break;
            };
            if reference & LEAF_TAG != 0 {
                if let Some(node) = self.leaves.get((reference & !LEAF_TAG) as usize)
                    && enter(&node.bounds)
                {
                    let (a, b) = (node.first as usize, (node.first + node.count) as usize);
                    leaf(self.order.get(a..b).unwrap_or(&[]));
                }
                continue;
            }
            let Some(node) = self.nodes.get(reference as usize) else {
                continue;
            };
            if !enter(&node.bounds) {
                continue;
            }
            for child in [node.count, node.first] {
                if let Some(slot) = stack.get_mut(top) {
                    *slot = child;
                    top += 1;
                }
            }
        }
    }

    /// Nearest entity surface to `p`, negative inside any entity.
    pub fn nearest(&self, p: [f64; 3]) -> Option<Nearest> {
        let mut best: Option<(f64, usize)> = None;
        let mut inside = false;
        let entities = &self.entities;
        let best_cell = core::cell::Cell::new(f64::INFINITY);
        self.walk(
            // A box holding p has distance 0 and is always opened, so containment is never missed.
            |b| b.distance(p) <= best_cell.get(),
            |slots| {
                for &i in slots {
                    let Some(e) = entities.get(i as usize) else {
                        continue;
                    };
                    inside |= contains(e, p);
                    let d = surface_distance(e, p);
                    if closer((d, i as usize), best) {
                        best = Some((d, i as usize));
                        best_cell.set(d);
                    }
                }
            },
        );
        best.map(|(d, i)| Nearest {
            signed_distance: if inside { -d } else { d },
            entity: i,
        })
    }

    /// The lowest-index entity containing `p`, if any.
    pub fn occupied(&self, p: [f64; 3]) -> Option<usize> {
        let mut found: Option<usize> = None;
        let entities = &self.entities;
        self.walk(
            |b| b.contains(p),
            |slots| {
                for &i in slots {
                    if entities.get(i as usize).is_some_and(|e| contains(e, p))
                        && found.is_none_or(|f| (i as usize) < f)
                    {
                        found = Some(i as usize);
                    }
                }
            },
        );
        found
    }

    /// The first entity surface along the ray `o + t d` (d need not be unit), up to `t_max`.
    pub fn ray_cast(&self, o: [f64; 3], d: [f64; 3], t_max: f64) -> Option<RayHit> {
        let d = normalised(d)?;
        let inv = d.map(|v| 1.0 / v);
        let mut best: Option<(f64, usize)> = None;
        let entities = &self.entities;
        let best_t = core::cell::Cell::new(t_max);
        self.walk(
            |b| b.ray_interval(o, inv, best_t.get()).is_some(),
            |slots| {
                for &i in slots {
                    let Some(e) = entities.get(i as usize) else {
                        continue;
                    };
                    if let Some(t) = ray_entity(e, o, d, best_t.get())
                        && closer((t, i as usize), best)
                    {
                        best = Some((t, i as usize));
                        best_t.set(t);
                    }
                }
            },
        );
        best.map(|(t, entity)| RayHit {
            t,
            entity,
            point: [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]],
        })
    }
}

/// The same three queries by scanning every entity: the reference the index is tested against
/// and benchmarked against.
pub mod brute_force {
    use super::*;

    pub fn nearest(entities: &[Entity], p: [f64; 3]) -> Option<Nearest> {
        nearest_of(entities.iter().copied(), p)
    }

    /// [`nearest`] over entities as they come: a device answers from its mapper's entities,
    /// with no copy of the map to scan.
    pub fn nearest_of(entities: impl IntoIterator<Item = Entity>, p: [f64; 3]) -> Option<Nearest> {
        let mut best: Option<(f64, usize)> = None;
        let mut inside = false;
        for (i, e) in entities.into_iter().enumerate() {
            let e = &e;
            inside |= contains(e, p);
            let d = surface_distance(e, p);
            if closer((d, i), best) {
                best = Some((d, i));
            }
        }
        best.map(|(d, i)| Nearest {
            signed_distance: if inside { -d } else { d },
            entity: i,
        })
    }

    pub fn occupied(entities: &[Entity], p: [f64; 3]) -> Option<usize> {
        entities.iter().position(|e| contains(e, p))
    }

    pub fn ray_cast(entities: &[Entity], o: [f64; 3], d: [f64; 3], t_max: f64) -> Option<RayHit> {
        ray_cast_of(entities.iter().copied(), o, d, t_max)
    }

    /// [`ray_cast`] over entities as they come.
    pub fn ray_cast_of(
        entities: impl IntoIterator<Item = Entity>,
        o: [f64; 3],
        d: [f64; 3],
        t_max: f64,
    ) -> Option<RayHit> {
        let d = normalised(d)?;
        let mut best: Option<(f64, usize)> = None;
        for (i, e) in entities.into_iter().enumerate() {
            if let Some(t) = ray_entity(&e, o, d, t_max)
                && closer((t, i), best)
            {
                best = Some((t, i));
            }
        }
        best.map(|(t, entity)| RayHit {
            t,
            entity,
            point: [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]],
        })
    }
}
