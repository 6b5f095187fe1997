//! scratch probe (to be removed)
use cutfem::fem::{Aabb, Grid, Ground, Model, Preconditioner, Simulation};
use cutfem::shapes::Shape;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let r: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10.0);
    let ground = args.get(2).is_some_and(|s| s == "ground");
    let steps: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(30);
    let shape = Shape::Box {
        center: [0.0, 1.0, 0.0],
        size: [1.29, 0.4, 0.8],
    };
    let sdf = shape.to_sdf(2.0 * r, 6).unwrap();
    let grid = Grid::new(sdf).unwrap();
    let model = Model {
        young: 2000.0,
        poisson: 0.3,
        damping_mass: 0.1,
        damping_stiffness: 0.01,
        gravity: gpumat::Vec3::new(0.0, -10.0, 0.0),
        corotation: true,
        dirichlet: if ground {
            vec![]
        } else {
            vec![Aabb {
                min: [-0.9, 0.6, -0.6],
                max: [-0.55, 1.4, 0.6],
            }]
        },
        ground: ground.then_some(Ground {
            normal: gpumat::Vec3::new(0.0, 1.0, 0.0),
            height: 0.75,
            stiffness: 1.0e4,
            softness: 100.0,
            scheme: Default::default(),
        }),
        dt: 0.01,
        theta: 0.6,
        ..Model::default()
    };
    if args.get(4).is_some_and(|s| s == "bench") {
        let mut sim = Simulation::new(grid.clone(), model.clone()).unwrap();
        sim.step().unwrap();
        let a = sim.newmark_matrix().clone();
        let r0 = gpumat::Matrix::eval(&a * &sim.u);
        let mut z = r0.clone();
        let ic = gpumat::BlockIc0::new(&a).unwrap();
        let bj = gpumat::BlockJacobi::new(&a).unwrap();
        use gpumat::Preconditioner as _;
        for _ in 0..3 {
            let t = Instant::now();
            for _ in 0..20 {
                ic.apply(&r0, &mut z);
            }
            let ti = t.elapsed().as_secs_f64() / 20.0;
            let t = Instant::now();
            for _ in 0..20 {
                bj.apply(&r0, &mut z);
            }
            let tb = t.elapsed().as_secs_f64() / 20.0;
            let t = Instant::now();
            for _ in 0..20 {
                z.assign(&a * &r0);
            }
            let ts = t.elapsed().as_secs_f64() / 20.0;
            println!(
                "ic0 apply {:.3} ms, bj apply {:.3} ms, spmv {:.3} ms, upper blocks {}",
                ti * 1e3,
                tb * 1e3,
                ts * 1e3,
                ic.upper_blocks()
            );
        }
        return;
    }
    let mut ref_u = None;
    for p in Preconditioner::ALL {
        let mut sim = Simulation::new(grid.clone(), model.clone()).unwrap();
        sim.solver.cg.tolerance = 1e-6;
        sim.solver.preconditioner = p;
        let t = Instant::now();
        let (mut its, mut solve, mut fac) = (vec![], 0.0, 0.0);
        for _ in 0..steps {
            let i = sim.step().unwrap();
            its.push(i.iterations);
            solve += i.solve_s;
            fac += i.factor_s;
        }
        let tot = t.elapsed().as_secs_f64();
        let n = steps as f64;
        let mean = its.iter().sum::<usize>() as f64 / n;
        let dev = match &ref_u {
            None => {
                ref_u = Some(sim.u.clone());
                0.0
            }
            Some(u) => {
                let d = gpumat::Matrix::eval(sim.u.ex() - u.ex());
                d.ex().norm() / u.ex().norm()
            }
        };
        println!("r={r} ground={ground} {:14} mean its {mean:6.1} cg {:8.2} ms factor {:8.2} ms/step facts {} total {tot:.2}s rel.dev {dev:.2e} its {:?}",
            p.name(), (solve - fac) / n * 1e3, fac / n * 1e3, sim.factorizations(), its);
    }
}
