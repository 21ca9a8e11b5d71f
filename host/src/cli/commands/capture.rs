//! `mema record` and `mema scanner-sim`: a capture's two ends. `record` keeps what a port
//! receives, byte for byte, until the end-of-stream frame; `scanner-sim` sends a cloud, a bag or
//! a registration as a scanner sends it, onto a port or into a capture file.

use anyhow::{Context, Result, bail};
use std::io::Write;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use mema::io::drive::{DriveConfig, drive};
use mema::io::kind::InputKind;
use mema::io::output::check_output_dir;
use mema::io::scene::Scene;
use mema::link::capture::CaptureWriter;
use mema::link::port::{
    ReadOutcome, is_terminal_device, open_for_reading, open_for_writing, read_some, write_waiting,
};
use mema::link::scanner::{SensorScan, scans_of, scans_of_input, send_scans, unit_name};

use super::serial::interrupted;
use crate::cli::args::{RecordArgs, ScannerSimArgs};
use crate::cli::errors::UsageError;

pub fn record(args: &RecordArgs) -> Result<()> {
    check_output_dir(&args.output)?;
    let mut port = open_for_reading(&args.port, args.baud)?;
    let mut capture = CaptureWriter::create(&args.output)?;
    let stop = interrupted();
    // The decoder only watches for the end-of-stream frame; the capture keeps every byte.
    let mut watch = mema_core::link::wire::Decoder::new();
    eprintln!("mema: listening on {}", args.port.display());
    let mut seen_end = false;
    let mut bytes = 0u64;
    let mut buf = [0u8; 4096];
    let reason = loop {
        if stop.load(Ordering::SeqCst) {
            break "interrupted (Ctrl-C)".to_string();
        }
        match read_some(port.as_mut(), &mut buf) {
            ReadOutcome::Bytes(n) => {
                let chunk = buf.get(..n).unwrap_or(&[]);
                capture.write(chunk)?;
                bytes += n as u64;
                let mut window = chunk;
                loop {
                    match watch.feed(window) {
                        mema_core::link::wire::Decoded::Consumed => break,
                        mema_core::link::wire::Decoded::Rejected { remaining, .. } => {
                            window = remaining
                        }
                        mema_core::link::wire::Decoded::Frame { frame, remaining } => {
                            seen_end |= frame.end_of_stream();
                            window = remaining;
                        }
                    }
                }
                if seen_end {
                    break "end of stream".to_string();
                }
            }
            ReadOutcome::Idle => {}
            ReadOutcome::Gone(reason) => break format!("port closed ({reason})"),
        }
    };
    capture.finish()?;
    eprintln!(
        "mema: {reason}: {bytes} bytes, {} frames",
        watch.stats().accepted
    );
    println!("{}", args.output.display());
    Ok(())
}

pub fn scanner_sim(args: &ScannerSimArgs) -> Result<()> {
    match (&args.cloud, &args.conf) {
        (Some(path), _) => super::check_bag_args(path, &args.bag)?,
        (None, Some(conf)) => super::check_bag_args(conf, &args.bag)?,
        (None, None) if args.bag.given() => {
            return Err(UsageError(
                "--topic and --frame choose a ROS 2 bag's messages; name the bag".into(),
            )
            .into());
        }
        (None, None) => {}
    }
    let scans = match (&args.conf, &args.cloud) {
        (Some(conf), _) => {
            if InputKind::of(conf) != InputKind::Registration {
                bail!(
                    "{}: not a registration file (lines `bmesh FILE tx ty tz qx qy qz qw`)",
                    conf.display()
                );
            }
            scans_of(conf, args.units.units.as_ref())?
        }
        (None, Some(path)) if InputKind::of(path) == InputKind::Bag => {
            scans_of_input(path, args.units.units.as_ref(), &args.bag.options())
                .with_context(|| path.display().to_string())?
        }
        (None, Some(path)) => vec![SensorScan::of_cloud(
            &super::read_in_metres(path, &args.units)?.0,
        )?],
        // The robot driving through the demo scene: each stop's scan after its pose.
        (None, None) if args.walker => drive(&mema::io::drive::room(), &mema::io::drive::walking())
            .iter()
            .map(SensorScan::of_drive)
            .collect(),
        (None, None) => drive(&Scene::demo(), &DriveConfig::default())
            .iter()
            .map(SensorScan::of_drive)
            .collect(),
    };
    if scans.iter().all(|s| s.points.is_empty()) {
        bail!("the cloud has no points to send");
    }
    let sending = send_scans(&scans)?;
    let half = 0.5 * mema_core::link::wire::unit_scale(sending.unit_exponent).unwrap_or(f64::NAN);
    eprintln!(
        "mema: scanner-sim: {} scan{}, unit {} (10^{} m) for a point spacing of {:.3} mm: rounding moves a coordinate by at most {:.3} mm",
        sending.scans,
        if sending.scans == 1 { "" } else { "s" },
        unit_name(sending.unit_exponent),
        sending.unit_exponent,
        sending.spacing * 1e3,
        half * 1e3
    );
    let bytes = sending.bytes;
    let mut port = open_for_writing(&args.port, args.baud)?;
    let stop = interrupted();
    let started = Instant::now();
    let bytes_per_point = bytes.len() as f64 / sending.points.max(1) as f64;
    let mut sent = 0usize;
    for chunk in bytes.chunks(args.chunk_bytes.max(1)) {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        write_waiting(&mut port, chunk)
            .with_context(|| format!("{}: write failed", args.port.display()))?;
        sent += chunk.len();
        if let Some(rate) = args.rate {
            let due = sent as f64 / bytes_per_point / rate;
            let ahead = due - started.elapsed().as_secs_f64();
            if ahead > 0.0 {
                std::thread::sleep(Duration::from_secs_f64(ahead));
            }
        }
    }
    port.flush()
        .with_context(|| format!("{}: flush failed", args.port.display()))?;
    let frames = sending.frames;
    // A device is a port; a FIFO is someone's reader; a regular file is what was made.
    let to_file =
        !is_terminal_device(&args.port) && std::fs::metadata(&args.port).is_ok_and(|m| m.is_file());
    if to_file {
        // No scanner listens on a file: say what was made of it, and what reads it.
        let path = args.port.display();
        eprintln!(
            "mema: scanner-sim: {path} is not a serial port or terminal device, so it is now a capture file: {} points in {frames} frames, {sent} bytes; map it with `mema replay {path}`",
            sending.points
        );
    } else {
        eprintln!(
            "mema: scanner-sim: sent {} points in {frames} frames, {sent} bytes, {:.2} s",
            sending.points,
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
