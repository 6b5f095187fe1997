//! Fitting a scene to observations: the problem set up from a scene file, the optimizer
//! objective around [`Problem`], the physical-space finite differences of `gradcheck`, and
//! the session's log ([`session`]: `fit.log`, resuming).

pub mod session;

use crate::cost::{ObservedPoint, PointCloudCost, Robust};
pub use crate::gradcheck::{gradcheck, GradCheck};
use crate::observations::Observations;
use crate::optim::{EvalError, GaussNewtonObjective, GnEval, Objective};
use crate::params::ParamSet;
use crate::problem::{Evaluation, Problem};
pub use crate::statistics::{invert_small, uncertainty, Uncertainty};
use crate::Error;
use cutfem::fem::advect::Diffusion;
use cutfem::fem::{Grid, Model};
use cutfem::scene::Scene;
use gpumat::Vec3;

/// Builds the point-cloud cost of `observations` on `grid`.
pub fn point_cloud_cost(
    grid: &Grid,
    observations: &Observations,
    robust: Robust,
) -> Result<PointCloudCost, Error> {
    let band = Diffusion::new(grid)?;
    Ok(PointCloudCost::new(
        grid,
        band,
        observed_frames(observations, &[]),
        robust,
    ))
}

/// Which point-to-surface residual a fit uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CostKind {
    /// distance to the simulated surface mesh ([`crate::cost_mesh::SurfaceCost`]): along each
    /// point's viewing ray when its camera's eye is known, else to the closest point
    #[default]
    Surface,
    /// the thesis' level-set value `phi(t)(x)` (eq. 5.4.4, [`PointCloudCost`])
    LevelSet,
}

impl std::str::FromStr for CostKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self, Error> {
        match s {
            "surface" => Ok(CostKind::Surface),
            "levelset" => Ok(CostKind::LevelSet),
            _ => Err(Error::Invalid(format!(
                "unknown cost `{s}` (known: surface, levelset)"
            ))),
        }
    }
}

/// The observed points grouped by frame; `eyes[c]` is the eye of camera `c`, when known.
pub fn observed_frames(observations: &Observations, eyes: &[[f64; 3]]) -> Vec<(usize, Vec<ObservedPoint>)> {
    observations
        .frames()
        .map(|(f, pts)| {
            let pts = pts
                .iter()
                .map(|p| ObservedPoint {
                    position: Vec3::new(p.position[0], p.position[1], p.position[2]),
                    weight: p.weight,
                    eye: p
                        .camera
                        .and_then(|c| eyes.get(c as usize))
                        .map(|e| Vec3::from_array(*e)),
                })
                .collect();
            (f, pts)
        })
        .collect()
}

/// The camera file `softbody observe` writes beside an observation CSV (`obs.csv` ->
/// `obs.cameras.json`): `{"cameras": [{"id": 0, "eye": [x, y, z], ...}, ...]}`.
pub fn cameras_path(observations: &std::path::Path) -> std::path::PathBuf {
    observations.with_extension("cameras.json")
}

/// The point-cloud reconstruction problem of a scene: its simulation, `steps` steps (default:
/// the scene's), the parameters and the observations.
pub fn scene_problem(
    scene: &Scene,
    observations: &Observations,
    params: ParamSet,
    robust: Robust,
    steps: Option<usize>,
    kind: CostKind,
    eyes: &[[f64; 3]],
) -> Result<Problem, Error> {
    scene_problem_reach(scene, observations, params, robust, steps, kind, eyes, None)
}

/// [`scene_problem`] whose surface cost charges points farther than `reach` (default: two
/// cells) from the surface a constant ([`crate::cost_mesh::SurfaceCost::with_reach`]).
#[allow(clippy::too_many_arguments)]
pub fn scene_problem_reach(
    scene: &Scene,
    observations: &Observations,
    params: ParamSet,
    robust: Robust,
    steps: Option<usize>,
    kind: CostKind,
    eyes: &[[f64; 3]],
    reach: Option<f64>,
) -> Result<Problem, Error> {
    let sim = scene.build_simulation()?;
    let mut params = params;
    if params.params.contains(&crate::params::Param::StiffnessField) {
        let cells = scene
            .model
            .as_ref()
            .and_then(|m| m.stiffness_field.as_ref())
            .map_or([4, 4, 4], |f| f.cells);
        params.field = Some(crate::params::FieldBasis::new(&sim.grid, cells)?.into());
    }
    let cost: Box<dyn crate::cost::Cost> = match kind {
        CostKind::Surface => {
            let cost =
                crate::cost_mesh::SurfaceCost::new(&sim.grid, observed_frames(observations, eyes), robust)?;
            Box::new(match reach {
                Some(r) => cost.with_reach(r),
                None => cost,
            })
        }
        CostKind::LevelSet => Box::new(point_cloud_cost(&sim.grid, observations, robust)?),
    };
    let steps = steps.unwrap_or(scene.time.steps);
    crate::problem::check_memory(steps, sim.grid.dof_nodes.len())
        .map_err(|e| Error::format(&scene.path, e.to_string()))?;
    // what the parameters need from the model (a section, an effect) is the scene's to give
    Problem::new(sim, params, cost, steps).map_err(|e| match e {
        Error::Invalid(m) => Error::format(&scene.path, m),
        e => e,
    })
}

