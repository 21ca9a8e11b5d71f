//! What both demos write and how they name it: the files in `--out-dir`, the picture's size,
//! paths as the shell words printed in their "Next:" lines.

use anyhow::{Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

use mema::io::cloud::LocalCloud;
use mema::io::mapfile::{HostMap, write_file_atomically};
use mema::progress::stage;
use mema::render::draw::{Style, View};
use mema::render::picture::{Size, TitleError, render};

/// The picture's size: large enough to read the legend, small enough to draw in a second.
const PICTURE: Size = Size {
    width: 1200,
    height: 900,
};

/// The files the demo writes, all in `--out-dir`.
#[derive(Serialize)]
pub struct DemoFiles {
    pub scan: PathBuf,
    pub map: PathBuf,
    pub picture: PathBuf,
}

impl DemoFiles {
    pub fn in_dir(dir: &Path) -> Self {
        Self {
            scan: dir.join("scan.ply"),
            map: dir.join("map.mema"),
            picture: dir.join("picture.png"),
        }
    }
}

/// `path` as a shell word: quoted only where it has to be.
pub fn shell_word(path: &Path) -> String {
    let text = path.display().to_string();
    let plain = text
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || "._/-+,:@".contains(c));
    if plain {
        text
    } else {
        format!("'{}'", text.replace('\'', r"'\''"))
    }
}

/// The picture both demos write: `map`'s entities shaded over `cloud`'s points, seen from the
/// iso view, as a PNG at `path` (written whole or not at all), titled with the error the demo
/// printed; the title.
pub fn write_picture(
    cloud: &LocalCloud,
    map: HostMap,
    path: &Path,
    title_error: TitleError,
) -> Result<String> {
    let (raster, report) = stage("drawing", || {
        render(
            cloud,
            &[("map.mema".to_owned(), map)],
            View::Iso,
            None,
            PICTURE,
            Style::Shaded,
            title_error,
        )
    })?;
    let png = raster.encode_png().context("PNG encoding")?;
    write_file_atomically(path, &png, "picture")?;
    Ok(report
        .panels
        .into_iter()
        .next()
        .map(|p| p.title)
        .unwrap_or_default())
}
