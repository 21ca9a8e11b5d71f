//! `mema info`: a map's entities per kind, bounds, layout and bytes.

use anyhow::Result;
use mema::analysis::stats;
use mema::io::mapfile::{HostMap, KindCounts};
use mema_core::map::Layout;
use serde::Serialize;

use crate::cli::args::InfoArgs;

#[derive(Serialize)]
struct InfoReport {
    entities: usize,
    kinds: KindCounts,
    origin: [f64; 3],
    /// World bounding box of the entity centres.
    center_min: [f64; 3],
    center_max: [f64; 3],
    /// Smallest and largest finite semi-axis.
    semi_axis_min: f64,
    semi_axis_max: f64,
    /// Table 2's count, as `mema map` and `mema eval` give it: each entity at its record's
    /// bytes in the layout (`record_bytes`).
    map_bytes: usize,
    /// The paper's count: 24 bytes for any entity (six f32).
    paper_bytes: usize,
    file_bytes: u64,
    /// How `.mema` stores (or would store) these entities, and its bytes per entity.
    layout: String,
    record_bytes: usize,
    /// Entities with a rotation other than the identity.
    oriented: usize,
    /// Why the entities are not on the quantized grid, where the streamed maps' rule says so
    /// (null otherwise).
    not_quantized: Option<String>,
    /// Scans whose range image the map keeps as its free space (0: none recorded), and the
    /// bytes of that part of the file.
    free_space_images: usize,
    free_space_bytes: usize,
}

fn layout_name(layout: &Layout) -> &'static str {
    match layout {
        Layout::AxisAligned => "version 1, axis-aligned f32",
        Layout::Oriented => "version 2, oriented f32",
        Layout::Quantized(_) => "version 2, oriented, quantized",
    }
}

/// Why `map`'s shells are written in f32, if the rule a streamed map's layout follows
/// ([`mema_core::stream::shells::quantizes`]) says so: most of them thinner than four steps of
/// the grid their extent would take.
fn not_quantized(map: &HostMap) -> Option<String> {
    use mema_core::stream::shells::{THIN_STEPS, quantizes};
    if map.quantization.is_some() || map.entities.is_empty() {
        return None;
    }
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for e in &map.entities {
        for (j, v) in e.entity.center.to_array().into_iter().enumerate() {
            lo[j] = lo[j].min(v);
            hi[j] = hi[j].max(v);
        }
    }
    let far = (0..3).map(|j| (hi[j] - lo[j]) / 2.0).fold(0.0f32, f32::max);
    let step = far / 32_767.0;
    let thin = map
        .entities
        .iter()
        .filter(|e| {
            let shortest = e
                .entity
                .semi_axes()
                .into_iter()
                .fold(f32::INFINITY, f32::min);
            shortest < THIN_STEPS * step
        })
        .count();
    (!quantizes(step, thin, map.entities.len(), 0.0)).then(|| {
        format!(
            "{thin} of {} shells are thinner than {THIN_STEPS} steps of the grid this map's extent takes ({:.3e} m a step): on it they would move off their surfaces, so they are kept in f32",
            map.entities.len(),
            step
        )
    })
}

pub fn info(args: &InfoArgs) -> Result<()> {
    let map = HostMap::read(&args.map)?;
    let file_bytes = std::fs::metadata(&args.map).map(|m| m.len()).unwrap_or(0);
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let (mut rmin, mut rmax) = (f64::INFINITY, 0.0f64);
    for e in &map.entities {
        let c = map.world_center(&e.entity);
        for j in 0..3 {
            lo[j] = lo[j].min(c[j]);
            hi[j] = hi[j].max(c[j]);
        }
        for r in e.entity.semi_axes().into_iter().filter(|r| r.is_finite()) {
            rmin = rmin.min(r as f64);
            rmax = rmax.max(r as f64);
        }
    }
    let r = InfoReport {
        entities: map.entities.len(),
        kinds: KindCounts::of(&map),
        origin: map.origin,
        center_min: lo,
        center_max: hi,
        semi_axis_min: rmin,
        semi_axis_max: rmax,
        map_bytes: map.entities.len() * map.layout().record_len(),
        paper_bytes: map.entities.len() * stats::MAP_BYTES_PER_ENTITY,
        file_bytes,
        layout: layout_name(&map.layout()).into(),
        oriented: map
            .entities
            .iter()
            .filter(|e| !e.entity.rotation.is_identity())
            .count(),
        record_bytes: map.layout().record_len(),
        not_quantized: not_quantized(&map),
        free_space_images: map.free_space.len(),
        free_space_bytes: mema::io::free_space::part_bytes(&map.free_space),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!("{}: {} entities", args.map.display(), r.entities);
        println!(
            "kinds: {} ellipsoid, {} sphere, {} pseudocylinder, {} plane_pair",
            r.kinds.ellipsoid, r.kinds.sphere, r.kinds.pseudocylinder, r.kinds.plane_pair
        );
        println!("origin (m): {:?}", r.origin);
        if r.entities == 0 {
            println!("centres: none; finite semi-axes: none (the map is empty)");
        } else {
            println!("centres (m): {:?} .. {:?}", r.center_min, r.center_max);
            println!(
                "finite semi-axes (m): {} .. {}",
                r.semi_axis_min, r.semi_axis_max
            );
        }
        println!(
            "layout: {} ({} bytes an entity), {} of {} entities oriented",
            r.layout, r.record_bytes, r.oriented, r.entities
        );
        if let Some(why) = &r.not_quantized {
            println!("not quantized: {why}");
        }
        println!(
            "bytes: {} in the file; map bytes (Table 2, {} per entity) {}; {} at the paper's 24 per entity",
            r.file_bytes, r.record_bytes, r.map_bytes, r.paper_bytes
        );
        if r.free_space_images == 0 {
            println!("free space: none recorded");
        } else {
            println!(
                "free space: range images of {} scans, {} bytes",
                r.free_space_images, r.free_space_bytes
            );
        }
    }
    Ok(())
}
