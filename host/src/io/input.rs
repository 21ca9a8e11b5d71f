//! Whole-file input with a bound on bytes and on waiting: maps, captures and clouds that come
//! from a pipe or a device. A regular file's length is checked before it is read; a pipe or
//! device is read up to a limit, and a FIFO nobody writes to, or a writer that goes quiet, ends
//! in an error after [`IDLE_TIMEOUT`] instead of a wait that never ends (`open` on a FIFO blocks
//! until a writer comes, so it is opened non-blocking and then polled).

use std::fs::File;
use std::io::Read;
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::os::unix::io::AsRawFd;
use std::path::Path;
use std::time::Duration;

/// Longest wait for the next bytes from a pipe or a device.
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(5);

/// Why an input could not be had whole.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("{path}: cannot read {what}: {cause}")]
    Io {
        path: String,
        what: &'static str,
        cause: std::io::Error,
    },
    #[error("{path}: too large: {got} for a {what}; at most {limit} bytes are read")]
    TooLarge {
        path: String,
        what: &'static str,
        got: String,
        limit: u64,
    },
    #[error(
        "{path}: nothing arrived for {} s (a pipe or device that nobody writes to is not a {what})",
        IDLE_TIMEOUT.as_secs()
    )]
    Idle { path: String, what: &'static str },
    #[error("{path}: not a {what}: {why}")]
    NotA {
        path: String,
        what: &'static str,
        why: String,
    },
}

/// How many first bytes [`read_bounded_as`] shows its check of the start.
pub const START_LEN: usize = 4;

/// A check of an input's first [`START_LEN`] bytes (fewer when it is shorter): the reason it
/// cannot be the input asked for, if it cannot.
pub type StartCheck = fn(&[u8]) -> Result<(), String>;

/// The bytes of `path`, at most `limit` of them; `what` names the input in errors ("map").
pub fn read_bounded(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>, InputError> {
    read_bounded_as(path, limit, what, |_| Ok(()))
}

/// [`read_bounded`], refusing an input whose first bytes `start` refuses before reading on
/// (`/dev/zero` named as a map is refused at its first bytes, not at the limit).
pub fn read_bounded_as(
    path: &Path,
    limit: u64,
    what: &'static str,
    start: StartCheck,
) -> Result<Vec<u8>, InputError> {
    let name = path.display().to_string();
    let io = |cause| InputError::Io {
        path: name.clone(),
        what,
        cause,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if meta.is_file() {
        if meta.len() > limit {
            return Err(InputError::TooLarge {
                path: name,
                what,
                got: format!("{} bytes", meta.len()),
                limit,
            });
        }
        let file = File::open(path).map_err(io)?;
        return read_polled(file, &name, limit, what, start);
    }
    let kind = meta.file_type();
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    if kind.is_fifo() || kind.is_socket() || kind.is_char_device() {
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(io)?;
    // A FIFO without a writer reads as ended at once: wait for its writer's first bytes (or
    // its hang-up) before taking a read of nothing for the end.
    if kind.is_fifo() && !readable_within(&file, IDLE_TIMEOUT) {
        return Err(InputError::Idle { path: name, what });
    }
    read_polled(file, &name, limit, what, start)
}

/// Reads a non-blocking source to its end, waiting at most [`IDLE_TIMEOUT`] for each piece.
fn read_polled(
    mut file: File,
    name: &str,
    limit: u64,
    what: &'static str,
    start: StartCheck,
) -> Result<Vec<u8>, InputError> {
    let mut bytes = Vec::new();
    let mut chunk = vec![0u8; 64 * 1024];
    let mut started = false;
    let check_start = |bytes: &[u8]| {
        start(bytes).map_err(|why| InputError::NotA {
            path: name.to_owned(),
            what,
            why,
        })
    };
    loop {
        match file.read(&mut chunk) {
            Ok(0) => {
                if !started {
                    check_start(&bytes)?;
                }
                return Ok(bytes);
            }
            Ok(n) => {
                bytes.extend_from_slice(chunk.get(..n).unwrap_or(&[]));
                if !started && bytes.len() >= START_LEN {
                    check_start(bytes.get(..START_LEN).unwrap_or(&bytes))?;
                    started = true;
                }
                if bytes.len() as u64 > limit {
                    return Err(InputError::TooLarge {
                        path: name.to_owned(),
                        what,
                        got: "a pipe or device giving more".to_owned(),
                        limit,
                    });
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if !readable_within(&file, IDLE_TIMEOUT) {
                    return Err(InputError::Idle {
                        path: name.to_owned(),
                        what,
                    });
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(cause) => {
                return Err(InputError::Io {
                    path: name.to_owned(),
                    what,
                    cause,
                });
            }
        }
    }
}

/// Whether `file` has bytes (or its end, or an error) to report within `timeout`.
fn readable_within(file: &File, timeout: Duration) -> bool {
    let mut poll = libc::pollfd {
        fd: file.as_raw_fd(),
        events: libc::POLLIN,
        revents: 0,
    };
    let ms = timeout.as_millis().min(i32::MAX as u128) as i32;
    // SAFETY: one valid pollfd for a descriptor `file` keeps open for the call's duration.
    let ready = unsafe { libc::poll(&mut poll, 1, ms) };
    ready > 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_device_without_end_is_too_large() {
        let e = read_bounded(Path::new("/dev/zero"), 1 << 20, "map").unwrap_err();
        assert!(matches!(e, InputError::TooLarge { .. }), "{e}");
    }

    #[test]
    fn a_fifo_nobody_writes_to_is_an_error_after_the_timeout() {
        let dir = std::env::temp_dir().join(format!("mema-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("quiet.fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let started = std::time::Instant::now();
        let e = read_bounded(&fifo, 1 << 20, "map").unwrap_err();
        assert!(matches!(e, InputError::Idle { .. }), "{e}");
        assert!(started.elapsed() >= IDLE_TIMEOUT);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_fifo_with_a_writer_is_read_whole() {
        let dir = std::env::temp_dir().join(format!("mema-input-w-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("busy.fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let path = fifo.clone();
        let writer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(200));
            std::fs::write(path, vec![7u8; 300_000]).unwrap();
        });
        let bytes = read_bounded(&fifo, 1 << 20, "map").unwrap();
        writer.join().unwrap();
        assert_eq!(bytes, vec![7u8; 300_000]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
