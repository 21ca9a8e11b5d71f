//! `mema query`, `mema transform` and `mema query-bench`: the map as a robot uses it.

use anyhow::{Context, Result, bail};
use mema::bench::query::run_bench;
use mema::io::cloud::LocalCloud;
use mema::io::cloud::load_cloud;
use mema::io::mapfile::HostMap;
use mema::io::output::check_map_output;
use mema::io::scene::{ScanConfig, Scene, scan};
use mema::mapping::{FitOptions, pipeline};
use mema::query::states::{State, StateAnswer, state_of};
use mema::query::{HostIndex, build_index, local, rotation_degrees, transform_map, world};
use mema_core::query::{Nearest, RayHit};
use mema_core::transform::RigidTransform;
use rayon::prelude::*;
use serde::Serialize;
use std::io::Write;
use std::path::Path;

use crate::cli::args::{QueryArgs, QueryBenchArgs, TransformArgs};
use crate::cli::errors::UsageError;

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

#[derive(Serialize)]
struct PointAnswer {
    point: [f64; 3],
    state: State,
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
    if args.point.is_none() && args.ray.is_none() && args.points.is_none() {
        return Err(UsageError(
            "nothing to ask: give --point x,y,z, --points FILE or --ray ox,oy,oz,dx,dy,dz".into(),
        )
        .into());
    }
    if !(args.tolerance.is_finite() && args.tolerance >= 0.0) {
        return Err(UsageError(format!(
            "--tolerance {} must be a length of 0 metres or more",
            args.tolerance
        ))
        .into());
    }
    let map = HostMap::read(&args.map)?;
    let index = build_index(&map).with_context(|| args.map.display().to_string())?;
    if let Some(path) = &args.points {
        points(args, &map, &index, path)?;
    }
    let kind = |i: usize| map.entities.get(i).map(|e| e.kind.name());
    if let Some(text) = &args.point {
        let p = parse_numbers::<3>(text, "--point")?;
        let q = local(&map, p);
        let nearest = index.nearest(q);
        let answer = PointAnswer {
            point: p,
            state: state_of(&map, &index, p, args.tolerance).state,
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
                    "point {:?}: {}, {} the map; nearest surface {:.6} m away, entity {entity} ({})",
                    p,
                    state_name(answer.state),
                    if signed_distance < 0.0 {
                        "inside"
                    } else {
                        "outside"
                    },
                    signed_distance.abs(),
                    kind(entity).unwrap_or("?")
                ),
                None => println!(
                    "point {p:?}: {}, the map is empty",
                    state_name(answer.state)
                ),
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
                    "ray from {o:?}: hits entity {entity} ({}) at range {t:.6} m, point {:?}",
                    kind(entity).unwrap_or("?"),
                    world(&map, point)
                ),
                None => println!("ray from {o:?}: no hit within {} m", args.max_range),
            }
        }
    }
    Ok(())
}

fn state_name(state: State) -> &'static str {
    match state {
        State::Free => "free",
        State::Occupied => "occupied",
        State::Unknown => "unknown",
    }
}

/// `--points FILE`: every point's state and signed distance, one line each (CSV, or JSON
/// lines), and a count of each state on stderr.
fn points(args: &QueryArgs, map: &HostMap, index: &HostIndex, path: &Path) -> Result<()> {
    let cloud = load_cloud(path).with_context(|| path.display().to_string())?;
    let world: Vec<[f64; 3]> = cloud
        .points
        .iter()
        .map(|p| {
            let p = p.to_f64();
            [0, 1, 2].map(|j| cloud.origin[j] + p[j])
        })
        .collect();
    let answers: Vec<StateAnswer> = world
        .par_iter()
        .map(|p| state_of(map, index, *p, args.tolerance))
        .collect();
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    if !args.json {
        writeln!(out, "x,y,z,state,signed_distance,entity")?;
    }
    let mut counts = [0usize; 3];
    for (p, a) in world.iter().zip(&answers) {
        counts[a.state as usize] += 1;
        if args.json {
            #[derive(Serialize)]
            struct Line<'a> {
                point: [f64; 3],
                #[serde(flatten)]
                answer: &'a StateAnswer,
            }
            serde_json::to_writer(
                &mut out,
                &Line {
                    point: *p,
                    answer: a,
                },
            )?;
            writeln!(out)?;
        } else {
            let entity = a.entity.map(|e| e.to_string()).unwrap_or_default();
            writeln!(
                out,
                "{},{},{},{},{},{entity}",
                p[0],
                p[1],
                p[2],
                state_name(a.state),
                a.signed_distance
            )?;
        }
    }
    out.flush()?;
    eprintln!(
        "mema: {} points: {} free, {} occupied, {} unknown{}",
        answers.len(),
        counts[State::Free as usize],
        counts[State::Occupied as usize],
        counts[State::Unknown as usize],
        if map.free_space.is_empty() {
            " (the map records no free space: map with --free-space to tell free from unknown)"
        } else {
            ""
        }
    );
    Ok(())
}

pub fn transform(args: &TransformArgs) -> Result<()> {
    check_map_output(&args.output)?;
    let map = HostMap::read(&args.map)?;
    let mut t = RigidTransform::IDENTITY;
    if let Some(text) = &args.rotate {
        t = rotation_degrees(parse_numbers::<3>(text, "--rotate")?);
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

pub fn query_bench(args: &QueryBenchArgs) -> Result<()> {
    let (map, scene) = match &args.map {
        Some(path) => (HostMap::read(path)?, None),
        None => {
            // The demo: the built-in scene's scan, mapped, then its own rays cast at the map.
            let scene = Scene::demo();
            let scan = scan(&scene, &ScanConfig::default());
            let cloud = LocalCloud::from_world(&scan.points);
            let config = FitOptions::default().config(args.k)?;
            let clusters = pipeline::cluster(&cloud.points, args.k, &config.kmeans)?;
            let fitted = pipeline::fit_all(&clusters.moments, config.seed, &config.fit);
            (
                pipeline::to_map(
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
        if r.recast.rays > 0 {
            println!("{}", r.recast.lines("demo scan re-cast at its own map"));
        }
    }
    Ok(())
}
