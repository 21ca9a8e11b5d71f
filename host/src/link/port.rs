//! Opening a rangefinder port: a serial device or pty through `serialport`, or a plain file (a
//! capture to write, for `scanner-sim`), so the same commands serve hardware and tests.

use anyhow::{Context, Result};
use std::io::{ErrorKind, Read, Write};
use std::path::Path;
use std::time::Duration;

/// How long one read waits before the caller gets control back (Ctrl-C, snapshots).
pub const READ_TIMEOUT: Duration = Duration::from_millis(100);

/// Whether `path` is a serial port or terminal device (a pty included), which the link
/// commands open as a port; any other path is a file.
pub fn is_terminal_device(path: &Path) -> bool {
    use std::os::unix::fs::FileTypeExt;
    std::fs::metadata(path).is_ok_and(|m| m.file_type().is_char_device())
}

fn open_serial(path: &Path, baud: u32) -> Result<Box<dyn serialport::SerialPort>> {
    serialport::new(path.to_string_lossy(), baud)
        .timeout(READ_TIMEOUT)
        .open()
        .with_context(|| format!("{}: cannot open serial port", path.display()))
}

/// A byte source: the port, read with a timeout.
pub fn open_for_reading(path: &Path, baud: u32) -> Result<Box<dyn Read + Send>> {
    if is_terminal_device(path) {
        Ok(Box::new(open_serial(path, baud)?))
    } else {
        anyhow::bail!("{}: not a serial port or terminal device", path.display())
    }
}

/// A byte sink: the port, or a file created at `path` when it is not a device.
pub fn open_for_writing(path: &Path, baud: u32) -> Result<Box<dyn Write + Send>> {
    if is_terminal_device(path) {
        Ok(Box::new(open_serial(path, baud)?))
    } else {
        let f = std::fs::File::create(path)
            .with_context(|| format!("{}: cannot create", path.display()))?;
        Ok(Box::new(std::io::BufWriter::new(f)))
    }
}

/// Both directions of a port (a device that answers: `mema device`), read with a timeout.
pub fn open_duplex(path: &Path, baud: u32) -> Result<Box<dyn serialport::SerialPort>> {
    if is_terminal_device(path) {
        open_serial(path, baud)
    } else {
        anyhow::bail!("{}: not a serial port or terminal device", path.display())
    }
}

/// What one read produced.
pub enum ReadOutcome {
    Bytes(usize),
    /// Nothing arrived within the timeout; the link is still there.
    Idle,
    /// The port closed or vanished (EOF, EIO on a hung-up pty, a pulled USB adapter).
    Gone(String),
}

/// One read from a port: bytes, nothing yet (a timeout), or the port gone.
pub fn read_some(port: &mut dyn Read, buf: &mut [u8]) -> ReadOutcome {
    match port.read(buf) {
        Ok(0) => ReadOutcome::Gone("end of file".into()),
        Ok(n) => ReadOutcome::Bytes(n),
        Err(e)
            if matches!(
                e.kind(),
                ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
            ) =>
        {
            ReadOutcome::Idle
        }
        Err(e) => ReadOutcome::Gone(e.to_string()),
    }
}

/// How long a write may make no progress before the port is given up on.
pub const WRITE_STALL: Duration = Duration::from_secs(30);

/// Writes all of `bytes`, waiting while the port takes none: a port's write times out after
/// [`READ_TIMEOUT`] when its reader holds the line (a board under QEMU takes a byte only once
/// its UART's data register is free, and holds it while its ring is full), which is a pause,
/// not a failure, until nothing has gone for [`WRITE_STALL`].
pub fn write_waiting(port: &mut dyn Write, bytes: &[u8]) -> std::io::Result<()> {
    let mut rest = bytes;
    let mut moved = std::time::Instant::now();
    while !rest.is_empty() {
        match port.write(rest) {
            Ok(0) => return Err(ErrorKind::WriteZero.into()),
            Ok(n) => {
                rest = rest.get(n..).unwrap_or(&[]);
                moved = std::time::Instant::now();
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) && moved.elapsed() < WRITE_STALL => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}
