//! The physical model of a simulation: material, damping, forces, boundaries, time stepping.
//!
//! Besides gravity's body force `M g`, a model may carry a generic [`ExternalForce`]: a nodal
//! force linear in `K` coefficients and independent of the state,
//! `f_ext = sum_k c_k F_k` (one `Vec3` per degree of freedom in each basis field `F_k`). It is
//! added to the force vector `f` of every step, so it enters the Newmark right-hand side as
//! `dt f_ext` (eq. 2.6.2) exactly like gravity; effects defined outside cutfem (e.g. the
//! `wind` traction of the adjoint crate) build their basis from the grid and need no code here.

use super::collision::Ground;
use crate::error::Error;
use gpumat::{Matrix, Vec3};
use std::sync::Arc;

/// A damping force with fixed nodal weights, `f_i = -c w_i v_i` (air drag: `w_i = A_i`, the
/// node's share of the surface area, so that `c` is a traction per unit velocity). It joins the
/// mass damping in the Newmark system: `A_ii += c w_i I`, `b_i += c w_i u_i` (module
/// [`crate::fem::assembly`]'s Newmark docs), i.e. the force `-c W (u' - u) / dt` of the step.
#[derive(Clone, Debug, PartialEq)]
pub struct NodalDamping {
    /// `w_i`, one per degree of freedom (shared: fixed while a fit moves `c`)
    pub weights: Arc<Vec<f64>>,
    /// `c >= 0`
    pub coefficient: f64,
}

/// A state-independent nodal force linear in its coefficients: `f = sum_k c_k F_k`.
#[derive(Clone, Debug, PartialEq)]
pub struct ExternalForce {
    /// the `K` basis fields `F_k`, one `Vec3` per degree of freedom each (shared: the basis
    /// does not change while a fit moves the coefficients)
    pub basis: Arc<Vec<Vec<Vec3<f64>>>>,
    /// the coefficients `c_k`
    pub coefficients: Vec<f64>,
    /// a name per coefficient, for reports (e.g. `wind.x`)
    pub labels: Vec<String>,
}

impl ExternalForce {
    /// Number of coefficients `K`.
    pub fn len(&self) -> usize {
        self.coefficients.len()
    }
    /// True without coefficients.
    pub fn is_empty(&self) -> bool {
        self.coefficients.is_empty()
    }

    /// Appends other fields (e.g. of a second effect): the bases, coefficients and labels are
    /// concatenated.
    pub fn extend(&mut self, other: &ExternalForce) {
        let mut basis = (*self.basis).clone();
        basis.extend(other.basis.iter().cloned());
        self.basis = Arc::new(basis);
        self.coefficients.extend(&other.coefficients);
        self.labels.extend(other.labels.iter().cloned());
    }

    /// Checks that there are as many basis fields and labels as coefficients, that every field
    /// has the same length and that all values are finite (messages name the scene key
    /// `model.external_force`).
    pub fn validate(&self) -> Result<(), String> {
        let k = self.coefficients.len();
        if self.basis.len() != k || self.labels.len() != k {
            return Err(format!(
                "{} basis fields and {} labels for {k} coefficients",
                self.basis.len(),
                self.labels.len()
            ));
        }
        if let Some(c) = self.coefficients.iter().find(|c| !c.is_finite()) {
            return Err(format!("coefficients must be finite, got {c}"));
        }
        let n = self.basis.first().map_or(0, Vec::len);
        for (f, label) in self.basis.iter().zip(&self.labels) {
            if f.len() != n {
                return Err(format!(
                    "the field of `{label}` has {} values, the first {n}",
                    f.len()
                ));
            }
            if f.iter().any(|v| !v.to_array().iter().all(|x| x.is_finite())) {
                return Err(format!("the field of `{label}` is not finite"));
            }
        }
        Ok(())
    }

    /// Errors unless every basis field has one value per degree of freedom.
    pub fn check_dofs(&self, dofs: usize) -> Result<(), Error> {
        match self.basis.iter().find(|f| f.len() != dofs) {
            Some(f) => Err(Error::Invalid(format!(
                "model.external_force: a basis field has {} values for {dofs} degrees of freedom",
                f.len()
            ))),
            None => Ok(()),
        }
    }

