//! The mesh file formats of `mema export`, written as they are made: PLY, OBJ and binary
//! glTF. Each entity's vertices are made into one reused buffer and written out; triangles come
//! from the shapes' shared lists. Every format lists the kinds in `EntityKind::ALL` order and,
//! within a kind, the entities in map order.

use anyhow::{Context, Result};
use mema_core::{EntityKind, MapEntity};
use std::io::Write;

use super::{Bounds, Shapes, Tessellation, entity_vertices, kind_colour, reserved};
use crate::io::mapfile::HostMap;

/// Calls `each` with every entity of `kind` that has a surface: its vertices (world
/// coordinates) and its triangles (indices into them).
fn each_entity(
    map: &HostMap,
    kind: EntityKind,
    bounds: &Bounds,
    t: &Tessellation,
    shapes: &Shapes,
    mut each: impl FnMut(&MapEntity, &[[f64; 3]], &[[u32; 3]]) -> Result<()>,
) -> Result<()> {
    let mut v = reserved(t.counts(0).0).context("memory for an entity's vertices")?;
    for e in map.entities.iter().filter(|e| e.kind == kind) {
        if let Some(tri) = entity_vertices(&mut v, map, e, bounds, t, shapes) {
            each(e, &v, tri)?;
        }
    }
    Ok(())
}

/// PLY's header for these counts (its length is part of [`MeshSize`]).
pub(crate) fn ply_header(map: &HostMap, vertices: u64, faces: u64) -> String {
    let o = map.origin;
    format!(
        "ply\nformat binary_little_endian 1.0\ncomment mema map, {} entities; map origin {} {} {}\n\
         element vertex {vertices}\nproperty double x\nproperty double y\nproperty double z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {faces}\nproperty list uchar int vertex_indices\nend_header\n",
        map.entities.len(),
        o[0],
        o[1],
        o[2]
    )
}

/// Binary little-endian PLY of (vertices, triangles) counted beforehand: `double x y z` and
/// `uchar red green blue` per vertex (the kind's colour), `list uchar int vertex_indices` per
/// face. The vertices come first, so the entities
/// are visited twice: for their vertices, then for their faces, which need only their counts.
pub(crate) fn write_ply(
    w: &mut impl Write,
    map: &HostMap,
    bounds: &Bounds,
    t: &Tessellation,
    shapes: &Shapes,
    (vertices, triangles): (u64, u64),
) -> Result<()> {
    w.write_all(ply_header(map, vertices, triangles).as_bytes())?;
    let mut record = [0u8; 27];
    for kind in EntityKind::ALL {
        record[24..].copy_from_slice(&kind_colour(kind));
        each_entity(map, kind, bounds, t, shapes, |_, v, _| {
            for p in v {
                for (j, c) in p.iter().enumerate() {
                    record[8 * j..8 * j + 8].copy_from_slice(&c.to_le_bytes());
                }
                w.write_all(&record)?;
            }
            Ok(())
        })?;
    }
    let mut base = 0u32;
    let mut face = [3u8; 13];
    for kind in EntityKind::ALL {
        for e in map.entities.iter().filter(|e| e.kind == kind) {
            let Some(tri) = shapes.of(e) else {
                continue;
            };
            for tr in tri {
                for (j, i) in tr.iter().enumerate() {
                    face[1 + 4 * j..5 + 4 * j].copy_from_slice(&(base + i).to_le_bytes());
                }
                w.write_all(&face)?;
            }
            base += t.counts(super::infinite_axes(e)).0 as u32;
        }
    }
    Ok(())
}

/// OBJ's first line.
pub(crate) fn obj_header(map: &HostMap) -> String {
    let o = map.origin;
    format!(
        "# mema map, {} entities; map origin {} {} {}\n",
        map.entities.len(),
        o[0],
        o[1],
        o[2]
    )
}

/// A coordinate in at most 25 characters that reads back to the same f64: plain decimals
/// where they are short (as before), the exponent form for the very small and very large,
/// whose plain decimals can run to hundreds of digits.
fn obj_number(w: &mut impl Write, x: f64) -> std::io::Result<()> {
    if x == 0.0 || !x.is_finite() || (1e-5..1e16).contains(&x.abs()) {
        write!(w, "{x}")
    } else {
        write!(w, "{x:e}")
    }
}

/// Wavefront OBJ with one group per kind and the kind's colour after each vertex (the
/// extension MeshLab, CloudCompare and Blender read). Each group's vertices come before its
/// faces, so each kind's entities are visited twice.
pub(crate) fn write_obj(
    w: &mut impl Write,
    map: &HostMap,
    bounds: &Bounds,
    t: &Tessellation,
    shapes: &Shapes,
) -> Result<()> {
    w.write_all(obj_header(map).as_bytes())?;
    let mut base = 1u32;
    for kind in EntityKind::ALL {
        let of_kind = || map.entities.iter().filter(move |e| e.kind == kind);
        if !of_kind().any(|e| shapes.of(e).is_some()) {
            continue;
        }
        let [r, g, b] = kind_colour(kind).map(|c| f64::from(c) / 255.0);
        writeln!(w, "g {}", kind.name())?;
        each_entity(map, kind, bounds, t, shapes, |_, v, _| {
            for p in v {
                w.write_all(b"v ")?;
                for c in p {
                    obj_number(w, *c)?;
                    w.write_all(b" ")?;
                }
                writeln!(w, "{r:.4} {g:.4} {b:.4}")?;
            }
            Ok(())
        })?;
        for e in of_kind() {
            let Some(tri) = shapes.of(e) else {
                continue;
            };
            for tr in tri {
                writeln!(w, "f {} {} {}", base + tr[0], base + tr[1], base + tr[2])?;
            }
            base += t.counts(super::infinite_axes(e)).0 as u32;
        }
    }
    Ok(())
}

