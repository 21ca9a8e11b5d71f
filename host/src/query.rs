//! `mema query`, `mema transform` and `mema query-bench`: the map as a robot uses it.

use anyhow::{Context, Result, bail};
use mema_core::MapEntity;
use mema_core::query::{MapIndex, Nearest, RayHit, brute_force};
use mema_core::transform::RigidTransform;
use serde::Serialize;
use std::time::Instant;

use crate::cli::{QueryArgs, QueryBenchArgs, TransformArgs, UsageError};
use crate::io::mapfile::HostMap;

/// Entities an index can hold on the host (the paper's largest map has 8,880).
pub const INDEX_CAPACITY: usize = 16_384;
pub type HostIndex = MapIndex<INDEX_CAPACITY>;

/// Builds the index on a thread with a large stack: at 16,384 entities the value is ~2.5 MB.
pub fn build_index(map: &HostMap) -> Result<Box<HostIndex>> {
    let entities: Vec<MapEntity> = map.entities.clone();
    std::thread::Builder::new()
        .stack_size(64 << 20)
        .spawn(move || HostIndex::build(entities).map(Box::new))
        .context("index thread")?
        .join()
        .map_err(|_| anyhow::anyhow!("index thread failed"))?
        .map_err(|e| anyhow::anyhow!("{e}; the map has too many entities for the query index"))
}

/// Parses `x,y,z` (or six numbers for a ray) from the command line.
pub fn parse_numbers<const N: usize>(text: &str, what: &str) -> Result<[f64; N], UsageError> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let bad = || {
        UsageError(format!(
            "{what} '{text}': expected {N} comma-separated numbers"
        ))
    };
    if parts.len() != N {
        return Err(bad());
    }
    let mut out = [0.0; N];
    for (o, p) in out.iter_mut().zip(parts) {
        *o = p
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(bad)?;
    }
    Ok(out)
}

fn local(map: &HostMap, p: [f64; 3]) -> [f64; 3] {
    [
        p[0] - map.origin[0],
        p[1] - map.origin[1],
        p[2] - map.origin[2],
    ]
}

fn world(map: &HostMap, p: [f64; 3]) -> [f64; 3] {
    [
        p[0] + map.origin[0],
        p[1] + map.origin[1],
        p[2] + map.origin[2],
    ]
}

#[derive(Serialize)]
struct PointAnswer {
    point: [f64; 3],
    signed_distance: Option<f64>,
    nearest_entity: Option<usize>,
    nearest_kind: Option<&'static str>,
    occupied_by: Option<usize>,
}

#[derive(Serialize)]
struct RayAnswer {
    origin: [f64; 3],
    direction: [f64; 3],
    hit: bool,
    range: Option<f64>,
    entity: Option<usize>,
    kind: Option<&'static str>,
    point: Option<[f64; 3]>,
}

pub fn query(args: &QueryArgs) -> Result<()> {
    if args.point.is_none() && args.ray.is_none() {
        return Err(UsageError(
            "nothing to ask: give --point x,y,z or --ray ox,oy,oz,dx,dy,dz".into(),
        )
        .into());
    }
    let map = HostMap::read(&args.map)?;
    let index = build_index(&map)?;
    let kind = |i: usize| map.entities.get(i).map(|e| e.kind.name());
    if let Some(text) = &args.point {
        let p = parse_numbers::<3>(text, "--point")?;
        let q = local(&map, p);
        let nearest = index.nearest(q);
        let answer = PointAnswer {
            point: p,
            signed_distance: nearest.map(|n| n.signed_distance),
            nearest_entity: nearest.map(|n| n.entity),
            nearest_kind: nearest.and_then(|n| kind(n.entity)),
            occupied_by: index.occupied(q),
        };
        if args.json {
            println!("{}", serde_json::to_string(&answer)?);
        } else {
            match nearest {
                Some(Nearest {
                    signed_distance,
                    entity,
                }) => println!(
                    "point {:?}: {} the map; nearest surface {:.6} away, entity {entity} ({})",
                    p,
                    if signed_distance < 0.0 {
                        "inside"
                    } else {
                        "outside"
                    },
                    signed_distance.abs(),
                    kind(entity).unwrap_or("?")
                ),
                None => println!("point {p:?}: the map is empty"),
            }
        }
    }
    if let Some(text) = &args.ray {
        let r = parse_numbers::<6>(text, "--ray")?;
        let (o, d) = ([r[0], r[1], r[2]], [r[3], r[4], r[5]]);
        if d == [0.0; 3] {
            bail!("--ray: the direction is zero");
        }
        let hit = index.ray_cast(local(&map, o), d, args.max_range);
        let answer = RayAnswer {
            origin: o,
            direction: d,
            hit: hit.is_some(),
            range: hit.map(|h| h.t),
            entity: hit.map(|h| h.entity),
            kind: hit.and_then(|h| kind(h.entity)),
            point: hit.map(|h| world(&map, h.point)),
        };
        if args.json {
            println!("{}", serde_json::to_string(&answer)?);
        } else {
            match hit {
                Some(RayHit { t, entity, point }) => println!(
                    "ray from {o:?}: hits entity {entity} ({}) at range {t:.6}, point {:?}",
                    kind(entity).unwrap_or("?"),
                    world(&map, point)
                ),
                None => println!("ray from {o:?}: no hit within {}", args.max_range),
            }
        }
    }
    Ok(())
}

