//! The whole adjoint gradient against central differences of the whole simulation, and a
//! Taylor test (the remainder `J(x + e d) - J(x) - e g.d` falls as `e^2`), for the displacement
//! cost (eq. 5.4.1) and the point-cloud cost (eq. 5.4.4) with every effect on.

mod common;
use common::assert_gauss_newton_is_the_fd_hessian;

use adjoint::cost::{Cost, DisplacementCost, ObservedPoint, PointCloudCost, Robust};
use adjoint::params::ParamSet;
use adjoint::problem::Problem;
use cutfem::fem::advect::Diffusion;
use cutfem::fem::collision::ContactScheme;
use cutfem::fem::element::Element;
use cutfem::fem::{Grid, MassMatrix, Model, Simulation};
use gpumat::{Matrix, Vec3};

const STEPS: usize = 8;

fn grid() -> Grid {
    common::bar_grid(10.0)
}

/// Every effect on ([`common::every_effect`]).
fn truth() -> Model {
    common::every_effect()
}

/// A start model away from the truth in every parameter.
fn start() -> Model {
    let mut m = truth();
    m.young = 3600.0;
    m.poisson = 0.27;
    m.density = 1.1;
    m.damping_mass = 0.13;
    m.damping_stiffness = 0.012;
    m.gravity = Vec3::new(0.3, -9.0, -0.2);
    let g = m.ground.as_mut().unwrap();
    g.normal = Vec3::new(0.03, 1.0, -0.02) * (1.0 / (1.0f64 + 0.0009 + 0.0004).sqrt());
    g.height = 0.15;
    m.initial_velocity = Vec3::new(0.0, -0.2, 0.0);
    m.initial_angular_velocity = Vec3::new(0.1, 0.0, -0.2);
    m
}

fn trajectory(model: Model) -> Vec<Matrix<Vec3<f64>>> {
    frames(model, STEPS)
}

/// The displacement of frames `0..=n` (each `model.substeps` steps).
fn frames(model: Model, n: usize) -> Vec<Matrix<Vec3<f64>>> {
    common::direct_frames(grid(), model, n)
}

fn all_params() -> ParamSet {
    ParamSet::parse(&[
        "young,poisson,density,damping_mass,damping_stiffness,gravity,ground,initial_velocity,initial_angular_velocity",
    ])
    .unwrap()
}

fn problem(cost: Box<dyn Cost>, params: ParamSet) -> Problem {
    let mut sim = Simulation::new(grid(), start()).unwrap();
    sim.solver.direct = true;
    Problem::new(sim, params, cost, STEPS).unwrap()
}

/// Compares each gradient component with central differences at steps 1e-3 to 1e-6 (in the
/// unconstrained coordinates, which are O(1)) and keeps the best agreement: large steps carry
/// truncation error (a sharp contact law needs 1e-6 for the ground height), small ones the rounding noise of the whole simulation (about
/// 1e-15 of the cost), which dominates for components much smaller than the others: an
/// absolute difference below `1e-10 ||g||_inf` also passes (components 1e5 times smaller than
/// the largest reach that noise floor).
fn check_against_fd(p: &mut Problem, tol: f64) {
    let x = p.x0();
    let (ev, g, _) = p.gradient(&x).unwrap();
    assert!(ev.cost > 0.0);
    let labels = p.params.labels();
    let gmax = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for k in 0..x.len() {
        let mut best = (f64::INFINITY, 0.0);
        for eps in [1e-3, 1e-4, 1e-5, 1e-6] {
            let mut xp = x.clone();
            xp[k] += eps;
            let mut xm = x.clone();
            xm[k] -= eps;
            let fd = (p.evaluate(&xp).unwrap().cost - p.evaluate(&xm).unwrap().cost) / (2.0 * eps);
            let err = (g[k] - fd).abs() / g[k].abs().max(fd.abs()).max(1e-300);
            if err < best.0 {
                best = (err, fd);
            }
        }
        let (err, fd) = best;
        let floor = (g[k] - fd).abs() <= 1e-10 * gmax;
        println!(
            "{:>28} adjoint {:+.10e} fd {:+.10e} rel {:.2e}{}",
            labels[k],
            g[k],
            fd,
            err,
            if floor { " (below the noise floor)" } else { "" }
        );
        assert!(
            err < tol || floor,
            "{}: adjoint {} vs fd {} (rel {err:.2e})",
            labels[k],
            g[k],
            fd
        );
    }
}

