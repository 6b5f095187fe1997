//! The Cholesky fallback of the step's linear solve (`cutfem::fem::solver`): when CG fails
//! (here: an unreachable tolerance, zero, with a handful of iterations), the step is solved by a
//! sparse Cholesky factorization instead. The fallback must be counted (`StepInfo::fallback`,
//! one more factorization) and give the step that a direct solve (`SolverSettings::direct`)
//! gives, for every preconditioner; without the fallback the step fails with an error.

mod fem_common;
use fem_common::*;

use cutfem::fem::sim::solve;
use cutfem::fem::{Aabb, Model, Preconditioner, Simulation, SolverSettings};
use gpumat::{Mat3, Matrix, SparseMatrix, Vec3};

/// A clamped corotated beam sagging under gravity and swinging from an initial velocity.
fn beam(solver: SolverSettings) -> Simulation {
    let model = Model {
        young: 5.0e3,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        dt: 0.01,
        damping_mass: 0.5,
        initial_velocity: Vec3::new(0.0, -0.5, 0.2),
        dirichlet: vec![Aabb {
            min: [-1.0, -1.0, -1.0],
            max: [0.051, 1.0, 1.0],
        }],
        ..Model::default()
    };
    let mut sim = box_sim([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], 0.05, model);
    sim.solver = solver;
    sim
}

/// Settings whose CG always fails: a relative and absolute tolerance of zero is never met
/// within 3 iterations.
fn failing_cg(preconditioner: Preconditioner, fallback: bool) -> SolverSettings {
    let mut s = SolverSettings {
        preconditioner,
        fallback,
        // every step's CG must run (and fail): no direct solve of the repeated matrix
        reuse_factor: false,
        ..SolverSettings::default()
    };
    s.cg.tolerance = 0.0;
    s.cg.absolute_tolerance = 0.0;
    s.cg.max_iterations = 3;
    s
}

/// Largest difference between two displacement fields relative to the largest entry of `b`.
fn rel_diff(a: &Matrix<Vec3<f64>>, b: &Matrix<Vec3<f64>>) -> f64 {
    let n = a.shape().rows;
    let (mut d, mut m) = (0.0f64, 0.0f64);
    for i in 0..n {
        let (x, y) = (a.get(i, 0, 0), b.get(i, 0, 0));
        for k in 0..3 {
            d = d.max((x.to_array()[k] - y.to_array()[k]).abs());
            m = m.max(y.to_array()[k].abs());
        }
    }
    d / m.max(f64::MIN_POSITIVE)
}

#[test]
fn failing_cg_falls_back_to_cholesky_and_matches_the_direct_step() {
    let steps = 4;
    let direct = SolverSettings {
        direct: true,
        ..SolverSettings::default()
    };
    let mut reference = beam(direct);
    for _ in 0..steps {
        let info = reference.step().expect("direct step");
        assert!(!info.fallback);
        assert_eq!(info.factorizations, 1);
    }
    let max_u = reference.u.ex().cwise_squared_norm().max().sqrt();
    assert!(max_u > 1e-3, "the beam moves: {max_u}");

    for p in Preconditioner::ALL {
        let mut sim = beam(failing_cg(p, true));
        let mut fallbacks = 0;
        for s in 0..steps {
            let info = sim.step().unwrap_or_else(|e| panic!("{p:?} step {s}: {e}"));
            assert!(info.fallback, "{p:?} step {s}: CG was to fail: {info:?}");
            assert!(info.factorizations >= 1, "{p:?} step {s}: {info:?}");
            assert!(
                info.residual < 1e-10,
                "{p:?} step {s}: residual {}",
                info.residual
            );
            fallbacks += usize::from(info.fallback);
        }
        assert_eq!(fallbacks, steps, "{p:?}");
        let du = rel_diff(&sim.u, &reference.u);
        let dv = rel_diff(&sim.v, &reference.v);
        eprintln!("{p:?}: fallback vs direct: u {du:.2e}, v {dv:.2e}");
        assert!(du < 1e-12 && dv < 1e-10, "{p:?}: u {du:e}, v {dv:e}");

        // without the fallback the same failure is an error naming the linear solve
        let mut strict = beam(failing_cg(p, false));
        let e = strict
            .step()
            .expect_err("CG fails without a fallback")
            .to_string();
        assert!(e.contains("linear solve"), "{p:?}: {e}");
    }

    // the default settings converge without the fallback, to the same step within CG's tolerance
    let mut cg = beam(SolverSettings::default());
    for _ in 0..steps {
        assert!(!cg.step().expect("cg step").fallback);
    }
    assert!(rel_diff(&cg.u, &reference.u) < 1e-5);
}

/// A 1D chain of 3x3 blocks, symmetric positive definite (condition number about 400): CG
/// with 2 iterations cannot solve it, the fallback solves it to round-off.
#[test]
fn solve_falls_back_on_a_matrix_cg_cannot_do_in_time() {
    let n = 80;
    let mut t = Vec::new();
    for i in 0..n {
        let d = Mat3::from_rows([[2.01, 0.0, 0.0], [0.0, 2.5, 0.1], [0.0, 0.1, 3.0]]);
        t.push((i, i, d));
        if i + 1 < n {
            t.push((i, i + 1, Mat3::from_scalar(-1.0)));
            t.push((i + 1, i, Mat3::from_scalar(-1.0)));
        }
    }
    let a = SparseMatrix::from_triplets(n, n, &t);
    let mut b = Matrix::<Vec3<f64>>::zeros(n, 1, 1);
    for i in 0..n {
        let s = i as f64;
        b.set(i, 0, 0, Vec3::new(s.sin(), 1.0, (0.3 * s).cos()));
    }
    let mut settings = SolverSettings::default();
    settings.cg.max_iterations = 2;

    let mut x = Matrix::zeros(n, 1, 1);
    let (iterations, residual, fallback) = solve(&a, &b, &mut x, &settings).expect("fallback");
    assert!(fallback, "CG was to fail");
    assert_eq!(iterations, 2);
    assert!(residual < 1e-12, "residual {residual}");

    let direct = SolverSettings {
        direct: true,
        ..SolverSettings::default()
    };
    let mut y = Matrix::zeros(n, 1, 1);
    let (_, _, used) = solve(&a, &b, &mut y, &direct).expect("direct");
    assert!(!used);
    assert!(rel_diff(&x, &y) < 1e-13, "{}", rel_diff(&x, &y));

    settings.fallback = false;
    let e = solve(&a, &b, &mut Matrix::zeros(n, 1, 1), &settings).expect_err("no fallback");
    assert!(e.to_string().contains("did not converge"), "{e}");
}
