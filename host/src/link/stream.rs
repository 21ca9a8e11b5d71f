//! Bytes in, map out: the decoder and the streaming mapper, exactly as the firmware runs them.

use anyhow::Result;
use mema_core::Point3;
use mema_core::fit::FitParams;
use mema_core::link::receiver::{Receiver, ReceiverStats};
use mema_core::link::wire::DecoderStats;
use mema_core::stream::{
    MAX_SUMMARY, Pacing, StreamMapper, StreamModel, StreamParams, summary_layout,
};

use super::carving::Carving;
use super::frames::{dequantise, quantise};
use super::lag::ScanLag;
use super::scanner::{SensorScan, SentScans, quantise_scans, send_scans};
use crate::error::ConfigError;
use crate::io::cloud::LocalCloud;
use crate::io::mapfile::HostMap;
use crate::mapping::options::{Model, PipelineConfig};

/// The host's capacity: `-k` may be at most this.
pub const MAX_CLUSTERS: usize = 2048;
/// Buckets of the centre hash: twice the capacity keeps chains short.
pub const GRID_BUCKETS: usize = 4096;
/// One cluster refit (about 600 fitness evaluations, ~0.1 ms) per this many points.
pub const REFIT_INTERVAL: u32 = 1024;

/// Working clusters: with every entity in working memory the stream keeps a finer summary
/// until its end ([`summary_layout`]); 2.4 MB of clusters, built on a thread of its own
/// ([`new_mapper_with`]).
pub const MAX_WORKING: usize = MAX_SUMMARY;

/// Working clusters and frozen entities share the host's bound: k <= `MAX_CLUSTERS` in all; the
/// working set may hold up to [`MAX_WORKING`] clusters until the end merges them down to k.
pub type HostStreamMapper = StreamMapper<MAX_WORKING, { 2 * MAX_WORKING }, MAX_CLUSTERS>;

/// How a stream holds its k ellipsoids: all in working memory (merging when full), or `working`
/// of them there and the rest frozen once the scan has left them (`--working`), as a small
/// device must (README, "Streaming").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capacity {
    pub k: usize,
    pub working: usize,
}

impl Capacity {
    /// All k clusters in working memory.
    pub fn all_working(k: usize) -> Self {
        Self { k, working: k }
    }

    /// k within the host mapper's fixed capacity ([`MAX_CLUSTERS`]), and `working` (all k when
    /// `None`) within k; frozen clusters cannot merge, so they do not combine with the
    /// tolerance mode.
    pub fn checked(k: usize, working: Option<usize>, tolerance: bool) -> Result<Self, ConfigError> {
        if k > MAX_CLUSTERS {
            return Err(ConfigError::StreamCapacity {
                k,
                max: MAX_CLUSTERS,
            });
        }
        let Some(working) = working else {
            return Ok(Self::all_working(k));
        };
        if working == 0 || working > k {
            return Err(ConfigError::Working { working, k });
        }
        if tolerance && working < k {
            // Tolerance mode decides k by merging, and a frozen cluster can no longer merge.
            return Err(ConfigError::WorkingWithTolerance);
        }
        Ok(Self { k, working })
    }
}

/// A boxed mapper of the paper's model: at 2,048 clusters it is too large for a test thread's
/// stack. `tolerance` > 0 turns on the tolerance mode (k follows from it, `k` is the capacity).
pub fn new_mapper(
    capacity: Capacity,
    seed: u64,
    fit: FitParams,
    tolerance: f64,
) -> Box<HostStreamMapper> {
    new_mapper_with(stream_params(
        capacity,
        seed,
        fit,
        tolerance,
        StreamModel::Paper,
    ))
}

/// The parameters `stream`, `replay` and `stream-bench` map with.
pub fn stream_params(
    capacity: Capacity,
    seed: u64,
    fit: FitParams,
    tolerance: f64,
    model: StreamModel,
) -> StreamParams {
    // Every entity in working memory, and no tolerance to merge by: the finer summary, merged
    // down to k at the end, as the firmware's parameters have it. The tolerance mode merges by
    // its own rule.
    let frozen = capacity.k.saturating_sub(capacity.working);
    let (max_clusters, final_clusters) = if tolerance > 0.0 {
        (capacity.working, 0)
    } else {
        summary_layout(capacity.k, frozen)
    };
    StreamParams {
        fit,
        seed,
        max_clusters,
        max_frozen: frozen,
        final_clusters,
        refit_interval: REFIT_INTERVAL,
        tolerance,
        model,
        // The device's pacing, so a replay is the device's map; the tolerance mode (host only)
        // merges to keep its promise, unpaced.
        pacing: if tolerance > 0.0 {
            Pacing::NONE
        } else {
            Pacing::device(&model)
        },
    }
}

