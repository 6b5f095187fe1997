//! The fitted parameters (interface.md: `young`, `poisson`, `density`, `damping_mass`,
//! `damping_stiffness`, `gravity`, `ground`, `initial_velocity`, plus the extension
//! `initial_angular_velocity`) and their unconstrained coordinates.
//!
//! Optimizers work on an unconstrained vector `x`. Positive quantities are fitted in log space
//! (`E = e^x`, `rho = e^x`, `alpha_{1,2} = e^x`); the Poisson ratio through a scaled logistic,
//! `nu = sigmoid(x) / 2`, so it stays inside `(0, 0.5)`; gravity and velocities are linear. The
//! ground plane `{n . x >= height}` is fitted as two tilt angles and its height:
//! `n = (-sin a_z cos a_x, cos a_z cos a_x, sin a_x)` (the `y` axis tilted about `x`, then `z`),
//! regular at the horizontal plane. The coefficients `c_k` of a model's external force
//! `f = sum_k c_k F_k` ([`cutfem::fem::ExternalForce`], e.g. the `wind` effect's traction) are
//! linear coordinates, one per basis field. Gradients are chained from the physical ones
//! ([`crate::backward::PhysicalGradient`]) with the Lame derivatives (eq. 5.5.5):
//! `dlambda/dE = nu/((1+nu)(1-2nu))`, `dmu/dE = 1/(2(1+nu))`,
//! `dlambda/dnu = E(1+2nu^2)/((1+nu)(1-2nu))^2`, `dmu/dnu = -E/(2(1+nu)^2)`.

use crate::backward::PhysicalGradient;
use crate::Error;
use cutfem::fem::Model;
use gpumat::Vec3;
use std::fmt;
use std::str::FromStr;

mod field;
mod layout;
pub use field::FieldBasis;
pub use layout::Layout;

/// Smallest starting value of a damping coefficient fitted in log space (a coefficient of
/// exactly 0 has no logarithm).
pub const DAMPING_FLOOR: f64 = 1e-4;

/// One named parameter (group) of the interface's vocabulary.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Param {
    /// Young's modulus (log)
    Young,
    /// Poisson ratio (logistic into (0, 0.5))
    Poisson,
    /// density (log)
    Density,
    /// Rayleigh mass damping (log)
    DampingMass,
    /// Rayleigh stiffness damping (log)
    DampingStiffness,
    /// gravity vector (3, linear)
    Gravity,
    /// ground plane: two tilt angles and the height (3)
    Ground,
    /// initial linear velocity (3, linear)
    InitialVelocity,
    /// initial angular velocity about the center of mass (3, linear)
    InitialAngularVelocity,
    /// log factors of Young's modulus on the nodes of a coarse trilinear grid
    StiffnessField,
    /// the coefficients of the model's external force (linear), as many as its basis fields:
    /// the count is taken from the model by [`ParamSet::layout`] (0 until then, see
    /// [`Param::EXTERNAL_FORCE`])
    ExternalForce(usize),
    /// the drag coefficient (log): traction per unit velocity on the surface
    Drag,
    /// the clamp's support stiffness (log): traction per unit displacement on the held surface
    Clamp,
    /// the ground friction (log): tangential traction per normal traction per sliding speed
    Friction,
}

impl Param {
    /// The external force's coefficients before their count is known (what parsing
    /// `external_force` and the effects' [`crate::diagnosis::effects::Effect::params`] give).
    pub const EXTERNAL_FORCE: Param = Param::ExternalForce(0);
}

/// The vocabulary, in the order of [`Param`].
pub const ALL: [Param; 14] = [
    Param::Young,
    Param::Poisson,
    Param::Density,
    Param::DampingMass,
    Param::DampingStiffness,
    Param::Gravity,
    Param::Ground,
    Param::InitialVelocity,
    Param::InitialAngularVelocity,
    Param::StiffnessField,
    Param::EXTERNAL_FORCE,
    Param::Drag,
    Param::Clamp,
    Param::Friction,
];

