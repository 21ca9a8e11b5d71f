//! `mema.Map`: a map in memory, its files, its entities as arrays, and what a robot asks of it
//! (distance, occupancy, ray casts), each question vectorised over many points.

use anyhow::Context;
use mema::analysis::eval::EvalDocument;
use mema::io::HostMap;
use mema::io::mapfile::{KindCounts, MapFormat};
use mema::query::states::{State, state_of};
use mema::query::{HostIndex, build_index, local, transform_map, world};
use mema_core::transform::RigidTransform;
use numpy::PyArrayMethods;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::{Mutex, OnceLock};

use crate::arrays::{array_n, array1, finite_rows, matrix3};
use crate::errors::{IntoPy, bad_value};

/// A map of ellipsoids, in metres. Made by `mema.map`, read by `mema.load`.
///
/// `len(map)` is its entity count; `map.entities` gives them as arrays; `save` writes a file
/// in the format of its extension (`.mema`, `.csv`, `.json`), as `mema map -o` does. The
/// queries take `(N, 3)` arrays (or one `(3,)` point) in world coordinates.
#[pyclass(module = "mema", name = "Map", frozen)]
pub struct Map {
    pub map: HostMap,
    /// The query index, built on the first query.
    index: OnceLock<Box<HostIndex>>,
    /// `mema map --json`'s report, for a map `mema.map` made.
    report: Option<serde_json::Value>,
    /// Each mapped point's cluster, for a map `mema.map` made.
    labels: Option<Vec<u32>>,
    /// The file the map was last read from or written to: `eval` measures its bytes there,
    /// as `mema eval` measures the file it is given.
    source: Mutex<Option<PathBuf>>,
}

impl Map {
    pub fn new(map: HostMap) -> Self {
        Self {
            map,
            index: OnceLock::new(),
            report: None,
            labels: None,
            source: Mutex::new(None),
        }
    }

    pub fn made(map: HostMap, report: serde_json::Value, labels: Vec<u32>) -> Self {
        Self {
            report: Some(report),
            labels: Some(labels),
            ..Self::new(map)
        }
    }

    pub fn read(path: PathBuf) -> anyhow::Result<Self> {
        let map = HostMap::read(&path)?;
        let made = Self::new(map);
        made.set_source(path);
        Ok(made)
    }

    fn set_source(&self, path: PathBuf) {
        if let Ok(mut source) = self.source.lock() {
            *source = Some(path);
        }
    }

    pub fn source(&self) -> Option<PathBuf> {
        self.source.lock().ok().and_then(|s| s.clone())
    }

    fn index(&self) -> anyhow::Result<&HostIndex> {
        if let Some(index) = self.index.get() {
            return Ok(index);
        }
        let built = build_index(&self.map)?;
        // Two threads may race to build it; either index is the same.
        Ok(self.index.get_or_init(|| built))
    }
}

/// The entities of a map as arrays, one row an entity, in world coordinates and metres.
///
/// `centres` `(K, 3)`; `semi_axes` `(K, 3)`, `inf` along a degenerated axis; `rotations`
/// `(K, 3, 3)` with `x_world = centre + R @ x_local`; `quaternions` `(K, 4)` the same
/// rotations as `(x, y, z, w)`; `weights` `(K, 3)` the stored `w = 1 / r^2` (0 for an infinite
/// axis); `kinds` `(K,)` strings: `ellipsoid`, `sphere`, `pseudocylinder` or `plane_pair`.
#[pyclass(module = "mema", name = "Entities", frozen)]
pub struct Entities {
    #[pyo3(get)]
    centres: Py<PyAny>,
    #[pyo3(get)]
    semi_axes: Py<PyAny>,
    #[pyo3(get)]
    rotations: Py<PyAny>,
    #[pyo3(get)]
    quaternions: Py<PyAny>,
    #[pyo3(get)]
    weights: Py<PyAny>,
    #[pyo3(get)]
    kinds: Py<PyAny>,
    count: usize,
}