    /// Adds `sum_k c_k F_k` to `f`.
    pub fn add_to(&self, f: &mut Matrix<Vec3<f64>>) {
        let fs = f.as_mut_slice();
        for (field, &c) in self.basis.iter().zip(&self.coefficients) {
            if c != 0.0 {
                for (out, v) in fs.iter_mut().zip(field) {
                    *out = *out + *v * c;
                }
            }
        }
    }
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// lower corner
    pub min: [f64; 3],
    /// upper corner
    pub max: [f64; 3],
}

impl Aabb {
    /// True when `p` lies inside (closed box).
    pub fn contains(&self, p: Vec3<f64>) -> bool {
        let p = p.to_array();
        (0..3).all(|d| p[d] >= self.min[d] && p[d] <= self.max[d])
    }
}

/// Everything the forward model needs besides the body.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// Young's modulus `E`
    pub young: f64,
    /// Poisson ratio `nu` in (0, 0.5)
    pub poisson: f64,
    /// mass density
    pub density: f64,
    /// Rayleigh mass damping `alpha_1` (D = alpha_1 M + alpha_2 K)
    pub damping_mass: f64,
    /// Rayleigh stiffness damping `alpha_2`
    pub damping_stiffness: f64,
    /// gravitational acceleration
    pub gravity: Vec3<f64>,
    /// ground contact, if any
    pub ground: Option<Ground>,
    /// corotated elasticity (sec. 2.7, 4.4.1.2)
    pub corotation: bool,
    /// regions held at zero displacement (Nitsche)
    pub dirichlet: Vec<Aabb>,
    /// how the Nitsche terms of the held surface are integrated ([`NitscheQuadrature`])
    pub nitsche_quadrature: NitscheQuadrature,
    /// the Nitsche penalty of the held surface ([`NitschePenalty`])
    pub nitsche: NitschePenalty,
    /// the grid element (`[numerics] element`)
    pub element: super::element::Element,
    /// the mass matrix of a grid body (`[numerics] mass`, [`MassMatrix`])
    pub mass: MassMatrix,
    /// initial linear velocity
    pub initial_velocity: Vec3<f64>,
    /// initial angular velocity (about the center of mass)
    pub initial_angular_velocity: Vec3<f64>,
    /// per active cell, a factor on Young's modulus (the `stiffness_field` effect; `None`:
    /// homogeneous)
    pub stiffness_scale: Option<std::sync::Arc<[f64]>>,
    /// a state-independent nodal force linear in its coefficients (module docs; `None`: none)
    pub external_force: Option<ExternalForce>,
    /// a velocity-proportional damping force with fixed nodal weights (the `drag` effect;
    /// `None`: none)
    pub drag: Option<NodalDamping>,
    /// the stiffness `k` (traction per unit displacement) of springs on the surface the
    /// Dirichlet boxes hold, in place of their rigid Nitsche hold: the block `k P_ij I`,
    /// `P_ij = int N_i N_j` over the held surface ([`crate::fem::NitscheFace::block`] without
    /// its traction terms; the `clamp` effect; `None`: held rigidly)
    pub support: Option<f64>,
    /// ground friction `mu` (tangential traction per unit normal traction per unit sliding
    /// speed; [`crate::fem::collision::add_friction_forces`], the `friction` effect; `None`:
    /// frictionless). Needs the ground.
    pub friction: Option<f64>,
    /// time step of the integrator (a scene's `time.dt / time.substeps`)
    pub dt: f64,
    /// Newmark-1 theta in [0.5, 1)
    pub theta: f64,
    /// integrator steps per frame: [`crate::fem::Simulation::step`] advances one frame,
    /// `substeps` steps of `dt` (`[time] substeps`, default 1)
    pub substeps: usize,
}

