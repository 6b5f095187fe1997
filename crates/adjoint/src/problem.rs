//! A reconstruction problem: a simulation, the parameters to fit and a cost; its value and its
//! adjoint gradient (thesis Alg. 5.1 forward, Alg. 5.3 backward).
//!
//! The forward pass stores only `u` and `v` per frame (3 numbers per node each); the backward
//! pass recomputes `K`, `A`, the contact forces and the cost gradients of the observed frames
//! from them (sec. 5.7) and runs [`crate::backward::step_adjoint`] from the last step to the
//! first:
//!
//! ```text
//! u_bar = dJ/du(T), v_bar = 0
//! for n = T-1 .. 0:
//!     g = u_bar + v_bar / (theta dt);   assemble A at (u_n, v_n);   solve A lam = g
//!     u_bar <- dJ/du(n) - v_bar / (theta dt) + dL/du_n
//!     v_bar <- -(1-theta)/theta v_bar + dL/dv_n;   p_bar += dL/dp
//! p_bar += adjoint of the initial velocity (v_bar)
//! ```

use crate::backward::{initial_velocity_adjoint, step_adjoint, PhysicalGradient};
use crate::cost::{Cost, FrameCost};
use crate::params::{Layout, ParamSet};
use crate::Error;
use cutfem::fem::{Model, Simulation};
use gpumat::{Matrix, Vec3};
use std::time::Instant;

/// The result of one evaluation.
#[derive(Clone, Debug)]
pub struct Evaluation {
    /// total cost
    pub cost: f64,
    /// per observed frame
    pub frames: Vec<FrameCost>,
    /// the model evaluated
    pub model: Model,
    /// seconds in the forward steps
    pub forward_s: f64,
    /// seconds in the cost (and its gradient)
    pub cost_s: f64,
    /// seconds in the backward pass
    pub backward_s: f64,
    /// CG iterations of the forward solves
    pub forward_iterations: usize,
    /// CG iterations of the adjoint solves
    pub backward_iterations: usize,
    /// direct-solver fallbacks
    pub fallbacks: usize,
    /// the Gauss-Newton matrix at the evaluated point (`n x n` row-major in the problem's
    /// coordinates) when the evaluation made it ([`Problem::gauss_newton`]); the standard
    /// errors at a fit's result use it instead of another tangent-linear pass
    pub gauss_newton: Option<Vec<f64>>,
}

impl Evaluation {
    /// Root mean square residual over all observed frames.
    pub fn rms(&self) -> f64 {
        let (s, n) = self
            .frames
            .iter()
            .fold((0.0, 0usize), |(s, n), f| (s + f.sum_squared, n + f.count));
        if n == 0 {
            0.0
        } else {
            (s / n as f64).sqrt()
        }
    }
}

/// Errors (naming `time.steps`) when `steps` steps of a body of `dofs` nodes need more memory
/// than is available: the adjoint keeps `u` and `v` of every frame, 3 f64 per node each.
pub fn check_memory(steps: usize, dofs: usize) -> Result<(), Error> {
    let bytes = (steps as u128 + 1) * dofs as u128 * 48;
    match cutfem::fem::grid::available_memory() {
        Some(avail) if bytes > avail as u128 => {
            let gib = |b: u128| b as f64 / (1u64 << 30) as f64;
            Err(Error::Invalid(format!(
                "time.steps: {steps} steps of {dofs} nodes keep {:.1} GiB of states for the adjoint, \
                 more than the {:.1} GiB available; lower the steps or the resolution",
                gib(bytes),
                gib(avail as u128)
            )))
        }
        _ => Ok(()),
    }
}

/// The observed frame at integrator step `t` (`substeps` steps per frame), if `frames` (sorted)
/// holds it.
pub(crate) fn observed_frame(frames: &[usize], t: usize, substeps: usize) -> Option<usize> {
    (t % substeps == 0 && frames.binary_search(&(t / substeps)).is_ok()).then_some(t / substeps)
}

/// A reconstruction problem (module docs).
#[derive(Debug)]
pub struct Problem {
    /// the simulation (reset for every evaluation)
    pub sim: Simulation,
    /// the model at the start (parameters not fitted keep these values)
    pub base: Model,
    /// the fitted parameters, checked against `base`
    pub params: Layout,
    /// the cost
    pub cost: Box<dyn Cost>,
    /// number of simulated frames (each `model.substeps` integrator steps)
    pub steps: usize,
    /// a displacement larger than this counts as divergence
    pub divergence_limit: f64,
}

/// A state vector stored compactly: 3 values per node (a `Vec3` in a matrix has 4 lanes).
struct Packed(Vec<[f64; 3]>);

