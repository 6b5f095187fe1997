//! `Problem::gauss_newton` replays the gradient's forward run in its tangent-linear pass
//! (`Simulation::replay_substep`) instead of stepping again: its cost, gradient and
//! Gauss-Newton matrix equal, to the bit, the separate `gradient` and `gauss_newton_matrix`
//! (which steps itself), with the default iterative solver and its repeated-matrix rule, on a
//! linear model (one matrix every step: factored and solved directly), a corotated one with
//! each contact scheme (a new matrix every step; the penalty contact's Newton iterations) and
//! the `rest_cholesky` solver (which is not replayed).

mod common;

use adjoint::problem::Problem;
use cutfem::fem::collision::ContactScheme;
use cutfem::fem::{Model, Preconditioner};

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The problem of [`common::problem`] with the default solver (not the direct one), fitted
/// from a stiffer, less compressible start.
fn iterative(truth: Model, params: &str, preconditioner: Preconditioner) -> Problem {
    let mut start = truth.clone();
    start.young *= 1.3;
    start.poisson = 0.25;
    let mut p = common::problem(truth, start, params);
    p.sim.solver.direct = false;
    p.sim.solver.preconditioner = preconditioner;
    p
}

fn assert_replay_is_exact(name: &str, mut p: Problem) {
    let x = p.x0();
    let (ev, g, h) = p.gauss_newton(&x).unwrap();
    let (ev_ref, g_ref, _) = p.gradient(&x).unwrap();
    let h_ref = p.gauss_newton_matrix(&x).unwrap();
    assert!(h.iter().any(|&v| v != 0.0), "{name}: H = 0");
    assert_eq!(ev.cost.to_bits(), ev_ref.cost.to_bits(), "{name}: cost");
    assert_eq!(bits(&g), bits(&g_ref), "{name}: gradient {g:?} vs {g_ref:?}");
    assert_eq!(bits(&h), bits(&h_ref), "{name}: H {h:?} vs {h_ref:?}");
    // the evaluation carries its matrix (the standard errors at a fit's result use it)
    assert_eq!(ev.gauss_newton.as_deref().map(bits), Some(bits(&h)), "{name}");
    assert!(ev_ref.gauss_newton.is_none());
}

#[test]
fn linear_model_without_contact() {
    let truth = Model {
        ground: None,
        corotation: false,
        initial_velocity: Default::default(),
        initial_angular_velocity: Default::default(),
        ..common::every_effect()
    };
    assert_replay_is_exact(
        "linear",
        iterative(truth, "young,poisson", Preconditioner::BlockIc0),
    );
}

#[test]
fn corotated_model_with_each_contact_scheme() {
    for scheme in [
        ContactScheme::Implicit,
        ContactScheme::Thesis,
        ContactScheme::Penalty,
        ContactScheme::Softmin,
    ] {
        let mut truth = common::every_effect();
        truth.corotation = true;
        let ground = truth.ground.as_mut().unwrap();
        ground.scheme = scheme;
        if scheme == ContactScheme::Penalty {
            (ground.stiffness, ground.softness) = (1e5, 1e5);
        }
        if scheme == ContactScheme::Softmin {
            // per unit area: about the other schemes' springs per crossing
            ground.stiffness /= 0.01;
        }
        assert_replay_is_exact(
            &format!("{scheme:?}"),
            iterative(truth, "young,poisson,ground", Preconditioner::BlockIc0),
        );
    }
}

#[test]
fn rest_cholesky_not_replayed_and_block_jacobi() {
    for pre in [Preconditioner::RestCholesky, Preconditioner::BlockJacobi] {
        assert_replay_is_exact(
            &format!("{pre:?}"),
            iterative(common::every_effect(), "young,poisson", pre),
        );
    }
}
