//! The tetrahedral time stepping: the grid's Newmark-1 scheme on the free nodes of a
//! [`TetMesh`] (see [`super`] for the maths).

use super::{TetAssembler, TetMesh};
use crate::error::Error;
use crate::fem::assembly::Material;
use crate::fem::collision::{softmin0, softmin0_derivative, ContactScheme};
use crate::fem::element::POLAR_ITERATIONS;
use crate::fem::grid::{Grid, INACTIVE};
use crate::fem::model::Model;
use crate::fem::sim::{newmark_system, solve_static, SolverSettings, StepInfo};
use crate::fem::solver::LinearSolver;
use gpumat::{Mat3, Matrix, SparseMatrix, Vec3};
use std::time::Instant;

/// Wall-clock seconds of the stages of one assembly (what [`StepInfo::assembly_s`] counts).
#[derive(Clone, Copy, Debug, Default)]
pub struct AssemblyTimes {
    /// per-element rotations (polar decompositions)
    pub rotations_s: f64,
    /// stiffness values
    pub stiffness_s: f64,
    /// body and corotation forces
    pub forces_s: f64,
    /// the Newmark matrix `A` and right-hand side `b`
    pub system_s: f64,
}

impl AssemblyTimes {
    /// Sum of the stages.
    pub fn total(&self) -> f64 {
        self.rotations_s + self.stiffness_s + self.forces_s + self.system_s
    }
}

/// A running tetrahedral simulation: the mesh, its fixed data, and the state `(u, v)` of the
/// free nodes.
#[derive(Debug)]
pub struct TetSimulation {
    /// the mesh
    pub mesh: TetMesh,
    /// the model
    pub model: Model,
    /// pattern and gather maps
    pub assembler: TetAssembler,
    /// lumped mass per free dof
    pub mass: Matrix<f64>,
    /// free dofs of the surface nodes (ground springs)
    pub contact_dofs: Vec<u32>,
    /// displacement of the free nodes
    pub u: Matrix<Vec3<f64>>,
    /// velocity of the free nodes
    pub v: Matrix<Vec3<f64>>,
    /// steps done
    pub steps: usize,
    /// solver settings
    pub solver: SolverSettings,
    k: SparseMatrix<Mat3<f64>>,
    a: SparseMatrix<Mat3<f64>>,
    f: Matrix<Vec3<f64>>,
    b: Matrix<Vec3<f64>>,
    linear: LinearSolver,
}

impl TetSimulation {
    /// Sets up the simulation at rest in the reference configuration with the model's
    /// initial velocity (zero at fixed nodes).
    pub fn new(mesh: TetMesh, model: Model) -> Result<Self, Error> {
        model.validate()?;
        if let Some(g) = model.ground.filter(|g| g.stiffness_per_area()) {
            let name = if g.scheme == ContactScheme::Penalty {
                "penalty"
            } else {
                "softmin"
            };
            return Err(Error::Invalid(format!(
                "ground.scheme: \"{name}\" (springs per unit area) is not available on the tetrahedral baseline (use \"implicit\" or \"thesis\")"
            )));
        }
        if model.friction.is_some() {
            return Err(Error::Invalid(
                "friction: ground friction is not available on the tetrahedral baseline".into(),
            ));
        }
        if model.support.is_some() {
            return Err(Error::Invalid(
                "clamp: an elastic support is not available on the tetrahedral baseline (its fixed nodes are held rigidly)"
                    .into(),
            ));
        }
        model.check_external_dofs(mesh.dofs())?;
        let assembler = TetAssembler::new(&mesh);
        let mass = assembler.lumped_mass(&mesh, model.density);
        let contact_dofs = mesh
            .free_nodes
            .iter()
            .enumerate()
            .filter(|(_, &n)| mesh.surface[n as usize])
            .map(|(d, _)| d as u32)
            .collect();
        let n = mesh.dofs();
        let k = SparseMatrix::zeros(assembler.pattern().clone(), 1);
        let a = SparseMatrix::zeros(assembler.pattern().clone(), 1);
        let free: Vec<Vec3<f64>> = mesh
            .free_nodes
            .iter()
            .map(|&n| mesh.positions[n as usize])
            .collect();
        let linear = LinearSolver::new(Some(&free));
        let mut sim = Self {
            u: Matrix::zeros(n, 1, 1),
            v: Matrix::zeros(n, 1, 1),
            f: Matrix::zeros(n, 1, 1),
            b: Matrix::zeros(n, 1, 1),
            mesh,
            model,
            assembler,
            mass,
            contact_dofs,
            steps: 0,
            solver: SolverSettings::default(),
            k,
            a,
            linear,
        };
        sim.v = sim.initial_velocity();
        Ok(sim)
    }

