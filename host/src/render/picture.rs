//! `mema draw`'s picture: one panel per map, side by side on the same scale, with its title,
//! legend and scale bar, and the geometry of each panel for `--json`.

use serde::Serialize;
use std::str::FromStr;

use super::camera::dot;
use super::draw::{self, Extent, Frame, LegendEntry, Raster, ScaleBar, Style, Up, View};
use super::export::Bounds;
use crate::analysis::eval::evaluate;
use crate::error::ConfigError;
use crate::io::cloud::LocalCloud;
use crate::io::mapfile::{HostMap, KindCounts};
use crate::mapping::pipeline;

/// A picture's size in pixels; parsed from `WIDTHxHEIGHT`, within 160x120 ..= 8192x8192.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Size {
    pub width: u32,
    pub height: u32,
}

impl FromStr for Size {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let parsed = s
            .split_once(['x', 'X'])
            .and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)));
        match parsed {
            Some((width, height))
                if (160..=8192).contains(&width) && (120..=8192).contains(&height) =>
            {
                Ok(Size { width, height })
            }
            Some(_) => Err(format!("'{s}' is outside 160x120 ..= 8192x8192 pixels")),
            None => Err(format!("'{s}' is not WIDTHxHEIGHT; consider 1200x900")),
        }
    }
}

/// Which mean eq. 13 error a panel's title shows.
#[derive(Clone, Copy, Debug)]
pub enum TitleError<'a> {
    /// Each point joining its nearest centre, as `mema eval` and `mema draw` report it.
    NearestCentre,
    /// Each map's own, as its caller measured and printed it (the demo: its clusters', the
    /// mean of the paper's Table 4), one per map.
    TableFour(&'a [f64]),
}

/// One panel of `mema draw --json`.
#[derive(Serialize)]
pub struct Panel {
    pub map: String,
    /// The title written over the panel.
    pub title: String,
    pub entities: usize,
    pub kinds: KindCounts,
    /// Eq. 13 over the cloud, as `mema eval` reports it.
    pub mean_error: f64,
    pub total_error: f64,
    /// [x, y, w, h] of the panel and of its plot area, in pixels.
    pub rect: [u32; 4],
    pub plot: [u32; 4],
    pub frame: Frame,
    pub legend: Vec<LegendEntry>,
    pub scale_bar: ScaleBar,
    /// The work of drawing the entities (see [`draw::DrawCost`]).
    pub cost: draw::DrawCost,
}

/// `mema draw --json`.
#[derive(Serialize)]
pub struct DrawReport {
    pub output: String,
    pub width: u32,
    pub height: u32,
    pub view: View,
    /// The world axis up in the picture, as asked (`None`: the view's own, z or the sensor's
    /// -y).
    pub up: Option<Up>,
    pub style: Style,
    pub points: usize,
    /// Points outside the frame, which holds where the points are dense (0 for a compact
    /// cloud: see [`super::camera::Extent::of_dense_points`]).
    pub points_outside: usize,
    pub point_size: i64,
    pub point_colour: [u8; 3],
    pub panels: Vec<Panel>,
}

