//! `mema export`: a map's entities as triangle meshes (PLY, OBJ, binary glTF).
//!
//! Tessellation, with S = `segments` and R = `rings` (these counts are the documented contract
//! that the tests check):
//! - ellipsoid and sphere: a UV sphere with poles on z, `(R - 1) S + 2` vertices and
//!   `2 S (R - 1)` triangles;
//! - pseudocylinder: an elliptic tube along its infinite axis, capped, spanning the bounding
//!   box along that axis: `2 S + 2` vertices, `4 S` triangles;
//! - pair of planes: two rectangles at `c ± r` on the finite axis, spanning the bounding box
//!   on the other two: 8 vertices, 4 triangles.
//!
//! Coordinates: PLY (`double`) and OBJ (text) hold world coordinates, so the mesh lands on the
//! cloud it came from; glTF positions are f32 by the specification, so they are local to the
//! map's origin and the one node carries the origin as its translation.

use anyhow::{Context, Result};
use mema_core::query::half_extents;
use mema_core::{EntityKind, MapEntity, Rotation};
use serde::Serialize;
use std::collections::TryReserveError;
use std::path::Path;

use crate::error::ConfigError;
use crate::io::mapfile::HostMap;

mod formats;
mod size;
pub use size::{DEFAULT_MAX_BYTES, MeshSize, OBJ_VERTEX_MAX};

/// Colours by kind (Okabe-Ito, readable with colour-blindness), shared with `mema draw`.
pub fn kind_colour(kind: EntityKind) -> [u8; 3] {
    match kind {
        EntityKind::Ellipsoid => [0, 114, 178],
        EntityKind::Sphere => [230, 159, 0],
        EntityKind::Pseudocylinder => [0, 158, 115],
        EntityKind::PlanePair => [213, 94, 0],
    }
}

/// The mesh formats, chosen by a path's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MeshFormat {
    Ply,
    Obj,
    Glb,
}

impl MeshFormat {
    /// The format of a mesh path's extension (`.ply`, `.obj`, `.glb`, any case).
    pub fn from_path(path: &Path) -> Result<Self, ConfigError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("ply") => Ok(Self::Ply),
            Some("obj") => Ok(Self::Obj),
            Some("glb") => Ok(Self::Glb),
            _ => Err(ConfigError::MeshExtension(path.to_path_buf())),
        }
    }
}

/// How finely entities are tessellated (see the module documentation for the counts).
#[derive(Clone, Copy, Debug)]
pub struct Tessellation {
    pub segments: u32,
    pub rings: u32,
}

impl Tessellation {
    /// Checks the counts: 3..=1024 segments and 2..=512 rings.
    pub fn checked(segments: u32, rings: u32) -> Result<Self, ConfigError> {
        if !(3..=1024).contains(&segments) || !(2..=512).contains(&rings) {
            return Err(ConfigError::Tessellation { segments, rings });
        }
        Ok(Self { segments, rings })
    }

    /// (vertices, triangles) of one entity with `degenerated` infinite axes; none with three,
    /// which leave no surface to mesh.
    pub fn counts(&self, degenerated: usize) -> (usize, usize) {
        let (s, r) = (self.segments as usize, self.rings as usize);
        match degenerated {
            0 => ((r - 1) * s + 2, 2 * s * (r - 1)),
            1 => (2 * s + 2, 4 * s),
            2 => (8, 4),
            _ => (0, 0),
        }
    }
}

