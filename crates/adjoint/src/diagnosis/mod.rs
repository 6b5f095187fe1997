//! Model diagnosis: compare the model with measurements, see where it fails, learn which
//! physical effect is missing.
//!
//! [`diagnose`] runs four stages:
//!
//! 1. **Fit the model as given** (Levenberg-Marquardt on the scene's fitted parameters,
//!    default `young, poisson`).
//! 2. **Where it fails** ([`residuals`]): every observed point's residual vector at the fit,
//!    per frame, per camera, per region of the reference surface, its direction over time, and
//!    a model-free noise floor from local plane fits.
//! 3. **Which effect is missing** ([`score`]): every effect of [`effects::catalogue`] that the
//!    model lacks gets a score statistic from the adjoint gradient and the Gauss-Newton matrix
//!    at its neutral value (or a data-driven start, or a plain switch); the best are refitted
//!    briefly and ranked by the Bayesian information criterion.
//! 4. **Verdict**: an effect is called missing when the data favour it strongly
//!    (`Delta BIC < -10`), it removes at least 3% of the rms, and the model's rms is above a
//!    tenth of the noise floor and above [`numerical_precision`] (below, the residual is the
//!    numerical noise of an exact model, where a likelihood ratio means nothing). The model *fails* when its rms exceeds 1.05 x
//!    the noise floor; the estimated floor is not needed to call an effect missing (it can be
//!    a few percent high: a hidden stiff inclusion left the rms at 1.01x the estimate while
//!    the field took 5% of it, Delta BIC -480). Otherwise: nothing missing.
//!
//! After the verdict, a caller that can afford a run at twice the resolution checks that the
//! named effect is not the model's own discretisation error ([`discretisation`]: its
//! improvement must persist on the finer grid; `softbody diagnose` does).

pub mod discretisation;
pub mod effects;
#[cfg(test)]
mod fixture;
pub mod floor;
pub mod history;
pub mod plausible;
pub mod residuals;
mod scan;
pub mod score;
mod search;
pub mod separate;
mod verdict;

pub use discretisation::{persistence, weigh_discretisation, FinerRun, Persistence};
pub use verdict::{failed, mark_unverified, unchecked};

use crate::cost::Robust;
use crate::cost_mesh::SurfaceCost;
use crate::fit::observed_frames;
use crate::observations::Observations;
use crate::params::ParamSet;
use crate::Error;
use cutfem::fem::collision::GroundPush;
use cutfem::fem::Model;
use cutfem::scene::Scene;
use effects::{catalogue, write_back_all, DataContext, Effect};
use residuals::{Direction, PointResidual, Region};
use score::{BaseFit, Candidate};
use search::{refit_floor, Search};
use verdict::on_bounds;

/// What a diagnosis works on.
#[derive(Clone, Copy, Debug)]
pub struct Setup<'a> {
    /// the observations
    pub observations: &'a Observations,
    /// camera eyes (index = camera id; empty when unknown)
    pub eyes: &'a [[f64; 3]],
    /// the cameras with their intrinsics (index = camera id; empty when unknown)
    pub cameras: &'a [crate::observe::DepthCamera],
    /// the loss
    pub robust: Robust,
    /// simulated steps (default: the scene's)
    pub steps: Option<usize>,
    /// reach of the surface cost (default: [`Setup::reach`])
    pub reach: Option<f64>,
}

impl Setup<'_> {
    /// The reach of the surface cost in a diagnosis: a quarter of the body's size (at least
    /// two cells), so that a model far off still has a gradient towards the points.
    pub fn reach(grid: &cutfem::fem::Grid) -> f64 {
        let d = grid.sdf.dims;
        let size = grid.sdf.spacing * (d[0].max(d[1]).max(d[2])) as f64;
        (0.25 * size).max(2.0 * grid.h())
    }
}

