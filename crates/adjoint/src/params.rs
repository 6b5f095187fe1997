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
pub use field::FieldBasis;

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
    /// the count is taken from the model by [`ParamSet::resolve`] (0 until then, see
    /// [`Param::EXTERNAL_FORCE`])
    ExternalForce(usize),
}

impl Param {
    /// The external force's coefficients before their count is known (what parsing
    /// `external_force` and the effects' [`crate::diagnosis::effects::Effect::params`] give).
    pub const EXTERNAL_FORCE: Param = Param::ExternalForce(0);
}

/// The vocabulary, in the order of [`Param`].
pub const ALL: [Param; 11] = [
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
];

impl Param {
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
        }
    }
    /// The names of its components (the external force's: `external_force[k]`; its reports use
    /// the model's labels, e.g. `wind.x`, see [`ParamSet::values`]).
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
                // no basis yet (not resolved by a problem): no coefficients, as in `to_x`
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

    /// Takes the number of external-force coefficients from `model` (a parsed set does not
    /// know it; [`crate::problem::Problem::new`] calls this).
    pub fn resolve(&mut self, model: &Model) {
        let k = model.external_force.as_ref().map_or(0, |e| e.len());
        for p in &mut self.params {
            if let Param::ExternalForce(n) = p {
                *n = k;
            }
        }
    }

    /// Checks that the model has what the parameters need (e.g. a ground plane).
    pub fn check(&self, model: &Model) -> Result<(), Error> {
        for p in &self.params {
            if let Param::ExternalForce(n) = *p {
                match &model.external_force {
                    None => {
                        return Err(Error::invalid(
                            "fitting `external_force` needs an effect that adds one (e.g. `wind` \
                             in [model].effects with a [wind] section)",
                        ))
                    }
                    Some(e) if e.len() != n => {
                        return Err(Error::Invalid(format!(
                            "external_force: {n} components for the model's {} coefficients (call ParamSet::resolve)",
                            e.len()
                        )))
                    }
                    _ => {}
                }
            }
        }
        if self.params.contains(&Param::StiffnessField) && self.field.is_none() {
            return Err(Error::invalid(
                "fitting `stiffness_field` needs its basis ([model].stiffness_field = { cells = [...] })",
            ));
        }
        if self.params.contains(&Param::Ground) && model.ground.is_none() {
            return Err(Error::invalid(
                "fitting `ground` needs a [ground] section and `ground` in [model].effects",
            ));
        }
        Ok(())
    }

    /// The unconstrained coordinates of the model's current values.
    pub fn to_x(&self, model: &Model) -> Vec<f64> {
        let mut x = Vec::new();
        for p in &self.params {
            match p {
                Param::Young => x.push(model.young.ln()),
                Param::Poisson => {
                    let s = 2.0 * model.poisson;
                    x.push((s / (1.0 - s)).ln());
                }
                Param::Density => x.push(model.density.ln()),
                Param::DampingMass => x.push(model.damping_mass.max(DAMPING_FLOOR).ln()),
                Param::DampingStiffness => x.push(model.damping_stiffness.max(DAMPING_FLOOR).ln()),
                Param::Gravity => x.extend(model.gravity.to_array()),
                Param::Ground => {
                    let g = model.ground.as_ref().expect("checked");
                    let (ax, az) = ground_angles(g.normal);
                    x.extend([ax, az, g.height]);
                }
                Param::InitialVelocity => x.extend(model.initial_velocity.to_array()),
                Param::InitialAngularVelocity => x.extend(model.initial_angular_velocity.to_array()),
                // fits start from the homogeneous material (all factors 1)
                Param::StiffnessField => x.extend(vec![0.0; self.field.as_ref().map_or(0, |f| f.len())]),
                Param::ExternalForce(_) => x.extend(external(model).coefficients.iter().copied()),
            }
        }
        x
    }

    /// Writes the parameters of `x` into `model`.
    pub fn apply(&self, x: &[f64], model: &mut Model) {
        let mut k = 0;
        let mut take = |n: usize| {
            let s = &x[k..k + n];
            k += n;
            s
        };
        for p in &self.params {
            match p {
                Param::Young => model.young = take(1)[0].exp(),
                Param::Poisson => model.poisson = 0.5 / (1.0 + (-take(1)[0]).exp()),
                Param::Density => model.density = take(1)[0].exp(),
                Param::DampingMass => model.damping_mass = take(1)[0].exp(),
                Param::DampingStiffness => model.damping_stiffness = take(1)[0].exp(),
                Param::Gravity => model.gravity = v3(take(3)),
                Param::Ground => {
                    let s = take(3);
                    let g = model.ground.as_mut().expect("checked");
                    g.normal = ground_normal(s[0], s[1]).0;
                    g.height = s[2];
                }
                Param::InitialVelocity => model.initial_velocity = v3(take(3)),
                Param::InitialAngularVelocity => model.initial_angular_velocity = v3(take(3)),
                Param::StiffnessField => {
                    // without a basis the set has no coefficients of it (`labels`)
                    if let Some(f) = &self.field {
                        model.stiffness_scale = Some(f.scales(take(f.len())).into());
                    }
                }
                Param::ExternalForce(_) => {
                    let e = model.external_force.as_mut().expect("checked");
                    let n = e.len();
                    e.coefficients.copy_from_slice(take(n));
                }
            }
        }
    }

    /// The physical values, labelled (e.g. `young`, `gravity.y`, `ground.normal.x`).
    pub fn values(&self, model: &Model) -> Vec<(String, f64)> {
        let mut out = Vec::new();
        for p in &self.params {
            let xyz = |name: &str, v: Vec3<f64>| {
                let a = v.to_array();
                ["x", "y", "z"]
                    .iter()
                    .zip(a)
                    .map(|(c, v)| (format!("{name}.{c}"), v))
                    .collect::<Vec<_>>()
            };
            match p {
                Param::Young => out.push((p.name().into(), model.young)),
                Param::Poisson => out.push((p.name().into(), model.poisson)),
                Param::Density => out.push((p.name().into(), model.density)),
                Param::DampingMass => out.push((p.name().into(), model.damping_mass)),
                Param::DampingStiffness => out.push((p.name().into(), model.damping_stiffness)),
                Param::Gravity => out.extend(xyz(p.name(), model.gravity)),
                Param::Ground => {
                    let g = model.ground.as_ref().expect("checked");
                    out.extend(xyz("ground.normal", g.normal));
                    out.push(("ground.height".into(), g.height));
                }
                Param::InitialVelocity => out.extend(xyz(p.name(), model.initial_velocity)),
                Param::InitialAngularVelocity => out.extend(xyz(p.name(), model.initial_angular_velocity)),
                Param::StiffnessField => {
                    // the factors' range: the coefficients themselves are in `x`
                    let s = model.stiffness_scale.as_deref().unwrap_or(&[]);
                    let (lo, hi) = s.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                        (a.min(v), b.max(v))
                    });
                    out.push((
                        "stiffness_field.min_factor".into(),
                        if s.is_empty() { 1.0 } else { lo },
                    ));
                    out.push((
                        "stiffness_field.max_factor".into(),
                        if s.is_empty() { 1.0 } else { hi },
                    ));
                }
                Param::ExternalForce(_) => {
                    let e = external(model);
                    out.extend(e.labels.iter().cloned().zip(e.coefficients.iter().copied()));
                }
            }
        }
        out
    }

    /// The gradient with respect to `x` of a function whose physical gradient is `g`, at the
    /// model `model` (which must be `apply(x)`'s result).
    pub fn chain(&self, model: &Model, g: &PhysicalGradient) -> Vec<f64> {
        let mut out = Vec::new();
        let (e, nu) = (model.young, model.poisson);
        for p in &self.params {
            match p {
                Param::Young => out.push(young_poisson_gradient(model, g).0 * e),
                Param::Poisson => out.push(young_poisson_gradient(model, g).1 * nu * (1.0 - 2.0 * nu)),
                Param::Density => out.push(g.density * model.density),
                Param::DampingMass => out.push(g.damping_mass * model.damping_mass),
                Param::DampingStiffness => out.push(g.damping_stiffness * model.damping_stiffness),
                Param::Gravity => out.extend(g.gravity.to_array()),
                Param::Ground => {
                    let gr = model.ground.as_ref().expect("checked");
                    let (ax, az) = ground_angles(gr.normal);
                    let (_, dx, dz) = ground_normal(ax, az);
                    out.extend([g.ground_normal.dot(dx), g.ground_normal.dot(dz), g.ground_height]);
                }
                Param::InitialVelocity => out.extend(g.initial_velocity.to_array()),
                Param::InitialAngularVelocity => out.extend(g.initial_angular_velocity.to_array()),
                Param::StiffnessField => {
                    let Some(f) = self.field.as_ref() else { continue };
                    let ones;
                    let s = match model.stiffness_scale.as_deref() {
                        Some(s) => s,
                        None => {
                            ones = vec![1.0; f.weights.len()];
                            &ones
                        }
                    };
                    out.extend(f.chain(s, &g.cell_scale));
                }
                Param::ExternalForce(_) => out.extend(external_gradient(model, g)),
            }
        }
        out
    }

    /// Per component of `x` ([`ParamSet::labels`]), the derivative of the reported quantity
    /// with respect to `x_k`: the value itself for log-fitted quantities, `nu (1 - 2 nu)` for
    /// the Poisson ratio, 1 for linear ones (gravity, velocities, the ground's tilt angles in
    /// radians and height, the field's log factors). Standard errors in `x` times these are
    /// standard errors of the reported quantities (first order).
    pub fn x_scales(&self, model: &Model) -> Vec<f64> {
        let mut out = Vec::new();
        for p in &self.params {
            match p {
                Param::Young => out.push(model.young),
                Param::Poisson => out.push(model.poisson * (1.0 - 2.0 * model.poisson)),
                Param::Density => out.push(model.density),
                Param::DampingMass => out.push(model.damping_mass),
                Param::DampingStiffness => out.push(model.damping_stiffness),
                Param::Gravity | Param::Ground | Param::InitialVelocity | Param::InitialAngularVelocity => {
                    out.extend([1.0; 3])
                }
                Param::StiffnessField => out.extend(vec![1.0; self.field.as_ref().map_or(0, |f| f.len())]),
                Param::ExternalForce(_) => out.extend(vec![1.0; external(model).len()]),
            }
        }
        out
    }

    /// Per component of `x`, true when it is the logarithm of a positive quantity (Young's
    /// modulus, density, damping; the stiffness field's log factors are not: they are 0 at the
    /// homogeneous material).
    pub fn log_coordinates(&self) -> Vec<bool> {
        let mut out = Vec::new();
        for p in &self.params {
            match p {
                Param::Young | Param::Density | Param::DampingMass | Param::DampingStiffness => {
                    out.push(true)
                }
                _ => out.extend(vec![false; self.component_count(*p)]),
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
    /// coefficients in `[1e-6, 1e4]`, the stiffness field's factors within `[1/100, 100]`;
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
                    Param::DampingMass | Param::DampingStiffness => (1e-6f64.ln(), 1e4f64.ln()),
                    Param::StiffnessField => (-100f64.ln(), 100f64.ln()),
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

    /// The gradient with respect to the physical values of [`ParamSet::values`] (for reports
    /// and `gradcheck`): `dJ/dE`, `dJ/dnu`, ..., the ground as `dJ/dn` (free vector) and
    /// `dJ/dheight`.
    pub fn physical(&self, model: &Model, g: &PhysicalGradient) -> Vec<(String, f64)> {
        let mut out = Vec::new();
        let xyz = |name: &str, v: Vec3<f64>| {
            ["x", "y", "z"]
                .iter()
                .zip(v.to_array())
                .map(|(c, v)| (format!("{name}.{c}"), v))
                .collect::<Vec<_>>()
        };
        for p in &self.params {
            match p {
                Param::Young => out.push((p.name().into(), young_poisson_gradient(model, g).0)),
                Param::Poisson => out.push((p.name().into(), young_poisson_gradient(model, g).1)),
                Param::Density => out.push((p.name().into(), g.density)),
                Param::DampingMass => out.push((p.name().into(), g.damping_mass)),
                Param::DampingStiffness => out.push((p.name().into(), g.damping_stiffness)),
                Param::Gravity => out.extend(xyz(p.name(), g.gravity)),
                Param::Ground => {
                    out.extend(xyz("ground.normal", g.ground_normal));
                    out.push(("ground.height".into(), g.ground_height));
                }
                Param::InitialVelocity => out.extend(xyz(p.name(), g.initial_velocity)),
                Param::InitialAngularVelocity => out.extend(xyz(p.name(), g.initial_angular_velocity)),
                Param::StiffnessField => {
                    // per coefficient, at the model's factors (the coefficients are log factors)
                    let labels = self.field.as_ref().map(|f| f.labels()).unwrap_or_default();
                    let gx = ParamSet {
                        params: vec![Param::StiffnessField],
                        field: self.field.clone(),
                    }
                    .chain(model, g);
                    out.extend(labels.into_iter().zip(gx));
                }
                Param::ExternalForce(_) => out.extend(
                    external(model)
                        .labels
                        .iter()
                        .cloned()
                        .zip(external_gradient(model, g)),
                ),
            }
        }
        out
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

/// The model's external force (present: [`ParamSet::check`]).
fn external(model: &Model) -> &cutfem::fem::ExternalForce {
    model.external_force.as_ref().expect("checked")
}

/// `dJ/dc_k` of the model's external force (zeros when no step was taken).
fn external_gradient(model: &Model, g: &PhysicalGradient) -> Vec<f64> {
    let n = external(model).len();
    (0..n)
        .map(|k| g.external.get(k).copied().unwrap_or(0.0))
        .collect()
}

fn v3(s: &[f64]) -> Vec3<f64> {
    Vec3::new(s[0], s[1], s[2])
}

#[cfg(test)]
mod tests;
