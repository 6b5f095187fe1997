//! Tests of the optimizers in `adjoint::optim` on small deterministic problems.

use std::ops::ControlFlow;

use adjoint::optim::{
    gradient_descent_bb, lbfgs, levenberg_marquardt, minimize, Damping, EvalError, FnObjective,
    GaussNewtonObjective, GnEval, IterationRecord, LeastSquaresFn, Objective, OptimError, OptimInfo,
    OptimParams, Optimizer, Termination,
};

type Residuals = Result<(Vec<f64>, Vec<f64>), EvalError>;

fn go_on(_: &IterationRecord) -> ControlFlow<()> {
    ControlFlow::Continue(())
}

/// Tight absolute tolerances, the other tests off.
fn tight(gradient: f64) -> OptimParams {
    OptimParams {
        gradient_tolerance: 0.0,
        absolute_gradient_tolerance: gradient,
        cost_tolerance: 0.0,
        step_tolerance: 0.0,
        max_iterations: 1000,
        max_evaluations: 5000,
        ..Default::default()
    }
}

/// Extended Rosenbrock (Moré, Garbow & Hillstrom 1981) in `n` (even) dimensions as least
/// squares: `r_{2i} = 10 (x_{2i+1} - x_{2i}^2)`, `r_{2i+1} = 1 - x_{2i}`; minimum at ones.
fn rosenbrock(x: &[f64]) -> Residuals {
    let n = x.len();
    let mut r = vec![0.0; n];
    let mut j = vec![0.0; n * n];
    for i in (0..n).step_by(2) {
        r[i] = 10.0 * (x[i + 1] - x[i] * x[i]);
        r[i + 1] = 1.0 - x[i];
        j[i * n + i] = -20.0 * x[i];
        j[i * n + i + 1] = 10.0;
        j[(i + 1) * n + i] = -1.0;
    }
    Ok((r, j))
}

fn rosenbrock_start(n: usize) -> Vec<f64> {
    (0..n).map(|i| if i % 2 == 0 { -1.2 } else { 1.0 }).collect()
}

fn max_error(x: &[f64], expected: &[f64]) -> f64 {
    x.iter()
        .zip(expected)
        .fold(0.0, |m, (a, b)| f64::max(m, (a - b).abs()))
}

fn assert_non_increasing(info: &OptimInfo) {
    for w in info.history.windows(2) {
        assert!(
            w[1].cost <= w[0].cost,
            "cost rose at iteration {}: {} -> {}",
            w[1].iteration,
            w[0].cost,
            w[1].cost
        );
    }
}

fn report(name: &str, info: &OptimInfo) {
    eprintln!(
        "{name}: {} iterations, {} evaluations ({} failed), cost {:.3e}, {}",
        info.iterations, info.evaluations, info.failed_evaluations, info.cost, info.termination
    );
}

#[test]
fn rosenbrock_lbfgs_2d_and_10d() {
    for n in [2, 10] {
        let mut f = LeastSquaresFn(rosenbrock);
        let (x, info) = lbfgs(&mut f, &rosenbrock_start(n), &tight(1e-10), &mut go_on).unwrap();
        report(&format!("lbfgs rosenbrock {n}d"), &info);
        assert_eq!(info.termination, Termination::GradientTolerance);
        assert!(max_error(&x, &vec![1.0; n]) < 1e-6, "{x:?}");
        assert_non_increasing(&info);
        assert_eq!(info.failed_evaluations, 0);
    }
}

#[test]
fn rosenbrock_levenberg_marquardt_2d_and_10d() {
    for damping in [Damping::Marquardt, Damping::Levenberg] {
        for n in [2, 10] {
            let mut f = LeastSquaresFn(rosenbrock);
            let params = OptimParams {
                damping,
                ..tight(1e-10)
            };
            let (x, info) = levenberg_marquardt(&mut f, &rosenbrock_start(n), &params, &mut go_on).unwrap();
            report(&format!("lm ({damping:?}) rosenbrock {n}d"), &info);
            assert!(info.termination.is_converged(), "{}", info.termination);
            assert!(max_error(&x, &vec![1.0; n]) < 1e-6, "{x:?}");
            assert_non_increasing(&info);
            // strictly decreasing: every iteration is an accepted step
            assert!(info.history.windows(2).all(|w| w[1].cost < w[0].cost));
        }
    }
}

/// `f = 1/2 (x - c)' Q' diag(lambda) Q (x - c)` with eigenvalues from 1 to 1e4 and a
/// Householder rotation `Q`.
struct Quadratic {
    lambda: Vec<f64>,
    v: Vec<f64>,
    c: Vec<f64>,
}

