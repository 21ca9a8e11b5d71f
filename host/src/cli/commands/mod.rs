//! One handler per subcommand: check the arguments, call the library, print.
pub mod bench;
pub mod eval;
pub mod info;
pub mod map;
pub mod query;
pub mod serial;
pub mod toolbox;

use anyhow::Result;
use mema::io::cloud::{LocalCloud, load_cloud};
use mema::io::{FileUnit, Units};
use mema::progress::stage;
use std::path::Path;

use crate::cli::args::UnitsArg;

/// Reads a cloud for mapping or comparing with a map: in metres, scaled by `--units` or the
/// unit its file gives (see `mema::io::units`). Says on stderr when `--units` overrides a
/// different unit the file gives.
pub fn read_in_metres(path: &Path, units: &UnitsArg) -> Result<(LocalCloud, Units)> {
    let cloud = stage("reading", || load_cloud(path))?;
    if let (Some(given), Some(file)) = (&units.units, &cloud.unit) {
        let same = matches!(file, FileUnit::Length { unit, .. } if unit.metres == given.metres);
        if !same {
            eprintln!(
                "mema: {}: --units {} overrides the file's {file}",
                path.display(),
                given.name
            );
        }
    }
    Ok(cloud.to_metres(&path.display().to_string(), units.units.as_ref())?)
}
