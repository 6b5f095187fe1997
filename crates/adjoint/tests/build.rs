//! Every command builds its simulation from a scene in one place
//! (`cutfem::scene::Scene::build_simulation`): `simulate`, `observe` and the synthetic data call it,
//! `fit`, `gradcheck` and `diagnose` through `scene_problem`. Here a scene with every
//! `[numerics]` key away from its default, and its model, reach the simulation both ways.

use adjoint::cost::Robust;
use adjoint::fit::{scene_problem, CostKind};
use adjoint::observations::{Observations, ObservedPoint};
use adjoint::params::ParamSet;
use cutfem::fem::advect::DisplacementExtension;
use cutfem::fem::element::Element;
use cutfem::fem::{NitscheQuadrature, Preconditioner, Simulation};
use cutfem::scene::Scene;
use cutfem::surface::SurfaceMethod;
use std::path::Path;

const SCENE: &str = r#"
[body]
shape = { kind = "box", center = [0.0, 0.3, 0.0], size = [0.5, 0.6, 0.5] }
resolution = 10
[material]
young = 100.0
poisson = 0.3
density = 1.0
[damping]
mass = 0.5
stiffness = 0.002
[gravity]
acceleration = [0.0, -10.0, 0.0]
[[dirichlet]]
min = [-0.3, -0.005, -0.3]
max = [0.3, 0.005, 0.3]
[time]
dt = 0.01
steps = 2
theta = 0.6
substeps = 3
[model]
effects = ["gravity", "damping"]
[numerics]
nitsche = "thesis"
nitsche_gamma = 7.0
cg_tolerance = 1e-9
cg_max_iterations = 321
diffusion = "linear"
preconditioner = "rest_cholesky"
element = "trilinear"
surface_subdivision = 3
surface_method = "dual_contouring"
"#;

/// What `[numerics]` and the scene's sections decide in a simulation.
fn check(sim: &Simulation, how: &str) {
    assert_eq!(sim.solver.preconditioner, Preconditioner::RestCholesky, "{how}");
    assert_eq!(sim.solver.cg.tolerance, 1e-9, "{how}");
    assert_eq!(sim.solver.cg.max_iterations, 321, "{how}");
    assert_eq!(sim.model.element, Element::Trilinear, "{how}");
    assert_eq!(sim.model.nitsche_quadrature, NitscheQuadrature::Thesis, "{how}");
    assert_eq!(
        sim.model.nitsche,
        cutfem::fem::NitschePenalty::Scaled(7.0),
        "{how}"
    );
    assert_eq!(sim.grid.surface_method, SurfaceMethod::DualContouring, "{how}");
    let fine = sim.grid.surface_sdf.as_ref().expect("a finer surface SDF");
    assert!((fine.spacing * 3.0 - sim.grid.h()).abs() < 1e-12, "{how}");
    assert_eq!(
        (sim.model.dt, sim.model.theta, sim.model.substeps),
        (0.01 / 3.0, 0.6, 3),
        "{how}"
    );
    assert_eq!(
        (sim.model.damping_mass, sim.model.damping_stiffness),
        (0.5, 0.002),
        "{how}"
    );
}

#[test]
fn every_command_builds_the_scene_s_simulation_with_its_numerics() {
    let scene = Scene::parse(SCENE, Path::new("build.toml")).unwrap();
    assert_eq!(scene.numerics.diffusion, DisplacementExtension::Linear);
    let direct = scene.build_simulation().unwrap();
    check(&direct, "Scene::build_simulation");
    let mut obs = Observations::new();
    obs.push(1, ObservedPoint::new([0.0, 0.6, 0.0]));
    let params = ParamSet::parse(&["young,poisson"]).unwrap();
    let problem = scene_problem(
        &scene,
        &obs,
        params,
        Robust::Squared,
        None,
        CostKind::Surface,
        &[],
    )
    .unwrap();
    check(&problem.sim, "scene_problem");
    // the same grid, model and surface both ways
    assert_eq!(problem.sim.grid.dofs(), direct.grid.dofs());
    assert_eq!(problem.sim.model, direct.model);
    assert_eq!(
        problem.sim.grid.surface().unwrap().mesh,
        direct.grid.surface().unwrap().mesh
    );
    // and a default scene gets the defaults
    let plain = SCENE[..SCENE.find("[numerics]").unwrap()].to_string();
    let sim = Scene::parse(&plain, Path::new("plain.toml"))
        .unwrap()
        .build_simulation()
        .unwrap();
    assert_eq!(sim.solver.preconditioner, Preconditioner::default());
    assert_eq!(sim.model.element, Element::default());
    assert_eq!(sim.grid.surface_method, SurfaceMethod::default());
}
