//! The linear solves of a [`Simulation`]: the step's `A u' = b` (sec. 4.4.18 of the thesis),
//! the backward pass' and the tangent pass' solves with the same `A`, the replay of a stored
//! step, the static equilibrium `K u = f`, and the solver's device and factor state. How a
//! solve is chosen (CG with its preconditioner, the Cholesky fallback, the repeated-matrix
//! rule) is [`crate::fem::solver`]'s.

use super::{Error, Simulation, StepInfo};
use crate::fem::model::Model;
use crate::fem::solver::{solve, Preconditioner, SolverSettings};
use gpumat::{Mat3, Matrix, SparseMatrix, Vec3};
use std::time::Instant;

impl Simulation {
    /// Takes the state `(u, v)` a [`Simulation::substep`] from the current state gave before
    /// (a stored run of the same model from the same start), without solving: the step is
    /// assembled as the substep assembles it and counts for the step counter and for the
    /// linear solver's repeated-matrix rule as the substep's solve would
    /// ([`LinearSolver::replay`]); the contact's Newton iterations are not replayed (their
    /// matrices change within the step, which the rule does not count). The tangent-linear
    /// pass of a fit replays its forward run this way. A `rest_cholesky` solver's state
    /// follows its solves' iteration counts, which a replay does not have:
    /// [`Simulation::replays_exactly`] says whether the solves after a replay are the ones
    /// after the substep.
    ///
    /// [`LinearSolver::replay`]: super::LinearSolver::replay
    pub fn replay_substep(&mut self, u: Matrix<Vec3<f64>>, v: Matrix<Vec3<f64>>) {
        self.contact_at = None;
        self.linear.new_step();
        self.assemble_system_with(false);
        self.linear.replay(&self.a, &self.solver);
        self.u = u;
        self.v = v;
        self.steps += 1;
    }

    /// Whether [`Simulation::replay_substep`] leaves the linear solver as the substep would
    /// (every solver but a host `rest_cholesky`, whose refactor rule follows CG's iterations).
    pub fn replays_exactly(&self) -> bool {
        self.solver.direct
            || self.linear.device_name().is_some()
            || self.solver.preconditioner != Preconditioner::RestCholesky
    }

