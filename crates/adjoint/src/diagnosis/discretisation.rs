//! Discretisation is not missing physics (docs/effects.md, "Discretisation is not missing
//! physics").
//!
//! A grid model has its own error, and with enough data any systematic misfit can look like a
//! missing effect: a drag that slows the swing of a coarse bar whose numerical phase drifts, a
//! soft band that undoes a thin part's locking. Such an effect fits the error of resolution `r`
//! and not the physics, so its improvement does not survive a change of grid. The check
//! ([`persistence`]) simulates both fits of the diagnosis, the model as given (`rms` at `r`)
//! and the named effect's refit (`rms_after` at `r`), with the parameters fitted at `r`, on the
//! grid of resolution `r' = 2r` with the time step refined alike (`crate::refine::carry_model`
//! moves the grid-dependent parts, `crate::refine::substeps_at` the step: a phase lag of the
//! time integrator is the model's own error as much as the grid's),
//! and weighs the two against the same observations with the verdict's own evidence rule
//! (module docs of [`super`]): with `n` residuals and `p` effect parameters,
//!
//! `Delta BIC(r') = n ln(rms_after(r')^2 / rms(r')^2) + p ln n`,
//!
//! and the improvement *persists* when `Delta BIC(r') < -threshold` and
//! `rms_after(r') < min_improvement * rms(r')`. An effect whose improvement does not persist is
//! withdrawn ([`weigh_discretisation`]). The fits are not repeated at `r'`: both models carry
//! the bias of `r` (an `E` fitted through locking is too soft at `r'`) alike, and what is
//! compared is whether the effect still explains what the model as given cannot.
//!
//! A first rule compared the misfit the effect removes, `sqrt(rms^2 - rms_after^2)`, with the
//! discretisation error estimated from two resolutions (`crate::refine`). It withdrew real
//! physics: on an 80-step bar with hidden mass damping, the phase error of the undamped swing
//! makes the `r`-vs-`2r` difference as large as the misfit the damping removes, though at `2r`
//! the damped model still fits far better. That estimate stays in the report (the
//! discretisation share of the rms), not in the verdict.

use super::{residuals, DiagnoseParams, Diagnosis, Setup};
use crate::cost_mesh::SurfaceCost;
use crate::fit::observed_frames;
use crate::Error;
use cutfem::fem::{Grid, Model, Simulation};
use cutfem::scene::Scene;
use serde_json::{json, Value};

/// The named effect's improvement on a finer grid ([`persistence`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Persistence {
    /// the effect
    pub effect: String,
    /// the finer grid's resolution `r'`
    pub resolution: f64,
    /// the model as given (its fit at `r`) on the finer grid
    pub rms: f64,
    /// the named effect's refit (at `r`) on the finer grid
    pub rms_after: f64,
    /// residuals compared
    pub points: usize,
    /// `Delta BIC(r')` (module docs)
    pub delta_bic: f64,
    /// whether the improvement persists
    pub persists: bool,
}

impl Persistence {
    /// Its JSON (the report's `discretisation.persistence`).
    pub fn to_json(&self) -> Value {
        json!({
            "effect": self.effect,
            "resolution": self.resolution,
            "rms": self.rms,
            "rms_after": self.rms_after,
            "points": self.points,
            "delta_bic": self.delta_bic,
            "persists": self.persists,
        })
    }
}

/// The residuals of the model as given on the finer grid, gathered from a run made for
/// another purpose: the refine check's `2r` run of the same model
/// ([`crate::refine::refine_check_observed`]), so that [`persistence`] simulates only the named
/// effect's refit there. [`FinerRun::observe`] is called at frame 0 and after every step.
pub struct FinerRun<'a> {
    setup: &'a Setup<'a>,
    cost: Option<(SurfaceCost, Vec<gpumat::Vec3<f64>>)>,
    records: Vec<residuals::PointResidual>,
    error: Option<String>,
    frames: usize,
}