impl Packed {
    fn pack(m: &Matrix<Vec3<f64>>) -> Self {
        Packed(m.as_slice().iter().map(|v| v.to_array()).collect())
    }
    fn unpack(&self) -> Matrix<Vec3<f64>> {
        Matrix::from_fn(self.0.len(), 1, 1, |i, _, _| Vec3::from_array(self.0[i]))
    }
}

/// The stored forward trajectory: `u` and `v` per frame (sec. 5.7: nothing else is stored;
/// `K`, `A`, the contact forces and the cost gradients are recomputed in the backward pass).
pub(crate) struct Trajectory {
    u: Vec<Packed>,
    v: Vec<Packed>,
}

impl Trajectory {
    /// The state after integrator step `t` (0: the initial state).
    pub(crate) fn state(&self, t: usize) -> (Matrix<Vec3<f64>>, Matrix<Vec3<f64>>) {
        (self.u[t].unpack(), self.v[t].unpack())
    }
}

impl Problem {
    /// Sets up a problem. Errors when an observed frame lies beyond `steps` or a parameter
    /// needs an effect the model lacks. The external force's coefficient count is taken from
    /// the model ([`ParamSet::layout`]).
    pub fn new(sim: Simulation, params: ParamSet, cost: Box<dyn Cost>, steps: usize) -> Result<Self, Error> {
        let base = sim.model.clone();
        let params = params.layout(&base)?;
        if let Some(&last) = cost.frames().last() {
            if last > steps {
                return Err(Error::Invalid(format!(
                    "observations: frame {last} lies beyond the {steps} simulated steps (raise [time].steps or --steps)"
                )));
            }
        }
        check_memory(steps * base.substeps, sim.grid.dof_nodes.len())?;
        let size = {
            let s = &sim.grid.sdf;
            let d = s.dims;
            s.spacing * (d[0].max(d[1]).max(d[2])) as f64
        };
        Ok(Self {
            sim,
            base,
            params,
            cost,
            steps,
            divergence_limit: 10.0 * size,
        })
    }

    /// Integrator steps simulated: `steps` frames of `model.substeps` steps each.
    pub fn integrator_steps(&self) -> usize {
        self.steps * self.base.substeps
    }

    /// The starting point in unconstrained coordinates.
    pub fn x0(&self) -> Vec<f64> {
        self.params.to_x(&self.base)
    }

    /// The model at `x`.
    pub fn model_at(&self, x: &[f64]) -> Model {
        let mut m = self.base.clone();
        self.params.apply(x, &mut m);
        m
    }

    fn forward(&mut self, model: Model, store: bool) -> Result<(Evaluation, Option<Trajectory>), Error> {
        let t0 = Instant::now();
        self.sim
            .reset(model.clone())
            .map_err(|e| Error::Invalid(e.to_string()))?;
        let frames = self.cost.frames();
        let mut ev = Evaluation {
            cost: 0.0,
            frames: Vec::new(),
            model,
            forward_s: 0.0,
            cost_s: 0.0,
            backward_s: 0.0,
            forward_iterations: 0,
            backward_iterations: 0,
            fallbacks: 0,
            gauss_newton: None,
        };
        let mut traj = store.then(|| Trajectory {
            u: vec![Packed::pack(&self.sim.u)],
            v: vec![Packed::pack(&self.sim.v)],
        });
        let mut cost_s = 0.0;
        let substeps = self.base.substeps;
        for t in 0..=self.integrator_steps() {
            if t > 0 {
                let info = self
                    .sim
                    .substep()
                    .map_err(|e| Error::Diverged(format!("step {t}: {e}")))?;
                ev.forward_iterations += info.iterations;
                ev.fallbacks += usize::from(info.fallback);
                let m = self.sim.max_displacement();
                if !m.is_finite() || m > self.divergence_limit {
                    return Err(Error::Diverged(format!(
                        "step {t}: displacement {m:.3e} exceeds {:.3e} ({})",
                        self.divergence_limit,
                        self.sim.scales_note()
                    )));
                }
                if let Some(tr) = &mut traj {
                    tr.u.push(Packed::pack(&self.sim.u));
                    tr.v.push(Packed::pack(&self.sim.v));
                }
            }
            if let Some(f) = observed_frame(&frames, t, substeps) {
                let tc = Instant::now();
                let fc = self
                    .cost
                    .frame_cost(f, &self.sim.u, None)
                    .map_err(|e| Error::Diverged(format!("frame {f}: {e}")))?;
                cost_s += tc.elapsed().as_secs_f64();
                ev.cost += fc.cost;
                ev.frames.push(fc);
            }
        }
        ev.cost_s = cost_s;
        ev.forward_s = t0.elapsed().as_secs_f64() - cost_s;
        Ok((ev, traj))
    }

    /// The cost of a given model (forward run only).
    pub fn evaluate_model(&mut self, model: Model) -> Result<Evaluation, Error> {
        Ok(self.forward(model, false)?.0)
    }

