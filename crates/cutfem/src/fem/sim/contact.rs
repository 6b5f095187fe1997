//! The ground-contact stages of a step ([`super::collision`], thesis sec. 2.8, Alg. 5.5): the
//! contact forces added to `f`, their linearized stiffness added to the Newmark matrix `A`, and
//! for [`ContactScheme::Penalty`] the Newton iteration that re-linearizes the contact at the
//! last iterate `u'_k` until the linearization's error at `u'_{k+1}` is below
//! [`PENALTY_TOLERANCE`]` h`:
//!
//! `A(u'_k) u'_{k+1} = b(u'_k)`, with `f_c(u') ~ f_c(u'_k) + K_c(u'_k) (u' - u'_k)`.
//!
//! The adjoint and tangent passes linearize at the converged `u'`
//! ([`Simulation::linearize_contact_at`]): `A` is then the Jacobian of the converged step
//! (implicit function theorem).

use super::Simulation;
use crate::error::Error;
use crate::fem::collision::{
    add_friction_forces, add_ground_forces, penalty_residual, ContactScheme, Crossing, GroundPush,
    PENALTY_MAX_ITERATIONS, PENALTY_TOLERANCE,
};
use crate::fem::step_info::StepInfo;
use gpumat::{Mat3, Matrix, Vec3};

/// Per crossing, a coefficient of its `w w^T (x) block` term in the Newmark matrix
/// ([`Simulation::add_crossing_blocks`]).
type CrossingTerms = Vec<(Crossing, f64)>;

impl Simulation {
    /// Adds the ground's push at the current state to `push` ([`GroundPush`]; nothing without
    /// the ground).
    pub fn add_ground_push(&self, push: &mut GroundPush) {
        if let Some(ground) = &self.model.ground {
            push.add_state(&self.grid, &self.crossings, ground, &self.u);
        }
    }

    /// How far the rest body reaches into the ground: the largest depth below the plane of a
    /// rest surface crossing and the share of crossings below it, when some crossing lies more
    /// than a quarter cell below (a body resting on the plane touches it within a cell's
    /// rounding). `None` without the ground or when the body starts above it. Such a start
    /// is a misplaced ground (a sign or unit), not a contact: the springs throw the body out.
    pub fn initial_penetration(&self) -> Option<(f64, f64)> {
        let ground = self.model.ground.as_ref()?;
        let depths: Vec<f64> = self
            .crossings
            .iter()
            .map(|c| -ground.distance(c.lerp(&self.grid.positions)))
            .collect();
        let deepest = depths.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (deepest > 0.25 * self.grid.h()).then(|| {
            let below = depths.iter().filter(|&&d| d > 0.0).count();
            (deepest, below as f64 / depths.len() as f64)
        })
    }

    /// Whether `push`, gathered from this simulation's states, says the ground holds the body
    /// off the plane ([`GroundPush::hovers`], with this body's weight and cell size).
    pub fn hovers(&self, push: &GroundPush) -> bool {
        let g = self.model.gravity;
        push.hovers(self.total_mass() * g.dot(g).sqrt(), self.grid.h())
    }

    /// Where the next [`Simulation::assemble_system`] linearizes a
    /// [`ContactScheme::Penalty`] contact: at `at` (the adjoint and tangent passes give the
    /// step's converged `u'`, so that `A` is the Jacobian of the converged step); `None`: at
    /// `u`. Other schemes ignore it; every step resets it.
    pub fn linearize_contact_at(&mut self, at: Option<Matrix<Vec3<f64>>>) {
        self.contact_at = at;
    }

    /// Adds the ground's forces at the current state to `f` and returns the crossings in
    /// contact with their slopes `(crossing, k softmin'(d))`, and the friction's terms
    /// `(crossing, mu N_c)` ([`add_friction_forces`]); counts the contacts in `info`.
    pub(super) fn ground_forces(&mut self, info: &mut StepInfo) -> (CrossingTerms, CrossingTerms) {
        let mut contact = std::mem::take(&mut self.contact);
        contact.clear();
        let mut friction = Vec::new();
        if let Some(ground) = &self.model.ground {
            info.contacts = add_ground_forces(
                &self.grid,
                &self.crossings,
                ground,
                (&self.u, &self.v, self.contact_at.as_ref()),
                self.model.dt,
                self.model.theta,
                &mut self.f,
                &mut contact,
            );
            if let Some(mu) = self.model.friction {
                add_friction_forces(
                    &self.grid,
                    &self.crossings,
                    ground,
                    mu,
                    &self.u,
                    self.model.dt,
                    &mut self.f,
                    &mut friction,
                );
            }
        }
        (contact, friction)
    }

    /// Adds `scale * (w w^T (x) block)` for each `(crossing, coefficient)` of `terms` to the
    /// Newmark matrix, in the crossings' fixed order: the linearized contact stiffness `K_c`
    /// (`block = n n^T`, coefficients `k softmin'(d)`) and the friction (`block = I - n n^T`,
    /// coefficients `mu N_c`).
    pub(super) fn add_crossing_blocks(&mut self, terms: &[(Crossing, f64)], block: Mat3<f64>, scale: f64) {
        let pattern = self.assembler.pattern().clone();
        let values = self.a.batch_values_mut(0);
        for &(c, slope) in terms {
            let w = [(c.a, 1.0 - c.t), (c.b, c.t)];
            for &(p, wp) in &w {
                for &(q, wq) in &w {
                    let k = pattern
                        .find(p as usize, q as usize)
                        .expect("crossing corners share a cell");
                    values[k] = values[k] + block * (scale * slope * wp * wq);
                }
            }
        }
    }

    /// Newton on a [`ContactScheme::Penalty`] contact (module docs), from the first solve's
    /// `x`; nothing for the other schemes. Adds the extra assemblies and solves to `info`.
    pub(super) fn newton_contact(
        &mut self,
        x: &mut Matrix<Vec3<f64>>,
        info: &mut StepInfo,
    ) -> Result<(), Error> {
        let Some(g) = self.model.ground.filter(|g| g.scheme == ContactScheme::Penalty) else {
            return Ok(());
        };
        let tolerance = PENALTY_TOLERANCE * self.grid.h();
        let mut at = self.u.clone();
        for iteration in 1.. {
            if penalty_residual(&self.grid, &self.crossings, &g, &at, x) <= tolerance {
                break;
            }
            if iteration > PENALTY_MAX_ITERATIONS {
                self.contact_at = None;
                return Err(Error::Invalid(format!(
                    "the penalty contact did not converge in {PENALTY_MAX_ITERATIONS} Newton \
                     iterations at step {}; lower ground.softness ({}) or time.dt ({})",
                    self.steps + 1,
                    g.softness,
                    self.model.dt
                )));
            }
            self.contact_at = Some(x.clone());
            let more = self.assemble_system_with(false);
            info.newton += 1;
            info.assembly_s += more.assembly_s;
            info.stiffness_s += more.stiffness_s;
            info.collision_s += more.collision_s;
            info.contacts = more.contacts;
            self.solve_step(x, info)?;
            if let Some(last) = self.contact_at.take() {
                at = last;
            }
        }
        Ok(())
    }
}
