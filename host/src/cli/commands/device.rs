//! `mema device`: points out to a mapping device, its map back (`mema::link::device`); with
//! `--listen`, the map of a sensor wired to the device, on the map's own line
//! (`mema::link::listen`).

use std::time::Duration;

use anyhow::{Context, Result};
use serde::Serialize;

use mema::io::atomic::write_file_atomically;
use mema::io::kind::InputKind;
use mema::io::output::check_map_output;
use mema::link::device::{DownlinkCounts, MapFrames};
use mema::link::listen::listen;
use mema::link::port::open_duplex;
use mema::link::queries::{QueryReport, ask};
use mema::link::scanner::{scans_of_input, send_scans};
use mema::link::session::{SessionEvent, SessionLimits, send_and_receive};
use mema_core::link::downlink::RING_BYTES;

use super::serial::CAPTURE_LIMIT;
use crate::cli::args::DeviceArgs;
use crate::cli::errors::UsageError;

/// What the device said of itself when the session began.
#[derive(Serialize)]
struct DeviceSays {
    /// Entities its map holds at most, and of them working clusters.
    capacity: u32,
    working: u32,
    model: &'static str,
    /// Its boot's identifier.
    boot: u32,
}

#[derive(Serialize)]
struct DeviceSummary {
    output: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    layout: Option<DeviceSays>,
    /// Bytes of the stream sent to the device (none when listening).
    #[serde(skip_serializing_if = "Option::is_none")]
    sent: Option<usize>,
    map_bytes: usize,
    #[serde(flatten)]
    downlink: DownlinkCounts,
    #[serde(skip_serializing_if = "Option::is_none")]
    queries: Option<QueryReport>,
}

pub fn device(args: &DeviceArgs) -> Result<()> {
    check_map_output(&args.output)?;
    let t = args.idle_timeout;
    if !(t > 0.0 && t.is_finite() && t < 1e9) {
        return Err(UsageError(format!(
            "--idle-timeout {t} must be a positive number of seconds"
        ))
        .into());
    }
    let silence = Duration::from_secs_f64(t);
    let quiet = args.json;
    let (port_path, got) = match (&args.listen, &args.port, &args.input) {
        (Some(path), ..) => (path, receive(args, path, silence)?),
        (None, Some(path), Some(input)) => (path, send(args, path, input, silence)?),
        _ => return Err(UsageError("name --port and what to send, or --listen".into()).into()),
    };
    let Got {
        mut port,
        map,
        mut frames,
        sent,
    } = got;
    if !quiet {
        eprintln!();
    }
    write_file_atomically(&args.output, &map, "map")?;
    let queries = if args.queries > 0 {
        let report = ask(&mut port, &mut frames, args.queries, 0)
            .with_context(|| format!("{}: queries", port_path.display()))?;
        if report.agreed != report.asked {
            anyhow::bail!(
                "{}: the device answered {} of {} queries unlike the host",
                port_path.display(),
                report.asked - report.agreed,
                report.asked
            );
        }
        Some(report)
    } else {
        None
    };
    let layout = frames.device_layout().map(|l| DeviceSays {
        capacity: l.capacity,
        working: l.working,
        model: if l.model == 0 { "paper" } else { "shells" },
        boot: frames.address().boot,
    });
    let summary = DeviceSummary {
        output: args.output.display().to_string(),
        layout,
        sent,
        map_bytes: map.len(),
        downlink: frames.counts.clone(),
        queries,
    };
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        println!(
            "{}: {} entities, {} bytes from the device ({} frames, {} refused, {} lost; {} entities asked again); the device refused {} of ours, {} sent again",
            summary.output,
            summary.downlink.entities,
            summary.map_bytes,
            summary.downlink.frames,
            summary.downlink.refused,
            summary.downlink.lost,
            summary.downlink.asked_again,
            summary.downlink.device_refused,
            summary.downlink.resent,
        );
    }
    Ok(())
}

/// What a run got from the device: the port (queries are asked on it), the map, its frames,
/// and the bytes of the stream sent (none when listening).
struct Got {
    port: Box<dyn serialport::SerialPort>,
    map: Vec<u8>,
    frames: MapFrames,
    sent: Option<usize>,
}

/// A listener's run: the map of a sensor wired to the device, on `path`.
fn receive(args: &DeviceArgs, path: &std::path::Path, silence: Duration) -> Result<Got> {
    if args.bag.given() {
        return Err(UsageError(
            "--topic and --frame choose a ROS 2 bag's messages to send; a listener sends none"
                .into(),
        )
        .into());
    }
    let mut port = open_duplex(path, args.baud)?;
    let mut frames = MapFrames::listening();
    let quiet = args.json;
    let map = listen(&mut port, &mut frames, silence, |f| {
        if !quiet {
            eprint!(
                "\rmema device: {} entities, {} bytes taken by the device",
                f.counts.entities,
                f.taken()
            );
        }
    })
    .with_context(|| format!("{} at {} baud: listening", path.display(), args.baud))?;
    Ok(Got {
        port,
        map,
        frames,
        sent: None,
    })
}

/// A host's session: `input` sent to the device on `path` in carry frames, its map back. The
/// port, the map, the frames and the bytes of the stream sent.
fn send(
    args: &DeviceArgs,
    path: &std::path::Path,
    input: &std::path::Path,
    silence: Duration,
) -> Result<Got> {
    super::check_bag_args(input, &args.bag)?;
    let name = input.display().to_string();
    let stream = match InputKind::of(input) {
        InputKind::Bag | InputKind::Registration => encode(args, input)?,
        _ => {
            let bytes = mema::io::input::read_bounded(input, CAPTURE_LIMIT, "input")?;
            // A capture starts with the protocol's delimiter; anything else is a cloud.
            if bytes.first() == Some(&0) {
                bytes
            } else {
                encode(args, input)?
            }
        }
    };
    let mut port = open_duplex(path, args.baud)?;
    let quiet = args.json;
    // The device's ring holds RING_BYTES: never more than that is in flight.
    let mut frames = MapFrames::default();
    let limits = SessionLimits {
        window: RING_BYTES,
        silence,
        first_carry: 0,
    };
    let map = send_and_receive(
        &mut port,
        &stream,
        limits,
        &mut frames,
        |event| match event {
            SessionEvent::Progress { done, taken } if !quiet => eprint!(
                "\rmema device: {done} bytes of carry frames taken, {taken} bytes read off the line"
            ),
            SessionEvent::Progress { .. } => {}
            // Said even with --json: the map written is then the whole stream's, from the start.
            SessionEvent::Restart(why) => {
                eprintln!("\nmema device: {why}; starting the session again")
            }
        },
    )
    .with_context(|| format!("{} at {} baud: {name}", path.display(), args.baud))?;
    Ok(Got {
        port,
        map,
        frames,
        sent: Some(stream.len()),
    })
}

/// A cloud, bag or registration file encoded as `mema scanner-sim` sends it.
fn encode(args: &DeviceArgs, input: &std::path::Path) -> Result<Vec<u8>> {
    let scans = scans_of_input(input, None, &args.bag.options())
        .with_context(|| input.display().to_string())?;
    Ok(send_scans(&scans)?.bytes)
}
