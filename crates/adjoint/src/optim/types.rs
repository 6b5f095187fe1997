//! The shared vocabulary of the optimizers: the objective traits, [`OptimParams`],
//! [`OptimInfo`] with its per-iteration [`IterationRecord`]s, the [`Termination`] reason
//! and [`OptimError`].
//!
//! Conventions used throughout:
//!
//! * `x` lives in an unconstrained space (the caller maps `log E`, `logit nu`, ...).
//! * The gradient norm in tolerances and records is the infinity norm `||g||_inf`.
//! * Step and point norms in the step tolerance are Euclidean.
//! * A least-squares cost is `f(x) = 1/2 sum_i w_i r_i(x)^2` (note the 1/2), so that its
//!   gradient is `J^T W r` and its Gauss-Newton matrix `J^T W J`.

use std::fmt;

use serde::Serialize;

/// A failed evaluation of the objective: typically the forward simulation diverged for
/// these parameters (e.g. "CG diverged at step 12"). The optimizers treat it as "this
/// point is too far": they shrink the step (line searches) or raise the damping
/// (Levenberg-Marquardt), and report [`Termination::Diverged`] when that does not help.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct EvalError {
    /// What went wrong, in words.
    pub message: String,
}

impl EvalError {
    /// An evaluation failure with the given message.
    pub fn new(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
        }
    }
}

/// A differentiable cost `f : R^n -> R`.
///
/// `eval` returns the cost and its gradient (length `n`). A non-finite cost or gradient
/// is treated like an [`EvalError`]. A gradient of the wrong length is a bug in the
/// objective and panics.
pub trait Objective {
    /// The cost `f(x)` and its gradient `grad f(x)`.
    fn eval(&mut self, x: &[f64]) -> Result<(f64, Vec<f64>), EvalError>;
}

/// Cost, gradient and Gauss-Newton matrix at one point, see [`GaussNewtonObjective`].
#[derive(Clone, Debug, PartialEq)]
pub struct GnEval {
    /// `f = 1/2 sum_i w_i r_i^2` (note the 1/2).
    pub cost: f64,
    /// `g = J^T W r`, length `n`.
    pub gradient: Vec<f64>,
    /// The Gauss-Newton matrix `J^T W J`, `n x n` row-major, symmetric positive
    /// semi-definite. Only the lower triangle is read. For a robust (e.g. Huber) cost use
    /// the IRLS weights `W = diag(psi(r_i) / r_i)`; the matrix then stays PSD and the
    /// gradient must still be the exact gradient of the robust cost.
    pub hessian: Vec<f64>,
}

/// A least-squares objective that can also give its Gauss-Newton matrix
/// (needed by [`levenberg_marquardt`](super::levenberg_marquardt)).
pub trait GaussNewtonObjective: Objective {
    /// Cost, gradient and Gauss-Newton matrix at `x`, see [`GnEval`].
    fn eval_gn(&mut self, x: &[f64]) -> Result<GnEval, EvalError>;
}

/// Damping matrix `D` of Levenberg-Marquardt, `(H + mu D) dx = -g`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Damping {
    /// `D = I` (Levenberg); `mu_0 = initial_damping * max_i H_ii`.
    Levenberg,
    /// `D = diag(H)` with Moré's running maximum of the diagonal (Marquardt; invariant
    /// under rescaling of the parameters); `mu_0 = initial_damping`.
    Marquardt,
}

/// Parameters shared by all optimizers (each field says who reads it).
///
/// Stopping tests run after every accepted step, in this order:
/// 1. gradient: `||g||_inf <= gradient_tolerance * ||g_0||_inf + absolute_gradient_tolerance`
///    (also checked at the start point),
/// 2. cost: `f_ref - f_new <= cost_tolerance * |f_ref|`, where `f_ref` is the cost before
///    the step (for the non-monotone gradient descent, the reference cost of its window),
/// 3. step: `||dx||_2 <= step_tolerance * (||x||_2 + step_tolerance)`,
/// 4. `max_iterations` accepted steps, 5. `max_evaluations` evaluations.
///
/// Set a tolerance to 0 to switch that test off.
#[derive(Clone, Debug, PartialEq)]
pub struct OptimParams {
    /// Maximum number of accepted steps (iterations).
    pub max_iterations: usize,
    /// Maximum number of objective evaluations, failed ones included (the first one, at
    /// the start point, is always made).
    pub max_evaluations: usize,
    /// Gradient tolerance relative to the start point's `||g_0||_inf`.
    pub gradient_tolerance: f64,
    /// Absolute gradient tolerance added to the relative one.
    pub absolute_gradient_tolerance: f64,
    /// Relative cost decrease below which an accepted step ends the run.
    pub cost_tolerance: f64,
    /// Relative step length below which the run ends.
    pub step_tolerance: f64,
    /// Failed evaluations in a row (each followed by a shrink of the step or a raise of
    /// the damping) after which the run ends with [`Termination::Diverged`].
    pub max_consecutive_failures: usize,
    /// Infinity norm of the first trial step of gradient descent and L-BFGS (and after an
    /// L-BFGS memory reset): the first step is `-initial_step * g / ||g||_inf`.
    pub initial_step: f64,
    /// L-BFGS: number of stored correction pairs `(s, y)`.
    pub lbfgs_memory: usize,
    /// Line searches: sufficient-decrease constant `c1` (Armijo).
    pub wolfe_c1: f64,
    /// L-BFGS line search: curvature constant `c2` of the strong Wolfe conditions.
    pub wolfe_c2: f64,
    /// Evaluations allowed in one line search (or LM rejections in a row) before giving up.
    pub max_line_search_evaluations: usize,
    /// Levenberg-Marquardt: damping matrix.
    pub damping: Damping,
    /// Levenberg-Marquardt: initial damping factor `tau` (see [`Damping`]).
    pub initial_damping: f64,
}

