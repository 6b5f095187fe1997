//! Direct sparse Cholesky (faer's supernodal/simplicial `LL^T`), for scalar and BSR matrices.
//!
//! The symbolic analysis (fill-reducing ordering, elimination tree) depends only on the
//! pattern and is done once; [`SparseCholesky::refactor`] redoes only the numeric phase when
//! the values change (pattern once, values every step). The factorization runs in `f64`
//! whatever the matrix's real type. It is a solver on its own, the fallback when CG fails,
//! and a preconditioner ([`Preconditioner`]).

use super::Preconditioner;
use crate::error::Error;
use crate::matrix::Matrix;
use crate::scalar::{Real, Scalar};
use crate::sparse::{BlockScalar, SparseMatrix, SparsityPattern};
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::Side;
use std::sync::Arc;

/// A sparse Cholesky factorization of every batch of a symmetric positive definite matrix.
#[derive(Debug, Clone)]
pub struct SparseCholesky<M: BlockScalar> {
    pattern: Arc<SparsityPattern>,
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    symbolic: SymbolicLlt<usize>,
    factors: Vec<Llt<usize, f64>>,
    _m: std::marker::PhantomData<M>,
}

impl<M: BlockScalar> SparseCholesky<M> {
    /// Analyses the pattern and factors every batch of `a`.
    pub fn new(a: &SparseMatrix<M>) -> Result<Self, Error> {
        let p = a.pattern();
        if p.rows() != p.cols() {
            return Err(Error::NotSquare {
                rows: p.rows(),
                cols: p.cols(),
            });
        }
        // A symmetric matrix's CSR arrays are also its CSC arrays.
        let (col_ptr, row_idx) = a.expanded_pattern();
        let n = p.rows() * M::BLOCK;
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic =
            SymbolicLlt::try_new(sym, Side::Lower).map_err(|e| Error::Factorization(format!("{e:?}")))?;
        let mut this = Self {
            pattern: p.clone(),
            n,
            col_ptr,
            row_idx,
            symbolic,
            factors: Vec::new(),
            _m: std::marker::PhantomData,
        };
        this.refactor(a)?;
        Ok(this)
    }

    /// Redoes the numeric factorization with new values on the same pattern.
    #[track_caller]
    pub fn refactor(&mut self, a: &SparseMatrix<M>) -> Result<(), Error> {
        assert!(
            self.pattern.same_as(a.pattern()),
            "gpumat::SparseCholesky::refactor: the matrix has another pattern"
        );
        let mut factors = Vec::with_capacity(a.batches());
        for b in 0..a.batches() {
            let vals = a.expanded_values_f64(b);
            let sym =
                SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx);
            let mat = SparseColMatRef::new(sym, &vals);
            let llt =
                Llt::try_new_with_symbolic(self.symbolic.clone(), mat, Side::Lower).map_err(|e| match e {
                    faer::sparse::linalg::LltError::Numeric(
                        faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index },
                    ) => Error::NotPositiveDefinite {
                        batch: b,
                        pivot: index,
                    },
                    other => Error::Factorization(format!("{other:?}")),
                })?;
            factors.push(llt);
        }
        self.factors = factors;
        Ok(())
    }

    /// Number of factored batches.
    pub fn batches(&self) -> usize {
        self.factors.len()
    }

    /// Solves `A x = b` in place for every batch (`b` is `n x 1 x batches`; a single
    /// factored batch serves every right-hand side).
    #[track_caller]
    pub fn solve_in_place(&self, x: &mut Matrix<M::Vector>) {
        let rows = self.pattern.rows();
        assert!(
            x.rows() == rows && x.cols() == 1,
            "gpumat::SparseCholesky::solve: right-hand side is {:?}, expected {rows} x 1 x batches",
            x.shape()
        );
        let nf = self.factors.len();
        assert!(
            nf == 1 || nf == x.batches(),
            "gpumat::SparseCholesky::solve: {nf} factors for {} right-hand sides",
            x.batches()
        );
        let lanes = <M::Vector as Scalar>::LANES;
        let mut buf = vec![0.0f64; self.n];
        for b in 0..x.batches() {
            let xb = x.batch_mut(b);
            for (i, v) in xb.iter().enumerate() {
                for l in 0..lanes {
                    buf[i * lanes + l] = v.lane(l).as_f64();
                }
            }
            let f = &self.factors[if nf == 1 { 0 } else { b }];
            f.solve_in_place(faer::MatMut::from_column_major_slice_mut(&mut buf, self.n, 1));
            for (i, v) in xb.iter_mut().enumerate() {
                *v = <M::Vector as Scalar>::from_lanes(|l| <M::Real as Real>::of(buf[i * lanes + l]));
            }
        }
    }

    /// Solves `A x = b`, returning `x`.
    pub fn solve(&self, b: &Matrix<M::Vector>) -> Matrix<M::Vector> {
        let mut x = b.clone();
        self.solve_in_place(&mut x);
        x
    }
}

impl<M: BlockScalar> Preconditioner<M::Vector> for SparseCholesky<M> {
    fn apply(&self, r: &Matrix<M::Vector>, z: &mut Matrix<M::Vector>) {
        z.assign(r.ex());
        self.solve_in_place(z);
    }
}