    /// Solves `A x = b` (the last assembly's) from `x`, adding the solver's counts and times to
    /// `info`.
    pub(super) fn solve_step(&mut self, x: &mut Matrix<Vec3<f64>>, info: &mut StepInfo) -> Result<(), Error> {
        let t = Instant::now();
        let si = self
            .linear
            .solve(&self.a, &self.b, x, &self.solver)
            .map_err(|e| Error::Invalid(format!("{e}; {}", self.scales_note())))?;
        info.iterations += si.iterations;
        info.residual = si.residual;
        info.fallback |= si.fallback;
        info.substituted |= si.substituted;
        info.factorizations += si.factorizations;
        info.factor_s += si.factor_s;
        info.solve_s += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// The static equilibrium `K u = f` of plain linear elasticity (no corotation, no ground,
    /// no inertia) under the body forces, with Nitsche Dirichlet terms.
    pub fn solve_static(&mut self) -> Result<StepInfo, Error> {
        let (_, blocks) = self.assemble_stiffness(false);
        self.blocks.keep(blocks);
        let mut f = std::mem::replace(&mut self.f, Matrix::zeros(0, 1, 1));
        let solved = solve_static(&self.model, &self.mass, self.stiffness(), &mut f, &self.solver);
        self.f = f;
        let (u, info) = solved?;
        self.u = u;
        Ok(info)
    }

    /// Solves `A x = rhs` with the Newmark matrix of the last [`Simulation::assemble_system`]
    /// and the simulation's solver settings, starting from `x` (the adjoint solve of the
    /// backward pass: `A` is symmetric). The solver's state is the forward steps' (a repeated
    /// matrix's factor serves both, [`crate::fem::solver`]). Returns `(iterations, relative
    /// residual, fallback)`.
    pub fn solve_newmark(
        &mut self,
        rhs: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
    ) -> Result<(usize, f64, bool), Error> {
        let si = self.linear.solve(&self.a, rhs, x, &self.solver)?;
        Ok((si.iterations, si.residual, si.fallback))
    }

    /// [`Simulation::solve_newmark`] to a relative residual of at most `tolerance` (the
    /// scene's CG tolerance when that is tighter).
    pub fn solve_newmark_to(
        &mut self,
        rhs: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        tolerance: f64,
    ) -> Result<(usize, f64, bool), Error> {
        let mut settings = self.solver;
        settings.cg.tolerance = settings.cg.tolerance.min(tolerance);
        let si = self.linear.solve(&self.a, rhs, x, &settings)?;
        Ok((si.iterations, si.residual, si.fallback))
    }

    /// The next `n` linear solves are with the current matrix ([`LinearSolver::expect_solves`]).
    ///
    /// [`LinearSolver::expect_solves`]: super::LinearSolver::expect_solves
    pub fn expect_solves(&mut self, n: usize) {
        self.linear.expect_solves(n);
    }

    /// Numeric factorizations of the linear solver's preconditioner so far.
    pub fn factorizations(&self) -> usize {
        self.linear.factorizations()
    }

    /// Entries of the kept factor of a repeated matrix ([`SolverSettings::reuse_factor`]), 0
    /// without one.
    ///
    /// [`SolverSettings::reuse_factor`]: super::SolverSettings::reuse_factor
    pub fn reused_factor_entries(&self) -> usize {
        self.linear.reused_factor_entries()
    }

    /// Block rows of each level of the `multigrid` preconditioner's hierarchy (finest first),
    /// when one is kept.
    pub fn multigrid_levels(&self) -> Option<Vec<usize>> {
        self.linear.multigrid_levels()
    }

    /// The multigrid hierarchy's estimates of `lambda_max(D^-1 A)` per smoothed level (the
    /// Chebyshev smoother's), when one is kept.
    pub fn multigrid_lambda_max(&self) -> Option<Vec<f64>> {
        self.linear.multigrid_lambda_max()
    }

    /// Runs the linear solves on `device` (`None`: on the host); `[numerics] backend = "cuda"`
    /// sets CUDA device 0 ([`crate::fem::device_solve`]).
    pub fn set_device(&mut self, device: Option<std::sync::Arc<dyn gpumat::device::Device>>) {
        self.linear.set_device(device);
    }

    /// The device the linear solves run on, by name (`None`: the host).
    pub fn device_name(&self) -> Option<String> {
        self.linear.device_name()
    }

    /// Drops a reused preconditioner factor (`rest_cholesky`): the next step factors afresh.
    /// The factor also follows changes of the model by itself, through the refactor rule.
    pub fn reset_preconditioner(&mut self) {
        self.linear.reset();
    }
}

/// The static equilibrium `K u = f` under the model's body forces (gravity times the lumped
/// mass, plus the external force), which are written to `f`. Shared by the grid and the tet
/// simulations.
pub(crate) fn solve_static(
    model: &Model,
    mass: &Matrix<f64>,
    k: &SparseMatrix<Mat3<f64>>,
    f: &mut Matrix<Vec3<f64>>,
    settings: &SolverSettings,
) -> Result<(Matrix<Vec3<f64>>, StepInfo), Error> {
    f.assign(mass.ex().cwise_mul(gpumat::scalar(model.gravity)));
    if let Some(e) = &model.external_force {
        e.add_to(f);
    }
    let mut x = Matrix::zeros(f.rows(), 1, 1);
    let t = Instant::now();
    let (iterations, residual, fallback) = solve(k, f, &mut x, settings)?;
    let info = StepInfo {
        iterations,
        residual,
        fallback,
        solve_s: t.elapsed().as_secs_f64(),
        ..Default::default()
    };
    Ok((x, info))
}
