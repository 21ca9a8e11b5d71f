//! `mema._mema.merge`: maps made apart (the tiles of `mema.tiles`) as one map around one origin.

use mema::io::HostMap;
use mema_core::map::record::Quantization;
use mema_core::{MapEntity, Point3};
use pyo3::prelude::*;

use crate::errors::bad_value;
use crate::map::Map;

/// One map holding every entity of `maps`, in their order, around one origin: the centre of the
/// box of their entities' world centres (given, `origin=`, when the caller wants another). Each
/// centre is moved in f64 (`map origin + centre - origin`) and rounded once to f32; axes and
/// rotations are kept. If any map is quantized, the merged map is quantized on the finest grid
/// that holds every entity, as a shells map is, so its `.mema` file costs what the budget paid
/// for; otherwise its entities stay f32.
#[pyfunction]
#[pyo3(signature = (maps, origin = None))]
pub fn merge(maps: Vec<PyRef<'_, Map>>, origin: Option<[f64; 3]>) -> PyResult<Map> {
    let maps: Vec<&HostMap> = maps.iter().map(|m| &m.map).collect();
    merge_maps(&maps, origin).map(Map::new)
}

fn merge_maps(maps: &[&HostMap], origin: Option<[f64; 3]>) -> PyResult<HostMap> {
    if maps.is_empty() {
        return Err(bad_value("maps", "give at least one map to merge"));
    }
    let world = |m: &HostMap, e: &MapEntity| m.world_center(&e.entity);
    let origin = match origin {
        Some(o) if o.iter().all(|v| v.is_finite()) => o,
        Some(_) => return Err(bad_value("origin", "expected three finite numbers")),
        None => {
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for m in maps {
                for e in &m.entities {
                    for (axis, v) in world(m, e).into_iter().enumerate() {
                        lo[axis] = lo[axis].min(v);
                        hi[axis] = hi[axis].max(v);
                    }
                }
            }
            if lo[0] > hi[0] {
                // No entity anywhere: the first map's frame is as good as any.
                maps[0].origin
            } else {
                // Halved first, as the readers centre a cloud, so huge bounds cannot overflow.
                std::array::from_fn(|a| lo[a] / 2.0 + hi[a] / 2.0)
            }
        }
    };
    let entities: Vec<MapEntity> = maps
        .iter()
        .flat_map(|m| {
            m.entities.iter().map(move |e| {
                let c = world(m, e);
                let local = |a: usize| (c[a] - origin[a]) as f32;
                let mut moved = *e;
                moved.entity.center = Point3::new(local(0), local(1), local(2));
                moved
            })
        })
        .collect();
    if maps.iter().all(|m| m.quantization.is_none()) {
        return Ok(HostMap::new(origin, entities));
    }
    let grid = Quantization::for_entities(entities.iter().copied());
    if !grid.is_valid() {
        return Err(bad_value(
            "maps",
            "their entities span more than one quantized map can hold",
        ));
    }
    Ok(HostMap {
        origin,
        entities: entities.into_iter().map(|e| grid.quantize(e)).collect(),
        quantization: Some(grid),
        // Tiles' free space is not merged yet (issue 29): the merged map records none.
        free_space: Vec::new(),
    })
}