#[test]
fn displacement_cost_gradient_matches_finite_differences() {
    let reference = trajectory(truth());
    let cost = DisplacementCost {
        reference: (2..=STEPS)
            .step_by(2)
            .map(|t| (t, 1.0, reference[t].clone()))
            .collect(),
    };
    let mut p = problem(Box::new(cost), all_params());
    check_against_fd(&mut p, 1e-6);
}

/// [`displacement_cost_gradient_matches_finite_differences`] with the truth and the start
/// model passed through `edit`.
fn displacement_cost_gradient_with(edit: impl Fn(Model) -> Model) {
    let reference = trajectory(edit(truth()));
    let cost = DisplacementCost {
        reference: (2..=STEPS)
            .step_by(2)
            .map(|t| (t, 1.0, reference[t].clone()))
            .collect(),
    };
    let mut sim = Simulation::new(grid(), edit(start())).unwrap();
    sim.solver.direct = true;
    let mut p = Problem::new(sim, all_params(), Box::new(cost), STEPS).unwrap();
    check_against_fd(&mut p, 1e-6);
}

/// The same with the incompatible element (exact integration, condensed bubbles, the empty
/// part at `FICTITIOUS_STIFFNESS`, rotations from the inside-averaged deformation gradient).
#[test]
fn displacement_cost_gradient_matches_finite_differences_incompatible() {
    displacement_cost_gradient_with(|mut m| {
        m.element = Element::Incompatible;
        assert!(m.corotation);
        m
    });
}

/// The same with the consistent mass (`[numerics] mass = "consistent"`): `M lam` in the
/// adjoint's mass, damping, density and gravity terms is the matrix' product
/// (`Simulation::mass_times`), every effect on.
#[test]
fn displacement_cost_gradient_matches_finite_differences_consistent_mass() {
    displacement_cost_gradient_with(|mut m| {
        m.mass = MassMatrix::Consistent;
        m
    });
}

#[test]
fn taylor_remainder_is_second_order() {
    let reference = trajectory(truth());
    let cost = DisplacementCost {
        reference: vec![(STEPS, 1.0, reference[STEPS].clone())],
    };
    let mut p = problem(Box::new(cost), all_params());
    let x = p.x0();
    let (ev, g, _) = p.gradient(&x).unwrap();
    let d: Vec<f64> = (0..x.len())
        .map(|k| ((k * 7919) % 13) as f64 / 13.0 - 0.5)
        .collect();
    let gd: f64 = g.iter().zip(&d).map(|(a, b)| a * b).sum();
    let mut prev = f64::NAN;
    let mut ratios = Vec::new();
    for i in 0..4 {
        let e = 1e-2 / 2f64.powi(i);
        let xe: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a + e * b).collect();
        let r = (p.evaluate(&xe).unwrap().cost - ev.cost - e * gd).abs();
        if prev.is_finite() {
            ratios.push(prev / r);
        }
        prev = r;
    }
    println!("Taylor remainder ratios (expect 4): {ratios:?}");
    for r in ratios {
        assert!((3.5..4.5).contains(&r), "remainder ratio {r}");
    }
}

#[test]
fn point_cloud_cost_gradient_matches_finite_differences() {
    // observations: the truth's deformed surface vertices
    let g = grid();
    let frames = surface_observations(&g);
    let mut band = Diffusion::new(&g).unwrap();
    band.params.tolerance = 1e-14;
    let cost = PointCloudCost::new(&g, band, frames, Robust::Squared);
    assert!(cost.candidate_cells() > 0);
    let params = ParamSet::parse(&["young,poisson,gravity,damping_mass"]).unwrap();
    let mut p = problem(Box::new(cost), params);
    let ev = p.evaluate(&p.x0()).unwrap();
    let outside: usize = ev.frames.iter().map(|f| f.outside).sum();
    println!("rms {} outside {outside}", ev.rms());
    check_against_fd(&mut p, 1e-6);
}

