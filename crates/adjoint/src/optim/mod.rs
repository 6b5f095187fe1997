//! Derivative-based optimizers for parameter reconstruction (thesis ch. 5).
//!
//! The problem is `min_x f(x)`, `x in R^n` with small `n` (1..30) already in an
//! unconstrained space, `f` a sum of squared (or Huber) residuals between a simulation and
//! measurements, and `grad f` from the adjoint method. Each evaluation costs seconds and
//! may fail (the forward simulation diverged), so the methods here
//!
//! * count every evaluation (`max_evaluations`) and return the best point ever evaluated,
//! * treat a failed evaluation ([`EvalError`]) as a step that went too far: line
//!   searches shrink the step, Levenberg-Marquardt raises its damping, and only after
//!   `max_consecutive_failures` failures in a row does the run end with
//!   [`Termination::Diverged`]; a failure at the start point is [`OptimError::StartFailed`],
//! * report every iteration to a callback as soon as it completes (iteration 0 is the
//!   start point), which may stop the run.
//!
//! | [`Optimizer`] | function | needs | method |
//! |---|---|---|---|
//! | `gd` | [`gradient_descent_bb`] | [`Objective`] | Barzilai & Borwein 1988 steps, non-monotone safeguard (Raydan 1997) |
//! | `lbfgs` | [`lbfgs`] | [`Objective`] | L-BFGS, Nocedal & Wright Alg. 7.4/7.5, strong-Wolfe search (Alg. 3.5/3.6) |
//! | `gauss-newton` | [`levenberg_marquardt`] | [`GaussNewtonObjective`] | Levenberg-Marquardt, Nielsen's damping update, Marquardt/Moré scaling |
//!
//! All share [`OptimParams`] (stopping rules documented there) and return
//! [`OptimResult`] = `Result<(best x, OptimInfo), OptimError>`.
//!
//! **Resuming** a run: call again with the last recorded `x` (from the log the callback
//! wrote) as the start. Internal state is not carried over: L-BFGS rebuilds its memory,
//! gradient descent its step, Levenberg-Marquardt restarts its damping from
//! `initial_damping`. Iteration numbers restart at 0; add the earlier count when
//! appending to a log.
//!
//! ```
//! use adjoint::optim::{minimize, LeastSquaresFn, OptimParams, Optimizer, Termination};
//! use std::ops::ControlFlow;
//! // Rosenbrock as least squares: r = [10 (x1 - x0^2), 1 - x0]
//! let mut f = LeastSquaresFn(|x: &[f64]| {
//!     Ok((vec![10.0 * (x[1] - x[0] * x[0]), 1.0 - x[0]], vec![-20.0 * x[0], 10.0, -1.0, 0.0]))
//! });
//! let optimizer: Optimizer = "lbfgs".parse().unwrap();
//! let params = OptimParams { gradient_tolerance: 1e-10, ..Default::default() };
//! let mut log = Vec::new();
//! let (x, info) = minimize(optimizer, &mut f, &[-1.2, 1.0], &params, &mut |rec| {
//!     log.push(rec.cost);
//!     ControlFlow::Continue(())
//! })
//! .unwrap();
//! assert!((x[0] - 1.0).abs() < 1e-6 && (x[1] - 1.0).abs() < 1e-6);
//! assert_eq!(log.len(), info.history.len());
//! assert!(info.termination.is_converged());
//! ```

mod gd;
mod lbfgs;
mod line_search;
mod lm;
mod objective;
mod run;
mod types;

use std::fmt;
use std::ops::ControlFlow;
use std::str::FromStr;

pub use gd::gradient_descent_bb;
pub use lbfgs::lbfgs;
pub use lm::levenberg_marquardt;
pub use objective::{FnObjective, LeastSquaresFn};
pub use types::{
    Damping, EvalError, GaussNewtonObjective, GnEval, IterationRecord, Objective, OptimError, OptimInfo,
    OptimParams, OptimResult, Termination,
};

/// The optimizers by their interface names (`[fit].optimizer`, `--optimizer`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Optimizer {
    /// `lbfgs`: [`lbfgs`].
    #[serde(rename = "lbfgs")]
    Lbfgs,
    /// `gd`: [`gradient_descent_bb`].
    #[serde(rename = "gd")]
    GradientDescent,
    /// `gauss-newton`: [`levenberg_marquardt`].
    #[serde(rename = "gauss-newton")]
    GaussNewton,
}

impl Optimizer {
    /// All optimizers, in the order of the interface documentation.
    pub const ALL: [Optimizer; 3] = [Self::Lbfgs, Self::GradientDescent, Self::GaussNewton];

    /// The interface name: `lbfgs`, `gd` or `gauss-newton`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Lbfgs => "lbfgs",
            Self::GradientDescent => "gd",
            Self::GaussNewton => "gauss-newton",
        }
    }
}

impl fmt::Display for Optimizer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An optimizer name that is not one of `lbfgs`, `gd`, `gauss-newton`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown optimizer `{name}` (expected one of: lbfgs, gd, gauss-newton)")]
pub struct UnknownOptimizer {
    /// The name given.
    pub name: String,
}

impl FromStr for Optimizer {
    type Err = UnknownOptimizer;

    /// Parses an interface name (exact, lower case).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|o| o.name() == s)
            .ok_or_else(|| UnknownOptimizer { name: s.to_owned() })
    }
}

/// Runs `optimizer` on `objective` from `x0`.
///
/// The objective must provide the Gauss-Newton matrix so that every optimizer can be
/// chosen at run time; gradient descent and L-BFGS only call [`Objective::eval`]. (For an
/// objective without it, call [`lbfgs`] or [`gradient_descent_bb`] directly.)
pub fn minimize<O: GaussNewtonObjective + ?Sized>(
    optimizer: Optimizer,
    objective: &mut O,
    x0: &[f64],
    params: &OptimParams,
    callback: &mut dyn FnMut(&IterationRecord) -> ControlFlow<()>,
) -> OptimResult {
    match optimizer {
        Optimizer::Lbfgs => lbfgs(objective, x0, params, callback),
        Optimizer::GradientDescent => gradient_descent_bb(objective, x0, params, callback),
        Optimizer::GaussNewton => levenberg_marquardt(objective, x0, params, callback),
    }
}
