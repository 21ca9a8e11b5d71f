//! The shells shaped to their input's rays, kept only where the points say the map is no worse
//! for it ([`crate::mapping::ray_shaping`] does the shaping).

use mema_core::MapEntity;
use mema_core::shell::ShellParams;
use serde::Serialize;

use crate::io::cloud::LocalCloud;
use crate::io::mapfile::HostMap;

/// What [`crate::mapping::ray_shaping`] did to a map's shells.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RayShapingReport {
    /// Rays of the input scored.
    pub rays: usize,
    /// The agreement tolerance (metres): two median point spacings.
    pub tolerance: f64,
    /// Rays whose first surface agreed with their end, and that stopped early: the shells as
    /// made, then shaped.
    pub agree: [usize; 2],
    pub early: [usize; 2],
    /// Shells whose shape changed.
    pub changed: usize,
    /// The two-way Chamfer distance to the points (metres) of the map as made and shaped.
    pub chamfer: [f64; 2],
    /// Whether the shaped map was kept (its Chamfer distance no worse).
    pub kept: bool,
}

/// Points and surface samples the shaped map is judged on against the map as made: enough
/// for the two Chamfer distances to differ by their maps, not by the draw.
const SHAPING_JUDGED_ON: usize = 20_000;

/// Shapes `map`'s shells to `cloud`'s rays, and keeps the shaped shells if their two-way
/// Chamfer distance to the points is no worse than the shells'. Shaping trades how close the
/// points lie to the surface for surface where the rays say there is none; on the dense depth
/// frames and the bunny's range scans that trade measured against the map, on the lidar
/// sweeps for it, so each map is judged on its own points.
pub(super) fn shape_to_rays(
    cloud: &LocalCloud,
    labels: &[u32],
    map: &mut HostMap,
    params: ShellParams,
) -> Option<RayShapingReport> {
    let entities: Vec<mema_core::Entity> = map.entities.iter().map(|e| e.entity).collect();
    let shaped = crate::mapping::ray_shaping::shape(cloud, labels, &entities)?;
    let tolerance = params.degeneration.sphere_tolerance;
    let candidate: Vec<MapEntity> = shaped
        .entities
        .iter()
        .map(|&entity| MapEntity {
            entity,
            kind: entity.kind(tolerance),
        })
        .collect();
    let grid = mema_core::map::record::Quantization::for_entities(candidate.iter().copied());
    let candidate: Vec<MapEntity> = candidate.into_iter().map(|e| grid.quantize(e)).collect();
    let step = cloud.points.len().div_ceil(SHAPING_JUDGED_ON).max(1);
    let points: Vec<[f64; 3]> = cloud
        .points
        .iter()
        .step_by(step)
        .map(|p| p.to_f64())
        .collect();
    let chamfer = |entities: &[MapEntity]| {
        let entities: Vec<mema_core::Entity> = entities.iter().map(|e| e.entity).collect();
        crate::analysis::fidelity::two_way_score(&points, &entities, 0, SHAPING_JUDGED_ON)
            .map_or(f64::INFINITY, |s| s.chamfer)
    };
    let (before, after) = (chamfer(&map.entities), chamfer(&candidate));
    let kept = after <= before;
    if kept {
        map.entities = candidate;
        map.quantization = Some(grid);
    }
    Some(RayShapingReport {
        rays: shaped.rays,
        tolerance: shaped.tolerance,
        agree: shaped.agree,
        early: shaped.early,
        changed: shaped.changed,
        chamfer: [before, after],
        kept,
    })
}
