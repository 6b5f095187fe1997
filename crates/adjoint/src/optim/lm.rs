//! Levenberg-Marquardt with Nielsen's damping update (Levenberg 1944; Marquardt 1963;
//! Nielsen 1999, "Damping parameter in Marquardt's method", IMM-REP-1999-05; Madsen,
//! Nielsen & Tingleff 2004, *Methods for non-linear least squares problems*, Alg. 3.16;
//! Moré 1978 for the scaling).
//!
//! For `f(x) = 1/2 r' W r` with gradient `g = J' W r` and Gauss-Newton matrix
//! `H = J' W J`, each trial step solves
//!
//! ```text
//! (H + mu D) h = -g,        D = I (Levenberg) or D = diag(d_i) (Marquardt),
//! ```
//!
//! with `d_i = max(H_ii, d_i of earlier iterations)` (Moré's running maximum, kept above
//! `1e-12 max_j d_j` so that a parameter without sensitivity stays damped). The system
//! is solved by a dense Cholesky factorization ([`gpumat::solve::SmallCholesky`]); if it
//! fails, `mu` is raised. The gain ratio compares the actual decrease with the one predicted
//! by the quadratic model `L(h) = f + g'h + 1/2 h'Hh`:
//!
//! ```text
//! rho = (f(x) - f(x + h)) / (L(0) - L(h)),   L(0) - L(h) = -g'h - 1/2 h'Hh = 1/2 h'(mu D h - g)
//! ```
//!
//! If `rho > 0` the step is accepted and `mu <- mu max(1/3, 1 - (2 rho - 1)^3)`, `nu <- 2`
//! (Nielsen); otherwise `mu <- mu nu`, `nu <- 2 nu`. A trial where the objective fails is
//! treated as a rejection. Costs of accepted iterates therefore decrease strictly.
//!
//! The initial damping is `mu_0 = tau max_i H_ii` (Levenberg) or `mu_0 = tau` (Marquardt)
//! with `tau = initial_damping`. Every trial point is evaluated with
//! [`GaussNewtonObjective::eval_gn`] (the matrix is needed there once the step is
//! accepted); an iteration is one accepted step, rejections only cost evaluations.
//!
//! **Resuming:** start again from the last recorded `x`; the damping restarts from
//! `initial_damping` (pass a larger one to resume cautiously).

use std::ops::ControlFlow;

use super::run::{add_scaled, dot, norm2, start_failed, EvalFailure, Run};
use super::types::{Damping, GaussNewtonObjective, IterationRecord, OptimParams, OptimResult, Termination};
use gpumat::solve::SmallCholesky;

/// Damping beyond which no step can make progress.
const MAX_DAMPING: f64 = 1e100;

/// Minimizes the least-squares `objective` from `x0` by Levenberg-Marquardt.
///
/// The callback sees the start point (iteration 0) and every accepted step; `Break`
/// stops the run. The history costs decrease strictly.
///
/// ```
/// use adjoint::optim::{levenberg_marquardt, LeastSquaresFn, OptimParams};
/// use std::ops::ControlFlow;
/// // r = [x0 - 1, 10 (x1 - x0^2)], J = [[1, 0], [-20 x0, 10]]
/// let mut f = LeastSquaresFn(|x: &[f64]| {
///     Ok((vec![x[0] - 1.0, 10.0 * (x[1] - x[0] * x[0])], vec![1.0, 0.0, -20.0 * x[0], 10.0]))
/// });
/// let params = OptimParams { gradient_tolerance: 1e-12, ..Default::default() };
/// let (x, info) = levenberg_marquardt(&mut f, &[-1.2, 1.0], &params, &mut |_| ControlFlow::Continue(())).unwrap();
/// assert!((x[0] - 1.0).abs() < 1e-8 && (x[1] - 1.0).abs() < 1e-8, "{x:?} {info:?}");
/// ```
pub fn levenberg_marquardt<O: GaussNewtonObjective + ?Sized>(
    objective: &mut O,
    x0: &[f64],
    params: &OptimParams,
    callback: &mut dyn FnMut(&IterationRecord) -> ControlFlow<()>,
) -> OptimResult {
    let n = x0.len();
    let mut run = Run::new(params, callback);
    let (mut current, mut hessian) = run.eval_gn(objective, x0).map_err(start_failed)?;
    if let Some(t) = run.start(&current) {
        return run.finish(t);
    }
    let mut scale = match params.damping {
        Damping::Levenberg => vec![1.0; n],
        Damping::Marquardt => vec![0.0; n],
    };
    update_scale(&mut scale, &hessian, params.damping);
    let max_diag = (0..n).fold(0.0_f64, |m, i| m.max(hessian[i * n + i]));
    let mut mu = match params.damping {
        Damping::Levenberg if max_diag > 0.0 => params.initial_damping * max_diag,
        _ => params.initial_damping,
    };
    let mut nu = 2.0;
    loop {
        let mut failures = 0;
        let mut rejections = 0;
        let (next, next_hessian, step_norm) = loop {
            if rejections >= params.max_line_search_evaluations || mu > MAX_DAMPING {
                return run.finish(Termination::LineSearchFailed);
            }
            let mut a = hessian.clone();
            for i in 0..n {
                a[i * n + i] += mu * scale[i];
            }
            let Some(chol) = SmallCholesky::factor(&a, n) else {
                raise(&mut mu, &mut nu);
                continue;
            };
            let minus_g: Vec<f64> = current.gradient.iter().map(|v| -v).collect();
            let h = chol.solve(&minus_g);
            let step_norm = norm2(&h);
            let x = add_scaled(&current.x, 1.0, &h);
            if run.small_step(step_norm, &current.x) || x == current.x {
                return run.finish(Termination::StepTolerance);
            }
            let scaled_h: Vec<f64> = (0..n).map(|i| mu * scale[i] * h[i]).collect();
            let predicted = 0.5 * (dot(&h, &scaled_h) - dot(&h, &current.gradient));
            match run.eval_gn(objective, &x) {
                Ok((p, hp)) => {
                    failures = 0;
                    let rho = (current.cost - p.cost) / predicted;
                    if rho > 0.0 && p.cost < current.cost {
                        mu *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                        nu = 2.0;
                        break (p, hp, step_norm);
                    }
                    rejections += 1;
                }
                Err(EvalFailure::Failed(message)) => {
                    failures += 1;
                    if failures > params.max_consecutive_failures {
                        return run.finish(Termination::Diverged { message });
                    }
                }
                Err(EvalFailure::Budget) => return run.finish(Termination::MaxEvaluations),
            }
            raise(&mut mu, &mut nu);
        };
        let reference = current.cost;
        current = next;
        hessian = next_hessian;
        update_scale(&mut scale, &hessian, params.damping);
        if let Some(t) = run.accept(reference, &current, step_norm) {
            return run.finish(t);
        }
    }
}

/// Marquardt's scaling with Moré's running maximum; `D = I` for Levenberg.
fn update_scale(scale: &mut [f64], hessian: &[f64], damping: Damping) {
    if damping == Damping::Levenberg {
        return;
    }
    let n = scale.len();
    for i in 0..n {
        scale[i] = scale[i].max(hessian[i * n + i]);
    }
    let max = scale.iter().copied().fold(0.0, f64::max);
    let floor = if max > 0.0 { 1e-12 * max } else { 1.0 };
    for s in scale.iter_mut() {
        *s = s.max(floor);
    }
}

/// Nielsen's increase after a rejected step: `mu <- mu nu`, `nu <- 2 nu`.
fn raise(mu: &mut f64, nu: &mut f64) {
    *mu *= *nu;
    *nu *= 2.0;
}
