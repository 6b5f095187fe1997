//! The preconditioners of the step's linear solve (`[numerics] preconditioner`): block IC(0)
//! and the reused rest-state Cholesky factor give the block-Jacobi trajectory within the CG
//! tolerance with fewer iterations, on the cuboid held at one end and on the ground; the
//! rest-state factor is made once and redone by the refactor rule, when the pattern changes
//! and on a reset; the scene key parses and rejects unknown names in one line.

mod fem_common;

use cutfem::fem::solver::{solve, LinearSolver, MAX_REUSED_FACTOR, MIN_SOLVES_AHEAD};
use cutfem::fem::{Grid, Model, Preconditioner, Simulation, SolverSettings};
use cutfem::scene::Scene;
use fem_common::{thesis_cuboid_grid, SMALL_BOX_SCENE};
use gpumat::{Mat3, Matrix, SparseMatrix, Vec3};
use std::path::Path;

struct Run {
    u: Matrix<Vec3<f64>>,
    iterations: Vec<usize>,
    factorizations: Vec<usize>,
    total_factorizations: usize,
}

fn run(grid: &Grid, model: &Model, settings: SolverSettings, steps: usize) -> Run {
    let mut sim = Simulation::new(grid.clone(), model.clone()).unwrap();
    sim.solver = settings;
    let (mut iterations, mut factorizations) = (Vec::new(), Vec::new());
    for _ in 0..steps {
        let info = sim.step().unwrap();
        assert!(!info.fallback, "{:?}: CG fell back", settings.preconditioner);
        assert!(
            !info.substituted,
            "{:?}: block-Jacobi stood in",
            settings.preconditioner
        );
        assert!(info.factor_s <= info.solve_s);
        iterations.push(info.iterations);
        factorizations.push(info.factorizations);
    }
    Run {
        total_factorizations: sim.factorizations(),
        u: sim.u,
        iterations,
        factorizations,
    }
}

fn settings(p: Preconditioner) -> SolverSettings {
    let mut s = SolverSettings {
        preconditioner: p,
        // these tests measure CG with each preconditioner (a linear model's matrix repeats)
        reuse_factor: false,
        ..SolverSettings::default()
    };
    s.cg.tolerance = 1e-9;
    s
}

fn relative_difference(a: &Matrix<Vec3<f64>>, b: &Matrix<Vec3<f64>>) -> f64 {
    Matrix::eval(a.ex() - b.ex()).ex().norm() / b.ex().norm()
}

#[test]
fn preconditioners_agree_with_block_jacobi_in_fewer_iterations() {
    let steps = 8;
    for ground in [false, true] {
        let (grid, model) = thesis_cuboid_grid(5.0, ground);
        let bj = run(&grid, &model, settings(Preconditioner::BlockJacobi), steps);
        assert_eq!(bj.total_factorizations, 0);
        assert!(bj.factorizations.iter().all(|&f| f == 0));
        let mean = |r: &Run| r.iterations.iter().sum::<usize>() as f64 / steps as f64;
        for p in [Preconditioner::BlockIc0, Preconditioner::RestCholesky] {
            let other = run(&grid, &model, settings(p), steps);
            let d = relative_difference(&other.u, &bj.u);
            assert!(d < 1e-6, "{p:?} (ground {ground}): displacement differs by {d:e}");
            assert!(
                2.0 * mean(&other) < mean(&bj),
                "{p:?} (ground {ground}): {:?} iterations vs block-Jacobi {:?}",
                other.iterations,
                bj.iterations
            );
            assert_eq!(
                other.factorizations.iter().sum::<usize>(),
                other.total_factorizations
            );
            match p {
                // a fresh IC(0) every step
                Preconditioner::BlockIc0 => assert!(other.factorizations.iter().all(|&f| f == 1)),
                // the rest-state factor serves every step of this short run
                _ => {
                    assert_eq!(other.factorizations[0], 1);
                    assert_eq!(other.total_factorizations, 1, "{:?}", other.iterations);
                    assert!(
                        other.iterations[0] <= 2,
                        "the exact factor: {:?}",
                        other.iterations
                    );
                }
            }
        }
    }
}

/// A step whose CG needs more than `refactor_iterations` makes the next step refactor: with
/// a threshold of 0 every step after the first refactors (and then converges at once).
#[test]
fn rest_cholesky_refactor_rule() {
    let (grid, model) = thesis_cuboid_grid(5.0, false);
    let mut s = settings(Preconditioner::RestCholesky);
    s.refactor_iterations = 0;
    let r = run(&grid, &model, s, 5);
    assert_eq!(r.factorizations, vec![1; 5]);
    assert!(r.iterations.iter().all(|&i| i <= 2), "{:?}", r.iterations);
    s.refactor_iterations = 2;
    let r = run(&grid, &model, s, 8);
    for k in 1..8 {
        let expected = usize::from(r.iterations[k - 1] > 2);
        assert_eq!(
            r.factorizations[k], expected,
            "step {k}: {:?} {:?}",
            r.iterations, r.factorizations
        );
    }
}

