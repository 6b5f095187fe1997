//! Whether a model's physical parameters can be simulated in `f64` at all, checked before the
//! first step, naming the key at fault (a step that fails on a singular or non-finite block
//! names no key).
//!
//! # The scales
//!
//! One node of a cell of size `h` carries, in the Newmark matrix `A` (force per displacement),
//! a diagonal of the scale
//!
//! `D = rho h^3 / (theta dt)^2 + (alpha rho h^3 + beta k) / (theta dt) + k + k_ground`,
//! `k = (lambda + 2 mu) s_max h`
//!
//! (lumped mass, Rayleigh damping `alpha`, `beta`, the stiffest P-wave modulus with the
//! stiffness field's largest factor `s_max`, a ground spring `k_ground`). The solver inverts
//! 3x3 blocks of `A` through products of three entries and the conjugate gradients square
//! residuals of the size `D u`; so `D` must lie within [`MIN_SCALE`]`..=`[`MAX_SCALE`]
//! (1e-100..1e100, leaving the cube inside `f64`'s 1e-308..1.8e308).
//!
//! The displacement of one step, `s = |v| dt + |omega| L dt + |g| dt^2` (initial velocity,
//! angular velocity over the body's extent `L`, gravity), must stay below
//! [`MAX_STEP_EXTENTS`] body extents: a body that moves a million of its sizes in one step is
//! not an experiment (and `D s` would overflow long before `s` does).
//!
//! # Naming the key
//!
//! Each term is a product of parameters with exponents (`rho^1 dt^-2` for the mass term). When
//! `D` is too large the largest term is at fault, and within it the parameter that
//! contributes the most decades upward (`exponent * log10(value)` largest); when too small,
//! the most decades downward. `time.dt = 1e-320` thus names `time.dt` (it contributes 640
//! decades to the mass term), `material.young = 1e308` names `material.young`.

use super::model::Model;
use crate::error::Error;

/// The largest scale of the Newmark matrix's diagonal (module docs).
pub const MAX_SCALE: f64 = 1e100;
/// The smallest scale of the Newmark matrix's diagonal (module docs).
pub const MIN_SCALE: f64 = 1e-100;
/// The most body extents one step may move the body (module docs).
pub const MAX_STEP_EXTENTS: f64 = 1e6;

