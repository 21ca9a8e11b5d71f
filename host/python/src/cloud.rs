//! Clouds between numpy and the library.
//!
//! A reader keeps a cloud as an f64 origin and f32 offsets from it (`LocalCloud`). Handed to
//! Python as world coordinates, `origin + offset` rounds in f64 wherever the origin has finer
//! bits than the sum (text clouds, whose origin is the centre of decimal bounds), and no rule
//! applied to the rounded values alone finds the reader's origin and offsets again. So
//! `read_cloud` returns a `mema.Cloud`: the world coordinates, which is what a numpy user works
//! with, and beside them the reader's frame (`origin`, `local`). [`input`] takes that frame as
//! long as the array still holds exactly `origin + local`, so the map is the command line's bit
//! for bit; any other array (or a Cloud since changed, sliced or computed on) is centred as the
//! readers centre a file ([`local_cloud`]).

use mema::io::cloud::LocalCloud;
use mema_core::Point3;
use numpy::{PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::arrays::rows;
use crate::errors::bad_value;

/// The frame a reader put a cloud in, as a `mema.Cloud` carries it.
pub struct Frame {
    pub origin: [f64; 3],
    pub local: Vec<[f32; 3]>,
    pub dropped_non_finite: usize,
    /// `mema eval --json`'s `unit` of the read.
    pub unit: serde_json::Value,
    /// Where the read's points were seen from, and the no-returns it left out.
    pub sensors: mema::io::sensors::Sensors,
    pub no_returns: usize,
}

/// Points given to `map` or `eval`: their rows, and the reader's frame if they came from
/// `read_cloud`.
pub struct Input {
    pub rows: Vec<[f64; 3]>,
    pub frame: Option<Frame>,
}

/// `obj`'s rows and, for a `mema.Cloud`, its frame (checked later, in [`Input::cloud`]).
pub fn input(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Input> {
    let rows = rows(obj, what, false)?.rows;
    let py = obj.py();
    let cloud_type = py.import("mema._cloud")?.getattr("Cloud")?;
    if !obj.is_instance(&cloud_type)? {
        return Ok(Input { rows, frame: None });
    }
    let (origin, local) = (obj.getattr("origin")?, obj.getattr("local")?);
    if origin.is_none() || local.is_none() {
        return Ok(Input { rows, frame: None });
    }
    let local: PyReadonlyArray2<'_, f32> = local
        .extract()
        .map_err(|e| bad_value(&format!("{what}.local"), e))?;
    if local.shape()[1] != 3 {
        return Err(bad_value(
            &format!("{what}.local"),
            "expected an (N, 3) array",
        ));
    }
    let local = local
        .as_array()
        .outer_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect();
    let unit = py
        .import("json")?
        .call_method1("dumps", (obj.getattr("unit")?,))?
        .extract::<String>()?;
    let frame = Frame {
        origin: origin.extract()?,
        local,
        dropped_non_finite: obj.getattr("dropped_non_finite")?.extract()?,
        unit: serde_json::from_str(&unit).map_err(|e| bad_value(&format!("{what}.unit"), e))?,
        sensors: match obj.getattr("sensors")? {
            s if s.is_none() => Default::default(),
            s => {
                let (origins, ends): (Vec<[f64; 3]>, Vec<usize>) = s
                    .extract()
                    .map_err(|e| bad_value(&format!("{what}.sensors"), e))?;
                mema::io::sensors::Sensors { origins, ends }
            }
        },
        no_returns: obj.getattr("no_returns")?.extract().unwrap_or(0),
    };
    Ok(Input {
        rows,
        frame: Some(frame),
    })
}

impl Input {
    /// The cloud to map or score: the reader's, if the rows are still exactly its origin plus
    /// its offsets, else the rows centred as a reader centres a file. The unit comes with the
    /// reader's frame.
    pub fn cloud(&self) -> Result<(LocalCloud, Option<serde_json::Value>), String> {
        if let Some(frame) = &self.frame
            && frame.local.len() == self.rows.len()
            && frame
                .local
                .iter()
                .zip(&self.rows)
                .all(|(x, w)| (0..3).all(|j| frame.origin[j] + f64::from(x[j]) == w[j]))
        {
            let cloud = LocalCloud {
                origin: frame.origin,
                points: frame.local.iter().copied().map(Point3::from).collect(),
                dropped_non_finite: frame.dropped_non_finite,
                dropped_by_class: Default::default(),
                outliers: Default::default(),
                unit: None,
                sensors: frame.sensors.clone(),
                no_returns: frame.no_returns,
            };
            return Ok((cloud, Some(frame.unit.clone())));
        }
        Ok((local_cloud(&self.rows)?, None))
    }
}

/// The cloud of `points` (world coordinates, in metres), centred exactly as the file readers
/// centre what they read ([`LocalCloud::from_world_checked`]). A binary cloud's array maps as
/// its file does; a text cloud's may differ in the last bit of its origin (see the module doc).
pub fn local_cloud(points: &[[f64; 3]]) -> Result<LocalCloud, String> {
    LocalCloud::from_world_checked(points).map_err(|e| e.to_string())
}

/// The cloud's points in world coordinates: origin plus each f32 point, in f64.
pub fn world_points(cloud: &LocalCloud) -> Vec<[f64; 3]> {
    cloud
        .points
        .iter()
        .map(|p| {
            let q = p.to_f64();
            [0, 1, 2].map(|j| cloud.origin[j] + q[j])
        })
        .collect()
}