/// A batch [`Model`] as the stream's: shells at the defaults and `fit`'s sphere tolerance, as
/// `mema map` makes them.
pub fn stream_model(model: Model, fit: &FitParams) -> StreamModel {
    match model {
        Model::Paper => StreamModel::Paper,
        Model::Shells => StreamModel::shells(fit.degeneration.sphere_tolerance),
    }
}

/// The mapper's parameters for a batch configuration (`mema stream`, `replay` and
/// `stream-bench`): a `tolerance` turns on the tolerance mode.
pub fn link_params(
    config: &PipelineConfig,
    capacity: Capacity,
    tolerance: Option<f64>,
    model: Model,
) -> StreamParams {
    stream_params(
        capacity,
        config.seed,
        config.fit,
        tolerance.unwrap_or(0.0),
        stream_model(model, &config.fit),
    )
}

/// The mapper's map as its file stores it: the paper's fits in f32 (version 1), shells on the
/// quantized grid (the entities already on it, so the map in memory is its file read back)
/// around the file's origin; `origin` is the receiver's (the mapper's points are relative to
/// it).
pub fn map_of(mapper: &HostStreamMapper, origin: [f64; 3]) -> HostMap {
    let layout = mapper.layout();
    HostMap {
        origin: mapper.file_origin(origin, layout),
        entities: mapper.stored_entities(layout).collect(),
        quantization: match layout {
            mema_core::map::Layout::Quantized(grid) => Some(grid),
            _ => None,
        },
        // A carving link adds its scans' ([`Link::carving`]).
        free_space: Vec::new(),
    }
}

/// A boxed mapper with every parameter chosen by the caller (tolerance mode, say).
pub fn new_mapper_with(params: StreamParams) -> Box<HostStreamMapper> {
    // Built on a thread with a large stack, then moved into the box by pointer: the mapper is
    // 2.6 MB, more than a test's or a worker's thread has. Neither the building nor the
    // fallback is inlined here, or this frame would reserve the mapper's size on the caller's
    // stack even when the thread builds it.
    std::thread::Builder::new()
        .stack_size(64 << 20)
        .spawn(move || build_mapper(params))
        .ok()
        .and_then(|h| h.join().ok())
        .unwrap_or_else(|| build_mapper(params))
}

#[inline(never)]
fn build_mapper(params: StreamParams) -> Box<HostStreamMapper> {
    Box::new(HostStreamMapper::new(params))
}

/// Receiver + mapper, fed with whatever chunks of bytes arrive.
///
/// A cloud sent as a rangefinder sends it, in chunks of any size, becomes a map:
///
/// ```
/// use mema::link::frames::{encode_stream, quantise};
/// use mema::link::stream::{Capacity, Link};
/// use mema_core::Point3;
///
/// // A 40 x 40 grid of points on a plane, 5 cm apart, as wire millimetres.
/// let wire: Vec<[i32; 3]> = (0..1_600)
///     .map(|i| quantise(Point3::new((i % 40) as f32 * 0.05, (i / 40) as f32 * 0.05, 0.0)))
///     .collect::<anyhow::Result<_>>()?;
/// let bytes = encode_stream(&wire)?;
/// let mut link = Link::new(Capacity::all_working(16), 0, Default::default(), 0.0);
/// for chunk in bytes.chunks(7) {
///     link.feed(chunk);
/// }
/// assert!(link.end_of_stream());
/// assert_eq!(link.stats().rejected, 0);
/// let map = link.finish();
/// assert!(!map.entities.is_empty() && map.entities.len() <= 16);
/// # Ok::<(), anyhow::Error>(())
/// ```
pub struct Link {
    pub receiver: Receiver,
    pub mapper: Box<HostStreamMapper>,
    /// Carving, when on ([`Link::carving`]): each scan's image judges the clusters it saw
    /// through, and is kept as the map's free space.
    pub carving: Option<Carving>,
    /// With free space kept ([`Link::carving`]): the scans held until later ones have judged
    /// their points.
    pub lag: Option<ScanLag>,
}

impl Link {
    /// A link of the paper's model.
    pub fn new(capacity: Capacity, seed: u64, fit: FitParams, tolerance: f64) -> Self {
        Self::with_params(stream_params(
            capacity,
            seed,
            fit,
            tolerance,
            StreamModel::Paper,
        ))
    }

