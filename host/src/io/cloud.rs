//! A cloud as the pipeline takes it: f32 points in a local frame around an f64 origin.

use anyhow::{Context, Result, bail};
use mema_core::Point3;
use std::path::Path;

use super::bag::{BagOptions, read_bag_keeping};
use super::conf::{RegisteredScan, read_registration};
use super::kind::InputKind;
use super::read::{
    ClassDrops, Cloud, OutlierDrops, Screening, read_cloud, read_cloud_in_metres_keeping,
};
use super::sensors::{Sensors, drop_no_returns};
use super::units::{FileUnit, LengthUnit, Units, resolve};

/// A cloud in its local frame, ready for the core.
///
/// The core works in f32; survey coordinates (hundreds of kilometres, millimetre detail) do
/// not fit f32, so every point is stored relative to `origin`, kept in f64.
#[derive(Clone, Debug, PartialEq)]
pub struct LocalCloud {
    /// The local frame's origin, in the file's own coordinates.
    pub origin: [f64; 3],
    /// The points, relative to `origin`.
    pub points: Vec<Point3>,
    /// Points the reader skipped because a coordinate was NaN or infinite.
    pub dropped_non_finite: usize,
    /// Points of a classified file (LAS/LAZ) the read left out: noise, withheld, other classes.
    pub dropped_by_class: ClassDrops,
    /// Isolated points the read left out ([`crate::io::read::Outliers`]).
    pub outliers: OutlierDrops,
    /// The unit the file says `origin` and `points` are in (`None`: it says nothing); see
    /// [`LocalCloud::to_metres`].
    pub unit: Option<FileUnit>,
    /// Where each point was seen from (empty: the input does not say, and no free space is
    /// recorded).
    pub sensors: Sensors,
    /// Points left out as no-returns: at (within the screening's `min_range` of) their
    /// sensor origin, where lidar drivers put a beam that came back empty.
    pub no_returns: usize,
}

/// Why world coordinates make no cloud ([`LocalCloud::from_world_checked`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WorldCloudError {
    #[error("no points (the array has 0 rows)")]
    Empty,
    #[error("no finite points ({rows} rows, all with a NaN or infinite coordinate)")]
    NoFinitePoint { rows: usize },
    #[error("{axis} spans {lo:e} to {hi:e}, beyond f32 even after centring")]
    BeyondF32 {
        axis: &'static str,
        lo: f64,
        hi: f64,
    },
}

/// The centre of `points`' bounding box, `(lo + hi) / 2` per axis; 0 for no points.
pub fn bounding_box_centre(points: &[[f64; 3]]) -> [f64; 3] {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for j in 0..3 {
            lo[j] = lo[j].min(p[j]);
            hi[j] = hi[j].max(p[j]);
        }
    }
    [0, 1, 2].map(|j| {
        if points.is_empty() {
            0.0
        } else {
            0.5 * (lo[j] + hi[j])
        }
    })
}

impl LocalCloud {
    /// From world coordinates: the bounding-box centre becomes the origin.
    ///
    /// ```
    /// use mema::io::LocalCloud;
    ///
    /// let cloud = LocalCloud::from_world(&[[100.0, 0.0, 0.0], [102.0, 4.0, 1.0]]);
    /// assert_eq!(cloud.origin, [101.0, 2.0, 0.5]);
    /// assert_eq!(cloud.points[1].to_array(), [1.0, 2.0, 0.5]);
    /// ```
    pub fn from_world(points: &[[f64; 3]]) -> Self {
        Self::around(bounding_box_centre(points), points.iter(), 0)
    }

    /// The points in world coordinates: `origin + p` in f64, exactly as the readers' origin
    /// and offsets give them.
    pub fn world_points(&self) -> Vec<[f64; 3]> {
        let o = self.origin;
        self.points
            .iter()
            .map(|p| {
                let q = p.to_f64();
                [o[0] + q[0], o[1] + q[1], o[2] + q[2]]
            })
            .collect()
    }

