//! The forward simulation: one function, [`Simulation::step`], shows the stage order.
//!
//! Per step (thesis sec. 4.4): rotations `R_e` from the current displacement (4.4.8-4.4.9),
//! stiffness values and corotation forces (4.4.1), ground forces (2.8), then Newmark-1 with
//! Rayleigh damping `D = alpha_1 M + alpha_2 K` (2.6.1-2.6.3):
//!
//! `A = (1/(theta dt) + alpha_1) M + (alpha_2 + theta dt) K`,
//! `b = ((1/(theta dt) + alpha_1) M + (alpha_2 - (1-theta) dt) K) u + M v / theta + dt f`,
//! `v' = (u' - u)/(theta dt) - (1-theta)/theta v`.
//!
//! (The thesis prints `+ (1-theta) dt K` in `b`; deriving the theta-scheme for
//! `M v' + D v + K u = f`, `u' = v` gives the minus sign used here.) From a stored `K`, `A` and
//! `b` are filled in one pass over its rows ([`newmark_system`], the tet simulation's path). A
//! grid step stores no `K`: its cell sweep computes `cu K u` and the corotation force cell by
//! cell, its row sweep writes the blocks of `A` on and above the diagonal straight from the
//! blocks of `K` and the rest of `b`, and a last pass mirrors the lower blocks of `A` and adds
//! the forces (see [`super::assembly`]). [`Simulation::assemble_system`] (the adjoint's
//! recomputed steps) keeps `K` as well; after a [`Simulation::step`] [`Simulation::stiffness`]
//! computes it on first use. `A u' = b` is solved by preconditioned CG warm-started at
//! `u + dt v` (4.4.18), falling back to a sparse Cholesky factorization when CG fails; the
//! preconditioner (block-Jacobi, block IC(0) or a reused rest-state Cholesky factor) is chosen
//! in [`SolverSettings`] (see [`super::solver`]). The contact stages (ground forces, their
//! stiffness in `A`, the penalty scheme's Newton iteration) are in `sim/contact.rs`, the linear
//! solves (the step's, the adjoint's and tangent's with the same `A`, a replayed step, statics)
//! in `sim/solve.rs`.

mod contact;
mod dirichlet;
mod kept;
mod solve;

pub use super::assembly::newmark_system;
use super::assembly::{Assembler, CellWork, ElementBlocks, Material};
use super::assembly::{StepCells, StepOutput, StepState};
use super::collision::{crossings, Crossing};
use super::element::{BlockCache, POLAR_ITERATIONS};
use super::grid::Grid;
use super::model::Model;
use super::plausible::extent;
use super::solver::LinearSolver;
pub use super::solver::{solve, Preconditioner, SolverSettings};
use crate::error::Error;
pub use dirichlet::{dirichlet_cells, NitscheFace};
use gpumat::{Mat3, Matrix, SparseMatrix, Vec3};
use kept::KeptStiffness;
pub(crate) use solve::solve_static;
use std::time::Instant;

pub use super::step_info::StepInfo;

/// A running simulation: the grid, its fixed data, and the state `(u, v)`.
#[derive(Debug)]
pub struct Simulation {
    /// the grid
    pub grid: Grid,
    /// the model
    pub model: Model,
    /// pattern and maps
    pub assembler: Assembler,
    /// lumped mass per dof (the row sums of the consistent mass too)
    pub mass: Matrix<f64>,
    /// the consistent mass on the assembler's pattern (`[numerics] mass = "consistent"`,
    /// [`crate::fem::assembly::mass`]); `None` for the lumped one
    pub mass_matrix: Option<Vec<f64>>,
    /// per cell, the part of its surface held by the Dirichlet boxes (Nitsche terms), if any
    pub dirichlet: Vec<Option<NitscheFace>>,
    /// surface crossings of grid edges
    pub crossings: Vec<Crossing>,
    /// displacement
    pub u: Matrix<Vec3<f64>>,
    /// velocity
    pub v: Matrix<Vec3<f64>>,
    /// integrator steps done (`model.substeps` per frame)
    pub steps: usize,
    /// solver settings
    pub solver: SolverSettings,
    /// `K` of the last assembly: kept by [`Simulation::assemble_system`], computed on first use
    /// after a step ([`Simulation::stiffness`])
    k: KeptStiffness,
    a: SparseMatrix<Mat3<f64>>,
    blocks: BlockCache,
    linear: LinearSolver,
    rotations: Option<Vec<Mat3<f64>>>,
    /// per-cell data of the corotated assembly (buffers reused by every step)
    cell_work: CellWork,
    contact: Vec<(Crossing, f64)>,
    /// where the penalty contact is linearized ([`Simulation::linearize_contact_at`])
    contact_at: Option<Matrix<Vec3<f64>>>,
    f: Matrix<Vec3<f64>>,
    b: Matrix<Vec3<f64>>,
}

