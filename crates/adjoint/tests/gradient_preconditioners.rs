//! The adjoint gradient does not depend on how the linear systems are solved: with CG and each
//! preconditioner (`cutfem::fem::Preconditioner::ALL`, the multigrid hierarchy made to coarsen
//! this small bar) to a tight tolerance, the forward and the backward solves (the transposed
//! Newmark systems `A lam = g`, eq. 5.5.2) give the direct solver's cost and gradient
//! to the solver's accuracy.

mod common;

use adjoint::cost::DisplacementCost;
use adjoint::params::ParamSet;
use adjoint::problem::Problem;
use cutfem::fem::{Grid, Model, Preconditioner, Simulation, SolverSettings};
use gpumat::{Matrix, Vec3};

const STEPS: usize = 6;

/// 12 x 4 x 4 cells (325 nodes): coarsened once by the multigrid below.
fn grid() -> Grid {
    common::bar_grid(20.0)
}

fn start() -> Model {
    let mut m = common::every_effect();
    m.young = 3600.0;
    m.poisson = 0.27;
    m.damping_mass = 0.13;
    m.gravity = Vec3::new(0.3, -9.0, -0.2);
    m
}

/// Frames `0..=STEPS` of the every-effect truth (direct solves).
fn reference() -> Vec<Matrix<Vec3<f64>>> {
    common::direct_frames(grid(), common::every_effect(), STEPS)
}

/// Cost and gradient of the start model against `reference` with `solver`.
/// Also the multigrid levels kept (block rows, finest first; empty without multigrid).
fn gradient(solver: SolverSettings, reference: &[Matrix<Vec3<f64>>]) -> (f64, Vec<f64>, usize, Vec<usize>) {
    let mut sim = Simulation::new(grid(), start()).unwrap();
    sim.solver = solver;
    let cost = DisplacementCost {
        reference: (1..=STEPS).map(|t| (t, 1.0, reference[t].clone())).collect(),
    };
    let params = ParamSet::parse(&["young,poisson,damping_mass,gravity,ground"]).unwrap();
    let mut p = Problem::new(sim, params, Box::new(cost), STEPS).unwrap();
    let x = p.x0();
    let (ev, g, _) = p.gradient(&x).unwrap();
    (
        ev.cost,
        g,
        ev.fallbacks,
        p.sim.multigrid_levels().unwrap_or_default(),
    )
}

#[test]
fn gradient_is_the_same_with_every_preconditioner() {
    let reference = reference();
    let direct = SolverSettings {
        direct: true,
        ..SolverSettings::default()
    };
    let (cost0, g0, _, _) = gradient(direct, &reference);
    let scale = g0.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(cost0 > 0.0 && scale > 0.0);
    for pre in Preconditioner::ALL {
        let mut s = SolverSettings {
            preconditioner: pre,
            fallback: false,
            ..SolverSettings::default()
        };
        s.cg.tolerance = 1e-12;
        s.cg.max_iterations = 2000;
        s.multigrid.max_coarse = 100;
        let (cost, g, fallbacks, levels) = gradient(s, &reference);
        let dg = g.iter().zip(&g0).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())) / scale;
        let dc = (cost - cost0).abs() / cost0;
        eprintln!(
            "{}: cost {dc:.1e}, gradient {dg:.1e} (relative to the direct solves'), levels {levels:?}",
            pre.name()
        );
        assert_eq!(fallbacks, 0, "{}", pre.name());
        if pre == Preconditioner::Multigrid {
            assert!(levels.len() >= 2, "multigrid levels {levels:?}");
        }
        assert!(dc < 1e-9, "{}: cost {cost} vs {cost0}", pre.name());
        assert!(dg < 1e-7, "{}: gradient {g:?} vs {g0:?}", pre.name());
    }
}