/// The solver state follows a change of pattern (new analysis) and a reset; the stateless
/// `solve` and the direct mode give the same solution.
#[test]
fn linear_solver_state_and_stateless_solve() {
    let (grid, model) = thesis_cuboid_grid(4.0, false);
    let mut sim = Simulation::new(grid, model).unwrap();
    sim.step().unwrap();
    let a = sim.newmark_matrix().clone();
    let b = Matrix::eval(
        &a * &sim.u + Matrix::<Vec3<f64>>::from_fn(a.rows(), 1, 1, |_, _, _| Vec3::new(0.0, -1.0, 0.0)).ex(),
    );
    let s = settings(Preconditioner::RestCholesky);
    let mut lin = LinearSolver::new(Some(&sim.grid.positions));
    let mut x = Matrix::zeros_shape(b.shape());
    let first = lin.solve(&a, &b, &mut x, &s).unwrap();
    assert_eq!((first.factorizations, first.fallback), (1, false));
    let mut x2 = Matrix::zeros_shape(b.shape());
    assert_eq!(lin.solve(&a, &b, &mut x2, &s).unwrap().factorizations, 0);
    // another pattern (another grid): analysed again, and again on the way back
    let (grid3, model3) = thesis_cuboid_grid(3.0, false);
    let mut other = Simulation::new(grid3, model3).unwrap();
    other.step().unwrap();
    let a3 = other.newmark_matrix();
    let b3 = Matrix::eval(a3 * &other.u);
    let mut y3 = Matrix::zeros_shape(b3.shape());
    let info = lin.solve(a3, &b3, &mut y3, &s).unwrap();
    assert_eq!(info.factorizations, 1);
    assert!(info.residual <= 1e-9);
    let mut x3 = Matrix::zeros_shape(b.shape());
    assert_eq!(lin.solve(&a, &b, &mut x3, &s).unwrap().factorizations, 1);
    lin.reset();
    let mut x4 = Matrix::zeros_shape(b.shape());
    assert_eq!(lin.solve(&a, &b, &mut x4, &s).unwrap().factorizations, 1);
    assert_eq!(lin.factorizations(), 4);
    for p in Preconditioner::ALL {
        let mut y = Matrix::zeros_shape(b.shape());
        if p == Preconditioner::Multigrid {
            // a bare matrix has no lattice to coarsen (tests/fem_multigrid.rs solves on grids)
            let err = solve(&a, &b, &mut y, &settings(p)).unwrap_err().to_string();
            assert!(err.contains("needs a grid's lattice"), "{err}");
            continue;
        }
        let (_, res, fallback) = solve(&a, &b, &mut y, &settings(p)).unwrap();
        assert!(res <= 1e-9 && !fallback, "{p:?}: residual {res:e}");
        assert!(relative_difference(&y, &x) < 1e-7, "{p:?}");
    }
    let mut y = Matrix::zeros_shape(b.shape());
    let direct = SolverSettings {
        direct: true,
        ..settings(Preconditioner::BlockJacobi)
    };
    let (its, res, _) = solve(&a, &b, &mut y, &direct).unwrap();
    assert!(its == 0 && res < 1e-10);
    assert!(relative_difference(&y, &x) < 1e-7);
    for x in [&x2, &x3, &x4] {
        assert!(relative_difference(x, &y) < 1e-7);
    }
}

/// The r = 2 cuboid after one step, its Newmark matrix and `A u` as a right-hand side.
fn stepped_cuboid_system() -> (Simulation, SparseMatrix<Mat3<f64>>, Matrix<Vec3<f64>>) {
    let (grid, model) = thesis_cuboid_grid(4.0, false);
    let mut sim = Simulation::new(grid, model).unwrap();
    sim.step().unwrap();
    let a = sim.newmark_matrix().clone();
    let b = Matrix::eval(&a * &sim.u);
    (sim, a, b)
}

