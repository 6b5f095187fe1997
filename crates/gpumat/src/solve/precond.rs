//! Preconditioners: identity, Jacobi (inverse diagonal, lane by lane) and block-Jacobi
//! (inverse 3x3 diagonal blocks).

use super::Preconditioner;
use crate::error::Error;
use crate::matrix::Matrix;
use crate::scalar::{Scalar, ScalarMul};
use crate::sparse::{BlockScalar, SparseMatrix};

/// No preconditioning: `z = r`.
#[derive(Clone, Copy, Debug, Default)]
pub struct IdentityPreconditioner;

impl<T: Scalar> Preconditioner<T> for IdentityPreconditioner {
    fn apply(&self, r: &Matrix<T>, z: &mut Matrix<T>) {
        z.assign(r.ex());
    }
}

/// Jacobi: `z = D^-1 r` with `D` the (lane) diagonal, per batch.
#[derive(Clone, Debug)]
pub struct Jacobi<V: Scalar> {
    inv_diag: Matrix<V>,
}

/// The diagonal blocks of every batch, or the first missing diagonal.
fn diagonal_blocks<M: BlockScalar>(a: &SparseMatrix<M>) -> Result<Matrix<M>, Error> {
    let p = a.pattern();
    if p.rows() != p.cols() {
        return Err(Error::NotSquare {
            rows: p.rows(),
            cols: p.cols(),
        });
    }
    let diag = p.diagonal_entries();
    if let Some(row) = diag.iter().position(Option::is_none) {
        return Err(Error::MissingDiagonal { row });
    }
    Ok(Matrix::from_fn(p.rows(), 1, a.batches(), |r, _, b| {
        a.batch_values(b)[diag[r].expect("checked above")]
    }))
}

impl<V: Scalar + ScalarMul<V, Output = V>> Jacobi<V> {
    /// From the diagonal of `a` (lanes of the diagonal blocks for BSR).
    pub fn new<M: BlockScalar<Vector = V>>(a: &SparseMatrix<M>) -> Result<Self, Error> {
        let blocks = diagonal_blocks(a)?;
        let mut inv = Matrix::zeros(blocks.rows(), 1, blocks.batches());
        for b in 0..blocks.batches() {
            for r in 0..blocks.rows() {
                let d = blocks.get(r, 0, b).block_diagonal();
                let ok = (0..V::LANES)
                    .all(|i| d.lane(i) != V::Real::ZERO && num_traits::Float::is_finite(d.lane(i)));
                if !ok {
                    return Err(Error::SingularDiagonal { row: r, batch: b });
                }
                inv.set(r, 0, b, d.map(|x| V::Real::ONE / x));
            }
        }
        Ok(Self { inv_diag: inv })
    }
    /// The inverse diagonal.
    pub fn inverse_diagonal(&self) -> &Matrix<V> {
        &self.inv_diag
    }
}

impl<V: Scalar + ScalarMul<V, Output = V>> Preconditioner<V> for Jacobi<V> {
    fn apply(&self, r: &Matrix<V>, z: &mut Matrix<V>) {
        z.assign(self.inv_diag.ex().cwise_mul(r.ex()));
    }
}

/// Block-Jacobi: `z = B^-1 r` with `B` the 3x3 diagonal blocks, per batch.
#[derive(Clone, Debug)]
pub struct BlockJacobi<M: Scalar> {
    inv_blocks: Matrix<M>,
}

impl<M: BlockScalar> BlockJacobi<M> {
    /// From the diagonal blocks of `a`.
    pub fn new(a: &SparseMatrix<M>) -> Result<Self, Error> {
        let mut blocks = diagonal_blocks(a)?;
        for b in 0..blocks.batches() {
            for r in 0..blocks.rows() {
                let inv = blocks
                    .get(r, 0, b)
                    .block_inverse()
                    .ok_or(Error::SingularDiagonal { row: r, batch: b })?;
                blocks.set(r, 0, b, inv);
            }
        }
        Ok(Self { inv_blocks: blocks })
    }
}

impl<M: BlockScalar> Preconditioner<M::Vector> for BlockJacobi<M> {
    fn apply(&self, r: &Matrix<M::Vector>, z: &mut Matrix<M::Vector>) {
        z.assign(self.inv_blocks.ex().cwise_mul(r.ex()));
    }
}
