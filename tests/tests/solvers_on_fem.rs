//! Across crates: the linear systems cutfem builds are solved alike by gpumat's batched CG
//! (block-Jacobi) and its direct sparse Cholesky, and the README's gpumat example runs.

use cutfem::fem::{Aabb, Grid, Model, Simulation};
use cutfem::shapes::Shape;
use gpumat::{cg, BlockJacobi, CgParams, Jacobi, Mat3, Matrix, SparseCholesky, SparseMatrix, Vec3};

#[test]
fn newmark_system_cg_matches_cholesky() {
    let shape = Shape::Box {
        center: [0.0, 1.0, 0.0],
        size: [0.6, 0.2, 0.3],
    };
    let grid = Grid::new(shape.to_sdf(20.0, 2).unwrap()).unwrap();
    let model = Model {
        gravity: Vec3::new(0.0, -10.0, 0.0),
        dirichlet: vec![Aabb {
            min: [-1.0, 0.0, -1.0],
            max: [-0.2, 2.0, 1.0],
        }],
        ..Model::default()
    };
    let mut sim = Simulation::new(grid, model).unwrap();
    for _ in 0..3 {
        sim.step().unwrap();
    }
    let a = sim.newmark_matrix().clone();
    // two right-hand sides at once (batched CG, one factorization)
    let b = Matrix::from_fn(a.rows(), 1, 2, |r, _, k| {
        sim.u.get(r, 0, 0) * (k as f64 + 1.0) + Vec3::new(0.0, -1.0, 0.1 * k as f64)
    });
    let mut x = Matrix::zeros_shape(b.shape());
    let params = CgParams {
        max_iterations: 5000,
        tolerance: 1e-10,
        absolute_tolerance: 0.0,
    };
    let info = cg(&a, &b, &mut x, &BlockJacobi::new(&a).unwrap(), &params).unwrap();
    let direct = SparseCholesky::new(&a).unwrap().solve(&b);
    let err = Matrix::eval(x.ex() - direct.ex()).ex().norm() / direct.ex().norm();
    assert!(err < 1e-8, "CG vs Cholesky: relative difference {err} ({info:?})");
    assert_eq!(info.iterations.len(), 2);
}

/// The example of README.md.
#[test]
fn readme_example() {
    let a = SparseMatrix::from_triplets(
        2,
        2,
        &[
            (0, 0, Mat3::<f64>::from_scalar(4.0)),
            (0, 1, Mat3::identity()),
            (1, 0, Mat3::identity()),
            (1, 1, Mat3::from_scalar(3.0)),
        ],
    );
    let b = Matrix::from_fn(2, 1, 2, |r, _, k| Vec3::splat((r + k) as f64));
    let mut x = Matrix::zeros(2, 1, 2);
    let info = cg(&a, &b, &mut x, &Jacobi::new(&a).unwrap(), &CgParams::default()).unwrap();
    let mut r = Matrix::zeros(2, 1, 2);
    r.assign(b.ex() - &a * x.ex());
    assert!(r.ex().norm() < 1e-9 && info.iterations.len() == 2);
}
