//! Limited-memory BFGS (Nocedal & Wright, *Numerical Optimization*, 2nd ed., Alg. 7.4
//! and 7.5; Liu & Nocedal 1989).
//!
//! With the last `m` pairs `s_k = x_{k+1} - x_k`, `y_k = g_{k+1} - g_k`, the direction is
//! `d = -H g`, where `H` is the L-BFGS inverse-Hessian approximation applied by the
//! two-loop recursion (Alg. 7.4) with the initial matrix `H_0 = gamma I`,
//! `gamma = s'y / y'y` of the newest pair (N&W eq. 7.20). The step length comes from the
//! strong-Wolfe line search ([`line_search`](super::line_search), Alg. 3.5/3.6,
//! `c1 = 1e-4`, `c2 = 0.9`), trying `a = 1` first.
//!
//! * A pair is stored only when `s'y > 1e-10 ||s|| ||y||` (positive curvature), which
//!   keeps `H` positive definite; otherwise the update is skipped.
//! * With an empty memory (first iteration, or after a reset) the direction is `-g` and
//!   the first trial step has infinity norm `initial_step`.
//! * If the direction is not a descent direction, or its line search finds no decrease,
//!   the memory is dropped and the iteration is retried along `-g`; a failing steepest
//!   descent search ends the run with [`Termination::LineSearchFailed`].
//!
//! **Resuming:** start again from the last recorded `x`; the memory is not saved, so the
//! resumed run rebuilds it from scratch (its first step is a scaled gradient step).

use std::collections::VecDeque;
use std::ops::ControlFlow;

use super::line_search::{strong_wolfe, LineSearchFailure};
use super::run::{dot, norm2, norm_inf, start_failed, sub, Run};
use super::types::{IterationRecord, Objective, OptimParams, OptimResult, Termination};

/// Curvature threshold: pairs with `s'y <= CURVATURE_EPS ||s|| ||y||` are skipped.
const CURVATURE_EPS: f64 = 1e-10;

/// One correction pair with `rho = 1 / s'y`.
struct Pair {
    s: Vec<f64>,
    y: Vec<f64>,
    rho: f64,
}

/// `-H g` by the two-loop recursion (N&W Alg. 7.4), newest pair last in `memory`.
fn direction(memory: &VecDeque<Pair>, g: &[f64]) -> Vec<f64> {
    let mut q: Vec<f64> = g.iter().map(|v| -v).collect();
    let mut alpha = vec![0.0; memory.len()];
    for (i, p) in memory.iter().enumerate().rev() {
        alpha[i] = p.rho * dot(&p.s, &q);
        for (q, y) in q.iter_mut().zip(&p.y) {
            *q -= alpha[i] * y;
        }
    }
    if let Some(p) = memory.back() {
        let gamma = 1.0 / (p.rho * dot(&p.y, &p.y));
        q.iter_mut().for_each(|v| *v *= gamma);
    }
    for (i, p) in memory.iter().enumerate() {
        let beta = p.rho * dot(&p.y, &q);
        for (q, s) in q.iter_mut().zip(&p.s) {
            *q += (alpha[i] - beta) * s;
        }
    }
    q
}

/// Minimizes `objective` from `x0` by L-BFGS with a strong-Wolfe line search.
///
/// The callback sees the start point (iteration 0) and every accepted step; `Break`
/// stops the run ([`Termination::Stopped`]). The best point evaluated is returned.
///
/// ```
/// use adjoint::optim::{lbfgs, EvalError, FnObjective, OptimParams};
/// use std::ops::ControlFlow;
/// // f(x) = (x0 - 1)^2 + 10 (x1 + 2)^2
/// let mut f = FnObjective(|x: &[f64]| -> Result<(f64, Vec<f64>), EvalError> {
///     let (a, b) = (x[0] - 1.0, x[1] + 2.0);
///     Ok((a * a + 10.0 * b * b, vec![2.0 * a, 20.0 * b]))
/// });
/// let params = OptimParams { gradient_tolerance: 1e-10, ..Default::default() };
/// let (x, info) = lbfgs(&mut f, &[0.0, 0.0], &params, &mut |_| ControlFlow::Continue(())).unwrap();
/// assert!((x[0] - 1.0).abs() < 1e-8 && (x[1] + 2.0).abs() < 1e-8);
/// assert!(info.termination.is_converged());
/// ```
pub fn lbfgs<O: Objective + ?Sized>(
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
    let m = params.lbfgs_memory.max(1);
    let mut memory: VecDeque<Pair> = VecDeque::with_capacity(m);
    loop {
        let g = &current.gradient;
        let mut d = direction(&memory, g);
        let slope = dot(g, &d);
        if memory.is_empty() || slope >= 0.0 || slope.is_nan() {
            memory.clear();
            d = g.iter().map(|v| -v).collect();
        }
        let a1 = if memory.is_empty() {
            params.initial_step / norm_inf(g)
        } else {
            1.0
        };
        let (_, next) = match strong_wolfe(&mut run, objective, &current, &d, a1) {
            Ok(found) => found,
            Err(LineSearchFailure::NoProgress) if !memory.is_empty() => {
                memory.clear();
                continue;
            }
            Err(LineSearchFailure::NoProgress) => return run.finish(Termination::LineSearchFailed),
            Err(LineSearchFailure::Budget) => return run.finish(Termination::MaxEvaluations),
            Err(LineSearchFailure::Diverged(message)) => {
                return run.finish(Termination::Diverged { message })
            }
        };
        let s = sub(&next.x, &current.x);
        let y = sub(&next.gradient, &current.gradient);
        let sy = dot(&s, &y);
        let step_norm = norm2(&s);
        if sy > CURVATURE_EPS * step_norm * norm2(&y) {
            if memory.len() == m {
                memory.pop_front();
            }
            memory.push_back(Pair { s, y, rho: 1.0 / sy });
        }
        let reference = current.cost;
        current = next;
        if let Some(t) = run.accept(reference, &current, step_norm) {
            return run.finish(t);
        }
    }
}