/// An axis-aligned box in world coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Bounds {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl Bounds {
    /// The world box of the map itself: each entity's centre ± its finite half extents along
    /// the world axes (its semi-axes when axis-aligned; a world axis a degenerated one is
    /// turned onto contributes the centre only), grown on each side to at least the largest
    /// finite semi-axis so a lone degenerated entity still gets a visible length.
    pub fn of_map(map: &HostMap) -> Self {
        let mut b = Bounds {
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
        };
        let mut largest = 0.0f64;
        for e in &map.entities {
            let c = map.world_center(&e.entity);
            let r = e.entity.semi_axes().map(f64::from);
            // Identity keeps the f32 semi-axes the axis-aligned boxes were always made of.
            let h = if e.entity.rotation.is_identity() {
                r
            } else {
                half_extents(&e.entity)
            };
            for j in 0..3 {
                if r[j].is_finite() {
                    largest = largest.max(r[j]);
                }
                let h = if h[j].is_finite() { h[j] } else { 0.0 };
                b.min[j] = b.min[j].min(c[j] - h);
                b.max[j] = b.max[j].max(c[j] + h);
            }
        }
        for j in 0..3 {
            let grow = (largest - (b.max[j] - b.min[j])).max(0.0) / 2.0;
            b.min[j] -= grow;
            b.max[j] += grow;
        }
        b
    }

    /// The box seen from an entity's axes around its world centre `c`: per axis, the extent of
    /// `R^T (x - c)` over the box's corners. A degenerated axis spans this, so a turned tube or
    /// plane crosses the whole box along its own direction.
    pub fn in_axes_of(&self, c: [f64; 3], rotation: &Rotation) -> Self {
        let mut b = Bounds {
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
        };
        for corner in 0..8 {
            let x = [0, 1, 2].map(|j| {
                let end = if corner >> j & 1 == 0 {
                    self.min[j]
                } else {
                    self.max[j]
                };
                end - c[j]
            });
            for (j, q) in rotation.inverse_rotate(x).into_iter().enumerate() {
                b.min[j] = b.min[j].min(q);
                b.max[j] = b.max[j].max(q);
            }
        }
        b
    }

    /// The world box of a cloud's points.
    pub fn of_points(origin: [f64; 3], points: &[mema_core::Point3]) -> Self {
        let mut b = Bounds {
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
        };
        for p in points {
            let q = p.to_f64();
            for j in 0..3 {
                b.min[j] = b.min[j].min(origin[j] + q[j]);
                b.max[j] = b.max[j].max(origin[j] + q[j]);
            }
        }
        b
    }
}

/// Triangles of one kind, in world coordinates.
#[derive(Default)]
pub struct Mesh {
    pub positions: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// The map as one mesh per kind present, in `EntityKind::ALL` order, held in memory (`mema
/// export` streams the same vertices and triangles to its file instead, [`export`]). The
/// memory is reserved fallibly, per kind, from the counts.
pub fn tessellate(
    map: &HostMap,
    bounds: &Bounds,
    t: &Tessellation,
) -> Result<Vec<(EntityKind, Mesh)>, TryReserveError> {
    let shapes = Shapes::new(t)?;
    let mut v = reserved(t.counts(0).0)?;
    let mut meshes: Vec<(EntityKind, Mesh)> = Vec::new();
    for kind in EntityKind::ALL {
        let of_kind = || map.entities.iter().filter(move |e| e.kind == kind);
        let (nv, nt) = of_kind()
            .map(|e| t.counts(infinite_axes(e)))
            .fold((0, 0), |(a, b), (c, d)| (a + c, b + d));
        let mut mesh = Mesh {
            positions: reserved(nv)?,
            triangles: reserved(nt)?,
        };
        for e in of_kind() {
            let Some(tri) = entity_vertices(&mut v, map, e, bounds, t, &shapes) else {
                continue;
            };
            let base = mesh.positions.len() as u32;
            mesh.positions.extend_from_slice(&v);
            mesh.triangles
                .extend(tri.iter().map(|t| t.map(|i| base + i)));
        }
        if !mesh.triangles.is_empty() {
            meshes.push((kind, mesh));
        }
    }
    Ok(meshes)
}

/// The triangles of each shape, which depend on the tessellation only: made once and shared
/// by every entity of that shape, so only vertices are made per entity.
pub(crate) struct Shapes {
    ellipsoid: Vec<[u32; 3]>,
    tube: Vec<[u32; 3]>,
    planes: Vec<[u32; 3]>,
}

impl Shapes {
    /// The shapes' triangles, their memory reserved fallibly (12.6 MB at the most segments
    /// and rings).
    pub(crate) fn new(t: &Tessellation) -> Result<Self, TryReserveError> {
        let (s, rings) = (t.segments, t.rings);
        let south = 1 + (rings - 1) * s;
        let at = |ring: u32, i: u32| 1 + (ring - 1) * s + i % s;
        let mut ellipsoid = reserved(t.counts(0).1)?;
        for i in 0..s {
            ellipsoid.push([0, at(1, i), at(1, i + 1)]);
            ellipsoid.push([south, at(rings - 1, i + 1), at(rings - 1, i)]);
        }
        for ring in 1..rings - 1 {
            for i in 0..s {
                let (a, b, c, d) = (
                    at(ring, i),
                    at(ring + 1, i),
                    at(ring + 1, i + 1),
                    at(ring, i + 1),
                );
                ellipsoid.push([a, b, c]);
                ellipsoid.push([a, c, d]);
            }
        }
        let (cap0, cap1) = (2 * s, 2 * s + 1);
        let mut tube = reserved(t.counts(1).1)?;
        for i in 0..s {
            let n = (i + 1) % s;
            tube.push([i, n, s + n]);
            tube.push([i, s + n, s + i]);
            tube.push([cap0, n, i]);
            tube.push([cap1, s + i, s + n]);
        }
        let mut planes = reserved(t.counts(2).1)?;
        planes.extend([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7]]);
        Ok(Shapes {
            ellipsoid,
            tube,
            planes,
        })
    }
}

