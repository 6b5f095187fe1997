//! Book-keeping shared by the optimizers: counting and checking evaluations, keeping the
//! best point, recording iterations, calling the callback and testing the stopping
//! criteria of [`OptimParams`].

use std::ops::ControlFlow;

use super::types::{
    EvalError, GaussNewtonObjective, IterationRecord, Objective, OptimError, OptimInfo, OptimParams,
    OptimResult, Termination,
};

/// The per-iteration callback: sees every record in order, `Break` stops the run.
pub(crate) type Callback<'c> = dyn FnMut(&IterationRecord) -> ControlFlow<()> + 'c;

/// An evaluated point.
#[derive(Clone, Debug)]
pub(crate) struct Point {
    pub x: Vec<f64>,
    pub cost: f64,
    pub gradient: Vec<f64>,
}

/// Why an evaluation produced no point.
#[derive(Clone, Debug)]
pub(crate) enum EvalFailure {
    /// `max_evaluations` is spent; nothing was evaluated.
    Budget,
    /// The objective failed (or returned a non-finite value).
    Failed(String),
}

/// The state of one optimizer run.
pub(crate) struct Run<'p, 'c> {
    pub params: &'p OptimParams,
    callback: &'p mut Callback<'c>,
    pub evaluations: usize,
    failed: usize,
    iterations: usize,
    history: Vec<IterationRecord>,
    best: Option<Point>,
    gradient_target: f64,
}

impl<'p, 'c> Run<'p, 'c> {
    #[track_caller]
    pub fn new(params: &'p OptimParams, callback: &'p mut Callback<'c>) -> Self {
        params.validate();
        Self {
            params,
            callback,
            evaluations: 0,
            failed: 0,
            iterations: 0,
            history: Vec::new(),
            best: None,
            gradient_target: 0.0,
        }
    }

    /// Counts one evaluation, or refuses when the budget is spent (the first evaluation
    /// is always allowed).
    fn spend(&mut self, x: &[f64]) -> Result<(), EvalFailure> {
        if self.evaluations > 0 && self.evaluations >= self.params.max_evaluations {
            return Err(EvalFailure::Budget);
        }
        self.evaluations += 1;
        if x.iter().any(|v| !v.is_finite()) {
            self.failed += 1;
            return Err(EvalFailure::Failed("non-finite parameters".into()));
        }
        Ok(())
    }

    /// Checks a returned cost and gradient; keeps the best point.
    #[track_caller]
    fn check(&mut self, x: &[f64], result: Result<(f64, Vec<f64>), EvalError>) -> Result<Point, EvalFailure> {
        let (cost, gradient) = match result {
            Ok(v) => v,
            Err(e) => {
                self.failed += 1;
                return Err(EvalFailure::Failed(e.message));
            }
        };
        assert_eq!(
            gradient.len(),
            x.len(),
            "adjoint::optim: the objective returned a gradient of length {} for {} parameters",
            gradient.len(),
            x.len()
        );
        if !cost.is_finite() || gradient.iter().any(|g| !g.is_finite()) {
            self.failed += 1;
            return Err(EvalFailure::Failed(format!(
                "non-finite cost or gradient (cost {cost})"
            )));
        }
        let point = Point {
            x: x.to_vec(),
            cost,
            gradient,
        };
        let better = match &self.best {
            Some(b) => point.cost < b.cost,
            None => true,
        };
        if better {
            self.best = Some(point.clone());
        }
        Ok(point)
    }

    /// Evaluates cost and gradient at `x`.
    #[track_caller]
    pub fn eval<O: Objective + ?Sized>(
        &mut self,
        objective: &mut O,
        x: &[f64],
    ) -> Result<Point, EvalFailure> {
        self.spend(x)?;
        let result = objective.eval(x);
        self.check(x, result)
    }

    /// Evaluates cost, gradient and Gauss-Newton matrix at `x`.
    #[track_caller]
    pub fn eval_gn<O: GaussNewtonObjective + ?Sized>(
        &mut self,
        objective: &mut O,
        x: &[f64],
    ) -> Result<(Point, Vec<f64>), EvalFailure> {
        self.spend(x)?;
        let (result, hessian) = match objective.eval_gn(x) {
            Ok(e) => (Ok((e.cost, e.gradient)), e.hessian),
            Err(e) => (Err(e), Vec::new()),
        };
        let n = x.len();
        if result.is_ok() {
            assert_eq!(
                hessian.len(),
                n * n,
                "adjoint::optim: the objective returned a Gauss-Newton matrix of length {} for {n} parameters",
                hessian.len()
            );
        }
        let point = self.check(x, result)?;
        if hessian.iter().any(|h| !h.is_finite()) {
            self.failed += 1;
            return Err(EvalFailure::Failed("non-finite Gauss-Newton matrix".into()));
        }
        Ok((point, hessian))
    }

