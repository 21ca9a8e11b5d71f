//! `mema._mema`, the extension module under the Python package `mema`: the host library's
//! reading, mapping, map files, evaluation and queries on numpy arrays.
//!
//! Every function that works for long (reading, mapping, scoring, queries) copies its input out
//! of Python first and then releases the GIL ([`Python::detach`]), so other Python threads run
//! meanwhile. Errors become exceptions through `errors::to_py`; nothing here panics on input.

mod arrays;
mod cloud;
mod errors;
mod map;
mod merge;
mod options;

use mema::batch::ToleranceOptions;
use mema::io::LengthUnit;
use mema::mapping::{FitOptions, ShellModel};
use mema_core::shell::ShellParams;
use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;
use std::ffi::CString;
use std::path::PathBuf;

use numpy::PyArrayMethods;

use crate::arrays::array_n;
use crate::errors::{IntoPy, MemaError, bad_value, count};
use crate::map::{Entities, Map};
use crate::options::{MapOptions, Size};

/// `units=`: one of `--units`' names.
pub(crate) fn parse_units(given: &str) -> PyResult<LengthUnit> {
    LengthUnit::parse(given).ok_or_else(|| {
        bad_value(
            "units",
            format!("'{given}' is not one of {}", LengthUnit::CHOICES.join(", ")),
        )
    })
}

/// `mema.read_cloud`'s reading (`python/mema/_cloud.py` wraps it into a `mema.Cloud`): the
/// cloud in metres as `mema map` reads it, `units` as `--units`, `topic` and `frame` as a
/// ROS 2 bag's `--topic` and `--frame`. Gives the world coordinates
/// `(N, 3)` float64, the reader's f32 offsets `(N, 3)` and f64 origin `(3,)`, the unit as
/// `mema eval --json` gives it (JSON text), the points dropped for a non-finite coordinate,
/// and the points the read left out: by `classes` (as `--classes`) noise, withheld, other
/// classes, and by `outliers` (as `mema map --outliers`, whose default it shares) isolated ones.
#[pyfunction]
#[pyo3(signature = (path, units = None, topic = None, frame = None, classes = None, outliers = None, min_range = None))]
#[allow(clippy::too_many_arguments)]
fn _read_cloud<'py>(
    py: Python<'py>,
    path: PathBuf,
    units: Option<&str>,
    topic: Option<String>,
    frame: Option<String>,
    classes: Option<&str>,
    outliers: Option<&str>,
    min_range: Option<f64>,
) -> PyResult<ReadCloud<'py>> {
    let given = units.map(parse_units).transpose()?;
    let classes: mema::io::read::Classes = match classes {
        Some(c) => c
            .parse()
            .map_err(|e: String| errors::bad_value("classes", &e))?,
        None => Default::default(),
    };
    let outliers = match outliers {
        Some(o) => o
            .parse()
            .map_err(|e: String| errors::bad_value("outliers", &e))?,
        None => mema::io::read::Outliers::DEFAULT,
    };
    if let Some(r) = min_range
        && !(r >= 0.0 && r.is_finite())
    {
        return Err(errors::bad_value(
            "min_range",
            "must be a finite number of metres, 0 or more",
        ));
    }
    let screening = mema::io::read::Screening {
        classes,
        outliers,
        min_range: min_range.unwrap_or(mema::io::read::Screening::DEFAULT.min_range),
    };
    let bag = mema::io::bag::BagOptions { topic, frame };
    if (bag.topic.is_some() || bag.frame.is_some())
        && mema::io::kind::InputKind::of(&path) != mema::io::kind::InputKind::Bag
    {
        return Err(errors::bad_value(
            "topic, frame",
            "choose a ROS 2 bag's messages, and this file is not a bag (an MCAP file)",
        ));
    }
    let (cloud, unit) = py
        .detach(|| mema::io::cloud::load_input_keeping(&path, given.as_ref(), &bag, screening))
        .into_py()?;
    let world = py.detach(|| cloud::world_points(&cloud));
    let local: Vec<f32> = cloud.points.iter().flat_map(|p| p.to_array()).collect();
    let unit = serde_json::to_string(&unit).map_err(|e| errors::to_py(e.into()))?;
    Ok((
        array_n(py, &world)?,
        numpy::PyArray1::from_vec(py, local)
            .reshape([cloud.points.len(), 3])?
            .into_any(),
        arrays::array1(py, cloud.origin.to_vec()),
        unit,
        cloud.dropped_non_finite,
        {
            let left = cloud.dropped_by_class;
            (
                left.noise,
                left.withheld,
                left.other_classes,
                cloud.outliers.dropped,
            )
        },
        (cloud.sensors.origins.clone(), cloud.sensors.ends.clone()),
        cloud.no_returns,
    ))
}

/// What [`_read_cloud`] gives.
type ReadCloud<'py> = (
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    String,
    usize,
    (usize, usize, usize, usize),
    (Vec<[f64; 3]>, Vec<usize>),
    usize,
);

