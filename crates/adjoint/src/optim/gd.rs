//! Gradient descent with Barzilai-Borwein steps and a non-monotone safeguard
//! (Barzilai & Borwein 1988, "Two-point step size gradient methods", IMA J. Numer. Anal.
//! 8:141-148; globalized by Raydan 1997, SIAM J. Optim. 7:26-33, with the non-monotone
//! line search of Grippo, Lampariello & Lucidi 1986).
//!
//! The iteration is `x_{k+1} = x_k - a_k g_k` with the BB step
//!
//! ```text
//! a_{k+1} = s'_k s_k / s'_k y_k,    s_k = x_{k+1} - x_k,  y_k = g_{k+1} - g_k
//! ```
//!
//! (the inverse of a Rayleigh quotient of the average Hessian along the step). When
//! `s'y <= 0` (negative curvature) the next step keeps the length of the last one,
//! `a = ||s|| / ||g_{k+1}||`. The step is accepted when
//!
//! ```text
//! f(x_k - a g_k) <= max_{0 <= j < M} f(x_{k-j}) - c1 a ||g_k||^2,     M = 20,
//! ```
//!
//! otherwise `a` is reduced by safeguarded quadratic interpolation (to between 10% and
//! 50% of its value), or to 25% after a failed evaluation. The costs of the history can
//! therefore rise for a few iterations, but the reference cost cannot, so the method
//! cannot blow up; the best point evaluated is what is returned. (BB is chaotic: with
//! `M = 10`, as in Raydan's paper, a condition-1e4 quadratic in our tests fell into a
//! cycle of backtracked steps that never grew long enough; `M = 20` avoided it and was
//! no worse on Rosenbrock.)
//!
//! The first trial step has infinity norm `initial_step`: `a_0 = initial_step / ||g_0||_inf`.
//!
//! **Resuming:** start again from the last recorded (or the returned best) `x`; the BB
//! step is rebuilt from `initial_step`.

use std::collections::VecDeque;
use std::ops::ControlFlow;

use super::line_search::FAILURE_SHRINK;
use super::run::{add_scaled, dot, norm2, norm_inf, start_failed, sub, EvalFailure, Run};
use super::types::{IterationRecord, Objective, OptimParams, OptimResult, Termination};

/// Length `M` of the non-monotone window.
const WINDOW: usize = 20;
/// Bounds on the BB step.
const MIN_STEP: f64 = 1e-30;
const MAX_STEP: f64 = 1e30;

/// Minimizes `objective` from `x0` by gradient descent with Barzilai-Borwein steps.
///
/// The callback sees the start point (iteration 0) and every accepted step; `Break`
/// stops the run. The best point evaluated is returned (the iterates need not decrease
/// monotonically).
///
/// ```
/// use adjoint::optim::{gradient_descent_bb, EvalError, FnObjective, OptimParams};
/// use std::ops::ControlFlow;
/// let mut f = FnObjective(|x: &[f64]| -> Result<(f64, Vec<f64>), EvalError> {
///     Ok((x[0] * x[0] + 5.0 * x[1] * x[1], vec![2.0 * x[0], 10.0 * x[1]]))
/// });
/// let params = OptimParams { gradient_tolerance: 1e-9, ..Default::default() };
/// let (x, _) = gradient_descent_bb(&mut f, &[1.0, 1.0], &params, &mut |_| ControlFlow::Continue(())).unwrap();
/// assert!(x[0].abs() < 1e-8 && x[1].abs() < 1e-8);
/// ```
pub fn gradient_descent_bb<O: Objective + ?Sized>(
    objective: &mut O,
    x0: &[f64],
    params: &OptimParams,
    callback: &mut dyn FnMut(&IterationRecord) -> ControlFlow<()>,
) -> OptimResult {
    let mut run = Run::new(params, callback);
    let mut current = run.eval(objective, x0).map_err(start_failed)?;
    if let Some(t) = run.start(&current) {
        return run.finish(t);
    }
    let mut window: VecDeque<f64> = VecDeque::from([current.cost]);
    let mut step = params.initial_step / norm_inf(&current.gradient);
    loop {
        let reference = window.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let gg = dot(&current.gradient, &current.gradient);
        let mut a = step.clamp(MIN_STEP, MAX_STEP);
        let mut failures = 0;
        let mut trials = 0;
        let next = loop {
            if trials >= params.max_line_search_evaluations {
                return run.finish(Termination::LineSearchFailed);
            }
            trials += 1;
            let x = add_scaled(&current.x, -a, &current.gradient);
            match run.eval(objective, &x) {
                Ok(p) if p.cost <= reference - params.wolfe_c1 * a * gg => break p,
                Ok(p) => {
                    // minimizer of the quadratic through f(0), f'(0) = -gg and f(a)
                    let curvature = p.cost - current.cost + a * gg;
                    let q = if curvature > 0.0 {
                        0.5 * a * a * gg / curvature
                    } else {
                        0.5 * a
                    };
                    a = q.clamp(0.1 * a, 0.5 * a);
                    failures = 0;
                }
                Err(EvalFailure::Failed(message)) => {
                    failures += 1;
                    if failures > params.max_consecutive_failures {
                        return run.finish(Termination::Diverged { message });
                    }
                    a *= FAILURE_SHRINK;
                }
                Err(failure) => return run.finish_failure(failure),
            }
        };
        let s = sub(&next.x, &current.x);
        let y = sub(&next.gradient, &current.gradient);
        let (ss, sy) = (dot(&s, &s), dot(&s, &y));
        let step_norm = ss.sqrt();
        step = if sy > 0.0 {
            ss / sy
        } else {
            step_norm / norm2(&next.gradient).max(f64::MIN_POSITIVE)
        };
        current = next;
        if window.len() == WINDOW {
            window.pop_front();
        }
        window.push_back(current.cost);
        if let Some(t) = run.accept(reference, &current, step_norm) {
            return run.finish(t);
        }
    }
}
