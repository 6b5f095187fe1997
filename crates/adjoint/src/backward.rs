//! The backward twin of [`cutfem::fem::Simulation::step`] (thesis Alg. 5.3, sec. 5.5.3-5.5.6).
//!
//! A forward step maps `(u, v)` to `u' = A(u, v, p)^{-1} b(u, v, p)` and
//! `v' = (u' - u) / (theta dt) - (1 - theta) / theta v` (eq. 2.6.2). Given the adjoints
//! `u'_bar`, `v'_bar` of the new state, the backward step
//!
//! 1. collects the adjoint of `u'`: `g = u'_bar + v'_bar / (theta dt)` (eq. 5.5.1),
//! 2. solves `A lam = g` with the same, symmetric `A` (eq. 5.5.2), recomputed from the stored
//!    `(u, v)` rather than stored (sec. 5.7),
//! 3. differentiates the Lagrangian `L = lam^T (b(u, v, p) - A(u, v, p) u')` with `u'` held
//!    fixed (eq. 5.5.3): `u_bar = dL/du - v'_bar / (theta dt)`,
//!    `v_bar = dL/dv - (1 - theta) / theta v'_bar`, and `p_bar += dL/dp`.
//!
//! With `c_M = 1/(theta dt) + alpha_1`,
//! `L = c_M lam^T M (u - u') + lam^T K(u) w + lam^T M v / theta
//!      + dt lam^T (M g + sum_k c_k F_k + f_rot(u) + f_c(u, v)) - theta dt lam^T K_c(u) u'`,
//! `w = (alpha_2 - (1 - theta) dt) u - (alpha_2 + theta dt) u'`. Its parts:
//! * mass, damping and gravity (sec. 5.5.3, 5.5.6): vector algebra;
//! * the external force `sum_k c_k F_k` ([`cutfem::fem::ExternalForce`]): it enters `b` as
//!   `dt f` like gravity, so `dL/dc_k = dt lam . F_k` (gravity: `dL/dg = dt sum_i m_i lam_i`);
//! * `K(u) w` and the corotation force: through the rotations, cell by cell
//!   ([`crate::local::cell_elastic_adjoint`], [`crate::local::polar_rotation_adjoint`], eq. 5.5.4),
//!   and the Lame parameters (5.5.5); the Nitsche blocks are linear in `(lambda, mu)`, the
//!   clamp's springs `k P` that replace them (the `clamp` effect) linear in `k`;
//! * contact (Alg. 5.5, sec. 5.5.5): per crossing ([`crate::local::contact_adjoint`]), and its
//!   friction `mu N(d) lam_c . P (u_c - u'_c)` ([`crate::local::friction_adjoint`]).

use crate::local::{
    cell_elastic_adjoint, contact_adjoint, deformation_gradient_adjoint, friction_adjoint,
    polar_rotation_adjoint,
};
use cutfem::fem::collision::Ground;
use cutfem::fem::element::{corner_offsets, deformation_gradient_with, POLAR_ITERATIONS};
use cutfem::fem::{NewmarkCoefficients, Simulation};
use gpumat::{Mat3, Matrix, Vec3};
use rayon::prelude::*;

/// Gradient of a scalar with respect to the physical parameters of a [`cutfem::fem::Model`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PhysicalGradient {
    /// Lame lambda
    pub lambda: f64,
    /// Lame mu
    pub mu: f64,
    /// density
    pub density: f64,
    /// Rayleigh `alpha_1`
    pub damping_mass: f64,
    /// Rayleigh `alpha_2`
    pub damping_stiffness: f64,
    /// the drag coefficient `c` ([`cutfem::fem::NodalDamping`])
    pub drag: f64,
    /// the stiffness `k` of the clamp's springs ([`cutfem::fem::Model::support`])
    pub support: f64,
    /// the ground friction `mu` ([`cutfem::fem::Model::friction`])
    pub friction: f64,
    /// gravity vector
    pub gravity: Vec3<f64>,
    /// ground normal (as a free vector; the caller projects it)
    pub ground_normal: Vec3<f64>,
    /// ground height
    pub ground_height: f64,
    /// initial linear velocity
    pub initial_velocity: Vec3<f64>,
    /// initial angular velocity
    pub initial_angular_velocity: Vec3<f64>,
    /// the coefficients of the external force, `dJ/dc_k` (empty without one)
    pub external: Vec<f64>,
    /// per active cell, the derivative with respect to its Young's modulus factor
    /// (`Model::stiffness_scale`; computed also when the model is homogeneous, where it is the
    /// score of a heterogeneous stiffness)
    pub cell_scale: Vec<f64>,
}

