//! Capture files: a rangefinder's raw bytes, as `mema record` saves them and `mema replay`
//! reads them.

use anyhow::{Context, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::io::mapfile::write_atomically;

/// A capture written progressively to a temporary file and renamed into place at the end, so a
/// crash leaves no partial capture at the path.
pub struct CaptureWriter {
    tmp: PathBuf,
    path: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
}

impl CaptureWriter {
    /// Starts a capture to `path` (a temporary file beside it until [`Self::finish`]).
    pub fn create(path: &Path) -> Result<Self> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let name = path
            .file_name()
            .with_context(|| format!("{}: not a file path", path.display()))?;
        let tmp = dir.join(format!(
            ".{}.{}.tmp",
            name.to_string_lossy(),
            std::process::id()
        ));
        let file = std::fs::File::create(&tmp)
            .with_context(|| format!("cannot write capture to {}", path.display()))?;
        Ok(Self {
            tmp,
            path: path.to_path_buf(),
            file: std::io::BufWriter::new(file),
        })
    }

    /// Appends bytes as they arrived.
    pub fn write(&mut self, bytes: &[u8]) -> Result<()> {
        self.file
            .write_all(bytes)
            .with_context(|| format!("writing {}", self.tmp.display()))
    }

    /// Syncs the capture and renames it into place.
    pub fn finish(self) -> Result<()> {
        let file = self.file.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&self.tmp, &self.path)
            .with_context(|| format!("cannot write capture to {}", self.path.display()))
    }
}

/// Writes a capture atomically (for tests and tools that build captures in memory).
pub fn write_capture(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically(path, bytes)
}