impl Simulation {
    /// Sets up the simulation of `grid` under `model` at rest in the reference configuration
    /// with the model's initial velocity.
    pub fn new(grid: Grid, model: Model) -> Result<Self, Error> {
        model.validate()?;
        model.check_plausible(grid.h(), extent(&grid))?;
        model.check_external_dofs(grid.dofs())?;
        if let Some(s) = &model.stiffness_scale {
            if s.len() != grid.cells.len() {
                return Err(Error::Invalid(format!(
                    "model.stiffness_scale: {} values for {} active cells",
                    s.len(),
                    grid.cells.len()
                )));
            }
        }
        let assembler = Assembler::new(&grid);
        let mass = assembler.lumped_mass(&grid, model.density);
        let mass_matrix = consistent_mass(&assembler, &grid, &model);
        let dirichlet = dirichlet_cells(&grid, &model)?;
        let crossings = crossings(&grid);
        let n = grid.dofs();
        let a = SparseMatrix::zeros(assembler.pattern().clone(), 1);
        let linear = LinearSolver::new(Some(&grid.positions)).with_lattice(grid.sdf.dims, &grid.dof_nodes);
        let mut sim = Self {
            u: Matrix::zeros(n, 1, 1),
            v: Matrix::zeros(n, 1, 1),
            f: Matrix::zeros(n, 1, 1),
            b: Matrix::zeros(n, 1, 1),
            grid,
            model,
            assembler,
            mass,
            mass_matrix,
            dirichlet,
            crossings,
            steps: 0,
            solver: SolverSettings::default(),
            k: KeptStiffness::default(),
            a,
            blocks: BlockCache::default(),
            linear,
            rotations: None,
            cell_work: CellWork::default(),
            contact: Vec::new(),
            contact_at: None,
        };
        sim.v = sim.initial_velocity();
        Ok(sim)
    }

    /// Replaces the model and returns to the reference state (frame 0) with the new model's
    /// initial velocity, keeping the grid, the pattern and the gather maps (pattern once,
    /// values every step). Used by the fitting loop for each parameter set.
    pub fn reset(&mut self, model: Model) -> Result<(), Error> {
        self.set_model(model)?;
        let n = self.grid.dofs();
        self.u = Matrix::zeros(n, 1, 1);
        self.v = self.initial_velocity();
        self.steps = 0;
        self.rotations = None;
        self.contact.clear();
        self.contact_at = None;
        self.k.forget();
        self.linear.new_run();
        Ok(())
    }

    /// Replaces the model, keeping the state `(u, v)` (the mass and the Nitsche cells follow
    /// the new density, Dirichlet boxes, Nitsche quadrature and element).
    pub fn set_model(&mut self, model: Model) -> Result<(), Error> {
        model.validate()?;
        model.check_external_dofs(self.grid.dofs())?;
        if let Some(s) = &model.stiffness_scale {
            if s.len() != self.grid.cells.len() {
                return Err(Error::Invalid(format!(
                    "model.stiffness_scale: {} values for {} active cells",
                    s.len(),
                    self.grid.cells.len()
                )));
            }
        }
        // the Nitsche cells depend on the boxes, their quadrature and the element (its
        // volumetric traction, `dirichlet`)
        fn held(m: &Model) -> (&[super::Aabb], super::NitscheQuadrature, super::element::Element) {
            (&m.dirichlet, m.nitsche_quadrature, m.element)
        }
        if held(&model) != held(&self.model) {
            self.dirichlet = dirichlet_cells(&self.grid, &model)?;
        }
        if model.density != self.model.density {
            self.mass = self.assembler.lumped_mass(&self.grid, model.density);
        }
        if model.density != self.model.density || model.mass != self.model.mass {
            self.mass_matrix = consistent_mass(&self.assembler, &self.grid, &model);
        }
        self.model = model;
        self.k.forget();
        self.linear.model_changed();
        Ok(())
    }