/// Maps an `(N, 3)` array of points in metres (float32 or float64; rows with a NaN or infinite
/// coordinate are dropped) into a `Map`, with every option of `mema map` under its name
/// (`--tangent-scale` is `tangent_scale=`). Give exactly one of `k` (entities), `bytes` (as many
/// entities as that many bytes of `.mema` file hold) or `tolerance` (metres of eq. 13 error per
/// cluster). A `mema.Cloud` from `read_cloud` maps in the frame its reader chose, so the same
/// cloud and options give the same map bytes as `mema map` on its file (as long as the array
/// still holds what was read); another array is centred as a reader centres a file.
/// `stream=True` maps as `mema map --stream` does: the streaming mapper, fed the bytes
/// `mema scanner-sim` would send (`working=` as `--working`).
/// `free_space=True` keeps each scan's range image as `--free-space` does, within `bytes`, for
/// `Map.state` to tell free from unknown. `no_ray_shaping=True` keeps the shells as their
/// clusters made them, as `--no-ray-shaping` does. The GIL is released while
/// mapping.
#[pyfunction(name = "map")]
#[pyo3(signature = (
    points, k = None, bytes = None, seed = 0, paper = false, *,
    model = "shells", tangent_scale = 2.0, normal_scale = 0.7, surface_rounds = 30,
    tolerance = None, capacity = 16384, voronoi_rounds = 0, entity = "ellipsoid",
    alpha = 0.8, threshold = 4.0, sphere_tolerance = 0.01, bounds = "spread",
    out_of_bounds = "clamp", volume = "exact", init = "seeded", generations = 50,
    max_iterations = 100, crop = None, voxel = None, stream = false, working = None,
    free_space = false, no_ray_shaping = false
))]
// One keyword an option, as Python callers expect (and as `mema map` has them).
#[allow(clippy::too_many_arguments)]
fn map_points<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    k: Option<i64>,
    bytes: Option<i64>,
    seed: u64,
    paper: bool,
    model: &str,
    tangent_scale: f64,
    normal_scale: f64,
    surface_rounds: i64,
    tolerance: Option<f64>,
    capacity: i64,
    voronoi_rounds: i64,
    entity: &str,
    alpha: f64,
    threshold: f64,
    sphere_tolerance: f64,
    bounds: &str,
    out_of_bounds: &str,
    volume: &str,
    init: &str,
    generations: i64,
    max_iterations: i64,
    crop: Option<Vec<f64>>,
    voxel: Option<f64>,
    stream: bool,
    working: Option<i64>,
    free_space: bool,
    no_ray_shaping: bool,
) -> PyResult<Map> {
    let k = k.map(|k| count::<usize>("k", k)).transpose()?;
    let bytes = bytes.map(|b| count::<usize>("bytes", b)).transpose()?;
    let (capacity, voronoi_rounds) = (
        count("capacity", capacity)?,
        count("voronoi_rounds", voronoi_rounds)?,
    );
    let size = match (k, bytes, tolerance) {
        (Some(k), None, None) => Size::K(k),
        (None, Some(bytes), None) => Size::Bytes(bytes),
        (None, None, Some(tolerance)) => Size::Tolerance(ToleranceOptions {
            tolerance,
            capacity,
            voronoi_rounds,
        }),
        _ => {
            return Err(bad_value(
                "k, bytes, tolerance",
                "give exactly one: k entities, a budget of bytes, or a tolerance in metres",
            ));
        }
    };
    let options = MapOptions {
        size,
        model: if paper {
            mema::mapping::Model::Paper
        } else {
            options::model(model)?
        },
        entity: options::entity(entity)?,
        shells: ShellModel {
            shell: ShellParams {
                tangent_scale,
                normal_scale,
                ..Default::default()
            },
            surface_rounds: count("surface_rounds", surface_rounds)?,
            free_space,
            ray_shaping: !no_ray_shaping,
        },
        fit: FitOptions {
            alpha,
            seed,
            threshold,
            sphere_tolerance,
            bounds: options::bounds(bounds)?,
            out_of_bounds: options::out_of_bounds(out_of_bounds)?,
            volume: options::volume(volume)?,
            initialisation: options::init(init)?,
            generations: count("generations", generations)?,
            max_iterations: count("max_iterations", max_iterations)?,
        },
        crop: options::crop(crop)?,
        voxel,
        stream: match (stream, working) {
            (true, working) => Some(working.map(|w| count("working", w)).transpose()?),
            (false, None) => None,
            (false, Some(_)) => return Err(bad_value("working", "takes stream=True")),
        },
    };
    let input = cloud::input(points, "points")?;
    let made = py.detach(|| options::run(&input, &options)).into_py()?;
    for warning in &made.warnings {
        let message = CString::new(warning.replace('\0', " "))?;
        PyErr::warn(py, &py.get_type::<PyUserWarning>(), &message, 1)?;
    }
    Ok(Map::made(made.map, made.report, made.labels))
}

/// Reads a map file (`.mema`, `.csv` or `.json`, by its extension).
#[pyfunction]
fn load(py: Python<'_>, path: PathBuf) -> PyResult<Map> {
    py.detach(|| Map::read(path)).into_py()
}

/// A map from its `.mema` bytes (`Map.to_bytes()`; how a `Map` is unpickled).
#[pyfunction]
fn from_bytes(data: &[u8]) -> PyResult<Map> {
    mema::io::HostMap::from_mema(data).into_py().map(Map::new)
}

/// The 3x3 matrix of `mema transform --rotate ax,ay,az`: rotations about x, then y, then z,
/// in degrees; multiples of 90 are exact axis permutations.
#[pyfunction]
fn rotation_degrees<'py>(py: Python<'py>, angles: [f64; 3]) -> PyResult<Bound<'py, PyAny>> {
    if !angles.iter().all(|a| a.is_finite()) {
        return Err(bad_value("angles", "must be finite"));
    }
    let m = mema::query::rotation_degrees(angles).rotation;
    let rotation = array_n(py, &m)?;
    Ok(rotation)
}

#[pymodule]
fn _mema(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MemaError", m.py().get_type::<MemaError>())?;
    m.add_class::<Map>()?;
    m.add_class::<Entities>()?;
    m.add_function(wrap_pyfunction!(_read_cloud, m)?)?;
    m.add_function(wrap_pyfunction!(map_points, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(from_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(rotation_degrees, m)?)?;
    m.add_function(wrap_pyfunction!(merge::merge, m)?)?;
    Ok(())
}
