//! `mema stream` and `replay`: the link from wire to map file (`record` and `scanner-sim`, the
//! capture's two ends, are in [`super::capture`]).

use anyhow::{Context, Result, bail};
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use mema::io::kind::InputKind;
use mema::io::output::check_map_output;
use mema::link::capture::CaptureWriter;
use mema::link::port::{ReadOutcome, open_for_reading, read_some};
use mema::link::scanner::{scans_of_input, send_scans};
use mema::link::stream::{Capacity, Link, link_params};
use mema_core::link::wire::DecoderStats;
use mema_core::stream::StreamParams;

use crate::cli::args::{ReplayArgs, StreamArgs, StreamShapeArgs};
use crate::cli::errors::{LinkIdle, LinkLost, UsageError};

/// `-k` within the host mapper's fixed capacity, and `--working` within `-k`.
pub fn capacity(k: usize, shape: &StreamShapeArgs) -> Result<Capacity, mema::ConfigError> {
    Capacity::checked(k, shape.working, shape.tolerance.is_some())
}

/// The mapper's parameters from the command line.
fn params(
    config: &mema::mapping::PipelineConfig,
    capacity: Capacity,
    shape: &StreamShapeArgs,
) -> StreamParams {
    link_params(config, capacity, shape.tolerance, shape.model.into())
}

/// The link `stream` and `replay` map through, with the shape's model and reach.
fn new_link(
    config: &mema::mapping::PipelineConfig,
    capacity: Capacity,
    shape: &StreamShapeArgs,
) -> Result<Link> {
    if !(shape.reach > 0.0 && shape.reach.is_finite()) {
        return Err(UsageError(format!(
            "--reach {} must be a positive number of metres",
            shape.reach
        ))
        .into());
    }
    let link = Link::with_params(params(config, capacity, shape)).with_reach(shape.reach);
    let image = shape.carve.unwrap_or(mema::link::carving::CARVE_IMAGE);
    Ok(if shape.free_space || shape.carve.is_some() {
        link.carving_with(image, shape.carve_every, shape.free_space)
    } else {
        link
    })
}

/// How often `stream` reports progress on stderr.
const PROGRESS_EVERY: Duration = Duration::from_secs(5);

/// Set by Ctrl-C, SIGTERM or SIGHUP (ctrlc's `termination` feature); every loop polls it
/// between reads, so a service manager's stop or a closed terminal writes the map as Ctrl-C does.
pub(super) fn interrupted() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    let handler_flag = flag.clone();
    // Only the first command in a process can install it; later calls keep the first flag's
    // meaning (a process runs one command).
    let _ = ctrlc::set_handler(move || handler_flag.store(true, Ordering::SeqCst));
    flag
}

/// Frames refused, by reason (they add up to `frames_rejected`).
#[derive(Serialize)]
pub struct Rejections {
    pub bad_crc: u64,
    pub bad_cobs: u64,
    pub bad_length: u64,
    /// An unknown version, or reserved bits set.
    pub bad_version: u64,
    pub oversized: u64,
    /// A unit exponent outside the range PROTOCOL.md gives.
    pub bad_unit: u64,
    /// A pose frame numbered 0, with points, or whose quaternion is not a unit one.
    pub bad_pose: u64,
}

impl Rejections {
    fn of(s: &DecoderStats) -> Self {
        Self {
            bad_crc: s.bad_crc,
            bad_cobs: s.bad_cobs,
            bad_length: s.bad_length,
            bad_version: s.bad_version,
            oversized: s.oversized,
            bad_unit: s.bad_unit,
            bad_pose: s.bad_pose,
        }
    }

    /// The non-zero reasons, for the summary line: " (2 bad CRC, 1 bad unit)", or nothing.
    fn text(&self) -> String {
        let reasons: Vec<String> = [
            (self.bad_crc, "bad CRC"),
            (self.bad_cobs, "bad COBS"),
            (self.bad_length, "bad length"),
            (self.bad_version, "bad version"),
            (self.oversized, "oversized"),
            (self.bad_unit, "bad unit"),
            (self.bad_pose, "bad pose"),
        ]
        .iter()
        .filter(|(n, _)| *n > 0)
        .map(|(n, what)| format!("{n} {what}"))
        .collect();
        if reasons.is_empty() {
            String::new()
        } else {
            format!(" ({})", reasons.join(", "))
        }
    }
}