impl std::fmt::Debug for FinerRun<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FinerRun")
            .field("frames", &self.frames)
            .field("records", &self.records.len())
            .field("error", &self.error)
            .finish()
    }
}

impl<'a> FinerRun<'a> {
    /// Gathers residuals against `setup`'s observations.
    pub fn new(setup: &'a Setup<'a>) -> Self {
        Self {
            setup,
            cost: None,
            records: Vec::new(),
            error: None,
            frames: 0,
        }
    }
    /// The run's state at frame `t` (frames in order from 0).
    pub fn observe(&mut self, sim: &Simulation, t: usize) {
        if self.error.is_some() || t != self.frames {
            self.error
                .get_or_insert_with(|| format!("frame {t} out of order"));
            return;
        }
        if self.cost.is_none() {
            let setup = self.setup;
            let cost = SurfaceCost::new(
                &sim.grid,
                observed_frames(setup.observations, setup.eyes),
                setup.robust,
            )
            .map(|c| c.with_reach(setup.reach.unwrap_or_else(|| Setup::reach(&sim.grid))));
            match cost {
                Ok(c) => {
                    let zero = gpumat::Matrix::zeros(sim.grid.dofs(), 1, 1);
                    let reference = c.vertices(&zero);
                    self.cost = Some((c, reference));
                }
                Err(e) => {
                    self.error = Some(e.to_string());
                    return;
                }
            }
        }
        let (cost, reference) = self.cost.as_ref().expect("made above");
        residuals::frame_residuals(
            &sim.u,
            t,
            cost,
            self.setup.observations,
            reference,
            &mut self.records,
        );
        self.frames += 1;
    }
    /// `(rms, points)` when the run covered frames `0..=steps` without error.
    pub fn rms(&self, steps: usize) -> Option<(f64, usize)> {
        (self.error.is_none() && self.frames == steps + 1).then(|| residuals::rms(self.records.iter()))
    }
}

/// Whether the named effect's improvement persists at resolution `resolution` (module docs);
/// `grid` is the diagnosis' grid (the scene's resolution). `given`: the model as given's
/// `(rms, points)` at `resolution` when a [`FinerRun`] has them (else it is simulated here).
/// `None` when no effect is named (or the named one has no refit).
pub fn persistence(
    setup: &Setup,
    d: &Diagnosis,
    grid: &Grid,
    resolution: f64,
    settings: &DiagnoseParams,
    given: Option<(f64, usize)>,
) -> Result<Option<Persistence>, Error> {
    let Some(name) = d.missing_effect.as_ref() else {
        return Ok(None);
    };
    let Some(c) = d.candidates.iter().find(|c| &c.effect == name) else {
        return Ok(None);
    };
    let (Some(scene), Some(model)) = (&c.scene, &c.model) else {
        return Ok(None);
    };
    let r = d.fitted_scene.resolution()?;
    crate::refine::check_memory(grid, r, resolution)?;
    let (rms, points) = match given {
        Some(g) => g,
        None => rms_at(setup, &d.fitted_scene, grid, &d.model, resolution)?,
    };
    let (rms_after, _) = rms_at(setup, scene, grid, model, resolution)?;
    let (delta_bic, persists) = evidence(rms, rms_after, points, c.params.len(), settings);
    Ok(Some(Persistence {
        effect: name.clone(),
        resolution,
        rms,
        rms_after,
        points,
        delta_bic,
        persists,
    }))
}

/// `Delta BIC` of `rms -> rms_after` over `points` residuals with `params` more parameters,
/// and whether it passes the verdict's rule (module docs).
fn evidence(
    rms: f64,
    rms_after: f64,
    points: usize,
    params: usize,
    settings: &DiagnoseParams,
) -> (f64, bool) {
    let n = points.max(1) as f64;
    let ratio = (rms_after / rms).powi(2).max(f64::MIN_POSITIVE);
    let delta_bic = n * ratio.ln() + params as f64 * n.ln();
    let passes = delta_bic < -settings.bic_threshold && rms_after < settings.min_improvement * rms;
    (delta_bic, passes)
}

