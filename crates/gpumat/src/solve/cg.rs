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

/// Solves `A x = b` for every batch, starting from the given `x` (warm start).
///
/// `b` and `x` are `n x 1 x batches`. Returns per-batch iterations and residuals.
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

    let mut r = Matrix::zeros_shape(shape);
    let mut z = Matrix::zeros_shape(shape);
    let mut q = Matrix::zeros_shape(shape);
    a.apply(x, &mut q);
    r.assign(b - &q);
    precond.apply(&r, &mut z);
    let mut p = z.clone();

    let bnorm = b.ex().norm_over(Axes::ROWS);
    let target: Vec<T::Real> = bnorm
        .as_slice()
        .iter()
        .map(|&bn| params.tolerance * bn + params.absolute_tolerance)
        .collect();
    let scale: Vec<T::Real> = bnorm
        .as_slice()
        .iter()
        .map(|&bn| if bn > zero { bn } else { T::Real::ONE })
        .collect();
    let mut rz = r.ex().dot_over(z.ex(), Axes::ROWS).into_vec();
    let mut rnorm = r.ex().norm_over(Axes::ROWS).into_vec();
    let mut info = CgInfo {
        iterations: vec![0; nb],
        residual: vec![zero; nb],
        converged: vec![false; nb],
    };
    let mut alpha = Matrix::<T::Real>::zeros(1, 1, nb);
    let mut beta = Matrix::<T::Real>::zeros(1, 1, nb);

    for it in 0..=params.max_iterations {
        let mut active = false;
        for bi in 0..nb {
            if !num_traits::Float::is_finite(rnorm[bi]) || !num_traits::Float::is_finite(rz[bi]) {
                return Err(CgError::NonFinite {
                    batch: bi,
                    iteration: it,
                });
            }
            info.residual[bi] = rnorm[bi] / scale[bi];
            if !info.converged[bi] {
                if rnorm[bi] <= target[bi] {
                    info.converged[bi] = true;
                } else {
                    active = true;
                }
            }
        }
        if !active || it == params.max_iterations {
            break;
        }
        a.apply(&p, &mut q);
        let pq = p.ex().dot_over(q.ex(), Axes::ROWS);
        for bi in 0..nb {
            let step = if info.converged[bi] {
                zero
            } else {
                let c = pq.as_slice()[bi];
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
                info.iterations[bi] += 1;
                rz[bi] / c
            };
            alpha.set(0, 0, bi, step);
        }
        x.assign_with(|x| x + alpha.ex().cwise_mul(p.ex()));
        r.assign_with(|r| r - alpha.ex().cwise_mul(q.ex()));
        precond.apply(&r, &mut z);
        let rz_new = r.ex().dot_over(z.ex(), Axes::ROWS).into_vec();
        rnorm = r.ex().norm_over(Axes::ROWS).into_vec();
        for bi in 0..nb {
            let bt = if info.converged[bi] || rz[bi] == zero {
                zero
            } else {
                rz_new[bi] / rz[bi]
            };
            beta.set(0, 0, bi, bt);
        }
        rz = rz_new;
        p.assign_with(|p| z.ex() + beta.ex().cwise_mul(p));
    }
    if info.converged.iter().all(|&c| c) {
        Ok(info)
    } else {
        Err(CgError::NoConvergence { info })
    }
}