/// Settings of [`diagnose`].
#[derive(Clone, Debug, PartialEq)]
pub struct DiagnoseParams {
    /// Gauss-Newton iterations of the fit as given
    pub fit_iterations: usize,
    /// candidates refitted
    pub refits: usize,
    /// Gauss-Newton iterations of each refit
    pub refit_iterations: usize,
    /// surface regions
    pub regions: usize,
    /// `Delta BIC` below which an effect is called missing (positive number)
    pub bic_threshold: f64,
    /// the model fails when its rms exceeds this many noise floors
    pub fail_ratio: f64,
    /// no effect is called missing while the rms is below this many noise floors, or below
    /// [`numerical_precision`] (the residual of an exact model on noise-free data)
    pub exact_ratio: f64,
    /// an effect must bring the rms below this fraction of the model's
    pub min_improvement: f64,
}

/// The smallest misfit this simulation can tell from zero: [`NUMERICAL_PRECISION`] times the
/// extent (bounding-box diagonal) of the observed points. Its linear solves stop at a relative
/// residual of 1e-8 (`cg_tolerance`), so an rms below this is the numerics' own.
pub fn numerical_precision(observations: &Observations) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for (_, points) in observations.frames() {
        for p in points {
            for d in 0..3 {
                lo[d] = lo[d].min(p.position[d]);
                hi[d] = hi[d].max(p.position[d]);
            }
        }
    }
    let extent = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
    if extent.is_finite() {
        NUMERICAL_PRECISION * extent
    } else {
        0.0
    }
}

/// See [`numerical_precision`].
pub const NUMERICAL_PRECISION: f64 = 1e-9;

impl Default for DiagnoseParams {
    fn default() -> Self {
        Self {
            fit_iterations: 12,
            refits: 4,
            refit_iterations: 8,
            regions: 8,
            bic_threshold: 10.0,
            fail_ratio: 1.05,
            exact_ratio: 0.1,
            min_improvement: 0.97,
        }
    }
}

/// The result of a diagnosis.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// effects of the model as given
    pub effects: Vec<String>,
    /// fitted parameters of the model as given
    pub fitted: Vec<(String, f64)>,
    /// rms at the scene's starting values
    pub rms_start: f64,
    /// rms of the model as given after its fit
    pub rms: f64,
    /// the estimated deviation of the measurement noise ([`floor::stated_floor`]): from the
    /// residuals at the fit ([`floor::residual_floor`]) or, when the cameras' intrinsics are
    /// known and that is smaller, from the depth images ([`residuals::noise_floor`]); `None`
    /// when it cannot be estimated (the method says why, [`floor::NO_FLOOR`])
    pub noise_floor: Option<f64>,
    /// how [`Diagnosis::noise_floor`] was estimated: `"depth images"`, `"residuals"` (at the fit
    /// as given), `"residuals at the best refit"` (the candidate with the smallest rms after its
    /// refit, when that floor is smaller) or, when the residuals are too few, `"plane fits"`
    pub noise_floor_method: &'static str,
    /// the standard error of [`Diagnosis::noise_floor`], when the method gives one
    pub noise_floor_std_error: Option<f64>,
    /// the fitted parameters of the model as given that ended on a bound of the fit's box
    /// (`(parameter, value, "lower" | "upper")`): a wrong model's fit often pushes one there (the
    /// Poisson ratio to 0.01 or 0.49), itself a clue that the model lacks something
    pub on_bounds: Vec<(String, f64, &'static str)>,
    /// where the ground pushed the fitted model's body over its frames (`None`: no ground) and
    /// whether that holds it off the plane (`GroundPush::hovers`: the softmin law's push before
    /// contact carries the body, a modelling error no parameter of the fit removes)
    pub ground_push: Option<(GroundPush, bool)>,
    /// `(frame, rms, points)`
    pub per_frame: Vec<(usize, f64, usize)>,
    /// `(camera, rms, points)`
    pub per_camera: Vec<(u32, f64, usize)>,
    /// residuals per region of the reference surface
    pub regions: Vec<Region>,
    /// the residuals' direction
    pub direction: Direction,
    /// the frame with the largest rms
    pub worst_frame: usize,
    /// every point's residual at the fit
    pub records: Vec<PointResidual>,
    /// candidates, best first
    pub candidates: Vec<Candidate>,
    /// the missing effect, if any
    pub missing_effect: Option<String>,
    /// other refitted effects the data cannot tell from the missing one: their `Delta BIC` is
    /// within [`DiagnoseParams::bic_threshold`] of its (drag and mass damping on a body of
    /// uniform thickness slow it alike)
    pub alternatives: Vec<String>,
    /// with an alternative: the motion of the design menu that tells the named effect from the
    /// first alternative best, and by how much their fitted models differ there
    /// ([`separate::separating_motion`])
    pub separation: Option<separate::Separation>,
    /// what the fitted values of the named effect imply physically, first, and of an
    /// alternative passed over because its values are implausible ([`plausible::judge`])
    pub plausibility: Vec<plausible::Plausibility>,
    /// the verdict in plain words
    pub verdict: String,
    /// why the verdict is not confirmed at the finer grid, when the discretisation guard could
    /// not run for the named effect ([`mark_unverified`]: the guard fails closed)
    pub unverified: Option<String>,
    /// the fitted model as given
    pub model: Model,
    /// the scene with the fitted values
    pub fitted_scene: Scene,
    /// the fitted parameters of the model as given (with the field basis, if any)
    pub base_params: ParamSet,
    /// their fitted coordinates
    pub base_x: Vec<f64>,
    /// their coordinates at the scene's starting values
    pub base_x_start: Vec<f64>,
}

