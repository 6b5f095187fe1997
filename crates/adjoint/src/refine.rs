//! The model's own error: the discretisation share of a fit's rms (issue 12, "know your own
//! error").
//!
//! A model state (a scene and a model on the grid of resolution `r`, e.g. the fitted one) is
//! simulated again on the grids of resolution `2r` and, when it can be built, `r/2`; the same
//! material points are compared. The points are the vertices `X_k` of the body's surface on the
//! `r` grid (area weights `a_k`, a third of the adjacent triangles' areas), and the
//! displacement of each grid at `X_k` is its trilinear FEM field there (the field the surface
//! moves with, sec. 4.5.1). Per frame `f`,
//!
//! `d_f(r, 2r) = sqrt( sum_k a_k |u_r(X_k, f) - u_2r(X_k, f)|^2 / sum_k a_k )`,
//!
//! and `d(r, 2r)` is the root mean square over the frames. If the error of resolution `r`
//! behaves like `e(r) = C r^-p`, then `d(r, 2r) = e(r) (1 - 2^-p)`, so with the observed order
//! `p = log2(d(r/2, r) / d(r, 2r))` (Richardson)
//!
//! `e(r) ~ d(r, 2r) 2^p / (2^p - 1)`,
//!
//! and the resolution `r'` that brings the error down to a target `t` is `r (e(r) / t)^(1/p)`.
//! Without an observed order (the `r/2` grid could not be built, or the differences do not
//! fall) the estimate is `d(r, 2r)` itself (exact for a fast-converging model, a lower bound
//! otherwise) and the suggested resolution uses `p = 1` (conservative). A resolution more than
//! [`MAX_REFINEMENT`] times finer is not suggested (the warning says no practical refinement
//! removes the error), and a noise floor at rounding (at most `1e-8` of the motion: data made
//! by this very model at this resolution) is said to be one rather than chased.
//!
//! The time step refines with the grid (`h` and `dt` halved together; `[time] substeps` is
//! doubled at `2r` and halved at `r/2` where it divides, else kept): the model's own error is
//! that of both discretisations, and the time error alone can exceed a depth camera's noise.
//! Measured on the independent clamped bar (Table H, `dt` = 0.03, trapezoidal Newmark, first
//! bending period 0.63 s): with a stiff inclusion too small to see, observed by a depth camera
//! with noise 0.0025, the model as given misses by 1.78 sigma with one integrator step per
//! frame and 1.42 sigma with four, and with one the swing's numerical phase lag was named a
//! missing initial velocity that kept its improvement on the grid of `2r` alone. The `r/2`
//! level keeps the step where the substeps do not divide; the observed order then mixes a
//! coarser grid with the same step, and the estimate is a lower bound when time dominates.
//!
//! With the lumped mass (`[numerics] mass = "lumped"`, the default) the check also runs the
//! model at `r` with the consistent mass and compares it with the same `2r` run: if the lumped
//! mass' error is `A h^2` and the rest `B h^2`, the lumped difference is `3/4 (A + B) h^2` and the
//! consistent one `|B - (A + B) / 4| h^2`, a third of it when the mass dominates (`B = 0`), the
//! same when it plays no part (`A = 0`). Below half, the warning names the consistent mass
//! (`cutfem::fem::assembly::mass`: the lumped mass' rotational inertia is `O(h^2)` too large).
//! Measured: the independent twisting bar 5.06e-3 lumped, 2.32e-3 consistent (named); the
//! swinging cantilever of the tests 1.40e-3, 1.31e-3 (not named). Where the lumped mass' slow
//! rotation cancels a stiff element's fast one, the consistent mass is the farther of the two
//! and is rightly not named (a 1 x 0.25 x 0.25 bar, faces on the grid lines of resolution 16,
//! twisting: 2.74e-3 lumped, 3.21e-3 consistent).
//!
//! Grid-dependent parts of the model move with it: a per-cell stiffness factor is read at the
//! finer cell's centre from the cell of `r` containing it, an external force's coefficients
//! are copied to the effect rebuilt on the other grid.