/// One term of a scale: its value and the parameters it is a product of
/// `(key, value, exponent)`.
#[derive(Clone, Debug)]
struct Term {
    what: &'static str,
    value: f64,
    factors: Vec<(&'static str, f64, f64)>,
}

impl Term {
    /// The factor contributing the most decades up (`up`) or down.
    fn culprit(&self, up: bool) -> (&'static str, f64) {
        let decades = |&(_, v, e): &(&str, f64, f64)| e * v.abs().log10();
        let f = self
            .factors
            .iter()
            .filter(|f| f.1 != 0.0)
            .max_by(|a, b| {
                let (a, b) = (decades(a), decades(b));
                if up {
                    a.total_cmp(&b)
                } else {
                    b.total_cmp(&a)
                }
            })
            .or(self.factors.first())
            .expect("a term has factors");
        (f.0, f.1)
    }
}

/// The terms of the diagonal scale `D` and of the step displacement `s` (module docs).
fn terms(m: &Model, h: f64, extent: f64) -> (Vec<Term>, Vec<Term>) {
    let (dt, theta) = (m.dt, m.theta);
    let (lambda, mu) = m.lame();
    let s_max = m
        .stiffness_scale
        .as_ref()
        .map_or(1.0, |s| s.iter().fold(0.0f64, |a, &b| a.max(b)));
    let p_modulus = (lambda + 2.0 * mu) * s_max;
    let nu_factor = if m.young > 0.0 {
        (lambda + 2.0 * mu) / m.young
    } else {
        1.0
    };
    let mass = m.density * h * h * h;
    let td = theta * dt;
    let young = ("material.young", m.young, 1.0);
    let field = ("model.stiffness_field", s_max, 1.0);
    let poisson = ("material.poisson", nu_factor, 1.0);
    let density = ("material.density", m.density, 1.0);
    let mut d = vec![
        Term {
            what: "mass term rho h^3 / (theta dt)^2",
            value: mass / (td * td),
            factors: vec![density, ("time.dt", dt, -2.0)],
        },
        Term {
            what: "stiffness term (lambda + 2 mu) h",
            value: p_modulus * h,
            factors: vec![young, poisson, field],
        },
    ];
    if m.damping_mass > 0.0 {
        d.push(Term {
            what: "mass damping term alpha rho h^3 / (theta dt)",
            value: m.damping_mass * mass / td,
            factors: vec![
                ("damping.mass", m.damping_mass, 1.0),
                density,
                ("time.dt", dt, -1.0),
            ],
        });
    }
    if m.damping_stiffness > 0.0 {
        d.push(Term {
            what: "stiffness damping term beta (lambda + 2 mu) h / (theta dt)",
            value: m.damping_stiffness * p_modulus * h / td,
            factors: vec![
                ("damping.stiffness", m.damping_stiffness, 1.0),
                young,
                ("time.dt", dt, -1.0),
            ],
        });
    }
    if let Some(g) = &m.ground {
        d.push(Term {
            what: "ground spring",
            value: g.stiffness,
            factors: vec![("ground.stiffness", g.stiffness, 1.0)],
        });
    }
    let norm = |v: gpumat::Vec3<f64>| {
        // without overflow of the squares
        let [x, y, z] = v.to_array();
        x.hypot(y).hypot(z)
    };
    let (v, w, g) = (
        norm(m.initial_velocity),
        norm(m.initial_angular_velocity),
        norm(m.gravity),
    );
    let s = vec![
        Term {
            what: "initial velocity times dt",
            value: v * dt,
            factors: vec![("initial.velocity", v, 1.0), ("time.dt", dt, 1.0)],
        },
        Term {
            what: "angular velocity times the extent times dt",
            value: w * extent * dt,
            factors: vec![("initial.angular_velocity", w, 1.0), ("time.dt", dt, 1.0)],
        },
        Term {
            what: "gravity times dt^2",
            value: g * dt * dt,
            factors: vec![("gravity.acceleration", g, 1.0), ("time.dt", dt, 2.0)],
        },
    ];
    (d, s)
}

fn total(terms: &[Term]) -> f64 {
    terms.iter().map(|t| t.value).sum()
}

fn largest(terms: &[Term]) -> &Term {
    terms
        .iter()
        .max_by(|a, b| a.value.total_cmp(&b.value))
        .expect("terms")
}

impl Model {
    /// Errors, naming the key at fault, when the model cannot be simulated in `f64` on cells
    /// of size `h` for a body of extent `extent` (module docs).
    pub fn check_plausible(&self, h: f64, extent: f64) -> Result<(), Error> {
        let (d, s) = terms(self, h, extent);
        let big = largest(&d);
        let dv = total(&d);
        let bad = |key: &str, value: f64, why: String| {
            Err(Error::Invalid(format!(
                "{key}: {value:e} is far outside what can be simulated: {why}"
            )))
        };
        if dv.is_nan() || dv > MAX_SCALE {
            let (key, value) = big.culprit(true);
            return bad(
                key,
                value,
                format!(
                    "the Newmark matrix's diagonal would be {dv:e} per node ({} {:e}), above {MAX_SCALE:e} \
                     (its 3x3 blocks are inverted through their cubes)",
                    big.what, big.value
                ),
            );
        }
        if dv < MIN_SCALE {
            let (key, value) = big.culprit(false);
            return bad(
                key,
                value,
                format!(
                    "the Newmark matrix's diagonal would be {dv:e} per node ({} {:e}), below {MIN_SCALE:e} \
                     (its 3x3 blocks are inverted through their cubes)",
                    big.what, big.value
                ),
            );
        }
        let sv = total(&s);
        let limit = MAX_STEP_EXTENTS * extent;
        if sv.is_nan() || sv > limit {
            let t = largest(&s);
            let (key, value) = t.culprit(true);
            return bad(
                key,
                value,
                format!(
                    "one step of {:e} would move the body {sv:e} ({} {:e}), more than {MAX_STEP_EXTENTS:e} \
                     times its extent {extent:e}",
                    self.dt, t.what, t.value
                ),
            );
        }
        Ok(())
    }

