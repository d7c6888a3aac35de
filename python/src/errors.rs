//! Library errors and Rust panics as Python exceptions.

use pyo3::prelude::*;
use pyo3::types::PyType;
use std::panic::{catch_unwind, AssertUnwindSafe};
use tensorscout::util::panic_message;

/// The exception class of `tensorscout._errors` for a library error: usage errors are `ValueError`s,
/// a missing file a `FileNotFoundError`, other file errors `OSError`s, all of them `tensorscout.Error`.
fn class_name(e: &tensorscout::Error) -> &'static str {
    match e {
        tensorscout::Error::Usage(_) => "UsageError",
        tensorscout::Error::Scene { .. } => "SceneError",
        tensorscout::Error::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            "MissingFileError"
        }
        tensorscout::Error::Io { .. } => "FileError",
        tensorscout::Error::Runtime(_) => "RunError",
    }
}

/// An exception of class `name` (from `tensorscout._errors`) with `msg`.
pub fn raise(py: Python<'_>, name: &str, msg: String) -> PyErr {
    let class = py
        .import("tensorscout._errors")
        .and_then(|m| m.getattr(name))
        .and_then(|c| c.cast_into::<PyType>().map_err(PyErr::from));
    match class {
        Ok(c) => PyErr::from_type(c, msg),
        Err(e) => e,
    }
}

/// A library error as its Python exception, with the message the command line prints.
pub fn to_py(py: Python<'_>, e: &tensorscout::Error) -> PyErr {
    raise(py, class_name(e), e.to_string())
}

/// A usage error (`ValueError`) with `msg`.
pub fn usage(py: Python<'_>, msg: impl Into<String>) -> PyErr {
    raise(py, "UsageError", msg.into())
}

/// Converts a library result.
pub trait IntoPy<T> {
    fn py_err(self, py: Python<'_>) -> PyResult<T>;
}

impl<T> IntoPy<T> for tensorscout::Result<T> {
    fn py_err(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| to_py(py, &e))
    }
}

/// Runs `f`; a panic inside becomes `tensorscout.InternalError` instead of unwinding into Python.
pub fn guard<T>(py: Python<'_>, f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|p| {
        Err(raise(
            py,
            "InternalError",
            format!("panic: {}", panic_message(&*p)),
        ))
    })
}
