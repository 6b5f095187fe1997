//! Direct sparse Cholesky (faer's supernodal/simplicial `LL^T`), for scalar and BSR matrices.
//!
//! The symbolic analysis (fill-reducing ordering, elimination tree) depends only on the
//! pattern and is done once; [`SparseCholesky::refactor`] redoes only the numeric phase when
//! the values change (pattern once, values every step). The ordering is faer's approximate
//! minimum degree by default, or a block ordering given by the caller
//! ([`SparseCholesky::with_ordering`], e.g. [`nested_dissection`](super::nested_dissection),
//! which on 3D grids has about half AMD's fill and factors several times faster). The
//! factorization runs in `f64` whatever the matrix's real type. It is a solver on its own, the
//! fallback when CG fails, and a preconditioner ([`Preconditioner`]).

use super::tree_solve::SupernodeTree;
use super::Preconditioner;
use crate::error::Error;
use crate::matrix::Matrix;
use crate::scalar::{Real, Scalar};
use crate::sparse::{BlockScalar, SparseMatrix, SparsityPattern};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Par, Side};
use std::sync::Arc;

/// A sparse Cholesky factorization of every batch of a symmetric positive definite matrix.
#[derive(Debug, Clone)]
pub struct SparseCholesky<M: BlockScalar> {
    pattern: Arc<SparsityPattern>,
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    symbolic: Arc<SymbolicCholesky<usize>>,
    /// the supernodal elimination tree the solves run over (`None`: a simplicial factor, or a
    /// tree without the containment property, solved by faer)
    tree: Option<Arc<SupernodeTree>>,
    factors: Vec<Vec<f64>>,
    _m: std::marker::PhantomData<M>,
}

/// Factors with fewer entries than this are computed on one thread ([`SparseCholesky::refactor`]).
pub const PARALLEL_FACTOR_ENTRIES: usize = 10_000_000;

impl<M: BlockScalar> SparseCholesky<M> {
    /// Analyses the pattern (AMD ordering) and factors every batch of `a`.
    pub fn new(a: &SparseMatrix<M>) -> Result<Self, Error> {
        Self::with_ordering(a, None)
    }

    /// Like [`SparseCholesky::new`] with a fill-reducing ordering of the block rows:
    /// `order[k]` is the block row eliminated `k`-th (a permutation of `0..rows`); `None` is
    /// faer's AMD.
    pub fn with_ordering(a: &SparseMatrix<M>, order: Option<&[usize]>) -> Result<Self, Error> {
        Self::analyse(a, order)?.factored(a)
    }

