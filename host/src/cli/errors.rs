//! How a failed command reads and exits. The library's errors name its own terms; here they
//! become the flags the user typed, and the exit status says what kind of failure it was:
//! 1 bad input or I/O, 2 bad usage (clap's own status for its errors; also a bag's topic or
//! frame that is not in it), 3 a stream that ended
//! before its end-of-stream frame, 4 a stream ended by `--idle-timeout`.

use mema::ConfigError;
use mema::io::bag::BagError;
use mema::mapping::filter::FilterError;

/// A value the user gave that cannot work; reported with exit status 2, like clap's own errors.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// The stream ended without its end-of-stream frame (port closed, cable pulled, capture cut).
/// The map of what arrived is written; the exit status is 3 so scripts can tell.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct LinkLost(pub String);

/// `--idle-timeout` ended a silent link before its end-of-stream frame (a lost last frame, a
/// sender that hung). The map of what arrived is written; the exit status is 4.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct LinkIdle(pub String);

/// Ends the process as Unix tools end when the reader of their standard output has gone
/// (`mema info MAP | head -1`): quietly, killed by SIGPIPE. Rust ignores SIGPIPE so that a
/// closed socket or port is an error the link code reports; only standard output ends this way.
pub fn end_on_closed_stdout() -> ! {
    // SAFETY: restoring the default action of one signal and raising it; no handler runs.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        libc::raise(libc::SIGPIPE);
    }
    // Only if the signal could not end the process: the status a shell shows for it.
    std::process::exit(128 + libc::SIGPIPE)
}

/// The exit status for `e`.
pub fn exit_status(e: &anyhow::Error) -> u8 {
    let bag_usage = e.downcast_ref::<BagError>().is_some_and(BagError::is_usage);
    if e.downcast_ref::<UsageError>().is_some()
        || e.downcast_ref::<ConfigError>().is_some()
        || bag_usage
    {
        2
    } else if e.downcast_ref::<LinkLost>().is_some() {
        3
    } else if e.downcast_ref::<LinkIdle>().is_some() {
        4
    } else {
        1
    }
}

/// `e` as one line, `{e:#}` with the library's errors in the command line's words.
pub fn message(e: &anyhow::Error) -> String {
    let causes: Vec<String> = e
        .chain()
        .map(|cause| {
            if let Some(c) = cause.downcast_ref::<ConfigError>() {
                config_message(c)
            } else if let Some(f) = cause.downcast_ref::<FilterError>() {
                filter_message(f)
            } else {
                cause.to_string()
            }
        })
        .collect();
    causes.join(": ")
}

/// What clap refused, as mema's other errors read: help and version print as clap prints
/// them, and a usage error is one line, `mema: <what was wrong>; see 'mema <command> --help'`,
/// exit 2. Clap's own runs to five lines, most of them a synopsis the help repeats.
pub fn usage_failed(e: clap::Error) -> std::process::ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        e.exit()
    }
    let args: Vec<String> = std::env::args().skip(1).collect();
    eprintln!(
        "mema: {}",
        brief_usage(&e.render().to_string(), &command_path(&args))
    );
    std::process::ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2))
}

/// `mema <subcommand>` as typed (the first word naming one), or `mema`.
fn command_path(args: &[String]) -> String {
    use clap::CommandFactory;
    let root = super::Cli::command();
    args.iter()
        .find_map(|a| root.find_subcommand(a))
        .map_or_else(|| "mema".to_owned(), |s| format!("mema {}", s.get_name()))
}

/// Clap's rendered error (no colour) as one line: the error, the arguments it lists, its tips,
/// and where the help is. The synopsis and the "For more information" line are dropped.
fn brief_usage(rendered: &str, command: &str) -> String {
    let mut what = String::new();
    let mut listed = Vec::new();
    let mut tips = Vec::new();
    for line in rendered.lines().map(str::trim) {
        if line.starts_with("Usage:") || line.starts_with("For more information") {
            break;
        }
        if let Some(rest) = line.strip_prefix("error:") {
            what = rest.trim().to_owned();
        } else if let Some(tip) = line.strip_prefix("tip:") {
            tips.push(tip.trim().to_owned());
        } else if !line.is_empty() {
            listed.push(line.to_owned());
        }
    }
    let mut out = what;
    if !listed.is_empty() {
        out = format!("{out} {}", listed.join(", "));
    }
    for tip in tips {
        out = format!("{out} ({tip})");
    }
    format!("{out}; see '{command} --help'")
}

