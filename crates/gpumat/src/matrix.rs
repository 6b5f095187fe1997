//! Dense batched matrices: column-major `rows x cols x batches`, as in cuMat.
//!
//! Element `(r, c, b)` lives at linear index `r + rows * (c + cols * b)`. A matrix is an
//! expression leaf ([`Matrix::ex`]); assigning an expression tree to a matrix evaluates the
//! whole tree in one pass over memory ([`Matrix::assign`]).

use crate::expr::{Ex, Expr, MatRef};
use crate::scalar::{Real, Scalar};
use crate::stats;

/// The dimensions of a batched matrix or expression.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Shape {
    /// rows
    pub rows: usize,
    /// columns
    pub cols: usize,
    /// batches
    pub batches: usize,
}

impl Shape {
    /// A shape.
    pub const fn new(rows: usize, cols: usize, batches: usize) -> Self {
        Self { rows, cols, batches }
    }
    /// Number of elements.
    pub const fn len(&self) -> usize {
        self.rows * self.cols * self.batches
    }
    /// True when there are no elements.
    pub const fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Rows and columns swapped.
    pub const fn transposed(&self) -> Self {
        Self::new(self.cols, self.rows, self.batches)
    }
    /// The broadcast of two shapes: each dimension must be equal or 1 on one side.
    #[track_caller]
    pub fn broadcast(self, other: Shape, op: &str) -> Shape {
        let dim = |a: usize, b: usize, what: &str| {
            if a == b || b == 1 {
                a
            } else if a == 1 {
                b
            } else {
                panic!("gpumat::{op}: cannot broadcast {what} {a} with {b} (shapes {self:?} and {other:?})")
            }
        };
        Shape::new(
            dim(self.rows, other.rows, "rows"),
            dim(self.cols, other.cols, "cols"),
            dim(self.batches, other.batches, "batches"),
        )
    }
    /// True when `self` can be broadcast to `out` (every dimension equal or 1).
    pub fn broadcasts_to(&self, out: Shape) -> bool {
        (self.rows == out.rows || self.rows == 1)
            && (self.cols == out.cols || self.cols == 1)
            && (self.batches == out.batches || self.batches == 1)
    }
}

/// A dense, column-major, batched matrix on the CPU.
#[derive(Clone, PartialEq)]
pub struct Matrix<T: Scalar> {
    data: Vec<T>,
    shape: Shape,
}

impl<T: Scalar> std::fmt::Debug for Matrix<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Matrix")
            .field("shape", &self.shape)
            .field("data", &self.data)
            .finish()
    }
}

impl<T: Scalar> Matrix<T> {
    fn from_vec_unchecked(data: Vec<T>, shape: Shape) -> Self {
        stats::count_allocation();
        Self { data, shape }
    }