    /// Records the start point (iteration 0); returns a termination if it is already
    /// converged or the callback stops.
    pub fn start(&mut self, point: &Point) -> Option<Termination> {
        let gnorm = norm_inf(&point.gradient);
        self.gradient_target =
            self.params.gradient_tolerance * gnorm + self.params.absolute_gradient_tolerance;
        let converged = gnorm <= self.gradient_target;
        let stop = self.record(point, 0.0);
        if converged {
            Some(Termination::GradientTolerance)
        } else if stop {
            Some(Termination::Stopped)
        } else if self.params.max_iterations == 0 {
            Some(Termination::MaxIterations)
        } else {
            None
        }
    }

    /// Pushes a record and calls the callback; returns whether the callback said stop.
    fn record(&mut self, point: &Point, step_norm: f64) -> bool {
        let record = IterationRecord {
            iteration: self.iterations,
            cost: point.cost,
            gradient_norm: norm_inf(&point.gradient),
            step_norm,
            x: point.x.clone(),
            evaluations: self.evaluations,
        };
        let flow = (self.callback)(&record);
        self.history.push(record);
        flow.is_break()
    }

    /// Counts an accepted step from a point of cost `reference` to `point`, records it,
    /// and tests the stopping criteria.
    pub fn accept(&mut self, reference: f64, point: &Point, step_norm: f64) -> Option<Termination> {
        self.iterations += 1;
        let p = self.params;
        let gnorm = norm_inf(&point.gradient);
        let termination = if gnorm <= self.gradient_target {
            Some(Termination::GradientTolerance)
        } else if reference - point.cost <= p.cost_tolerance * reference.abs() {
            Some(Termination::CostTolerance)
        } else if self.small_step(step_norm, &point.x) {
            Some(Termination::StepTolerance)
        } else if self.iterations >= p.max_iterations {
            Some(Termination::MaxIterations)
        } else if self.evaluations >= p.max_evaluations {
            Some(Termination::MaxEvaluations)
        } else {
            None
        };
        let stop = self.record(point, step_norm);
        termination.or(stop.then_some(Termination::Stopped))
    }

    /// `||dx|| <= step_tolerance (||x|| + step_tolerance)`.
    pub fn small_step(&self, step_norm: f64, x: &[f64]) -> bool {
        let tol = self.params.step_tolerance;
        step_norm <= tol * (norm2(x) + tol)
    }

    /// Ends the run with the best point seen.
    pub fn finish(self, termination: Termination) -> OptimResult {
        let best = self
            .best
            .expect("adjoint::optim: finish called before any successful evaluation");
        Ok((
            best.x,
            OptimInfo {
                iterations: self.iterations,
                evaluations: self.evaluations,
                failed_evaluations: self.failed,
                termination,
                cost: best.cost,
                gradient: best.gradient,
                history: self.history,
            },
        ))
    }

    /// Ends the run by an evaluation failure: the budget or a divergence.
    pub fn finish_failure(self, failure: EvalFailure) -> OptimResult {
        self.finish(match failure {
            EvalFailure::Budget => Termination::MaxEvaluations,
            EvalFailure::Failed(message) => Termination::Diverged { message },
        })
    }
}

/// The error for a failed first evaluation.
pub(crate) fn start_failed(failure: EvalFailure) -> OptimError {
    OptimError::StartFailed {
        message: match failure {
            EvalFailure::Failed(m) => m,
            EvalFailure::Budget => "no evaluation allowed".into(),
        },
    }
}

pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

pub(crate) fn norm2(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

pub(crate) fn norm_inf(a: &[f64]) -> f64 {
    a.iter().fold(0.0, |m, v| m.max(v.abs()))
}

/// `x + alpha d`.
pub(crate) fn add_scaled(x: &[f64], alpha: f64, d: &[f64]) -> Vec<f64> {
    x.iter().zip(d).map(|(x, d)| x + alpha * d).collect()
}

/// `a - b`.
pub(crate) fn sub(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(a, b)| a - b).collect()
}