#[derive(Serialize)]
pub struct StreamSummary {
    pub map: String,
    pub end: String,
    pub points: u64,
    pub frames_accepted: u64,
    pub frames_rejected: u64,
    pub rejected: Rejections,
    pub frames_lost: u64,
    pub frames_duplicated: u64,
    /// Valid frames after the end-of-stream frame: counted, not mapped.
    pub frames_after_end: u64,
    /// Sessions the sender began (more than 1: it started again mid-stream).
    pub sessions: u64,
    /// Pose frames received.
    pub poses: u64,
    /// Points frames not mapped: the pose they name never arrived.
    pub frames_without_pose: u64,
    /// Points not mapped: farther than `--reach` from the map's origin, or past the world's
    /// range.
    pub points_out_of_reach: u64,
    /// Points not mapped: no-returns, at the sensor itself (a beam that returned nothing).
    pub no_returns: u64,
    /// Pose frames refused: their pose out of reach.
    pub poses_out_of_reach: u64,
    /// Times the map started again because later poses outvoted the first (a glitch as the
    /// first pose): what was mapped before is not in the map.
    pub origin_restarts: u64,
    /// The receiver's origin (metres in the world): the first point it mapped, exactly. (A
    /// quantized map file's origin is the centre of its entities, around this.)
    pub origin: [f64; 3],
    pub bytes: u64,
    pub ellipsoids: usize,
    /// From the start of listening (or replaying) to the end.
    pub elapsed_s: f64,
    /// From the first point's arrival to the last's: the time the points took to arrive.
    pub arrival_s: f64,
    /// Points over `arrival_s`: the rate the link delivered while it delivered, not diluted
    /// by the wait for the scanner to start (0 when every point came in one read).
    pub points_per_s: f64,
    /// Points that joined their nearest cluster beyond the join radius because the device's
    /// pacing could not pay for room (docs/firmware.md, "Longest tick, the link and pacing"): where the map is coarser than the
    /// points asked for.
    pub paced_joins: u64,
    /// Points the pacing could not pay room for, with no cluster within
    /// [`mema_core::stream::PACED_REACH`] join radii:
    /// left out of the map (a single far point would thicken its cluster's shell), their rays
    /// still carved.
    pub paced_shed: u64,
    /// Pairs of frozen entities merged to make room (a device's layout).
    pub coarsened: u64,
    /// Clusters carved with `--free-space`: later scans saw through them.
    pub carved: u64,
    /// Working clusters merged at the finish because they were finer than the coarsened
    /// store (a device's layout): why such a map holds fewer entities than `-k`.
    pub balanced: u64,
    /// Frozen entities taken back into working memory by points that came back to them (a
    /// device's layout, shells).
    pub thawed: u64,
}

/// When the mapper's points first and last grew: the window a rate is measured over.
#[derive(Default)]
struct Arrivals {
    seen: u64,
    first: Option<Instant>,
    last: Option<Instant>,
}

impl Arrivals {
    /// Notes the mapper's point count after a read; a count that grew is an arrival now.
    fn note(&mut self, points: u64) {
        if points > self.seen {
            let now = Instant::now();
            self.first.get_or_insert(now);
            self.last = Some(now);
            self.seen = points;
        }
    }

    fn seconds(&self) -> f64 {
        match (self.first, self.last) {
            (Some(first), Some(last)) => last.duration_since(first).as_secs_f64(),
            _ => 0.0,
        }
    }
}