/// `lam^T (b - A u')` for the last [`Simulation::assemble_system`]: the Lagrangian whose
/// derivatives [`step_adjoint`] computes (used by the derivative checks).
pub fn step_lagrangian(sim: &Simulation, u_next: &Matrix<Vec3<f64>>, lam: &Matrix<Vec3<f64>>) -> f64 {
    let a = sim.newmark_matrix();
    let b = sim.newmark_rhs();
    lam.ex().dot(b - a * u_next)
}

/// Adds the derivatives of `L = lam^T (b - A u')` (module docs) to `u_bar`, `v_bar` and `grad`.
/// `sim` must have been assembled ([`Simulation::assemble_system`]) at the step's start state
/// `(sim.u, sim.v)`, its contact linearized at `u_next`
/// ([`Simulation::linearize_contact_at`]); `u_next` is the state the forward step produced.
///
/// The stages of [`Simulation::step`] before the solve (rotations, element blocks, external
/// force, contact, Newmark `A` and `b`) each add their terms of `L`; the solve and the
/// velocity update are reversed by the caller ([`crate::problem::Problem::gradient`]: `g`,
/// `A lam = g`). The sums are independent and are accumulated in this fixed order, so the
/// result does not depend on the thread count.
pub fn step_adjoint(
    sim: &Simulation,
    u_next: &Matrix<Vec3<f64>>,
    lam: &Matrix<Vec3<f64>>,
    u_bar: &mut Matrix<Vec3<f64>>,
    v_bar: &mut Matrix<Vec3<f64>>,
    grad: &mut PhysicalGradient,
) {
    let st = Stage {
        sim,
        nm: sim.model.newmark(),
        u_next,
        lam,
        us: sim.u.as_slice(),
        uns: u_next.as_slice(),
        ls: lam.as_slice(),
        scale: sim.model.stiffness_scale.as_deref(),
        lame: sim.model.lame(),
    };
    // Newmark A and b: mass, damping, gravity and the external force (vector algebra)
    st.newmark(u_bar, v_bar, grad);
    // element blocks and rotations: the elastic terms, cell by cell
    st.elastic(u_bar, grad);
    // element blocks: the Nitsche terms of Dirichlet cells
    st.nitsche(grad);
    // contact: per edge crossing
    st.contact(u_bar, v_bar, grad);
}

/// What every stage of [`step_adjoint`] reads.
struct Stage<'a> {
    sim: &'a Simulation,
    /// the model's Newmark coefficients
    nm: NewmarkCoefficients,
    u_next: &'a Matrix<Vec3<f64>>,
    lam: &'a Matrix<Vec3<f64>>,
    /// `u`, `u'` and `lam` per degree of freedom
    us: &'a [Vec3<f64>],
    uns: &'a [Vec3<f64>],
    ls: &'a [Vec3<f64>],
    /// the per-cell stiffness factors, if any
    scale: Option<&'a [f64]>,
    /// `(lambda, mu)`
    lame: (f64, f64),
}

