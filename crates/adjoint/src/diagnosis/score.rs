//! Which effect is missing: the score (Lagrange-multiplier) test of each effect the model
//! lacks, a short refit of the best ones, and the Bayesian information criterion.
//!
//! With the squared loss `C(x) = 1/2 sum r^2` of `N` residuals, fitted to `C_0` by the model
//! as given, switch an effect on at its neutral value (its parameters `x_e` appended to the
//! fitted `x_b`). The Gauss-Newton model of the cost around that point, with gradient `g` from
//! the adjoint pass and matrix `H = J^T J` from the tangent-linear pass, predicts the decrease
//!
//! ```text
//! delta = 1/2 g^T H^{-1} g          (= 1/2 g_e^T S^{-1} g_e at a converged fit, g_b = 0,
//!                                       S = H_ee - H_eb H_bb^{-1} H_be the Schur complement)
//! ```
//!
//! and the score statistic `LM = 2 delta / s^2 = N delta / C_0` with the residual variance
//! `s^2 = 2 C_0 / N` of the model as given; it is chi-square with `p_e` degrees of freedom
//! when the effect is absent (Rao 1948; Engle 1984). Effects with no gradient at the neutral
//! value start at a data-driven value instead ([`super::effects::Probe::Initialized`]): then
//! `delta = C_0 - (C(x_0) - 1/2 g^T H^{-1} g)`; effects without parameters are switched on and
//! compared, `delta = C_0 - C(x_0)`.
//!
//! An effect with many coordinates (a stiffness field) is scored in the plane of the base
//! coordinates and its gradient direction `d = g_e / |g_e|` only, `D^T H D` from one tangent
//! pass per direction: a lower bound of the full statistic at a fraction of the cost.
//!
//! The best candidates (by `LM - p_e ln N`) are refitted for a few Gauss-Newton iterations and
//! ranked by `Delta BIC = N ln(RSS_after / RSS_before) + p_e ln N` (Schwarz 1978), so that an
//! effect must explain more than noise to be chosen.

use super::effects::{DataContext, Effect, Probe};
use super::{scan, Setup};
use crate::fit::{invert_small, scene_problem_reach, CostKind, FitObjective};
use crate::optim::{minimize, EvalError, GaussNewtonObjective, GnEval, Objective, OptimParams, Optimizer};
use crate::params::ParamSet;
use crate::problem::{Evaluation, Problem};
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::Scene;
use std::ops::ControlFlow;

/// One candidate effect.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Candidate {
    /// the effect
    pub effect: String,
    /// how it was probed
    pub probe: Probe,
    /// the parameter components it adds
    pub params: Vec<String>,
    /// the score statistic `LM` (module docs)
    pub score: f64,
    /// the rms the Gauss-Newton model predicts after adding it (NaN: the model predicted a
    /// negative cost, no prediction)
    pub predicted_rms: f64,
    /// the rms after the short refit (`None`: not refitted)
    pub rms_after: Option<f64>,
    /// `Delta BIC` of the refit (negative: the data favour the effect)
    pub delta_bic: Option<f64>,
    /// the refitted physical values (base and effect parameters)
    pub values: Vec<(String, f64)>,
    /// the TOML that switches it on with the refitted values
    pub suggestion: String,
    /// why it could not be probed or refitted, if so
    pub error: Option<String>,
    /// the parameters of the fit as given that ended on a bound and that this candidate's refit
    /// moved off it, with their refitted values (empty: none, or nothing was on a bound)
    pub frees: Vec<(String, f64)>,
    /// the refitted model
    #[serde(skip)]
    pub model: Option<Model>,
    /// the Gauss-Newton step `-H^{-1} g` of the probe (empty for a switch)
    #[serde(skip)]
    pub step: Vec<f64>,
    /// the refitted coordinates (base parameters, then the effect's)
    #[serde(skip)]
    pub x: Vec<f64>,
    /// the scene with the effect switched on
    #[serde(skip)]
    pub scene: Option<Scene>,
}