/// Evaluations kept by `x`, shared with the caller's iteration callback.
pub type EvaluationLog = std::rc::Rc<std::cell::RefCell<Vec<(Vec<f64>, Evaluation)>>>;

/// The first line (1-based) of an observation CSV whose frame is `frame`, if any.
pub fn frame_line(path: &std::path::Path, frame: usize) -> Option<usize> {
    first_line_with(path, "frame", frame as u64)
}

/// The first line (1-based) of an observation CSV whose integer column `column` (named in the
/// header, case-insensitive) holds `value`, if any: where an error about that value points.
pub fn first_line_with(path: &std::path::Path, column: &str, value: u64) -> Option<usize> {
    let text = cutfem::input::read_string(path, cutfem::input::MAX_DATA_BYTES).ok()?;
    let mut lines = text.lines().enumerate();
    let header = lines.next()?.1;
    let col = header
        .trim_start_matches('\u{feff}')
        .split(',')
        .position(|c| c.trim().eq_ignore_ascii_case(column))?;
    lines
        .find(|(_, l)| l.split(',').nth(col).and_then(|f| f.trim().parse::<u64>().ok()) == Some(value))
        .map(|(i, _)| i + 1)
}

/// Errors (naming the file and line) when an observed frame lies beyond `steps`.
pub fn check_frames(observations: &Observations, path: &std::path::Path, steps: usize) -> Result<(), Error> {
    match observations.last_frame() {
        Some(last) if last > steps => {
            let line = frame_line(path, last).map_or(String::new(), |l| format!(":{l}"));
            Err(Error::Invalid(format!(
                "{}{line}: frame {last} lies beyond the {steps} simulated steps (raise [time].steps or pass --steps)",
                path.display()
            )))
        }
        _ => Ok(()),
    }
}

/// Checks observations against a problem before fitting: frames beyond the simulated steps
/// and observations entirely out of reach of the simulated body are errors naming the file
/// (and line).
pub fn check_observations(
    problem: &mut Problem,
    observations: &Observations,
    path: &std::path::Path,
) -> Result<Evaluation, Error> {
    check_frames(observations, path, problem.steps)?;
    let ev = problem
        .evaluate(&problem.x0())
        .map_err(|e| Error::invalid(format!("the starting model: {e}")))?;
    check_reach(&ev, path)?;
    Ok(ev)
}

/// The second half of [`check_observations`], on an evaluation at the starting parameters:
/// observations entirely out of reach of the simulated body are an error naming `path`.
pub fn check_reach(ev: &Evaluation, path: &std::path::Path) -> Result<(), Error> {
    let (outside, count) = ev
        .frames
        .iter()
        .fold((0, 0), |(o, c), f| (o + f.outside, c + f.count));
    if count > 0 && outside == count {
        return Err(Error::Invalid(format!(
            "{}: none of the {count} observed points lies within reach (two cells) of the simulated surface at the starting parameters; check their units, frames and coordinate frame",
            path.display()
        )));
    }
    Ok(())
}

/// The optimizer's view of a [`Problem`]: every evaluation runs the forward and adjoint passes
/// (and, for Gauss-Newton, the tangent-linear pass); the evaluations are kept by `x` in a
/// shared log so that an iteration callback can report the rms of each iteration at once.
#[derive(Debug)]
pub struct FitObjective<'a> {
    /// the problem
    pub problem: &'a mut Problem,
    /// evaluations done, in order: `(x, evaluation)`
    pub evaluations: EvaluationLog,
}