use crate::Error;
use cutfem::fem::grid::{available_memory, BYTES_PER_NODE, INACTIVE};
use cutfem::fem::{Grid, MassMatrix, Model, Simulation};
use cutfem::scene::Scene;
use gpumat::{Matrix, Vec3};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::sync::Arc;

/// The outcome of [`refine_check`].
#[derive(Clone, Debug, PartialEq)]
pub struct RefineCheck {
    /// the model's resolution `r` (cells per world unit)
    pub resolution: f64,
    /// the rms surface displacement of the run at `r` (the motion's scale), world units
    pub motion: f64,
    /// `d(r, 2r)`, world units
    pub difference: f64,
    /// the largest `|u_r - u_2r|` at a surface point over all frames
    pub max_difference: f64,
    /// `d(r/2, r)`, when the `r/2` grid could be built
    pub coarser_difference: Option<f64>,
    /// the observed order `p`, when the differences fall (`p > 0.25`)
    pub order: Option<f64>,
    /// the estimated discretisation error of resolution `r`, world units
    pub estimate: f64,
    /// `(frame, d_f(r, 2r))`
    pub per_frame: Vec<(usize, f64)>,
    /// why the `r/2` level is missing, if it is
    pub note: Option<String>,
    /// integrator steps per frame at `r` (at `2r` twice as many)
    pub substeps: usize,
    /// with the lumped mass: `d(r, 2r)` with the consistent mass at `r` (module docs)
    pub consistent_mass_difference: Option<f64>,
}

impl RefineCheck {
    /// The resolution that brings the estimated error down to `target` (none needed when it
    /// is below already).
    pub fn resolution_for(&self, target: f64) -> Option<f64> {
        if target.is_nan() || target <= 0.0 || self.estimate <= target {
            return None;
        }
        let p = self.order.unwrap_or(1.0).clamp(0.5, 4.0);
        Some((self.resolution * (self.estimate / target).powf(1.0 / p)).ceil())
    }

    /// The check as JSON, judged against the noise floor `noise` when it is known: `share` is
    /// the estimate over the noise, a warning when it exceeds the noise, and the resolution
    /// that would bring it to half the noise (where it adds at most 12% to the rms).
    /// `suggested_resolution` is absent where it would be more than [`MAX_REFINEMENT`] times
    /// finer (`required_resolution` still says what it would take).
    pub fn to_json(&self, noise: Option<f64>) -> Value {
        let required = noise.and_then(|n| self.resolution_for(0.5 * n));
        let suggested = required.filter(|&r| r <= MAX_REFINEMENT * self.resolution);
        json!({
            "resolution": self.resolution,
            "motion": self.motion,
            "finer_resolution": 2.0 * self.resolution,
            "substeps": self.substeps,
            "finer_substeps": substeps_at(self.substeps, 2.0),
            "difference": self.difference,
            "max_difference": self.max_difference,
            "coarser_difference": self.coarser_difference,
            "order": self.order,
            "estimate": self.estimate,
            "noise_floor": noise,
            "share": noise.map(|n| self.estimate / n),
            "warning": self.warning(noise),
            "suggested_resolution": suggested,
            "required_resolution": required,
            "noise_at_rounding": noise.map(|n| self.rounding_floor(n)),
            "consistent_mass_difference": self.consistent_mass_difference,
            "mass_dominates": self.mass_dominates(),
            "per_frame": self.per_frame.iter().map(|(f, d)| json!({"frame": f, "difference": d})).collect::<Vec<_>>(),
            "note": self.note,
        })
    }

    /// Whether the consistent mass takes away most of the difference to `2r` (module docs).
    pub fn mass_dominates(&self) -> bool {
        self.consistent_mass_difference
            .is_some_and(|d| d < 0.5 * self.difference)
    }

