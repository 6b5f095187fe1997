//! The `friction` effect (ground friction, `f_c = -mu N_c P v_c` at each contact crossing):
//! its physics against the tangential momentum balance of a sliding block, its adjoint gradient
//! against central differences of the whole simulation (every other effect on), and its
//! Gauss-Newton matrix against the Hessian at zero residual.

mod common;

use common::{bar_grid, every_effect, momentum, problem};

use adjoint::params::ParamSet;
use cutfem::fem::collision::{crossings, ContactScheme, Ground};
use cutfem::fem::{Aabb, Grid, Model, Simulation};
use gpumat::Vec3;

fn grid() -> Grid {
    bar_grid(10.0)
}

fn ground(scheme: ContactScheme) -> Ground {
    Ground {
        normal: Vec3::new(0.0, 1.0, 0.0),
        height: 0.14,
        stiffness: if scheme == ContactScheme::Penalty {
            3e5
        } else {
            1e3
        },
        softness: 60.0,
        scheme,
    }
}

/// Every effect on ([`every_effect`]) with an end-face hold, a faster slide, and friction `mu`.
fn model(mu: f64) -> Model {
    Model {
        dirichlet: vec![Aabb {
            min: [-0.4, 0.0, -0.2],
            max: [-0.299, 0.5, 0.2],
        }],
        initial_velocity: Vec3::new(0.3, -0.3, 0.05),
        friction: Some(mu),
        ..every_effect()
    }
}

/// A free block landing while it slides along x (gravity along -y, the ground's normal +y):
/// the internal forces cancel, gravity and the normal contact forces have no x or z part, so
/// each Newmark step changes the tangential momentum by exactly the friction's impulse,
/// `sum_c -mu N_c P (u'_c - u_c)` with `N_c` each crossing's normal force at the step's start
/// (to 1e-8 of the momentum). The sliding slows; without friction it does not (1e-8).
#[test]
fn friction_s_impulse_is_the_change_of_tangential_momentum() {
    for scheme in [ContactScheme::Implicit, ContactScheme::Penalty] {
        let mu = 2.0;
        let m = Model {
            young: 3000.0,
            density: 1.0,
            corotation: true,
            gravity: Vec3::new(0.0, -10.0, 0.0),
            ground: Some(ground(scheme)),
            initial_velocity: Vec3::new(1.0, -0.3, 0.2),
            friction: Some(mu),
            dt: 0.01,
            ..Model::default()
        };
        let g = grid();
        let cross = crossings(&g);
        let mut sim = Simulation::new(g, m.clone()).unwrap();
        sim.solver.direct = true;
        let tangential = |p: Vec3<f64>| Vec3::new(p.x, 0.0, p.z);
        let p0 = tangential(momentum(&sim));
        let mut largest = 0.0f64;
        for n in 1..=30 {
            let (p, u) = (momentum(&sim), sim.u.clone());
            sim.step().unwrap();
            let (us, un) = (u.as_slice(), sim.u.as_slice());
            let gr = sim.model.ground.unwrap();
            let mut impulse = Vec3::default();
            for c in &cross {
                let (a, b, t) = (c.a as usize, c.b as usize, c.t);
                let ip = |s: &[Vec3<f64>]| s[a] * (1.0 - t) + s[b] * t;
                let x = sim.grid.positions[a] * (1.0 - t) + sim.grid.positions[b] * t + ip(us);
                let normal_force = -gr.spring(c) * gr.law(x.y - gr.height).0;
                impulse = impulse + tangential(ip(un) - ip(us)) * (-mu * normal_force.max(0.0));
            }
            let change = tangential(momentum(&sim) - p);
            let balance = (change - impulse).norm() / p0.norm();
            assert!(
                balance < 1e-8,
                "{scheme:?} step {n}: balance off by {balance:.2e}"
            );
            largest = largest.max(impulse.norm() / p0.norm());
        }
        let slowed = tangential(momentum(&sim)).norm() / p0.norm();
        assert!(
            largest > 1e-3 && slowed < 0.9,
            "{scheme:?}: friction acted ({largest:.2e}, left {slowed:.3})"
        );
        // and without friction the tangential momentum is kept
        let mut free = Simulation::new(grid(), Model { friction: None, ..m }).unwrap();
        free.solver.direct = true;
        for _ in 0..30 {
            free.step().unwrap();
        }
        let drift = (tangential(momentum(&free)) - p0).norm() / p0.norm();
        assert!(
            drift < 1e-8,
            "{scheme:?}: tangential momentum drift without friction {drift:.2e}"
        );
    }
}

/// `dJ/dmu` (per crossing, through the normal force also `dJ/du` and the plane) against
/// central differences, with every other effect on and the ground fitted alongside.
#[test]
fn friction_gradient_matches_finite_differences() {
    let mut p = problem(model(1.5), model(0.8), "young,ground,friction");
    let x = p.x0();
    common::assert_gradient_is_the_fd_gradient(&mut p, &x, 1e-6);
    assert_eq!(p.params.labels()[4], "friction");
    assert_eq!(p.params.values(&p.base)[5], ("friction".to_string(), 0.8));
}

/// The tangent-linear pass differentiates the friction through the model: at zero residual
/// the Gauss-Newton matrix equals the finite-difference Hessian.
#[test]
fn friction_gauss_newton_matrix_is_the_hessian_at_zero_residual() {
    let mut p = problem(model(1.5), model(1.5), "young,friction");
    let x = p.x0();
    common::assert_gauss_newton_is_the_fd_hessian(&mut p, &x, 1e-4);
}

/// Fitting `friction` needs the ground and the effect; a model with friction but no ground is
/// refused.
#[test]
fn fitting_friction_without_it_names_the_section() {
    let e = ParamSet::parse(&["friction"])
        .unwrap()
        .layout(&Model::default())
        .unwrap_err();
    assert!(e.to_string().contains("[friction]"), "{e}");
    let m = Model {
        friction: Some(1.0),
        ..Model::default()
    };
    let Err(e) = Simulation::new(grid(), m) else {
        panic!("friction without a ground is refused")
    };
    assert!(e.to_string().contains("needs the ground"), "{e}");
}