impl Shapes {
    /// The triangles of `e`'s shape, `None` for an entity with no finite axis.
    pub(crate) fn of(&self, e: &MapEntity) -> Option<&[[u32; 3]]> {
        match infinite_axes(e) {
            0 => Some(&self.ellipsoid),
            1 => Some(&self.tube),
            2 => Some(&self.planes),
            _ => None,
        }
    }
}

/// The infinite semi-axes of `e`, which choose its shape (and [`Tessellation::counts`]).
pub(crate) fn infinite_axes(e: &MapEntity) -> usize {
    e.entity
        .semi_axes()
        .iter()
        .filter(|r| !r.is_finite())
        .count()
}

/// An empty vector with room for `n` items, or the error of a machine that has not the memory
/// (returned rather than ending the process, see [`crate::heap::fallible`]).
pub(crate) fn reserved<T>(n: usize) -> Result<Vec<T>, TryReserveError> {
    let mut v = Vec::new();
    crate::heap::fallible(|| v.try_reserve_exact(n))?;
    Ok(v)
}

/// Replaces `v` with an entity's vertices in world coordinates and returns its triangles
/// (indices into `v`), or `None` for an entity with no finite axis, which has no surface.
///
/// An oriented entity is meshed axis-aligned around 0 in its own axes, its degenerated axes
/// spanning the bounds seen along those axes, and each vertex is then placed at `c + R v`. An
/// axis-aligned one is meshed where it is, so its vertices keep the bits they always had.
fn entity_vertices<'s>(
    v: &mut Vec<[f64; 3]>,
    map: &HostMap,
    e: &MapEntity,
    b: &Bounds,
    t: &Tessellation,
    shapes: &'s Shapes,
) -> Option<&'s [[u32; 3]]> {
    let c = map.world_center(&e.entity);
    let rotation = e.entity.rotation;
    let r = e.entity.semi_axes().map(f64::from);
    v.clear();
    let tri = if rotation.is_identity() {
        axis_aligned_vertices(v, c, r, b, t, shapes)
    } else {
        axis_aligned_vertices(v, [0.0; 3], r, &b.in_axes_of(c, &rotation), t, shapes)
    }?;
    if !rotation.is_identity() {
        for p in v.iter_mut() {
            let q = rotation.rotate(*p);
            *p = [0, 1, 2].map(|j| c[j] + q[j]);
        }
    }
    Some(tri)
}