    /// From world coordinates of outside origin (a caller's array), centred exactly as the
    /// file readers centre what they read: rows with a NaN or infinite coordinate are dropped
    /// and counted, the origin is the bounding box's centre with each bound halved before
    /// adding (no overflow near f64's limits), and a box too wide for f32 around that centre
    /// is refused rather than mapped as infinities.
    ///
    /// ```
    /// use mema::io::LocalCloud;
    ///
    /// let cloud = LocalCloud::from_world_checked(&[[1.0, 2.0, 3.0], [f64::NAN, 0.0, 0.0]])?;
    /// assert_eq!((cloud.points.len(), cloud.dropped_non_finite), (1, 1));
    /// assert!(LocalCloud::from_world_checked(&[[f64::NAN, 0.0, 0.0]]).is_err());
    /// # Ok::<(), mema::io::cloud::WorldCloudError>(())
    /// ```
    pub fn from_world_checked(points: &[[f64; 3]]) -> Result<Self, WorldCloudError> {
        let finite = |p: &&[f64; 3]| p.iter().all(|c| c.is_finite());
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut kept = 0;
        for p in points.iter().filter(finite) {
            for j in 0..3 {
                lo[j] = lo[j].min(p[j]);
                hi[j] = hi[j].max(p[j]);
            }
            kept += 1;
        }
        if kept == 0 {
            return Err(match points.len() {
                0 => WorldCloudError::Empty,
                rows => WorldCloudError::NoFinitePoint { rows },
            });
        }
        let origin: [f64; 3] = std::array::from_fn(|j| lo[j] / 2.0 + hi[j] / 2.0);
        for (axis, j) in ["x", "y", "z"].into_iter().zip(0..3) {
            if hi[j] / 2.0 - lo[j] / 2.0 > f64::from(f32::MAX) {
                return Err(WorldCloudError::BeyondF32 {
                    axis,
                    lo: lo[j],
                    hi: hi[j],
                });
            }
        }
        let dropped = points.len() - kept;
        Ok(Self::around(origin, points.iter().filter(finite), dropped))
    }

    /// Every point as f32 offsets from `origin`.
    fn around<'a>(
        origin: [f64; 3],
        points: impl Iterator<Item = &'a [f64; 3]>,
        dropped_non_finite: usize,
    ) -> Self {
        let points = points
            .map(|p| {
                Point3::new(
                    (p[0] - origin[0]) as f32,
                    (p[1] - origin[1]) as f32,
                    (p[2] - origin[2]) as f32,
                )
            })
            .collect();
        Self {
            origin,
            points,
            dropped_non_finite,
            dropped_by_class: ClassDrops::default(),
            outliers: OutlierDrops::default(),
            unit: None,
            sensors: Sensors::default(),
            no_returns: 0,
        }
    }

    /// The cloud in metres: scaled by the unit `given` (`--units`), else the one the file
    /// says, else taken as metres already. A cloud in metres is returned untouched, bit for
    /// bit. The points were cast to f32 in the file's unit, so this rounds twice; reading
    /// with [`load_cloud_in_metres`] scales before the cast. Fails for geographic coordinates (degrees) or a unit mema does not know, unless a
    /// unit is given; `name` starts the message. Call it once: the result says metres.
    ///
    /// ```
    /// use mema::io::{LengthUnit, LocalCloud};
    ///
    /// let mm = LocalCloud::from_world(&[[0.0, 0.0, 0.0], [1000.0, 2000.0, 0.0]]);
    /// let (m, units) = mm.to_metres("scan", LengthUnit::parse("mm").as_ref())?;
    /// assert_eq!(m.origin, [0.5, 1.0, 0.0]);
    /// assert_eq!(m.points[1].to_array(), [0.5, 1.0, 0.0]);
    /// assert_eq!(units.to_string(), "millimetre (--units)");
    /// # Ok::<(), anyhow::Error>(())
    /// ```
    pub fn to_metres(
        mut self,
        name: &str,
        given: Option<&LengthUnit>,
    ) -> Result<(Self, Units), super::units::UnitError> {
        let units = resolve(name, self.unit.as_ref(), given)?;
        let scale = units.unit.metres;
        if !units.unit.is_metre() {
            self.origin = self.origin.map(|c| c * scale);
            for o in &mut self.sensors.origins {
                *o = o.map(|c| c * scale);
            }
            for p in &mut self.points {
                let q = p.to_f64();
                *p = Point3::new(
                    (q[0] * scale) as f32,
                    (q[1] * scale) as f32,
                    (q[2] * scale) as f32,
                );
            }
        }
        self.unit = Some(FileUnit::Length {
            unit: LengthUnit::metre(),
            source: "scaled to metres",
        });
        Ok((self, units))
    }
}

