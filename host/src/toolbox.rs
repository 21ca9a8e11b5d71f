//! The toolbox commands: `draw`, `export`, `completions` and `man`.

use anyhow::{Context, Result};
use clap::{Args, CommandFactory};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::cli::{Cli, UsageError};
use crate::commands::{KindCounts, LocalCloud, evaluate, load_cloud};
use crate::io::mapfile::HostMap;
use crate::progress::stage;
use crate::render::draw::{self, Frame, LegendEntry, Raster, Style, View};
use crate::render::export::{Bounds, ExportReport, Tessellation};

/// `--size WxH` in pixels.
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

#[derive(Args, Debug)]
pub struct DrawArgs {
    /// The cloud the map was made from (any readable format).
    pub input: PathBuf,
    pub map: PathBuf,
    /// The picture to write (.png).
    #[arg(short, long)]
    pub output: PathBuf,
    #[arg(long, value_enum, default_value_t = View::Iso)]
    pub view: View,
    /// Picture size in pixels; with --compare, the two panels share it side by side.
    #[arg(long, default_value = "1200x900")]
    pub size: Size,
    #[arg(long, value_enum, default_value_t = Style::Shaded)]
    pub style: Style,
    /// A second map drawn beside the first on the same scale (the paper's Figure 12:
    /// `mema map --entity sphere` writes the spherical one).
    #[arg(long, value_name = "MAP")]
    pub compare: Option<PathBuf>,
    /// Print the picture's geometry (frames, legends) as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct ExportArgs {
    pub map: PathBuf,
    /// The mesh to write: .ply, .obj or .glb.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Clip degenerated entities to this cloud's bounding box (default: the map's own extent).
    #[arg(long, value_name = "CLOUD")]
    pub cloud: Option<PathBuf>,
    /// Vertices around each ellipsoid and tube.
    #[arg(long, default_value_t = 24)]
    pub segments: u32,
    /// Latitude bands of each ellipsoid.
    #[arg(long, default_value_t = 12)]
    pub rings: u32,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct CompletionsArgs {
    pub shell: clap_complete::Shell,
}

/// Fails before any work if `path` lacks the extension or its directory cannot take it.
fn check_output(path: &Path, ext: &[&str], what: &str) -> Result<()> {
    let got = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !got.as_deref().is_some_and(|g| ext.contains(&g)) {
        return Err(UsageError(format!(
            "{}: a {what} needs the extension .{}",
            path.display(),
            ext.join(", .")
        ))
        .into());
    }
    crate::commands::check_output_file(path, what)
}

fn read_map(path: &Path) -> Result<HostMap> {
    let map = HostMap::read(path)?;
    if map.entities.is_empty() {
        anyhow::bail!("{}: the map has no entities", path.display());
    }
    Ok(map)
}

/// One panel of `mema draw --json`.
#[derive(Serialize)]
pub struct Panel {
    pub map: String,
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
}

#[derive(Serialize)]
pub struct ScaleBar {
    /// In the cloud's units.
    pub length: f64,
    pub pixels: i64,
}

/// `mema draw --json`.
#[derive(Serialize)]
pub struct DrawReport {
    pub output: String,
    pub width: u32,
    pub height: u32,
    pub view: View,
    pub style: Style,
    pub points: usize,
    pub point_size: i64,
    pub point_colour: [u8; 3],
    pub panels: Vec<Panel>,
}

/// Renders the picture; the caller writes it.
pub fn render(
    cloud: &LocalCloud,
    maps: &[(String, HostMap)],
    view: View,
    size: Size,
    style: Style,
) -> Result<(Raster, DrawReport)> {
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
        return Err(UsageError(format!(
            "--size {}x{} leaves a {plot_w}x{plot_h} plot; consider 1200x900",
            size.width, size.height
        ))
        .into());
    }
    let points: Vec<[f64; 3]> = cloud.points.iter().map(|p| p.to_f64()).collect();
    let point_size = if points.len() as u64 * 64 < u64::from(plot_w) * u64::from(plot_h) {
        2
    } else {
        1
    };
    let mut raster = Raster::new(size.width, size.height);
    let mut panels = Vec::new();
    for (i, (name, map)) in maps.iter().enumerate() {
        let x0 = i as u32 * panel_w;
        let plot = [x0 + 8, top, plot_w, plot_h];
        let frame = Frame::fit(cloud.origin, view.camera(), &points, plot);
        let scene = draw::PanelScene {
            frame,
            clips: cluster_boxes(cloud, map),
            plot,
            style,
            points: &points,
            point_size,
        };
        draw::draw_panel(&mut raster, &scene, map);
        let errors = evaluate(cloud, map).errors;
        let title = format!(
            "{name}: {} entities, mean e {:.4}",
            map.entities.len(),
            errors.mean
        );
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
        let (length, pixels) = draw::draw_scale_bar(
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
            entities: map.entities.len(),
            kinds: KindCounts::of(map),
            mean_error: errors.mean,
            total_error: errors.total,
            rect: [x0, 0, panel_w, size.height],
            plot,
            frame,
            legend,
            scale_bar: ScaleBar { length, pixels },
        });
    }
    let report = DrawReport {
        output: String::new(),
        width: size.width,
        height: size.height,
        view,
        style,
        points: points.len(),
        point_size,
        point_colour: draw::POINT_COLOUR,
        panels,
    };
    Ok((raster, report))
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
    let labels = crate::mapping::pipeline::nearest_centre_labels(&in_map, &centres);
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