impl Model {
    /// The coefficients of one Newmark-1 step of this model ([`NewmarkCoefficients`]).
    pub fn newmark(&self) -> NewmarkCoefficients {
        NewmarkCoefficients::new(self.dt, self.theta, self.damping_mass, self.damping_stiffness)
    }
}

/// The coefficients of one Newmark-1 step with Rayleigh damping `D = a1 M + a2 K` (thesis eq.
/// 2.6.2), the one home of these numbers for the forward step, its tangent and its adjoint:
///
/// `A = cm M + ck K`, `b = cm M u + cu K u + cv M v + dt f`, and the velocity update
/// `v' = cvel (u' - u) - cold v`, with
///
/// `cm = 1/(theta dt) + a1`, `ck = a2 + theta dt`, `cu = a2 - (1 - theta) dt`, `cv = 1/theta`,
/// `cvel = 1/(theta dt)`, `cold = (1 - theta)/theta`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewmarkCoefficients {
    /// time step
    pub dt: f64,
    /// Newmark theta
    pub theta: f64,
    /// `1/(theta dt) + a1`: the mass in `A` and `M u` in `b`
    pub cm: f64,
    /// `a2 + theta dt`: the stiffness in `A`
    pub ck: f64,
    /// `a2 - (1 - theta) dt`: `K u` in `b`
    pub cu: f64,
    /// `1/theta`: `M v` in `b`
    pub cv: f64,
    /// `1/(theta dt)`: `u' - u` in the velocity update
    pub cvel: f64,
    /// `(1 - theta)/theta`: the old velocity in the velocity update
    pub cold: f64,
}

impl NewmarkCoefficients {
    /// Those of time step `dt`, `theta` and Rayleigh damping `a1`, `a2`.
    pub fn new(dt: f64, theta: f64, a1: f64, a2: f64) -> Self {
        Self {
            dt,
            theta,
            cm: 1.0 / (theta * dt) + a1,
            ck: a2 + theta * dt,
            cu: a2 - (1.0 - theta) * dt,
            cv: 1.0 / theta,
            cvel: 1.0 / (theta * dt),
            cold: (1.0 - theta) / theta,
        }
    }

    /// The velocity update in place: `v <- cvel (u_next - u) - cold v`.
    pub fn update_velocity(
        &self,
        v: &mut gpumat::Matrix<Vec3<f64>>,
        u_next: &gpumat::Matrix<Vec3<f64>>,
        u: &gpumat::Matrix<Vec3<f64>>,
    ) {
        let (c, cold) = (self.cvel, self.cold);
        v.assign_with(|v| (u_next.ex() - u.ex()) * c - v * cold);
    }
}

/// The most integrator steps per frame (`[time] substeps`).
pub const MAX_SUBSTEPS: usize = 1000;

/// The Nitsche penalty `eta` of the held surface (eq. 4.4.16-4.4.17).
///
/// The thesis fixes `eta = 1e8` whatever the material and the cell size. A penalty far above
/// `(lambda + 2 mu) / h` turns the weak clamp into a penalty method: the held surface is then
/// pinned pointwise, and a sliver of held surface in a cell (a box a little wider than the face
/// it holds catches strips of the side faces) pins the whole cell, which shortens a cantilever
/// by a cell (10% stiffer at four cells through the thickness, `docs/simulation.md`). A penalty
/// below a few `(lambda + 2 mu) / h` loses coercivity. [`NitschePenalty::Scaled`] keeps the
/// ratio fixed, so the clamp behaves the same in any units, for any material and resolution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NitschePenalty {
    /// `eta = gamma (lambda + 2 mu) |G_e| / |K_e|` with the cell's own Lame constants (the
    /// stiffness field included), `|G_e|` its held area and `|K_e|` its inside volume (`1 / h`
    /// for a full face of a full cell; the local inverse estimate, so that a sliver of
    /// material under a held face stays coercive); `[numerics] nitsche_gamma`, default
    /// [`DEFAULT_NITSCHE_GAMMA`]
    Scaled(f64),
    /// a fixed `eta` in stress per length (the thesis: 1e8); `[numerics] nitsche_eta`
    Fixed(f64),
}

