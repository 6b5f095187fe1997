//! A [`ParamSet`] checked against a model: its [`Layout`], the only type that maps between the
//! unconstrained coordinates `x` and a model (module docs of [`super`] for the coordinates).
//!
//! [`ParamSet::layout`] checks once that the model has what each parameter needs (a ground
//! plane for `ground`, an external force for `external_force`, a basis for `stiffness_field`)
//! and stores it in the parameter's [`Slot`]: a slot carries the base model's plane and force
//! basis, so writing `x` into a model that lacks them puts the base's back, and no method of a
//! layout can meet a missing part.

use super::DAMPING_FLOOR;
use super::{ground_angles, ground_normal, young_poisson_gradient, FieldBasis, Param, ParamSet};
use crate::backward::PhysicalGradient;
use crate::Error;
use cutfem::fem::{ExternalForce, Ground, Model, NodalDamping};
use gpumat::Vec3;
use std::sync::Arc;

/// One parameter with what it needs from the model it was checked against.
#[derive(Clone, Debug)]
enum Slot {
    Young,
    Poisson,
    Density,
    DampingMass,
    DampingStiffness,
    Gravity,
    /// the base model's plane (its stiffness, softness and scheme are kept when `x` moves it)
    Ground(Ground),
    InitialVelocity,
    InitialAngularVelocity,
    StiffnessField(Arc<FieldBasis>),
    /// the base model's force: its basis fields and labels
    ExternalForce(ExternalForce),
    /// the base model's drag: its nodal weights
    Drag(NodalDamping),
    /// the clamp's springs (the base model's stiffness)
    Clamp(f64),
    /// the ground friction (needs the ground)
    Friction,
}

/// A checked [`ParamSet`] ([`ParamSet::layout`]); it reads as its set (`Deref`).
#[derive(Clone, Debug)]
pub struct Layout {
    set: ParamSet,
    slots: Vec<Slot>,
}

impl std::ops::Deref for Layout {
    type Target = ParamSet;
    fn deref(&self) -> &ParamSet {
        &self.set
    }
}

impl ParamSet {
    /// Checks that `model` has what the parameters need and returns the layout; the external
    /// force's coefficient count is taken from the model.
    pub fn layout(&self, model: &Model) -> Result<Layout, Error> {
        let mut set = self.clone();
        let mut slots = Vec::with_capacity(set.params.len());
        for p in &mut set.params {
            slots.push(match *p {
                Param::Young => Slot::Young,
                Param::Poisson => Slot::Poisson,
                Param::Density => Slot::Density,
                Param::DampingMass => Slot::DampingMass,
                Param::DampingStiffness => Slot::DampingStiffness,
                Param::Gravity => Slot::Gravity,
                Param::Ground => Slot::Ground(model.ground.ok_or_else(|| {
                    Error::invalid("fitting `ground` needs a [ground] section and `ground` in [model].effects")
                })?),
                Param::InitialVelocity => Slot::InitialVelocity,
                Param::InitialAngularVelocity => Slot::InitialAngularVelocity,
                Param::StiffnessField => Slot::StiffnessField(self.field.clone().ok_or_else(|| {
                    Error::invalid(
                        "fitting `stiffness_field` needs its basis ([model].stiffness_field = { cells = [...] })",
                    )
                })?),
                Param::ExternalForce(_) => {
                    let e = model.external_force.clone().ok_or_else(|| {
                        Error::invalid(
                            "fitting `external_force` needs an effect that adds one (e.g. `wind` in \
                             [model].effects with a [wind] section)",
                        )
                    })?;
                    *p = Param::ExternalForce(e.len());
                    Slot::ExternalForce(e)
                }
                Param::Drag => Slot::Drag(model.drag.clone().ok_or_else(|| {
                    Error::invalid("fitting `drag` needs a [drag] section and `drag` in [model].effects")
                })?),
                Param::Friction => {
                    if model.ground.is_none() || model.friction.is_none() {
                        return Err(Error::invalid(
                            "fitting `friction` needs the ground and a [friction] section, both in [model].effects",
                        ));
                    }
                    Slot::Friction
                }
                Param::Clamp => Slot::Clamp(model.support.ok_or_else(|| {
                    Error::invalid("fitting `clamp` needs a [clamp] section and `clamp` in [model].effects")
                })?),
            });
        }
        Ok(Layout { set, slots })
    }
}

impl Layout {
    /// The checked set.
    pub fn set(&self) -> &ParamSet {
        &self.set
    }