/// The fitted model as given: its scene with the fitted values, the fitted unconstrained `x`
/// of the base parameters, the base parameter set (with its field basis) and the cost.
#[derive(Debug)]
pub struct BaseFit {
    /// scene with the fitted values written back
    pub scene: Scene,
    /// the fitted base coordinates
    pub x: Vec<f64>,
    /// the base coordinates of the scene's starting values
    pub x_start: Vec<f64>,
    /// the base parameters
    pub params: ParamSet,
    /// the evaluation at the fit
    pub eval: Evaluation,
}

/// The problem of `scene` with the base parameters plus `extra`, at the base fit.
pub fn extended_problem(
    setup: &Setup,
    base: &BaseFit,
    scene: &Scene,
    extra: &[crate::params::Param],
) -> Result<(Problem, Vec<f64>), Error> {
    extended_problem_at(setup, &base.params, &base.x, scene, extra)
}

/// [`extended_problem`] for base parameters `params` fitted to `x`.
pub fn extended_problem_at(
    setup: &Setup,
    base_params: &ParamSet,
    base_x: &[f64],
    scene: &Scene,
    extra: &[crate::params::Param],
) -> Result<(Problem, Vec<f64>), Error> {
    let base = BaseRef {
        params: base_params,
        x: base_x,
    };
    let mut names: Vec<&str> = base.params.params.iter().map(|p| p.name()).collect();
    names.extend(extra.iter().map(|p| p.name()));
    let params = ParamSet::parse(&names)?;
    let mut problem = diagnosis_problem(scene, setup, params)?;
    let base_set = ParamSet {
        params: base.params.params.clone(),
        field: problem.params.field.clone(),
    }
    .layout(&problem.base)?;
    base_set.apply(base.x, &mut problem.base);
    let extra_set = ParamSet {
        params: extra.to_vec(),
        field: problem.params.field.clone(),
    }
    .layout(&problem.base)?;
    let mut x0 = base.x.to_vec();
    if !extra.is_empty() {
        x0.extend(extra_set.to_x(&problem.base));
    }
    Ok((problem, x0))
}

/// Effects with more coordinates than this are scored along their gradient direction.
pub const MAX_FULL_SCORE: usize = 8;

/// Fits with more coordinates than this use L-BFGS (gradients only) instead of
/// Levenberg-Marquardt (one tangent pass per coordinate and iteration).
pub const MAX_GAUSS_NEWTON: usize = 40;

struct BaseRef<'a> {
    params: &'a ParamSet,
    x: &'a [f64],
}

/// The surface-cost problem of `scene` with the diagnosis' reach ([`Setup::reach`]).
pub fn diagnosis_problem(scene: &Scene, setup: &Setup, params: ParamSet) -> Result<Problem, Error> {
    let mut problem = scene_problem_reach(
        scene,
        setup.observations,
        params,
        setup.robust,
        setup.steps,
        CostKind::Surface,
        setup.eyes,
        setup.reach,
    )?;
    if setup.reach.is_none() {
        let reach = Setup::reach(&problem.sim.grid);
        problem.cost = Box::new(
            crate::cost_mesh::SurfaceCost::new(
                &problem.sim.grid,
                crate::fit::observed_frames(setup.observations, setup.eyes),
                setup.robust,
            )?
            .with_reach(reach),
        );
    }
    Ok(problem)
}