/// Renders the picture of `cloud` and one panel per named map; the caller writes it
/// ([`Raster::encode_png`]). Every panel has the same frame, fitted to the points and to every
/// map's entities, so nothing is cut at the plot's edge. Fails if `size` leaves too small a
/// plot, or if `up` lies along the view. Shows its progress over the entities on stderr
/// ([`crate::progress`]).
///
/// ```
/// use mema::io::{HostMap, LocalCloud};
/// use mema::render::draw::{Style, View};
/// use mema::render::picture::{Size, TitleError, render};
/// use mema_core::{Entity, MapEntity, Point3};
///
/// let points = [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]];
/// let cloud = LocalCloud::from_world(&points);
/// let sphere = Entity::sphere(Point3::new(0.0, 0.0, 0.0), 1.0);
/// let entity = MapEntity { entity: sphere, kind: sphere.kind(0.01) };
/// let map = HostMap::new([0.0; 3], vec![entity]);
/// let size: Size = "400x300".parse().map_err(anyhow::Error::msg)?;
/// let maps = [("sphere".to_string(), map)];
/// let (raster, report) = render(&cloud, &maps, View::Iso, None, size, Style::Shaded, TitleError::NearestCentre)?;
/// assert_eq!(report.panels[0].entities, 1);
/// assert!(raster.encode_png()?.starts_with(b"\x89PNG"));
/// # Ok::<(), anyhow::Error>(())
/// ```
pub fn render(
    cloud: &LocalCloud,
    maps: &[(String, HostMap)],
    view: View,
    up: Option<Up>,
    size: Size,
    style: Style,
    title_error: TitleError,
) -> Result<(Raster, DrawReport), ConfigError> {
    let n = maps.len() as u32;
    let panel_w = size.width / n;
    let ts: i64 = if panel_w >= 900 { 2 } else { 1 };
    let kinds_shown = maps
        .iter()
        .map(|(_, m)| {
            mema_core::EntityKind::ALL
                .iter()
                .filter(|k| m.entities.iter().any(|e| e.kind == **k))
                .count()
        })
        .max()
        .unwrap_or(0) as u32;
    let top = (12 + 8 * ts) as u32;
    let bottom = (kinds_shown + 1) * (10 * ts as u32) + 12;
    let plot_h = size.height.saturating_sub(top + bottom + 4);
    let plot_w = panel_w.saturating_sub(16);
    if plot_w < 64 || plot_h < 48 {
        return Err(ConfigError::PictureTooSmall {
            width: size.width,
            height: size.height,
            plot_width: plot_w,
            plot_height: plot_h,
        });
    }
    let points: Vec<[f64; 3]> = cloud.points.iter().map(|p| p.to_f64()).collect();
    let point_size = if points.len() as u64 * 64 < u64::from(plot_w) * u64::from(plot_h) {
        2
    } else {
        1
    };
    let camera = view.camera_with(up)?;
    let clips: Vec<Vec<draw::Clip>> = maps.iter().map(|(_, m)| cluster_boxes(cloud, m)).collect();
    // Extents lie on the screen plane, whatever a frame's scale and offset, so a probe frame
    // measures them; every panel then fits the one extent into its own plot, at one scale.
    let plot_at = |i: u32| [i * panel_w + 8, top, plot_w, plot_h];
    // Framed where the points are dense: a few strays far out must not shrink the rest to a
    // blob (`Extent::of_dense_points`); what lies outside is counted in the report.
    let mut extent = Extent::of_dense_points(&camera, &points);
    let outside = points
        .iter()
        .filter(|p| !extent.holds(dot(**p, camera.right), dot(**p, camera.up)))
        .count();
    let probe = Frame::fit_extent(cloud.origin, camera, &extent, plot_at(0));
    let reach = entity_reach(&extent, &probe, plot_at(0));
    for ((_, map), clips) in maps.iter().zip(&clips) {
        extent.union(&reach.clamp(&draw::entities_extent(&probe, map, clips)));
    }
    let entities: usize = maps.iter().map(|(_, m)| m.entities.len()).sum();
    let progress = crate::progress::Stage::counted("drawing entities", entities as u64);
    let mut raster = Raster::new(size.width, size.height);
    let mut panels = Vec::new();
    for (i, ((name, map), clips)) in maps.iter().zip(clips).enumerate() {
        let x0 = i as u32 * panel_w;
        let plot = plot_at(i as u32);
        let frame = Frame::fit_extent(cloud.origin, camera, &extent, plot);
        let scene = draw::PanelScene {
            frame,
            clips,
            plot,
            style,
            points: &points,
            point_size,
        };
        let cost = draw::draw_panel(&mut raster, &scene, map, &|| progress.inc(1));
        let errors = evaluate(cloud, map).errors;
        let title = match title_error {
            TitleError::NearestCentre => format!(
                "{name}: {} entities, eq. 13 by nearest centre {:.6}",
                map.entities.len(),
                errors.mean
            ),
            TitleError::TableFour(means) => format!(
                "{name}: {} entities, eq. 13 as fitted {:.6}",
                map.entities.len(),
                means.get(i).copied().unwrap_or(f64::NAN)
            ),
        };
        raster.text(i64::from(x0) + 8, 6, ts, &title, draw::INK);
        let legend_y = i64::from(top + plot_h) + 8;
        let legend = draw::draw_legend(
            &mut raster,
            i64::from(x0) + 8,
            legend_y,
            ts,
            map,
            points.len(),
        );
        let right = i64::from(x0 + panel_w) - 12;
        let scale_bar = draw::draw_scale_bar(
            &mut raster,
            right,
            legend_y + 4 * ts,
            ts,
            &frame,
            f64::from(plot_w) / 4.0,
        );
        if i > 0 {
            raster.fill(
                [i64::from(x0), 0, 1, i64::from(size.height)],
                [200, 200, 200],
            );
        }
        panels.push(Panel {
            map: name.clone(),
            title,
            entities: map.entities.len(),
            kinds: KindCounts::of(map),
            mean_error: errors.mean,
            total_error: errors.total,
            rect: [x0, 0, panel_w, size.height],
            plot,
            frame,
            legend,
            scale_bar,
            cost,
        });
    }
    let report = DrawReport {
        output: String::new(),
        width: size.width,
        height: size.height,
        view,
        up,
        style,
        points: points.len(),
        points_outside: outside,
        point_size,
        point_colour: draw::POINT_COLOUR,
        panels,
    };
    Ok((raster, report))
}