    /// A link whose mapper has every parameter chosen by the caller.
    pub fn with_params(params: StreamParams) -> Self {
        Self {
            receiver: Receiver::new(),
            mapper: new_mapper_with(params),
            carving: None,
            lag: None,
        }
    }

    /// The link carving what later scans see through ([`mema_core::stream::carve`]): scans
    /// are the runs of points frames from one sensor origin.
    pub fn carving(self) -> Self {
        self.carving_with(super::carving::CARVE_IMAGE, 1, true)
    }

    /// [`Link::carving`] as a device carves: whole-sphere images of `[rows, columns]` pixels
    /// taking every `every`-th return of a scan (the STM32F405 board's
    /// `mema_firmware::BOARD_CARVE_IMAGE` and `BOARD_CARVE_EVERY`), keeping each scan's image
    /// as the map's free space if `keep_free_space`. Images of more pixels than
    /// [`super::carving::CARVE_IMAGE`] carve nothing.
    pub fn carving_with(mut self, image: [u16; 2], every: u16, keep_free_space: bool) -> Self {
        self.carving = Carving::new(image, every, keep_free_space);
        // A map that keeps free space is the host's own: its points are carved as `mema map`
        // carves them, each scan held until later ones have looked (a device's is not).
        self.lag = keep_free_space.then(ScanLag::new);
        self
    }

    /// The link refusing points and poses farther than `reach` metres from the map's origin on
    /// any axis ([`mema_core::link::receiver::DEFAULT_REACH`] by default).
    pub fn with_reach(mut self, reach: f32) -> Self {
        self.receiver = Receiver::reaching(reach);
        self
    }

    /// Feeds one chunk; the points of its frames go straight into the mapper, through their
    /// pose into the world (frames after the end of stream are only counted, so any chunking
    /// gives the same map).
    pub fn feed(&mut self, chunk: &[u8]) {
        let link = std::cell::RefCell::new((&mut self.mapper, &mut self.carving, &mut self.lag));
        self.receiver.feed_all(
            chunk,
            |frame, placement| {
                let (mapper, carving, lag) = &mut *link.borrow_mut();
                mapper.note_resolution(frame.unit_scale() as f32);
                let sensor = placement.place([0, 0, 0]);
                match lag {
                    Some(lag) => {
                        let mut send = |sensor, p, seen_through| {
                            take_point(mapper, carving, sensor, p, seen_through)
                        };
                        for p in placement.points(&frame) {
                            lag.push(sensor, p, &mut send);
                        }
                    }
                    None => {
                        for p in placement.points(&frame) {
                            take_point(mapper, carving, sensor, p, false);
                        }
                    }
                }
            },
            || {
                let (mapper, carver, lag) = &mut *link.borrow_mut();
                mapper.restart();
                if let Some(carver) = carver {
                    carver.restart();
                }
                if let Some(lag) = lag {
                    lag.restart();
                }
            },
        );
    }

    /// Whether the end-of-stream frame has arrived.
    pub fn end_of_stream(&self) -> bool {
        self.receiver.ended()
    }

    /// The decoder's counts: frames accepted, rejected (by reason), lost, repeated, sessions,
    /// bytes.
    pub fn stats(&self) -> &DecoderStats {
        self.receiver.decoder_stats()
    }

    /// The receiver's counts: frames after the end, poses, points frames without their pose.
    pub fn receiver_stats(&self) -> &ReceiverStats {
        self.receiver.stats()
    }

    /// The map so far: stale clusters refitted first (a snapshot).
    pub fn snapshot(&mut self) -> HostMap {
        self.mapper.refit_stale();
        self.map()
    }

    /// The final map: every cluster refitted from its final moments.
    pub fn finish(&mut self) -> HostMap {
        if let Some(lag) = &mut self.lag {
            let (mapper, carving) = (&mut self.mapper, &mut self.carving);
            lag.finish(&mut |sensor, p, seen_through| {
                take_point(mapper, carving, sensor, p, seen_through)
            });
        }
        if let Some(carving) = &mut self.carving {
            carving.end_scan(&mut self.mapper);
        }
        self.mapper.finish();
        self.map()
    }

    fn map(&self) -> HostMap {
        let origin = self.receiver.origin();
        let mut map = map_of(&self.mapper, origin);
        if let Some(carving) = &self.carving {
            map.free_space = carving.images_at(origin, map.origin);
        }
        map
    }
}

