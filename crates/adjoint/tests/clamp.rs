//! The `clamp` effect (an imperfect clamp: springs `-k P u`, `P_ij = int N_i N_j` over the held
//! surface, in place of the rigid Nitsche hold): its physics against the momentum balance of a step and the
//! static force balance, its limit `k -> infinity` against the rigid hold, its adjoint gradient
//! against central differences of the whole simulation (every other effect on), and its
//! Gauss-Newton matrix against the Hessian at zero residual.

mod common;

use common::{bar_grid as grid, every_effect, momentum, problem};

use adjoint::params::ParamSet;
use cutfem::fem::{Aabb, Model, NodalDamping, Simulation};
use cutfem::scene::effects::wind::node_areas;
use gpumat::Vec3;
use std::sync::Arc;

/// Holds the bar's end face at x = -0.3 (its sides only along a sliver 1e-7 wide: a held sliver of side surface pins its cell's far corners as the springs stiffen).
fn hold() -> Vec<Aabb> {
    vec![Aabb {
        min: [-0.4, 0.0, -0.2],
        max: [-0.2999999, 0.5, 0.2],
    }]
}

/// The summed force of the springs `k P` on the displacement `u`: `sum_i (k P u)_i`, from the
/// held cells' faces (independent of the assembly).
fn spring_force(sim: &Simulation, k: f64, u: &[Vec3<f64>]) -> Vec3<f64> {
    let mut f = Vec3::default();
    for (c, face) in sim.grid.cells.iter().zip(&sim.dirichlet) {
        let Some(face) = face else { continue };
        for i in 0..8 {
            for j in 0..8 {
                f = f + face.block(i, j, 0.0, 0.0, k) * u[c.dofs[j] as usize];
            }
        }
    }
    f
}

/// Every effect on ([`every_effect`]) with the end-face hold, drag, and the clamp with
/// stiffness `k`.
fn model(k: f64) -> Model {
    Model {
        dirichlet: hold(),
        drag: Some(NodalDamping {
            weights: Arc::new(node_areas(&grid(10.0))),
            coefficient: 0.3,
        }),
        support: Some(k),
        ..every_effect()
    }
}

/// Summed over the nodes the elastic forces cancel (corotated or not), so each Newmark step
/// changes the momentum `P = sum_i m_i v_i` by the impulse of gravity and of the springs alone:
/// `P' - P = dt M g - sum_i (k P (a2 (u' - u) + dt (theta u' + (1 - theta) u)))_i`
/// (Rayleigh's `a2` damps the springs as part of the stiffness). Held rigidly instead, the
/// Nitsche terms take the reaction and the balance does not close.
#[test]
fn the_springs_impulse_closes_the_momentum_balance() {
    let g = grid(10.0);
    let (k, dt, a2) = (4e4, 0.01, 0.005);
    let base = Model {
        young: 3000.0,
        poisson: 0.3,
        density: 1.0,
        damping_stiffness: a2,
        corotation: true,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        dirichlet: hold(),
        initial_angular_velocity: Vec3::new(0.0, 0.0, 1.0),
        dt,
        ..Model::default()
    };
    let m = Model {
        support: Some(k),
        ..base.clone()
    };
    let mut sim = Simulation::new(g, m).unwrap();
    sim.solver.direct = true;
    let theta = sim.model.theta;
    let weight = Vec3::new(0.0, -10.0, 0.0) * (sim.total_mass() * dt);
    let mut moved = 0.0f64;
    for n in 1..=30 {
        let (p, u) = (momentum(&sim), sim.u.clone());
        sim.step().unwrap();
        let at: Vec<Vec3<f64>> = u
            .as_slice()
            .iter()
            .zip(sim.u.as_slice())
            .map(|(&a, &b)| (b - a) * a2 + (b * theta + a * (1.0 - theta)) * dt)
            .collect();
        let spring = spring_force(&sim, -k, &at);
        let balance = (momentum(&sim) - p - weight - spring).norm() / weight.norm();
        assert!(
            balance < 1e-8,
            "step {n}: momentum balance off by {balance:.2e} of dt M g"
        );
        moved = moved.max(spring.norm() / weight.norm());
    }
    // the springs carried a real share of the load
    assert!(moved > 0.5, "largest spring impulse {moved} of dt M g");
    // held rigidly, the same bookkeeping misses the reaction
    let mut rigid = Simulation::new(grid(10.0), base).unwrap();
    rigid.solver.direct = true;
    let p = momentum(&rigid);
    rigid.step().unwrap();
    let off = (momentum(&rigid) - p - weight).norm() / weight.norm();
    assert!(
        off > 0.1,
        "a rigid hold's reaction is not in the balance: {off:.2e}"
    );
}