/// At the truth (zero residuals) the Gauss-Newton matrix from the tangent-linear sensitivities
/// is the exact Hessian: compare with central differences of the adjoint gradient.
#[test]
fn gauss_newton_matrix_is_the_hessian_at_zero_residual() {
    let reference = trajectory(truth());
    let cost = DisplacementCost {
        reference: (2..=STEPS)
            .step_by(2)
            .map(|t| (t, 1.0, reference[t].clone()))
            .collect(),
    };
    let params = ParamSet::parse(&["young,poisson,density,gravity,ground,initial_velocity"]).unwrap();
    let mut sim = Simulation::new(grid(), truth()).unwrap();
    sim.solver.direct = true;
    let mut p = Problem::new(sim, params, Box::new(cost), STEPS).unwrap();
    let x = p.x0();
    let n = x.len();
    let h = p.gauss_newton_matrix(&x).unwrap();
    let eps = 1e-4;
    let mut hmax = 0.0f64;
    let mut fd = vec![0.0; n * n];
    for b in 0..n {
        let mut xp = x.clone();
        xp[b] += eps;
        let mut xm = x.clone();
        xm[b] -= eps;
        let (gp, gm) = (p.gradient(&xp).unwrap().1, p.gradient(&xm).unwrap().1);
        for a in 0..n {
            fd[a * n + b] = (gp[a] - gm[a]) / (2.0 * eps);
            hmax = hmax.max(fd[a * n + b].abs());
        }
    }
    let labels = p.params.labels();
    for a in 0..n {
        for b in 0..n {
            let (an, f) = (h[a * n + b], fd[a * n + b]);
            let err = (an - f).abs() / hmax;
            assert!(
                err < 1e-5,
                "H[{}][{}]: tangent {an} vs fd {f} (rel to max {err:.1e})",
                labels[a],
                labels[b]
            );
        }
    }
}

/// Observations: every third vertex of the truth's deformed surface at frames 2, 5, 8.
fn surface_observations(g: &Grid) -> Vec<(usize, Vec<ObservedPoint>)> {
    let surface = g.surface().unwrap();
    let reference = trajectory(truth());
    (2..=STEPS)
        .step_by(3)
        .map(|t| {
            let u = &reference[t];
            let mesh = g.deformed(&surface, u);
            let pts = mesh
                .vertices
                .iter()
                .step_by(3)
                .map(|v| ObservedPoint {
                    position: Vec3::new(v[0], v[1], v[2]),
                    weight: 1.0,
                    eye: None,
                })
                .collect();
            (t, pts)
        })
        .collect()
}

#[test]
fn surface_cost_gradient_matches_finite_differences_and_vanishes_at_the_truth() {
    use adjoint::cost_mesh::SurfaceCost;
    let g = grid();
    let frames = surface_observations(&g);
    // at the truth, points on the simulated surface have zero residual
    let cost = SurfaceCost::new(&g, frames.clone(), Robust::Squared).unwrap();
    let mut sim = Simulation::new(grid(), truth()).unwrap();
    sim.solver.direct = true;
    let params = ParamSet::parse(&["young,poisson,gravity,damping_mass,ground"]).unwrap();
    let mut p = Problem::new(sim, params.clone(), Box::new(cost), STEPS).unwrap();
    let ev = p.evaluate(&p.x0()).unwrap();
    assert!(ev.rms() < 1e-12, "rms at the truth {}", ev.rms());
    // away from it, the adjoint gradient matches central differences
    let cost = SurfaceCost::new(&g, frames, Robust::Squared).unwrap();
    let mut p = problem(Box::new(cost), params);
    let ev = p.evaluate(&p.x0()).unwrap();
    println!("surface cost rms at the start {}", ev.rms());
    assert_eq!(ev.frames.iter().map(|f| f.outside).sum::<usize>(), 0);
    check_against_fd(&mut p, 1e-6);
}