/// Probes `effect` at the base fit (module docs).
pub fn probe(setup: &Setup, base: &BaseFit, effect: &dyn Effect, data: &DataContext) -> Candidate {
    let mut c = Candidate {
        effect: effect.name().to_string(),
        probe: effect.probe(),
        params: Vec::new(),
        score: 0.0,
        predicted_rms: base.eval.rms(),
        rms_after: None,
        delta_bic: None,
        values: Vec::new(),
        suggestion: String::new(),
        error: None,
        frees: Vec::new(),
        model: None,
        step: Vec::new(),
        x: Vec::new(),
        scene: None,
    };
    let run = |c: &mut Candidate| -> Result<(), Error> {
        let mut scene = base.scene.clone();
        effect.switch_on(&mut scene, data)?;
        // the candidate's scene is checked where it is made, as a user's scene would be
        let scene = scene.checked(&format!("the candidate `{}`", effect.name()))?;
        let (mut problem, x0) = extended_problem(setup, base, &scene, &effect.params())?;
        c.params = problem.params.labels()[base.x.len()..].to_vec();
        let (c0, n) = totals(&base.eval);
        let predicted = match effect.probe() {
            Probe::Switch => problem.evaluate(&x0)?.cost,
            Probe::Score | Probe::Initialized => {
                let (ev, g, _) = problem.gradient(&x0)?;
                // the base coordinates, and the effect's own ones when few, else only the
                // direction of its gradient (a lower bound of the decrease; one tangent pass
                // instead of one per coefficient of a stiffness field)
                let nb = base.x.len();
                let mut dirs: Vec<Vec<f64>> = Vec::new();
                let unit = |k: usize| {
                    let mut d = vec![0.0; x0.len()];
                    d[k] = 1.0;
                    d
                };
                dirs.extend((0..nb).map(unit));
                if x0.len() - nb <= MAX_FULL_SCORE {
                    dirs.extend((nb..x0.len()).map(unit));
                } else {
                    let norm = g[nb..].iter().map(|v| v * v).sum::<f64>().sqrt();
                    if norm > 0.0 {
                        let mut d = vec![0.0; x0.len()];
                        for k in nb..x0.len() {
                            d[k] = g[k] / norm;
                        }
                        dirs.push(d);
                    }
                }
                let h = problem.gauss_newton_directions(&x0, &dirs)?;
                let gd: Vec<f64> = dirs
                    .iter()
                    .map(|d| d.iter().zip(&g).map(|(a, b)| a * b).sum())
                    .collect();
                let (q, step_d) = quadratic_step(&gd, &h);
                let mut step = vec![0.0; x0.len()];
                for (d, s) in dirs.iter().zip(&step_d) {
                    for (t, v) in step.iter_mut().zip(d) {
                        *t += s * v;
                    }
                }
                c.step = step;
                ev.cost - 0.5 * q.max(0.0)
            }
        };
        // a Gauss-Newton model of a sum of squares cannot fall below zero (its minimum is half
        // the squared residual left after projecting out the Jacobian's range): one that does
        // divides a gradient by a curvature at rounding level (a log coordinate probed near 0)
        // and predicts nothing; its rms is not a number (shown "-", JSON null), not 0
        let valid = predicted > 0.0 || (predicted == 0.0 && c0 == 0.0);
        let predicted = predicted.max(0.0);
        let delta = c0 - predicted;
        c.score = if c0 > 0.0 { n * delta / c0 } else { 0.0 };
        c.predicted_rms = if valid {
            (2.0 * predicted / n.max(1.0)).sqrt()
        } else {
            f64::NAN
        };
        c.scene = Some(scene);
        Ok(())
    };
    if let Err(e) = run(&mut c) {
        c.error = Some(e.to_string());
        c.score = f64::NEG_INFINITY;
    }
    c
}

