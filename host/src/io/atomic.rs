//! Files written whole or not at all: through a temporary file in the same directory, a sync
//! and a rename, then a sync of the directory, so neither a reader nor a crash ever sees a
//! partial file at the path and the rename itself survives a power cut.

use anyhow::{Context, Result};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes `bytes` to `path` atomically. `what` names the file in errors ("map", "labels",
/// "picture", "mesh"). Temporary files left by writers of the same name that died (their
/// process is gone) are removed first, so crashes do not leave them forever.
pub fn write_file_atomically(path: &Path, bytes: &[u8], what: &str) -> Result<()> {
    write_atomically_with(path, what, |w| Ok(w.write_all(bytes)?)).map(|_| ())
}

/// Writes to `path` atomically what `write` writes to the buffered file it is given, and
/// returns the file's size: a large output is streamed, never held. If `write` fails, the
/// temporary file is removed and `path` is left as it was.
pub fn write_atomically_with(
    path: &Path,
    what: &str,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<u64> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .with_context(|| format!("{}: not a file path", path.display()))?
        .to_string_lossy();
    remove_stale_temporaries(dir, &name);
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| -> Result<u64> {
        let mut w = BufWriter::with_capacity(1 << 20, File::create(&tmp)?);
        write(&mut w)?;
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        let written = f.metadata()?.len();
        std::fs::rename(&tmp, path)?;
        // The rename is durable only once the directory entry is on disk.
        File::open(dir)?.sync_all()?;
        Ok(written)
    })();
    result
        .inspect_err(|_| {
            let _ = std::fs::remove_file(&tmp);
        })
        .with_context(|| format!("cannot write {what} to {}", path.display()))
}

/// Removes `.NAME.PID.tmp` files in `dir` whose process no longer runs (Linux's /proc tells;
/// where there is no /proc nothing is removed, as a live writer cannot be told from a dead one).
fn remove_stale_temporaries(dir: &Path, name: &str) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let prefix = format!(".{name}.");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(pid) = file
            .to_str()
            .and_then(|f| f.strip_prefix(&prefix))
            .and_then(|rest| rest.strip_suffix(".tmp"))
            .and_then(|pid| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}