/// The default `gamma` of [`NitschePenalty::Scaled`]: the smallest power-of-two multiple of 10
/// with which every cut configuration of the coercivity sweep in `tests/fem_nitsche.rs` stays
/// positive definite (both elements, `nu` up to 0.49).
pub const DEFAULT_NITSCHE_GAMMA: f64 = 20.0;

/// The mass matrix of a grid body (`[numerics] mass`; [`crate::fem::assembly::mass`] has the
/// formulas and why). Both have the same row sums, so gravity, the total mass and the center of
/// mass do not depend on the choice.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MassMatrix {
    /// each cell's mass on its corners, `m_i = rho int N_i` (the thesis', sec. 4.4.2; the
    /// default): a diagonal matrix, rotational inertia too large by `O(h^2)` (10% for a bar
    /// 4.4 cells across twisting about its axis)
    #[default]
    Lumped,
    /// `M_ij = rho int N_i N_j` over the inside part of each cell, on the stiffness matrix'
    /// pattern: exact inertia for every field the cell represents
    Consistent,
}

/// How the Nitsche terms of the held surface are integrated (`[numerics] nitsche`; the
/// formulas in [`crate::fem::sim::dirichlet`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NitscheQuadrature {
    /// the thesis' (eq. 4.4.15-4.4.17): nodal weights `w_b(e, i)`, the traction at the
    /// corners and the cell's mean normal; its penalty is the fixed 1e8 unless given
    Thesis,
    /// consistent quadrature over the held surface; its penalty is the scaled one
    /// ([`NitschePenalty::Scaled`] with [`DEFAULT_NITSCHE_GAMMA`]) unless given (the default)
    #[default]
    Consistent,
}

impl NitscheQuadrature {
    /// The penalty used when the scene gives none.
    pub fn default_penalty(self) -> NitschePenalty {
        match self {
            Self::Thesis => NitschePenalty::Fixed(1e8),
            Self::Consistent => NitschePenalty::Scaled(DEFAULT_NITSCHE_GAMMA),
        }
    }
}

impl NitschePenalty {
    /// `(eta, eta per unit of lambda + 2 mu)` on a grid of cell size `h`: the penalty of a cell
    /// whose Lame constants are `lambda, mu` is `eta + per_modulus (lambda + 2 mu)`.
    pub fn terms(self, h: f64) -> (f64, f64) {
        match self {
            Self::Scaled(gamma) => (0.0, gamma / h),
            Self::Fixed(eta) => (eta, 0.0),
        }
    }
}

impl Default for Model {
    fn default() -> Self {
        Self {
            young: 2000.0,
            poisson: 0.3,
            density: 1.0,
            damping_mass: 0.0,
            damping_stiffness: 0.0,
            gravity: Vec3::default(),
            ground: None,
            corotation: true,
            dirichlet: Vec::new(),
            nitsche_quadrature: NitscheQuadrature::default(),
            nitsche: NitscheQuadrature::default().default_penalty(),
            element: super::element::Element::default(),
            mass: MassMatrix::default(),
            initial_velocity: Vec3::default(),
            initial_angular_velocity: Vec3::default(),
            stiffness_scale: None,
            external_force: None,
            drag: None,
            support: None,
            friction: None,
            dt: 0.01,
            theta: 0.6,
            substeps: 1,
        }
    }
}