/// The vertices of an entity of semi-axes `r` centred at `c`, unturned, pushed to `v`; `None`
/// without a finite axis.
fn axis_aligned_vertices<'s>(
    v: &mut Vec<[f64; 3]>,
    c: [f64; 3],
    r: [f64; 3],
    b: &Bounds,
    t: &Tessellation,
    shapes: &'s Shapes,
) -> Option<&'s [[u32; 3]]> {
    let (s, rings) = (t.segments, t.rings);
    let angle = |i: u32| std::f64::consts::TAU * f64::from(i) / f64::from(s);
    let finite: Vec<usize> = (0..3).filter(|&j| r[j].is_finite()).collect();
    match finite[..] {
        [_, _, _] => {
            v.push([c[0], c[1], c[2] + r[2]]);
            for ring in 1..rings {
                let theta = std::f64::consts::PI * f64::from(ring) / f64::from(rings);
                for i in 0..s {
                    let (st, ct, phi) = (theta.sin(), theta.cos(), angle(i));
                    v.push([
                        c[0] + r[0] * st * phi.cos(),
                        c[1] + r[1] * st * phi.sin(),
                        c[2] + r[2] * ct,
                    ]);
                }
            }
            v.push([c[0], c[1], c[2] - r[2]]);
            Some(&shapes.ellipsoid)
        }
        [j, k] => {
            let a = 3 - j - k;
            for end in [b.min[a], b.max[a]] {
                for i in 0..s {
                    let mut p = [0.0; 3];
                    p[a] = end;
                    p[j] = c[j] + r[j] * angle(i).cos();
                    p[k] = c[k] + r[k] * angle(i).sin();
                    v.push(p);
                }
            }
            for end in [b.min[a], b.max[a]] {
                let mut p = c;
                p[a] = end;
                v.push(p);
            }
            Some(&shapes.tube)
        }
        [n] => {
            let (u, w) = ((n + 1) % 3, (n + 2) % 3);
            for side in [-1.0, 1.0] {
                for (du, dw) in [
                    (b.min[u], b.min[w]),
                    (b.max[u], b.min[w]),
                    (b.max[u], b.max[w]),
                    (b.min[u], b.max[w]),
                ] {
                    let mut p = [0.0; 3];
                    p[n] = c[n] + side * r[n];
                    p[u] = du;
                    p[w] = dw;
                    v.push(p);
                }
            }
            Some(&shapes.planes)
        }
        // `Entity` keeps at least one finite axis; a map read from elsewhere without one has
        // no surface to draw.
        _ => None,
    }
}

/// Per-kind figures of `mema export --json`.
#[derive(Serialize, Default)]
pub struct KindMesh {
    pub entities: usize,
    pub vertices: u64,
    pub triangles: u64,
}

/// `mema export --json`: `output`, `format`, `entities`, `vertices`, `triangles`, `bytes`
/// (written) and `limit`, `bounds` (`min`, `max`, `source`: "cloud" or "map") and `kinds`
/// (per kind: entities, vertices, triangles).
#[derive(Serialize)]
pub struct ExportReport {
    pub output: String,
    pub format: MeshFormat,
    pub entities: usize,
    pub vertices: u64,
    pub triangles: u64,
    /// The file's size as written.
    pub bytes: u64,
    /// The most bytes the export was allowed to write.
    pub limit: u64,
    pub bounds: Bounds,
    pub bounds_source: &'static str,
    pub kinds: std::collections::BTreeMap<&'static str, KindMesh>,
}