/// The outcome of adding an effect and fitting on.
#[derive(Clone, Debug)]
pub struct Refined {
    /// the scene with the effect on
    pub scene: Scene,
    /// the fitted model
    pub model: Model,
    /// the fitted values (base parameters, then the effect's)
    pub values: Vec<(String, f64)>,
    /// its evaluation
    pub eval: crate::problem::Evaluation,
}

/// Adds the candidate effect `name` of a diagnosis to the model and refits, as a user does
/// after the verdict: the scene's own starting values for the base parameters (the wrong
/// model's fit may have wandered off) with the effect's values from the short refit, or the
/// short refit's whole optimum where it fits the data better, then `iterations` iterations.
pub fn add_and_refit(setup: &Setup, d: &Diagnosis, name: &str, iterations: usize) -> Result<Refined, Error> {
    let c = d
        .candidates
        .iter()
        .find(|c| c.effect == name)
        .ok_or_else(|| Error::Invalid(format!("`{name}` is not a candidate of this diagnosis")))?;
    let scene = c
        .scene
        .clone()
        .ok_or_else(|| Error::Invalid(format!("`{name}` could not be probed")))?;
    let e = effects::effect(name).ok_or_else(|| Error::Invalid(format!("unknown effect `{name}`")))?;
    let (mut problem, x0) =
        score::extended_problem_at(setup, &d.base_params, &d.base_x, &scene, &e.params())?;
    let nb = d.base_x_start.len();
    let same_layout = c.x.len() == x0.len();
    let user = if same_layout && nb <= x0.len() {
        let mut s = d.base_x_start.clone();
        s.extend_from_slice(&c.x[nb..]);
        s
    } else {
        x0
    };
    // the short refit's own optimum is the other start a user has (the verdict's suggested
    // values): the fit goes on from the better of the two, so that a contact or a throw whose
    // misfit is not convex in the base parameters is not refitted into a worse basin than the
    // diagnosis already found
    let start = if same_layout && c.x != user {
        let mut rms_at = |x: &[f64]| problem.evaluate(x).map_or(f64::INFINITY, |e| e.rms());
        if rms_at(&c.x) < rms_at(&user) {
            c.x.clone()
        } else {
            user
        }
    } else {
        user
    };
    let (x, eval) = score::fit_problem(&mut problem, &start, iterations)?;
    let model = problem.model_at(&x);
    let values = problem.params.values(&model);
    Ok(Refined {
        scene,
        model,
        values,
        eval,
    })
}

