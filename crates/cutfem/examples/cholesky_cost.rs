//! Cost of a sparse Cholesky factorization of the Newmark matrix of the cuboid, and CG with it
//! as a preconditioner (cells of size 1/(2r)).
use cutfem::fem::{Aabb, Grid, Model, Simulation};
use cutfem::shapes::Shape;
use gpumat::{cg, BlockJacobi, CgParams, Matrix, SparseCholesky};
use std::time::Instant;

fn main() {
    let r: f64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10.0);
    let shape = Shape::Box {
        center: [0.0, 1.0, 0.0],
        size: [1.29, 0.4, 0.8],
    };
    let sdf = shape.to_sdf(2.0 * r, 2).unwrap();
    let grid = Grid::new(sdf).unwrap();
    let model = Model {
        gravity: gpumat::Vec3::new(0.0, -10.0, 0.0),
        dirichlet: vec![Aabb {
            min: [-0.9, 0.6, -0.6],
            max: [-0.55, 1.4, 0.6],
        }],
        damping_mass: 0.1,
        damping_stiffness: 0.01,
        ..Model::default()
    };
    let mut sim = Simulation::new(grid, model).unwrap();
    sim.step().unwrap();
    let a = sim.newmark_matrix().clone();
    let t = Instant::now();
    let chol = SparseCholesky::new(&a).unwrap();
    println!("dofs {} factor {:.3}s", 3 * a.rows(), t.elapsed().as_secs_f64());
    for _ in 0..5 {
        sim.step().unwrap();
    }
    let a = sim.newmark_matrix().clone();
    let b = Matrix::eval(&a * &sim.u);
    let params = CgParams {
        max_iterations: 2000,
        tolerance: 1e-8,
        absolute_tolerance: 0.0,
    };
    let mut x = Matrix::zeros_shape(b.shape());
    let t = Instant::now();
    let info = cg(&a, &b, &mut x, &chol, &params).unwrap();
    println!(
        "cholesky-pcg: {} its in {:.3}s",
        info.iterations[0],
        t.elapsed().as_secs_f64()
    );
    let mut x = Matrix::zeros_shape(b.shape());
    let t = Instant::now();
    let info = cg(&a, &b, &mut x, &BlockJacobi::new(&a).unwrap(), &params).unwrap();
    println!(
        "block-jacobi-pcg: {} its in {:.3}s",
        info.iterations[0],
        t.elapsed().as_secs_f64()
    );
}
