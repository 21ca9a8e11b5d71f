//! Tests of `draw`: row spans against whole boxes, frames fitted to entities, scale-bar labels.

use super::*;
use crate::mapping::pipeline::{KMeansEngine, run_kmeans};
use mema_core::{MapEntity, kmeans::KMeansParams, shell::ShellParams};

/// A shells map of car6 (turned ellipsoids), with every third entity made a tube and every
/// fifth a plane pair by dropping axes, so every kind and turn is drawn.
fn scene() -> (crate::io::LocalCloud, HostMap) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/car6.pcd");
    let cloud = crate::io::load_cloud(path.as_ref()).expect("car6");
    let params = KMeansParams::default();
    let run = run_kmeans(&cloud.points, 120, &params, KMeansEngine::Accelerated).unwrap();
    let shells = crate::mapping::shells::shell_map(
        cloud.origin,
        &cloud.points,
        &run.labels,
        &run.centres,
        &ShellParams::default(),
    );
    let entities = shells
        .entities
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let mut entity = e.entity;
            if i % 5 == 0 {
                entity.weights[(i + 1) % 3] = 0.0;
                entity.weights[(i + 2) % 3] = 0.0;
            } else if i % 3 == 0 {
                entity.weights[i % 2] = 0.0;
            }
            MapEntity {
                entity,
                kind: entity.kind(0.01),
            }
        })
        .collect();
    (cloud.clone(), HostMap::new(cloud.origin, entities))
}

/// Row spans paint exactly the pixels the whole projected box paints, in every view and
/// style: they only skip pixels no ray can hit.
#[test]
fn row_spans_paint_what_the_whole_box_paints() {
    let (cloud, map) = scene();
    let clips = crate::render::picture::cluster_boxes(&cloud, &map);
    let points: Vec<[f64; 3]> = cloud.points.iter().map(|p| p.to_f64()).collect();
    let plot = [8, 8, 624, 464];
    let mut covered = 0;
    for (view, up) in [
        (View::Iso, None),
        (View::Top, None),
        (View::Front, Some(Up::Y)),
        (View::Sensor, None),
    ] {
        let camera = view.camera_with(up).unwrap();
        let frame = Frame::fit(cloud.origin, camera, &points, plot);
        for style in [Style::Shaded, Style::Outline] {
            let paint = |cull| {
                let mut r = Raster::new(640, 480);
                let cost = paint_entities(&mut r, &frame, &map, &clips, plot, style, cull, &|| {});
                (r.pixels, cost)
            };
            let ((rows, spans), (boxed, boxes)) = (paint(Cull::Rows), paint(Cull::Box));
            let differ = rows.iter().zip(&boxed).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{view:?} {style:?}");
            assert_eq!(spans.hits, boxes.hits, "{view:?} {style:?}");
            assert!(
                spans.rays < boxes.rays,
                "{view:?} {style:?}: {spans:?} {boxes:?}"
            );
            covered += rows.iter().filter(|p| **p != BACKGROUND).count();
        }
    }
    assert!(covered > 100_000, "{covered}");
}

/// Every entity's silhouette lies in its extent: no pixel it paints falls outside the
/// frame fitted to the entities alone.
#[test]
fn a_frame_fitted_to_the_entities_holds_every_silhouette() {
    let (cloud, map) = scene();
    let clips = crate::render::picture::cluster_boxes(&cloud, &map);
    let plot = [20, 20, 600, 440];
    for view in [View::Iso, View::Side, View::Sensor] {
        let camera = view.camera();
        let probe = Frame::fit(cloud.origin, camera, &[], plot);
        let extent = entities_extent(&probe, &map, &clips);
        let frame = Frame::fit_extent(cloud.origin, camera, &extent, plot);
        // Drawn on a picture with room around the plot, nothing lands outside the plot.
        let whole = [0, 0, 640, 480];
        let mut r = Raster::new(640, 480);
        draw_entities(&mut r, &frame, &map, &clips, whole, Style::Shaded);
        let (mut inside, mut outside) = (0, 0);
        for (i, p) in r.pixels.iter().enumerate() {
            let (x, y) = ((i % 640) as u32, (i / 640) as u32);
            if *p == BACKGROUND {
                continue;
            }
            let within = (20..620).contains(&x) && (20..460).contains(&y);
            if within { inside += 1 } else { outside += 1 }
        }
        assert_eq!(
            outside, 0,
            "{view:?}: {outside} of {inside} pixels off the plot"
        );
        assert!(inside > 10_000, "{view:?}");
    }
}

#[test]
fn scale_bar_labels_carry_their_unit() {
    let cases = [
        (0.1, "10 cm"),
        (1.0, "1 m"),
        (0.05, "5 cm"),
        (0.002, "2 mm"),
        (2e-6, "2 um"),
        (20.0, "20 m"),
        (500.0, "500 m"),
        (5_000.0, "5 km"),
    ];
    for (metres, want) in cases {
        assert_eq!(length_label(metres), want);
    }
    // Every round length the bar can take reads back as itself.
    for e in -7..6 {
        for m in [1.0, 2.0, 5.0] {
            let l = nice_length(m * 10f64.powi(e) * 1.000_001);
            let label = length_label(l);
            let (value, unit) = label.split_once(' ').unwrap();
            let size = match unit {
                "km" => 1e3,
                "m" => 1.0,
                "cm" => 1e-2,
                "mm" => 1e-3,
                _ => 1e-6,
            };
            let back: f64 = value.parse::<f64>().unwrap() * size;
            assert!((back / l - 1.0).abs() < 1e-9, "{l} as {label}");
        }
    }
}