/// Progress messages of a diagnosis (stage, done, total).
pub type Progress<'a> = &'a mut dyn FnMut(&str, usize, usize);

/// Diagnoses `scene` (the model as given) against the observations of `setup`, fitting
/// `params` (module docs).
pub fn diagnose(
    scene: &Scene,
    setup: &Setup,
    params: ParamSet,
    settings: &DiagnoseParams,
    progress: Progress,
) -> Result<Diagnosis, Error> {
    let on: Vec<Box<dyn Effect>> = catalogue()
        .into_iter()
        .filter(|e| scene.effect_on(e.name()))
        .collect();
    let off: Vec<Box<dyn Effect>> = catalogue()
        .into_iter()
        .filter(|e| !scene.effect_on(e.name()) && e.applies(scene))
        .collect();
    let total = 3 + off.len() + settings.refits;
    progress("fit the model as given", 0, total);
    let mut problem = score::diagnosis_problem(scene, setup, params)?;
    let reach = setup.reach.unwrap_or_else(|| Setup::reach(&problem.sim.grid));
    let setup = &Setup {
        reach: Some(reach),
        ..*setup
    };
    let x0 = problem.x0();
    let rms_start = problem.evaluate(&x0)?.rms();
    let (x, eval) = score::fit_problem(&mut problem, &x0, settings.fit_iterations)?;
    let model = problem.model_at(&x);
    let base_bounds = problem.params.bounds(&x0);
    let on_bounds = on_bounds(&problem.params.values(&model), &base_bounds, &x);
    let mut fitted_scene = scene.clone();
    write_back_all(&mut fitted_scene, &model);
    let base = BaseFit {
        scene: fitted_scene.clone(),
        x,
        x_start: x0.clone(),
        params: problem.params.set().clone(),
        eval,
    };

    progress("residuals", 1, total);
    let steps = setup.steps.unwrap_or(scene.time.steps);
    let cost = SurfaceCost::new(
        &problem.sim.grid,
        observed_frames(setup.observations, setup.eyes),
        setup.robust,
    )?
    .with_reach(reach);
    let (records, push) = residuals::point_residuals_and_push(
        &mut problem.sim,
        model.clone(),
        steps,
        &cost,
        setup.observations,
    )?;
    let ground_push = model.ground.is_some().then(|| (push, problem.sim.hovers(&push)));
    let h = problem.sim.grid.h();
    let (mut noise_floor, mut noise_floor_method, mut noise_floor_std_error) =
        floor::stated_floor(setup.observations, setup.cameras, setup.eyes, 2.0 * h, &records);
    let (per_frame, per_camera) = (residuals_per_frame(&records), residuals_per_camera(&records));
    let verts: Vec<[f64; 3]> = cost.surface().mesh.vertices.clone();
    let centers = residuals::kmeans(&verts, settings.regions);
    let regions = residuals::regions(&records, &centers);
    let direction = residuals::direction(&records);
    // the frame of the largest rms (the earliest of equals)
    let worst_frame = per_frame
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
        .map_or(0, |p| p.0);
    let rms = residuals::rms(records.iter()).0;

    // which effect is missing
    let data = DataContext {
        observations: setup.observations,
        spacing: h,
        reference: &verts,
    };
    let search = Search {
        setup,
        base: &base,
        off: &off,
        settings,
        points: records.len(),
        // unknown: never pruned by it
        floor: noise_floor.unwrap_or(f64::NAN),
    };
    let mut candidates = search.candidates(&data, progress, total);
    // a fit as given with a parameter on its bound is not clean: every candidate that could
    // free it is refitted (beyond the refit budget), and the verdict says which did
    let bounded = verdict::bounded(&base_bounds, &base.x);
    if !bounded.is_empty() {
        progress("refit what could free a bound", total, total);
        search.refit_more(
            &mut candidates,
            |c| verdict::could_free(c, &bounded),
            progress,
            total,
        );
    }
    if noise_floor_method != "plane fits" {
        // the residual floor is an upper bound that a large smooth misfit inflates, the depth
        // images' one that shape and motion inflate: the best refit's residuals give a tighter
        // one (measured on the independent hidden-gravity bar: 2.54 sigma at the fit as given,
        // rms 13.6 sigma)
        if let Some(f) = refit_floor(&candidates, steps, &cost, setup.observations)? {
            if noise_floor.map_or(true, |n| f.sigma < n) {
                noise_floor = Some(f.sigma);
                noise_floor_std_error = Some(f.std_error);
                noise_floor_method = "residuals at the best refit";
            }
        }
    }
    progress("verdict", total, total);
    // an rms at the simulation's numerical precision is an exact fit, whatever the floor: the
    // residual estimate of noise-free data is that precision too (the noise-free bunny with
    // nothing hidden: rms 8.9e-17, floor 7.2e-17, and an initial velocity "explained" it by
    // Delta BIC -573)
    let precision = numerical_precision(setup.observations);
    // "exact" and "fails" are measured against the floor: without one, neither is said
    let exact = rms <= precision || noise_floor.is_some_and(|f| rms <= settings.exact_ratio * f);
    let fails = !exact && noise_floor.is_some_and(|f| rms > settings.fail_ratio * f);
    let (mut missing, mut alternatives) = pick(&candidates, rms, exact, settings);
    // what the named effect's values imply: one that explains the data only with values no
    // body has asks for the rest of the search, and between effects the data cannot tell
    // apart the plausible one is named
    let judge = |c: &Candidate| match plausible::judge(c, setup.observations, noise_floor) {
        Ok(p) => p,
        Err(e) => Some(plausible::Plausibility {
            effect: c.effect.clone(),
            implies: format!("its fitted values could not be judged: {e}"),
            implausible: None,
        }),
    };
    let mut judged = missing.and_then(|i| judge(&candidates[i]));
    let mut refitted_all = false;
    if judged.as_ref().is_some_and(|j| j.implausible.is_some()) {
        progress(
            "refit the rest: the named effect's values are implausible",
            total,
            total,
        );
        search.refit_more(&mut candidates, |c| search.rank(c) > 0.0, progress, total);
        refitted_all = true;
        let named = judged.as_ref().map(|j| j.effect.clone());
        (missing, alternatives) = pick(&candidates, rms, exact, settings);
        // judged again only when another effect is named now (one simulation each)
        if missing.map(|i| &candidates[i].effect) != named.as_ref() {
            judged = missing.and_then(|i| judge(&candidates[i]));
        }
    }
    let mut passed_over = None;
    if let (Some(m), Some(j)) = (missing, judged.as_ref().filter(|j| j.implausible.is_some())) {
        let plausible_alt = alternatives.iter().find_map(|&a| {
            judge(&candidates[a])
                .filter(|p| p.implausible.is_none())
                .map(|p| (a, p))
        });
        if let Some((a, p)) = plausible_alt {
            alternatives.retain(|&x| x != a);
            alternatives.insert(0, m);
            missing = Some(a);
            passed_over = Some(j.clone());
            judged = Some(p);
        }
    }
    for c in &mut candidates {
        c.frees = verdict::freed(c, &bounded, &base_bounds);
    }
    let missing = missing.map(|i| &candidates[i]);
    let missing_effect = missing.map(|c| c.effect.clone());
    let alternatives: Vec<String> = alternatives
        .iter()
        .map(|&i| candidates[i].effect.clone())
        .collect();
    let mut verdict = verdict::full(
        missing,
        rms,
        (noise_floor, noise_floor_method),
        precision,
        fails,
        &candidates,
        &on_bounds,
    );
    verdict.push_str(&verdict::plausibility(
        judged.as_ref(),
        passed_over.as_ref(),
        refitted_all,
    ));
    verdict.push_str(&verdict::freeing(&on_bounds, &candidates, missing));
    if !alternatives.is_empty() {
        verdict.push_str(&format!(
            "\n(or {}: the data do not tell {} from {}, Delta BIC within {})",
            alternatives.join(", "),
            if alternatives.len() == 1 { "it" } else { "them" },
            missing_effect.as_deref().unwrap_or(""),
            settings.bic_threshold
        ));
    }
    // which recording would tell them apart (a failure leaves the verdict as it is: the
    // alternatives are named either way)
    let separation = match (missing, alternatives.first()) {
        (Some(m), Some(alt)) => {
            progress("separating the alternatives", total, total);
            candidates
                .iter()
                .find(|c| &c.effect == alt)
                .and_then(|b| separate::separating_motion(m, b).ok().flatten())
        }
        _ => None,
    };
    if let Some(s) = &separation {
        verdict.push_str(&separate::advice(s, noise_floor));
    }
    Ok(Diagnosis {
        separation,
        plausibility: judged.into_iter().chain(passed_over).collect(),
        effects: on.iter().map(|e| e.name().to_string()).collect(),
        fitted: problem.params.values(&model),
        rms_start,
        rms,
        noise_floor,
        noise_floor_method,
        noise_floor_std_error,
        on_bounds,
        ground_push,
        per_frame,
        per_camera,
        regions,
        direction,
        worst_frame,
        records,
        candidates,
        missing_effect,
        alternatives,
        verdict,
        unverified: None,
        model,
        fitted_scene,
        base_params: base.params,
        base_x: base.x,
        base_x_start: base.x_start,
    })
}

