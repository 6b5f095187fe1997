//! The crate's error type (numerical and structural failures; shape violations panic).

use thiserror::Error;

/// Errors of gpumat's fallible operations.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    /// CSR arrays that do not form a valid pattern.
    #[error("invalid sparsity pattern: {0}")]
    InvalidPattern(String),
    /// A preconditioner needs a diagonal entry the pattern does not store.
    #[error("row {row} has no diagonal entry")]
    MissingDiagonal {
        /// the row
        row: usize,
    },
    /// A zero or non-finite diagonal (block) that cannot be inverted.
    #[error("diagonal block of row {row} (batch {batch}) is singular or not finite")]
    SingularDiagonal {
        /// the row
        row: usize,
        /// the batch
        batch: usize,
    },
    /// The direct solver found the matrix not positive definite.
    #[error("matrix (batch {batch}) is not positive definite: Cholesky pivot {pivot} is not positive")]
    NotPositiveDefinite {
        /// the batch
        batch: usize,
        /// the failing scalar pivot
        pivot: usize,
    },
    /// The direct solver failed for another reason.
    #[error("sparse factorization failed: {0}")]
    Factorization(String),
    /// The matrix is not square.
    #[error("matrix is {rows}x{cols}, a square matrix is needed")]
    NotSquare {
        /// rows
        rows: usize,
        /// columns
        cols: usize,
    },
    /// The CUDA backend is not available in this build or on this machine.
    #[error("CUDA backend unavailable: {0}")]
    CudaUnavailable(String),
    /// A CUDA driver call failed on an open device (allocation, copy, launch, synchronisation),
    /// or a kernel name is not in the catalogue.
    #[error("CUDA device error: {0}")]
    Device(String),
    /// NVRTC rejected a CUDA source (the source's name and the first error line).
    #[error("CUDA compile failed: {0}")]
    Compile(String),
}