/// Reads any cloud file the readers know (PLY, PCD, LAS/LAZ, XYZ/CSV, KITTI `.bin`; see
/// [`crate::io::read`]) into its local frame, in the file's own coordinates and unit (see
/// [`load_cloud_in_metres`] for the cloud as maps take it).
///
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/car6.pcd");
/// let cloud = mema::io::load_cloud(path.as_ref())?;
/// assert!(cloud.points.len() > 1000);
/// # Ok::<(), anyhow::Error>(())
/// ```
pub fn load_cloud(path: &Path) -> Result<LocalCloud> {
    match InputKind::of(path) {
        InputKind::Registration => Ok(load_registered_in_metres(path, None)?.0),
        InputKind::Bag => Ok(load_bag_in_metres(path, &BagOptions::default(), None)?.0),
        InputKind::StandardInput | InputKind::Cloud => Ok(local(read_cloud(path)?)),
    }
}

fn local(cloud: Cloud) -> LocalCloud {
    let n = cloud.points.len();
    LocalCloud {
        sensors: cloud
            .sensor
            .map(|s| Sensors::single(s, n))
            .unwrap_or_default(),
        no_returns: cloud.no_returns,
        origin: cloud.origin,
        points: cloud.points.into_iter().map(Point3::from).collect(),
        dropped_non_finite: cloud.dropped_non_finite,
        dropped_by_class: cloud.dropped_by_class,
        outliers: cloud.outliers,
        unit: cloud.unit,
    }
}

/// The cloud as maps take it: in metres, scaled by `given` (`--units`), else by the unit the
/// file says, else taken as metres; and the unit it was read in. The scale is applied in f64
/// before the cast to f32 (see [`crate::io::read::read_cloud_in_metres`]), so it costs no
/// precision, and a cloud in metres reads bit for bit as [`load_cloud`] reads it.
///
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/autzen_trim.laz");
/// let (cloud, units) = mema::io::load_cloud_in_metres(path.as_ref(), None)?;
/// assert_eq!(units.to_string(), "foot (LAS GeoKeys)");
/// assert!(cloud.origin[0] > 0.3 * 637_000.0 && cloud.origin[0] < 0.31 * 637_000.0);
/// # Ok::<(), anyhow::Error>(())
/// ```
pub fn load_cloud_in_metres(
    path: &Path,
    given: Option<&LengthUnit>,
) -> Result<(LocalCloud, Units)> {
    load_input_in_metres(path, given, &BagOptions::default())
}

/// [`load_cloud_in_metres`] with the topic and frame of a ROS 2 bag (see
/// [`crate::io::bag`]); `bag` is ignored for every other input.
pub fn load_input_in_metres(
    path: &Path,
    given: Option<&LengthUnit>,
    bag: &BagOptions,
) -> Result<(LocalCloud, Units)> {
    load_input_keeping(path, given, bag, Screening::default())
}

/// [`load_input_in_metres`] leaving out what `screening` says: points of a classified file
/// (LAS/LAZ) by class, isolated points ([`Screening`]). A registration file's scans and a bag's
/// messages are each screened on their own, in their own frame, as the file of that one scan
/// would be; the counts are their sums.
pub fn load_input_keeping(
    path: &Path,
    given: Option<&LengthUnit>,
    bag: &BagOptions,
    screening: Screening,
) -> Result<(LocalCloud, Units)> {
    match InputKind::of(path) {
        // Several registered scans (a `.conf`): all of them, in their common frame.
        InputKind::Registration => load_registered_keeping(path, given, screening),
        InputKind::Bag => load_bag_keeping(path, bag, given, screening),
        InputKind::StandardInput | InputKind::Cloud => {
            load_cloud_file_keeping(path, given, screening)
        }
    }
}