pub fn draw(args: &DrawArgs) -> Result<()> {
    check_output(&args.output, &["png"], "picture")?;
    let cloud = stage("reading", || load_cloud(&args.input))?;
    let mut maps = vec![(file_name(&args.map), read_map(&args.map)?)];
    if let Some(other) = &args.compare {
        maps.push((file_name(other), read_map(other)?));
    }
    let (raster, mut report) = stage("rendering", || {
        render(&cloud, &maps, args.view, args.size, args.style)
    })?;
    let png = raster.encode_png().context("PNG encoding")?;
    crate::io::mapfile::write_file_atomically(&args.output, &png, "picture")
        .with_context(|| format!("{}", args.output.display()))?;
    report.output = args.output.display().to_string();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        for p in &report.panels {
            println!(
                "{}: {} entities, mean eq. 13 error {:.6}",
                p.map, p.entities, p.mean_error
            );
        }
        println!(
            "wrote {} ({}x{}, {} view)",
            report.output,
            report.width,
            report.height,
            args.view.name()
        );
    }
    Ok(())
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

impl View {
    fn name(self) -> &'static str {
        match self {
            View::Iso => "iso",
            View::Top => "top",
            View::Front => "front",
            View::Side => "side",
        }
    }
}

pub fn export(args: &ExportArgs) -> Result<()> {
    let t = Tessellation::checked(args.segments, args.rings)?;
    crate::render::export::MeshFormat::from_path(&args.output)?;
    check_output(&args.output, &["ply", "obj", "glb"], "mesh")?;
    let map = read_map(&args.map)?;
    let (bounds, source) = match &args.cloud {
        Some(path) => {
            let cloud = stage("reading", || load_cloud(path))?;
            (Bounds::of_points(cloud.origin, &cloud.points), "cloud")
        }
        None => (Bounds::of_map(&map), "map"),
    };
    let report: ExportReport =
        crate::render::export::export(&map, bounds, source, &t, &args.output)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "wrote {}: {} entities as {} vertices and {} triangles (degenerated ones clipped to the {}'s box)",
            report.output, report.entities, report.vertices, report.triangles, report.bounds_source
        );
    }
    Ok(())
}

pub fn completions(args: &CompletionsArgs) -> Result<()> {
    let mut out = Vec::new();
    clap_complete::generate(args.shell, &mut Cli::command(), "mema", &mut out);
    print_bytes(&out)
}

pub fn man() -> Result<()> {
    let mut out = Vec::new();
    clap_mangen::Man::new(Cli::command()).render(&mut out)?;
    print_bytes(&out)
}

/// A closed pipe (`mema man | head`) is not an error worth a message.
fn print_bytes(bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    match std::io::stdout().write_all(bytes) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other.context("stdout"),
    }
}