/// A point of a scan seen from `sensor` into the mapper, unless later scans saw through it, and
/// into the carving's image of that scan (a new scan if `sensor` is not the current one's).
fn take_point(
    mapper: &mut HostStreamMapper,
    carving: &mut Option<Carving>,
    sensor: Point3,
    p: Point3,
    seen_through: bool,
) {
    if let Some(carving) = carving {
        carving.sensor_at(sensor, mapper);
    }
    if !seen_through {
        mapper.add(p);
    }
    if let Some(carving) = carving {
        carving.add_return(p);
    }
}

/// The direct path the tests compare a version 1 link against: the same points, quantised to
/// millimetres as a version 1 capture carries them, straight into the mapper as
/// `(v * 10^-3) as f32` (the paper's model).
pub fn map_points_directly(
    cloud: &LocalCloud,
    capacity: Capacity,
    seed: u64,
    fit: FitParams,
) -> Result<HostMap> {
    let params = stream_params(capacity, seed, fit, 0.0, StreamModel::Paper);
    map_points_directly_with(cloud, params)
}

/// [`map_points_directly`] with every parameter chosen (the model, say).
pub fn map_points_directly_with(cloud: &LocalCloud, params: StreamParams) -> Result<HostMap> {
    let wire: Vec<[i32; 3]> = cloud
        .points
        .iter()
        .map(|p| quantise(*p))
        .collect::<Result<_>>()?;
    let mut mapper = new_mapper_with(params);
    // The receiver's origin is the first point; the others reach the mapper as whole
    // millimetres from it.
    let first = wire.first().copied().unwrap_or([0; 3]);
    for q in &wire {
        mapper.add(dequantise([0, 1, 2].map(|j| q[j] - first[j])));
    }
    mapper.finish();
    let origin = first.map(|v| i64::from(v) * 1_000_000);
    Ok(map_of(
        &mapper,
        mema_core::link::receiver::metres_of_nm(origin),
    ))
}

/// The direct path the tests compare `scanner-sim` into `stream` against: the integers
/// scanner-sim sends of `cloud` (its unit, its sensor at the cloud's centre in whole metres),
/// taken to the map's frame here in whole nanometres, `v 10^e + t - origin` with the origin the
/// first point, and fed to the mapper as the nearest f32 to that many units: no bytes, frames
/// or receiver.
pub fn map_sent_directly_with(cloud: &LocalCloud, params: StreamParams) -> Result<HostMap> {
    let wire = quantise_scans(&[SensorScan::of_cloud(cloud)?])?;
    let unit = |e: i8| mema_core::link::wire::unit_scale(e).unwrap_or(f64::NAN);
    let nm = |e: i8| 10i64.pow(u32::try_from(i16::from(e) + 9).unwrap_or(0));
    let (s, per_unit, per_pose_unit) = (
        unit(wire.unit_exponent),
        nm(wire.unit_exponent),
        nm(wire.pose_exponent),
    );
    let mut mapper = new_mapper_with(params);
    let mut origin: Option<[i64; 3]> = None;
    for scan in &wire.scans {
        anyhow::ensure!(
            scan.pose.rotation[..3] == [0, 0, 0],
            "a cloud is sent unturned"
        );
        let t = scan.pose.translation.map(|v| v * per_pose_unit);
        for p in &scan.points {
            let w = [0, 1, 2].map(|j| i64::from(p[j]) * per_unit + t[j]);
            let o = *origin.get_or_insert(w);
            let local = |j: usize| ((w[j] - o[j]) / per_unit) as f64 * s;
            mapper.add(mema_core::Point3::new(
                local(0) as f32,
                local(1) as f32,
                local(2) as f32,
            ));
        }
    }
    mapper.finish();
    let origin = mema_core::link::receiver::metres_of_nm(origin.unwrap_or([0; 3]));
    Ok(map_of(&mapper, origin))
}

/// `scans` sent as `mema scanner-sim` sends them and received as `mema stream` receives them
/// (carving with `carve`, as `--free-space` asks), in one process: the bytes sent, and the link
/// after them (its counts and its finished map).
pub fn stream_scans(
    scans: &[SensorScan],
    params: StreamParams,
    carve: bool,
) -> Result<(SentScans, Link, HostMap)> {
    let sent = send_scans(scans)?;
    let link = Link::with_params(params);
    let mut link = if carve { link.carving() } else { link };
    link.feed(&sent.bytes);
    let map = link.finish();
    Ok((sent, link, map))
}