#[pymethods]
impl Entities {
    fn __len__(&self) -> usize {
        self.count
    }

    fn __repr__(&self) -> String {
        format!(
            "Entities({} rows: centres, semi_axes, rotations, quaternions, weights, kinds)",
            self.count
        )
    }
}

/// JSON text as Python objects (dicts keep the keys' order).
fn json_to_py<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| crate::errors::to_py(e.into()))?;
    py.import("json")?.call_method1("loads", (text,))
}

#[pymethods]
impl Map {
    fn __len__(&self) -> usize {
        self.map.entities.len()
    }

    fn __repr__(&self) -> String {
        let k = KindCounts::of(&self.map);
        format!(
            "mema.Map({} entities: {} ellipsoid, {} sphere, {} pseudocylinder, {} plane_pair; origin {:?})",
            self.map.entities.len(),
            k.ellipsoid,
            k.sphere,
            k.pseudocylinder,
            k.plane_pair,
            self.map.origin
        )
    }

    /// Two maps are equal when their origins and entities are the same bits.
    fn __eq__(&self, other: &Self) -> bool {
        self.map == other.map
    }

    /// `Map(data)`: the map of `.mema` bytes (`Map.to_bytes()`), as `mema.from_bytes`.
    #[new]
    fn from_mema(data: &[u8]) -> PyResult<Self> {
        HostMap::from_mema(data).into_py().map(Self::new)
    }

