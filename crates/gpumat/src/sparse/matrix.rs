//! Sparse matrix values on a shared pattern.

use super::pattern::SparsityPattern;
use super::spmv::{SpMV, SpMVT, SparseRef};
use crate::expr::{Ex, Expr, MatRef};
use crate::matrix::{Matrix, Shape};
use crate::scalar::{Scalar, ScalarMul};
use crate::stats;
use std::sync::Arc;

/// A batched sparse matrix: one shared [`SparsityPattern`], `batches` sets of values.
/// With `T = Mat3<R>` this is a 3x3 block-sparse (BSR) matrix.
#[derive(Clone, Debug)]
pub struct SparseMatrix<T: Scalar> {
    pattern: Arc<SparsityPattern>,
    values: Vec<T>,
    batches: usize,
}

impl<T: Scalar> SparseMatrix<T> {
    /// All stored values zero.
    pub fn zeros(pattern: Arc<SparsityPattern>, batches: usize) -> Self {
        stats::count_allocation();
        let values = vec![T::ZERO; pattern.nnz() * batches];
        Self {
            pattern,
            values,
            batches,
        }
    }
    /// From values (batch after batch, in pattern order).
    #[track_caller]
    pub fn from_values(pattern: Arc<SparsityPattern>, batches: usize, values: Vec<T>) -> Self {
        assert_eq!(
            values.len(),
            pattern.nnz() * batches,
            "gpumat::SparseMatrix::from_values: {} values for {} entries x {batches} batches",
            values.len(),
            pattern.nnz()
        );
        stats::count_allocation();
        Self {
            pattern,
            values,
            batches,
        }
    }
    /// From `(row, col, value)` triplets (one batch); duplicates are summed.
    #[track_caller]
    pub fn from_triplets(rows: usize, cols: usize, triplets: &[(usize, usize, T)]) -> Self {
        let pattern = SparsityPattern::from_entries(rows, cols, triplets.iter().map(|t| (t.0, t.1)));
        let mut m = Self::zeros(pattern, 1);
        for &(r, c, v) in triplets {
            let k = m
                .pattern
                .find(r, c)
                .expect("entry is in the pattern built from the triplets");
            m.values[k] = m.values[k].add(v);
        }
        m
    }
    /// The shared pattern.
    pub fn pattern(&self) -> &Arc<SparsityPattern> {
        &self.pattern
    }
    /// Rows (in blocks for BSR).
    pub fn rows(&self) -> usize {
        self.pattern.rows()
    }
    /// Columns (in blocks for BSR).
    pub fn cols(&self) -> usize {
        self.pattern.cols()
    }
    /// Batches.
    pub fn batches(&self) -> usize {
        self.batches
    }
    /// Stored entries per batch.
    pub fn nnz(&self) -> usize {
        self.pattern.nnz()
    }
    /// The shape as an expression would see it.
    pub fn shape(&self) -> Shape {
        Shape::new(self.rows(), self.cols(), self.batches)
    }
    /// All values.
    pub fn values(&self) -> &[T] {
        &self.values
    }
    /// All values, mutable.
    pub fn values_mut(&mut self) -> &mut [T] {
        &mut self.values
    }
    /// The values of batch `b`.
    pub fn batch_values(&self, b: usize) -> &[T] {
        &self.values[b * self.nnz()..(b + 1) * self.nnz()]
    }
    /// The values of batch `b`, mutable.
    pub fn batch_values_mut(&mut self, b: usize) -> &mut [T] {
        let n = self.nnz();
        &mut self.values[b * n..(b + 1) * n]
    }
    /// Element `(r, c)` of batch `b` (zero when not stored).
    pub fn get(&self, r: usize, c: usize, b: usize) -> T {
        self.pattern
            .find(r, c)
            .map_or(T::ZERO, |k| self.values[b * self.nnz() + k])
    }
    /// This matrix as an expression leaf (for [`Ex::sparse_view`] sums).
    pub fn ex(&self) -> Ex<SparseRef<'_, T>> {
        Ex(SparseRef::new(self))
    }
    /// `self * x` as a fusable expression.
    #[track_caller]
    pub fn mul<E: Expr>(&self, x: Ex<E>) -> Ex<SpMV<'_, T, E>>
    where
        T: ScalarMul<E::Elem>,
    {
        Ex(SpMV::new(self, x.0))
    }
    /// `self^T * x` as a fusable expression (blocks transposed too).
    #[track_caller]
    pub fn transpose_mul<E: Expr>(&self, x: Ex<E>) -> Ex<SpMVT<'_, T, E>>
    where
        T: ScalarMul<E::Elem>,
    {
        Ex(SpMVT::new(self, x.0))
    }
    /// Dense copy of batch `b` (for tests and small problems).
    pub fn to_dense(&self, b: usize) -> Matrix<T> {
        let mut m = Matrix::zeros(self.rows(), self.cols(), 1);
        for r in 0..self.rows() {
            for k in self.pattern.row_range(r) {
                m.set(
                    r,
                    self.pattern.col_idx()[k] as usize,
                    0,
                    self.values[b * self.nnz() + k],
                );
            }
        }
        m
    }
}

impl<'a, T: Scalar, E: Expr> std::ops::Mul<Ex<E>> for &'a SparseMatrix<T>
where
    T: ScalarMul<E::Elem>,
{
    type Output = Ex<SpMV<'a, T, E>>;
    #[track_caller]
    fn mul(self, x: Ex<E>) -> Self::Output {
        self.mul(x)
    }
}
impl<'a, T: Scalar, X: Scalar> std::ops::Mul<&'a Matrix<X>> for &'a SparseMatrix<T>
where
    T: ScalarMul<X>,
{
    type Output = Ex<SpMV<'a, T, MatRef<'a, X>>>;
    #[track_caller]
    fn mul(self, x: &'a Matrix<X>) -> Self::Output {
        SparseMatrix::mul(self, x.ex())
    }
}
