//! Tangent-linear (forward) sensitivities and the Gauss-Newton matrix (the thesis' sec. 5.6
//! could not use Gauss-Newton; with few parameters it is cheap).
//!
//! For each fitted coordinate `x_k` the sensitivities `S_u = du/dx_k`, `S_v = dv/dx_k` follow
//! the linearized step (eq. 2.6.2 differentiated):
//!
//! ```text
//! A S_u' = dR,   dR = d/de [ b(u + e S_u, v + e S_v, x + e e_k) - A(...) u' ] at e = 0,
//! S_v'   = (S_u' - S_u) / (theta dt) - (1 - theta) / theta S_v,
//! ```
//!
//! one extra solve per parameter and step with the same `A` as the forward step. The directional
//! derivative `dR` of the step residual (with `u'` fixed) is taken by a central difference of
//! two assemblies (relative accuracy about 1e-8); the solve is exact to a relative residual of
//! at most 1e-8 ([`TANGENT_TOLERANCE`], the scene's `cg_tolerance` when tighter; the default
//! is 1e-8), whatever looser tolerance a scene gives its forward solves. The
//! Gauss-Newton matrix is `H = sum_t J_t^T W_t J_t` with `J_t = dr_t/du S_u(t)` from the cost's
//! linearization ([`crate::cost::Cost::frame_gauss_newton`]); the gradient stays the exact
//! adjoint one.
//!
//! The pass needs the forward states `u(t)`: [`Problem::gauss_newton`] takes them from the
//! gradient's stored forward run (each step replayed, not solved:
//! [`cutfem::fem::Simulation::replay_substep`], which leaves the linear solver as the step's
//! own solve would, so the matrix is the same to the bit); [`Problem::gauss_newton_matrix`]
//! steps itself.

use crate::problem::{Evaluation, Problem, Trajectory};
use crate::Error;
use cutfem::fem::Model;
use gpumat::{Matrix, Vec3};

/// Step of the central difference of the step residual, in the unconstrained coordinates.
const EPS: f64 = 1e-6;

/// Relative residual of the tangent solves, about the central difference's own accuracy.
const TANGENT_TOLERANCE: f64 = 1e-8;

impl Problem {
    /// The cost, its adjoint gradient and the Gauss-Newton matrix (`n x n`, row-major) at `x`.
    ///
    /// The tangent-linear pass replays the gradient's forward run from its stored states
    /// instead of solving each step again ([`cutfem::fem::Simulation::replay_substep`]): the
    /// same matrix, to the bit, as [`Problem::gauss_newton_matrix`] at `x`, for every solver
    /// that replays exactly (otherwise the pass runs its own forward steps).
    pub fn gauss_newton(&mut self, x: &[f64]) -> Result<(Evaluation, Vec<f64>, Vec<f64>), Error> {
        let (mut ev, g, traj) = self.gradient_keeping_states(x)?;
        let h = self.tangent_pass(x, &unit_directions(x.len()), Some(&traj))?;
        ev.gauss_newton = Some(h.clone());
        Ok((ev, g, h))
    }

    /// The sensitivities `du(t)/dx_k` for every step (index `t`), or only the observed frames'
    /// Gauss-Newton contributions: returns `H`.
    pub fn gauss_newton_matrix(&mut self, x: &[f64]) -> Result<Vec<f64>, Error> {
        self.tangent_pass(x, &unit_directions(x.len()), None)
    }

    /// The Gauss-Newton matrix in the directions `dirs` (`D^T H D`, `m x m` row-major for `m`
    /// directions): one tangent-linear pass per direction instead of one per coordinate.
    pub fn gauss_newton_directions(&mut self, x: &[f64], dirs: &[Vec<f64>]) -> Result<Vec<f64>, Error> {
        self.tangent_pass(x, dirs, None)
    }