impl Param {
    /// True when it is fitted as the logarithm of a positive quantity (one coordinate).
    pub fn is_log(self) -> bool {
        matches!(
            self,
            Param::Young
                | Param::Density
                | Param::DampingMass
                | Param::DampingStiffness
                | Param::Drag
                | Param::Clamp
                | Param::Friction
        )
    }
    /// The interface name.
    pub fn name(self) -> &'static str {
        match self {
            Param::Young => "young",
            Param::Poisson => "poisson",
            Param::Density => "density",
            Param::DampingMass => "damping_mass",
            Param::DampingStiffness => "damping_stiffness",
            Param::Gravity => "gravity",
            Param::Ground => "ground",
            Param::InitialVelocity => "initial_velocity",
            Param::InitialAngularVelocity => "initial_angular_velocity",
            Param::StiffnessField => "stiffness_field",
            Param::ExternalForce(_) => "external_force",
            Param::Drag => "drag",
            Param::Clamp => "clamp",
            Param::Friction => "friction",
        }
    }
    /// The names of its components (the external force's: `external_force[k]`; its reports use
    /// the model's labels, e.g. `wind.x`, see [`Layout::values`]).
    pub fn components(self) -> Vec<String> {
        let xyz = |p: &str| ["x", "y", "z"].iter().map(|c| format!("{p}.{c}")).collect();
        match self {
            Param::Gravity | Param::InitialVelocity | Param::InitialAngularVelocity => xyz(self.name()),
            Param::Ground => vec![
                "ground.angle_x".into(),
                "ground.angle_z".into(),
                "ground.height".into(),
            ],
            Param::ExternalForce(n) => (0..n).map(|k| format!("external_force[{k}]")).collect(),
            _ => vec![self.name().into()],
        }
    }
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Param {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self, Error> {
        ALL.iter().copied().find(|p| p.name() == s).ok_or_else(|| {
            let names: Vec<_> = ALL.iter().map(|p| p.name()).collect();
            Error::invalid(format!(
                "unknown parameter `{}` (known: {})",
                cutfem::scene::quote(s, cutfem::scene::MAX_QUOTE),
                names.join(", ")
            ))
        })
    }
}

/// The ground normal of tilt angles `(a_x, a_z)` and its derivatives.
pub fn ground_normal(ax: f64, az: f64) -> (Vec3<f64>, Vec3<f64>, Vec3<f64>) {
    let (sx, cx, sz, cz) = (ax.sin(), ax.cos(), az.sin(), az.cos());
    (
        Vec3::new(-sz * cx, cz * cx, sx),
        Vec3::new(sz * sx, -cz * sx, cx),
        Vec3::new(-cz * cx, -sz * cx, 0.0),
    )
}

/// The tilt angles of a unit normal.
pub fn ground_angles(n: Vec3<f64>) -> (f64, f64) {
    let [x, y, z] = n.to_array();
    (z.clamp(-1.0, 1.0).asin(), (-x).atan2(y))
}

/// An ordered set of fitted parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamSet {
    /// the parameters, in the user's order, without duplicates
    pub params: Vec<Param>,
    /// the basis of `stiffness_field`, when fitted
    pub field: Option<std::sync::Arc<FieldBasis>>,
}

impl ParamSet {
    /// Parses a comma-separated list (or a list of names).
    pub fn parse<S: AsRef<str>>(names: &[S]) -> Result<Self, Error> {
        let mut params = Vec::new();
        for n in names {
            for part in n.as_ref().split(',').map(str::trim).filter(|s| !s.is_empty()) {
                let p: Param = part.parse()?;
                if params.contains(&p) {
                    return Err(Error::Invalid(format!("parameter `{p}` given twice")));
                }
                params.push(p);
            }
        }
        if params.is_empty() {
            return Err(Error::invalid("no parameters to fit"));
        }
        Ok(Self { params, field: None })
    }

