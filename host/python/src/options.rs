//! `mema.map`'s keywords: the options of `mema map`, checked in the order the command line
//! checks them, and the library's run that the command makes of them.

use anyhow::{Context, Result};
use mema::batch::{ToleranceOptions, build_map, map_to_tolerance};
use mema::link::scanner::SensorScan;
use mema::link::stream::{Capacity, link_params, stream_scans};
use mema::mapping::filter::{self, CropBox, check_voxel};
use mema::mapping::{EntityChoice, FitOptions, Model, ShellModel, most_entities};
use mema_core::de::OutOfBounds;
use mema_core::fit::{Initialisation, SemiAxisBounds};
use mema_core::fitness::VolumeTerm;
use pyo3::PyResult;

use crate::cloud::Input;
use crate::errors::bad_value;

/// One of `choices` (the command line's value names), for the keyword `what`.
fn choose<T: Copy>(what: &str, given: &str, choices: &[(&str, T)]) -> PyResult<T> {
    choices
        .iter()
        .find(|(name, _)| *name == given)
        .map(|(_, value)| *value)
        .ok_or_else(|| {
            let names: Vec<_> = choices
                .iter()
                .map(|(name, _)| format!("'{name}'"))
                .collect();
            bad_value(
                what,
                format!("'{given}' is not one of {}", names.join(", ")),
            )
        })
}

pub fn model(given: &str) -> PyResult<Model> {
    choose(
        "model",
        given,
        &[("shells", Model::Shells), ("paper", Model::Paper)],
    )
}

pub fn entity(given: &str) -> PyResult<EntityChoice> {
    choose(
        "entity",
        given,
        &[
            ("ellipsoid", EntityChoice::Ellipsoid),
            ("sphere", EntityChoice::Sphere),
        ],
    )
}

/// `--bounds`: the same boxes the command line's names stand for.
pub fn bounds(given: &str) -> PyResult<SemiAxisBounds> {
    choose(
        "bounds",
        given,
        &[
            (
                "spread",
                SemiAxisBounds::Spread {
                    lower: 0.05,
                    upper: 3.0,
                },
            ),
            ("threshold", SemiAxisBounds::Threshold { lower: 0.05 }),
        ],
    )
}

pub fn out_of_bounds(given: &str) -> PyResult<OutOfBounds> {
    choose(
        "out_of_bounds",
        given,
        &[
            ("clamp", OutOfBounds::Clamp),
            ("reflect", OutOfBounds::Reflect),
            ("resample", OutOfBounds::Resample),
        ],
    )
}

pub fn volume(given: &str) -> PyResult<VolumeTerm> {
    choose(
        "volume",
        given,
        &[
            ("exact", VolumeTerm::Exact),
            ("spread", VolumeTerm::SpreadRelative),
        ],
    )
}

pub fn init(given: &str) -> PyResult<Initialisation> {
    choose(
        "init",
        given,
        &[
            ("seeded", Initialisation::MomentSeeded),
            ("random", Initialisation::Random),
        ],
    )
}

/// `crop=(xmin, ymin, zmin, xmax, ymax, zmax)`, checked as `--crop` is.
pub fn crop(given: Option<Vec<f64>>) -> PyResult<Option<CropBox>> {
    let Some(values) = given else {
        return Ok(None);
    };
    let [x0, y0, z0, x1, y1, z1] = values[..] else {
        return Err(bad_value(
            "crop",
            format!(
                "{} values; expected six: (xmin, ymin, zmin, xmax, ymax, zmax)",
                values.len()
            ),
        ));
    };
    let (min, max) = ([x0, y0, z0], [x1, y1, z1]);
    if min.iter().chain(&max).any(|v| !v.is_finite()) {
        return Err(bad_value("crop", "the bounds must be finite"));
    }
    if (0..3).any(|j| min[j] > max[j]) {
        return Err(bad_value(
            "crop",
            "each minimum must not exceed its maximum",
        ));
    }
    Ok(Some(CropBox { min, max }))
}