/// One cloud file (or standard input) in metres, as [`load_cloud_in_metres`] takes it, for
/// callers that have already asked [`InputKind::of`] what their input is.
pub fn load_cloud_file_in_metres(
    path: &Path,
    given: Option<&LengthUnit>,
) -> Result<(LocalCloud, Units)> {
    load_cloud_file_keeping(path, given, Screening::default())
}

/// [`load_cloud_file_in_metres`] leaving out what `screening` says.
pub fn load_cloud_file_keeping(
    path: &Path,
    given: Option<&LengthUnit>,
    screening: Screening,
) -> Result<(LocalCloud, Units)> {
    let mut cloud = read_cloud_in_metres_keeping(path, given, screening)?;
    let units = cloud.units.take().unwrap_or_else(Units::assumed);
    let mut cloud = local(cloud);
    cloud.unit = Some(FileUnit::Length {
        unit: LengthUnit::metre(),
        source: "scaled to metres",
    });
    Ok((cloud, units))
}

/// A scan read in metres: its pose (translation in metres) and its points in the scanner's
/// frame.
#[derive(Clone, Debug)]
pub struct ScanInMetres {
    pub scan: RegisteredScan,
    pub points: Vec<[f64; 3]>,
    /// Where the sensor was in the scan's frame: the file's own (a PCD's VIEWPOINT), else the
    /// frame's origin, which the pose's translation puts in the world.
    pub sensor: [f64; 3],
}

/// What the reads of a registration file's scans left out, summed over its scans, so that the
/// points kept and these add up to the scans' slots.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ScanDrops {
    /// Slots with a NaN or infinite coordinate (an organized scan's empty returns).
    pub non_finite: usize,
    pub by_class: ClassDrops,
    /// Isolated points; the worst is placed in the common frame.
    pub outliers: OutlierDrops,
    /// No-returns: points at their scan's sensor origin.
    pub no_returns: usize,
}

/// Every scan of registration file `path`, read in metres (scaled by `given`, else by the unit
/// each file says, else taken as metres; the translations by the same unit), and the units of
/// the first scan.
pub fn read_scans_in_metres(
    path: &Path,
    given: Option<&LengthUnit>,
) -> Result<(Vec<ScanInMetres>, Units)> {
    let (scans, units, _) = read_scans_keeping(path, given, Screening::DEFAULT)?;
    Ok((scans, units))
}

/// [`read_scans_in_metres`] leaving out of each scan what `screening` says, as a read of that
/// scan's file alone would, and what was left out.
pub fn read_scans_keeping(
    path: &Path,
    given: Option<&LengthUnit>,
    screening: Screening,
) -> Result<(Vec<ScanInMetres>, Units, ScanDrops)> {
    let mut drops = ScanDrops::default();
    let mut out = Vec::new();
    let mut first_units = None;
    for scan in read_registration(path)? {
        match InputKind::of(&scan.path) {
            InputKind::Registration => bail!(
                "{}: a registration file names another, {}",
                path.display(),
                scan.path.display()
            ),
            InputKind::Bag => bail!(
                "{}: a scan is a cloud file, and {} is a ROS 2 bag",
                path.display(),
                scan.path.display()
            ),
            InputKind::StandardInput | InputKind::Cloud => {}
        }
        let (cloud, units) = load_cloud_file_keeping(&scan.path, given, screening)
            .with_context(|| format!("{}: scan {}", path.display(), scan.path.display()))?;
        let scale = units.unit.metres;
        let mut points = cloud.world_points();
        // A file that says where its sensor was has had its no-returns left out by the read;
        // any other scan was taken from its frame's origin, the pose's translation.
        let sensor = match cloud.sensors.origins.first() {
            Some(&s) => s,
            None => {
                drops.no_returns += drop_no_returns(&mut points, [0.0; 3], screening.min_range);
                [0.0; 3]
            }
        };
        drops.no_returns += cloud.no_returns;
        let scan = RegisteredScan {
            translation: scan.translation.map(|v| v * scale),
            ..scan
        };
        drops.non_finite += cloud.dropped_non_finite;
        drops.by_class.add(cloud.dropped_by_class);
        drops.outliers.add(cloud.outliers, |p| scan.to_world(p));
        out.push(ScanInMetres {
            scan,
            points,
            sensor,
        });
        first_units.get_or_insert(units);
    }
    Ok((out, first_units.unwrap_or_else(Units::assumed), drops))
}

