//! The crate's error type. Every message is one line naming the file, line or key at fault.

use std::path::PathBuf;
use thiserror::Error;

/// Errors of cutfem.
#[derive(Debug, Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// the file
        path: PathBuf,
        /// the cause
        source: std::io::Error,
    },
    /// A file's content is malformed (the message names the line or field when it can).
    #[error("{}: {msg}", path.display())]
    Format {
        /// the file
        path: PathBuf,
        /// what is wrong, e.g. "line 12: expected 3 coordinates"
        msg: String,
    },
    /// A parameter or input is invalid (the message names the key).
    #[error("{0}")]
    Invalid(String),
    /// A linear-algebra failure.
    #[error(transparent)]
    Linalg(#[from] gpumat::Error),
}

impl Error {
    /// A format error for `path`.
    pub fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            msg: msg.into(),
        }
    }
    /// An I/O error for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}