impl Quadratic {
    fn new(n: usize) -> Self {
        let lambda = (0..n)
            .map(|i| 10f64.powf(4.0 * i as f64 / (n - 1) as f64))
            .collect();
        let v: Vec<f64> = (0..n).map(|i| 1.0 + (i as f64 * 0.7).sin()).collect();
        let norm = v.iter().map(|a| a * a).sum::<f64>().sqrt();
        Self {
            lambda,
            v: v.iter().map(|a| a / norm).collect(),
            c: (0..n).map(|i| (i as f64 - 3.0) * 0.5).collect(),
        }
    }

    /// `Q z = z - 2 v (v'z)` (symmetric and orthogonal).
    fn reflect(&self, z: &[f64]) -> Vec<f64> {
        let vz: f64 = self.v.iter().zip(z).map(|(a, b)| a * b).sum();
        z.iter().zip(&self.v).map(|(z, v)| z - 2.0 * v * vz).collect()
    }
}

impl Objective for Quadratic {
    fn eval(&mut self, x: &[f64]) -> Result<(f64, Vec<f64>), EvalError> {
        let d: Vec<f64> = x.iter().zip(&self.c).map(|(x, c)| x - c).collect();
        let z = self.reflect(&d);
        let cost = 0.5 * z.iter().zip(&self.lambda).map(|(z, l)| l * z * z).sum::<f64>();
        let lz: Vec<f64> = z.iter().zip(&self.lambda).map(|(z, l)| l * z).collect();
        Ok((cost, self.reflect(&lz)))
    }
}

#[test]
fn ill_conditioned_quadratic_bb_and_lbfgs() {
    let n = 10;
    let x0 = vec![0.0; n];
    let c = Quadratic::new(n).c;
    // relative gradient tolerance 1e-10 (||g_0|| = 2.4e4, lambda_min = 1): error ~1e-6;
    // BB needs many iterations at this conditioning (cheap here)
    let params = OptimParams {
        gradient_tolerance: 1e-10,
        max_iterations: 5000,
        max_evaluations: 10000,
        ..tight(0.0)
    };
    let (x, info) = gradient_descent_bb(&mut Quadratic::new(n), &x0, &params, &mut go_on).unwrap();
    report("gd-bb quadratic cond 1e4", &info);
    assert_eq!(info.termination, Termination::GradientTolerance);
    assert!(max_error(&x, &c) < 1e-6, "{x:?}");
    // the best point is returned even though BB is non-monotone
    let min = info.history.iter().map(|r| r.cost).fold(f64::INFINITY, f64::min);
    assert!(info.cost <= min);

    let (x, info) = lbfgs(&mut Quadratic::new(n), &x0, &params, &mut go_on).unwrap();
    report("lbfgs quadratic cond 1e4", &info);
    assert_eq!(info.termination, Termination::GradientTolerance);
    assert!(max_error(&x, &c) < 1e-6, "{x:?}");
    assert_non_increasing(&info);
}

/// Residuals of `y(t) = a exp(-b t) + c` against exact data of `(2, 0.7, 0.5)`.
fn exponential(x: &[f64]) -> Residuals {
    let (a, b, c) = (x[0], x[1], x[2]);
    let mut r = Vec::new();
    let mut j = Vec::new();
    for k in 0..20 {
        let t = 0.25 * k as f64;
        let data = 2.0 * (-0.7 * t).exp() + 0.5;
        let e = (-b * t).exp();
        r.push(a * e + c - data);
        j.extend([e, -a * t * e, 1.0]);
    }
    Ok((r, j))
}

#[test]
fn exponential_fit_levenberg_marquardt() {
    let mut f = LeastSquaresFn(exponential);
    let (x, info) = levenberg_marquardt(&mut f, &[1.0, 0.2, 0.0], &tight(1e-12), &mut go_on).unwrap();
    report("lm exponential fit", &info);
    assert!(info.termination.is_converged(), "{}", info.termination);
    assert!(max_error(&x, &[2.0, 0.7, 0.5]) < 1e-8, "{x:?}");
    assert_non_increasing(&info);
    // the same problem with L-BFGS, for comparison
    let (x, info) = lbfgs(&mut f, &[1.0, 0.2, 0.0], &tight(1e-10), &mut go_on).unwrap();
    report("lbfgs exponential fit", &info);
    assert!(max_error(&x, &[2.0, 0.7, 0.5]) < 1e-6, "{x:?}");
}