fn config_message(e: &ConfigError) -> String {
    match e {
        ConfigError::NoClusters => {
            "k must be at least 1; consider -k 150 (about one entity per 100 points)".into()
        }
        ConfigError::Alpha(a) => format!("--alpha {a} is outside [0, 1]; the paper uses 0.8"),
        ConfigError::Threshold(t) => format!("--threshold {t} must be a positive length"),
        ConfigError::SphereTolerance(s) => format!("--sphere-tolerance {s} must be >= 0"),
        ConfigError::TangentScale(v) => format!("--tangent-scale {v} must be positive"),
        ConfigError::NormalScale(v) => format!("--normal-scale {v} must be positive"),
        ConfigError::BudgetTooSmall { bytes, per } => {
            format!("--bytes {bytes} holds no entity; one takes {per} bytes in this model")
        }
        ConfigError::BudgetTakenByFreeSpace {
            bytes,
            scans,
            free,
            per,
        } => format!(
            "--bytes {bytes} holds no entity beside the free space of the input's {scans} scans ({free} bytes); one takes {per} more"
        ),
        ConfigError::Tolerance(t) => {
            format!("--tolerance {t} must be a positive length in metres")
        }
        ConfigError::ToleranceCapacity => "--capacity must be at least 1".into(),
        ConfigError::Voxel(size) => format!(
            "--voxel {size} must be a positive length; consider --voxel 0.05 (5 cm in metres)"
        ),
        ConfigError::Tessellation { segments, rings } => format!(
            "--segments {segments} --rings {rings}: need 3..=1024 segments and 2..=512 rings; consider the defaults, 24 and 12"
        ),
        ConfigError::TooManyVertices(v) => {
            format!("{v} vertices exceed 31-bit indices; consider fewer --segments or --rings")
        }
        ConfigError::MeshTooLarge {
            entities,
            segments,
            rings,
            vertices,
            triangles,
            bytes,
            format,
            limit,
            fits,
        } => {
            let consider = match fits {
                Some((s, r)) => format!("consider --segments {s} --rings {r}, which fit"),
                None => "even --segments 3 --rings 2 do not fit; consider a map of fewer entities"
                    .into(),
            };
            format!(
                "{entities} entities at --segments {segments} --rings {rings} make {vertices} vertices and {triangles} triangles, {bytes} bytes of {format} ({}), over --max-bytes {limit} ({}); {consider}",
                human_bytes(*bytes),
                human_bytes(*limit)
            )
        }
        ConfigError::PictureTooSmall {
            width,
            height,
            plot_width,
            plot_height,
        } => format!(
            "--size {width}x{height} leaves a {plot_width}x{plot_height} plot; consider 1200x900"
        ),
        ConfigError::StreamCapacity { k, max } => {
            format!("-k {k} is over the streaming mapper's capacity of {max}")
        }
        ConfigError::Working { working, k } => {
            format!("--working {working} must be between 1 and -k ({k})")
        }
        ConfigError::WorkingWithTolerance => {
            "--working and --tolerance do not combine: frozen clusters cannot merge".into()
        }
        ConfigError::UpAlongView => {
            "--view sensor --up z: the sensor view looks along z; consider --up y or no --up, or --view horizon for a z-up lidar".into()
        }
        ConfigError::ZeroBudget(b) => format!("--budgets {b}: a budget is at least 1 byte"),
        // The extensions' messages name no flag; any variant added later reads as the library
        // words it until it gets its flags here.
        other => other.to_string(),
    }
}

/// Bytes in the largest binary unit that leaves at least 1 of it ("97.6 GiB").
fn human_bytes(bytes: u64) -> String {
    let units = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < units.len() {
        value /= 1024.0;
        unit += 1;
    }
    match unit {
        0 => format!("{bytes} bytes"),
        _ => format!("{value:.1} {}", units[unit]),
    }
}

fn filter_message(e: &FilterError) -> String {
    match e {
        FilterError::CropLeavesNothing { min, max } => {
            format!("--crop {min:?}..{max:?} leaves no points of the cloud")
        }
        FilterError::VoxelTooSmall { size, reach, least } => format!(
            "--voxel {size} is too small for this cloud: its coordinates reach {reach}, more than 2^53 voxels from zero; use at least {least:e} (in the file's units)"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::Context;

    #[test]
    fn usage_errors_keep_the_error_its_list_and_tips_on_one_line() {
        let missing = "error: the following required arguments were not provided:\n  --output <OUTPUT>\n  <INPUT>\n\nUsage: mema map --output <OUTPUT> <INPUT>\n\nFor more information, try '--help'.\n";
        assert_eq!(
            brief_usage(missing, "mema map"),
            "the following required arguments were not provided: --output <OUTPUT>, <INPUT>; see 'mema map --help'"
        );
        let typo = "error: unexpected argument '--bogus' found\n\n  tip: a similar argument exists: '--bounds'\n\nUsage: mema map --bounds <BOUNDS> <INPUT>\n\nFor more information, try '--help'.\n";
        assert_eq!(
            brief_usage(typo, "mema map"),
            "unexpected argument '--bogus' found (a similar argument exists: '--bounds'); see 'mema map --help'"
        );
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(command_path(&args(&["map", "-o", "demo"])), "mema map");
        assert_eq!(command_path(&args(&["--bogus"])), "mema");
    }

    #[test]
    fn library_errors_read_as_flags_inside_their_context() {
        let e = Err::<(), _>(ConfigError::Alpha(2.0))
            .context("car6.pcd")
            .unwrap_err();
        assert_eq!(
            message(&e),
            "car6.pcd: --alpha 2 is outside [0, 1]; the paper uses 0.8"
        );
        assert_eq!(exit_status(&e), 2);
        let e = anyhow::Error::from(FilterError::CropLeavesNothing {
            min: [0.0; 3],
            max: [1.0; 3],
        })
        .context("x.pcd");
        assert_eq!(
            message(&e),
            "x.pcd: --crop [0.0, 0.0, 0.0]..[1.0, 1.0, 1.0] leaves no points of the cloud"
        );
        assert_eq!(exit_status(&e), 1);
        let e = anyhow::Error::from(ConfigError::MapExtension("m.txt".into())).context("a");
        assert_eq!(
            message(&e),
            format!("{e:#}"),
            "no flag to name: the library's words"
        );
        assert_eq!(exit_status(&e), 2);
        assert_eq!(exit_status(&anyhow::Error::from(LinkLost("cut".into()))), 3);
        assert_eq!(
            exit_status(&anyhow::Error::from(LinkIdle("quiet".into()))),
            4
        );
        assert_eq!(exit_status(&anyhow::anyhow!("broken file")), 1);
    }
}
