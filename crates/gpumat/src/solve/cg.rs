//! Batched preconditioned conjugate gradients (thesis Alg. 4.1, sec. 3.4).
//!
//! Every batch `b` solves its own system `A_b x_b = r_b` with its own step sizes
//! `alpha_b = (r_b . z_b) / (p_b . A p_b)` and `beta_b = (r_b' . z_b') / (r_b . z_b)`, and
//! stops on its own: once `||r_b|| <= tol ||b_b|| + abs_tol`, its `alpha_b` and `beta_b` are
//! zero and its `x_b` stays put. Per-batch scalars are `1 x 1 x batches` matrices that
//! broadcast, so every vector update is one fused pass over all batches.
//!
//! Failures are values: a batch whose curvature `p . A p` is not positive gives
//! [`CgError::NotPositiveDefinite`]; a non-finite residual gives [`CgError::NonFinite`];
//! running out of iterations gives [`CgError::NoConvergence`] with the [`CgInfo`].
//!
//! The algorithm is written once, [`run_cg`], over the operations of a backend ([`CgOps`]):
//! the host's ([`cg`]: `Matrix` vectors, any [`LinearOperator`] and [`Preconditioner`], the
//! state read every iteration) and a device's ([`crate::device::device_cg`]: catalogue
//! kernels, the state read back every few iterations).

use super::{LinearOperator, Preconditioner};
use crate::expr::Axes;
use crate::matrix::Matrix;
use crate::scalar::{Real, Scalar, ScalarMul};

/// Parameters of [`cg`].
#[derive(Clone, Copy, Debug)]
pub struct CgParams<R> {
    /// Maximum number of iterations.
    pub max_iterations: usize,
    /// Relative tolerance on the residual norm, `||r|| <= tolerance ||b||`.
    pub tolerance: R,
    /// Absolute tolerance added to the relative one.
    pub absolute_tolerance: R,
}

impl<R: Real> Default for CgParams<R> {
    fn default() -> Self {
        Self {
            max_iterations: 1000,
            tolerance: R::of(1e-6),
            absolute_tolerance: R::ZERO,
        }
    }
}

/// What [`cg`] did, per batch.
#[derive(Clone, Debug, PartialEq)]
pub struct CgInfo<R> {
    /// Iterations run for each batch.
    pub iterations: Vec<usize>,
    /// Final residual norm relative to `||b||` (absolute when `b = 0`), per batch.
    pub residual: Vec<R>,
    /// Whether each batch met the tolerance.
    pub converged: Vec<bool>,
}

impl<R: Real> CgInfo<R> {
    /// The largest iteration count over the batches.
    pub fn max_iterations(&self) -> usize {
        self.iterations.iter().copied().max().unwrap_or(0)
    }
    /// The largest relative residual over the batches.
    pub fn max_residual(&self) -> R {
        self.residual.iter().copied().fold(R::ZERO, |a, b| a.max(b))
    }
}

/// Why [`cg`] failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CgError<R: Real> {
    /// The iteration limit was reached before every batch converged.
    #[error("CG did not converge within {} iterations (max relative residual {})", .info.max_iterations(), .info.max_residual())]
    NoConvergence {
        /// the state at the end
        info: CgInfo<R>,
    },
    /// `p . A p <= 0` in a batch: the matrix (or preconditioner) is not positive definite.
    #[error(
        "CG: matrix of batch {batch} is not positive definite (p.Ap = {curvature} at iteration {iteration})"
    )]
    NotPositiveDefinite {
        /// the batch
        batch: usize,
        /// the iteration
        iteration: usize,
        /// the offending `p . A p`
        curvature: R,
    },
    /// A residual or step became NaN or infinite.
    #[error("CG: non-finite value in batch {batch} at iteration {iteration}")]
    NonFinite {
        /// the batch
        batch: usize,
        /// the iteration
        iteration: usize,
    },
    /// A device call of the device CG ([`crate::device::device_cg`]) failed.
    #[error("CG on the device: {0}")]
    Device(crate::error::Error),
}

/// The per-batch state of a CG run, as [`CgOps::state`] reads it.
#[derive(Clone, Debug, PartialEq)]
pub struct CgState<R> {
    /// batches still iterating
    pub active: Vec<bool>,
    /// `r . r`
    pub rr: Vec<R>,
    /// `r . z`
    pub rz: Vec<R>,
    /// `p . A p` of the last iteration (0 before the first)
    pub pq: Vec<R>,
    /// steps taken
    pub iterations: Vec<usize>,
}

