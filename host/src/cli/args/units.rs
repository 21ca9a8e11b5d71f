//! `--units`: the unit of a cloud's coordinates where its file does not say.

use clap::Args;
use mema::io::LengthUnit;

/// `--units` for every command that reads a cloud.
#[derive(Args, Debug, Clone, Default)]
pub struct UnitsArg {
    /// The unit of the cloud's coordinates: m, mm, cm, km, in, ft (0.3048 m) or us-ft
    /// (1200/3937 m). Needed where the file does not say (PLY, PCD, XYZ, KITTI, LAS without a
    /// CRS: metres assumed); overrides what a LAS file's CRS says. The cloud is scaled to
    /// metres on reading, so maps and every length on the command line are in metres.
    #[arg(long, value_name = "UNIT", value_parser = parse_unit)]
    pub units: Option<LengthUnit>,
    /// Which points of a classified cloud (LAS/LAZ) to keep: `not-noise` (every point but
    /// ASPRS classes 7 and 18, low and high noise, and withheld points, as PDAL users expect),
    /// `all`, or classes separated by commas (`2,6`: ground and buildings; withheld points
    /// left out). Other formats carry no classes and keep every point.
    #[arg(long, value_name = "CLASSES", default_value = "not-noise", value_parser = parse_classes)]
    pub classes: mema::io::read::Classes,
    /// Points closer than this to their sensor origin are no-returns, never surface (metres;
    /// default 0.01): lidar drivers write a beam that came back empty as the sensor's own
    /// position. Applies where the input says where its sensor was (a .conf's poses, a PCD's
    /// VIEWPOINT or organized frame, a KITTI scan, a bag's frames).
    #[arg(long, value_name = "METRES", value_parser = parse_min_range)]
    pub min_range: Option<f64>,
}

fn parse_min_range(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(r) if r >= 0.0 && r.is_finite() => Ok(r),
        _ => Err(format!("'{s}' is not a length of at least 0 (metres)")),
    }
}

fn parse_classes(s: &str) -> Result<mema::io::read::Classes, String> {
    s.parse()
}

fn parse_unit(s: &str) -> Result<LengthUnit, String> {
    LengthUnit::parse(s).ok_or_else(|| {
        format!(
            "unknown unit '{s}'; one of {}",
            LengthUnit::CHOICES.join(", ")
        )
    })
}
