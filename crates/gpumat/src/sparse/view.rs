//! Sparse views: evaluating a dense-looking expression only on a pattern's entries.
//!
//! Thesis sec. 4.4.3: the Newmark matrix `A = a M + b K` with a lumped (diagonal) `M` has
//! K's pattern. `(M.as_diagonal() * a + K.ex() * b).sparse_view(K.pattern())` assigned to a
//! sparse matrix evaluates the expression at each stored `(r, c)` only: one pass over K's
//! values, no dense temporary.

use super::matrix::SparseMatrix;
use super::pattern::SparsityPattern;
use crate::expr::Expr;
use crate::scalar::Scalar;
use crate::stats;
use rayon::prelude::*;
use std::sync::Arc;

/// An expression restricted to the entries of a pattern; assign it with
/// [`SparseMatrix::assign`].
#[derive(Debug)]
pub struct SparseView<E> {
    e: E,
    pattern: Arc<SparsityPattern>,
}

impl<E: Expr> SparseView<E> {
    /// The view.
    pub fn new(e: E, pattern: Arc<SparsityPattern>) -> Self {
        Self { e, pattern }
    }
}

/// Rows per work item of a sparse assignment.
const ROW_CHUNK: usize = 256;

impl<T: Scalar> SparseMatrix<T> {
    /// Writes the view's values at every stored entry (one pass). The view's pattern must be
    /// this matrix's pattern and its expression must broadcast to `rows x cols x batches`.
    #[track_caller]
    pub fn assign<E: Expr<Elem = T>>(&mut self, view: SparseView<E>) {
        assert!(
            self.pattern().same_as(&view.pattern),
            "gpumat::SparseMatrix::assign: the view's pattern is not this matrix's pattern"
        );
        let out = self.shape();
        let es = view.e.shape();
        assert!(
            es.broadcasts_to(out),
            "gpumat::SparseMatrix::assign: expression of shape {es:?} does not fit {out:?}"
        );
        stats::count_pass();
        let by_entry = view.e.sparse_compatible(&view.pattern);
        let pattern = self.pattern().clone();
        let nnz = pattern.nnz();
        let rows = pattern.rows();
        let e = &view.e;
        let fill_rows = |b: usize, r0: usize, vals: &mut [T]| {
            let base = pattern.row_ptr()[r0];
            let r1 = (r0 + ROW_CHUNK).min(rows);
            for r in r0..r1 {
                for k in pattern.row_range(r) {
                    let c = pattern.col_idx()[k] as usize;
                    // SAFETY: (r, c, b) is inside `out`, to which `e` broadcasts; `k` is an
                    // entry of `pattern`, and `by_entry` says every sparse leaf shares it.
                    vals[k - base] = unsafe {
                        if by_entry {
                            e.entry(k, r, c, b)
                        } else {
                            e.at(r, c, b)
                        }
                    };
                }
            }
        };
        // Work items: (batch, first row); each owns the values of its rows.
        let chunks_per_batch = rows.div_ceil(ROW_CHUNK);
        let mut items: Vec<(usize, usize, &mut [T])> = Vec::with_capacity(chunks_per_batch * out.batches);
        let mut rest = self.values_mut();
        for b in 0..out.batches {
            for j in 0..chunks_per_batch {
                let r0 = j * ROW_CHUNK;
                let r1 = (r0 + ROW_CHUNK).min(rows);
                let len = pattern.row_ptr()[r1] - pattern.row_ptr()[r0];
                let (head, tail) = rest.split_at_mut(len);
                items.push((b, r0, head));
                rest = tail;
            }
        }
        debug_assert!(rest.is_empty() || nnz == 0);
        if nnz * out.batches >= crate::expr::PAR_THRESHOLD {
            items
                .into_par_iter()
                .for_each(|(b, r0, vals)| fill_rows(b, r0, vals));
        } else {
            items.into_iter().for_each(|(b, r0, vals)| fill_rows(b, r0, vals));
        }
    }
}