    /// Builds the mesh from `grid` ([`TetMesh::from_grid`]) and the simulation.
    pub fn from_grid(grid: &Grid, model: Model) -> Result<Self, Error> {
        let mesh = TetMesh::from_grid(grid, &model)?;
        Self::new(mesh, model)
    }

    /// The initial velocity `v0 + omega x (x - c)` at the free nodes, `c` the center of mass
    /// (of all nodes, fixed ones weighted by their lumped mass too).
    pub fn initial_velocity(&self) -> Matrix<Vec3<f64>> {
        let mut node_mass = vec![0.0; self.mesh.nodes()];
        for (t, tet) in self.mesh.tets.iter().enumerate() {
            for &v in tet {
                node_mass[v as usize] += 0.25 * self.mesh.volumes[t];
            }
        }
        let total: f64 = node_mass.iter().sum();
        let mut c = Vec3::default();
        for (p, &m) in self.mesh.positions.iter().zip(&node_mass) {
            c = c + *p * m;
        }
        let c = c * (1.0 / total);
        let (v0, w) = (self.model.initial_velocity, self.model.initial_angular_velocity);
        Matrix::from_fn(self.mesh.dofs(), 1, 1, |i, _, _| {
            v0 + w.cross(self.mesh.positions[self.mesh.free_nodes[i] as usize] - c)
        })
    }

    /// Mass of the free nodes.
    pub fn total_mass(&self) -> f64 {
        self.mass.as_slice().iter().sum()
    }

    fn material(&self) -> Material {
        let (lambda, mu) = self.model.lame();
        Material {
            lambda,
            mu,
            eta: 0.0,
            eta_per_modulus: 0.0,
            element: self.model.element,
            support: None,
        }
    }

    /// Rotations, stiffness and forces for the current state into `self.k`, `self.f`.
    fn assemble_into(&mut self, times: &mut AssemblyTimes) {
        let m = self.material();
        let t = Instant::now();
        let rot = self
            .model
            .corotation
            .then(|| self.assembler.rotations(&self.mesh, &self.u, POLAR_ITERATIONS));
        times.rotations_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        self.assembler
            .assemble_stiffness(&self.mesh, &m, rot.as_deref(), &mut self.k);
        times.stiffness_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let g = self.model.gravity;
        self.f.assign(self.mass.ex().cwise_mul(gpumat::scalar(g)));
        if let Some(e) = &self.model.external_force {
            e.add_to(&mut self.f);
        }
        if let Some(r) = &rot {
            self.assembler
                .add_corotation_forces(&self.mesh, &m, r, &mut self.f);
        }
        times.forces_s += t.elapsed().as_secs_f64();
    }

    /// The Newmark matrix and right-hand side from `self.k`, `self.f` and the state.
    fn assemble_system(&mut self) {
        newmark_system(
            &self.model,
            &self.mass,
            &self.k,
            &self.u,
            &self.v,
            &self.f,
            &mut self.a,
            &mut self.b,
        );
    }

    /// Runs the assembly stages of a step (rotations, stiffness, forces, `A` and `b`, no
    /// contact and no solve) for the current state and returns their timings; the state is
    /// unchanged.
    pub fn assemble_timed(&mut self) -> AssemblyTimes {
        let mut times = AssemblyTimes::default();
        self.assemble_into(&mut times);
        let t = Instant::now();
        self.assemble_system();
        times.system_s = t.elapsed().as_secs_f64();
        times
    }

    /// Adds the ground springs at the free surface nodes to `self.f`; returns the contacts.
    /// With [`ContactScheme::Implicit`] the force added is `f(u) - theta J u` and the
    /// springs' slopes `k softmin'(d)` are returned as `(dof, slope)` for the Newmark matrix.
    fn add_ground_forces(&mut self, stiffness: &mut Vec<(u32, f64)>) -> usize {
        stiffness.clear();
        let Some(ground) = self.model.ground else { return 0 };
        let (dt, theta) = (self.model.dt, self.model.theta);
        let (us, vs) = (self.u.as_slice(), self.v.as_slice());
        let fs = self.f.as_mut_slice();
        let n = ground.normal;
        let mut touching = 0;
        for &d in &self.contact_dofs {
            let i = d as usize;
            let x = self.mesh.positions[self.mesh.free_nodes[i] as usize] + us[i];
            let dist = ground.distance(x);
            let f_now = -ground.stiffness * softmin0(dist, ground.softness);
            let slope = ground.stiffness * softmin0_derivative(dist, ground.softness);
            if dist < 0.0 {
                touching += 1;
            }
            let mag = match ground.scheme {
                ContactScheme::Thesis => theta * (f_now - dt * slope * n.dot(vs[i])) + (1.0 - theta) * f_now,
                // the penalty scheme is refused by `new`
                ContactScheme::Implicit | ContactScheme::Softmin | ContactScheme::Penalty => {
                    if slope > 0.0 {
                        stiffness.push((d, slope));
                    }
                    f_now + theta * slope * n.dot(us[i])
                }
            };
            fs[i] = fs[i] + n * mag;
        }
        touching
    }