    /// The unconstrained coordinates of the model's current values.
    pub fn to_x(&self, model: &Model) -> Vec<f64> {
        let mut x = Vec::new();
        for s in &self.slots {
            match s {
                Slot::Young => x.push(model.young.ln()),
                Slot::Poisson => {
                    let s = 2.0 * model.poisson;
                    x.push((s / (1.0 - s)).ln());
                }
                Slot::Density => x.push(model.density.ln()),
                Slot::DampingMass => x.push(model.damping_mass.max(DAMPING_FLOOR).ln()),
                Slot::DampingStiffness => x.push(model.damping_stiffness.max(DAMPING_FLOOR).ln()),
                Slot::Gravity => x.extend(model.gravity.to_array()),
                Slot::Ground(base) => {
                    let g = model.ground.unwrap_or(*base);
                    let (ax, az) = ground_angles(g.normal);
                    x.extend([ax, az, g.height]);
                }
                Slot::InitialVelocity => x.extend(model.initial_velocity.to_array()),
                Slot::InitialAngularVelocity => x.extend(model.initial_angular_velocity.to_array()),
                // fits start from the homogeneous material (all factors 1)
                Slot::StiffnessField(f) => x.extend(vec![0.0; f.len()]),
                Slot::ExternalForce(base) => x.extend(force(model, base).coefficients.iter().copied()),
                Slot::Drag(base) => x.push(drag(model, base).coefficient.max(DAMPING_FLOOR).ln()),
                Slot::Clamp(base) => x.push(model.support.unwrap_or(*base).ln()),
                Slot::Friction => x.push(model.friction.unwrap_or(0.0).max(DAMPING_FLOOR).ln()),
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
        for s in &self.slots {
            match s {
                Slot::Young => model.young = take(1)[0].exp(),
                Slot::Poisson => model.poisson = 0.5 / (1.0 + (-take(1)[0]).exp()),
                Slot::Density => model.density = take(1)[0].exp(),
                Slot::DampingMass => model.damping_mass = take(1)[0].exp(),
                Slot::DampingStiffness => model.damping_stiffness = take(1)[0].exp(),
                Slot::Gravity => model.gravity = v3(take(3)),
                Slot::Ground(base) => {
                    let s = take(3);
                    let g = model.ground.get_or_insert(*base);
                    g.normal = ground_normal(s[0], s[1]).0;
                    g.height = s[2];
                }
                Slot::InitialVelocity => model.initial_velocity = v3(take(3)),
                Slot::InitialAngularVelocity => model.initial_angular_velocity = v3(take(3)),
                Slot::StiffnessField(f) => model.stiffness_scale = Some(f.scales(take(f.len())).into()),
                Slot::ExternalForce(base) => {
                    let e = model.external_force.get_or_insert_with(|| base.clone());
                    let n = e.len();
                    e.coefficients.copy_from_slice(take(n));
                }
                Slot::Drag(base) => {
                    let c = take(1)[0].exp();
                    model.drag.get_or_insert_with(|| base.clone()).coefficient = c;
                }
                Slot::Clamp(_) => model.support = Some(take(1)[0].exp()),
                Slot::Friction => model.friction = Some(take(1)[0].exp()),
            }
        }
    }

    /// The physical values, labelled (e.g. `young`, `gravity.y`, `ground.normal.x`).
    pub fn values(&self, model: &Model) -> Vec<(String, f64)> {
        let mut out = Vec::new();
        for (s, p) in self.slots.iter().zip(&self.set.params) {
            let name = || p.name().to_string();
            match s {
                Slot::Young => out.push((name(), model.young)),
                Slot::Poisson => out.push((name(), model.poisson)),
                Slot::Density => out.push((name(), model.density)),
                Slot::DampingMass => out.push((name(), model.damping_mass)),
                Slot::DampingStiffness => out.push((name(), model.damping_stiffness)),
                Slot::Gravity => out.extend(xyz(p.name(), model.gravity)),
                Slot::Ground(base) => {
                    let g = model.ground.unwrap_or(*base);
                    out.extend(xyz("ground.normal", g.normal));
                    out.push(("ground.height".into(), g.height));
                }
                Slot::InitialVelocity => out.extend(xyz(p.name(), model.initial_velocity)),
                Slot::InitialAngularVelocity => out.extend(xyz(p.name(), model.initial_angular_velocity)),
                Slot::StiffnessField(_) => {
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
                Slot::Drag(base) => out.push((name(), drag(model, base).coefficient)),
                Slot::Clamp(base) => out.push((name(), model.support.unwrap_or(*base))),
                Slot::Friction => out.push((name(), model.friction.unwrap_or(0.0))),
                Slot::ExternalForce(base) => {
                    let e = force(model, base);
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
        for s in &self.slots {
            match s {
                Slot::Young => out.push(young_poisson_gradient(model, g).0 * e),
                Slot::Poisson => out.push(young_poisson_gradient(model, g).1 * nu * (1.0 - 2.0 * nu)),
                Slot::Density => out.push(g.density * model.density),
                Slot::DampingMass => out.push(g.damping_mass * model.damping_mass),
                Slot::DampingStiffness => out.push(g.damping_stiffness * model.damping_stiffness),
                Slot::Gravity => out.extend(g.gravity.to_array()),
                Slot::Ground(base) => {
                    let (ax, az) = ground_angles(model.ground.unwrap_or(*base).normal);
                    let (_, dx, dz) = ground_normal(ax, az);
                    out.extend([g.ground_normal.dot(dx), g.ground_normal.dot(dz), g.ground_height]);
                }
                Slot::InitialVelocity => out.extend(g.initial_velocity.to_array()),
                Slot::InitialAngularVelocity => out.extend(g.initial_angular_velocity.to_array()),
                Slot::StiffnessField(f) => out.extend(field_chain(f, model, g)),
                Slot::ExternalForce(base) => out.extend(force_gradient(base, g)),
                Slot::Drag(base) => out.push(g.drag * drag(model, base).coefficient),
                Slot::Clamp(base) => out.push(g.support * model.support.unwrap_or(*base)),
                Slot::Friction => out.push(g.friction * model.friction.unwrap_or(0.0)),
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
        for s in &self.slots {
            match s {
                Slot::Young => out.push(model.young),
                Slot::Poisson => out.push(model.poisson * (1.0 - 2.0 * model.poisson)),
                Slot::Density => out.push(model.density),
                Slot::DampingMass => out.push(model.damping_mass),
                Slot::DampingStiffness => out.push(model.damping_stiffness),
                Slot::Gravity | Slot::Ground(_) | Slot::InitialVelocity | Slot::InitialAngularVelocity => {
                    out.extend([1.0; 3])
                }
                Slot::StiffnessField(f) => out.extend(vec![1.0; f.len()]),
                Slot::ExternalForce(base) => out.extend(vec![1.0; base.len()]),
                Slot::Drag(base) => out.push(drag(model, base).coefficient),
                Slot::Clamp(base) => out.push(model.support.unwrap_or(*base)),
                Slot::Friction => out.push(model.friction.unwrap_or(0.0)),
            }
        }
        out
    }

    /// The gradient with respect to the physical values of [`Layout::values`] (for reports
    /// and `gradcheck`): `dJ/dE`, `dJ/dnu`, ..., the ground as `dJ/dn` (free vector) and
    /// `dJ/dheight`.
    pub fn physical(&self, model: &Model, g: &PhysicalGradient) -> Vec<(String, f64)> {
        let mut out = Vec::new();
        for (s, p) in self.slots.iter().zip(&self.set.params) {
            let name = || p.name().to_string();
            match s {
                Slot::Young => out.push((name(), young_poisson_gradient(model, g).0)),
                Slot::Poisson => out.push((name(), young_poisson_gradient(model, g).1)),
                Slot::Density => out.push((name(), g.density)),
                Slot::DampingMass => out.push((name(), g.damping_mass)),
                Slot::DampingStiffness => out.push((name(), g.damping_stiffness)),
                Slot::Gravity => out.extend(xyz(p.name(), g.gravity)),
                Slot::Ground(_) => {
                    out.extend(xyz("ground.normal", g.ground_normal));
                    out.push(("ground.height".into(), g.ground_height));
                }
                Slot::InitialVelocity => out.extend(xyz(p.name(), g.initial_velocity)),
                Slot::InitialAngularVelocity => out.extend(xyz(p.name(), g.initial_angular_velocity)),
                // per coefficient, at the model's factors (the coefficients are log factors)
                Slot::StiffnessField(f) => out.extend(f.labels().into_iter().zip(field_chain(f, model, g))),
                Slot::ExternalForce(base) => {
                    out.extend(base.labels.iter().cloned().zip(force_gradient(base, g)))
                }
                Slot::Drag(_) => out.push((name(), g.drag)),
                Slot::Clamp(_) => out.push((name(), g.support)),
                Slot::Friction => out.push((name(), g.friction)),
            }
        }
        out
    }
}

/// The model's external force, or the base's when the model has none.
fn force<'a>(model: &'a Model, base: &'a ExternalForce) -> &'a ExternalForce {
    model.external_force.as_ref().unwrap_or(base)
}

/// The model's drag, or the base's when the model has none.
fn drag<'a>(model: &'a Model, base: &'a NodalDamping) -> &'a NodalDamping {
    model.drag.as_ref().unwrap_or(base)
}

/// `dJ/dc_k` of the external force (zeros when no step was taken).
fn force_gradient(base: &ExternalForce, g: &PhysicalGradient) -> Vec<f64> {
    (0..base.len())
        .map(|k| g.external.get(k).copied().unwrap_or(0.0))
        .collect()
}

/// The field's log-factor gradient at the model's factors (all 1 when it has none).
fn field_chain(f: &FieldBasis, model: &Model, g: &PhysicalGradient) -> Vec<f64> {
    let ones;
    let s = match model.stiffness_scale.as_deref() {
        Some(s) => s,
        None => {
            ones = vec![1.0; f.weights.len()];
            &ones
        }
    };
    f.chain(s, &g.cell_scale)
}

/// `name.x`, `name.y`, `name.z` with the components of `v`.
fn xyz(name: &str, v: Vec3<f64>) -> Vec<(String, f64)> {
    ["x", "y", "z"]
        .iter()
        .zip(v.to_array())
        .map(|(c, v)| (format!("{name}.{c}"), v))
        .collect()
}

fn v3(s: &[f64]) -> Vec3<f64> {
    Vec3::new(s[0], s[1], s[2])
}