    /// The center of mass of the reference configuration.
    pub fn center_of_mass(&self) -> Vec3<f64> {
        let m = self.mass.as_slice();
        let total: f64 = m.iter().sum();
        let mut c = Vec3::default();
        for (p, &mi) in self.grid.positions.iter().zip(m) {
            c = c + *p * mi;
        }
        c * (1.0 / total)
    }

    /// The initial velocity field `v0 + omega x (x - c)` with `c` the center of mass.
    pub fn initial_velocity(&self) -> Matrix<Vec3<f64>> {
        let c = self.center_of_mass();
        let (v0, w) = (self.model.initial_velocity, self.model.initial_angular_velocity);
        Matrix::from_fn(self.grid.dofs(), 1, 1, |i, _, _| {
            v0 + w.cross(self.grid.positions[i] - c)
        })
    }

    /// Total mass.
    pub fn total_mass(&self) -> f64 {
        self.mass.as_slice().iter().sum()
    }

    /// The material constants of an assembly: Lame constants, Nitsche penalty, element.
    pub(crate) fn material(&self) -> Material {
        let (lambda, mu) = self.model.lame();
        let (eta, eta_per_modulus) = self.model.nitsche.terms(self.grid.h());
        Material {
            lambda,
            mu,
            eta,
            eta_per_modulus,
            element: self.model.element,
            support: self.model.support,
        }
    }

    /// The element blocks for the current material (built when not among the kept ones).
    fn blocks(&mut self) -> ElementBlocks {
        let m = self.material();
        match self.blocks.take(m.element, m.lambda, m.mu) {
            Some(b) => b,
            None => self.assembler.element_blocks(&self.grid, &m),
        }
    }

    /// Writes the stiffness values (rotated when `corotation`, with Nitsche terms) into `K`
    /// (stored in `self.k`); returns the rotations used and the element blocks (for the
    /// corotation forces).
    fn assemble_stiffness(&mut self, corotation: bool) -> (Option<Vec<Mat3<f64>>>, ElementBlocks) {
        let m = self.material();
        let blocks = self.blocks();
        let rot = corotation.then(|| {
            self.assembler
                .rotations(&self.grid, &blocks, &self.u, POLAR_ITERATIONS)
        });
        let mut k = self.k.buffer(self.assembler.pattern());
        self.assembler.assemble_stiffness(
            &self.grid,
            &m,
            &blocks,
            rot.as_deref(),
            &self.dirichlet,
            self.model.stiffness_scale.as_deref(),
            &mut k,
        );
        self.k.keep(k);
        (rot, blocks)
    }

    /// The pass over cells and rows of a step's assembly ([`super::assembly`]) for the current
    /// state into the buffers of the last step: `A`, `f = M g`, `b` without `dt f` (and with
    /// `keep_k` also `K`, returned). Returns the seconds spent, all counted as rotations and
    /// stiffness.
    fn assemble(&mut self, keep_k: bool) -> (f64, Option<SparseMatrix<Mat3<f64>>>) {
        let t = Instant::now();
        let m = self.material();
        let blocks = self.blocks();
        let mut k = if keep_k {
            Some(self.k.buffer(self.assembler.pattern()))
        } else {
            self.k.forget();
            None
        };
        let scale = self.model.stiffness_scale.as_deref();
        let mut rot = self
            .model
            .corotation
            .then(|| self.rotations.take().unwrap_or_default());
        let state = StepState {
            model: &self.model,
            mass: &self.mass,
            mass_matrix: self.mass_matrix.as_deref(),
            u: &self.u,
            v: &self.v,
        };
        let cells = StepCells {
            grid: &self.grid,
            m: &m,
            blocks: &blocks,
            iterations: POLAR_ITERATIONS,
            dirichlet: &self.dirichlet,
            scale,
        };
        self.assembler.assemble_step(
            &cells,
            rot.as_mut(),
            &mut self.cell_work,
            &state,
            StepOutput {
                k: k.as_mut(),
                a: &mut self.a,
                b: &mut self.b,
                f: &mut self.f,
            },
        );
        self.blocks.keep(blocks);
        self.rotations = rot;
        (t.elapsed().as_secs_f64(), k)
    }

    /// Advances one frame: `model.substeps` integrator steps ([`Simulation::substep`]; one
    /// by default). The info sums the iterations, factorizations and seconds of the steps and
    /// keeps the largest residual and the last contact count.
    pub fn step(&mut self) -> Result<StepInfo, Error> {
        let mut info = self.substep()?;
        for _ in 1..self.model.substeps {
            info.then(self.substep()?);
        }
        Ok(info)
    }