/// A heterogeneous Young's modulus: the gradient of the field's coefficients (log factors on
/// a coarse trilinear grid) matches central differences.
#[test]
fn stiffness_field_gradient_matches_finite_differences() {
    use adjoint::params::FieldBasis;
    let g = grid();
    let basis = FieldBasis::new(&g, [2, 1, 1]).unwrap();
    // truth: the free end twice as stiff
    let c_true: Vec<f64> = (0..basis.len())
        .map(|k| if k % 3 == 2 { 0.7 } else { 0.0 })
        .collect();
    let mut truth_model = truth();
    truth_model.stiffness_scale = Some(basis.scales(&c_true).into());
    let reference = trajectory(truth_model);
    let cost = DisplacementCost {
        reference: (2..=STEPS)
            .step_by(2)
            .map(|t| (t, 1.0, reference[t].clone()))
            .collect(),
    };
    let mut params = ParamSet::parse(&["young,stiffness_field"]).unwrap();
    params.field = Some(basis.into());
    let mut sim = Simulation::new(grid(), truth()).unwrap();
    sim.solver.direct = true;
    let mut p = Problem::new(sim, params, Box::new(cost), STEPS).unwrap();
    check_against_fd(&mut p, 1e-6);
}

/// The same with the residual along each point's viewing ray (camera eyes known).
#[test]
fn ray_residual_gradient_matches_finite_differences() {
    use adjoint::cost_mesh::SurfaceCost;
    let g = grid();
    let eyes = [Vec3::new(0.3, 2.5, 2.0), Vec3::new(-1.5, 1.0, -2.0)];
    let frames: Vec<(usize, Vec<ObservedPoint>)> = surface_observations(&g)
        .into_iter()
        .map(|(t, pts)| {
            let pts = pts
                .into_iter()
                .enumerate()
                .map(|(i, mut p)| {
                    p.eye = Some(eyes[i % 2]);
                    p
                })
                .collect();
            (t, pts)
        })
        .collect();
    let cost = SurfaceCost::new(&g, frames, Robust::Squared).unwrap();
    let params = ParamSet::parse(&["young,poisson,gravity,ground"]).unwrap();
    let mut p = problem(Box::new(cost), params);
    check_against_fd(&mut p, 1e-6);
}

/// The located hits a cost keeps per frame are what a fresh search returns: asked for
/// displacements in turn (the same again, another, the first back, another reach), every answer
/// equals a new cost's.
#[test]
fn kept_hits_equal_a_fresh_search() {
    use adjoint::cost_mesh::SurfaceCost;
    let g = grid();
    let eye = Vec3::new(0.3, 2.5, 2.0);
    let frames: Vec<(usize, Vec<ObservedPoint>)> = surface_observations(&g)
        .into_iter()
        .map(|(t, pts)| {
            (
                t,
                pts.into_iter()
                    .map(|p| ObservedPoint { eye: Some(eye), ..p })
                    .collect(),
            )
        })
        .collect();
    let states = trajectory(start());
    let mut kept = SurfaceCost::new(&g, frames.clone(), Robust::Squared).unwrap();
    let near = kept.outside_residual;
    for (frame, state, reach) in [
        (2, 2, near),
        (2, 2, near),
        (2, 5, near),
        (5, 5, near),
        (2, 2, near),
        (2, 2, 0.05 * near),
    ] {
        kept.outside_residual = reach;
        let mut fresh = SurfaceCost::new(&g, frames.clone(), Robust::Squared).unwrap();
        fresh.outside_residual = reach;
        let got = kept.residuals(frame, &states[state]);
        assert!(got.iter().any(Option::is_some));
        assert_eq!(
            got,
            fresh.residuals(frame, &states[state]),
            "frame {frame}, state {state}, reach {reach}"
        );
    }
    assert!(kept.kept_bytes() > 0);
    // within a budget: frames beyond it are searched afresh (same hits), the kept bytes stay
    // within it and a kept frame is still replaced
    let mut bounded = SurfaceCost::new(&g, frames.clone(), Robust::Squared).unwrap();
    let fresh = SurfaceCost::new(&g, frames.clone(), Robust::Squared).unwrap();
    bounded.residuals(2, &states[2]);
    let one = bounded.kept_bytes();
    assert!(one > 0);
    bounded.located_budget = one;
    for (frame, state) in [(5, 5), (2, 5), (5, 5), (2, 2)] {
        assert_eq!(
            bounded.residuals(frame, &states[state]),
            fresh.residuals(frame, &states[state])
        );
        assert_eq!(bounded.kept_bytes(), one, "frame {frame}, state {state}");
    }
}

