//! The library's error type. Each variant says whether the user or the run is at fault, which is what
//! the CLI turns into exit code 2 (usage) or 1 (run-time failure).

use std::path::PathBuf;

/// Every error the library returns. Messages are one line and name the file, key or value at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A config key, flag value or option the user gave is invalid (exit code 2).
    #[error("{0}")]
    Usage(String),
    /// A scene file could not be read or is not a usable scene (exit code 1).
    #[error("{path}: {msg}")]
    Scene { path: PathBuf, msg: String },
    /// An input/output failure on a named file (exit code 1).
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Any other run-time failure (exit code 1).
    #[error("{0}")]
    Runtime(String),
}

impl Error {
    /// Builds a usage error from anything printable.
    pub fn usage(msg: impl Into<String>) -> Self {
        Error::Usage(msg.into())
    }

    /// Builds a scene error naming the file.
    pub fn scene(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Scene {
            path: path.into(),
            msg: msg.into(),
        }
    }

    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// The process exit code this error maps to: 2 for usage errors, 1 otherwise.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Usage(_) => 2,
            _ => 1,
        }
    }
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;