    /// Advances one integrator step of `model.dt`: [`Simulation::assemble_system`], then the
    /// solve and the velocity update (eq. 2.6.2-2.6.4).
    pub fn substep(&mut self) -> Result<StepInfo, Error> {
        self.contact_at = None;
        self.linear.new_step();
        let mut info = self.assemble_system_with(false);
        let dt = self.model.dt;
        let mut x = Matrix::eval(self.u.ex() + self.v.ex() * dt);
        self.solve_step(&mut x, &mut info)?;
        self.newton_contact(&mut x, &mut info)?;

        // v' = (u' - u)/(theta dt) - (1-theta)/theta v, then u = u'
        self.model.newmark().update_velocity(&mut self.v, &x, &self.u);
        self.u = x;
        self.steps += 1;
        Ok(info)
    }

    /// The scales of the current model and the parameters that dominate them
    /// ([`Model::scales_note`]), for the error of a step that failed.
    pub fn scales_note(&self) -> String {
        self.model.scales_note(self.grid.h(), extent(&self.grid))
    }

    /// The stages of a step before the solve, for the current state `(u, v)`: rotations and
    /// stiffness (4.4.1), corotation, body and external forces, ground forces (2.8), then the Newmark
    /// matrix `A` and right-hand side `b` (2.6.2), keeping the stiffness matrix `K`
    /// ([`Simulation::stiffness`]). The adjoint pass calls it to recompute `A` and `K` at a
    /// stored state instead of storing them (thesis sec. 5.7).
    pub fn assemble_system(&mut self) -> StepInfo {
        self.assemble_system_with(true)
    }

    /// [`Simulation::assemble_system`], storing `K` only when `keep_k`.
    pub(crate) fn assemble_system_with(&mut self, keep_k: bool) -> StepInfo {
        let mut info = StepInfo::default();
        let (dt, theta) = (self.model.dt, self.model.theta);
        let t0 = Instant::now();
        let (stiffness_s, k) = self.assemble(keep_k);
        info.stiffness_s = stiffness_s;
        if let Some(e) = &self.model.external_force {
            e.add_to(&mut self.f);
        }
        info.assembly_s += t0.elapsed().as_secs_f64();

        let t1 = Instant::now();
        let (contact, friction) = self.ground_forces(&mut info);
        info.collision_s = t1.elapsed().as_secs_f64();

        let t2 = Instant::now();
        // b += dt f
        self.assembler.finish_step(dt, &self.f, &mut self.b);
        if let Some(k) = k {
            self.k.keep(k);
        }
        if let Some(ground) = &self.model.ground {
            let n = ground.normal;
            self.add_crossing_blocks(&contact, n.outer(n), ground.contact_theta(theta) * dt);
            self.add_crossing_blocks(&friction, Mat3::identity() - n.outer(n), 1.0);
        }
        self.contact = contact;
        info.assembly_s += t2.elapsed().as_secs_f64();
        info
    }

    /// The elastic force `-K u` (corotated when the model says so, with the corotation force
    /// `-R K (R^T x - x)`), without body or contact forces. Assembles the stiffness.
    pub fn elastic_force(&mut self) -> Matrix<Vec3<f64>> {
        let (rot, blocks) = self.assemble_stiffness(self.model.corotation);
        let mut f = Matrix::eval(-(self.stiffness() * &self.u));
        if let Some(r) = &rot {
            self.assembler.add_corotation_forces(
                &self.grid,
                &blocks,
                r,
                self.model.stiffness_scale.as_deref(),
                &mut f,
            );
        }
        self.blocks.keep(blocks);
        f
    }

    /// The per-cell rotations of the last assembly (`None` without corotation).
    pub fn rotations(&self) -> Option<&[Mat3<f64>]> {
        self.rotations.as_deref()
    }

    /// The crossings in contact at the last assembly with their spring slopes
    /// `k softmin'(d)` (implicit and penalty contact schemes).
    pub fn contact(&self) -> &[(Crossing, f64)] {
        &self.contact
    }

