//! One handler per subcommand: check the arguments, call the library, print.
pub mod bench;
pub mod demo;
mod demo_files;
pub mod demo_moving;
pub mod eval;
pub mod info;
pub mod map;
pub mod query;
pub mod serial;
pub mod toolbox;

use anyhow::Result;
use mema::io::Units;
use mema::io::cloud::{LocalCloud, load_cloud_in_metres};
use mema::progress::stage;
use std::path::Path;

use crate::cli::args::UnitsArg;

/// Reads a cloud for mapping or comparing with a map: in metres, scaled by `--units` or the
/// unit its file gives (see `mema::io::units`). Says on stderr when `--units` overrides a
/// different unit the file gives.
pub fn read_in_metres(path: &Path, units: &UnitsArg) -> Result<(LocalCloud, Units)> {
    let (cloud, units) = stage("reading", || {
        load_cloud_in_metres(path, units.units.as_ref())
    })?;
    if let Some(file) = &units.overrides {
        eprintln!(
            "mema: {}: --units {} overrides the file's {file}",
            mema::io::read::input_name(path),
            units.unit.name
        );
    }
    Ok((cloud, units))
}