/// The operations of the batched CG on one backend; the algorithm ([`run_cg`]) is written once
/// over them (architecture principle 2). The vectors and per-batch scalars live where the
/// backend keeps them: the host's are [`Matrix`] values and small vectors ([`cg`]), a device's
/// stay on the device ([`crate::device::device_cg`]).
pub trait CgOps<T: Scalar> {
    /// `||b_b||` per batch.
    fn b_norms(&mut self) -> Result<Vec<T::Real>, CgError<T::Real>>;
    /// `r = b - A x`, `z = P^-1 r`, `p = z`, `(r.z, r.r)`; a batch with `||r|| <= target` does
    /// not start.
    fn start(&mut self, target: &[T::Real]) -> Result<(), CgError<T::Real>>;
    /// One iteration of every running batch (iteration `it`, for errors): `q = A p`,
    /// `alpha = (r.z) / (p.q)`, `x += alpha p`, `r -= alpha q`, `z = P^-1 r`,
    /// `beta = (r.z)_new / (r.z)`, `p = z + beta p`; a batch with `||r|| <= target` stops.
    fn iterate(&mut self, it: usize) -> Result<(), CgError<T::Real>>;
    /// The per-batch state (on a device: a read-back).
    fn state(&mut self) -> Result<CgState<T::Real>, CgError<T::Real>>;
}

/// The batched preconditioned CG over `ops` (thesis Alg. 4.1, module docs), reading the
/// per-batch state every `check_every` iterations (and at the limit): the failure checks and
/// the stop when no batch runs. A stopped batch takes no step, so `check_every` changes the
/// time spent, not the result.
pub fn run_cg<T: Scalar, O: CgOps<T> + ?Sized>(
    ops: &mut O,
    params: &CgParams<T::Real>,
    check_every: usize,
) -> Result<CgInfo<T::Real>, CgError<T::Real>> {
    let zero = T::Real::ZERO;
    let bnorm = ops.b_norms()?;
    let target: Vec<T::Real> = bnorm
        .iter()
        .map(|&bn| params.tolerance * bn + params.absolute_tolerance)
        .collect();
    let scale: Vec<T::Real> = bnorm
        .iter()
        .map(|&bn| if bn > zero { bn } else { T::Real::ONE })
        .collect();
    ops.start(&target)?;
    let check_every = check_every.max(1);
    let mut it = 0;
    let state = loop {
        if it % check_every == 0 || it == params.max_iterations {
            let st = ops.state()?;
            let finite = num_traits::Float::is_finite;
            for bi in 0..st.active.len() {
                if !finite(st.rr[bi]) || !finite(st.rz[bi]) || (st.active[bi] && !finite(st.pq[bi])) {
                    return Err(CgError::NonFinite {
                        batch: bi,
                        iteration: it,
                    });
                }
                if it > 0 && st.active[bi] && st.pq[bi] <= zero {
                    return Err(CgError::NotPositiveDefinite {
                        batch: bi,
                        iteration: it,
                        curvature: st.pq[bi],
                    });
                }
            }
            if st.active.iter().all(|&a| !a) || it == params.max_iterations {
                break st;
            }
        }
        ops.iterate(it)?;
        it += 1;
    };
    let info = CgInfo {
        residual: state
            .rr
            .iter()
            .zip(&scale)
            .map(|(&rr, &s)| num_traits::Float::sqrt(rr) / s)
            .collect(),
        converged: state.active.iter().map(|&a| !a).collect(),
        iterations: state.iterations,
    };
    if info.converged.iter().all(|&c| c) {
        Ok(info)
    } else {
        Err(CgError::NoConvergence { info })
    }
}

/// The host's [`CgOps`]: `Matrix` vectors, any [`LinearOperator`] and [`Preconditioner`].
struct HostCg<'a, T: Scalar, A: ?Sized, P: ?Sized> {
    a: &'a A,
    b: &'a Matrix<T>,
    x: &'a mut Matrix<T>,
    precond: &'a P,
    r: Matrix<T>,
    z: Matrix<T>,
    p: Matrix<T>,
    q: Matrix<T>,
    target: Vec<T::Real>,
    rz: Vec<T::Real>,
    rr: Vec<T::Real>,
    pq: Vec<T::Real>,
    active: Vec<bool>,
    iterations: Vec<usize>,
    alpha: Matrix<T::Real>,
    beta: Matrix<T::Real>,
}

impl<T, A, P> HostCg<'_, T, A, P>
where
    T: Scalar,
    T::Real: ScalarMul<T, Output = T>,
    A: LinearOperator<T> + ?Sized,
    P: Preconditioner<T> + ?Sized,
{
    /// `rr` from `r`, and every running batch whose `||r|| <= target` stops.
    fn residual_norms(&mut self) {
        self.rr = self.r.ex().squared_norm_over(Axes::ROWS).into_vec();
        for bi in 0..self.active.len() {
            if self.active[bi] && num_traits::Float::sqrt(self.rr[bi]) <= self.target[bi] {
                self.active[bi] = false;
            }
        }
    }
}