    /// Whether the noise floor `n` is rounding: at most [`ROUNDING`] of the motion. Only
    /// observations made by this very model at this resolution match it so closely.
    pub fn rounding_floor(&self, n: f64) -> bool {
        n <= ROUNDING * self.motion
    }

    /// A one-line warning when the estimated discretisation error exceeds the noise floor: the
    /// resolution that brings it to half the floor, or, where that is more than
    /// [`MAX_REFINEMENT`] times finer, that no practical refinement does; a floor at rounding
    /// ([`Self::rounding_floor`]) is said to be one (the data carry the same discretisation).
    pub fn warning(&self, noise: Option<f64>) -> Option<String> {
        let n = noise?;
        (self.estimate > n).then(|| {
            let head = format!(
                "the model's own discretisation error (about {:.3e} at resolution {}) exceeds the noise floor {:.3e}",
                self.estimate, self.resolution, n
            );
            if self.rounding_floor(n) {
                return format!(
                    "{head}, a floor at rounding ({:.1e} of the motion): the observations match this \
                     model exactly, as data made by this very model at this resolution do; its \
                     discretisation error is then in the data too and biases nothing here, but it \
                     would against measured data",
                    n / self.motion
                );
            }
            let r = self
                .resolution_for(0.5 * n)
                .unwrap_or(2.0 * self.resolution);
            let mass = match self.consistent_mass_difference {
                Some(d) if self.mass_dominates() => format!(
                    "; most of it is the lumped mass' inertia (with [numerics] mass = \"consistent\" the difference to resolution {} falls from {:.3e} to {d:.3e}): set that first",
                    2.0 * self.resolution,
                    self.difference
                ),
                _ => String::new(),
            };
            if r > MAX_REFINEMENT * self.resolution {
                return format!(
                    "{head}: fitted parameters are biased; no practical refinement removes it (it \
                     would take resolution {r:.3e}, more than {MAX_REFINEMENT}x finer){mass}"
                );
            }
            format!(
                "{head}: fitted parameters are biased; set [body] resolution = {r} or more and [time] substeps = {} (the step refined with the grid){mass}",
                substeps_at(self.substeps, (r / self.resolution).ceil()),
            )
        })
    }

    /// A one-line summary for people.
    pub fn summary(&self, noise: Option<f64>) -> String {
        let order = self.order.map_or("no observed order".to_string(), |p| {
            format!("observed order {p:.2}")
        });
        let mut s = format!(
            "discretisation: surface motion differs by rms {:.3e} (max {:.3e}) between resolution {} and {} (substeps {} and {}); {order}; estimated error {:.3e}",
            self.difference,
            self.max_difference,
            self.resolution,
            2.0 * self.resolution,
            self.substeps,
            substeps_at(self.substeps, 2.0),
            self.estimate
        );
        if let Some(n) = noise {
            let share = self.estimate / n;
            s.push_str(&if share < 1e4 {
                format!(" = {share:.2} x the noise floor")
            } else {
                format!(" = {share:.2e} x the noise floor")
            });
        }
        s
    }
}

/// Differences (and noise floors) below this share of the motion are rounding (no observed
/// order from them).
const ROUNDING: f64 = 1e-8;

/// The most a suggested resolution refines the model's: 8 times finer is 512 times the nodes
/// and 8 times the steps; beyond that a suggestion is not a run.
pub const MAX_REFINEMENT: f64 = 8.0;

/// What [`refine_check`] compares.
#[derive(Clone, Debug, Default)]
pub struct RefineParams {
    /// steps to simulate (default: the scene's)
    pub steps: Option<usize>,
    /// the frames compared (default: all of `1..=steps`)
    pub frames: Option<Vec<usize>>,
    /// skip the `r/2` level (no observed order)
    pub no_order: bool,
}