/// Applies `transform` to a whole map: the origin moves exactly in f64, shapes per entity
/// (`None` if `transform` is not a rigid rotation). The result is not quantized: a rotated grid
/// entity is no longer on the grid, and rounding it again would make the rotation lossy.
pub fn transform_map(map: &HostMap, transform: &RigidTransform) -> Option<HostMap> {
    // x' = R (origin + local) + t = (R origin + t) + R local.
    let origin = transform.apply_point(map.origin);
    let rotation_only = RigidTransform {
        translation: [0.0; 3],
        ..*transform
    };
    let entities = map
        .entities
        .iter()
        .map(|e| {
            Some(MapEntity {
                entity: rotation_only.apply_entity(&e.entity)?,
                kind: e.kind,
            })
        })
        .collect::<Option<Vec<_>>>()?;
    Some(HostMap::new(origin, entities))
}

pub fn transform(args: &TransformArgs) -> Result<()> {
    crate::commands::check_output(&args.output)?;
    let map = HostMap::read(&args.map)?;
    let mut t = RigidTransform::IDENTITY;
    if let Some(text) = &args.rotate {
        let deg = parse_numbers::<3>(text, "--rotate")?;
        for (axis, angle) in deg.iter().enumerate() {
            let step = RigidTransform::rotation_about(axis, angle.to_radians());
            // Multiples of 90 degrees are axis permutations: snap them so they stay exact.
            let step = if angle.rem_euclid(90.0) == 0.0 {
                RigidTransform {
                    rotation: step.rotation.map(|r| r.map(f64::round)),
                    ..step
                }
            } else {
                step
            };
            t = step.after(&t);
        }
    }
    if let Some(text) = &args.translate {
        t = RigidTransform::translation(parse_numbers::<3>(text, "--translate")?).after(&t);
    }
    let moved = transform_map(&map, &t)
        .with_context(|| format!("{}: the transform is not a rotation", args.map.display()))?;
    moved.write(&args.output)?;
    eprintln!(
        "mema: transformed {} entities ({})",
        moved.entities.len(),
        if t.is_axis_permutation() {
            "translation and axis permutation: exact, axis-aligned entities stay axis-aligned"
        } else {
            "rotation: entities turned with the map, orientation stored as a quaternion"
        }
    );
    println!("{}", args.output.display());
    Ok(())
}

#[derive(Serialize)]
pub struct QueryBench {
    pub entities: usize,
    pub queries: usize,
    pub disagreements: usize,
    pub index_queries_per_s: f64,
    pub brute_force_queries_per_s: f64,
    pub speedup: f64,
    /// The demo scene's rays cast against its own map.
    pub rays: usize,
    pub rays_hit_both: usize,
    pub rays_scene_only: usize,
    pub rays_map_only: usize,
    pub range_rmse: f64,
    /// Median and 95th percentile of |map range - scene range| over rays that hit both.
    pub range_median_abs: f64,
    pub range_p95_abs: f64,
}

/// Seeded random queries over the map's box (10% margin): points for nearest/occupancy, rays
/// from those points in random directions.
pub fn random_queries(map: &HostMap, count: usize, seed: u64) -> Vec<([f64; 3], [f64; 3])> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for e in &map.entities {
        let c = e.entity.center.to_f64();
        for j in 0..3 {
            lo[j] = lo[j].min(c[j]);
            hi[j] = hi[j].max(c[j]);
        }
    }
    let mut s = seed | 1;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..count)
        .map(|_| {
            let p = [0, 1, 2].map(|j| {
                let margin = 0.1 * (hi[j] - lo[j]);
                lo[j] - margin + next() * (hi[j] - lo[j] + 2.0 * margin)
            });
            let d = [next() - 0.5, next() - 0.5, next() - 0.5];
            (p, d)
        })
        .collect()
}