/// Tessellates `map` and writes it to `output` in the format of its extension, atomically,
/// streaming: one entity's vertices are held at a time, so memory does not grow with the map.
///
/// The mesh's size is counted from the map before any of it is made ([`MeshSize`]); past
/// `max_bytes` ([`DEFAULT_MAX_BYTES`] is `mema export`'s) or past 32-bit indices it is a
/// [`ConfigError`] naming the counts and the finest tessellation that fits, and nothing is
/// written. Memory the machine refuses is an error, not an abort.
pub fn export(
    map: &HostMap,
    bounds: Bounds,
    bounds_source: &'static str,
    t: &Tessellation,
    output: &Path,
    max_bytes: u64,
) -> Result<ExportReport> {
    let format = MeshFormat::from_path(output)?;
    let size = MeshSize::of(map, t, format);
    size.check(map, t, max_bytes)?;
    let shapes = Shapes::new(t).context("memory for the mesh's triangles")?;
    let written = crate::io::atomic::write_atomically_with(output, "mesh", |w| match format {
        MeshFormat::Ply => {
            let counts = (size.vertices, size.triangles);
            formats::write_ply(w, map, &bounds, t, &shapes, counts)
        }
        MeshFormat::Obj => formats::write_obj(w, map, &bounds, t, &shapes),
        MeshFormat::Glb => formats::write_glb(w, map, &bounds, t, &shapes, &size.kinds),
    })?;
    let mut kinds = std::collections::BTreeMap::new();
    for (i, kind) in EntityKind::ALL.into_iter().enumerate() {
        kinds.insert(
            kind.name(),
            KindMesh {
                entities: map.entities.iter().filter(|e| e.kind == kind).count(),
                vertices: size.kinds[i].0,
                triangles: size.kinds[i].1,
            },
        );
    }
    Ok(ExportReport {
        output: output.display().to_string(),
        format,
        entities: map.entities.len(),
        vertices: size.vertices,
        triangles: size.triangles,
        bytes: written,
        limit: max_bytes,
        bounds,
        bounds_source,
        kinds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use mema_core::{Entity, Point3};

    fn entity(r: [f64; 3], kind: EntityKind) -> MapEntity {
        let weights = r.map(|r| {
            if r.is_finite() {
                (1.0 / (r * r)) as f32
            } else {
                0.0
            }
        });
        let entity = Entity::axis_aligned(Point3::new(0.5, -0.25, 1.0), weights);
        MapEntity { entity, kind }
    }

    /// Every entity's mesh is closed and consistently wound (each directed edge once, its
    /// reverse once) except the two open rectangles of a plane pair, with the documented counts.
    #[test]
    fn meshes_are_closed_and_counted_as_documented() {
        let inf = f64::INFINITY;
        let cases = [
            entity([0.3, 0.2, 0.1], EntityKind::Ellipsoid),
            entity([inf, 0.2, 0.1], EntityKind::Pseudocylinder),
            entity([0.3, inf, inf], EntityKind::PlanePair),
        ];
        let t = Tessellation::checked(7, 5).unwrap();
        // Turned, every mesh keeps its counts, its closure and its outward winding.
        let turn = mema_core::Rotation::from_quaternion([0.3, -0.5, 0.2, 0.8]).unwrap();
        let turned = cases.map(|e| MapEntity {
            entity: e.entity.with_rotation(turn),
            ..e
        });
        for e in cases.into_iter().chain(turned) {
            let map = HostMap::new([10.0, 20.0, 30.0], vec![e]);
            let bounds = Bounds::of_map(&map);
            let meshes = tessellate(&map, &bounds, &t).expect("memory");
            let (_, mesh) = &meshes[0];
            let d = e.entity.degenerated_axes();
            assert_eq!(
                (mesh.positions.len(), mesh.triangles.len()),
                t.counts(d),
                "{e:?}"
            );
            let mut edges = std::collections::HashMap::new();
            for tri in &mesh.triangles {
                for k in 0..3 {
                    *edges.entry((tri[k], tri[(k + 1) % 3])).or_insert(0) += 1;
                }
            }
            let closed = edges
                .iter()
                .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1));
            assert_eq!(closed, d < 2, "{e:?}");
            // Outward winding: the signed volume is positive for the closed solids.
            let volume: f64 = mesh
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                    let cross = [
                        b[1] * c[2] - b[2] * c[1],
                        b[2] * c[0] - b[0] * c[2],
                        b[0] * c[1] - b[1] * c[0],
                    ];
                    (a[0] * cross[0] + a[1] * cross[1] + a[2] * cross[2]) / 6.0
                })
                .sum();
            if d < 2 {
                assert!(volume > 0.0, "{e:?}: {volume}");
            }
        }
    }
}
