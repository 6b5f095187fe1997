//! The smoothers of the multigrid levels, both polynomials in `D^-1 A` (`D`: the 3x3 diagonal
//! blocks), hence self-adjoint in the `A` inner product, so that a V-cycle with the same
//! smoother before and after the coarse correction is symmetric:
//!
//! - damped block-Jacobi, `x <- x + omega D^-1 (b - A x)`, `nu` sweeps: error propagation
//!   `(I - omega D^-1 A)^nu`, convergent while `omega lambda_max(D^-1 A) < 2`;
//! - Chebyshev of degree `nu` on `D^-1 A` over `[lower, upper] = [f, 1.1] lambda` (`f`: [`MultigridParams::chebyshev_lower`](super::MultigridParams), default 0.1), with
//!   `lambda` a power-iteration estimate of `lambda_max(D^-1 A)` ([`estimate_lambda_max`]): the
//!   error propagation is the scaled Chebyshev polynomial `T_nu((theta - t) / delta) /
//!   T_nu(theta / delta)` (`theta`, `delta`: centre and half width of the interval), smallest
//!   over the upper part of the spectrum whatever its scale (three-term recurrence, Saad,
//!   *Iterative methods for sparse linear systems*, Alg. 12.1).

use crate::block::{Mat3, Vec3};
use crate::matrix::Matrix;
use crate::sparse::SparseMatrix;

/// Power iterations of [`estimate_lambda_max`].
const POWER_ITERATIONS: usize = 10;
/// The Chebyshev interval's upper end relative to the estimate of `lambda_max(D^-1 A)`.
const CHEBYSHEV_UPPER: f64 = 1.1;

/// Which smoother the levels use (the module docs of [`Multigrid`](super::Multigrid)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Smoother {
    /// damped block-Jacobi, `sweeps` sweeps with damping `omega`
    Jacobi,
    /// Chebyshev polynomial of degree `sweeps` in `D^-1 A`
    #[default]
    Chebyshev,
}

/// The largest eigenvalue of `D^-1 A` estimated by power iteration (the ratio of successive
/// norms), from a fixed start vector: deterministic.
pub(super) fn estimate_lambda_max(a: &SparseMatrix<Mat3<f64>>, dinv: &Matrix<Mat3<f64>>) -> f64 {
    let n = a.rows();
    let mut x = Matrix::from_fn(n, 1, 1, |r, _, _| {
        let h = (r as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let f = |s: u32| ((h >> s) & 0xFFFF) as f64 / 65536.0 + 0.5;
        Vec3::new(f(0), f(16), f(32))
    });
    let mut y = Matrix::zeros(n, 1, 1);
    let mut lambda = 0.0;
    let mut norm = x.ex().norm();
    for _ in 0..POWER_ITERATIONS {
        if norm == 0.0 || !norm.is_finite() {
            break;
        }
        y.assign(dinv.ex().cwise_mul(a * x.ex()) * (1.0 / norm));
        let ny = y.ex().norm();
        lambda = ny;
        std::mem::swap(&mut x, &mut y);
        norm = ny;
    }
    lambda
}

/// What one level's smoothing needs.
pub(super) struct Smoothing<'a> {
    pub a: &'a SparseMatrix<Mat3<f64>>,
    pub dinv: &'a Matrix<Mat3<f64>>,
    pub lambda: f64,
    pub kind: Smoother,
    pub sweeps: usize,
    pub omega: f64,
    /// the Chebyshev interval's lower end relative to `lambda`
    pub lower: f64,
}

impl Smoothing<'_> {
    /// Smooths `A x = b` in place; `zero`: `x` is zero on entry (saves a product). `t` and `d`
    /// are scratch of `b`'s shape.
    pub(super) fn run(
        &self,
        b: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        zero: bool,
        t: &mut Matrix<Vec3<f64>>,
        d: &mut Matrix<Vec3<f64>>,
    ) {
        let (a, dinv) = (self.a, self.dinv);
        match self.kind {
            Smoother::Jacobi => {
                let w = self.omega;
                for s in 0..self.sweeps {
                    if s == 0 && zero {
                        x.assign(dinv.ex().cwise_mul(b.ex()) * w);
                    } else {
                        t.assign(x.ex() + dinv.ex().cwise_mul(b - a * &*x) * w);
                        std::mem::swap(x, t);
                    }
                }
            }
            Smoother::Chebyshev => {
                let (lower, upper) = (self.lower * self.lambda, CHEBYSHEV_UPPER * self.lambda);
                let theta = 0.5 * (upper + lower);
                let delta = 0.5 * (upper - lower);
                let sigma = theta / delta;
                let mut rho = 1.0 / sigma;
                if zero {
                    d.assign(dinv.ex().cwise_mul(b.ex()) * (1.0 / theta));
                    x.assign(d.ex());
                } else {
                    d.assign(dinv.ex().cwise_mul(b - a * &*x) * (1.0 / theta));
                    x.assign_with(|x| x + d.ex());
                }
                for _ in 1..self.sweeps {
                    let next = 1.0 / (2.0 * sigma - rho);
                    let (c1, c2) = (next * rho, 2.0 * next / delta);
                    {
                        let xr = &*x;
                        d.assign_with(|d| d * c1 + dinv.ex().cwise_mul(b - a * xr) * c2);
                    }
                    x.assign_with(|x| x + d.ex());
                    rho = next;
                }
            }
        }
    }
}