    /// Adds `theta dt K_c` (`K_c = slope n n^T` per contact spring) to the Newmark matrix.
    fn add_contact_stiffness(&mut self, contact: &[(u32, f64)]) {
        let Some(ground) = self.model.ground else { return };
        let nn = ground.normal.outer(ground.normal);
        let scale = self.model.theta * self.model.dt;
        let pattern = self.assembler.pattern().clone();
        let values = self.a.batch_values_mut(0);
        for &(d, slope) in contact {
            let k = pattern
                .find(d as usize, d as usize)
                .expect("the pattern holds the diagonal");
            values[k] = values[k] + nn * (scale * slope);
        }
    }

    /// Advances one frame, `model.substeps` integrator steps (as
    /// [`crate::fem::Simulation::step`]).
    pub fn step(&mut self) -> Result<StepInfo, Error> {
        let mut info = self.substep()?;
        for _ in 1..self.model.substeps {
            info.then(self.substep()?);
        }
        Ok(info)
    }

    /// Advances one integrator step (the stage order of [`crate::fem::Simulation::substep`]).
    fn substep(&mut self) -> Result<StepInfo, Error> {
        let mut info = StepInfo::default();
        let dt = self.model.dt;
        let mut times = AssemblyTimes::default();
        self.assemble_into(&mut times);
        info.assembly_s = times.total();
        info.stiffness_s = times.rotations_s + times.stiffness_s;

        let t1 = Instant::now();
        let mut contact = Vec::new();
        info.contacts = self.add_ground_forces(&mut contact);
        info.collision_s = t1.elapsed().as_secs_f64();

        let t2 = Instant::now();
        self.assemble_system();
        self.add_contact_stiffness(&contact);
        info.assembly_s += t2.elapsed().as_secs_f64();

        let t3 = Instant::now();
        let mut x = Matrix::eval(self.u.ex() + self.v.ex() * dt);
        let si = self.linear.solve(&self.a, &self.b, &mut x, &self.solver)?;
        info.iterations = si.iterations;
        info.residual = si.residual;
        info.fallback = si.fallback;
        info.factorizations = si.factorizations;
        info.factor_s = si.factor_s;
        info.solve_s = t3.elapsed().as_secs_f64();

        // v' = (u' - u)/(theta dt) - (1-theta)/theta v, then u = u'
        self.model.newmark().update_velocity(&mut self.v, &x, &self.u);
        self.u = x;
        self.steps += 1;
        Ok(info)
    }

    /// The static equilibrium `K u = f` of plain linear elasticity under the body forces.
    pub fn solve_static(&mut self) -> Result<StepInfo, Error> {
        let m = self.material();
        self.assembler
            .assemble_stiffness(&self.mesh, &m, None, &mut self.k);
        let (u, info) = solve_static(&self.model, &self.mass, &self.k, &mut self.f, &self.solver)?;
        self.u = u;
        Ok(info)
    }

    /// The elastic force `-K u` at the free nodes (corotated when the model says so, with the
    /// corotation force), without body or contact forces. Assembles the stiffness.
    pub fn elastic_force(&mut self) -> Matrix<Vec3<f64>> {
        let m = self.material();
        let rot = self
            .model
            .corotation
            .then(|| self.assembler.rotations(&self.mesh, &self.u, POLAR_ITERATIONS));
        self.assembler
            .assemble_stiffness(&self.mesh, &m, rot.as_deref(), &mut self.k);
        let mut f = Matrix::eval(-(&self.k * &self.u));
        if let Some(r) = &rot {
            self.assembler.add_corotation_forces(&self.mesh, &m, r, &mut f);
        }
        f
    }

    /// The stiffness matrix of the last assembly.
    pub fn stiffness(&self) -> &SparseMatrix<Mat3<f64>> {
        &self.k
    }
    /// The Newmark matrix `A` of the last step.
    pub fn newmark_matrix(&self) -> &SparseMatrix<Mat3<f64>> {
        &self.a
    }

    /// The displacement of every mesh node (zero at fixed nodes).
    pub fn node_displacements(&self) -> Vec<Vec3<f64>> {
        let us = self.u.as_slice();
        self.mesh
            .node_dofs
            .iter()
            .map(|&d| {
                if d == INACTIVE {
                    Vec3::default()
                } else {
                    us[d as usize]
                }
            })
            .collect()
    }

    /// Kinetic energy `1/2 sum m v^2`.
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.mass.ex().cwise_mul(self.v.ex().cwise_squared_norm()).sum()
    }
    /// Elastic energy `1/2 u^T K u` of the last assembled stiffness.
    pub fn elastic_energy(&self) -> f64 {
        0.5 * self.u.ex().dot(&self.k * &self.u)
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