fn summary(
    link: &Link,
    map: &Path,
    end: &str,
    ellipsoids: usize,
    started: Instant,
    arrivals: &Arrivals,
) -> StreamSummary {
    let s = link.stats();
    let elapsed = started.elapsed().as_secs_f64();
    let arrival = arrivals.seconds();
    let points = link.mapper.stats().points;
    StreamSummary {
        map: map.display().to_string(),
        end: end.into(),
        points,
        frames_accepted: s.accepted,
        frames_rejected: s.rejected,
        rejected: Rejections::of(s),
        frames_lost: s.lost,
        frames_duplicated: s.duplicates,
        frames_after_end: link.receiver_stats().after_end,
        sessions: s.sessions,
        poses: link.receiver_stats().poses,
        frames_without_pose: link.receiver_stats().no_pose,
        points_out_of_reach: link.receiver_stats().points_out_of_reach,
        no_returns: link.receiver_stats().no_returns,
        poses_out_of_reach: link.receiver_stats().poses_out_of_reach,
        origin_restarts: link.receiver_stats().restarts,
        origin: link.receiver.origin(),
        bytes: s.bytes,
        ellipsoids,
        elapsed_s: elapsed,
        arrival_s: arrival,
        points_per_s: if arrival > 0.0 {
            points as f64 / arrival
        } else {
            0.0
        },
        paced_joins: link.mapper.stats().paced_joins,
        paced_shed: link.mapper.stats().paced_shed,
        coarsened: link.mapper.stats().coarsened,
        carved: link.mapper.stats().carved,
        balanced: link.mapper.stats().balanced,
        thawed: link.mapper.stats().thawed,
    }
}

fn report(s: &StreamSummary, json: bool) -> Result<()> {
    let mut extra = String::new();
    if s.frames_after_end > 0 {
        extra.push_str(&format!(
            ", {} after the end (not mapped)",
            s.frames_after_end
        ));
    }
    if s.sessions > 1 {
        extra.push_str(&format!(", {} sessions", s.sessions));
    }
    if s.poses > 0 {
        let plural = if s.poses == 1 { "" } else { "s" };
        extra.push_str(&format!(", {} pose{plural}", s.poses));
    }
    if s.paced_joins > 0 {
        extra.push_str(&format!(
            ", {} points joined beyond the radius (paced)",
            s.paced_joins
        ));
    }
    if s.paced_shed > 0 {
        extra.push_str(&format!(
            ", {} shed (paced, no cluster within {} radii)",
            s.paced_shed,
            mema_core::stream::PACED_REACH
        ));
    }
    if s.coarsened > 0 {
        extra.push_str(&format!(", {} merges of frozen entities", s.coarsened));
    }
    if s.thawed > 0 {
        extra.push_str(&format!(
            ", {} frozen entities thawed (points came back to them)",
            s.thawed
        ));
    }
    if s.balanced > 0 {
        extra.push_str(&format!(
            ", {} merged at the end (working clusters finer than the store)",
            s.balanced
        ));
    }
    if s.carved > 0 {
        extra.push_str(&format!(
            ", {} clusters carved (seen through by two later scans)",
            s.carved
        ));
    }
    if s.frames_without_pose > 0 {
        extra.push_str(&format!(
            ", {} without their pose (not mapped)",
            s.frames_without_pose
        ));
    }
    if s.points_out_of_reach > 0 {
        extra.push_str(&format!(
            ", {} points out of reach (not mapped)",
            s.points_out_of_reach
        ));
    }
    if s.no_returns > 0 {
        extra.push_str(&format!(
            ", {} no-returns at the sensor (not mapped)",
            s.no_returns
        ));
    }
    if s.poses_out_of_reach > 0 {
        let plural = if s.poses_out_of_reach == 1 { "" } else { "s" };
        extra.push_str(&format!(
            ", {} pose{plural} out of reach (refused)",
            s.poses_out_of_reach
        ));
    }
    if s.origin_restarts > 0 {
        extra.push_str(&format!(
            ", started again {} time{} (the first poses were outvoted by later ones far from them; what they placed is not mapped)",
            s.origin_restarts,
            if s.origin_restarts == 1 { "" } else { "s" }
        ));
    }
    eprintln!(
        "mema: {}: {} points, frames {} accepted / {} rejected{} / {} lost / {} repeated{extra}, {} ellipsoids, {:.2} s, {:.0} points/s over the {:.2} s they took to arrive",
        s.end,
        s.points,
        s.frames_accepted,
        s.frames_rejected,
        s.rejected.text(),
        s.frames_lost,
        s.frames_duplicated,
        s.ellipsoids,
        s.elapsed_s,
        s.points_per_s,
        s.arrival_s
    );
    if json {
        println!("{}", serde_json::to_string(s)?);
    } else {
        println!("{}", s.map);
    }
    Ok(())
}