    /// The tangent-linear pass in the directions `dirs`, replaying a stored forward run of
    /// the model at `x` when given (and the solver replays exactly), else stepping itself.
    fn tangent_pass(
        &mut self,
        x: &[f64],
        dirs: &[Vec<f64>],
        stored: Option<&Trajectory>,
    ) -> Result<Vec<f64>, Error> {
        let stored = stored.filter(|_| self.sim.replays_exactly());
        let n = dirs.len();
        let model = self.model_at(x);
        let dofs = self.sim.grid.dofs();
        let frames = self.cost.frames();
        let dt = model.dt;
        let models: Vec<(Model, Model)> = dirs
            .iter()
            .map(|d| {
                let xp: Vec<f64> = x.iter().zip(d).map(|(a, b)| a + EPS * b).collect();
                let xm: Vec<f64> = x.iter().zip(d).map(|(a, b)| a - EPS * b).collect();
                (self.model_at(&xp), self.model_at(&xm))
            })
            .collect();
        // initial sensitivities: u(0) = 0; v(0) depends on the initial-velocity parameters
        let mut su: Vec<Matrix<Vec3<f64>>> = vec![Matrix::zeros(dofs, 1, 1); n];
        let mut sv: Vec<Matrix<Vec3<f64>>> = Vec::with_capacity(n);
        let invalid = |e: cutfem::Error| Error::Invalid(e.to_string());
        for (mp, mm) in &models {
            self.sim.reset(mp.clone()).map_err(invalid)?;
            let vp = self.sim.v.clone();
            self.sim.reset(mm.clone()).map_err(invalid)?;
            sv.push(Matrix::eval((vp.ex() - self.sim.v.ex()) * (0.5 / EPS)));
        }
        self.sim.reset(model.clone()).map_err(invalid)?;
        let mut h = vec![0.0; n * n];
        let add = |h: &mut Vec<f64>, c: Vec<f64>| h.iter_mut().zip(c).for_each(|(a, b)| *a += b);
        if frames.binary_search(&0).is_ok() {
            let c = self
                .cost
                .frame_gauss_newton(0, &self.sim.u, &su)
                .map_err(|e| Error::Diverged(e.to_string()))?;
            add(&mut h, c);
        }
        let nm = model.newmark();
        let substeps = model.substeps;
        for t in 1..=self.integrator_steps() {
            let (u0, v0) = (self.sim.u.clone(), self.sim.v.clone());
            match stored {
                Some(traj) => {
                    let (u, v) = traj.state(t);
                    self.sim.replay_substep(u, v);
                }
                None => {
                    self.sim
                        .substep()
                        .map_err(|e| Error::Diverged(format!("step {t}: {e}")))?;
                }
            }
            let (u1, v1) = (self.sim.u.clone(), self.sim.v.clone());
            let mut drs = Vec::with_capacity(n);
            for k in 0..n {
                let mut res = [Matrix::zeros(dofs, 1, 1), Matrix::zeros(dofs, 1, 1)];
                for (side, (m, sign)) in [(&models[k].0, 1.0), (&models[k].1, -1.0)]
                    .into_iter()
                    .enumerate()
                {
                    self.sim.set_model(m.clone()).map_err(invalid)?;
                    self.sim.u = Matrix::eval(u0.ex() + su[k].ex() * (sign * EPS));
                    self.sim.v = Matrix::eval(v0.ex() + sv[k].ex() * (sign * EPS));
                    self.sim.linearize_contact_at(Some(u1.clone()));
                    self.sim.assemble_system();
                    res[side] = Matrix::eval(self.sim.newmark_rhs() - self.sim.newmark_matrix() * &u1);
                }
                drs.push(Matrix::eval((res[0].ex() - res[1].ex()) * (0.5 / EPS)));
            }
            self.sim.set_model(model.clone()).map_err(invalid)?;
            self.sim.u = u0;
            self.sim.v = v0;
            self.sim.linearize_contact_at(Some(u1.clone()));
            self.sim.assemble_system();
            self.sim.expect_solves(n);
            for k in 0..n {
                let mut x = Matrix::eval(su[k].ex() + sv[k].ex() * dt);
                self.sim
                    .solve_newmark_to(&drs[k], &mut x, TANGENT_TOLERANCE)
                    .map_err(|e| Error::Diverged(format!("tangent step {t}: {e}")))?;
                nm.update_velocity(&mut sv[k], &x, &su[k]);
                su[k] = x;
            }
            self.sim.u = u1;
            self.sim.v = v1;
            if let Some(f) = crate::problem::observed_frame(&frames, t, substeps) {
                let c = self
                    .cost
                    .frame_gauss_newton(f, &self.sim.u, &su)
                    .map_err(|e| Error::Diverged(e.to_string()))?;
                add(&mut h, c);
            }
        }
        Ok(h)
    }
}

/// The unit vectors of `R^n`.
fn unit_directions(n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|k| {
            let mut d = vec![0.0; n];
            d[k] = 1.0;
            d
        })
        .collect()
}