impl Default for OptimParams {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            max_evaluations: 300,
            gradient_tolerance: 1e-6,
            absolute_gradient_tolerance: 0.0,
            cost_tolerance: 1e-10,
            step_tolerance: 1e-10,
            max_consecutive_failures: 10,
            initial_step: 0.1,
            lbfgs_memory: 8,
            wolfe_c1: 1e-4,
            wolfe_c2: 0.9,
            max_line_search_evaluations: 20,
            damping: Damping::Marquardt,
            initial_damping: 1e-3,
        }
    }
}

impl OptimParams {
    /// Panics (naming the field) if a parameter is out of range.
    #[track_caller]
    pub fn validate(&self) {
        let p = self;
        let nonneg = [
            ("gradient_tolerance", p.gradient_tolerance),
            ("absolute_gradient_tolerance", p.absolute_gradient_tolerance),
            ("cost_tolerance", p.cost_tolerance),
            ("step_tolerance", p.step_tolerance),
        ];
        for (name, v) in nonneg {
            assert!(v >= 0.0, "adjoint::optim: {name} = {v} must be >= 0");
        }
        assert!(
            p.initial_step > 0.0 && p.initial_step.is_finite(),
            "adjoint::optim: initial_step = {} must be positive",
            p.initial_step
        );
        assert!(
            0.0 < p.wolfe_c1 && p.wolfe_c1 < p.wolfe_c2 && p.wolfe_c2 < 1.0,
            "adjoint::optim: need 0 < wolfe_c1 < wolfe_c2 < 1, got {} and {}",
            p.wolfe_c1,
            p.wolfe_c2
        );
        assert!(
            p.initial_damping > 0.0 && p.initial_damping.is_finite(),
            "adjoint::optim: initial_damping = {} must be positive",
            p.initial_damping
        );
        assert!(
            p.max_line_search_evaluations > 0,
            "adjoint::optim: max_line_search_evaluations must be positive"
        );
    }
}

/// Why an optimizer stopped.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "reason", rename_all = "snake_case")]
pub enum Termination {
    /// The gradient tolerance was met.
    GradientTolerance,
    /// An accepted step decreased the cost by less than the cost tolerance.
    CostTolerance,
    /// The step became shorter than the step tolerance.
    StepTolerance,
    /// `max_iterations` steps were taken.
    MaxIterations,
    /// `max_evaluations` evaluations were spent.
    MaxEvaluations,
    /// The objective kept failing (e.g. the simulation diverged) although the step was
    /// shrunk or the damping raised `max_consecutive_failures` times in a row, or it
    /// failed at the start point.
    Diverged {
        /// The objective's last error message.
        message: String,
    },
    /// No step along the search direction decreased the cost enough (the gradient may be
    /// inaccurate, or the cost is at round-off level).
    LineSearchFailed,
    /// The callback asked to stop.
    Stopped,
}

impl fmt::Display for Termination {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::GradientTolerance => write!(f, "converged: gradient below tolerance"),
            Self::CostTolerance => write!(f, "converged: cost decrease below tolerance"),
            Self::StepTolerance => write!(f, "converged: step below tolerance"),
            Self::MaxIterations => write!(f, "stopped: iteration limit reached"),
            Self::MaxEvaluations => write!(f, "stopped: evaluation limit reached"),
            Self::Diverged { message } => {
                write!(
                    f,
                    "stopped: the objective failed and backtracking did not help ({message})"
                )
            }
            Self::LineSearchFailed => {
                write!(f, "stopped: no step decreased the cost (line search failed)")
            }
            Self::Stopped => write!(f, "stopped by the caller"),
        }
    }
}

impl Termination {
    /// Whether this is one of the convergence tests (gradient, cost, step).
    pub fn is_converged(&self) -> bool {
        matches!(
            self,
            Self::GradientTolerance | Self::CostTolerance | Self::StepTolerance
        )
    }
}

/// The state after one iteration (iteration 0 is the start point).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IterationRecord {
    /// Iteration number, 0 for the start point.
    pub iteration: usize,
    /// Cost at `x`.
    pub cost: f64,
    /// `||g||_inf` at `x`.
    pub gradient_norm: f64,
    /// `||dx||_2` of the step that led here (0 at the start point).
    pub step_norm: f64,
    /// The current iterate.
    pub x: Vec<f64>,
    /// Evaluations spent so far (failed ones included).
    pub evaluations: usize,
}

/// What an optimizer did. The returned point is the best one evaluated (lowest cost).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OptimInfo {
    /// Accepted steps.
    pub iterations: usize,
    /// Objective evaluations, failed ones included.
    pub evaluations: usize,
    /// Evaluations that returned an error (or a non-finite value).
    pub failed_evaluations: usize,
    /// Why the run ended.
    pub termination: Termination,
    /// Cost at the returned point.
    pub cost: f64,
    /// Gradient at the returned point.
    pub gradient: Vec<f64>,
    /// One record per iteration, starting with the start point (iteration 0).
    pub history: Vec<IterationRecord>,
}

/// Why an optimizer could not return any point.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum OptimError {
    /// The objective failed at the start point (or the start point is not finite).
    #[error("the objective failed at the starting point: {message}")]
    StartFailed {
        /// The objective's error message.
        message: String,
    },
}

impl OptimError {
    /// The termination reason this error stands for ([`Termination::Diverged`]).
    pub fn termination(&self) -> Termination {
        match self {
            Self::StartFailed { message } => Termination::Diverged {
                message: message.clone(),
            },
        }
    }
}

/// The result of every optimizer: the best point and what happened.
pub type OptimResult = Result<(Vec<f64>, OptimInfo), OptimError>;