/// How a link loop ended, before the end-of-stream frame.
enum Stop {
    /// Ctrl-C, SIGTERM or SIGHUP.
    Signal,
    /// `--idle-timeout`: no frame for this long.
    Idle(f64),
    /// The port closed or vanished, or the capture ended.
    Lost(String),
}

/// Writes the final map, reports, and turns an unfinished stream into [`LinkLost`] or
/// [`LinkIdle`].
fn conclude(
    mut link: Link,
    output: &Path,
    end: Option<Stop>,
    (started, arrivals): (Instant, &Arrivals),
    json: bool,
) -> Result<()> {
    let map = link.finish();
    map.write(output)?;
    let end_text = match (&end, link.end_of_stream()) {
        (_, true) => "end of stream".to_string(),
        (Some(Stop::Signal), false) => "interrupted (Ctrl-C, SIGTERM or SIGHUP)".to_string(),
        (Some(Stop::Idle(seconds)), false) => {
            format!("no frame for {seconds} s (--idle-timeout), before end of stream")
        }
        (Some(Stop::Lost(reason)), false) => format!("link lost before end of stream ({reason})"),
        (None, false) => "input ended before end of stream".to_string(),
    };
    report(
        &summary(
            &link,
            output,
            &end_text,
            map.entities.len(),
            started,
            arrivals,
        ),
        json,
    )?;
    if let Some(why) = nothing_mapped(&link) {
        bail!(
            "nothing was mapped: {why}; the empty map is in {}",
            output.display()
        );
    }
    let lost = format!(
        "{end_text}; the map of what arrived is in {}",
        output.display()
    );
    match (end, link.end_of_stream()) {
        (_, true) | (Some(Stop::Signal), _) => Ok(()),
        (Some(Stop::Idle(_)), _) => Err(LinkIdle(lost).into()),
        _ => Err(LinkLost(lost).into()),
    }
}

/// Why a stream that brought frames mapped no point, if it did not: every frame refused, every
/// pose out of reach, ... A stream that only ended (no points sent) is not refused.
fn nothing_mapped(link: &Link) -> Option<String> {
    if link.mapper.stats().points > 0 {
        return None;
    }
    let (s, r) = (link.stats(), link.receiver_stats());
    let mut reasons = Vec::new();
    if s.rejected > 0 {
        reasons.push(format!(
            "{} frames rejected{}",
            s.rejected,
            Rejections::of(s).text()
        ));
    }
    if r.poses_out_of_reach > 0 {
        reasons.push(format!(
            "{} poses out of reach (refused; past {} km from the world frame's 0, or farther than the reach from the first)",
            r.poses_out_of_reach,
            mema_core::link::receiver::WORLD_LIMIT_NM / 1_000_000_000_000
        ));
    }
    if r.no_pose > 0 {
        reasons.push(format!("{} points frames without their pose", r.no_pose));
    }
    if r.points_out_of_reach > 0 {
        reasons.push(format!("{} points out of reach", r.points_out_of_reach));
    }
    if r.no_returns > 0 {
        reasons.push(format!("{} no-returns at the sensor", r.no_returns));
    }
    (!reasons.is_empty()).then(|| reasons.join(", "))
}