/// An external force `sum_k c_k F_k` with the wind's three surface-traction fields
/// (`F_d[i] = A_i e_d`) and a fourth, non-uniform one (a twist about the box's axis).
fn with_external_force(mut m: Model, coefficients: [f64; 4]) -> Model {
    use cutfem::fem::ExternalForce;
    use cutfem::scene::effects::wind;
    let g = grid();
    let mut basis = wind::basis(&g);
    let areas = wind::node_areas(&g);
    basis.push(
        g.positions
            .iter()
            .zip(&areas)
            .map(|(p, &a)| Vec3::new(0.0, -(p.to_array()[2]), p.to_array()[1] - 0.25) * (20.0 * a))
            .collect(),
    );
    m.external_force = Some(ExternalForce {
        basis: std::sync::Arc::new(basis),
        coefficients: coefficients.to_vec(),
        labels: vec!["wind.x".into(), "wind.y".into(), "wind.z".into(), "twist".into()],
    });
    m
}

/// The external force's coefficients: the adjoint gradient `dt sum_t lam_t . F_k` matches
/// central differences of the whole simulation (with every other effect on).
#[test]
fn external_force_gradient_matches_finite_differences() {
    let truth_model = with_external_force(truth(), [0.5, -1.0, 0.3, 0.4]);
    let reference = trajectory(truth_model);
    let cost = DisplacementCost {
        reference: (2..=STEPS)
            .step_by(2)
            .map(|t| (t, 1.0, reference[t].clone()))
            .collect(),
    };
    let mut sim = Simulation::new(grid(), with_external_force(start(), [0.2, -0.6, 0.0, 0.1])).unwrap();
    sim.solver.direct = true;
    let params = ParamSet::parse(&["young,gravity,external_force"]).unwrap();
    let mut p = Problem::new(sim, params, Box::new(cost), STEPS).unwrap();
    assert_eq!(
        p.params.labels()[4..],
        [
            "external_force[0]",
            "external_force[1]",
            "external_force[2]",
            "external_force[3]"
        ]
    );
    let values: Vec<String> = p.params.values(&p.base).into_iter().map(|v| v.0).collect();
    assert_eq!(values[4..], ["wind.x", "wind.y", "wind.z", "twist"]);
    check_against_fd(&mut p, 1e-6);
}

/// The tangent-linear pass differentiates the assemblies through `model_at`, external force
/// included: at zero residual its Gauss-Newton matrix is the Hessian.
#[test]
fn gauss_newton_matrix_with_external_force_is_the_hessian_at_zero_residual() {
    let truth_model = with_external_force(truth(), [0.5, -1.0, 0.3, 0.4]);
    let reference = trajectory(truth_model.clone());
    let cost = DisplacementCost {
        reference: (2..=STEPS)
            .step_by(2)
            .map(|t| (t, 1.0, reference[t].clone()))
            .collect(),
    };
    let params = ParamSet::parse(&["young,external_force"]).unwrap();
    let mut sim = Simulation::new(grid(), truth_model).unwrap();
    sim.solver.direct = true;
    let mut p = Problem::new(sim, params, Box::new(cost), STEPS).unwrap();
    let x = p.x0();
    assert_eq!(x.len(), 5);
    let n = x.len();
    let h = p.gauss_newton_matrix(&x).unwrap();
    let eps = 1e-4;
    let mut hmax = 0.0f64;
    let mut fd = vec![0.0; n * n];
    for b in 0..n {
        let mut xp = x.clone();
        xp[b] += eps;
        let mut xm = x.clone();
        xm[b] -= eps;
        let (gp, gm) = (p.gradient(&xp).unwrap().1, p.gradient(&xm).unwrap().1);
        for a in 0..n {
            fd[a * n + b] = (gp[a] - gm[a]) / (2.0 * eps);
            hmax = hmax.max(fd[a * n + b].abs());
        }
    }
    for a in 0..n {
        for b in 0..n {
            let (an, f) = (h[a * n + b], fd[a * n + b]);
            let err = (an - f).abs() / hmax;
            assert!(
                err < 1e-5,
                "H[{a}][{b}]: tangent {an} vs fd {f} (rel to max {err:.1e})"
            );
        }
    }
}

/// `substeps` integrator steps per frame: frame `f` of a model with `dt` and 2 substeps is
/// step `2f` of the same model with `dt / 2` and one.
fn substepped(mut m: Model) -> Model {
    m.dt *= 0.5;
    m.substeps = 2;
    m
}