/// How far entities may widen a picture fitted to the points: the plot's window at the
/// points' own scale, doubled about its centre, so the cloud is drawn at least half as large
/// as it alone would be. Shells reaching past their points at a cloud's edge fit well within;
/// a paper ellipsoid with a 4 m axis on a 15 cm bunny would otherwise shrink it to a dot.
fn entity_reach(points: &Extent, fitted: &Frame, plot: [u32; 4]) -> Extent {
    let centre = [points.s, points.t].map(|[lo, hi]| lo / 2.0 + hi / 2.0);
    let half = [plot[2], plot[3]].map(|n| f64::from(n) / fitted.scale);
    Extent {
        s: [centre[0] - half[0], centre[0] + half[0]],
        t: [centre[1] - half[1], centre[1] + half[1]],
    }
}

/// Per entity, the box of the points nearest its centre (as `mema eval` assigns them), in the
/// entity's axes (`R^T p`, p local to the cloud's origin; see [`draw::Clip`]): a degenerated
/// entity is drawn over its own cluster's extent along its infinite axes, not across the whole
/// cloud, whichever way it is turned. An entity no point is nearest to gets the cloud's box,
/// seen along its axes.
pub fn cluster_boxes(cloud: &LocalCloud, map: &HostMap) -> Vec<draw::Clip> {
    let shift = [0, 1, 2].map(|j| cloud.origin[j] - map.origin[j]);
    let in_map: Vec<mema_core::Point3> = cloud
        .points
        .iter()
        .map(|p| {
            let q = p.to_f64();
            let [x, y, z] = [0, 1, 2].map(|j| (q[j] + shift[j]) as f32);
            mema_core::Point3::new(x, y, z)
        })
        .collect();
    let centres: Vec<_> = map.entities.iter().map(|e| e.entity.center).collect();
    let labels = pipeline::nearest_centre_labels(&in_map, &centres);
    let all = Bounds::of_points([0.0; 3], &cloud.points);
    let mut boxes = vec![([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]); centres.len()];
    let grow = |b: &mut draw::Clip, q: [f64; 3]| {
        for (j, q) in q.into_iter().enumerate() {
            b.0[j] = b.0[j].min(q);
            b.1[j] = b.1[j].max(q);
        }
    };
    for (p, &l) in cloud.points.iter().zip(&labels) {
        if let (Some(b), Some(e)) = (boxes.get_mut(l as usize), map.entities.get(l as usize)) {
            grow(b, e.entity.rotation.inverse_rotate(p.to_f64()));
        }
    }
    let empty = |b: &draw::Clip| b.0[0] > b.1[0];
    boxes
        .into_iter()
        .zip(&map.entities)
        .map(|(b, e)| {
            if !empty(&b) {
                return b;
            }
            if e.entity.rotation.is_identity() || empty(&(all.min, all.max)) {
                return (all.min, all.max);
            }
            // The cloud's corners turned: their box holds every turned point.
            let mut turned = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for corner in 0..8 {
                let q = [0, 1, 2].map(|j| {
                    if corner >> j & 1 == 0 {
                        all.min[j]
                    } else {
                        all.max[j]
                    }
                });
                grow(&mut turned, e.entity.rotation.inverse_rotate(q));
            }
            turned
        })
        .collect()
}