impl Stage<'_> {
    /// Mass, damping, gravity and the external force (sec. 5.5.3, 5.5.6).
    fn newmark(
        &self,
        u_bar: &mut Matrix<Vec3<f64>>,
        v_bar: &mut Matrix<Vec3<f64>>,
        grad: &mut PhysicalGradient,
    ) {
        let (sim, u_next, lam, nm) = (self.sim, self.u_next, self.lam, self.nm);
        let model = &sim.model;
        let (dt, theta) = (nm.dt, nm.theta);
        let (cm, cw) = (nm.cm, nm.cu);
        let k = sim.stiffness();
        let (u, v) = (&sim.u, &sim.v);
        let k_lam = Matrix::eval(k * lam);
        // `M lam` (M symmetric: lumped or consistent, [`Simulation::mass_times`])
        let m_lam = sim.mass_times(lam);
        u_bar.assign_with(|ub| ub + m_lam.ex() * cm + k_lam.ex() * cw);
        v_bar.assign_with(|vb| vb + m_lam.ex() * nm.cv);
        let lam_m_du = m_lam.ex().dot(u - u_next);
        let lam_m_v = m_lam.ex().dot(v.ex());
        let s: Vec3<f64> = m_lam.ex().sum();
        let lam_m_g = s.dot(model.gravity);
        grad.density += (cm * lam_m_du + lam_m_v / theta + dt * lam_m_g) / model.density;
        grad.damping_mass += lam_m_du;
        grad.damping_stiffness += k_lam.ex().dot(u - u_next);
        // the drag's `c W (u' - u)`: `b` has `c W u`, `A` has `c W`
        if let Some(d) = &model.drag {
            let w = d.weights.as_slice();
            let ls = lam.as_slice();
            for (i, ub) in u_bar.as_mut_slice().iter_mut().enumerate() {
                *ub = *ub + ls[i] * (d.coefficient * w[i]);
            }
            let (us, un) = (u.as_slice(), u_next.as_slice());
            grad.drag += (0..w.len()).map(|i| w[i] * ls[i].dot(us[i] - un[i])).sum::<f64>();
        }
        grad.gravity = grad.gravity + s * dt;
        if let Some(ext) = &model.external_force {
            grad.external.resize(ext.len(), 0.0);
            for (gk, field) in grad.external.iter_mut().zip(ext.basis.iter()) {
                *gk += dt
                    * field
                        .iter()
                        .zip(lam.as_slice())
                        .map(|(f, l)| f.dot(*l))
                        .sum::<f64>();
            }
        }
    }

    /// `K(u) w` and the corotation force, through the rotations (eq. 5.5.4) and the Lame
    /// parameters (5.5.5), with the per-cell stiffness factors.
    fn elastic(&self, u_bar: &mut Matrix<Vec3<f64>>, grad: &mut PhysicalGradient) {
        let (sim, nm, scale, (lame_l, lame_m)) = (self.sim, self.nm, self.scale, self.lame);
        let (dt, cw, cn) = (nm.dt, nm.cu, nm.ck);
        let grid = &sim.grid;
        let h = grid.h();
        let x = corner_offsets(h);
        let blocks = sim.element_blocks().expect("assembled");
        let rotations = sim.rotations();
        let (us, uns, ls) = (self.us, self.uns, self.ls);
        let per_cell: Vec<([Vec3<f64>; 8], f64, f64, f64)> = grid
            .cells
            .par_iter()
            .enumerate()
            .map(|(e, c)| {
                let d = |q: usize| c.dofs[q] as usize;
                let lam_e: [Vec3<f64>; 8] = std::array::from_fn(|q| ls[d(q)]);
                let a_e: [Vec3<f64>; 8] = std::array::from_fn(|q| us[d(q)] * cw - uns[d(q)] * cn - x[q] * dt);
                let r = rotations.map_or(Mat3::identity(), |r| r[e]);
                // the cell's term is s_e times the homogeneous one (linear in lambda, mu)
                let se = scale.map_or(1.0, |s| s[e]);
                let set = blocks.set(e);
                let (r_bar, dl, dm) = cell_elastic_adjoint(set, &r, &lam_e, &a_e, &x, dt);
                let mut ub = [Vec3::default(); 8];
                if rotations.is_some() {
                    let u_e: [Vec3<f64>; 8] = std::array::from_fn(|q| us[d(q)]);
                    let w = set.gradient_weights();
                    let f = deformation_gradient_with(&u_e, w, h);
                    let f_bar = polar_rotation_adjoint(f, POLAR_ITERATIONS, r_bar * se);
                    deformation_gradient_adjoint(&f_bar, w, h, &mut ub);
                }
                (ub, dl, dm, se)
            })
            .collect();
        if grad.cell_scale.len() != grid.cells.len() {
            grad.cell_scale = vec![0.0; grid.cells.len()];
        }
        for (e, (_, dl, dm, se)) in per_cell.iter().enumerate() {
            grad.lambda += se * dl;
            grad.mu += se * dm;
            grad.cell_scale[e] += lame_l * dl + lame_m * dm;
        }
        if rotations.is_some() {
            let ubs = u_bar.as_mut_slice();
            ubs.par_iter_mut().enumerate().for_each(|(dof, out)| {
                for &(e, q) in sim.assembler.cells_of(dof) {
                    *out = *out + per_cell[e as usize].0[q as usize];
                }
            });
        }
    }

    /// The Nitsche terms: linear in `(lambda, mu, eta)`, independent of `u`; a scaled penalty
    /// is `eta = p (lambda + 2 mu) se` (`NitschePenalty::terms`), so d/dlambda carries `p` and
    /// d/dmu `2 p`; a fixed one does not depend on them.
    fn nitsche(&self, grad: &mut PhysicalGradient) {
        let (sim, nm, scale, (lame_l, lame_m)) = (self.sim, self.nm, self.scale, self.lame);
        let (cw, cn) = (nm.cu, nm.ck);
        let grid = &sim.grid;
        let (us, uns, ls) = (self.us, self.uns, self.ls);
        if grad.cell_scale.len() != grid.cells.len() {
            grad.cell_scale = vec![0.0; grid.cells.len()];
        }
        let w_at = |q: usize| us[q] * cw - uns[q] * cn;
        let p = sim.model.nitsche.terms(grid.h()).1;
        for (e, c) in grid.cells.iter().enumerate() {
            let Some(ci) = &sim.dirichlet[e] else {
                continue;
            };
            if sim.model.support.is_some() {
                // the springs `k P_ij I` instead: linear in `k`, free of `lambda, mu`
                for i in 0..8 {
                    let li = ls[c.dofs[i] as usize];
                    for j in 0..8 {
                        grad.support += li.dot(ci.block(i, j, 0.0, 0.0, 1.0) * w_at(c.dofs[j] as usize));
                    }
                }
                continue;
            }
            let se = scale.map_or(1.0, |s| s[e]);
            for i in 0..8 {
                let li = ls[c.dofs[i] as usize];
                for j in 0..8 {
                    let wj = w_at(c.dofs[j] as usize);
                    let pe = p * ci.penalty_factor;
                    let nl = li.dot(ci.block(i, j, 1.0, 0.0, pe) * wj);
                    let nm = li.dot(ci.block(i, j, 0.0, 1.0, 2.0 * pe) * wj);
                    grad.lambda += se * nl;
                    grad.mu += se * nm;
                    grad.cell_scale[e] += lame_l * nl + lame_m * nm;
                }
            }
        }
    }

    /// Contact (Alg. 5.5, sec. 5.5.5): per crossing ([`contact_adjoint`]).
    fn contact(
        &self,
        u_bar: &mut Matrix<Vec3<f64>>,
        v_bar: &mut Matrix<Vec3<f64>>,
        grad: &mut PhysicalGradient,
    ) {
        let sim = self.sim;
        let Some(g) = &sim.model.ground else {
            return;
        };
        let (dt, theta) = (self.nm.dt, self.nm.theta);
        let grid = &sim.grid;
        let (us, uns, vs, ls) = (self.us, self.uns, sim.v.as_slice(), self.ls);
        let ubs = u_bar.as_mut_slice();
        let vbs = v_bar.as_mut_slice();
        for c in &sim.crossings {
            let (a, b, t) = (c.a as usize, c.b as usize, c.t);
            let ip = |s: &[Vec3<f64>]| s[a] * (1.0 - t) + s[b] * t;
            let x0 = grid.positions[a] * (1.0 - t) + grid.positions[b] * t;
            let spring = Ground {
                stiffness: g.spring(c),
                ..*g
            };
            let adj = contact_adjoint(&spring, dt, theta, x0, ip(us), ip(uns), ip(vs), ip(ls));
            ubs[a] = ubs[a] + adj.u * (1.0 - t);
            ubs[b] = ubs[b] + adj.u * t;
            if let Some(mu) = sim.model.friction {
                let fr = friction_adjoint(&spring, mu, x0, ip(us), ip(uns), ip(ls));
                ubs[a] = ubs[a] + fr.u * (1.0 - t);
                ubs[b] = ubs[b] + fr.u * t;
                grad.ground_normal = grad.ground_normal + fr.normal;
                grad.ground_height += fr.height;
                grad.friction += fr.mu;
            }
            vbs[a] = vbs[a] + adj.v * (1.0 - t);
            vbs[b] = vbs[b] + adj.v * t;
            grad.ground_normal = grad.ground_normal + adj.normal;
            grad.ground_height += adj.height;
        }
    }
}

/// Adds the adjoint of the initial velocity `v0 + omega x (x - c)` for `v_bar` (the adjoint of
/// frame 0's velocity) to `grad`.
pub fn initial_velocity_adjoint(sim: &Simulation, v_bar: &Matrix<Vec3<f64>>, grad: &mut PhysicalGradient) {
    let c = sim.center_of_mass();
    for (p, vb) in sim.grid.positions.iter().zip(v_bar.as_slice()) {
        grad.initial_velocity = grad.initial_velocity + *vb;
        grad.initial_angular_velocity = grad.initial_angular_velocity + (*p - c).cross(*vb);
    }
}