/// Refits a probed candidate for `iterations` Gauss-Newton iterations and sets its rms and
/// `Delta BIC`.
pub fn refit(setup: &Setup, base: &BaseFit, effect: &dyn Effect, c: &mut Candidate, iterations: usize) {
    let Some(scene) = c.scene.clone() else { return };
    let run = || -> Result<(Vec<f64>, Evaluation, Problem), Error> {
        let (mut problem, x0) = extended_problem(setup, base, &scene, &effect.params())?;
        // the best of three starts (one forward run each): the base fit with the effect at
        // its probe value; the probe's Gauss-Newton step from there (a log coordinate takes
        // the step linearly, `q (1 + dx)`: damping switched on at 1e-4 needs it), kept inside
        // the box of [`ParamSet::bounds`]; the scene's own starting values with the effect at
        // its probe value (a wrong model's base fit may have wandered off)
        let mut starts = vec![x0.clone()];
        if c.step.len() == x0.len() {
            let logs = problem.params.log_coordinates();
            let bounds = problem.params.bounds(&x0);
            starts.push(
                x0.iter()
                    .zip(&c.step)
                    .zip(&logs)
                    .zip(&bounds)
                    .map(|(((&x, &dx), &log), &(lo, hi))| {
                        let v = if log {
                            x + (1.0 + dx).max(1e-3).ln()
                        } else {
                            x + dx
                        };
                        v.clamp(lo, hi)
                    })
                    .collect(),
            );
        }
        let mut scene_start = None;
        if base.x_start.len() == base.x.len() {
            let mut xs = base.x_start.clone();
            xs.extend_from_slice(&x0[base.x.len()..]);
            starts.push(xs.clone());
            scene_start = Some(xs);
        }
        let mut start = x0.clone();
        let mut best = f64::INFINITY;
        let mut scene_cost = None;
        for xs in starts {
            if let Ok(e) = problem.evaluate(&xs) {
                if Some(&xs) == scene_start.as_ref() {
                    scene_cost = Some(e.cost);
                }
                if e.cost < best {
                    best = e.cost;
                    start = xs;
                }
            }
        }
        scan::magnitudes(&mut problem, base.x.len(), &mut start, best);
        scan::step(&mut problem, base.x.len(), &x0, &c.step, &mut start, best);
        let mut fit = fit_problem(&mut problem, &start, iterations);
        // the wrong model's base fit may have wandered off (a body made soft to stop where a
        // hidden ground stops it, the Poisson ratio pushed to its bound to mimic a hidden drag),
        // and a start's cost before the effect's values are fitted says little about where a
        // refit ends: refit from the scene's own values too (their magnitudes scanned as well)
        // and keep the better (also when the first reached the stated noise floor: on
        // noise-free data the floor is an upper bound, and the torus' hidden damping refitted
        // to 2.7e-4 under a floor of 4.7e-4 lost to drag at 3e-5; the second reaches 0)
        if let (Some(mut xs), Some(cost)) = (scene_start.filter(|xs| *xs != start), scene_cost) {
            scan::magnitudes(&mut problem, base.x.len(), &mut xs, cost);
            scan::step(&mut problem, base.x.len(), &x0, &c.step, &mut xs, cost);
            if let Ok(other) = fit_problem(&mut problem, &xs, iterations) {
                if fit.as_ref().map_or(true, |f| other.1.cost < f.1.cost) {
                    fit = Ok(other);
                }
            }
        }
        let (x, ev) = fit?;
        Ok((x, ev, problem))
    };
    match run() {
        Ok((x, ev, problem)) => {
            let (_, n) = totals(&base.eval);
            let before = base.eval.rms().powi(2).max(f64::MIN_POSITIVE);
            let after = ev.rms().powi(2).max(f64::MIN_POSITIVE);
            let p = c.params.len() as f64;
            c.rms_after = Some(ev.rms());
            c.delta_bic = Some(n * (after / before).ln() + p * n.ln());
            let model = problem.model_at(&x);
            c.x = x;
            c.values = problem.params.values(&model);
            c.suggestion = effect.suggestion(&model);
            c.model = Some(model);
        }
        Err(e) => c.error = Some(e.to_string()),
    }
}

