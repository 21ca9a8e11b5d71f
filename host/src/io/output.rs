//! Checks that an output can be written, made before any work, and the labels file.

use anyhow::{Context, Result};
use std::path::Path;

use super::mapfile::{MapFormat, write_file_atomically};

/// Fails before any work if the map could not be written where asked: an unknown extension
/// (a [`crate::ConfigError`]) or a directory that cannot take it.
pub fn check_map_output(path: &Path) -> Result<()> {
    MapFormat::from_path(path)?;
    check_output_file(path, "map")
}

/// Fails before any work if `path`'s directory is missing or not writable.
pub fn check_output_dir(path: &Path) -> Result<()> {
    check_output_file(path, "file")
}

/// Fails before any work if a `what` file could not be written at `path`: its directory must
/// exist, be a directory, and take a new file (probed with an empty file, removed at once).
pub fn check_output_file(path: &Path, what: &str) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.exists() {
        anyhow::bail!(
            "cannot write {what} to {}: directory {} does not exist",
            path.display(),
            dir.display()
        );
    }
    if !dir.is_dir() {
        anyhow::bail!(
            "cannot write {what} to {}: {} is not a directory",
            path.display(),
            dir.display()
        );
    }
    let probe = dir.join(format!(".mema-probe.{}", std::process::id()));
    match std::fs::File::create(&probe) {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => Err(e).with_context(|| {
            format!(
                "cannot write {what} to {}: directory {} is not writable",
                path.display(),
                dir.display()
            )
        }),
    }
}

/// Writes one cluster index per line, atomically.
pub fn write_labels(path: &Path, labels: &[u32]) -> Result<()> {
    let mut text = String::with_capacity(labels.len() * 4);
    for l in labels {
        text.push_str(&l.to_string());
        text.push('\n');
    }
    write_file_atomically(path, text.as_bytes(), "labels")
}