    /// Pickles as its `.mema` bytes (the map only, not `report` or `labels`).
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyBytes>,))> {
        let bytes = slf.get().map.to_mema().into_py()?;
        Ok((slf.get_type().into_any(), (PyBytes::new(slf.py(), &bytes),)))
    }

    /// Writes the map to `path` in the format of its extension (`.mema`, `.csv`, `.json`),
    /// atomically, as `mema map -o` writes it.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.map.write(&path)).into_py()?;
        self.set_source(path);
        Ok(())
    }

    /// The bytes `save` would write for `format` (`"mema"`, `"csv"` or `"json"`).
    #[pyo3(signature = (format = "mema"))]
    fn to_bytes<'py>(&self, py: Python<'py>, format: &str) -> PyResult<Bound<'py, PyBytes>> {
        let format = MapFormat::from_path(format!("map.{format}").as_ref()).map_err(|_| {
            bad_value(
                "format",
                format!("'{format}' is not 'mema', 'csv' or 'json'"),
            )
        })?;
        let bytes = self.map.encode_as(format).into_py()?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// The local frame's origin in world coordinates (metres), `(3,)`.
    #[getter]
    fn origin<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array1(py, self.map.origin.to_vec())
    }

    /// Whether the `.mema` file is quantized (14 bytes an entity, the shells' format).
    #[getter]
    fn quantized(&self) -> bool {
        self.map.quantization.is_some()
    }

    /// `mema map --json`'s report as a dict (tables 2 and 4, kinds, k-means), for a map
    /// `mema.map` made; `None` for one read from a file.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.report.as_ref().map(|r| json_to_py(py, r)).transpose()
    }

    /// Each mapped point's cluster (int64), what `mema map --labels` writes: one per point
    /// left after dropping non-finite rows, `crop` and `voxel`, in their order; `None` for a
    /// map read from a file.
    #[getter]
    fn labels<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.labels
            .as_ref()
            .map(|l| array1(py, l.iter().map(|&c| i64::from(c)).collect()))
    }

    /// The entities as arrays ([`Entities`]).
    #[getter]
    fn entities(&self, py: Python<'_>) -> PyResult<Entities> {
        let entities = &self.map.entities;
        let centres: Vec<[f64; 3]> = entities
            .iter()
            .map(|e| self.map.world_center(&e.entity))
            .collect();
        let semi_axes: Vec<[f64; 3]> = entities.iter().map(|e| e.entity.semi_axes_f64()).collect();
        let rotations: Vec<[f64; 9]> = entities
            .iter()
            .map(|e| {
                let m = e.entity.rotation.matrix();
                [
                    m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2],
                ]
            })
            .collect();
        let quaternions: Vec<[f64; 4]> = entities
            .iter()
            .map(|e| e.entity.rotation.to_array().map(f64::from))
            .collect();
        let weights: Vec<[f64; 3]> = entities
            .iter()
            .map(|e| e.entity.weights.map(f64::from))
            .collect();
        let kinds: Vec<&str> = entities.iter().map(|e| e.kind.name()).collect();
        let numpy = py.import("numpy")?;
        Ok(Entities {
            centres: array_n(py, &centres)?.unbind(),
            semi_axes: array_n(py, &semi_axes)?.unbind(),
            rotations: array_n(py, &rotations)?
                .cast_into::<numpy::PyArray2<f64>>()?
                .reshape([entities.len(), 3, 3])?
                .into_any()
                .unbind(),
            quaternions: array_n(py, &quaternions)?.unbind(),
            weights: array_n(py, &weights)?.unbind(),
            kinds: numpy.call_method1("array", (kinds, "U14"))?.unbind(),
            count: entities.len(),
        })
    }

    /// `mema eval --json` of this map against `cloud` (a path, read in metres as `mema eval`
    /// reads it, `units` as its `--units`; or an `(N, 3)` array in metres, a `mema.Cloud` in
    /// the frame and unit it was read in): a dict of eq. 13's
    /// statistics, the two-way score with `samples` surface points seeded by `seed`, the map's
    /// bytes (of the file it was last read from or saved to, else of its `.mema` encoding) and
    /// the unit.
    #[pyo3(signature = (cloud, samples = 200_000, seed = 0, units = None))]
    fn eval<'py>(
        &self,
        py: Python<'py>,
        cloud: &Bound<'py, PyAny>,
        samples: i64,
        seed: u64,
        units: Option<&str>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let samples: usize = crate::errors::count("samples", samples)?;
        use mema::analysis::eval::{MAX_SAMPLES, evaluate, points_in_map_frame};
        if samples == 0 || samples > MAX_SAMPLES {
            return Err(bad_value(
                "samples",
                format!("{samples} must be between 1 and {MAX_SAMPLES}"),
            ));
        }
        if self.map.entities.is_empty() {
            return Err(bad_value("map", "the map has no entities"));
        }
        let given = units.map(crate::parse_units).transpose()?;
        let input = match cloud.extract::<PathBuf>() {
            Ok(path) => Scored::Path(path),
            Err(_) if given.is_some() => {
                return Err(bad_value(
                    "units",
                    "only a file's coordinates are scaled; an array is taken in metres",
                ));
            }
            Err(_) => Scored::Points(crate::cloud::input(cloud, "cloud")?),
        };
        let source = self.source();
        let doc = py
            .detach(|| -> anyhow::Result<EvalDocument> {
                let (cloud, unit) = match input {
                    Scored::Path(path) => {
                        let (cloud, unit) = mema::io::load_cloud_in_metres(&path, given.as_ref())?;
                        (cloud, serde_json::to_value(unit)?)
                    }
                    Scored::Points(input) => {
                        let (cloud, unit) = input.cloud().map_err(anyhow::Error::msg)?;
                        let unit = match unit {
                            Some(unit) => unit,
                            None => serde_json::to_value(mema::io::Units::assumed())?,
                        };
                        (cloud, unit)
                    }
                };
                let bytes = file_bytes(&self.map, source)?;
                let eq13 = evaluate(&cloud, &self.map);
                let entities: Vec<_> = self.map.entities.iter().map(|e| e.entity).collect();
                let fidelity = mema::analysis::fidelity::two_way_score(
                    &points_in_map_frame(&cloud, &self.map),
                    &entities,
                    seed,
                    samples,
                )?;
                Ok(EvalDocument {
                    eq13,
                    fidelity,
                    bytes,
                    dropped_non_finite: cloud.dropped_non_finite,
                    unit,
                })
            })
            .into_py()?;
        let value = serde_json::to_value(&doc).map_err(|e| crate::errors::to_py(e.into()))?;
        json_to_py(py, &value)
    }

    /// The nearest entity surface to each point: `(signed_distance, entity)`, float64 metres
    /// (negative inside an entity) and int64 indices, `(N,)` each, or two scalars for one
    /// `(3,)` point. An empty map answers NaN and -1.
    fn nearest<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let rows = finite_rows(points, "points", true)?;
        let index = self.index().into_py()?;
        let found: Vec<(f64, i64)> = py.detach(|| {
            rows.rows
                .par_iter()
                .map(|&p| {
                    index
                        .nearest(local(&self.map, p))
                        .map_or((f64::NAN, -1), |n| (n.signed_distance, n.entity as i64))
                })
                .collect()
        });
        let (distance, entity): (Vec<f64>, Vec<i64>) = found.into_iter().unzip();
        if rows.single {
            return Ok((
                distance[0].into_pyobject(py)?.into_any(),
                entity[0].into_pyobject(py)?.into_any(),
            ));
        }
        Ok((array1(py, distance), array1(py, entity)))
    }

    /// What the map says of each point: `"free"` (a scan the map keeps saw through it),
    /// `"occupied"` (within `tolerance` metres of an entity's surface, or inside one) or
    /// `"unknown"`, as `mema query --points` says it; a `(N,)` array of str, or one str for one
    /// `(3,)` point. A map made without `free_space=True` calls nothing free.
    #[pyo3(signature = (points, tolerance = 0.1))]
    fn state<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        tolerance: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        if !(tolerance.is_finite() && tolerance >= 0.0) {
            return Err(bad_value("tolerance", format!("{tolerance} must be >= 0")));
        }
        let rows = finite_rows(points, "points", true)?;
        let index = self.index().into_py()?;
        let found: Vec<&'static str> = py.detach(|| {
            rows.rows
                .par_iter()
                .map(|&p| match state_of(&self.map, index, p, tolerance).state {
                    State::Free => "free",
                    State::Occupied => "occupied",
                    State::Unknown => "unknown",
                })
                .collect()
        });
        if rows.single {
            return Ok(found[0].into_pyobject(py)?.into_any());
        }
        py.import("numpy")?.call_method1("asarray", (found,))
    }

    /// The entity holding each point (int64, `(N,)`, or a scalar for one `(3,)` point), -1
    /// where the point is in free space; `occupied(p) >= 0` is the boolean.
    fn occupied<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let rows = finite_rows(points, "points", true)?;
        let index = self.index().into_py()?;
        let found: Vec<i64> = py.detach(|| {
            rows.rows
                .par_iter()
                .map(|&p| index.occupied(local(&self.map, p)).map_or(-1, |e| e as i64))
                .collect()
        });
        if rows.single {
            return Ok(found[0].into_pyobject(py)?.into_any());
        }
        Ok(array1(py, found))
    }

    /// The first entity surface along each ray within `max_range` metres: `(range, entity,
    /// point)`, `(N,)` float64, `(N,)` int64 and `(N, 3)` float64 world points, with `inf`, -1
    /// and NaN where a ray hits nothing. `origins` and `directions` are `(N, 3)` or one `(3,)`
    /// row shared by every ray; directions need not be unit (ranges are along the normalised
    /// direction). Two `(3,)` rows give scalars and a `(3,)` point.
    #[pyo3(signature = (origins, directions, max_range = 1e6))]
    fn ray_cast<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        max_range: f64,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let origins = finite_rows(origins, "origins", true)?;
        let directions = finite_rows(directions, "directions", true)?;
        if max_range.is_nan() || max_range < 0.0 {
            return Err(bad_value("max_range", format!("{max_range} must be >= 0")));
        }
        if let Some(i) = directions.rows.iter().position(|d| *d == [0.0; 3]) {
            return Err(bad_value("directions", format!("row {i} is zero")));
        }
        let (no, nd) = (origins.rows.len(), directions.rows.len());
        let n = no.max(nd);
        if (no != n && no != 1) || (nd != n && nd != 1) {
            return Err(bad_value(
                "rays",
                format!("{no} origins and {nd} directions; give as many of each, or one of either"),
            ));
        }
        let index = self.index().into_py()?;
        let hits: Vec<(f64, i64, [f64; 3])> = py.detach(|| {
            (0..n)
                .into_par_iter()
                .map(|i| {
                    let o = origins.rows[if no == 1 { 0 } else { i }];
                    let d = directions.rows[if nd == 1 { 0 } else { i }];
                    index
                        .ray_cast(local(&self.map, o), d, max_range)
                        .map_or((f64::INFINITY, -1, [f64::NAN; 3]), |h| {
                            (h.t, h.entity as i64, world(&self.map, h.point))
                        })
                })
                .collect()
        });
        let range: Vec<f64> = hits.iter().map(|h| h.0).collect();
        let entity: Vec<i64> = hits.iter().map(|h| h.1).collect();
        let points: Vec<[f64; 3]> = hits.iter().map(|h| h.2).collect();
        if origins.single && directions.single {
            return Ok((
                range[0].into_pyobject(py)?.into_any(),
                entity[0].into_pyobject(py)?.into_any(),
                array1(py, points[0].to_vec()),
            ));
        }
        Ok((array1(py, range), array1(py, entity), array_n(py, &points)?))
    }

    /// The map moved by `x' = rotation @ x + translation` (a 3x3 rotation matrix, the identity
    /// if omitted; a translation in metres, zero if omitted), as `mema transform` moves it:
    /// exact for translations and axis permutations (`rotation_degrees` with multiples of 90).
    #[pyo3(signature = (rotation = None, translation = None))]
    fn transform(
        &self,
        rotation: Option<&Bound<'_, PyAny>>,
        translation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Map> {
        let turn = match rotation {
            Some(r) => RigidTransform {
                rotation: matrix3(r, "rotation")?,
                translation: [0.0; 3],
            },
            None => RigidTransform::IDENTITY,
        };
        let shift = match translation {
            Some(t) => {
                let three = || bad_value("translation", "expected three finite numbers (x, y, z)");
                let rows = finite_rows(t, "translation", true).map_err(|_| three())?;
                match rows.rows.as_slice() {
                    [t] if rows.single => *t,
                    _ => return Err(three()),
                }
            }
            None => [0.0; 3],
        };
        // Composed as the command line composes --rotate and --translate, so the same matrix
        // gives the same bits.
        let t = RigidTransform::translation(shift).after(&turn);
        let moved = transform_map(&self.map, &t).ok_or_else(|| {
            bad_value(
                "rotation",
                "not a rotation matrix (orthonormal with determinant +1, within 1e-6)",
            )
        })?;
        Ok(Map::new(moved))
    }
}

/// What `eval` scores against.
enum Scored {
    Path(PathBuf),
    Points(crate::cloud::Input),
}

/// The map's bytes as `mema eval` reports them: measured on the file it came from or went to,
/// if that is still there, else those of its `.mema` encoding (whose size its layout fixes).
fn file_bytes(
    map: &HostMap,
    source: Option<PathBuf>,
) -> anyhow::Result<mema::analysis::eval::FileBytes> {
    if let Some(path) = source.filter(|p| p.is_file()) {
        return mema::analysis::eval::FileBytes::of(&path, map)
            .with_context(|| path.display().to_string());
    }
    let layout = map.layout();
    let file_bytes = layout.encoded_len(map.entities.len()) as u64;
    let header_bytes = layout.encoded_len(0) as u64;
    Ok(mema::analysis::eval::FileBytes {
        file_bytes,
        header_bytes,
        bytes_per_entity: (file_bytes - header_bytes) as f64 / map.entities.len().max(1) as f64,
    })
}