pub fn run_bench(
    map: &HostMap,
    queries: usize,
    ray_check: Option<&crate::io::scene::Scene>,
) -> Result<QueryBench> {
    let index = build_index(map)?;
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    let qs = random_queries(map, queries, 0x5EED);
    let max_range = 1e9;
    let start = Instant::now();
    let indexed: Vec<_> = qs
        .iter()
        .map(|(p, d)| {
            (
                index.nearest(*p),
                index.occupied(*p),
                index.ray_cast(*p, *d, max_range),
            )
        })
        .collect();
    let index_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let brute: Vec<_> = qs
        .iter()
        .map(|(p, d)| {
            (
                brute_force::nearest(&entities, *p),
                brute_force::occupied(&entities, *p),
                brute_force::ray_cast(&entities, *p, *d, max_range),
            )
        })
        .collect();
    let brute_s = start.elapsed().as_secs_f64();
    let disagreements = indexed
        .iter()
        .zip(brute.iter())
        .filter(|(a, b)| a != b)
        .count();

    let (mut rays, mut both, mut scene_only, mut map_only, mut sum2) = (0, 0, 0, 0, 0.0);
    let mut abs_errors = Vec::new();
    if let Some(scene) = ray_check {
        let config = crate::io::scene::ScanConfig::default();
        let sensor = local(map, config.sensor);
        for d in config.ray_directions() {
            rays += 1;
            let truth = scene.ray_cast(config.sensor, d, config.max_range);
            let mapped = index.ray_cast(sensor, d, config.max_range);
            match (truth, mapped) {
                (Some(t), Some(m)) => {
                    both += 1;
                    sum2 += (m.t - t.range) * (m.t - t.range);
                    abs_errors.push((m.t - t.range).abs());
                }
                (Some(_), None) => scene_only += 1,
                (None, Some(_)) => map_only += 1,
                (None, None) => {}
            }
        }
    }
    let per_s = |secs: f64| queries as f64 * 3.0 / secs;
    Ok(QueryBench {
        entities: map.entities.len(),
        queries: queries * 3,
        disagreements,
        index_queries_per_s: per_s(index_s),
        brute_force_queries_per_s: per_s(brute_s),
        speedup: brute_s / index_s,
        rays,
        rays_hit_both: both,
        rays_scene_only: scene_only,
        rays_map_only: map_only,
        range_rmse: if both > 0 {
            (sum2 / both as f64).sqrt()
        } else {
            0.0
        },
        range_median_abs: quantile(&mut abs_errors, 0.5),
        range_p95_abs: quantile(&mut abs_errors, 0.95),
    })
}

fn quantile(values: &mut [f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * q).round() as usize]
}

pub fn query_bench(args: &QueryBenchArgs) -> Result<()> {
    let (map, scene) = match &args.map {
        Some(path) => (HostMap::read(path)?, None),
        None => {
            // The demo: the built-in scene's scan, mapped, then its own rays cast at the map.
            let scene = crate::io::scene::Scene::demo();
            let scan = crate::io::scene::scan(&scene, &crate::io::scene::ScanConfig::default());
            let cloud = crate::commands::LocalCloud::from_world(&scan.points);
            let config = crate::cli::default_fit_args().config(args.k)?;
            let clusters =
                crate::mapping::pipeline::cluster(&cloud.points, args.k, &config.kmeans)?;
            let fitted =
                crate::mapping::pipeline::fit_all(&clusters.moments, config.seed, &config.fit);
            (
                crate::mapping::pipeline::to_map(
                    cloud.origin,
                    &fitted.ellipsoids,
                    config.fit.degeneration.sphere_tolerance,
                ),
                Some(scene),
            )
        }
    };
    let r = run_bench(&map, args.queries, scene.as_ref())?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!(
            "{} entities, {} queries (nearest, occupancy, ray): {} disagreements with the brute-force scan\n  index {:.0} queries/s, brute force {:.0} queries/s: {:.1}x",
            r.entities,
            r.queries,
            r.disagreements,
            r.index_queries_per_s,
            r.brute_force_queries_per_s,
            r.speedup
        );
        if r.rays > 0 {
            println!(
                "  demo scan re-cast at its own map: {} rays, {} hit both, {} only the scene, {} only the map\n  range error over rays hitting both: RMSE {:.4} m, median {:.4} m, 95th percentile {:.4} m",
                r.rays,
                r.rays_hit_both,
                r.rays_scene_only,
                r.rays_map_only,
                r.range_rmse,
                r.range_median_abs,
                r.range_p95_abs
            );
        }
    }
    Ok(())
}