/// The repeated-matrix rule (`reuse_factor`): solves with one matrix within a time step stay
/// CG (a tangent pass' few solves per step) unless `MIN_SOLVES_AHEAD` are announced; the same
/// matrix met at a later step is factored and solved directly, and the factor serves every
/// later solve with it; a run starts afresh.
#[test]
fn repeated_matrix_is_factored_only_across_steps() {
    let (sim, a, b) = stepped_cuboid_system();
    let s = SolverSettings {
        preconditioner: Preconditioner::BlockIc0,
        ..SolverSettings::default()
    };
    assert!(s.reuse_factor);
    let mut lin = LinearSolver::new(Some(&sim.grid.positions));
    let solve_once = |lin: &mut LinearSolver| {
        let mut x = Matrix::zeros_shape(b.shape());
        let info = lin.solve(&a, &b, &mut x, &s).unwrap();
        assert!(info.residual <= s.cg.tolerance, "{info:?}");
        (info.factorizations, info.iterations)
    };
    lin.new_step();
    // within the step: CG each time (block IC(0) counts one factorization per solve)
    for _ in 0..3 {
        let (f, its) = solve_once(&mut lin);
        assert!(f == 1 && its > 0, "({f}, {its})");
    }
    // the next step meets it again: one direct factor, no CG iterations, and none after
    lin.new_step();
    assert_eq!(solve_once(&mut lin), (1, 0));
    assert_eq!(solve_once(&mut lin), (0, 0));
    lin.new_step();
    assert_eq!(solve_once(&mut lin), (0, 0));
    // a new run forgets the factor: CG again
    lin.new_run();
    lin.new_step();
    let (f, its) = solve_once(&mut lin);
    assert!(f == 1 && its > 0, "({f}, {its})");
    // two solves announced within a step: CG; three: the first is factored and solved directly
    lin.new_run();
    lin.new_step();
    lin.expect_solves(MIN_SOLVES_AHEAD - 1);
    let (f, its) = solve_once(&mut lin);
    assert!(f == 1 && its > 0, "({f}, {its})");
    lin.new_run();
    lin.new_step();
    lin.expect_solves(MIN_SOLVES_AHEAD);
    assert_eq!(solve_once(&mut lin), (1, 0));
    assert_eq!(solve_once(&mut lin), (0, 0));
}

/// `max_reused_factor` bounds the factor of a repeated matrix: below its size the matrix is
/// solved by CG at every step and no factor is kept; at or above it, factored as usual.
#[test]
fn repeated_matrix_factor_respects_the_size_limit() {
    let (sim, a, b) = stepped_cuboid_system();
    let run = |limit: usize| {
        let s = SolverSettings {
            preconditioner: Preconditioner::BlockJacobi,
            max_reused_factor: limit,
            ..SolverSettings::default()
        };
        let mut lin = LinearSolver::new(Some(&sim.grid.positions));
        let mut its = Vec::new();
        for _ in 0..3 {
            lin.new_step();
            let mut x = Matrix::zeros_shape(b.shape());
            let info = lin.solve(&a, &b, &mut x, &s).unwrap();
            assert!(info.residual <= s.cg.tolerance, "{info:?}");
            its.push(info.iterations);
        }
        (its, lin.reused_factor_entries())
    };
    let (its, entries) = run(usize::MAX);
    assert!(
        its[0] > 0 && its[1..] == [0, 0] && entries > 0,
        "{its:?} {entries}"
    );
    let (its, kept) = run(entries);
    assert!(its[1..] == [0, 0] && kept == entries, "{its:?}");
    let (its, kept) = run(entries - 1);
    assert!(its.iter().all(|&i| i > 0) && kept == 0, "{its:?} {kept}");
}

#[test]
fn scene_preconditioner_key() {
    let base = SMALL_BOX_SCENE;
    let path = Path::new("scene.toml");
    let scene = Scene::parse(base, path).unwrap();
    assert_eq!(scene.numerics.preconditioner, Preconditioner::BlockIc0);
    for (name, want) in [
        ("block_jacobi", Preconditioner::BlockJacobi),
        ("block_ic0", Preconditioner::BlockIc0),
        ("rest_cholesky", Preconditioner::RestCholesky),
        ("multigrid", Preconditioner::Multigrid),
    ] {
        let text = format!("{base}[numerics]\npreconditioner = \"{name}\"\n");
        let scene = Scene::parse(&text, path).unwrap();
        let p = scene.numerics.preconditioner;
        assert_eq!((p, p.name()), (want, name));
    }
    let err = Scene::parse(&format!("{base}[numerics]\npreconditioner = \"amg\"\n"), path)
        .unwrap_err()
        .to_string();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains(
            "unknown variant `amg`, expected one of `block_jacobi`, `block_ic0`, `rest_cholesky`, `multigrid`"
        ),
        "{err}"
    );
}

/// `[numerics] reuse_factor_mb` sets the size limit of a repeated matrix's factor (default
/// `MAX_REUSED_FACTOR` entries, 200 MB); a negative or non-finite one is a one-line error that
/// names the key.
#[test]
fn scene_reuse_factor_mb_key() {
    let base = SMALL_BOX_SCENE;
    let path = Path::new("scene.toml");
    let limit = |text: &str| {
        Scene::parse(text, path)
            .unwrap()
            .solver_settings(SolverSettings::default())
            .max_reused_factor
    };
    assert_eq!(limit(base), MAX_REUSED_FACTOR);
    assert_eq!(
        limit(&format!("{base}[numerics]\nreuse_factor_mb = 1000.0\n")),
        125_000_000
    );
    assert_eq!(limit(&format!("{base}[numerics]\nreuse_factor_mb = 0.0\n")), 0);
    for bad in ["-1.0", "nan", "inf"] {
        let err = Scene::parse(&format!("{base}[numerics]\nreuse_factor_mb = {bad}\n"), path)
            .unwrap_err()
            .to_string();
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains("numerics.reuse_factor_mb"), "{err}");
    }
}
