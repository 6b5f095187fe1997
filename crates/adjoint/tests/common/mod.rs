//! What the adjoint crate's test files share: the small bar with every effect on, its
//! displacement-cost problems, the momentum of a simulation, and the derivative checks.
#![allow(dead_code)] // each test file uses a part

use adjoint::cost::DisplacementCost;
use adjoint::params::ParamSet;
use adjoint::problem::Problem;
use cutfem::fem::collision::{ContactScheme, Ground};
use cutfem::fem::{Aabb, Grid, Model, Simulation};
use cutfem::shapes::Shape;
use gpumat::{Matrix, Vec3};

/// Integrator steps of the problems of [`problem`].
pub const STEPS: usize = 8;

/// A 0.6 x 0.2 x 0.2 bar along x centred at y = 0.25 (its bottom at y = 0.15), `resolution`
/// cells per unit.
pub fn bar_grid(resolution: f64) -> Grid {
    let shape = Shape::Box {
        center: [0.0, 0.25, 0.0],
        size: [0.6, 0.2, 0.2],
    };
    Grid::new(shape.to_sdf(resolution, 6).unwrap()).unwrap()
}

/// Every core effect on for [`bar_grid`]: corotation, Rayleigh damping, gravity, ground
/// contact just below the bar, a clamp of its left end, initial velocities.
pub fn every_effect() -> Model {
    Model {
        young: 3000.0,
        poisson: 0.3,
        density: 1.0,
        damping_mass: 0.1,
        damping_stiffness: 0.01,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        ground: Some(Ground {
            normal: Vec3::new(0.0, 1.0, 0.0),
            height: 0.14,
            stiffness: 1e3,
            softness: 60.0,
            scheme: ContactScheme::Implicit,
        }),
        dirichlet: vec![Aabb {
            min: [-0.4, 0.0, -0.2],
            max: [-0.22, 0.5, 0.2],
        }],
        initial_velocity: Vec3::new(0.1, -0.3, 0.05),
        initial_angular_velocity: Vec3::new(0.2, 0.1, -0.3),
        ..Model::default()
    }
}

/// The displacement cost of `truth` on [`bar_grid`]`(10)` at every second of [`STEPS`] steps,
/// and the problem of fitting `params` from `start` (direct solves).
pub fn problem(truth: Model, start: Model, params: &str) -> Problem {
    let out = direct_frames(bar_grid(10.0), truth, STEPS);
    let cost = DisplacementCost {
        reference: (2..=STEPS).step_by(2).map(|t| (t, 1.0, out[t].clone())).collect(),
    };
    let mut sim = Simulation::new(bar_grid(10.0), start).unwrap();
    sim.solver.direct = true;
    Problem::new(sim, ParamSet::parse(&[params]).unwrap(), Box::new(cost), STEPS).unwrap()
}

/// The displacements of frames `0..=n` (each `model.substeps` steps) of `model` on `grid`,
/// with direct solves.
pub fn direct_frames(grid: Grid, model: Model, n: usize) -> Vec<Matrix<Vec3<f64>>> {
    let mut sim = Simulation::new(grid, model).unwrap();
    sim.solver.direct = true;
    let mut out = vec![sim.u.clone()];
    for _ in 0..n {
        sim.step().unwrap();
        out.push(sim.u.clone());
    }
    out
}

/// The momentum `sum_i m_i v_i` of `s`.
pub fn momentum(s: &Simulation) -> Vec3<f64> {
    s.mass
        .as_slice()
        .iter()
        .zip(s.v.as_slice())
        .fold(Vec3::default(), |p, (&m, &v)| p + v * m)
}

/// The adjoint gradient at `x` against central differences of the cost: per coordinate, the
/// best relative difference over the steps 1e-3, 1e-4, 1e-5 is below `tol`.
pub fn assert_gradient_is_the_fd_gradient(p: &mut Problem, x: &[f64], tol: f64) {
    let (ev, g, _) = p.gradient(x).unwrap();
    assert!(ev.cost > 0.0);
    for k in 0..x.len() {
        let mut best = f64::INFINITY;
        for eps in [1e-3, 1e-4, 1e-5] {
            let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
            xp[k] += eps;
            xm[k] -= eps;
            let fd = (p.evaluate(&xp).unwrap().cost - p.evaluate(&xm).unwrap().cost) / (2.0 * eps);
            best = best.min((g[k] - fd).abs() / g[k].abs().max(fd.abs()));
        }
        assert!(best < tol, "{}: rel {best:.2e}", p.params.labels()[k]);
    }
}

/// The Gauss-Newton matrix at `x` against central differences (step `eps`) of the adjoint
/// gradient, each entry within 1e-5 of the larger of its two diagonal entries (at zero
/// residual the Gauss-Newton matrix is the Hessian).
pub fn assert_gauss_newton_is_the_fd_hessian(p: &mut Problem, x: &[f64], eps: f64) {
    let n = x.len();
    let h = p.gauss_newton_matrix(x).unwrap();
    for b in 0..n {
        let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
        xp[b] += eps;
        xm[b] -= eps;
        let (gp, gm) = (p.gradient(&xp).unwrap().1, p.gradient(&xm).unwrap().1);
        for a in 0..n {
            let fd = (gp[a] - gm[a]) / (2.0 * eps);
            let scale = h[a * n + a].abs().max(h[b * n + b].abs());
            assert!(
                (h[a * n + b] - fd).abs() <= 1e-5 * scale,
                "H[{a}][{b}]: tangent {} vs fd {fd}",
                h[a * n + b]
            );
        }
    }
}
