//! Conversion of (block-)sparse matrices to scalar faer sparse matrices.
//!
//! A BSR matrix with `n` block rows of 3x3 blocks expands to a `3n x 3m` scalar matrix whose
//! entry `(3 br + i, 3 bc + j)` is lane `(i, j)` of block `(br, bc)`.

use super::matrix::SparseMatrix;
use crate::block::{Mat3, Vec3};
use crate::scalar::{Real, Scalar, ScalarMul};
use faer::sparse::{SparseColMat, SparseRowMat, SymbolicSparseRowMat};

/// A sparse-matrix element that is a `BLOCK x BLOCK` block of reals, with the vector type it
/// multiplies.
pub trait BlockScalar: Scalar + ScalarMul<Self::Vector, Output = Self::Vector> {
    /// The vector element (`R` for reals, `Vec3<R>` for `Mat3<R>`).
    type Vector: Scalar<Real = Self::Real> + ScalarMul<Self::Vector, Output = Self::Vector>;
    /// Block size.
    const BLOCK: usize;
    /// Entry `(i, j)` of the block.
    fn block_get(&self, i: usize, j: usize) -> Self::Real;
    /// The diagonal of the block as a vector element.
    fn block_diagonal(&self) -> Self::Vector {
        Self::Vector::from_lanes(|i| self.block_get(i, i))
    }
    /// The inverse block, if it exists.
    fn block_inverse(&self) -> Option<Self>;
}

impl<R: Real + ScalarMul<R, Output = R>> BlockScalar for R {
    type Vector = R;
    const BLOCK: usize = 1;
    fn block_get(&self, _i: usize, _j: usize) -> R {
        *self
    }
    fn block_inverse(&self) -> Option<Self> {
        (*self != R::ZERO && self.is_finite()).then(|| R::ONE / *self)
    }
}

macro_rules! block_mat3 {
    ($r:ty) => {
        impl BlockScalar for Mat3<$r> {
            type Vector = Vec3<$r>;
            const BLOCK: usize = 3;
            fn block_get(&self, i: usize, j: usize) -> $r {
                self.m[i][j]
            }
            fn block_inverse(&self) -> Option<Self> {
                self.inverse()
            }
        }
    };
}
block_mat3!(f32);
block_mat3!(f64);

impl<T: BlockScalar> SparseMatrix<T> {
    /// Expanded scalar CSR arrays `(row_ptr, col_idx)` of the block pattern.
    pub fn expanded_pattern(&self) -> (Vec<usize>, Vec<usize>) {
        let p = self.pattern();
        let bs = T::BLOCK;
        let mut row_ptr = Vec::with_capacity(p.rows() * bs + 1);
        let mut col_idx = Vec::with_capacity(p.nnz() * bs * bs);
        row_ptr.push(0);
        for br in 0..p.rows() {
            for _i in 0..bs {
                for k in p.row_range(br) {
                    let bc = p.col_idx()[k] as usize;
                    col_idx.extend((0..bs).map(|j| bc * bs + j));
                }
                row_ptr.push(col_idx.len());
            }
        }
        (row_ptr, col_idx)
    }
    /// Expanded scalar values of batch `b`, in the order of [`SparseMatrix::expanded_pattern`],
    /// converted to `f64`.
    pub fn expanded_values_f64(&self, b: usize) -> Vec<f64> {
        let p = self.pattern();
        let bs = T::BLOCK;
        let vals = self.batch_values(b);
        let mut out = Vec::with_capacity(p.nnz() * bs * bs);
        for br in 0..p.rows() {
            for i in 0..bs {
                for k in p.row_range(br) {
                    out.extend((0..bs).map(|j| vals[k].block_get(i, j).as_f64()));
                }
            }
        }
        out
    }
    /// Batch `b` as a scalar faer CSR matrix.
    pub fn to_faer_csr(&self, b: usize) -> SparseRowMat<usize, T::Real> {
        let (row_ptr, col_idx) = self.expanded_pattern();
        let bs = T::BLOCK;
        let p = self.pattern();
        let vals = self.batch_values(b);
        let mut out = Vec::with_capacity(col_idx.len());
        for br in 0..p.rows() {
            for i in 0..bs {
                for k in p.row_range(br) {
                    out.extend((0..bs).map(|j| vals[k].block_get(i, j)));
                }
            }
        }
        let sym = SymbolicSparseRowMat::new_checked(p.rows() * bs, p.cols() * bs, row_ptr, None, col_idx);
        SparseRowMat::new(sym, out)
    }
    /// Batch `b` as a scalar faer CSC matrix.
    pub fn to_faer(&self, b: usize) -> SparseColMat<usize, T::Real> {
        self.to_faer_csr(b)
            .to_col_major()
            .expect("faer: out of memory converting to CSC")
    }
}