impl Model {
    /// Checks the parameter ranges; the error names the scene key.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |key: &str, why: String| Err(Error::Invalid(format!("{key}: {why}")));
        if !(self.young > 0.0 && self.young.is_finite()) {
            return bad(
                "material.young",
                format!("Young's modulus must be positive, got {}", self.young),
            );
        }
        if !(self.poisson > 0.0 && self.poisson < 0.5) {
            return bad(
                "material.poisson",
                format!("Poisson ratio must lie in (0, 0.5), got {}", self.poisson),
            );
        }
        if !(self.density > 0.0 && self.density.is_finite()) {
            return bad(
                "material.density",
                format!("density must be positive, got {}", self.density),
            );
        }
        if !(self.damping_mass >= 0.0 && self.damping_mass.is_finite()) {
            return bad("damping.mass", format!("must be >= 0, got {}", self.damping_mass));
        }
        if !(self.damping_stiffness >= 0.0 && self.damping_stiffness.is_finite()) {
            return bad(
                "damping.stiffness",
                format!("must be >= 0, got {}", self.damping_stiffness),
            );
        }
        if !(self.dt > 0.0 && self.dt.is_finite()) {
            return bad("time.dt", format!("time step must be positive, got {}", self.dt));
        }
        if !(1..=MAX_SUBSTEPS).contains(&self.substeps) {
            return bad(
                "time.substeps",
                format!("must lie in 1..={MAX_SUBSTEPS}, got {}", self.substeps),
            );
        }
        if !(self.theta >= 0.5 && self.theta < 1.0) {
            return bad(
                "time.theta",
                format!("Newmark theta must lie in [0.5, 1), got {}", self.theta),
            );
        }
        let (key, value) = match self.nitsche {
            NitschePenalty::Scaled(g) => ("numerics.nitsche_gamma", g),
            NitschePenalty::Fixed(eta) => ("numerics.nitsche_eta", eta),
        };
        if !(value > 0.0 && value.is_finite()) {
            return bad(key, format!("must be positive, got {value}"));
        }
        if !self.gravity.to_array().iter().all(|g| g.is_finite()) {
            return bad("gravity.acceleration", "must be finite".into());
        }
        if let Some(g) = &self.ground {
            let n = g.normal.norm();
            if !(n > 0.0 && n.is_finite()) {
                return bad("ground.normal", "must be a non-zero vector".into());
            }
            if !(g.stiffness > 0.0 && g.stiffness.is_finite()) {
                return bad(
                    "ground.stiffness",
                    format!("must be positive, got {}", g.stiffness),
                );
            }
            if !(g.softness > 0.0 && g.softness.is_finite()) {
                return bad("ground.softness", format!("must be positive, got {}", g.softness));
            }
        }
        if let Some(s) = &self.stiffness_scale {
            if let Some(v) = s.iter().find(|v| !(**v > 0.0 && v.is_finite())) {
                return bad(
                    "model.stiffness_field",
                    format!("Young's modulus factors must be positive, got {v}"),
                );
            }
        }
        if let Some(e) = &self.external_force {
            if let Err(why) = e.validate() {
                return bad("model.external_force", why);
            }
        }
        if let Some(d) = &self.drag {
            if !(d.coefficient >= 0.0 && d.coefficient.is_finite()) {
                return bad("drag.coefficient", format!("must be >= 0, got {}", d.coefficient));
            }
            if let Some(w) = d.weights.iter().find(|w| !(**w >= 0.0 && w.is_finite())) {
                return bad("model.drag", format!("weights must be >= 0, got {w}"));
            }
        }
        if let Some(k) = self.support.filter(|k| !(*k > 0.0 && k.is_finite())) {
            return bad("clamp.stiffness", format!("must be finite and > 0, got {k}"));
        }
        if let Some(mu) = self.friction.filter(|m| !(*m >= 0.0 && m.is_finite())) {
            return bad(
                "friction.coefficient",
                format!("must be finite and >= 0, got {mu}"),
            );
        }
        if self.friction.is_some() && self.ground.is_none() {
            return bad(
                "friction",
                "ground friction needs the ground ([ground] and `ground` in [model].effects)".into(),
            );
        }
        if self.support.is_some() && self.dirichlet.is_empty() {
            return bad(
                "clamp",
                "an elastic support needs a [[dirichlet]] box whose hold it softens".into(),
            );
        }
        for (i, b) in self.dirichlet.iter().enumerate() {
            if !(0..3).all(|d| b.min[d] <= b.max[d]) {
                return bad(&format!("dirichlet[{i}]"), "min must not exceed max".into());
            }
        }
        Ok(())
    }

    /// Errors unless the external force and the drag, if any, have one value per degree of
    /// freedom.
    pub fn check_external_dofs(&self, dofs: usize) -> Result<(), Error> {
        if let Some(d) = self.drag.as_ref().filter(|d| d.weights.len() != dofs) {
            return Err(Error::Invalid(format!(
                "model.drag: {} weights for {dofs} degrees of freedom",
                d.weights.len()
            )));
        }
        self.external_force
            .as_ref()
            .map_or(Ok(()), |e| e.check_dofs(dofs))
    }

    /// Lame coefficients `(lambda, mu)`.
    pub fn lame(&self) -> (f64, f64) {
        super::element::lame(self.young, self.poisson)
    }
}