/// Rosenbrock that fails (like a diverged simulation) where `x0 > 1.5` or `x1 < -0.5`,
/// counting the failures.
struct Fragile {
    failures: usize,
}

impl Fragile {
    fn check(&mut self, x: &[f64]) -> Result<(), EvalError> {
        if x[0] > 1.5 || x[1] < -0.5 {
            self.failures += 1;
            Err(EvalError::new("CG diverged at step 12"))
        } else {
            Ok(())
        }
    }
}

impl Objective for Fragile {
    fn eval(&mut self, x: &[f64]) -> Result<(f64, Vec<f64>), EvalError> {
        self.check(x)?;
        LeastSquaresFn(rosenbrock).eval(x)
    }
}

impl GaussNewtonObjective for Fragile {
    fn eval_gn(&mut self, x: &[f64]) -> Result<GnEval, EvalError> {
        self.check(x)?;
        LeastSquaresFn(rosenbrock).eval_gn(x)
    }
}

#[test]
fn backtracks_around_failing_region() {
    // a large first step (5 in the infinity norm) lands in the failing region for GD and
    // L-BFGS; the first Levenberg-Marquardt step goes to (-0.13, -1.13), also failing
    let params = OptimParams {
        initial_step: 5.0,
        ..tight(1e-9)
    };
    for optimizer in Optimizer::ALL {
        let mut f = Fragile { failures: 0 };
        let (x, info) = minimize(optimizer, &mut f, &[-1.2, 1.0], &params, &mut go_on).unwrap();
        report(&format!("{optimizer} fragile rosenbrock"), &info);
        assert!(f.failures > 0, "{optimizer} never hit the failing region");
        assert_eq!(info.failed_evaluations, f.failures);
        assert!(
            info.termination.is_converged(),
            "{optimizer}: {}",
            info.termination
        );
        assert!(max_error(&x, &[1.0, 1.0]) < 1e-6, "{optimizer}: {x:?}");
        if optimizer != Optimizer::GradientDescent {
            assert_non_increasing(&info);
        }
    }
}

#[test]
fn failure_at_start_is_diverged() {
    let message = "CG diverged at step 3";
    for optimizer in Optimizer::ALL {
        let mut f = LeastSquaresFn(|_: &[f64]| -> Residuals { Err(EvalError::new(message)) });
        let err = minimize(
            optimizer,
            &mut f,
            &[1.0, 2.0],
            &OptimParams::default(),
            &mut go_on,
        )
        .unwrap_err();
        assert_eq!(
            err,
            OptimError::StartFailed {
                message: message.into()
            }
        );
        assert_eq!(
            err.termination(),
            Termination::Diverged {
                message: message.into()
            }
        );
        assert!(err.to_string().contains(message));
    }
    // a NaN cost counts as a failure too
    let mut f = FnObjective(|_: &[f64]| Ok((f64::NAN, vec![0.0])));
    let err = lbfgs(&mut f, &[0.0], &OptimParams::default(), &mut go_on).unwrap_err();
    assert!(matches!(err, OptimError::StartFailed { .. }));
}

#[test]
fn failing_everywhere_but_the_start_reports_divergence() {
    let params = OptimParams {
        max_consecutive_failures: 5,
        ..OptimParams::default()
    };
    for optimizer in Optimizer::ALL {
        let mut f = LeastSquaresFn(|x: &[f64]| -> Residuals {
            if x == [0.5, 0.5] {
                rosenbrock(x)
            } else {
                Err(EvalError::new("simulation exploded"))
            }
        });
        let (x, info) = minimize(optimizer, &mut f, &[0.5, 0.5], &params, &mut go_on).unwrap();
        assert_eq!(x, [0.5, 0.5], "{optimizer}: the start is the best point");
        assert_eq!(
            info.termination,
            Termination::Diverged {
                message: "simulation exploded".into()
            },
            "{optimizer}"
        );
        assert_eq!(info.failed_evaluations, 6, "{optimizer}");
        assert_eq!(info.iterations, 0);
        assert!(info.termination.to_string().contains("simulation exploded"));
    }
}

