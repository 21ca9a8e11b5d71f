//! The toolbox commands: `draw`, `export`, `completions` and `man`.

use anyhow::{Context, Result};
use clap::CommandFactory;
use mema::io::mapfile::{HostMap, write_file_atomically};
use mema::io::output::check_output_file;
use mema::progress::stage;
use mema::render::crop::Ball;
use mema::render::export::{
    self as mesh, Bounds, ExportReport, MeshFormat, MeshSize, Tessellation,
};
use mema::render::picture::{TitleError, render};
use std::path::{Path, PathBuf};

use super::read_in_metres;
use crate::cli::args::{Cli, CompletionsArgs, DrawArgs, ExportArgs, ManArgs};
use crate::cli::errors::UsageError;

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
    check_output_file(path, what)
}

fn read_map(path: &Path) -> Result<HostMap> {
    let map = HostMap::read(path)?;
    if map.entities.is_empty() {
        anyhow::bail!("{}: the map has no entities", path.display());
    }
    Ok(map)
}

pub fn draw(args: &DrawArgs) -> Result<()> {
    check_output(&args.output, &["png"], "picture")?;
    let ball = match (&args.around, args.radius) {
        (Some(around), Some(radius)) => {
            let centre = super::query::parse_numbers::<3>(around, "--around")?;
            Some(Ball::new(centre, radius).map_err(|e| UsageError(e.to_string()))?)
        }
        _ => None,
    };
    let (cloud, _) = read_in_metres(&args.input, &args.units)?;
    let mut maps = vec![(file_name(&args.map), read_map(&args.map)?)];
    if let Some(other) = &args.compare {
        maps.push((file_name(other), read_map(other)?));
    }
    let cloud = match ball {
        Some(ball) => {
            for (name, map) in &mut maps {
                *map = ball.map(map);
                if map.entities.is_empty() {
                    anyhow::bail!(
                        "{name}: no entity is centred within {} m of --around",
                        ball.radius
                    );
                }
            }
            ball.cloud(&cloud)
                .with_context(|| args.input.display().to_string())?
        }
        None => cloud,
    };
    // The renderer shows its own progress, counted over the entities.
    let (raster, mut report) = render(
        &cloud,
        &maps,
        args.view.into(),
        args.up.map(Into::into),
        args.size,
        args.style.into(),
        TitleError::NearestCentre,
    )?;
    let png = raster.encode_png().context("PNG encoding")?;
    write_file_atomically(&args.output, &png, "picture")
        .with_context(|| format!("{}", args.output.display()))?;
    report.output = args.output.display().to_string();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        for p in &report.panels {
            println!(
                "{}: {} entities, eq. 13 by nearest centre {:.6} (as mema eval)",
                p.map, p.entities, p.mean_error
            );
        }
        if report.points_outside > 0 {
            println!(
                "frame: where the points are dense; {} of {} points lie outside it (--around X,Y,Z --radius R frames any part)",
                report.points_outside, report.points
            );
        }
        let up = report.up.map_or(String::new(), |u| {
            format!(", {} up", ["x", "y", "z"][u.axis()])
        });
        println!(
            "wrote {} ({}x{}, {} view{up})",
            report.output,
            report.width,
            report.height,
            report.view.name()
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

pub fn export(args: &ExportArgs) -> Result<()> {
    let t = Tessellation::checked(args.segments, args.rings)?;
    MeshFormat::from_path(&args.output)?;
    check_output(&args.output, &["ply", "obj", "glb"], "mesh")?;
    let map = read_map(&args.map)?;
    // Counted and checked against --max-bytes before the cloud is read or any vertex made.
    let format = MeshFormat::from_path(&args.output)?;
    MeshSize::of(&map, &t, format)
        .check(&map, &t, args.max_bytes)
        .with_context(|| args.map.display().to_string())?;
    let (bounds, source) = match &args.cloud {
        Some(path) => {
            let (cloud, _) = read_in_metres(path, &args.units)?;
            (Bounds::of_points(cloud.origin, &cloud.points), "cloud")
        }
        None => (Bounds::of_map(&map), "map"),
    };
    let report: ExportReport = stage("writing the mesh", || {
        mesh::export(&map, bounds, source, &t, &args.output, args.max_bytes)
    })?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "wrote {}: {} entities as {} vertices and {} triangles, {} bytes (degenerated ones clipped to the {}'s box)",
            report.output,
            report.entities,
            report.vertices,
            report.triangles,
            report.bytes,
            report.bounds_source
        );
    }
    Ok(())
}

pub fn completions(args: &CompletionsArgs) -> Result<()> {
    let mut out = Vec::new();
    clap_complete::generate(args.shell, &mut Cli::command(), "mema", &mut out);
    print_bytes(&out)
}

pub fn man(args: &ManArgs) -> Result<()> {
    let Some(dir) = &args.out_dir else {
        let mut out = Vec::new();
        clap_mangen::Man::new(Cli::command()).render(&mut out)?;
        return print_bytes(&out);
    };
    if !dir.is_dir() {
        return Err(UsageError(format!(
            "--out-dir {}: not an existing directory",
            dir.display()
        ))
        .into());
    }
    // Built, so each subcommand's page is named after its path (mema-map.1); the `help`
    // subcommand is no command of mema's and gets no page.
    let mut root = Cli::command().disable_help_subcommand(true);
    root.build();
    let mut written = Vec::new();
    write_pages(&root, dir, &mut written)?;
    for path in &written {
        println!("{}", path.display());
    }
    eprintln!(
        "mema: wrote {} man pages to {}; read one with `man {}`",
        written.len(),
        dir.display(),
        dir.join("mema-map.1").display()
    );
    Ok(())
}

/// Writes `command`'s page and its subcommands' pages into `dir`, each atomically.
fn write_pages(command: &clap::Command, dir: &Path, written: &mut Vec<PathBuf>) -> Result<()> {
    let page = clap_mangen::Man::new(command.clone());
    let path = dir.join(page.get_filename());
    let mut roff = Vec::new();
    page.render(&mut roff)?;
    write_file_atomically(&path, &roff, "man page")?;
    written.push(path);
    for sub in command.get_subcommands().filter(|s| !s.is_hide_set()) {
        write_pages(sub, dir, written)?;
    }
    Ok(())
}

/// A closed pipe (`mema man | head`) ends the process as it ends Unix tools.
fn print_bytes(bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    match std::io::stdout().write_all(bytes) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            crate::cli::errors::end_on_closed_stdout()
        }
        other => other.context("stdout"),
    }
}