    /// An error naming `time.dt` and `time.substeps` once the displacement is no longer
    /// finite (the steps diverged).
    pub fn check_finite(&self) -> Result<(), Error> {
        if self.u.as_slice().iter().all(gpumat::Scalar::is_finite) {
            return Ok(());
        }
        Err(Error::Invalid(format!(
            "the simulation diverged (non-finite displacement); reduce time.dt ({}) or raise time.substeps",
            self.scales_note()
        )))
    }

    /// The unrotated element blocks of the last assembly.
    pub fn element_blocks(&self) -> Option<&ElementBlocks> {
        self.blocks.last()
    }

    /// The force vector `f` of the last assembly: body, external and contact forces (the
    /// elastic forces, corotation included, enter `b` cell by cell and are not stored; see
    /// [`Assembler::add_corotation_forces`] and [`Simulation::elastic_force`]). After
    /// [`Simulation::solve_static`]: the body and external forces.
    pub fn force(&self) -> &Matrix<Vec3<f64>> {
        &self.f
    }

    /// The Newmark right-hand side `b` of the last assembly.
    pub fn newmark_rhs(&self) -> &Matrix<Vec3<f64>> {
        &self.b
    }

    /// The stiffness matrix of the last assembly (corotated at its rotations when the model
    /// says so, with the Nitsche terms), for the current model. [`Simulation::assemble_system`]
    /// keeps it; after a [`Simulation::step`] (which does not need it), or a change of the
    /// model, it is computed here on first use, on the calling thread alone (a plain
    /// [`Assembler::assemble_stiffness`], the same values), and kept until the next assembly.
    pub fn stiffness(&self) -> &SparseMatrix<Mat3<f64>> {
        self.k.get_or_compute(|| {
            let m = self.material();
            let mut fresh = None;
            let blocks = match self.blocks.get(m.element, m.lambda, m.mu) {
                Some(b) => b,
                None => &*fresh.insert(ElementBlocks::build(&self.grid, m.element, m.lambda, m.mu, false)),
            };
            let mut k = SparseMatrix::zeros(self.assembler.pattern().clone(), 1);
            let rotations = self.rotations.as_deref().filter(|_| self.model.corotation);
            let scale = self.model.stiffness_scale.as_deref();
            let inputs = (&self.grid, &m, blocks, rotations, &self.dirichlet[..], scale);
            self.assembler.assemble_stiffness_serial(inputs, &mut k);
            k
        })
    }
    /// The Newmark matrix `A` of the last step.
    pub fn newmark_matrix(&self) -> &SparseMatrix<Mat3<f64>> {
        &self.a
    }

    /// `M x` for the model's mass matrix (lumped: `m_i x_i`; consistent: the sum over the row's
    /// blocks in column order).
    pub fn mass_times(&self, x: &Matrix<Vec3<f64>>) -> Matrix<Vec3<f64>> {
        match &self.mass_matrix {
            None => Matrix::eval(self.mass.ex().cwise_mul(x.ex())),
            Some(m) => {
                let p = self.assembler.pattern();
                let (rp, cols, xs) = (p.row_ptr(), p.col_idx(), x.as_slice());
                Matrix::from_fn(p.rows(), 1, 1, |r, _, _| {
                    (rp[r]..rp[r + 1]).fold(Vec3::default(), |acc, k| acc + xs[cols[k] as usize] * m[k])
                })
            }
        }
    }

    /// Kinetic energy `1/2 v^T M v`.
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.v.ex().dot(self.mass_times(&self.v).ex())
    }
    /// Elastic energy `1/2 u^T K u` of the last assembled (unrotated, or rotated) stiffness
    /// ([`Simulation::stiffness`]).
    pub fn elastic_energy(&self) -> f64 {
        0.5 * self.u.ex().dot(self.stiffness() * &self.u)
    }
    /// Gravitational potential `-sum m g . u` (relative to the reference configuration).
    pub fn gravity_energy(&self) -> f64 {
        let g = self.model.gravity;
        -self
            .mass
            .ex()
            .cwise_mul(self.u.ex().cwise_dot(gpumat::scalar(g)))
            .sum()
    }
    /// The largest displacement norm.
    pub fn max_displacement(&self) -> f64 {
        self.u.ex().cwise_squared_norm().max().sqrt()
    }
}

/// The consistent mass of `model` on `assembler`'s pattern, or `None` for the lumped one.
fn consistent_mass(assembler: &Assembler, grid: &Grid, model: &Model) -> Option<Vec<f64>> {
    (model.mass == super::model::MassMatrix::Consistent)
        .then(|| assembler.consistent_mass(grid, model.density))
}
