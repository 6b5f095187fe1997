//! The stiffness matrix of the last assembly, kept or computed on first use.
//!
//! A forward step does not need `K` as a matrix (see [`crate::fem::assembly`]); the adjoint's
//! recomputed steps and a few diagnostics do. [`KeptStiffness`] holds `K` when an assembly kept
//! it, and otherwise lets [`super::Simulation::stiffness`] compute it once on demand behind a
//! shared reference. Its buffer is reused from assembly to assembly.

use gpumat::{Mat3, SparseMatrix, SparsityPattern};
use std::sync::{Arc, OnceLock};

/// `K` of the last assembly, if kept or computed since, and a spare buffer.
#[derive(Debug, Default)]
pub(super) struct KeptStiffness {
    k: OnceLock<SparseMatrix<Mat3<f64>>>,
    /// the buffer of `K` while `k` is empty
    spare: Option<SparseMatrix<Mat3<f64>>>,
}

impl KeptStiffness {
    /// Forgets `K` (keeping its buffer).
    pub(super) fn forget(&mut self) {
        if let Some(k) = self.k.take() {
            self.spare = Some(k);
        }
    }

    /// A buffer for `K` on `pattern` (the kept one's, the spare or a new one); `K` counts as
    /// forgotten until [`KeptStiffness::keep`] puts it back.
    pub(super) fn buffer(&mut self, pattern: &Arc<SparsityPattern>) -> SparseMatrix<Mat3<f64>> {
        self.forget();
        self.spare
            .take()
            .filter(|k| Arc::ptr_eq(k.pattern(), pattern))
            .unwrap_or_else(|| SparseMatrix::zeros(pattern.clone(), 1))
    }

    /// Keeps `k` as the stiffness of the last assembly.
    pub(super) fn keep(&mut self, k: SparseMatrix<Mat3<f64>>) {
        self.forget();
        let _ = self.k.set(k);
    }

    /// The kept `K`, or the one `compute` gives (then kept).
    pub(super) fn get_or_compute(
        &self,
        compute: impl FnOnce() -> SparseMatrix<Mat3<f64>>,
    ) -> &SparseMatrix<Mat3<f64>> {
        self.k.get_or_init(compute)
    }
}