    /// The cost at `x` (forward run only).
    pub fn evaluate(&mut self, x: &[f64]) -> Result<Evaluation, Error> {
        let model = self.model_at(x);
        Ok(self.forward(model, false)?.0)
    }

    /// The cost at `x` and its adjoint gradient with respect to `x` (and the physical one).
    pub fn gradient(&mut self, x: &[f64]) -> Result<(Evaluation, Vec<f64>, PhysicalGradient), Error> {
        let model = self.model_at(x);
        let (ev, traj) = self.forward(model.clone(), true)?;
        let mut traj = traj.expect("stored");
        self.backward(&model, ev, &mut traj, true)
    }

    /// The cost at `x`, its adjoint gradient and the forward run's stored states (for the
    /// tangent-linear pass, [`Problem::gauss_newton`]).
    pub(crate) fn gradient_keeping_states(
        &mut self,
        x: &[f64],
    ) -> Result<(Evaluation, Vec<f64>, Trajectory), Error> {
        let model = self.model_at(x);
        let (ev, traj) = self.forward(model.clone(), true)?;
        let mut traj = traj.expect("stored");
        let (ev, g, _) = self.backward(&model, ev, &mut traj, false)?;
        Ok((ev, g, traj))
    }

    /// The backward pass over a stored forward run of `model` (the evaluation `ev`); frees the
    /// states it no longer needs as it goes when `free`.
    fn backward(
        &mut self,
        model: &Model,
        mut ev: Evaluation,
        traj: &mut Trajectory,
        free: bool,
    ) -> Result<(Evaluation, Vec<f64>, PhysicalGradient), Error> {
        let tb = Instant::now();
        let n = self.sim.grid.dofs();
        let nm = model.newmark();
        let mut grad = PhysicalGradient::default();
        let frames = self.cost.frames();
        let mut cost_s = 0.0;
        let substeps = self.base.substeps;
        let last = self.integrator_steps();
        // dJ/du(t) of an observed frame, recomputed from the stored state
        let mut cost_grad =
            |cost: &dyn Cost, t: usize, u: &Matrix<Vec3<f64>>| -> Result<Matrix<Vec3<f64>>, Error> {
                let mut g = Matrix::zeros(n, 1, 1);
                if let Some(f) = observed_frame(&frames, t, substeps) {
                    let tc = Instant::now();
                    cost.frame_cost(f, u, Some(&mut g))
                        .map_err(|e| Error::Diverged(format!("frame {f}: {e}")))?;
                    cost_s += tc.elapsed().as_secs_f64();
                }
                Ok(g)
            };
        let mut ub = cost_grad(self.cost.as_ref(), last, &traj.u[last].unpack())?;
        let mut vb: Matrix<Vec3<f64>> = Matrix::zeros(n, 1, 1);
        let mut lam: Matrix<Vec3<f64>> = Matrix::zeros(n, 1, 1);
        // the previous adjoint, for a linear extrapolation as the CG warm start
        let mut lam_prev: Option<Matrix<Vec3<f64>>> = None;
        let c = nm.cvel;
        for step in (0..last).rev() {
            let g = Matrix::eval(ub.ex() + vb.ex() * c);
            self.sim.u = traj.u[step].unpack();
            self.sim.v = traj.v[step].unpack();
            let u_next = traj.u[step + 1].unpack();
            self.sim.linearize_contact_at(Some(u_next.clone()));
            self.sim.assemble_system();
            let last = lam.clone();
            if let Some(prev) = &lam_prev {
                lam.assign_with(|l| l * 2.0 - prev.ex());
            }
            lam_prev = Some(last);
            let (its, _, fallback) = self
                .sim
                .solve_newmark(&g, &mut lam)
                .map_err(|e| Error::Diverged(format!("adjoint step {step}: {e}")))?;
            ev.backward_iterations += its;
            ev.fallbacks += usize::from(fallback);
            let mut new_ub = cost_grad(self.cost.as_ref(), step, &self.sim.u)?;
            new_ub.assign_with(|u| u - vb.ex() * c);
            let mut new_vb = Matrix::eval(vb.ex() * -nm.cold);
            step_adjoint(&self.sim, &u_next, &lam, &mut new_ub, &mut new_vb, &mut grad);
            ub = new_ub;
            vb = new_vb;
            // free what the rest of the pass no longer needs
            if free {
                traj.u.truncate(step + 1);
                traj.v.truncate(step + 1);
            }
        }
        initial_velocity_adjoint(&self.sim, &vb, &mut grad);
        ev.backward_s = tb.elapsed().as_secs_f64() - cost_s;
        ev.cost_s += cost_s;
        let gx = self.params.chain(model, &grad);
        Ok((ev, gx, grad))
    }
}
