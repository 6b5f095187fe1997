//! Geometric multigrid for 3x3 block (BSR) symmetric positive definite matrices, as a CG
//! preconditioner: Galerkin coarse operators, damped block-Jacobi smoothing, a symmetric
//! V-cycle and a sparse Cholesky solve on the coarsest level.
//!
//! **Hierarchy.** The caller gives scalar prolongations `P_l` (level `l + 1` to level `l`,
//! e.g. trilinear interpolation on a lattice, [`lattice_prolongations`]); each acts on 3-vectors
//! as `P_l (x) I3`, the same weights for the three components. The coarse operators are the
//! Galerkin products
//!
//! ```text
//! A_{l+1} = P_l^T A_l P_l,
//! ```
//!
//! symmetric positive definite when `A_0 = A` is and `P_l` has full column rank. Their patterns
//! are computed once ([`Multigrid::new`]); [`Multigrid::refresh`] recomputes the values (and the
//! smoothers and the coarsest factor) from a new `A` on the same pattern: pattern once, values
//! every step.
//!
//! **Smoother** ([`Smoother`], module `smoother`): a polynomial in `D_l^-1 A_l` with `D_l` the
//! 3x3 diagonal blocks of `A_l`, self-adjoint in the `A_l` inner product: damped block-Jacobi
//! `x <- x + omega D_l^-1 (b - A_l x)` (converges while `omega lambda_max(D_l^-1 A_l) < 2`), or
//! (the default) a Chebyshev polynomial over `[0.1, 1.1] lambda_l` (the lower end:
//! [`MultigridParams::chebyshev_lower`]), `lambda_l` a power-iteration
//! estimate of `lambda_max(D_l^-1 A_l)` made at every refresh, which adapts to the spectrum's
//! scale (cut cells, penalties) where a fixed `omega` may not.
//!
//! **Cycle.** `V(nu, nu)` ([`MultigridParams::sweeps`] = `nu`) from `x = 0` at every level:
//! `nu` smoothing sweeps, the residual restricted by `P_l^T`, the coarse correction (recursively;
//! the coarsest level is solved exactly by a sparse Cholesky factor), prolongated by `P_l` and
//! added, then `nu` sweeps again. With the same smoother before and after, the map
//! `r -> z = M^-1 r` is linear, symmetric and positive definite, so preconditioned CG stays
//! valid. Every product runs row by row in a fixed order: the result does not depend on the
//! number of threads.
//!
//! The cycle borrows the fine matrix: [`Multigrid::preconditioner`] pairs the hierarchy with
//! the `A` it was last refreshed from, and that pair is the [`Preconditioner`] for [`cg`].
//!
//! ```
//! use gpumat::solve::{lattice_prolongations, Multigrid, MultigridParams};
//! use gpumat::{cg, CgParams, Mat3, Matrix, SparseMatrix, Vec3};
//! // a 1D Laplacian (x) I3 on 33 nodes
//! let n = 33;
//! let mut t = Vec::new();
//! for i in 0..n {
//!     t.push((i, i, Mat3::from_scalar(2.0)));
//!     if i > 0 {
//!         t.push((i, i - 1, Mat3::from_scalar(-1.0)));
//!         t.push((i - 1, i, Mat3::from_scalar(-1.0)));
//!     }
//! }
//! let a = SparseMatrix::from_triplets(n, n, &t);
//! let params = MultigridParams { max_coarse: 5, ..Default::default() };
//! let nodes: Vec<usize> = (0..n).collect();
//! let mg = Multigrid::new(&a, lattice_prolongations([n, 1, 1], &nodes, &params), params).unwrap();
//! let b = Matrix::constant(n, 1, 1, Vec3::splat(1.0));
//! let mut x = Matrix::zeros(n, 1, 1);
//! let info = cg(&a, &b, &mut x, &mg.preconditioner(&a), &CgParams { tolerance: 1e-10, ..Default::default() }).unwrap();
//! assert!(info.iterations[0] < 10);
//! ```
//!
//! [`cg`]: super::cg

mod galerkin;
mod lattice;
mod smoother;
#[cfg(test)]
mod tests;

pub use lattice::lattice_prolongations;
pub use smoother::Smoother;

use super::{Preconditioner, SparseCholesky};
use crate::block::{Mat3, Vec3};
use crate::error::Error;
use crate::matrix::Matrix;
use crate::sparse::{SparseMatrix, SparsityPattern};
use galerkin::Galerkin;
use smoother::{estimate_lambda_max, Smoothing};
use std::sync::Arc;

/// Options of [`Multigrid`] and [`lattice_prolongations`] (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MultigridParams {
    /// the most levels, the finest included
    pub max_levels: usize,
    /// the smoother
    pub smoother: Smoother,
    /// smoothing sweeps (Chebyshev: the degree) before and after the coarse correction (`nu`
    /// of `V(nu, nu)`)
    pub sweeps: usize,
    /// damping of the block-Jacobi smoother
    pub omega: f64,
    /// the lower end of the Chebyshev interval relative to the estimate of
    /// `lambda_max(D^-1 A)` (the upper end is 1.1 times it)
    pub chebyshev_lower: f64,
    /// coarsen until a level has at most this many block unknowns (lattice nodes)
    pub max_coarse: usize,
}

