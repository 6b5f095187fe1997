//! Linear solvers: batched preconditioned conjugate gradients (thesis sec. 3.4, Alg. 4.1), a
//! direct sparse Cholesky solver (faer) usable alone, as a fallback, or as a preconditioner,
//! with a geometric nested-dissection ordering, the block incomplete Cholesky IC(0)
//! preconditioner, a geometric multigrid preconditioner (Galerkin V-cycle), and small dense solves (Cholesky, inverse) for the optimizers.

mod cg;
mod cholesky;
mod dense;
mod ic0;
mod multigrid;
mod ordering;
mod precond;
mod tree_solve;

pub use cg::{cg, run_cg, CgError, CgInfo, CgOps, CgParams, CgState};
pub use cholesky::{SparseCholesky, PARALLEL_FACTOR_ENTRIES};
pub use dense::{invert_small, SmallCholesky};
pub use ic0::{BlockIc0, Ic0Params};
pub use multigrid::{lattice_prolongations, Multigrid, MultigridCycle, MultigridParams, Smoother};
pub use ordering::nested_dissection;
pub use precond::{BlockJacobi, IdentityPreconditioner, Jacobi};

use crate::matrix::Matrix;
use crate::scalar::{Scalar, ScalarMul};
use crate::sparse::SparseMatrix;

/// A linear map on batched vectors (`n x 1 x batches`).
pub trait LinearOperator<T: Scalar>: Sync {
    /// The dimension `n` (rows = columns).
    fn dim(&self) -> usize;
    /// `y = A x`, batch by batch.
    fn apply(&self, x: &Matrix<T>, y: &mut Matrix<T>);
    /// `y = A^T x`, batch by batch (the adjoint method's operator: `A^T lambda = dJ/du`).
    fn transpose_apply(&self, x: &Matrix<T>, y: &mut Matrix<T>);
}

/// The transpose of an operator as an operator (`apply` is the inner one's `transpose_apply`),
/// e.g. to solve `A^T x = b` with [`cg`] when `A` is not symmetric.
#[derive(Clone, Copy, Debug)]
pub struct Transposed<'a, O>(pub &'a O);

impl<T: Scalar, O: LinearOperator<T>> LinearOperator<T> for Transposed<'_, O> {
    fn dim(&self) -> usize {
        self.0.dim()
    }
    fn apply(&self, x: &Matrix<T>, y: &mut Matrix<T>) {
        self.0.transpose_apply(x, y);
    }
    fn transpose_apply(&self, x: &Matrix<T>, y: &mut Matrix<T>) {
        self.0.apply(x, y);
    }
}

impl<M: Scalar + ScalarMul<T, Output = T>, T: Scalar> LinearOperator<T> for SparseMatrix<M> {
    fn dim(&self) -> usize {
        self.rows()
    }
    fn apply(&self, x: &Matrix<T>, y: &mut Matrix<T>) {
        y.assign(self * x);
    }
    fn transpose_apply(&self, x: &Matrix<T>, y: &mut Matrix<T>) {
        y.assign(self.transpose_mul(x.ex()));
    }
}

/// An approximate inverse `z = P^-1 r`.
pub trait Preconditioner<T: Scalar>: Sync {
    /// `z = P^-1 r`.
    fn apply(&self, r: &Matrix<T>, z: &mut Matrix<T>);
}