/// The candidate the verdict names (by index: the first, when the data favour it strongly,
/// `Delta BIC < -threshold`, and it removes enough of the rms) and the refitted candidates the
/// data cannot tell from it (`Delta BIC` within the threshold of its).
fn pick(
    candidates: &[Candidate],
    rms: f64,
    exact: bool,
    settings: &DiagnoseParams,
) -> (Option<usize>, Vec<usize>) {
    let missing = candidates.first().filter(|c| {
        !exact
            && c.delta_bic.is_some_and(|d| d < -settings.bic_threshold)
            && c.rms_after.is_some_and(|r| r < settings.min_improvement * rms)
    });
    let alternatives = match missing.and_then(|c| c.delta_bic) {
        Some(best) => (1..candidates.len())
            .filter(|&i| {
                candidates[i]
                    .delta_bic
                    .is_some_and(|d| d < best + settings.bic_threshold)
            })
            .collect(),
        None => Vec::new(),
    };
    (missing.map(|_| 0), alternatives)
}

/// The rms and point count of each observed frame: `(frame, rms, points)` in frame order.
fn residuals_per_frame(records: &[PointResidual]) -> Vec<(usize, f64, usize)> {
    let mut frames: Vec<usize> = records.iter().map(|r| r.frame).collect();
    frames.dedup();
    frames
        .iter()
        .map(|&f| {
            let (r, n) = residuals::rms(records.iter().filter(|r| r.frame == f));
            (f, r, n)
        })
        .collect()
}

/// The rms and point count of each camera: `(camera, rms, points)` in camera order.
fn residuals_per_camera(records: &[PointResidual]) -> Vec<(u32, f64, usize)> {
    let mut cams: Vec<u32> = records.iter().filter_map(|r| r.camera).collect();
    cams.sort_unstable();
    cams.dedup();
    cams.iter()
        .map(|&c| {
            let (r, n) = residuals::rms(records.iter().filter(|r| r.camera == Some(c)));
            (c, r, n)
        })
        .collect()
}
