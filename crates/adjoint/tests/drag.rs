//! The `drag` effect (linear air drag, `f_i = -c A_i v_i`): its physics against the analytic
//! decay of a body's momentum, its adjoint gradient against central differences of the whole
//! simulation (every other effect on), and its Gauss-Newton matrix against the Hessian at zero
//! residual.

mod common;

use common::{bar_grid, every_effect, momentum, problem};

use adjoint::params::ParamSet;
use cutfem::fem::{Grid, Model, NodalDamping, Simulation};
use cutfem::scene::effects::wind::node_areas;
use gpumat::Vec3;
use std::sync::Arc;

fn grid() -> Grid {
    bar_grid(10.0)
}

fn drag(g: &Grid, c: f64) -> Option<NodalDamping> {
    Some(NodalDamping {
        weights: Arc::new(node_areas(g)),
        coefficient: c,
    })
}

/// Every effect on ([`every_effect`]) and drag `c`.
fn model(c: f64) -> Model {
    Model {
        drag: drag(&grid(), c),
        ..every_effect()
    }
}

/// A free body (no gravity, no clamp, no ground) moving at `v0`: drag is the only external
/// force. Summed over the nodes the internal forces cancel, so each Newmark step changes the
/// momentum `P = sum_i m_i v_i` by exactly the drag's impulse, `P' - P = -c sum_i A_i (u'_i -
/// u_i)` (to the round-off of a stiff solve, 1e-8 of P). A stiff body moves nearly rigidly, `P = m V`, and the trapezoidal rule
/// with `u' - u = dt (theta V' + (1 - theta) V)` then gives `V_n = V_0 r^n`,
/// `r = (1 - (1 - theta) k dt) / (1 + theta k dt)`, `k = c A / m` (`A` the surface area, `m` the
/// mass).
#[test]
fn drag_decays_a_free_body_s_momentum_as_the_analytic_rate() {
    let g = grid();
    let (c, dt) = (0.2, 0.01);
    let m = Model {
        young: 1e7,
        density: 1.0,
        corotation: false,
        initial_velocity: Vec3::new(1.0, 0.5, 0.0),
        drag: drag(&g, c),
        dt,
        ..Model::default()
    };
    let mut sim = Simulation::new(g, m).unwrap();
    sim.solver.direct = true;
    let w = sim.model.drag.as_ref().unwrap().weights.clone();
    let area: f64 = w.iter().sum();
    let mass = sim.total_mass();
    let p0 = momentum(&sim);
    let k = c * area / mass;
    let theta = sim.model.theta;
    let r = (1.0 - (1.0 - theta) * k * dt) / (1.0 + theta * k * dt);
    for n in 1..=40 {
        let (p_before, u_before) = (momentum(&sim), sim.u.clone());
        sim.step().unwrap();
        let p = momentum(&sim);
        let impulse = u_before
            .as_slice()
            .iter()
            .zip(sim.u.as_slice())
            .zip(w.iter())
            .fold(Vec3::default(), |s, ((&a, &b), &wi)| s + (b - a) * (-c * wi));
        let balance = (p - p_before - impulse).norm() / p0.norm();
        assert!(balance < 1e-8, "step {n}: momentum balance off by {balance:.2e}");
        let expected = p0 * r.powi(n);
        let err = (p - expected).norm() / p0.norm();
        assert!(
            err < 1e-6,
            "step {n}: momentum {p:?} vs {expected:?} (rel {err:.2e})"
        );
    }
    // it did decay noticeably
    assert!(r.powi(40) < 0.3, "decay factor {}", r.powi(40));
    // and without drag the momentum is conserved
    let mut free = Simulation::new(
        grid(),
        Model {
            drag: None,
            ..sim.model.clone()
        },
    )
    .unwrap();
    free.solver.direct = true;
    for _ in 0..40 {
        free.step().unwrap();
    }
    let drift = (momentum(&free) - p0).norm() / p0.norm();
    assert!(drift < 1e-8, "momentum drift without drag {drift:.2e}");
}

/// `dJ/dc = sum_t lam_t . W (u_t - u_{t+1})` against central differences, with every other
/// effect on and the other parameters fitted alongside.
#[test]
fn drag_gradient_matches_finite_differences() {
    let mut p = problem(model(0.8), model(0.5), "young,damping_mass,drag");
    let x = p.x0();
    common::assert_gradient_is_the_fd_gradient(&mut p, &x, 1e-6);
    assert_eq!(p.params.labels()[2], "drag");
    assert_eq!(p.params.values(&p.base)[2], ("drag".to_string(), 0.5));
}

/// The tangent-linear pass differentiates the drag through the model: at zero residual the
/// Gauss-Newton matrix equals the finite-difference Hessian.
#[test]
fn drag_gauss_newton_matrix_is_the_hessian_at_zero_residual() {
    let mut p = problem(model(0.8), model(0.8), "young,drag");
    let x = p.x0();
    common::assert_gauss_newton_is_the_fd_hessian(&mut p, &x, 1e-4);
}

/// Fitting `drag` needs the effect in the model; the error says how to switch it on.
#[test]
fn fitting_drag_without_it_names_the_section() {
    let e = ParamSet::parse(&["drag"])
        .unwrap()
        .layout(&Model::default())
        .unwrap_err();
    assert!(e.to_string().contains("[drag]"), "{e}");
}
