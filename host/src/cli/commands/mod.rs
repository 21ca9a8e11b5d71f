//! One handler per subcommand: check the arguments, call the library, print.
pub mod bench;
pub mod capture;
pub mod demo;
mod demo_files;
pub mod demo_moving;
pub mod device;
pub mod eval;
pub mod info;
pub mod map;
pub mod query;
pub mod serial;
pub mod toolbox;

use anyhow::Result;
use mema::io::Units;
use mema::io::cloud::{LocalCloud, load_input_keeping};
use mema::io::kind::InputKind;
use mema::io::read::{Outliers, Screening};
use mema::progress::stage;
use std::path::Path;

use crate::cli::args::{BagArg, UnitsArg};
use crate::cli::errors::UsageError;

/// Reads a cloud for mapping or comparing with a map: in metres, scaled by `--units` or the
/// unit its file gives (see `mema::io::units`). Says on stderr when `--units` overrides a
/// different unit the file gives.
pub fn read_in_metres(path: &Path, units: &UnitsArg) -> Result<(LocalCloud, Units)> {
    read_input(path, units, &BagArg::default(), Outliers::Unchecked)
}

/// `--topic` and `--frame` name a ROS 2 bag's messages: given for any other input, they are a
/// usage error rather than ignored.
pub fn check_bag_args(path: &Path, bag: &BagArg) -> Result<()> {
    if bag.given() && InputKind::of(path) != InputKind::Bag {
        return Err(UsageError(format!(
            "--topic and --frame choose a ROS 2 bag's messages, and {} is not a bag (an MCAP file)",
            mema::io::read::input_name(path)
        ))
        .into());
    }
    Ok(())
}

/// [`read_in_metres`] of any input, a ROS 2 bag's PointCloud2 messages with `bag`'s topic and
/// frame included, and a cloud file's isolated points treated as `outliers` says (`mema
/// map --outliers`; the commands that score or draw a cloud take it as it is).
pub fn read_input(
    path: &Path,
    units: &UnitsArg,
    bag: &BagArg,
    outliers: Outliers,
) -> Result<(LocalCloud, Units)> {
    check_bag_args(path, bag)?;
    let screening = Screening {
        classes: units.classes,
        outliers,
        min_range: units.min_range.unwrap_or(mema::io::read::NO_RETURN_RANGE),
    };
    let (cloud, units) = stage("reading", || {
        load_input_keeping(path, units.units.as_ref(), &bag.options(), screening)
    })?;
    if let (Some(worst), Outliers::Dropped { neighbours, ratio }) = (cloud.outliers.worst, outliers)
    {
        let [x, y, z] = worst.at;
        eprintln!(
            "mema: {}: dropped {} isolated points (mean distance to their {neighbours} nearest over {ratio} x the median, {:.3e} m); the worst, at ({x:.3}, {y:.3}, {z:.3}) m, is {:.3e} m from its neighbours (--outliers off keeps them)",
            mema::io::read::input_name(path),
            cloud.outliers.dropped,
            cloud.outliers.cut,
            worst.distance,
        );
    }
    let left = cloud.dropped_by_class;
    if left.total() > 0 {
        eprintln!(
            "mema: {}: left out {} noise points (ASPRS classes 7, 18), {} withheld, {} of other classes (--classes all keeps them)",
            mema::io::read::input_name(path),
            left.noise,
            left.withheld,
            left.other_classes
        );
    }
    if let Some(file) = &units.overrides {
        eprintln!(
            "mema: {}: --units {} overrides the file's {file}",
            mema::io::read::input_name(path),
            units.unit.name
        );
    }
    Ok((cloud, units))
}