/// The discretisation check of `model` (on `grid`, built from `scene` at its resolution): see
/// the module docs. `progress(level, step, steps)` reports the runs.
pub fn refine_check(
    scene: &Scene,
    grid: &Grid,
    model: &Model,
    params: &RefineParams,
    progress: &mut dyn FnMut(&str, usize, usize),
) -> Result<RefineCheck, Error> {
    refine_check_observed(scene, grid, model, params, progress, &mut |_, _| {})
}

/// [`refine_check`], with `fine(sim, t)` called on the `2r` run at frame 0 and after every step
/// `t` (another check can use the same finer run: the diagnosis' persistence,
/// `crate::diagnosis::discretisation`).
pub fn refine_check_observed(
    scene: &Scene,
    grid: &Grid,
    model: &Model,
    params: &RefineParams,
    progress: &mut dyn FnMut(&str, usize, usize),
    observe_fine: &mut dyn FnMut(&Simulation, usize),
) -> Result<RefineCheck, Error> {
    let r = scene.resolution()?;
    let steps = params.steps.unwrap_or(scene.time.steps);
    let frames: Vec<usize> = match &params.frames {
        Some(f) => f.iter().copied().filter(|&f| f >= 1 && f <= steps).collect(),
        None => (1..=steps).collect(),
    };
    if frames.is_empty() {
        return Err(Error::invalid("refine check: no frame to compare"));
    }
    let (points, weights) = surface_points(grid);
    if points.is_empty() {
        return Err(Error::invalid("refine check: the body has no surface"));
    }
    check_memory(grid, r, 2.0 * r)?;
    let base = run(
        grid.clone(),
        model.clone(),
        scene,
        steps,
        &frames,
        &points,
        "resolution r",
        progress,
        &mut |_, _| {},
    )?;
    let fine = at_resolution(scene, grid, model, 2.0 * r)?;
    let fine = run(
        fine.0,
        fine.1,
        scene,
        steps,
        &frames,
        &points,
        "resolution 2r",
        progress,
        observe_fine,
    )?;
    let (per_frame, difference, max_difference) = compare(&base, &fine, &weights, &frames);
    // the lumped mass' share: the model at `r` with the consistent mass against the same `2r`
    let consistent_mass_difference = match model.mass {
        MassMatrix::Consistent => None,
        MassMatrix::Lumped => {
            let consistent = Model {
                mass: MassMatrix::Consistent,
                ..model.clone()
            };
            let c = run(
                grid.clone(),
                consistent,
                scene,
                steps,
                &frames,
                &points,
                "resolution r, consistent mass",
                progress,
                &mut |_, _| {},
            )?;
            Some(compare(&c, &fine, &weights, &frames).1)
        }
    };
    let zero = vec![vec![Some([0.0; 3]); points.len()]; frames.len()];
    let motion = compare(&base, &zero, &weights, &frames).1;
    let mut note = None;
    let coarser_difference = if params.no_order {
        None
    } else {
        let coarse = at_resolution(scene, grid, model, 0.5 * r).and_then(|(g, m)| {
            run(
                g,
                m,
                scene,
                steps,
                &frames,
                &points,
                "resolution r/2",
                progress,
                &mut |_, _| {},
            )
        });
        match coarse {
            Ok(c) => Some(compare(&c, &base, &weights, &frames).1),
            Err(e) => {
                note = Some(format!("no observed order: resolution {} fails: {e}", 0.5 * r));
                None
            }
        }
    };
    // differences at rounding level (a rigid motion, exact on every grid) have no order
    let order = coarser_difference
        .filter(|&c| c > 0.0 && difference > ROUNDING * motion)
        .map(|c| (c / difference).log2())
        .filter(|&p| p > 0.25);
    let estimate = match order {
        Some(p) => difference * 2f64.powf(p) / (2f64.powf(p) - 1.0),
        None => difference,
    };
    Ok(RefineCheck {
        resolution: r,
        motion,
        difference,
        max_difference,
        coarser_difference,
        order,
        estimate,
        per_frame,
        note,
        substeps: model.substeps,
        consistent_mass_difference,
    })
}