/// The rms (and residual count) of `model` (on `grid`, built from `scene`) simulated on the
/// grid of `resolution` against the observations of `setup`.
fn rms_at(
    setup: &Setup,
    scene: &Scene,
    grid: &Grid,
    model: &Model,
    resolution: f64,
) -> Result<(f64, usize), Error> {
    let (other, m) = crate::refine::at_resolution(scene, grid, model, resolution)?;
    let level = format!("resolution {resolution}");
    let mut sim = Simulation::new(other, m.clone()).map_err(|e| Error::step(&level, e))?;
    sim.solver = scene.solver_settings(sim.solver);
    let cost = SurfaceCost::new(
        &sim.grid,
        observed_frames(setup.observations, setup.eyes),
        setup.robust,
    )?
    .with_reach(setup.reach.unwrap_or_else(|| Setup::reach(&sim.grid)));
    let steps = setup.steps.unwrap_or(scene.time.steps);
    let records = residuals::point_residuals(&mut sim, m, steps, &cost, setup.observations)
        .map_err(|e| Error::Invalid(format!("{level}: {e}")))?;
    Ok(residuals::rms(records.iter()))
}

/// Withdraws the named effect when its improvement does not persist on the finer grid
/// (`missing_effect` and `alternatives` cleared, the verdict says why). Returns whether it did.
pub fn weigh_discretisation(d: &mut Diagnosis, p: &Persistence) -> bool {
    let Some(verdict) = withdrawal(d.missing_effect.as_deref(), p) else {
        return false;
    };
    d.missing_effect = None;
    d.alternatives.clear();
    d.verdict = verdict;
    true
}

/// The verdict when the effect `named` is withdrawn by `p` (else `None`).
fn withdrawal(named: Option<&str>, p: &Persistence) -> Option<String> {
    (!p.persists && named == Some(p.effect.as_str())).then(|| {
        format!(
            "nothing called missing: {} improves the fit at this grid but not at resolution {} \
             (rms {:.4e} -> {:.4e}, Delta BIC {:.1}): it fits the model's own discretisation \
             error; refine the grid ([body] resolution) and diagnose again",
            p.effect, p.resolution, p.rms, p.rms_after, p.delta_bic
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The verdict's rule at the finer grid: strong evidence and a 3% fall of the rms.
    #[test]
    fn the_improvement_must_pass_the_verdicts_rule() {
        let s = DiagnoseParams::default();
        // 1000 residuals: 0.0125 -> 0.0100 is Delta BIC 1000 ln 0.64 + ln 1000 = -439.4
        let (bic, ok) = evidence(0.0125, 0.0100, 1000, 1, &s);
        assert!((bic - (1000.0 * 0.64f64.ln() + 1000f64.ln())).abs() < 1e-9);
        assert!(ok);
        // a 1% fall: strong evidence over many points, too small an improvement
        assert!(!evidence(0.0100, 0.0099, 100_000, 1, &s).1);
        // a 5% fall over 20 points: not enough evidence for two parameters
        let (bic, ok) = evidence(0.0100, 0.0095, 20, 2, &s);
        assert!(bic > -s.bic_threshold && !ok, "{bic}");
        // worse at the finer grid
        assert!(!evidence(0.0100, 0.0110, 1000, 1, &s).1);
    }

    /// Only a named effect whose improvement does not persist is withdrawn.
    #[test]
    fn an_improvement_that_does_not_persist_is_withdrawn() {
        let mut p = Persistence {
            effect: "drag".into(),
            resolution: 40.0,
            rms: 0.0125,
            rms_after: 0.0124,
            points: 1000,
            delta_bic: 5.0,
            persists: true,
        };
        assert_eq!(withdrawal(Some("drag"), &p), None);
        p.persists = false;
        assert_eq!(withdrawal(Some("damping"), &p), None);
        assert_eq!(withdrawal(None, &p), None);
        let v = withdrawal(Some("drag"), &p).expect("withdrawn");
        assert!(v.contains("drag") && v.contains("resolution 40"), "{v}");
    }
}
