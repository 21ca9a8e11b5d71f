//! The library's errors as Python exceptions: the whole `anyhow` chain on one line, as the
//! command line prints it, under the exception a Python caller would catch for it.

use mema::ConfigError;
use mema::io::input::InputError;
use mema::io::read::ReadError;
use pyo3::PyErr;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyPermissionError, PyValueError};

pyo3::create_exception!(
    mema,
    MemaError,
    PyValueError,
    "Data mema cannot use: a file that is no cloud or map, a truncated one, a cloud with no finite \
     point. A ValueError, so code that already catches those catches it too."
);

/// `anyhow::Result` into `PyResult`, through [`to_py`].
pub trait IntoPy<T> {
    fn into_py(self) -> Result<T, PyErr>;
}

impl<T> IntoPy<T> for anyhow::Result<T> {
    fn into_py(self) -> Result<T, PyErr> {
        self.map_err(to_py)
    }
}

/// A request no data could satisfy (`k = 0`, an unknown extension) is a `ValueError`; a file
/// the system would not open is the `OSError` Python raises for it (so `FileNotFoundError`
/// for a missing one); anything wrong with the data is a [`MemaError`].
pub fn to_py(e: anyhow::Error) -> PyErr {
    // The command line's words for options, in Python's.
    let message = format!("{e:#}")
        .replace("--units", "units=")
        .replace("consider -k ", "consider k=");
    if e.chain().any(|c| c.downcast_ref::<ConfigError>().is_some()) {
        return PyValueError::new_err(message);
    }
    // The readers keep the OS error inside their message, not as a `source` (so the chain
    // does not print it twice); writes put an `io::Error` in the chain.
    let kind = e.chain().find_map(|c| {
        if let Some(ReadError::Io { cause, .. }) = c.downcast_ref::<ReadError>() {
            return Some(cause.kind());
        }
        if let Some(InputError::Io { cause, .. }) = c.downcast_ref::<InputError>() {
            return Some(cause.kind());
        }
        c.downcast_ref::<std::io::Error>().map(std::io::Error::kind)
    });
    match kind {
        Some(std::io::ErrorKind::NotFound) => PyFileNotFoundError::new_err(message),
        Some(std::io::ErrorKind::PermissionDenied) => PyPermissionError::new_err(message),
        Some(_) => PyOSError::new_err(message),
        None => MemaError::new_err(message),
    }
}

/// A `ValueError` for a bad argument, its name first.
pub fn bad_value(what: &str, why: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{what}: {why}"))
}

/// A count given as a Python int: `what` and the value in the error, where pyo3's unsigned
/// conversion would only say "can't convert negative int to unsigned".
pub fn count<T: TryFrom<i64>>(what: &str, value: i64) -> Result<T, PyErr> {
    T::try_from(value).map_err(|_| {
        bad_value(
            what,
            format!("{value} is not a count (0 or more, and not too large)"),
        )
    })
}