#[test]
fn a_frame_of_substeps_is_that_many_steps() {
    let steps = trajectory(Model { dt: 0.005, ..truth() });
    let frames = frames(substepped(truth()), STEPS / 2);
    for (f, u) in frames.iter().enumerate() {
        let d = u
            .as_slice()
            .iter()
            .zip(steps[2 * f].as_slice())
            .map(|(a, b)| (*a - *b).norm())
            .fold(0.0, f64::max);
        assert!(d <= 1e-14, "frame {f}: {d}");
    }
}

/// The adjoint gradient and the Gauss-Newton matrix run through every integrator step and
/// read the cost at the frames only.
#[test]
fn substep_gradient_and_gauss_newton_match_finite_differences() {
    let reference = frames(substepped(truth()), STEPS / 2);
    let cost = DisplacementCost {
        reference: vec![(2, 1.0, reference[2].clone()), (3, 0.5, reference[3].clone())],
    };
    let mut sim = Simulation::new(grid(), substepped(start())).unwrap();
    sim.solver.direct = true;
    let mut p = Problem::new(sim, all_params(), Box::new(cost), STEPS / 2).unwrap();
    check_against_fd(&mut p, 1e-6);

    // at the truth the Gauss-Newton matrix is the Hessian
    let cost = DisplacementCost {
        reference: vec![(2, 1.0, reference[2].clone()), (3, 0.5, reference[3].clone())],
    };
    let mut sim = Simulation::new(grid(), substepped(truth())).unwrap();
    sim.solver.direct = true;
    let params = ParamSet::parse(&["young,poisson,gravity"]).unwrap();
    let mut p = Problem::new(sim, params, Box::new(cost), STEPS / 2).unwrap();
    let x = p.x0();
    // the cost reads frame f after f frames (2f steps), not after f steps
    let at_truth = p.evaluate(&x).unwrap().cost;
    assert!(at_truth <= 1e-24, "cost at the truth {at_truth}");
    assert_gauss_newton_is_the_fd_hessian(&mut p, &x, 1e-4);
}

/// The penalty contact (per unit area, Newton-iterated within each step) with a sharper law.
fn penalty(mut m: Model) -> Model {
    let g = m.ground.as_mut().unwrap();
    g.scheme = ContactScheme::Penalty;
    g.stiffness = 3e5;
    g.softness = 300.0;
    m
}

/// The adjoint of the converged Newton step (implicit function theorem) against finite
/// differences of the whole simulation, and the Gauss-Newton matrix at the truth against the
/// Hessian.
#[test]
fn penalty_contact_gradient_and_gauss_newton_match_finite_differences() {
    let reference = trajectory(penalty(truth()));
    let newton = {
        let mut sim = Simulation::new(grid(), penalty(truth())).unwrap();
        sim.solver.direct = true;
        (0..STEPS).map(|_| sim.step().unwrap().newton).sum::<usize>()
    };
    assert!(
        newton > 0,
        "the penalty steps did no Newton iteration: no contact?"
    );
    let observed = |r: &[Matrix<Vec3<f64>>]| DisplacementCost {
        reference: (2..=STEPS).step_by(2).map(|t| (t, 1.0, r[t].clone())).collect(),
    };
    let mut sim = Simulation::new(grid(), penalty(start())).unwrap();
    sim.solver.direct = true;
    let mut p = Problem::new(sim, all_params(), Box::new(observed(&reference)), STEPS).unwrap();
    check_against_fd(&mut p, 1e-6);

    let mut sim = Simulation::new(grid(), penalty(truth())).unwrap();
    sim.solver.direct = true;
    let params = ParamSet::parse(&["young,poisson,gravity,ground"]).unwrap();
    let mut p = Problem::new(sim, params, Box::new(observed(&reference)), STEPS).unwrap();
    let x = p.x0();
    // the sharp law's third derivatives need a small step: the difference quotients of H[7][7]
    // (height, height) at steps 1e-3 ... 1e-7 were 155.0, 165.12, 164.529, 164.52315,
    // 164.52309 against the tangent's 164.52311
    assert_gauss_newton_is_the_fd_hessian(&mut p, &x, 1e-6);
}