pub fn stream(args: &StreamArgs) -> Result<()> {
    let config = args.fit.config(args.k)?;
    let capacity = capacity(args.k, &args.shape)?;
    check_map_output(&args.output)?;
    if let Some(t) = args.idle_timeout
        && !(t > 0.0 && t.is_finite())
    {
        return Err(UsageError(format!(
            "--idle-timeout {t} must be a positive number of seconds"
        ))
        .into());
    }
    let mut port = open_for_reading(&args.port, args.baud)?;
    let mut record = match &args.record {
        Some(path) => Some(CaptureWriter::create(path)?),
        None => None,
    };
    let stop = interrupted();
    let mut link = new_link(&config, capacity, &args.shape)?;
    eprintln!("mema: listening on {}", args.port.display());
    let started = Instant::now();
    let mut arrivals = Arrivals::default();
    let mut last_snapshot = Instant::now();
    let mut last_progress = Instant::now();
    let mut last_frame = Instant::now();
    let mut buf = [0u8; 4096];
    let end = loop {
        if last_progress.elapsed() >= PROGRESS_EVERY {
            let s = link.stats();
            eprintln!(
                "mema: {:.0} s: {} points, frames {} accepted / {} rejected / {} lost, {} clusters",
                started.elapsed().as_secs_f64(),
                link.mapper.stats().points,
                s.accepted,
                s.rejected,
                s.lost,
                link.mapper.clusters().len()
            );
            last_progress = Instant::now();
        }
        if stop.load(Ordering::SeqCst) {
            break Some(Stop::Signal);
        }
        match read_some(port.as_mut(), &mut buf) {
            ReadOutcome::Bytes(n) => {
                let bytes = buf.get(..n).unwrap_or(&[]);
                if let Some(r) = record.as_mut() {
                    r.write(bytes)?;
                }
                let frames = link.stats().accepted;
                link.feed(bytes);
                arrivals.note(link.mapper.stats().points);
                if link.stats().accepted > frames {
                    last_frame = Instant::now();
                }
                if link.end_of_stream() {
                    break None;
                }
            }
            ReadOutcome::Idle => {}
            ReadOutcome::Gone(reason) => break Some(Stop::Lost(reason)),
        }
        if let Some(seconds) = args.idle_timeout
            && last_frame.elapsed() >= Duration::from_secs_f64(seconds)
        {
            break Some(Stop::Idle(seconds));
        }
        if let Some(every) = args.snapshot_every
            && last_snapshot.elapsed() >= Duration::from_secs_f64(every)
        {
            // A full disk or a vanished directory must not end the stream: the map in memory
            // is the only copy of what arrived, and the next snapshot or the end may succeed.
            match link.snapshot().write(&args.output) {
                Ok(()) => eprintln!(
                    "mema: snapshot: {} points, {} ellipsoids",
                    link.mapper.stats().points,
                    link.mapper.clusters().len()
                ),
                Err(e) => eprintln!("mema: snapshot failed, the stream goes on: {e:#}"),
            }
            last_snapshot = Instant::now();
        }
    };
    if let Some(r) = record {
        r.finish()?;
    }
    conclude(link, &args.output, end, (started, &arrivals), args.json)
}

/// The largest capture replayed: 1 GiB is about 88 million points on the wire (12.2 bytes a
/// point in full frames); `mema replay /dev/zero` used to read until memory ran out.
pub(super) const CAPTURE_LIMIT: u64 = 1 << 30;

pub fn replay(args: &ReplayArgs) -> Result<()> {
    let config = args.fit.config(args.k)?;
    let capacity = capacity(args.k, &args.shape)?;
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| args.capture.with_extension("mema"));
    check_map_output(&output)?;
    super::check_bag_args(&args.capture, &args.bag)?;
    let bytes = if InputKind::of(&args.capture) == InputKind::Bag {
        // A bag's scans, as `scanner-sim` would send them: what `map BAG --stream` maps.
        let scans = scans_of_input(&args.capture, None, &args.bag.options())
            .with_context(|| args.capture.display().to_string())?;
        send_scans(&scans)?.bytes
    } else {
        mema::io::input::read_bounded(&args.capture, CAPTURE_LIMIT, "capture")?
    };
    let stop = interrupted();
    let mut link = new_link(&config, capacity, &args.shape)?;
    let started = Instant::now();
    let mut arrivals = Arrivals::default();
    let mut end = None;
    for chunk in bytes.chunks(args.chunk_bytes.max(1)) {
        if stop.load(Ordering::SeqCst) {
            end = Some(Stop::Signal);
            break;
        }
        // Past the end-of-stream frame the rest is still fed: it is only counted, and then
        // counted whole whatever the chunk size.
        let paced = !link.end_of_stream();
        link.feed(chunk);
        arrivals.note(link.mapper.stats().points);
        if let Some(rate) = args.rate.filter(|_| paced) {
            // Pace by points delivered, as the scanner would have.
            let due = link.mapper.stats().points as f64 / rate;
            let ahead = due - started.elapsed().as_secs_f64();
            if ahead > 0.0 {
                std::thread::sleep(Duration::from_secs_f64(ahead));
            }
        }
    }
    conclude(link, &output, end, (started, &arrivals), args.json)
}