    /// Component labels, in the order of `x`.
    pub fn labels(&self) -> Vec<String> {
        self.params
            .iter()
            .flat_map(|p| match (p, &self.field) {
                (Param::StiffnessField, Some(f)) => f.labels(),
                // no basis yet (a set not checked into a layout): no coefficients
                (Param::StiffnessField, None) => Vec::new(),
                _ => p.components(),
            })
            .collect()
    }

    /// Length of `x`.
    pub fn len(&self) -> usize {
        self.labels().len()
    }
    /// True when no parameter is fitted.
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// Per component of `x`, true when it is the logarithm of a positive quantity (Young's
    /// modulus, density, damping; the stiffness field's log factors are not: they are 0 at the
    /// homogeneous material).
    pub fn log_coordinates(&self) -> Vec<bool> {
        let mut out = Vec::new();
        for p in &self.params {
            if p.is_log() {
                out.push(true);
            } else {
                out.extend(vec![false; self.component_count(*p)]);
            }
        }
        out
    }

    /// Per component of `x`, true when it is a log factor of the stiffness field.
    pub fn field_coordinates(&self) -> Vec<bool> {
        let mut out = Vec::new();
        for p in &self.params {
            out.extend(vec![*p == Param::StiffnessField; self.component_count(*p)]);
        }
        out
    }

    /// A plausible box for the coordinates of a fit starting at `x0`: Young's modulus and the
    /// density within a factor 100 of the start, the Poisson ratio in `[0.01, 0.49]`, damping
    /// coefficients (and the friction) in `[1e-6, 1e4]`, the stiffness field's factors within `[1/100, 100]`, the
    /// clamp's stiffness from 1e-6 to 100 times the start (it can soften far, stiffen less);
    /// the rest unbounded.
    pub fn bounds(&self, x0: &[f64]) -> Vec<(f64, f64)> {
        let logit = |nu: f64| (2.0 * nu / (1.0 - 2.0 * nu)).ln();
        let mut out = Vec::new();
        let mut k = 0;
        for p in &self.params {
            let n = self.component_count(*p);
            for _ in 0..n {
                let x = x0.get(k).copied().unwrap_or(0.0);
                out.push(match p {
                    Param::Young | Param::Density => (x - 100f64.ln(), x + 100f64.ln()),
                    Param::Poisson => (logit(0.01), logit(0.49)),
                    Param::DampingMass | Param::DampingStiffness | Param::Drag | Param::Friction => {
                        (1e-6f64.ln(), 1e4f64.ln())
                    }
                    Param::StiffnessField => (-100f64.ln(), 100f64.ln()),
                    Param::Clamp => (x - 1e6f64.ln(), x + 100f64.ln()),
                    _ => (f64::NEG_INFINITY, f64::INFINITY),
                });
                k += 1;
            }
        }
        out
    }

    fn component_count(&self, p: Param) -> usize {
        match (p, &self.field) {
            (Param::StiffnessField, Some(f)) => f.len(),
            (Param::StiffnessField, None) => 0,
            _ => p.components().len(),
        }
    }
}

/// `(dJ/dE, dJ/dnu)` from `(dJ/dlambda, dJ/dmu)` at the model's `E`, `nu` (eq. 5.5.5, module
/// docs).
pub fn young_poisson_gradient(model: &Model, g: &PhysicalGradient) -> (f64, f64) {
    let (e, nu) = (model.young, model.poisson);
    let de = g.lambda * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)) + g.mu / (2.0 * (1.0 + nu));
    let dnu = g.lambda * e * (1.0 + 2.0 * nu * nu) / ((1.0 + nu) * (1.0 - 2.0 * nu)).powi(2)
        - g.mu * e / (2.0 * (1.0 + nu) * (1.0 + nu));
    (de, dnu)
}

#[cfg(test)]
mod tests;