impl<T, A, P> CgOps<T> for HostCg<'_, T, A, P>
where
    T: Scalar,
    T::Real: ScalarMul<T, Output = T>,
    A: LinearOperator<T> + ?Sized,
    P: Preconditioner<T> + ?Sized,
{
    fn b_norms(&mut self) -> Result<Vec<T::Real>, CgError<T::Real>> {
        Ok(self.b.ex().norm_over(Axes::ROWS).into_vec())
    }
    fn start(&mut self, target: &[T::Real]) -> Result<(), CgError<T::Real>> {
        self.target = target.to_vec();
        self.a.apply(self.x, &mut self.q);
        self.r.assign(self.b - &self.q);
        self.precond.apply(&self.r, &mut self.z);
        self.p = self.z.clone();
        self.rz = self.r.ex().dot_over(self.z.ex(), Axes::ROWS).into_vec();
        self.residual_norms();
        Ok(())
    }
    fn iterate(&mut self, it: usize) -> Result<(), CgError<T::Real>> {
        let zero = T::Real::ZERO;
        self.a.apply(&self.p, &mut self.q);
        self.pq = self.p.ex().dot_over(self.q.ex(), Axes::ROWS).into_vec();
        for bi in 0..self.active.len() {
            let step = if !self.active[bi] {
                zero
            } else {
                let c = self.pq[bi];
                if !num_traits::Float::is_finite(c) {
                    return Err(CgError::NonFinite {
                        batch: bi,
                        iteration: it,
                    });
                }
                if c <= zero {
                    return Err(CgError::NotPositiveDefinite {
                        batch: bi,
                        iteration: it,
                        curvature: c,
                    });
                }
                self.iterations[bi] += 1;
                self.rz[bi] / c
            };
            self.alpha.set(0, 0, bi, step);
        }
        let (alpha, p, q) = (&self.alpha, &self.p, &self.q);
        self.x.assign_with(|x| x + alpha.ex().cwise_mul(p.ex()));
        self.r.assign_with(|r| r - alpha.ex().cwise_mul(q.ex()));
        self.precond.apply(&self.r, &mut self.z);
        let rz_new = self.r.ex().dot_over(self.z.ex(), Axes::ROWS).into_vec();
        // beta of the batches that ran this iteration (a batch stops after its update of p)
        for bi in 0..self.active.len() {
            let bt = if !self.active[bi] || self.rz[bi] == zero {
                zero
            } else {
                rz_new[bi] / self.rz[bi]
            };
            self.beta.set(0, 0, bi, bt);
        }
        self.rz = rz_new;
        let (beta, z) = (&self.beta, &self.z);
        self.p.assign_with(|p| z.ex() + beta.ex().cwise_mul(p));
        self.residual_norms();
        Ok(())
    }
    fn state(&mut self) -> Result<CgState<T::Real>, CgError<T::Real>> {
        Ok(CgState {
            active: self.active.clone(),
            rr: self.rr.clone(),
            rz: self.rz.clone(),
            pq: self.pq.clone(),
            iterations: self.iterations.clone(),
        })
    }
}

/// Solves `A x = b` for every batch, starting from the given `x` (warm start).
///
/// `b` and `x` are `n x 1 x batches`. Returns per-batch iterations and residuals. The
/// algorithm is [`run_cg`] over the host's operations, checking the state every iteration.
///
/// ```
/// use gpumat::{cg, CgParams, Jacobi, Matrix, SparseMatrix};
/// // [[4, 1], [1, 3]] x = [1, 2]
/// let a = SparseMatrix::<f64>::from_triplets(2, 2, &[(0, 0, 4.0), (0, 1, 1.0), (1, 0, 1.0), (1, 1, 3.0)]);
/// let b = Matrix::column(&[1.0, 2.0]);
/// let mut x = Matrix::zeros(2, 1, 1);
/// let info = cg(&a, &b, &mut x, &Jacobi::new(&a).unwrap(), &CgParams::default()).unwrap();
/// assert!((x.get(0, 0, 0) - 1.0 / 11.0).abs() < 1e-9 && info.iterations[0] <= 2);
/// ```
#[track_caller]
pub fn cg<T, A, P>(
    a: &A,
    b: &Matrix<T>,
    x: &mut Matrix<T>,
    precond: &P,
    params: &CgParams<T::Real>,
) -> Result<CgInfo<T::Real>, CgError<T::Real>>
where
    T: Scalar,
    T::Real: ScalarMul<T, Output = T>,
    A: LinearOperator<T> + ?Sized,
    P: Preconditioner<T> + ?Sized,
{
    let n = a.dim();
    let shape = b.shape();
    assert!(
        shape.rows == n && shape.cols == 1,
        "gpumat::cg: b is {shape:?}, expected {n} x 1 x batches"
    );
    assert_eq!(x.shape(), shape, "gpumat::cg: x and b differ in shape");
    let nb = shape.batches;
    let zero = T::Real::ZERO;
    let mut ops = HostCg {
        a,
        b,
        x,
        precond,
        r: Matrix::zeros_shape(shape),
        z: Matrix::zeros_shape(shape),
        p: Matrix::zeros_shape(shape),
        q: Matrix::zeros_shape(shape),
        target: Vec::new(),
        rz: vec![zero; nb],
        rr: vec![zero; nb],
        pq: vec![zero; nb],
        active: vec![true; nb],
        iterations: vec![0; nb],
        alpha: Matrix::zeros(1, 1, nb),
        beta: Matrix::zeros(1, 1, nb),
    };
    run_cg(&mut ops, params, 1)
}
