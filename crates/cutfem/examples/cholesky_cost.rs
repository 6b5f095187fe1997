//! Cost of the preconditioners of the Newmark system of the cuboid held at one end (Table
//! B.5's model, cells of size 1/(2r), `cargo run --release -p cutfem --example cholesky_cost --
//! 20`): sparse Cholesky with AMD and with nested dissection (fill and factor time), and one
//! solve of the fifth step's system to relative residual 1e-6 by CG with block-Jacobi, the
//! modified block IC(0) and the first step's (rest-state) Cholesky factor.
use cutfem::fem::solver::IC0_RELAXATION;
use cutfem::fem::{Aabb, Grid, Model, Simulation};
use cutfem::shapes::Shape;
use gpumat::{
    cg, nested_dissection, BlockIc0, BlockJacobi, CgParams, Ic0Params, Matrix, Preconditioner,
    SparseCholesky, Vec3,
};
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
    let grid = Grid::new(shape.to_sdf(2.0 * r, 6).unwrap()).unwrap();
    let model = Model {
        young: 2000.0,
        poisson: 0.3,
        corotation: true,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        dirichlet: vec![Aabb {
            min: [-0.9, 0.6, -0.6],
            max: [-0.55, 1.4, 0.6],
        }],
        damping_mass: 0.1,
        damping_stiffness: 0.01,
        dt: 0.01,
        theta: 0.6,
        ..Model::default()
    };
    let mut sim = Simulation::new(grid, model).unwrap();
    sim.step().unwrap();
    let rest = sim.newmark_matrix().clone();
    println!("r = {r}: {} dofs", 3 * rest.rows());
    let t = Instant::now();
    let amd = SparseCholesky::new(&rest).unwrap();
    println!(
        "Cholesky, AMD order: factor {:.3} s, {} entries",
        t.elapsed().as_secs_f64(),
        amd.factor_nnz()
    );
    drop(amd);
    let t = Instant::now();
    let coords: Vec<[f64; 3]> = sim.grid.positions.iter().map(|p| [p.x, p.y, p.z]).collect();
    let order = nested_dissection(rest.pattern(), &coords);
    let chol = SparseCholesky::with_ordering(&rest, Some(&order)).unwrap();
    println!(
        "Cholesky, nested dissection: order + factor {:.3} s, {} entries",
        t.elapsed().as_secs_f64(),
        chol.factor_nnz()
    );
    for _ in 0..4 {
        sim.step().unwrap();
    }
    let a = sim.newmark_matrix().clone();
    let b = Matrix::eval(&a * &sim.u);
    let params = CgParams {
        max_iterations: 5000,
        tolerance: 1e-6,
        absolute_tolerance: 0.0,
    };
    let t = Instant::now();
    let ic = BlockIc0::with_params(
        &a,
        Ic0Params {
            shift: 0.0,
            relaxation: IC0_RELAXATION,
        },
    )
    .unwrap();
    println!("modified block IC(0): factor {:.4} s", t.elapsed().as_secs_f64());
    let bj = BlockJacobi::new(&a).unwrap();
    let pre: [(&str, &dyn Preconditioner<Vec3<f64>>); 3] = [
        ("block-Jacobi", &bj),
        ("modified block IC(0)", &ic),
        ("rest-state Cholesky", &chol),
    ];
    for (name, p) in pre {
        let mut x = Matrix::zeros_shape(b.shape());
        let t = Instant::now();
        let info = cg(&a, &b, &mut x, p, &params).unwrap();
        println!(
            "CG with {name}: {} iterations in {:.4} s",
            info.iterations[0],
            t.elapsed().as_secs_f64()
        );
    }
}