/// The surface vertices of `grid`'s body and their area weights.
fn surface_points(grid: &Grid) -> (Vec<[f64; 3]>, Vec<f64>) {
    let mesh = cutfem::surface::extract_surface(&grid.sdf).mesh;
    let mut w = vec![0.0; mesh.vertices.len()];
    for (f, face) in mesh.faces.iter().enumerate() {
        let area = mesh.triangle_area(f);
        for &i in face {
            w[i as usize] += area / 3.0;
        }
    }
    (mesh.vertices, w)
}

/// Fails when the grid of resolution `finer` (of `grid`, resolution `r`) would not fit in the
/// available memory (its node count grows as `(finer / r)^3`).
pub(crate) fn check_memory(grid: &Grid, r: f64, finer: f64) -> Result<(), Error> {
    let need = ((finer / r).powi(3) * (grid.dofs() * BYTES_PER_NODE * 2) as f64) as usize;
    match available_memory() {
        Some(avail) if need > avail => Err(Error::Invalid(format!(
            "the grid at resolution {finer} needs about {} MB, {} MB are available",
            need >> 20,
            avail >> 20
        ))),
        _ => Ok(()),
    }
}

/// The simulation grid of `scene` at `resolution` and `model` carried over to it, its time
/// step refined with the grid (module docs: `[time] substeps` times `resolution / r` on a
/// finer grid; divided on a coarser one where the substeps divide, else kept).
pub(crate) fn at_resolution(
    scene: &Scene,
    grid: &Grid,
    model: &Model,
    resolution: f64,
) -> Result<(Grid, Model), Error> {
    let other = scene.grid_at(Some(resolution))?;
    let mut m = scene.build_model(&other)?;
    carry_model(model, grid, &mut m, &other);
    let substeps = substeps_at(model.substeps, resolution / scene.resolution()?);
    m.dt = model.dt * model.substeps as f64 / substeps as f64;
    m.substeps = substeps;
    Ok((other, m))
}

/// The integrator steps per frame on a grid `factor` times as fine as one with `substeps`:
/// `substeps * factor` (rounded) when finer, `substeps / (1 / factor)` when coarser and that
/// divides, else `substeps` (the frame spacing bounds the step).
pub fn substeps_at(substeps: usize, factor: f64) -> usize {
    if factor >= 1.0 {
        substeps * (factor.round() as usize).max(1)
    } else {
        let d = ((1.0 / factor).round() as usize).max(1);
        if substeps % d == 0 {
            substeps / d
        } else {
            substeps
        }
    }
}

/// Carries `from` (on `grid`) over to `to` (built from the same scene on `other`): every
/// global value, the external force's coefficients, the drag coefficient (on `to`'s own nodal
/// weights), and the per-cell stiffness factor read
/// from the cell of `grid` containing each cell centre of `other` (1 outside `grid`'s cells).
pub fn carry_model(from: &Model, grid: &Grid, to: &mut Model, other: &Grid) {
    let external = to.external_force.take();
    let drag = to.drag.take();
    *to = Model {
        stiffness_scale: None,
        external_force: None,
        drag: None,
        ..from.clone()
    };
    // the drag's nodal surface weights belong to the grid: `to`'s, with `from`'s coefficient
    if let (Some(mut d), Some(f)) = (drag, &from.drag) {
        d.coefficient = f.coefficient;
        to.drag = Some(d);
    }
    if let (Some(mut e), Some(f)) = (external, &from.external_force) {
        if e.coefficients.len() == f.coefficients.len() {
            e.coefficients.clone_from(&f.coefficients);
        }
        to.external_force = Some(e);
    }
    if let Some(scale) = &from.stiffness_scale {
        let index: HashMap<[usize; 3], usize> =
            grid.cells.iter().enumerate().map(|(e, c)| (c.coord, e)).collect();
        let (h, o) = (grid.h(), grid.sdf.origin);
        let field: Vec<f64> = other
            .cells
            .iter()
            .map(|c| {
                let x = (other.cell_origin(c) + Vec3::splat(0.5 * other.h())).to_array();
                let coord: [usize; 3] =
                    std::array::from_fn(|d| ((x[d] - o[d]) / h).floor().max(0.0) as usize);
                index.get(&coord).map_or(1.0, |&e| scale[e])
            })
            .collect();
        to.stiffness_scale = Some(Arc::from(field));
    }
}

