//! Adapters that turn closures into objectives: [`FnObjective`] (cost and gradient) and
//! [`LeastSquaresFn`] (residuals and Jacobian, giving the Gauss-Newton matrix too).

use super::types::{EvalError, GaussNewtonObjective, GnEval, Objective};

/// An [`Objective`] from a closure `x -> (cost, gradient)`.
#[derive(Clone, Debug)]
pub struct FnObjective<F>(pub F);

impl<F> Objective for FnObjective<F>
where
    F: FnMut(&[f64]) -> Result<(f64, Vec<f64>), EvalError>,
{
    fn eval(&mut self, x: &[f64]) -> Result<(f64, Vec<f64>), EvalError> {
        (self.0)(x)
    }
}

/// A least-squares objective from a closure `x -> (r, J)` with residuals `r` (length `m`)
/// and their Jacobian `J` (`m x n`, row-major). The cost is `1/2 r'r`, the gradient
/// `J'r` and the Gauss-Newton matrix `J'J` (fold weights in as `sqrt(w_i) r_i`).
#[derive(Clone, Debug)]
pub struct LeastSquaresFn<F>(pub F);

impl<F> LeastSquaresFn<F>
where
    F: FnMut(&[f64]) -> Result<(Vec<f64>, Vec<f64>), EvalError>,
{
    #[track_caller]
    fn residuals(&mut self, x: &[f64]) -> Result<(Vec<f64>, Vec<f64>), EvalError> {
        let (r, j) = (self.0)(x)?;
        assert_eq!(
            j.len(),
            r.len() * x.len(),
            "LeastSquaresFn: Jacobian has {} entries, expected {} x {}",
            j.len(),
            r.len(),
            x.len()
        );
        Ok((r, j))
    }
}

impl<F> Objective for LeastSquaresFn<F>
where
    F: FnMut(&[f64]) -> Result<(Vec<f64>, Vec<f64>), EvalError>,
{
    fn eval(&mut self, x: &[f64]) -> Result<(f64, Vec<f64>), EvalError> {
        let (r, j) = self.residuals(x)?;
        let n = x.len();
        let mut g = vec![0.0; n];
        for (ri, row) in r.iter().zip(j.chunks_exact(n.max(1))) {
            for (gk, jk) in g.iter_mut().zip(row) {
                *gk += jk * ri;
            }
        }
        Ok((0.5 * r.iter().map(|v| v * v).sum::<f64>(), g))
    }
}

impl<F> GaussNewtonObjective for LeastSquaresFn<F>
where
    F: FnMut(&[f64]) -> Result<(Vec<f64>, Vec<f64>), EvalError>,
{
    fn eval_gn(&mut self, x: &[f64]) -> Result<GnEval, EvalError> {
        let (r, j) = self.residuals(x)?;
        let n = x.len();
        let mut gradient = vec![0.0; n];
        let mut hessian = vec![0.0; n * n];
        for (ri, row) in r.iter().zip(j.chunks_exact(n.max(1))) {
            for a in 0..n {
                gradient[a] += row[a] * ri;
                for b in 0..n {
                    hessian[a * n + b] += row[a] * row[b];
                }
            }
        }
        Ok(GnEval {
            cost: 0.5 * r.iter().map(|v| v * v).sum::<f64>(),
            gradient,
            hessian,
        })
    }
}