/// How many entities: exactly one of `k`, `bytes` and `tolerance`, as `mema map` requires.
#[derive(Clone, Copy, Debug)]
pub enum Size {
    K(usize),
    Bytes(usize),
    Tolerance(ToleranceOptions),
}

/// Every option of `mema map` but the files (the input is the points, the output and the labels
/// are the returned map's) and `--units` (`read_cloud`'s; arrays are in metres).
#[derive(Clone, Copy, Debug)]
pub struct MapOptions {
    pub size: Size,
    pub model: Model,
    pub entity: EntityChoice,
    pub shells: ShellModel,
    pub fit: FitOptions,
    pub crop: Option<CropBox>,
    pub voxel: Option<f64>,
    /// `--stream`: the streaming mapper, fed the bytes `mema scanner-sim` would send of the
    /// points, with at most this many clusters working (`--working`; all of k when `None`).
    pub stream: Option<Option<usize>>,
}

/// What a run made, and what the caller should hear about it.
pub struct Made {
    pub map: mema::io::HostMap,
    /// The report `mema map --json` prints, without `output`; its `unit` is the one
    /// `read_cloud` read in, or metres assumed for another array.
    pub report: serde_json::Value,
    pub labels: Vec<u32>,
    /// What `mema map` says on stderr: a budget larger than the points allow, a map of mostly
    /// degenerate entities.
    pub warnings: Vec<String>,
}

/// Maps `points` as `mema map` maps the cloud it reads (`host/src/cli/commands/map.rs`): the
/// same checks in the same order, the same filters and library calls, so the same points and
/// options give the same map bytes.
pub fn run(input: &Input, options: &MapOptions) -> Result<Made> {
    let model = options.model;
    if model == Model::Shells && options.entity == EntityChoice::Sphere {
        anyhow::bail!(
            "entity='sphere' is the paper's comparison; add paper=True (or model='paper')"
        );
    }
    // Free space is the batch shells' only here (stream=True sends one scan, which carves
    // nothing): asked for elsewhere, it would be silently missing.
    if options.shells.free_space {
        let without = if model != Model::Shells {
            Some("paper=True")
        } else if options.stream.is_some() {
            Some("stream=True")
        } else if matches!(options.size, Size::Tolerance(_)) {
            Some("tolerance=")
        } else {
            None
        };
        if let Some(without) = without {
            anyhow::bail!(
                "free_space=True is kept by the shells' batch map only, not with {without}"
            );
        }
    }
    options.shells.check()?;
    let size = options.size;
    if let Size::Tolerance(tolerance) = size {
        tolerance.check()?;
        let config = options.fit.config(1)?;
        let voxel = options.voxel.map(check_voxel).transpose()?;
        let (cloud, unit) = input.cloud().map_err(anyhow::Error::msg)?;
        let (cloud, _) = filter::apply(cloud, options.crop, voxel).context("points")?;
        let built = map_to_tolerance(&cloud, &tolerance, &config, model, options.shells.shell)
            .context("points")?;
        let mut report = serde_json::to_value(built.report(&cloud, "".as_ref()))?;
        finish_report(&mut report, unit)?;
        return Ok(Made {
            labels: built.labels(cloud.points.len()),
            map: built.map,
            report,
            warnings: Vec::new(),
        });
    }
    if let Some(working) = options.stream {
        return stream(input, options, working);
    }
    let k = match size {
        Size::Bytes(bytes) => model.entities_in(bytes)?,
        Size::K(k) => k,
        Size::Tolerance(_) => 0,
    };
    let mut config = options.fit.config(k)?;
    let voxel = options.voxel.map(check_voxel).transpose()?;
    let (cloud, unit) = input.cloud().map_err(anyhow::Error::msg)?;
    let (cloud, mut counts) = filter::apply(cloud, options.crop, voxel).context("points")?;
    // What other scans saw through is not surface, as on the command line.
    let cloud = if options.shells.free_space && model == mema::mapping::Model::Shells {
        let (carved, dropped) = mema::mapping::carve::carve(cloud);
        counts.carved = Some(dropped);
        carved
    } else {
        cloud
    };
    // The budget holds the scans' free space too, as on the command line.
    if let (Size::Bytes(bytes), true) = (size, options.shells.free_space) {
        config.k = model.entities_beside_free_space(bytes, cloud.sensors.origins.len())?;
    }
    let mut warnings = Vec::new();
    // A budget is an upper bound, as on the command line: past a quarter of the points,
    // clusters of one to three points have no shape to fit.
    let most = most_entities(cloud.points.len());
    if let Size::Bytes(bytes) = size
        && config.k > most
    {
        warnings.push(format!(
            "{bytes} bytes hold {} entities, but {} points make at most {most} clusters of {}; mapping with k = {most}",
            config.k,
            cloud.points.len(),
            mema::mapping::MIN_POINTS_PER_ENTITY
        ));
        config.k = most;
    }
    let built =
        build_map(&cloud, &config, model, options.shells, options.entity).context("points")?;
    let mut report = built.report;
    report.set_filter(counts);
    warnings.extend(degenerate_warning(&report, options.fit.threshold));
    let mut report = serde_json::to_value(&report)?;
    finish_report(&mut report, unit)?;
    Ok(Made {
        map: built.map,
        report,
        labels: built.labels,
        warnings,
    })
}