impl Default for MultigridParams {
    fn default() -> Self {
        Self {
            max_levels: 12,
            smoother: Smoother::Chebyshev,
            sweeps: 3,
            omega: 0.7,
            chebyshev_lower: 0.1,
            max_coarse: 2000,
        }
    }
}

/// One smoothed level: its prolongation to the level above and the Galerkin plan.
#[derive(Debug, Clone)]
struct Level {
    /// `P_l`: level `l + 1` to level `l`
    p: SparseMatrix<f64>,
    galerkin: Galerkin,
    /// `D_l^-1`
    dinv: Matrix<Mat3<f64>>,
    /// the estimate of `lambda_max(D_l^-1 A_l)` (Chebyshev)
    lambda: f64,
}

/// A multigrid hierarchy of a BSR matrix (module docs).
#[derive(Debug, Clone)]
pub struct Multigrid {
    params: MultigridParams,
    fine: Arc<SparsityPattern>,
    levels: Vec<Level>,
    /// `A_1 .. A_L`
    coarse: Vec<SparseMatrix<Mat3<f64>>>,
    /// the factor of `A_L` (`A_0` when there is no prolongation)
    chol: SparseCholesky<Mat3<f64>>,
    /// scratch for `A_l P_l`
    ap: Vec<Mat3<f64>>,
}

/// `D^-1` of batch 0 of `a`.
fn inverse_diagonal(a: &SparseMatrix<Mat3<f64>>) -> Result<Matrix<Mat3<f64>>, Error> {
    let p = a.pattern();
    let diag = p.diagonal_entries();
    let vals = a.batch_values(0);
    let mut out = Matrix::zeros(p.rows(), 1, 1);
    for (r, d) in diag.iter().enumerate() {
        let d = d.ok_or(Error::MissingDiagonal { row: r })?;
        let inv = vals[d]
            .inverse()
            .filter(|m| m.m.iter().flatten().all(|v| v.is_finite()))
            .ok_or(Error::SingularDiagonal { row: r, batch: 0 })?;
        out.set(r, 0, 0, inv);
    }
    Ok(out)
}

impl Multigrid {
    /// The hierarchy of `a` (square, one batch, every diagonal block stored) over the
    /// prolongations `p` (`p[l]` has the rows of level `l`; at most `params.max_levels - 1`
    /// are used): the symbolic Galerkin products, then [`Multigrid::refresh`].
    #[track_caller]
    pub fn new(
        a: &SparseMatrix<Mat3<f64>>,
        mut p: Vec<SparseMatrix<f64>>,
        params: MultigridParams,
    ) -> Result<Self, Error> {
        let pat = a.pattern();
        if pat.rows() != pat.cols() {
            return Err(Error::NotSquare {
                rows: pat.rows(),
                cols: pat.cols(),
            });
        }
        assert!(
            a.batches() == 1,
            "gpumat::Multigrid: {} batches, one is supported",
            a.batches()
        );
        p.truncate(params.max_levels.max(1) - 1);
        let mut levels = Vec::with_capacity(p.len());
        let mut coarse = Vec::with_capacity(p.len());
        let mut rows = pat.clone();
        let mut ap = 0;
        for pl in p {
            let galerkin = Galerkin::new(&rows, pl.pattern());
            ap = ap.max(galerkin.ap_nnz());
            rows = galerkin.coarse_pattern().clone();
            coarse.push(SparseMatrix::zeros(rows.clone(), 1));
            levels.push(Level {
                p: pl,
                galerkin,
                dinv: Matrix::zeros(0, 1, 1),
                lambda: 0.0,
            });
        }
        // the coarsest operator's values are not known yet: analyse its pattern only
        let coarsest = coarse.last().unwrap_or(a);
        let chol = SparseCholesky::analyse(coarsest, None)?;
        let mut this = Self {
            params,
            fine: pat.clone(),
            levels,
            coarse,
            chol,
            ap: vec![Mat3::default(); ap],
        };
        this.refresh(a)?;
        Ok(this)
    }

