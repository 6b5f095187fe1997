//! The Galerkin triple product `A_c = P^T A P` of a 3x3 block matrix `A` and a scalar
//! prolongation `P` (acting as `P (x) I3`), with the patterns computed once
//! ([`Galerkin::new`]) and the values recomputed by [`Galerkin::values`] (pattern once, values
//! every step).
//!
//! Two row-wise products, each row computed alone in a fixed order (deterministic whatever the
//! thread count): `(A P)_{kJ} = sum_l A_{kl} P_{lJ}` over the rows `k` of `A`, then
//! `(A_c)_{IJ} = sum_k P_{kI} (A P)_{kJ}` over the columns `I` of `P` (its transpose map).

use crate::block::Mat3;
use crate::sparse::{SparseMatrix, SparsityPattern};
use rayon::prelude::*;
use std::sync::Arc;

/// Rows per parallel task of the numeric products.
const ROWS_PER_TASK: usize = 256;

/// The symbolic phase of `P^T A P`: the patterns of `A P` and of the product.
#[derive(Debug, Clone)]
pub(super) struct Galerkin {
    /// the pattern of `A P` (fine rows x coarse columns)
    ap: Arc<SparsityPattern>,
    /// the pattern of `P^T A P`
    coarse: Arc<SparsityPattern>,
}

/// The pattern of `rows(i) -> union of cols(j)` over the entries `j` of row `i`.
fn product_pattern(
    rows: usize,
    cols: usize,
    row_entries: impl Fn(usize) -> Vec<usize> + Sync,
    inner: &SparsityPattern,
) -> Arc<SparsityPattern> {
    let per_row: Vec<Vec<usize>> = (0..rows)
        .into_par_iter()
        .map(|i| {
            let mut c: Vec<usize> = row_entries(i)
                .into_iter()
                .flat_map(|j| inner.row_range(j).map(|e| inner.col_idx()[e] as usize))
                .collect();
            c.sort_unstable();
            c.dedup();
            c
        })
        .collect();
    let mut row_ptr = Vec::with_capacity(rows + 1);
    row_ptr.push(0);
    for r in &per_row {
        row_ptr.push(row_ptr.last().copied().unwrap_or(0) + r.len());
    }
    let col_idx = per_row.into_iter().flatten().collect();
    SparsityPattern::new(rows, cols, row_ptr, col_idx).expect("sorted unique columns form a valid pattern")
}

/// `out[pos of col] += v` in a sorted row.
#[inline(always)]
fn add_at(cols: &[u32], vals: &mut [Mat3<f64>], col: u32, v: Mat3<f64>) {
    let q = cols
        .binary_search(&col)
        .expect("the symbolic product holds every entry");
    vals[q] = vals[q] + v;
}

impl Galerkin {
    /// The patterns of `A P` and `P^T A P` (`a`: `n x n` blocks, `p`: `n x m` weights).
    #[track_caller]
    pub(super) fn new(a: &SparsityPattern, p: &SparsityPattern) -> Self {
        assert!(
            a.rows() == a.cols() && a.cols() == p.rows(),
            "gpumat::Multigrid: A is {}x{}, P is {}x{}",
            a.rows(),
            a.cols(),
            p.rows(),
            p.cols()
        );
        let ap = product_pattern(
            a.rows(),
            p.cols(),
            |k| a.row_range(k).map(|e| a.col_idx()[e] as usize).collect(),
            p,
        );
        let tm = p.transpose_map();
        let coarse = product_pattern(
            p.cols(),
            p.cols(),
            |i| tm.row_idx[tm.col_ptr[i]..tm.col_ptr[i + 1]].to_vec(),
            &ap,
        );
        Self { ap, coarse }
    }

    /// The pattern of `P^T A P`.
    pub(super) fn coarse_pattern(&self) -> &Arc<SparsityPattern> {
        &self.coarse
    }

    /// Stored blocks of the intermediate `A P`.
    pub(super) fn ap_nnz(&self) -> usize {
        self.ap.nnz()
    }

    /// The values of `P^T A P` (batch 0 of `a`) into `out`, with `ap` (`ap_nnz` blocks) as
    /// scratch for `A P`.
    pub(super) fn values(
        &self,
        a: &SparseMatrix<Mat3<f64>>,
        p: &SparseMatrix<f64>,
        ap: &mut [Mat3<f64>],
        out: &mut SparseMatrix<Mat3<f64>>,
    ) {
        let (apat, ppat) = (a.pattern(), p.pattern());
        let (avals, pvals) = (a.batch_values(0), p.batch_values(0));
        let appat = &*self.ap;
        appat
            .split_rows_mut(ap, ROWS_PER_TASK)
            .into_par_iter()
            .for_each(|(r0, chunk)| {
                let base = appat.row_ptr()[r0];
                chunk.iter_mut().for_each(|v| *v = Mat3::default());
                let rows = r0..(r0 + ROWS_PER_TASK).min(appat.rows());
                for k in rows {
                    let range = appat.row_range(k);
                    let cols = &appat.col_idx()[range.clone()];
                    let vals = &mut chunk[range.start - base..range.end - base];
                    for e in apat.row_range(k) {
                        let l = apat.col_idx()[e] as usize;
                        let m = avals[e];
                        for f in ppat.row_range(l) {
                            add_at(cols, vals, ppat.col_idx()[f], m * pvals[f]);
                        }
                    }
                }
            });
        let ap = &*ap;
        let tm = ppat.transpose_map();
        let cpat = self.coarse.clone();
        cpat.split_rows_mut(out.batch_values_mut(0), ROWS_PER_TASK)
            .into_par_iter()
            .for_each(|(r0, chunk)| {
                let base = cpat.row_ptr()[r0];
                chunk.iter_mut().for_each(|v| *v = Mat3::default());
                for i in r0..(r0 + ROWS_PER_TASK).min(cpat.rows()) {
                    let range = cpat.row_range(i);
                    let cols = &cpat.col_idx()[range.clone()];
                    let vals = &mut chunk[range.start - base..range.end - base];
                    for t in tm.col_ptr[i]..tm.col_ptr[i + 1] {
                        let (k, w) = (tm.row_idx[t], pvals[tm.entry[t]]);
                        for e in appat.row_range(k) {
                            add_at(cols, vals, appat.col_idx()[e], ap[e] * w);
                        }
                    }
                }
            });
    }
}