impl<'a> FitObjective<'a> {
    /// Wraps a problem.
    pub fn new(problem: &'a mut Problem) -> Self {
        Self {
            problem,
            evaluations: EvaluationLog::default(),
        }
    }
    /// The evaluation at exactly `x`, if one was made.
    pub fn evaluation_at(&self, x: &[f64]) -> Option<Evaluation> {
        find_evaluation(&self.evaluations, x)
    }
    fn keep(&mut self, x: &[f64], ev: Evaluation) {
        self.evaluations.borrow_mut().push((x.to_vec(), ev));
    }
}

/// The evaluation at exactly `x` in a log, if any.
pub fn find_evaluation(log: &EvaluationLog, x: &[f64]) -> Option<Evaluation> {
    log.borrow()
        .iter()
        .rev()
        .find(|(xe, _)| xe == x)
        .map(|(_, e)| e.clone())
}

impl Objective for FitObjective<'_> {
    fn eval(&mut self, x: &[f64]) -> Result<(f64, Vec<f64>), EvalError> {
        let (ev, g, _) = self
            .problem
            .gradient(x)
            .map_err(|e| EvalError::new(e.to_string()))?;
        let cost = ev.cost;
        self.keep(x, ev);
        Ok((cost, g))
    }
}

impl GaussNewtonObjective for FitObjective<'_> {
    fn eval_gn(&mut self, x: &[f64]) -> Result<GnEval, EvalError> {
        let (ev, gradient, hessian) = self
            .problem
            .gauss_newton(x)
            .map_err(|e| EvalError::new(e.to_string()))?;
        let cost = ev.cost;
        self.keep(x, ev);
        Ok(GnEval {
            cost,
            gradient,
            hessian,
        })
    }
}

/// Reads a physical parameter component by its label ([`crate::params::Layout::values`]).
pub fn get_physical(model: &Model, label: &str) -> Option<f64> {
    physical_slot(&mut model.clone(), label).map(|v| *v)
}

/// Writes a physical parameter component by its label; false when the label is unknown.
pub fn set_physical(model: &mut Model, label: &str, value: f64) -> bool {
    physical_slot(model, label).map(|v| *v = value).is_some()
}

/// The physical value labelled `label` in `model` (the labels of
/// [`crate::params::Layout::values`]), to read or write; `None` when the model lacks it.
fn physical_slot<'m>(model: &'m mut Model, label: &str) -> Option<&'m mut f64> {
    fn lane<'v>(v: &'v mut Vec3<f64>, c: &str) -> Option<&'v mut f64> {
        match c {
            "x" => Some(&mut v.x),
            "y" => Some(&mut v.y),
            "z" => Some(&mut v.z),
            _ => None,
        }
    }
    let (head, tail) = label.rsplit_once('.').unwrap_or((label, ""));
    match (head, tail) {
        ("young", "") => Some(&mut model.young),
        ("poisson", "") => Some(&mut model.poisson),
        ("density", "") => Some(&mut model.density),
        ("damping_mass", "") => Some(&mut model.damping_mass),
        ("damping_stiffness", "") => Some(&mut model.damping_stiffness),
        ("gravity", c) => lane(&mut model.gravity, c),
        ("initial_velocity", c) => lane(&mut model.initial_velocity, c),
        ("initial_angular_velocity", c) => lane(&mut model.initial_angular_velocity, c),
        ("ground.normal", c) => lane(&mut model.ground.as_mut()?.normal, c),
        ("ground", "height") => Some(&mut model.ground.as_mut()?.height),
        ("drag", "") => Some(&mut model.drag.as_mut()?.coefficient),
        ("clamp", "") => model.support.as_mut(),
        ("friction", "") => model.friction.as_mut(),
        _ => {
            let k = external_index(model, label)?.1;
            Some(&mut model.external_force.as_mut()?.coefficients[k])
        }
    }
}

/// The external force of `model` and the index of its coefficient labelled `label` (its label,
/// e.g. `wind.x`, or `external_force[k]`).
fn external_index<'m>(model: &'m Model, label: &str) -> Option<(&'m cutfem::fem::ExternalForce, usize)> {
    let e = model.external_force.as_ref()?;
    let k = e.labels.iter().position(|l| l == label).or_else(|| {
        let k: usize = label
            .strip_prefix("external_force[")?
            .strip_suffix(']')?
            .parse()
            .ok()?;
        (k < e.len()).then_some(k)
    })?;
    Some((e, k))
}