/// The displacement at each point per compared frame (`None` where the grid has no active
/// node around the point).
type Track = Vec<Vec<Option<[f64; 3]>>>;

#[allow(clippy::too_many_arguments)]
fn run(
    grid: Grid,
    model: Model,
    scene: &Scene,
    steps: usize,
    frames: &[usize],
    points: &[[f64; 3]],
    level: &str,
    progress: &mut dyn FnMut(&str, usize, usize),
    observe: &mut dyn FnMut(&Simulation, usize),
) -> Result<Track, Error> {
    let mut sim = Simulation::new(grid, model).map_err(|e| Error::step(level, e))?;
    sim.solver = scene.solver_settings(sim.solver);
    let mut out = Vec::with_capacity(frames.len());
    observe(&sim, 0);
    for f in 1..=steps {
        sim.step()
            .map_err(|e| Error::step(format!("{level}, step {f}"), e))?;
        progress(level, f, steps);
        observe(&sim, f);
        if frames.contains(&f) {
            out.push(
                points
                    .iter()
                    .map(|&p| displacement_at(&sim.grid, &sim.u, p))
                    .collect(),
            );
        }
    }
    Ok(out)
}

/// The trilinear FEM displacement of `grid` at `p`, over the active corners of the cell
/// containing `p` (renormalized; `None` when they carry less than 1e-6 of the weight).
pub fn displacement_at(grid: &Grid, u: &Matrix<Vec3<f64>>, p: [f64; 3]) -> Option<[f64; 3]> {
    let s = &grid.sdf;
    let (c, t) = s.locate(p)?;
    let (mut sum, mut wsum) = ([0.0; 3], 0.0);
    for k in 0..8 {
        let o = [k & 1, (k >> 1) & 1, (k >> 2) & 1];
        let w: f64 = (0..3)
            .map(|d| if o[d] == 1 { t[d] } else { 1.0 - t[d] })
            .product();
        let dof = grid.node_dofs[s.index(c[0] + o[0], c[1] + o[1], c[2] + o[2])];
        if dof == INACTIVE || w == 0.0 {
            continue;
        }
        let v = u.get(dof as usize, 0, 0).to_array();
        for d in 0..3 {
            sum[d] += w * v[d];
        }
        wsum += w;
    }
    (wsum > 1e-6).then(|| sum.map(|x| x / wsum))
}

/// Per frame and overall: the area-weighted rms and the max of `|a - b|` over the points both
/// tracks know.
fn compare(a: &Track, b: &Track, w: &[f64], frames: &[usize]) -> (Vec<(usize, f64)>, f64, f64) {
    let (mut total, mut wtotal, mut max) = (0.0, 0.0, 0.0f64);
    let per_frame = frames
        .iter()
        .zip(a.iter().zip(b))
        .map(|(&f, (fa, fb))| {
            let (mut s, mut ws) = (0.0, 0.0);
            for ((pa, pb), &wk) in fa.iter().zip(fb).zip(w) {
                if let (Some(x), Some(y)) = (pa, pb) {
                    let d2: f64 = (0..3).map(|d| (x[d] - y[d]).powi(2)).sum();
                    s += wk * d2;
                    ws += wk;
                    max = max.max(d2.sqrt());
                }
            }
            total += s;
            wtotal += ws;
            (f, if ws > 0.0 { (s / ws).sqrt() } else { 0.0 })
        })
        .collect();
    let rms = if wtotal > 0.0 {
        (total / wtotal).sqrt()
    } else {
        0.0
    };
    (per_frame, rms, max)
}