    /// The scales of the model (module docs) and the parameter that dominates each, for an
    /// error of a step that failed: `"Newmark diagonal 3e95 per node (largest: material.young
    /// = 1e95), displacement per step 1e-3 (largest: gravity.acceleration = 9.8)"`.
    pub fn scales_note(&self, h: f64, extent: f64) -> String {
        let (d, s) = terms(self, h, extent);
        let (dk, dv) = largest(&d).culprit(true);
        let (sk, sv) = largest(&s).culprit(true);
        format!(
            "scales of the model: Newmark diagonal {:.3e} per node (largest: {dk} = {dv:e}), \
             displacement per step {:.3e} (largest: {sk} = {sv:e})",
            total(&d),
            total(&s)
        )
    }
}

/// The diagonal of the bounding box of the grid's nodes (the body's extent, for
/// [`Model::check_plausible`]).
pub fn extent(grid: &super::grid::Grid) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &grid.positions {
        for (d, x) in p.to_array().into_iter().enumerate() {
            lo[d] = lo[d].min(x);
            hi[d] = hi[d].max(x);
        }
    }
    let e = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
    if e.is_finite() && e > 0.0 {
        e
    } else {
        grid.h()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::Ground;
    use gpumat::Vec3;

    fn model() -> Model {
        Model {
            young: 2000.0,
            poisson: 0.3,
            density: 1.0,
            gravity: Vec3::new(0.0, -10.0, 0.0),
            dt: 0.01,
            ..Model::default()
        }
    }

    fn err(m: &Model) -> String {
        m.check_plausible(0.1, 1.0).unwrap_err().to_string()
    }

    #[test]
    fn plausible_models_pass() {
        model().check_plausible(0.1, 1.0).unwrap();
        let mut m = model();
        m.young = 1e12;
        m.density = 8000.0;
        m.dt = 1e-6;
        m.check_plausible(0.01, 1.0).unwrap();
    }

    #[test]
    fn the_parameter_at_fault_is_named() {
        let mut m = model();
        m.young = 1e308;
        assert!(
            err(&m).starts_with("material.young: 1e308 is far outside"),
            "{}",
            err(&m)
        );
        let mut m = model();
        m.dt = 1e-320;
        assert!(
            err(&m).starts_with("time.dt: 1e-320 is far outside"),
            "{}",
            err(&m)
        );
        let mut m = model();
        m.density = 1e250;
        assert!(err(&m).starts_with("material.density: 1e250"), "{}", err(&m));
        let mut m = model();
        m.ground = Some(Ground {
            normal: Vec3::new(0.0, 1.0, 0.0),
            height: 0.0,
            stiffness: 1e308,
            softness: 100.0,
            scheme: crate::fem::collision::ContactScheme::Implicit,
        });
        assert!(err(&m).starts_with("ground.stiffness: 1e308"), "{}", err(&m));
        let mut m = model();
        m.initial_velocity = Vec3::new(1e308, 0.0, 0.0);
        assert!(err(&m).starts_with("initial.velocity: 1e308"), "{}", err(&m));
        let mut m = model();
        m.gravity = Vec3::new(0.0, -1e300, 0.0);
        assert!(err(&m).starts_with("gravity.acceleration: 1e300"), "{}", err(&m));
        let mut m = model();
        m.young = 1e-300;
        m.density = 1e-300;
        assert!(err(&m).contains("below 1e-100"), "{}", err(&m));
        assert!(m.scales_note(0.1, 1.0).contains("Newmark diagonal"));
    }
}