    /// A matrix of zeros.
    pub fn zeros(rows: usize, cols: usize, batches: usize) -> Self {
        let shape = Shape::new(rows, cols, batches);
        Self::from_vec_unchecked(vec![T::ZERO; shape.len()], shape)
    }
    /// A matrix filled with `value`.
    pub fn constant(rows: usize, cols: usize, batches: usize, value: T) -> Self {
        let shape = Shape::new(rows, cols, batches);
        Self::from_vec_unchecked(vec![value; shape.len()], shape)
    }
    /// A matrix of zeros of the given shape.
    pub fn zeros_shape(shape: Shape) -> Self {
        Self::zeros(shape.rows, shape.cols, shape.batches)
    }
    /// From column-major data (batch after batch).
    #[track_caller]
    pub fn from_slice(rows: usize, cols: usize, batches: usize, data: &[T]) -> Self {
        Self::from_vec(rows, cols, batches, data.to_vec())
    }
    /// From a column-major vector (batch after batch), taking ownership.
    #[track_caller]
    pub fn from_vec(rows: usize, cols: usize, batches: usize, data: Vec<T>) -> Self {
        let shape = Shape::new(rows, cols, batches);
        assert_eq!(
            data.len(),
            shape.len(),
            "gpumat::Matrix::from_vec: {} values for shape {rows}x{cols}x{batches}",
            data.len()
        );
        Self::from_vec_unchecked(data, shape)
    }
    /// From an iterator of column-major values.
    #[track_caller]
    pub fn from_iter_shape(
        rows: usize,
        cols: usize,
        batches: usize,
        iter: impl IntoIterator<Item = T>,
    ) -> Self {
        Self::from_vec(rows, cols, batches, iter.into_iter().collect())
    }
    /// From a closure `f(row, col, batch)`.
    pub fn from_fn(
        rows: usize,
        cols: usize,
        batches: usize,
        mut f: impl FnMut(usize, usize, usize) -> T,
    ) -> Self {
        let shape = Shape::new(rows, cols, batches);
        let mut data = Vec::with_capacity(shape.len());
        for b in 0..batches {
            for c in 0..cols {
                for r in 0..rows {
                    data.push(f(r, c, b));
                }
            }
        }
        Self::from_vec_unchecked(data, shape)
    }
    /// A column vector `n x 1 x 1`.
    pub fn column(data: &[T]) -> Self {
        Self::from_slice(data.len(), 1, 1, data)
    }
    /// The shape.
    pub fn shape(&self) -> Shape {
        self.shape
    }
    /// Rows.
    pub fn rows(&self) -> usize {
        self.shape.rows
    }
    /// Columns.
    pub fn cols(&self) -> usize {
        self.shape.cols
    }
    /// Batches.
    pub fn batches(&self) -> usize {
        self.shape.batches
    }
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.data.len()
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
    /// The column-major data.
    pub fn as_slice(&self) -> &[T] {
        &self.data
    }
    /// The column-major data, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.data
    }
    /// The data of batch `b`.
    #[track_caller]
    pub fn batch(&self, b: usize) -> &[T] {
        let n = self.shape.rows * self.shape.cols;
        &self.data[b * n..(b + 1) * n]
    }
    /// The data of batch `b`, mutable.
    #[track_caller]
    pub fn batch_mut(&mut self, b: usize) -> &mut [T] {
        let n = self.shape.rows * self.shape.cols;
        &mut self.data[b * n..(b + 1) * n]
    }
    /// Consumes the matrix, returning its data.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }
    #[track_caller]
    fn index(&self, r: usize, c: usize, b: usize) -> usize {
        let s = self.shape;
        assert!(
            r < s.rows && c < s.cols && b < s.batches,
            "gpumat::Matrix: index ({r}, {c}, {b}) out of bounds for {s:?}"
        );
        r + s.rows * (c + s.cols * b)
    }
    /// Element `(r, c, b)`.
    #[track_caller]
    pub fn get(&self, r: usize, c: usize, b: usize) -> T {
        self.data[self.index(r, c, b)]
    }
    /// Sets element `(r, c, b)`.
    #[track_caller]
    pub fn set(&mut self, r: usize, c: usize, b: usize, v: T) {
        let i = self.index(r, c, b);
        self.data[i] = v;
    }
    /// This matrix as an expression leaf.
    pub fn ex(&self) -> Ex<MatRef<'_, T>> {
        Ex(MatRef::new(&self.data, self.shape))
    }
    /// Evaluates an expression into a new matrix (one pass, one allocation).
    pub fn eval<E: Expr<Elem = T>>(e: Ex<E>) -> Self {
        let mut m = Self::zeros_shape(e.0.shape());
        m.assign(e);
        m
    }
    /// Reshapes without moving data (the element count must stay the same).
    #[track_caller]
    pub fn reshape(mut self, rows: usize, cols: usize, batches: usize) -> Self {
        let s = Shape::new(rows, cols, batches);
        assert_eq!(
            s.len(),
            self.data.len(),
            "gpumat::Matrix::reshape: element count changes"
        );
        self.shape = s;
        self
    }
}

impl<R: Real> Matrix<R> {
    /// Batch `b` as a faer matrix (copied).
    pub fn to_faer(&self, b: usize) -> faer::Mat<R> {
        let s = self.shape;
        faer::Mat::from_fn(s.rows, s.cols, |i, j| self.get(i, j, b))
    }
    /// Batch `b` as a borrowed faer view (no copy).
    pub fn faer_ref(&self, b: usize) -> faer::MatRef<'_, R> {
        faer::MatRef::from_column_major_slice(self.batch(b), self.shape.rows, self.shape.cols)
    }
    /// Batch `b` as a mutable faer view (no copy).
    pub fn faer_mut(&mut self, b: usize) -> faer::MatMut<'_, R> {
        let (r, c) = (self.shape.rows, self.shape.cols);
        faer::MatMut::from_column_major_slice_mut(self.batch_mut(b), r, c)
    }
    /// A batched matrix from faer matrices of equal shape (one per batch).
    #[track_caller]
    pub fn from_faer(mats: &[faer::MatRef<'_, R>]) -> Self {
        assert!(!mats.is_empty(), "gpumat::Matrix::from_faer: no matrices");
        let (rows, cols) = (mats[0].nrows(), mats[0].ncols());
        for m in mats {
            assert!(
                m.nrows() == rows && m.ncols() == cols,
                "gpumat::Matrix::from_faer: batches differ in shape"
            );
        }
        Self::from_fn(rows, cols, mats.len(), |r, c, b| mats[b][(r, c)])
    }
}