/// The static bar hanging from its springs: the springs carry the whole weight,
/// `sum_i (k P u)_i = M g` (summed, `K` drops out). As `k -> infinity` the springs converge
/// to a hold (each tenfold stiffer spring moves the tip about ten times less: the penalty's
/// `O(1/k)`), and that hold is the rigid Nitsche hold up to the discretisation (the gap
/// shrinks under refinement).
#[test]
fn the_springs_carry_the_weight_and_tend_to_the_rigid_hold() {
    let base = Model {
        young: 3000.0,
        poisson: 0.3,
        density: 1.0,
        corotation: false,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        dirichlet: hold(),
        ..Model::default()
    };
    let tip = |s: &Simulation| -> f64 {
        let (mut sum, mut n) = (0.0, 0.0);
        for (p, u) in s.grid.positions.iter().zip(s.u.as_slice()) {
            if p.x > 0.3 - 1e-9 {
                sum += u.y;
                n += 1.0;
            }
        }
        sum / n
    };
    let (lambda, mu) = base.lame();
    let mut gaps = Vec::new();
    for resolution in [10.0, 20.0] {
        let mut rigid = Simulation::new(grid(resolution), base.clone()).unwrap();
        rigid.solver.direct = true;
        rigid.solve_static().unwrap();
        let rigid_tip = tip(&rigid);
        assert!(rigid_tip < -1e-3, "the bar bends: tip {rigid_tip}");
        let h = grid(resolution).h();
        let mut tips = Vec::new();
        for factor in [1e1, 1e2, 1e3, 1e4, 1e5] {
            let k = factor * (lambda + 2.0 * mu) / h;
            let m = Model {
                support: Some(k),
                ..base.clone()
            };
            let mut sim = Simulation::new(grid(resolution), m).unwrap();
            sim.solver.direct = true;
            sim.solve_static().unwrap();
            let carried = spring_force(&sim, k, sim.u.as_slice());
            let weight = Vec3::new(0.0, -10.0, 0.0) * sim.total_mass();
            let balance = (carried - weight).norm() / weight.norm();
            assert!(
                balance < 1e-8,
                "k = {factor}: springs carry {carried:?} of {weight:?}"
            );
            tips.push(tip(&sim));
        }
        println!("resolution {resolution}: rigid tip {rigid_tip:.5e}, springs {tips:?}");
        let steps: Vec<f64> = tips.windows(2).map(|t| (t[1] - t[0]).abs()).collect();
        for s in steps.windows(2) {
            assert!(s[1] < 0.2 * s[0], "resolution {resolution}: steps {steps:?}");
        }
        gaps.push((tips[4] - rigid_tip).abs() / rigid_tip.abs());
    }
    println!("gap of the stiffest springs to the rigid hold: {gaps:?}");
    assert!(gaps[1] < 0.6 * gaps[0] && gaps[1] < 0.1, "gaps {gaps:?}");
}

/// `dJ/dk = sum_t lam_t^T P (cu u_t - ck u_{t+1})` against central differences, with every
/// other effect on (Rayleigh's `a2` fitted alongside: it damps the springs too).
#[test]
fn clamp_gradient_matches_finite_differences() {
    let mut p = problem(model(2e4), model(6e4), "young,damping_stiffness,clamp");
    let x = p.x0();
    common::assert_gradient_is_the_fd_gradient(&mut p, &x, 1e-6);
    assert_eq!(p.params.labels()[2], "clamp");
    assert_eq!(p.params.values(&p.base)[2], ("clamp".to_string(), 6e4));
}

/// The tangent-linear pass differentiates the springs through the model: at zero residual the
/// Gauss-Newton matrix equals the finite-difference Hessian.
#[test]
fn clamp_gauss_newton_matrix_is_the_hessian_at_zero_residual() {
    let mut p = problem(model(2e4), model(2e4), "young,clamp");
    let x = p.x0();
    common::assert_gauss_newton_is_the_fd_hessian(&mut p, &x, 1e-4);
}

/// Fitting `clamp` needs the effect in the model; the error says how to switch it on. A
/// support without a held region is refused.
#[test]
fn fitting_clamp_without_it_names_the_section() {
    let e = ParamSet::parse(&["clamp"])
        .unwrap()
        .layout(&Model::default())
        .unwrap_err();
    assert!(e.to_string().contains("[clamp]"), "{e}");
    let g = grid(10.0);
    let m = Model {
        support: Some(1.0),
        ..Model::default()
    };
    let Err(e) = Simulation::new(g, m) else {
        panic!("a support without a held region is refused")
    };
    let e = e.to_string();
    assert!(e.contains("clamp") && e.contains("[[dirichlet]]"), "{e}");
}
