//! The crate's error type: one enum for every fallible function of adjoint (reading data
//! files, setting up and evaluating a reconstruction problem, the diagnosis). Every message is
//! one line naming the file, line, key or step at fault; the `softbody` CLI prints it as is.
//!
//! The optimizers keep their own small contract ([`crate::optim::EvalError`],
//! [`crate::optim::OptimError`]): they are generic over any objective and never see files or
//! models.

use std::path::PathBuf;
use thiserror::Error;

/// Errors of adjoint. A file that cannot be read or written, or whose content is wrong as a
/// whole, is cutfem's [`cutfem::Error::Io`] / [`cutfem::Error::Format`] (one home for file
/// errors, [`Error::io`] and [`Error::format`] build them).
#[derive(Debug, Error)]
pub enum Error {
    /// A line of a data file could not be parsed.
    #[error("{}: line {line}: {msg}", path.display())]
    Parse {
        /// the file
        path: PathBuf,
        /// 1-based line number
        line: usize,
        /// what is wrong
        msg: String,
    },
    /// A line of a JSON-lines file (a fit log, a diagnosis history) is not what it should be;
    /// the location is written `file:line` as compilers do.
    #[error("{}:{line}: {msg}", path.display())]
    Line {
        /// the file
        path: PathBuf,
        /// 1-based line number
        line: usize,
        /// what is wrong
        msg: String,
    },
    /// An argument, option or parameter choice is invalid (the message names the key).
    #[error("{0}")]
    Invalid(String),
    /// The forward simulation diverged (non-finite or exploding displacement, failed solve).
    #[error("forward simulation diverged: {0}")]
    Diverged(String),
    /// A simulation step failed; `at` says where ("step 12", "r = 20, step 3").
    #[error("{at}: {source}")]
    Step {
        /// where in the run
        at: String,
        /// the cause
        source: cutfem::Error,
    },
    /// Reading a file, building or running the model failed (scene, grid, solver).
    #[error(transparent)]
    Cutfem(#[from] cutfem::Error),
    /// An optimizer could not start (the objective failed at the starting point).
    #[error(transparent)]
    Optim(#[from] crate::optim::OptimError),
    /// A linear-algebra failure.
    #[error(transparent)]
    Linalg(#[from] gpumat::Error),
}

impl Error {
    /// An [`Error::Invalid`] with the given message.
    pub fn invalid(msg: impl Into<String>) -> Self {
        Error::Invalid(msg.into())
    }
    /// An I/O error for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Cutfem(cutfem::Error::io(path, source))
    }
    /// A whole-file format error for `path`: its content is wrong as a whole (a JSON
    /// document, a scene that cannot be built, a log that belongs to another run); the message
    /// names the key when it can.
    pub fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Cutfem(cutfem::Error::format(path, msg))
    }
    /// A failed simulation step at `at`.
    pub fn step(at: impl Into<String>, source: cutfem::Error) -> Self {
        Error::Step {
            at: at.into(),
            source,
        }
    }
}

/// The CLI reports an error as its one-line message.
impl From<Error> for String {
    fn from(e: Error) -> String {
        e.to_string()
    }
}