    /// Recomputes the coarse operators, smoothers and the coarsest factor from `a` (the
    /// pattern the hierarchy was built for).
    #[track_caller]
    pub fn refresh(&mut self, a: &SparseMatrix<Mat3<f64>>) -> Result<(), Error> {
        assert!(
            self.fine.same_as(a.pattern()) && a.batches() == 1,
            "gpumat::Multigrid::refresh: the matrix has another pattern or several batches"
        );
        let chebyshev = self.params.smoother == Smoother::Chebyshev;
        for l in 0..self.levels.len() {
            let (done, rest) = self.coarse.split_at_mut(l);
            let fine = if l == 0 { a } else { &done[l - 1] };
            let level = &mut self.levels[l];
            level.dinv = inverse_diagonal(fine)?;
            if chebyshev {
                level.lambda = estimate_lambda_max(fine, &level.dinv);
                if !(level.lambda > 0.0 && level.lambda.is_finite()) {
                    return Err(Error::SingularDiagonal { row: 0, batch: 0 });
                }
            }
            let ap = &mut self.ap[..level.galerkin.ap_nnz()];
            level.galerkin.values(fine, &level.p, ap, &mut rest[0]);
        }
        let coarsest = self.coarse.last().unwrap_or(a);
        self.chol.refactor(coarsest)
    }

    /// Levels, the finest and the coarsest included.
    pub fn levels(&self) -> usize {
        self.levels.len() + 1
    }

    /// Block unknowns of every level, finest first.
    pub fn level_rows(&self) -> Vec<usize> {
        std::iter::once(self.fine.rows())
            .chain(self.coarse.iter().map(|c| c.rows()))
            .collect()
    }

    /// The estimates of `lambda_max(D_l^-1 A_l)` of the smoothed levels (Chebyshev; 0 with
    /// block-Jacobi).
    pub fn lambda_max(&self) -> Vec<f64> {
        self.levels.iter().map(|l| l.lambda).collect()
    }

    /// The pattern of the fine matrix.
    pub fn pattern(&self) -> &Arc<SparsityPattern> {
        &self.fine
    }

    /// The options.
    pub fn params(&self) -> &MultigridParams {
        &self.params
    }

    /// The V-cycle preconditioner with `a`, the matrix of the last [`Multigrid::refresh`].
    #[track_caller]
    pub fn preconditioner<'a>(&'a self, a: &'a SparseMatrix<Mat3<f64>>) -> MultigridCycle<'a> {
        assert!(
            self.fine.same_as(a.pattern()),
            "gpumat::Multigrid::preconditioner: the matrix has another pattern"
        );
        MultigridCycle { mg: self, a }
    }

    /// The operator of level `l` (`a` at level 0).
    fn op<'a>(&'a self, a: &'a SparseMatrix<Mat3<f64>>, l: usize) -> &'a SparseMatrix<Mat3<f64>> {
        if l == 0 {
            a
        } else {
            &self.coarse[l - 1]
        }
    }

    /// `x = M_l^-1 b` at level `l` (from `x = 0`), one V-cycle.
    fn cycle(&self, a: &SparseMatrix<Mat3<f64>>, l: usize, b: &Matrix<Vec3<f64>>, x: &mut Matrix<Vec3<f64>>) {
        if l == self.levels.len() {
            x.assign(b.ex());
            self.chol.solve_in_place(x);
            return;
        }
        let level = &self.levels[l];
        let smoothing = Smoothing {
            a: self.op(a, l),
            dinv: &level.dinv,
            lambda: level.lambda,
            kind: self.params.smoother,
            sweeps: self.params.sweeps,
            omega: self.params.omega,
            lower: self.params.chebyshev_lower,
        };
        let mut t = Matrix::zeros_shape(b.shape());
        let mut d = Matrix::zeros_shape(b.shape());
        smoothing.run(b, x, true, &mut t, &mut d);
        // coarse correction
        t.assign(b - smoothing.a * &*x);
        let bc = Matrix::eval(level.p.transpose_mul(t.ex()));
        let mut xc = Matrix::zeros_shape(bc.shape());
        self.cycle(a, l + 1, &bc, &mut xc);
        x.assign_with(|x| x + level.p.mul(xc.ex()));
        smoothing.run(b, x, false, &mut t, &mut d);
    }
}

/// The V-cycle of a [`Multigrid`] with its fine matrix: the [`Preconditioner`] for [`cg`].
///
/// [`cg`]: super::cg
#[derive(Clone, Copy, Debug)]
pub struct MultigridCycle<'a> {
    mg: &'a Multigrid,
    a: &'a SparseMatrix<Mat3<f64>>,
}

impl Preconditioner<Vec3<f64>> for MultigridCycle<'_> {
    #[track_caller]
    fn apply(&self, r: &Matrix<Vec3<f64>>, z: &mut Matrix<Vec3<f64>>) {
        let n = self.a.rows();
        assert!(
            r.rows() == n && r.cols() == 1 && z.shape() == r.shape(),
            "gpumat::Multigrid: residual is {:?} for {n} rows",
            r.shape()
        );
        if r.batches() == 1 {
            self.mg.cycle(self.a, 0, r, z);
            return;
        }
        for b in 0..r.batches() {
            let rb = Matrix::from_slice(n, 1, 1, r.batch(b));
            let mut zb = Matrix::zeros(n, 1, 1);
            self.mg.cycle(self.a, 0, &rb, &mut zb);
            z.batch_mut(b).copy_from_slice(zb.as_slice());
        }
    }
}