#[test]
fn max_iterations_and_evaluations_are_honoured() {
    for optimizer in Optimizer::ALL {
        let params = OptimParams {
            max_iterations: 3,
            ..tight(0.0)
        };
        let mut f = LeastSquaresFn(rosenbrock);
        let (_, info) = minimize(optimizer, &mut f, &rosenbrock_start(10), &params, &mut go_on).unwrap();
        assert_eq!(info.termination, Termination::MaxIterations, "{optimizer}");
        assert_eq!(info.iterations, 3);
        assert_eq!(info.history.len(), 4);

        let params = OptimParams {
            max_evaluations: 7,
            ..tight(0.0)
        };
        let (x, info) = minimize(optimizer, &mut f, &rosenbrock_start(10), &params, &mut go_on).unwrap();
        assert_eq!(info.termination, Termination::MaxEvaluations, "{optimizer}");
        assert!(info.evaluations <= 7, "{optimizer}: {}", info.evaluations);
        // the returned point is the best evaluated
        let (cost, _) = f.eval(&x).unwrap();
        assert_eq!(cost, info.cost);
        assert!(info.history.iter().all(|r| r.cost >= info.cost));
    }
    // zero iterations: only the start point
    let params = OptimParams {
        max_iterations: 0,
        ..OptimParams::default()
    };
    let (x, info) = lbfgs(&mut LeastSquaresFn(rosenbrock), &[0.0, 0.0], &params, &mut go_on).unwrap();
    assert_eq!((x, info.evaluations), (vec![0.0, 0.0], 1));
}

#[test]
fn callback_sees_every_iteration_in_order_and_can_stop() {
    for optimizer in Optimizer::ALL {
        let mut seen: Vec<IterationRecord> = Vec::new();
        let mut f = LeastSquaresFn(rosenbrock);
        let (_, info) = minimize(optimizer, &mut f, &rosenbrock_start(2), &tight(1e-8), &mut |r| {
            seen.push(r.clone());
            ControlFlow::Continue(())
        })
        .unwrap();
        assert_eq!(seen, info.history, "{optimizer}");
        assert_eq!(seen.len(), info.iterations + 1);
        for (i, r) in seen.iter().enumerate() {
            assert_eq!(r.iteration, i);
        }
        assert!(seen.windows(2).all(|w| w[0].evaluations < w[1].evaluations));
        assert_eq!(seen.last().unwrap().evaluations, info.evaluations);

        let mut calls = 0;
        let (_, info) = minimize(optimizer, &mut f, &rosenbrock_start(2), &tight(1e-8), &mut |r| {
            calls += 1;
            if r.iteration == 4 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
        assert_eq!(info.termination, Termination::Stopped, "{optimizer}");
        assert_eq!((info.iterations, calls, info.history.len()), (4, 5, 5));
    }
}

#[test]
fn resume_from_a_recorded_point() {
    let mut f = LeastSquaresFn(rosenbrock);
    let params = OptimParams {
        max_iterations: 10,
        ..tight(1e-10)
    };
    let (_, first) = lbfgs(&mut f, &rosenbrock_start(2), &params, &mut go_on).unwrap();
    assert_eq!(first.termination, Termination::MaxIterations);
    let last = first.history.last().unwrap().x.clone();
    let (x, second) = lbfgs(&mut f, &last, &tight(1e-10), &mut go_on).unwrap();
    assert_eq!(second.history[0].cost, first.history.last().unwrap().cost);
    assert!(max_error(&x, &[1.0, 1.0]) < 1e-6);
}

#[test]
fn optimizer_names() {
    assert_eq!("lbfgs".parse::<Optimizer>(), Ok(Optimizer::Lbfgs));
    assert_eq!("gd".parse::<Optimizer>(), Ok(Optimizer::GradientDescent));
    assert_eq!("gauss-newton".parse::<Optimizer>(), Ok(Optimizer::GaussNewton));
    for o in Optimizer::ALL {
        assert_eq!(o.to_string().parse::<Optimizer>(), Ok(o));
    }
    let err = "newton".parse::<Optimizer>().unwrap_err();
    assert_eq!(
        err.to_string(),
        "unknown optimizer `newton` (expected one of: lbfgs, gd, gauss-newton)"
    );
    assert!("LBFGS".parse::<Optimizer>().is_err());
}

#[test]
fn start_at_the_minimum_converges_immediately() {
    let mut f = LeastSquaresFn(rosenbrock);
    for optimizer in Optimizer::ALL {
        let (x, info) = minimize(
            optimizer,
            &mut f,
            &[1.0, 1.0],
            &OptimParams::default(),
            &mut go_on,
        )
        .unwrap();
        assert_eq!(x, [1.0, 1.0]);
        assert_eq!(info.termination, Termination::GradientTolerance);
        assert_eq!((info.iterations, info.evaluations), (0, 1));
    }
}