    /// The symbolic analysis alone (ordering, elimination tree, the factor's size
    /// [`SparseCholesky::factor_nnz`]), so that a caller can decide whether to factor; it
    /// solves nothing until [`SparseCholesky::factored`] or [`SparseCholesky::refactor`].
    pub fn analyse(a: &SparseMatrix<M>, order: Option<&[usize]>) -> Result<Self, Error> {
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
        let perm = order.map(|o| expand_order(o, p.rows(), M::BLOCK)).transpose()?;
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let ordering = match &perm {
            None => SymmetricOrdering::Amd,
            Some((fwd, inv)) => SymmetricOrdering::Custom(faer::perm::PermRef::new_checked(fwd, inv, n)),
        };
        let symbolic = factorize_symbolic_cholesky(sym, Side::Lower, ordering, Default::default())
            .map_err(|e| Error::Factorization(format!("{e:?}")))?;
        let tree = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => SupernodeTree::new(s).map(Arc::new),
            SymbolicCholeskyRaw::Simplicial(_) => None,
        };
        Ok(Self {
            pattern: p.clone(),
            n,
            col_ptr,
            row_idx,
            symbolic: Arc::new(symbolic),
            tree,
            factors: Vec::new(),
            _m: std::marker::PhantomData,
        })
    }

    /// This analysis with the numeric factors of `a` ([`SparseCholesky::refactor`]).
    pub fn factored(mut self, a: &SparseMatrix<M>) -> Result<Self, Error> {
        self.refactor(a)?;
        Ok(self)
    }

    /// Redoes the numeric factorization with new values on the same pattern (the symbolic
    /// analysis and ordering are kept).
    #[track_caller]
    pub fn refactor(&mut self, a: &SparseMatrix<M>) -> Result<(), Error> {
        // faer's parallel supernodal factorization only pays off on large factors: on the
        // 2-core Xeon a 27-point 3x3-block matrix factored 2.3x faster sequentially at 3e5
        // factor entries, 1.55x at 2e6, 1.08x at 8e6, and 1.14x slower at 2.3e7 (the
        // `chol_par` example, 2026-12-06); its idle workers' spinning also takes the cores
        // from other work
        self.refactor_on(a, self.symbolic.len_val() >= PARALLEL_FACTOR_ENTRIES)
    }

    /// [`SparseCholesky::refactor`] on faer's global parallelism (`parallel`, rayon's pool by
    /// default) or on one thread, whatever the factor's size.
    #[track_caller]
    pub fn refactor_on(&mut self, a: &SparseMatrix<M>, parallel: bool) -> Result<(), Error> {
        assert!(
            self.pattern.same_as(a.pattern()),
            "gpumat::SparseCholesky::refactor: the matrix has another pattern"
        );
        let par = if parallel {
            faer::get_global_parallelism()
        } else {
            Par::Seq
        };
        let mut buf = MemBuffer::try_new(
            self.symbolic
                .factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        )
        .map_err(|_| Error::Factorization("out of memory".into()))?;
        let mut factors = Vec::with_capacity(a.batches());
        for b in 0..a.batches() {
            let vals = a.expanded_values_f64(b);
            let sym =
                SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx);
            let mat = SparseColMatRef::new(sym, &vals);
            let mut l = Vec::new();
            l.try_reserve_exact(self.symbolic.len_val())
                .map_err(|_| Error::Factorization("out of memory".into()))?;
            l.resize(self.symbolic.len_val(), 0.0f64);
            self.symbolic
                .factorize_numeric_llt(
                    &mut l,
                    mat,
                    Side::Lower,
                    Default::default(),
                    par,
                    MemStack::new(&mut buf),
                    Default::default(),
                )
                .map_err(|e| match e {
                    faer::linalg::solvers::LltError::NonPositivePivot { index } => {
                        Error::NotPositiveDefinite {
                            batch: b,
                            pivot: index,
                        }
                    }
                })?;
            factors.push(l);
        }
        self.factors = factors;
        Ok(())
    }

    /// Number of factored batches.
    pub fn batches(&self) -> usize {
        self.factors.len()
    }

    /// Stored entries of one factor `L` (the fill of the ordering).
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// The pattern the factorization was analysed for.
    pub fn pattern(&self) -> &Arc<SparsityPattern> {
        &self.pattern
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
        let mut permuted = vec![0.0f64; self.n];
        // faer's own solve (simplicial factors) runs on one thread: its `Par::rayon(0)` was no
        // faster on the memory-bound triangular solves (measured 2026-12-05); the supernodal
        // factors are solved over their elimination tree ([`SupernodeTree`]), subtrees in
        // parallel
        let par = Par::Seq;
        let mut stack = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(1, par));
        for b in 0..x.batches() {
            let xb = x.batch_mut(b);
            for (i, v) in xb.iter().enumerate() {
                for l in 0..lanes {
                    buf[i * lanes + l] = v.lane(l).as_f64();
                }
            }
            let f = &self.factors[if nf == 1 { 0 } else { b }];
            match &self.tree {
                Some(tree) => {
                    // the factor's ordering: row i of the permuted system is row fwd[i]
                    let fwd = self.symbolic.perm().map(|p| p.arrays().0);
                    let at = |i: usize| fwd.map_or(i, |f| f[i]);
                    for (i, v) in permuted.iter_mut().enumerate() {
                        *v = buf[at(i)];
                    }
                    tree.solve(f, &mut permuted);
                    for (i, &v) in permuted.iter().enumerate() {
                        buf[at(i)] = v;
                    }
                }
                None => LltRef::new(&self.symbolic, f).solve_in_place_with_conj(
                    Conj::No,
                    faer::MatMut::from_column_major_slice_mut(&mut buf, self.n, 1),
                    par,
                    MemStack::new(&mut stack),
                ),
            }
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

/// The scalar permutation `(fwd, inv)` of a block ordering (`fwd[new] = old`).
fn expand_order(order: &[usize], rows: usize, block: usize) -> Result<(Vec<usize>, Vec<usize>), Error> {
    let bad = |why: String| Error::Factorization(format!("ordering: {why}"));
    if order.len() != rows {
        return Err(bad(format!("{} entries for {rows} block rows", order.len())));
    }
    let n = rows * block;
    let mut fwd = Vec::with_capacity(n);
    let mut inv = vec![usize::MAX; n];
    for &o in order {
        if o >= rows || inv[o * block] != usize::MAX {
            return Err(bad(format!("block row {o} is out of range or repeated")));
        }
        for l in 0..block {
            inv[o * block + l] = fwd.len();
            fwd.push(o * block + l);
        }
    }
    Ok((fwd, inv))
}

impl<M: BlockScalar> Preconditioner<M::Vector> for SparseCholesky<M> {
    fn apply(&self, r: &Matrix<M::Vector>, z: &mut Matrix<M::Vector>) {
        z.assign(r.ex());
        self.solve_in_place(z);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sparse::SparseMatrix;

    /// The 7-point Laplacian (plus a shift) of a `g^3` grid and its node coordinates.
    fn grid(g: usize) -> (SparseMatrix<f64>, Vec<[f64; 3]>) {
        let idx = |i: usize, j: usize, k: usize| i + g * (j + g * k);
        let mut trip = Vec::new();
        let mut coords = Vec::new();
        for k in 0..g {
            for j in 0..g {
                for i in 0..g {
                    coords.push([i as f64, j as f64, k as f64]);
                    let me = idx(i, j, k);
                    trip.push((me, me, 6.1));
                    for (d, n) in [
                        (i, idx(i.wrapping_sub(1), j, k)),
                        (j, idx(i, j.wrapping_sub(1), k)),
                    ]
                    .into_iter()
                    .chain([(k, idx(i, j, k.wrapping_sub(1)))])
                    {
                        if d > 0 {
                            trip.push((me, n, -1.0));
                            trip.push((n, me, -1.0));
                        }
                    }
                }
            }
        }
        (SparseMatrix::from_triplets(g * g * g, g * g * g, &trip), coords)
    }

    /// The elimination-tree solve equals faer's supernodal solve of the same factor (to
    /// rounding: another summation order), gives the same bits on 1 and 4 threads, and runs
    /// subtrees in parallel on this matrix.
    #[test]
    fn tree_solve_matches_faer_and_is_thread_independent() {
        let (a, coords) = grid(28);
        let order = super::super::nested_dissection(a.pattern(), &coords);
        let chol = SparseCholesky::with_ordering(&a, Some(&order)).unwrap();
        let tree = chol.tree.as_ref().expect("a supernodal factor with its tree");
        assert!(
            tree.splits(),
            "no parallel subtrees (factor {} entries)",
            chol.factor_nnz()
        );
        let n = a.rows();
        let b: Vec<f64> = (0..n)
            .map(|i| ((i * 7919) % 1013) as f64 / 1013.0 - 0.5)
            .collect();
        // faer's own solve
        let mut want = b.clone();
        let mut stack = MemBuffer::new(chol.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        LltRef::new(&chol.symbolic, &chol.factors[0]).solve_in_place_with_conj(
            Conj::No,
            faer::MatMut::from_column_major_slice_mut(&mut want, n, 1),
            Par::Seq,
            MemStack::new(&mut stack),
        );
        let solve = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut x = Matrix::<f64>::zeros(n, 1, 1);
            x.batch_mut(0).copy_from_slice(&b);
            pool.install(|| chol.solve_in_place(&mut x));
            x.batch(0).to_vec()
        };
        let one = solve(1);
        let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (i, (g, w)) in one.iter().zip(&want).enumerate() {
            assert!((g - w).abs() <= 1e-12 * scale, "x[{i}] = {g}, faer {w}");
        }
        let four = solve(4);
        assert!(one.iter().zip(&four).all(|(p, q)| p.to_bits() == q.to_bits()));
    }

    /// The numeric factor has the same bits on one thread and on faer's parallel path in a
    /// pool of 4 threads ([`SparseCholesky::refactor_on`]), so the size threshold of
    /// [`SparseCholesky::refactor`] changes no result.
    #[test]
    fn factor_bits_do_not_depend_on_the_threads() {
        let (a, coords) = grid(28);
        let order = super::super::nested_dissection(a.pattern(), &coords);
        let mut chol = SparseCholesky::with_ordering(&a, Some(&order)).unwrap();
        chol.refactor_on(&a, false).unwrap();
        let one = chol.factors.clone();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
        pool.install(|| chol.refactor_on(&a, true)).unwrap();
        assert_eq!(one.len(), chol.factors.len());
        let same = one[0]
            .iter()
            .zip(&chol.factors[0])
            .all(|(p, q)| p.to_bits() == q.to_bits());
        assert!(same, "factor of {} entries differs", chol.factor_nnz());
    }

    /// A banded matrix in its natural order: the elimination tree is one long chain of
    /// supernodes, most with subtrees above the parallel threshold. The solve walks it in a
    /// loop, not by recursion: it runs on a thread with a 128 KiB stack.
    #[test]
    fn tree_solve_walks_a_long_chain_without_deep_recursion() {
        let (n, band) = (40_000usize, 128usize);
        let mut trip = Vec::new();
        for i in 0..n {
            trip.push((i, i, 2.0 * band as f64 + 1.0));
            for d in 1..=band.min(i) {
                trip.push((i, i - d, -1.0));
                trip.push((i - d, i, -1.0));
            }
        }
        let a = SparseMatrix::from_triplets(n, n, &trip);
        let natural: Vec<usize> = (0..n).collect();
        let chol = SparseCholesky::with_ordering(&a, Some(&natural)).unwrap();
        let b: Vec<f64> = (0..n).map(|i| (i % 17) as f64 - 8.0).collect();
        let x = std::thread::Builder::new()
            .stack_size(128 << 10)
            .spawn(move || {
                assert!(chol.tree.is_some(), "a supernodal factor");
                let mut x = Matrix::<f64>::zeros(n, 1, 1);
                x.batch_mut(0).copy_from_slice(&b);
                chol.solve_in_place(&mut x);
                x.batch(0).to_vec()
            })
            .unwrap()
            .join()
            .unwrap();
        // the residual of A x = b
        let b: Vec<f64> = (0..n).map(|i| (i % 17) as f64 - 8.0).collect();
        let mut worst = 0.0f64;
        for i in 0..n {
            let mut ax = (2.0 * band as f64 + 1.0) * x[i];
            for d in 1..=band {
                if i >= d {
                    ax -= x[i - d];
                }
                if i + d < n {
                    ax -= x[i + d];
                }
            }
            worst = worst.max((ax - b[i]).abs());
        }
        assert!(worst < 1e-9, "residual {worst}");
    }
}