/// The cuboid of the thesis' Tables B.5 and B.6: a 1.29 x 0.4 x 0.8 box centred at (0, 1, 0),
/// E 2000, nu 0.3, Rayleigh damping (0.1, 0.01), gravity 10, corotation, `dt` 0.01, theta 0.6;
/// held at its left end (B.5, `ground = false`) or dropped on the ground at height 0.75
/// (B.6). Its grid at resolution `r` has cells of size `1 / (2 r)` (`shape.to_sdf(2 r, pad)`).
pub fn thesis_cuboid(ground: bool) -> (crate::shapes::Shape, Model) {
    let shape = crate::shapes::Shape::Box {
        center: [0.0, 1.0, 0.0],
        size: [1.29, 0.4, 0.8],
    };
    let model = Model {
        young: 2000.0,
        poisson: 0.3,
        damping_mass: 0.1,
        damping_stiffness: 0.01,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        corotation: true,
        dirichlet: if ground {
            vec![]
        } else {
            vec![Aabb {
                min: [-0.9, 0.6, -0.6],
                max: [-0.55, 1.4, 0.6],
            }]
        },
        ground: ground.then_some(Ground {
            normal: Vec3::new(0.0, 1.0, 0.0),
            height: 0.75,
            // the thesis' law: springs per crossing
            stiffness: 1.0e4,
            softness: 100.0,
            scheme: super::collision::ContactScheme::Implicit,
        }),
        dt: 0.01,
        theta: 0.6,
        ..Model::default()
    };
    (shape, model)
}

#[cfg(test)]
mod tests {
    use super::*;
    use gpumat::Matrix;

    /// The velocity update is the Newmark-1 relation `u' = u + dt ((1 - theta) v + theta v')`
    /// (eq. 2.6.3), and the coefficients of `A` and `b` are those of eq. 2.6.2.
    #[test]
    fn newmark_coefficients_satisfy_the_newmark_relation() {
        for (dt, theta, a1, a2) in [
            (0.01, 0.5, 0.0, 0.0),
            (0.003, 0.6, 0.4, 0.002),
            (0.1, 0.99, 2.0, 0.1),
        ] {
            let c = NewmarkCoefficients::new(dt, theta, a1, a2);
            assert!((c.cm - (c.cvel + a1)).abs() < 1e-12 * c.cm);
            assert!((c.ck - (a2 + theta * dt)).abs() < 1e-15);
            assert!((c.cu - (c.ck - dt)).abs() < 1e-12);
            assert!((c.cv * theta - 1.0).abs() < 1e-15);
            let u = Matrix::from_fn(3, 1, 1, |i, _, _| Vec3::new(i as f64, 0.5, -1.0));
            let un = Matrix::from_fn(3, 1, 1, |i, _, _| Vec3::new(0.3 * i as f64, 0.7, -0.9));
            let v0 = Matrix::from_fn(3, 1, 1, |i, _, _| Vec3::new(1.0, -2.0 * i as f64, 0.25));
            let mut v = v0.clone();
            c.update_velocity(&mut v, &un, &u);
            for i in 0..3 {
                let (a, b, old, new) = (u.get(i, 0, 0), un.get(i, 0, 0), v0.get(i, 0, 0), v.get(i, 0, 0));
                let predicted = a + (old * (1.0 - theta) + new * theta) * dt;
                assert!(
                    (predicted - b).norm() < 1e-12,
                    "dt {dt} theta {theta}: {predicted:?} vs {b:?}"
                );
            }
        }
    }
}