/// Fits `problem` from `x0` with Levenberg-Marquardt: the best `x` and its evaluation.
///
/// A stiffness field's log factors `c_k` carry a Gaussian prior centred on the homogeneous
/// material: the fit minimizes `C(x) + alpha/2 sum_k c_k^2` (a MAP estimate; the returned
/// evaluation is the data's alone). `alpha = FIELD_PRIOR x max_k H_kk`, the best-seen
/// factor's Gauss-Newton curvature at the start, fixed for the fit: a factor the data see
/// [`FIELD_PRIOR`] times less well than that one stays near homogeneous instead of wandering
/// along a direction the data hardly see (with a global Young's modulus fitted too, a uniform
/// shift of the factors is such a direction; so are coarse cells the body barely fills).
///
/// L-BFGS replaces Levenberg-Marquardt above [`MAX_GAUSS_NEWTON`] coordinates. The model is
/// only ever evaluated inside [`ParamSet::bounds`]: the optimizer minimizes `C(P(x))` with `P`
/// the projection onto the box (a coordinate beyond its bound has no effect, and its gradient
/// and Gauss-Newton rows are zero), and the result is `P(x)`. A parameter the data hardly
/// determine (the Poisson ratio of a body in free flight under a wrong model) cannot leave its
/// plausible range, and a fit whose start lies on a bound (the Poisson ratio a wrong model
/// pushed to 0.01) still moves the other coordinates (a step that only crossed the bound would
/// otherwise count as a failed evaluation, however good it is for the rest).
pub fn fit_problem(
    problem: &mut Problem,
    x0: &[f64],
    iterations: usize,
) -> Result<(Vec<f64>, Evaluation), Error> {
    if iterations == 0 {
        let ev = problem.evaluate(x0)?;
        return Ok((x0.to_vec(), ev));
    }
    let params = OptimParams {
        max_iterations: iterations,
        max_evaluations: if x0.len() > MAX_GAUSS_NEWTON {
            3 * iterations
        } else {
            iterations + 4
        },
        gradient_tolerance: 1e-8,
        cost_tolerance: 1e-6,
        ..Default::default()
    };
    let bounds = problem.params.bounds(x0);
    let prior = field_prior(problem, x0)?;
    let mut obj = Bounded {
        inner: FitObjective::new(problem),
        bounds,
        prior,
    };
    let optimizer = if x0.len() > MAX_GAUSS_NEWTON {
        Optimizer::Lbfgs
    } else {
        Optimizer::GaussNewton
    };
    let (x, _) = minimize(optimizer, &mut obj, x0, &params, &mut |_| {
        ControlFlow::Continue(())
    })?;
    let x = obj.project(&x);
    let ev = match obj.inner.evaluation_at(&x) {
        Some(ev) => ev,
        None => obj.inner.problem.evaluate(&x)?,
    };
    Ok((x, ev))
}

/// The prior's strength relative to the best-seen field factor's curvature ([`fit_problem`]).
pub const FIELD_PRIOR: f64 = 1e-3;

/// `(coordinate, alpha)` of the stiffness field's prior at the start `x0` of a fit
/// ([`fit_problem`]); empty without a field.
fn field_prior(problem: &mut Problem, x0: &[f64]) -> Result<Vec<(usize, f64)>, Error> {
    let coords: Vec<usize> = problem
        .params
        .field_coordinates()
        .iter()
        .enumerate()
        .filter_map(|(k, &f)| f.then_some(k))
        .collect();
    if coords.is_empty() {
        return Ok(Vec::new());
    }
    let dirs: Vec<Vec<f64>> = coords
        .iter()
        .map(|&k| {
            let mut d = vec![0.0; x0.len()];
            d[k] = 1.0;
            d
        })
        .collect();
    let h = problem.gauss_newton_directions(x0, &dirs)?;
    let m = coords.len();
    let alpha = FIELD_PRIOR * (0..m).map(|i| h[i * m + i]).fold(0.0f64, f64::max);
    Ok(coords.into_iter().map(|k| (k, alpha)).collect())
}