/// Per kind, the box of its f32 positions local to the map's origin (glTF's accessor min and
/// max).
type KindBoxes = [([f32; 3], [f32; 3]); 4];

/// The glTF JSON chunk, unpadded: the layout follows from the counts alone (per kind present,
/// its positions then its indices in the binary chunk); `boxes` gives the accessors' min and
/// max, or 0 for each when only the length is wanted.
pub(crate) fn glb_json(
    map: &HostMap,
    kinds: &[(u64, u64); 4],
    boxes: Option<&KindBoxes>,
) -> serde_json::Result<Vec<u8>> {
    use serde_json::json;
    let (mut views, mut accessors, mut primitives, mut materials) =
        (vec![], vec![], vec![], vec![]);
    let mut offset = 0u64;
    for (k, kind) in EntityKind::ALL.into_iter().enumerate() {
        let (v, f) = kinds[k];
        if f == 0 {
            continue;
        }
        let (lo, hi) = boxes.map_or(([0.0f32; 3], [0.0f32; 3]), |b| b[k]);
        views.push(
            json!({"buffer": 0, "byteOffset": offset, "byteLength": 12 * v, "target": 34962}),
        );
        offset += 12 * v;
        accessors.push(
            json!({"bufferView": views.len() - 1, "componentType": 5126, "count": v,
            "type": "VEC3", "min": lo, "max": hi}),
        );
        views.push(
            json!({"buffer": 0, "byteOffset": offset, "byteLength": 12 * f, "target": 34963}),
        );
        offset += 12 * f;
        accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5125,
            "count": 3 * f, "type": "SCALAR"}));
        let [r, g, b] = kind_colour(kind).map(|c| f64::from(c) / 255.0);
        materials.push(json!({"name": kind.name(),
            "pbrMetallicRoughness": {"baseColorFactor": [r, g, b, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8}}));
        primitives.push(
            json!({"attributes": {"POSITION": accessors.len() - 2}, "indices": accessors.len() - 1,
            "material": materials.len() - 1, "mode": 4}),
        );
    }
    let doc = json!({
        "asset": {"version": "2.0", "generator": concat!("mema ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "mema map", "mesh": 0, "translation": map.origin,
            "extras": {"mema_origin": map.origin, "entities": map.entities.len()}}],
        "meshes": [{"name": "entities", "primitives": primitives}],
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": offset}],
    });
    serde_json::to_vec(&doc)
}

/// An entity's vertices as glTF holds them: f32, local to the map's origin.
fn local(map: &HostMap, p: &[f64; 3]) -> [f32; 3] {
    [0, 1, 2].map(|j| (p[j] - map.origin[j]) as f32)
}

/// Binary glTF 2.0: one node translated to the map's origin, one mesh with a primitive and a
/// material per kind, f32 positions relative to the origin and u32 indices; `kinds` holds each
/// kind's (vertices, triangles), counted beforehand. The JSON chunk
/// comes first and holds each kind's box, so the vertices are made once for the boxes and
/// again to be written.
pub(crate) fn write_glb(
    w: &mut impl Write,
    map: &HostMap,
    bounds: &Bounds,
    t: &Tessellation,
    shapes: &Shapes,
    kinds: &[(u64, u64); 4],
) -> Result<()> {
    let mut boxes: KindBoxes = [([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]); 4];
    for (k, kind) in EntityKind::ALL.into_iter().enumerate() {
        let (lo, hi) = &mut boxes[k];
        each_entity(map, kind, bounds, t, shapes, |_, v, _| {
            for p in v {
                let q = local(map, p);
                for j in 0..3 {
                    lo[j] = lo[j].min(q[j]);
                    hi[j] = hi[j].max(q[j]);
                }
            }
            Ok(())
        })?;
    }
    let mut json = glb_json(map, kinds, Some(&boxes))?;
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin: u64 = kinds.iter().map(|(v, f)| 12 * (v + f)).sum();
    let total = u32::try_from(12 + 8 + json.len() as u64 + 8 + bin)
        .context("the mesh exceeds glTF's 4 GiB limit")?;
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&total.to_le_bytes())?;
    w.write_all(&(json.len() as u32).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(&json)?;
    w.write_all(&(bin as u32).to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    for kind in EntityKind::ALL {
        each_entity(map, kind, bounds, t, shapes, |_, v, _| {
            for p in v {
                for c in local(map, p) {
                    w.write_all(&c.to_le_bytes())?;
                }
            }
            Ok(())
        })?;
        // Indices count from the kind's own first vertex: each kind is its own primitive.
        let mut base = 0u32;
        for e in map.entities.iter().filter(|e| e.kind == kind) {
            let Some(tri) = shapes.of(e) else {
                continue;
            };
            for i in tri.iter().flatten() {
                w.write_all(&(base + i).to_le_bytes())?;
            }
            base += t.counts(super::infinite_axes(e)).0 as u32;
        }
    }
    Ok(())
}