/// `stream=True`: as `mema map --stream` maps a cloud's file, the points sent as one scan whose
/// sensor sits at their bounding-box centre, through the receiver and the streaming mapper.
fn stream(input: &Input, options: &MapOptions, working: Option<usize>) -> Result<Made> {
    let Size::K(k) = options.size else {
        anyhow::bail!("stream=True takes k entities, not a budget of bytes or a tolerance");
    };
    if options.crop.is_some() || options.voxel.is_some() {
        anyhow::bail!("stream=True maps the points as sent: no crop or voxel");
    }
    let config = options.fit.config(k)?;
    let capacity = Capacity::checked(config.k, working, false)?;
    let (cloud, _) = input.cloud().map_err(anyhow::Error::msg)?;
    let scans = [SensorScan::of_cloud(&cloud)?];
    // One scan: nothing for later scans to see through, so nothing to carve.
    let (sent, link, map) = stream_scans(
        &scans,
        link_params(&config, capacity, None, options.model),
        false,
    )?;
    let report = serde_json::json!({
        "scans": sent.scans,
        "points": link.mapper.stats().points,
        "unit_exponent": sent.unit_exponent,
        "spacing": sent.spacing,
        "entities": map.entities.len(),
        "origin": map.origin,
    });
    Ok(Made {
        map,
        report,
        labels: Vec::new(),
        warnings: Vec::new(),
    })
}

/// The report as `mema map --json` prints it, but for `output`, the file written, which a map
/// in memory has not yet.
fn finish_report(report: &mut serde_json::Value, unit: Option<serde_json::Value>) -> Result<()> {
    if let Some(fields) = report.as_object_mut() {
        fields.remove("output");
        let unit = match unit {
            Some(unit) => unit,
            None => serde_json::to_value(mema::io::Units::assumed())?,
        };
        fields.insert("unit".into(), unit);
    }
    Ok(())
}

/// `mema map`'s warning when most entities degenerated: clusters wider than the threshold
/// everywhere mostly mean coordinates that are not metres.
fn degenerate_warning(r: &mema::batch::MapReport, threshold: f64) -> Option<String> {
    let degenerate = r.kinds.pseudocylinder + r.kinds.plane_pair;
    let all = r.memory.entities;
    (all > 0 && 2 * degenerate > all).then(|| {
        format!(
            "{degenerate} of {all} entities degenerated (an axis past the {threshold} m threshold); \
             the points are taken as metres: if they are not, scale them (read_cloud(path, units='mm'), say)"
        )
    })
}