/// All scans of registration file `path` in the common frame, in metres, as one cloud.
pub fn load_registered_in_metres(
    path: &Path,
    given: Option<&LengthUnit>,
) -> Result<(LocalCloud, Units)> {
    load_registered_keeping(path, given, Screening::DEFAULT)
}

/// [`load_registered_in_metres`] leaving out of each scan what `screening` says; the cloud
/// counts what every scan's read left out.
pub fn load_registered_keeping(
    path: &Path,
    given: Option<&LengthUnit>,
    screening: Screening,
) -> Result<(LocalCloud, Units)> {
    let (scans, units, drops) = read_scans_keeping(path, given, screening)?;
    let world: Vec<[f64; 3]> = scans
        .iter()
        .flat_map(|s| s.points.iter().map(|p| s.scan.to_world(*p)))
        .collect();
    let mut cloud = LocalCloud::from_world(&world);
    for s in &scans {
        cloud
            .sensors
            .push_run(s.scan.to_world(s.sensor), s.points.len());
    }
    cloud.no_returns = drops.no_returns;
    cloud.dropped_non_finite = drops.non_finite;
    cloud.dropped_by_class = drops.by_class;
    cloud.outliers = drops.outliers;
    cloud.unit = Some(FileUnit::Length {
        unit: LengthUnit::metre(),
        source: "scaled to metres",
    });
    Ok((cloud, units))
}

/// The PointCloud2 messages of a ROS 2 bag as one cloud in metres: each message's points in
/// `options.frame` (or as they are without one), gathered and centred exactly as
/// [`load_registered_in_metres`] gathers a registration file's scans, so a bag of those scans
/// with their poses on `/tf` gives the same cloud, bit for bit.
///
/// ```no_run
/// use mema::io::bag::BagOptions;
///
/// let options = BagOptions { topic: Some("/points".into()), frame: Some("world".into()) };
/// let (cloud, _) = mema::io::cloud::load_bag_in_metres("scans.mcap".as_ref(), &options, None)?;
/// println!("{} points around {:?}", cloud.points.len(), cloud.origin);
/// # Ok::<(), anyhow::Error>(())
/// ```
pub fn load_bag_in_metres(
    path: &Path,
    options: &BagOptions,
    given: Option<&LengthUnit>,
) -> Result<(LocalCloud, Units)> {
    load_bag_keeping(path, options, given, Screening::DEFAULT)
}

/// [`load_bag_in_metres`] leaving out of each message what `screening` says (see
/// [`crate::io::bag::read_bag_keeping`]).
pub fn load_bag_keeping(
    path: &Path,
    options: &BagOptions,
    given: Option<&LengthUnit>,
    screening: Screening,
) -> Result<(LocalCloud, Units)> {
    let bag = read_bag_keeping(path, options, given, screening)?;
    let world: Vec<[f64; 3]> = bag.scans.iter().flat_map(|s| s.world_points()).collect();
    let mut cloud = LocalCloud::from_world(&world);
    for s in &bag.scans {
        // Each message is in its sensor's frame: the pose takes that frame's origin to the world.
        cloud.sensors.push_run(s.pose.translation, s.points.len());
    }
    cloud.no_returns = usize::try_from(bag.no_returns).unwrap_or(usize::MAX);
    cloud.dropped_non_finite = usize::try_from(bag.dropped_non_finite).unwrap_or(usize::MAX);
    cloud.outliers = bag.outliers;
    cloud.unit = Some(FileUnit::Length {
        unit: LengthUnit::metre(),
        source: "scaled to metres",
    });
    Ok((cloud, bag.units))
}
