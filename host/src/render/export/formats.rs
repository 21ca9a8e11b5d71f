//! The mesh file formats of `mema export`: PLY, OBJ and binary glTF.

use anyhow::{Context, Result};
use mema_core::EntityKind;

use super::{Mesh, kind_colour};
use crate::io::mapfile::HostMap;

/// Binary little-endian PLY: `double x y z` and `uchar red green blue` per vertex (the kind's
/// colour), `list uchar int vertex_indices` per face.
pub fn to_ply(map: &HostMap, meshes: &[(EntityKind, Mesh)]) -> Vec<u8> {
    let vertices: usize = meshes.iter().map(|(_, m)| m.positions.len()).sum();
    let faces: usize = meshes.iter().map(|(_, m)| m.triangles.len()).sum();
    let o = map.origin;
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment mema map, {} entities; map origin {} {} {}\n\
         element vertex {vertices}\nproperty double x\nproperty double y\nproperty double z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {faces}\nproperty list uchar int vertex_indices\nend_header\n",
        map.entities.len(),
        o[0],
        o[1],
        o[2]
    )
    .into_bytes();
    for (kind, m) in meshes {
        for p in &m.positions {
            p.iter()
                .for_each(|c| out.extend_from_slice(&c.to_le_bytes()));
            out.extend_from_slice(&kind_colour(*kind));
        }
    }
    let mut base = 0u32;
    for (_, m) in meshes {
        for t in &m.triangles {
            out.push(3);
            t.iter()
                .for_each(|i| out.extend_from_slice(&(base + i).to_le_bytes()));
        }
        base += m.positions.len() as u32;
    }
    out
}

/// Wavefront OBJ with one group per kind and the kind's colour after each vertex (the
/// extension MeshLab, CloudCompare and Blender read).
pub fn to_obj(map: &HostMap, meshes: &[(EntityKind, Mesh)]) -> Vec<u8> {
    use std::fmt::Write;
    let o = map.origin;
    let mut s = format!(
        "# mema map, {} entities; map origin {} {} {}\n",
        map.entities.len(),
        o[0],
        o[1],
        o[2]
    );
    let mut base = 1u32;
    for (kind, m) in meshes {
        let [r, g, b] = kind_colour(*kind).map(|c| f64::from(c) / 255.0);
        let _ = writeln!(s, "g {}", kind.name());
        for p in &m.positions {
            let _ = writeln!(s, "v {} {} {} {r:.4} {g:.4} {b:.4}", p[0], p[1], p[2]);
        }
        for t in &m.triangles {
            let _ = writeln!(s, "f {} {} {}", base + t[0], base + t[1], base + t[2]);
        }
        base += m.positions.len() as u32;
    }
    s.into_bytes()
}

/// Binary glTF 2.0: one node translated to the map's origin, one mesh with a primitive and a
/// material per kind, f32 positions relative to the origin and u32 indices.
pub fn to_glb(map: &HostMap, meshes: &[(EntityKind, Mesh)]) -> Result<Vec<u8>> {
    use serde_json::json;
    let mut bin: Vec<u8> = Vec::new();
    let (mut views, mut accessors, mut primitives, mut materials) =
        (vec![], vec![], vec![], vec![]);
    for (kind, m) in meshes {
        let local: Vec<[f32; 3]> = m
            .positions
            .iter()
            .map(|p| [0, 1, 2].map(|j| (p[j] - map.origin[j]) as f32))
            .collect();
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let start = bin.len();
        for p in &local {
            for j in 0..3 {
                lo[j] = lo[j].min(p[j]);
                hi[j] = hi[j].max(p[j]);
                bin.extend_from_slice(&p[j].to_le_bytes());
            }
        }
        views.push(json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start, "target": 34962}));
        accessors.push(
            json!({"bufferView": views.len() - 1, "componentType": 5126, "count": local.len(),
            "type": "VEC3", "min": lo, "max": hi}),
        );
        let start = bin.len();
        for i in m.triangles.iter().flatten() {
            bin.extend_from_slice(&i.to_le_bytes());
        }
        views.push(json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start, "target": 34963}));
        accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5125,
            "count": 3 * m.triangles.len(), "type": "SCALAR"}));
        let [r, g, b] = kind_colour(*kind).map(|c| f64::from(c) / 255.0);
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
        "buffers": [{"byteLength": bin.len()}],
    });
    let mut json_chunk = serde_json::to_vec(&doc)?;
    while !json_chunk.len().is_multiple_of(4) {
        json_chunk.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json_chunk.len() + 8 + bin.len();
    let total = u32::try_from(total).context("the mesh exceeds glTF's 4 GiB limit")?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total.to_le_bytes());
    for (kind, chunk) in [(*b"JSON", &json_chunk), (*b"BIN\0", &bin)] {
        out.extend_from_slice(&(chunk.len() as u32).to_le_bytes());
        out.extend_from_slice(&kind);
        out.extend_from_slice(chunk);
    }
    Ok(out)
}