/// A fit objective confined to a box, with the field's prior ([`fit_problem`]).
struct Bounded<'a> {
    inner: FitObjective<'a>,
    bounds: Vec<(f64, f64)>,
    /// `(coordinate, alpha)`: `alpha/2 x_k^2` added to the cost
    prior: Vec<(usize, f64)>,
}

impl Bounded<'_> {
    /// `P(x)`: `x` clamped into the box.
    fn project(&self, x: &[f64]) -> Vec<f64> {
        x.iter()
            .zip(&self.bounds)
            .map(|(&v, &(lo, hi))| v.clamp(lo, hi))
            .collect()
    }
    /// Whether coordinate `k` of `x` lies beyond its bound (the projection holds it there).
    fn outside(&self, x: &[f64], k: usize) -> bool {
        let (lo, hi) = self.bounds[k];
        x[k] < lo || x[k] > hi
    }
    /// Checks that `x` is finite (the projection of a NaN is not a point).
    fn check(x: &[f64]) -> Result<(), EvalError> {
        match x.iter().position(|v| !v.is_finite()) {
            Some(k) => Err(EvalError::new(format!("coordinate {k} is not finite"))),
            None => Ok(()),
        }
    }
}

impl Objective for Bounded<'_> {
    fn eval(&mut self, x: &[f64]) -> Result<(f64, Vec<f64>), EvalError> {
        Self::check(x)?;
        let p = self.project(x);
        let (mut cost, mut g) = self.inner.eval(&p)?;
        for &(k, alpha) in &self.prior {
            cost += 0.5 * alpha * p[k] * p[k];
            g[k] += alpha * p[k];
        }
        for (k, gk) in g.iter_mut().enumerate() {
            if self.outside(x, k) {
                *gk = 0.0;
            }
        }
        Ok((cost, g))
    }
}

impl GaussNewtonObjective for Bounded<'_> {
    fn eval_gn(&mut self, x: &[f64]) -> Result<GnEval, EvalError> {
        Self::check(x)?;
        let p = self.project(x);
        let mut ev = self.inner.eval_gn(&p)?;
        let n = x.len();
        for &(k, alpha) in &self.prior {
            ev.cost += 0.5 * alpha * p[k] * p[k];
            ev.gradient[k] += alpha * p[k];
            ev.hessian[k * n + k] += alpha;
        }
        for k in (0..n).filter(|&k| self.outside(x, k)) {
            ev.gradient[k] = 0.0;
            for j in 0..n {
                ev.hessian[k * n + j] = 0.0;
                ev.hessian[j * n + k] = 0.0;
            }
        }
        Ok(ev)
    }
}

/// `(cost, residual count)` of an evaluation (outside points included, as in the rms).
pub fn totals(ev: &Evaluation) -> (f64, f64) {
    let n: usize = ev.frames.iter().map(|f| f.count).sum();
    (ev.cost, n as f64)
}

/// `(g^T H^{-1} g, -H^{-1} g)` with a tiny relative ridge on `H` (directions the data do not
/// see add nothing).
pub fn quadratic_step(g: &[f64], h: &[f64]) -> (f64, Vec<f64>) {
    let n = g.len();
    let none = (0.0, vec![0.0; n]);
    if n == 0 {
        return none;
    }
    let scale = (0..n).map(|i| h[i * n + i]).fold(0.0f64, f64::max);
    if scale <= 0.0 {
        return none;
    }
    let mut hr = h.to_vec();
    for i in 0..n {
        hr[i * n + i] += 1e-9 * scale;
    }
    let Some(inv) = invert_small(&hr, n) else {
        return none;
    };
    let step: Vec<f64> = (0..n)
        .map(|i| -(0..n).map(|j| inv[i * n + j] * g[j]).sum::<f64>())
        .collect();
    (-g.iter().zip(&step).map(|(a, b)| a * b).sum::<f64>(), step)
}
