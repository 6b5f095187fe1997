//! The discretisation check (`adjoint::refine`): exact where every resolution is exact, falling
//! differences under refinement for a bending cantilever, and the model state carried between
//! grids.

use adjoint::refine::{carry_model, displacement_at, refine_check, RefineParams, MAX_REFINEMENT};
use cutfem::fem::Grid;
use cutfem::scene::Scene;
use gpumat::{Matrix, Vec3};
use std::path::Path;

fn scene(text: &str) -> Scene {
    Scene::parse(text, Path::new("/tmp/refine-test.toml")).unwrap_or_else(|e| panic!("{e}"))
}

/// The check of a scene's own model, with the default parameters.
fn check_scene(s: &Scene) -> adjoint::refine::RefineCheck {
    let sim = s.build_simulation().unwrap();
    refine_check(
        s,
        &sim.grid,
        &sim.model,
        &RefineParams::default(),
        &mut |_, _, _| {},
    )
    .unwrap()
}

/// A free body falling from rest under gravity `g` (`theta` given in `[time]`).
fn free_fall(theta: &str) -> Scene {
    scene(&format!(
        "[body]\nshape = {{ kind = \"sphere\", center = [0.0, 1.0, 0.0], radius = 0.3 }}\nresolution = 8\n\
         [material]\nyoung = 1000.0\npoisson = 0.3\n[gravity]\nacceleration = [0.0, -10.0, 0.0]\n\
         [time]\ndt = 0.02\nsteps = 5\n{theta}\n[model]\neffects = [\"gravity\"]\n"
    ))
}

/// A free body in free fall moves rigidly on every grid, and the trapezoidal rule (`theta` =
/// 1/2) integrates a constant acceleration exactly, `u = g t^2 / 2`, at every step: the check
/// (which refines the step with the grid) finds no difference.
#[test]
fn free_fall_is_resolution_independent() {
    let s = free_fall("theta = 0.5");
    let check = check_scene(&s);
    eprintln!("{}", check.summary(None));
    assert_eq!(check.per_frame.len(), 5);
    assert!(check.difference < 1e-9, "{check:?}");
    assert!(check.max_difference < 1e-8, "{check:?}");
    assert_eq!(check.order, None, "no order from zero differences");
    assert_eq!(check.resolution_for(1e-3), None);
}

/// The check refines the time step with the grid. For a free fall the theta scheme keeps the
/// velocity exact and advances `u' = u + dt v + theta g dt^2`, so after time `t` its error is
/// `(theta - 1/2) g dt t`, grid-independent: with `dt` halved at `2r` the check's difference at
/// frame `f` is `(theta - 1/2) g t_f dt / 2` exactly (`theta` = 0.6, `g` = 10, `dt` = 0.02:
/// `2e-4 f`), and an estimate that saw only the grid would be zero.
#[test]
fn free_fall_sees_the_time_steps_error() {
    let s = free_fall("theta = 0.6");
    let check = check_scene(&s);
    eprintln!("{}", check.summary(None));
    assert_eq!(check.substeps, 1);
    for &(f, d) in &check.per_frame {
        let t = 0.02 * f as f64;
        let expected = (0.6 - 0.5) * 10.0 * t * 0.02 / 2.0;
        assert!((d - expected).abs() < 1e-9, "frame {f}: {d} vs {expected}");
    }
}

const CANTILEVER: &str = "[body]\nshape = { kind = \"box\", center = [0.5, 0.0, 0.0], size = [1.0, 0.25, 0.25] }\n\
     resolution = 12\n[material]\nyoung = 3000.0\npoisson = 0.3\n[gravity]\nacceleration = [0.0, -10.0, 0.0]\n\
     [[dirichlet]]\nmin = [-0.5, -0.5, -0.5]\nmax = [0.16666666666666666, 0.5, 0.5]\n[time]\ndt = 0.02\nsteps = 8\n\
     [model]\neffects = [\"gravity\"]\n";

/// [`CANTILEVER`] with the element `element`.
fn cantilever(element: &str) -> Scene {
    scene(&format!("{CANTILEVER}[numerics]\nelement = \"{element}\"\n"))
}

/// A cantilever swinging under gravity, held on its first sixth (a grid plane of all three
/// grids: a box ending inside a cell holds the cell's whole face, a clamp that moves with the
/// resolution). With the thesis element, which locks and converges from below at about first
/// order, the differences fall under refinement (an observed order), the estimate exceeds the
/// `r`/`2r` difference by the Richardson factor, and a target below the estimate asks for a
/// finer grid. The incompatible element (the default) moves less between 12 and 24 cells per
/// unit than the thesis element; its differences need not fall monotonically (at 6 cells per
/// unit errors of opposite sign cancel), and then the check reports no order.
#[test]
fn cantilever_differences_fall_under_refinement() {
    let check = check_scene(&cantilever("trilinear"));
    let default = check_scene(&cantilever("incompatible"));
    eprintln!("{}\n{}", check.summary(Some(0.01)), default.summary(Some(0.01)));
    assert!(
        default.difference < 0.5 * check.difference,
        "{default:?}\n{check:?}"
    );
    if default.order.is_none() {
        assert_eq!(default.estimate, default.difference);
    }
    eprintln!("{}\n{check:?}", check.summary(Some(0.01)));
    let coarser = check.coarser_difference.expect("r/2 runs");
    assert!(check.difference > 0.0 && coarser > check.difference, "{check:?}");
    let p = check.order.expect("an observed order");
    assert!(p > 0.25, "{p}");
    let factor = 2f64.powf(p) / (2f64.powf(p) - 1.0);
    assert!((check.estimate - factor * check.difference).abs() <= 1e-12 * check.estimate);
    let r = check.resolution_for(0.5 * check.estimate).expect("a finer grid");
    assert!(r > check.resolution, "{r}");
    // the JSON carries the verdict against a noise floor: a finer grid where a practical one
    // (at most MAX_REFINEMENT times finer) reaches the floor, else only what it would take
    let j = check.to_json(Some(0.5 * check.estimate));
    assert!(j["warning"].is_string());
    let suggested = j["suggested_resolution"].as_f64().unwrap();
    assert!(suggested > check.resolution && suggested <= MAX_REFINEMENT * check.resolution);
    assert_eq!(j["required_resolution"].as_f64(), Some(suggested));
    let far = check.to_json(Some(1e-3 * check.estimate));
    assert!(
        far["warning"].is_string() && far["suggested_resolution"].is_null(),
        "{far}"
    );
    assert!(far["required_resolution"].as_f64().unwrap() > MAX_REFINEMENT * check.resolution);
    let quiet = check.to_json(Some(10.0 * check.estimate));
    assert!(quiet["warning"].is_null() && quiet["suggested_resolution"].is_null());
}

/// A bar held at one end and twisting about its axis (no gravity; 4 cells across): with the
/// lumped mass most of the difference to `2r` is the mass' rotational inertia (its error `2 h^2
/// / a^2`), so the consistent mass at `r` is much closer to the `2r` run, and the warning names
/// it; the swinging cantilever's difference is not the mass' (bending translates sections), and
/// its warning does not. With the consistent mass the check does not run the extra level.
#[test]
fn the_check_names_the_consistent_mass_where_the_inertia_dominates() {
    // a round bar like the independent reference's twisting one (tests/reference_values/
    // independent/twist), its cap held, no gravity: a pure twist of a body without edges, whose
    // difference to 2r is mostly the mass' (measured: lumped 4.85e-3, consistent 2.39e-3; the
    // square bar, its corners' sub-cell chamfer also changing with r: 4.11e-3, 3.14e-3)
    let twist = |mass: &str| {
        scene(&format!(
            "[body]\nshape = {{ kind = \"capsule\", a = [0.12, 1.0, 0.0], b = [1.0, 1.0, 0.0], radius = 0.12 }}\n\
             resolution = 20\n[material]\nyoung = 2400.0\npoisson = 0.35\n[damping]\nmass = 0.8\nstiffness = 0.0\n[gravity]\nacceleration = [0.0, 0.0, 0.0]\n\
             [[dirichlet]]\nmin = [-0.05, 0.8, -0.2]\nmax = [0.1, 1.2, 0.2]\n\
             [initial]\nangular_velocity = [10.0, 0.0, 0.0]\n[time]\ndt = 0.005\nsteps = 80\n\
             [model]\neffects = [\"gravity\", \"damping\", \"initial_velocity\"]\n[numerics]\nmass = \"{mass}\"\n"
        ))
    };
    let lumped = check_scene(&twist("lumped"));
    let d = lumped
        .consistent_mass_difference
        .expect("the consistent level runs");
    eprintln!("{}; consistent mass: {d:.3e}", lumped.summary(None));
    assert!(d < 0.5 * lumped.difference, "{lumped:?}");
    assert!(lumped.mass_dominates());
    let w = lumped.warning(Some(0.1 * lumped.estimate)).expect("a warning");
    assert!(w.contains("mass = \"consistent\""), "{w}");
    let consistent = check_scene(&twist("consistent"));
    assert_eq!(consistent.consistent_mass_difference, None);
    eprintln!("{}", consistent.summary(None));
    assert!(consistent.difference < lumped.difference, "{consistent:?}");

    let swing = check_scene(&cantilever("incompatible"));
    let d = swing
        .consistent_mass_difference
        .expect("the default mass is lumped");
    eprintln!("{}; consistent mass: {d:.3e}", swing.summary(None));
    assert!(!swing.mass_dominates(), "{swing:?}");
    let w = swing.warning(Some(0.1 * swing.estimate)).expect("a warning");
    assert!(!w.contains("consistent"), "{w}");
}

/// The verdict against three noise floors of one check (error 1e-3, order 2, motion 0.1 at
/// resolution 10): a floor of 1e-4 gets a resolution to set (10 (1e-3 / 5e-5)^(1/2) -> 45);
/// a floor of 1e-7 would need 1415, more than 8x finer: no resolution is suggested, the
/// warning says so; a floor of 1e-12 is rounding (data made by this very model), said as such.
#[test]
fn the_warning_suggests_only_practical_resolutions() {
    let check = adjoint::refine::RefineCheck {
        resolution: 10.0,
        motion: 0.1,
        difference: 0.75e-3,
        max_difference: 2e-3,
        coarser_difference: Some(3e-3),
        order: Some(2.0),
        estimate: 1e-3,
        per_frame: vec![(1, 0.75e-3)],
        note: None,
        substeps: 1,
        consistent_mass_difference: None,
    };
    let w = check.warning(Some(1e-4)).expect("a warning");
    assert!(w.contains("set [body] resolution = 45 or more"), "{w}");
    assert_eq!(check.to_json(Some(1e-4))["suggested_resolution"], 45.0);

    let w = check.warning(Some(1e-7)).expect("a warning");
    assert!(
        w.contains("no practical refinement removes it (it would take resolution 1.415e3"),
        "{w}"
    );
    let j = check.to_json(Some(1e-7));
    assert!(j["suggested_resolution"].is_null(), "{j}");
    assert_eq!(j["required_resolution"], 1415.0);
    assert_eq!(j["noise_at_rounding"], false);

    let w = check.warning(Some(1e-12)).expect("a warning");
    assert!(w.contains("a floor at rounding (1.0e-11 of the motion)"), "{w}");
    assert!(!w.contains("resolution ="), "{w}");
    assert_eq!(check.to_json(Some(1e-12))["noise_at_rounding"], true);
    assert!(check.summary(Some(1e-12)).ends_with("= 1.00e9 x the noise floor"));
    assert!(check.warning(Some(1e-2)).is_none());
}

/// The trilinear field at a node is the node's value; at a point inside a full cell it is the
/// trilinear interpolant, exact for a linear field.
#[test]
fn displacement_at_interpolates_the_fem_field() {
    let s = scene(CANTILEVER);
    let sim = s.build_simulation().unwrap();
    let g: &Grid = &sim.grid;
    let field = |p: Vec3<f64>| [0.3 * p.x - 0.1 * p.y, 0.2 * p.z + 1.0, p.x + p.y + p.z];
    let u = Matrix::from_fn(g.dofs(), 1, 1, |i, _, _| Vec3::from_array(field(g.positions[i])));
    let full = g.cells.iter().find(|c| c.is_full()).expect("a full cell");
    let o = g.cell_origin(full);
    let p = o + Vec3::new(0.3, 0.6, 0.45) * g.h();
    let got = displacement_at(g, &u, p.to_array()).expect("inside");
    let want = field(p);
    for d in 0..3 {
        assert!((got[d] - want[d]).abs() < 1e-12, "{got:?} {want:?}");
    }
    assert_eq!(displacement_at(g, &u, [100.0, 0.0, 0.0]), None);
}

/// A per-cell stiffness factor moves to the finer grid by containment: every fine cell reads
/// the factor of the coarse cell containing its centre.
#[test]
fn stiffness_field_carries_to_a_finer_grid() {
    let s = scene(CANTILEVER);
    let sim = s.build_simulation().unwrap();
    let (g, mut model) = (&sim.grid, sim.model.clone());
    // factor: 1 + the cell's x index
    let scale: Vec<f64> = g.cells.iter().map(|c| 1.0 + c.coord[0] as f64).collect();
    model.stiffness_scale = Some(scale.clone().into());
    model.young = 1234.0;
    let fine_sdf = s.body_sdf_at(Some(24.0)).unwrap();
    let fine = Grid::new(fine_sdf).unwrap();
    let mut to = s.build_model(&fine).unwrap();
    carry_model(&model, g, &mut to, &fine);
    assert_eq!(to.young, 1234.0);
    let got = to.stiffness_scale.as_deref().expect("field");
    assert_eq!(got.len(), fine.cells.len());
    for (c, &f) in fine.cells.iter().zip(got) {
        let x = fine.cell_origin(c).x + 0.5 * fine.h();
        let coarse_i = ((x - g.sdf.origin[0]) / g.h()).floor() as usize;
        let want = g
            .cells
            .iter()
            .find(|k| {
                let ko = g.cell_origin(k);
                let xc = fine.cell_origin(c) + Vec3::splat(0.5 * fine.h());
                (0..3).all(|d| {
                    let (a, b) = (ko.to_array()[d], xc.to_array()[d]);
                    b >= a && b < a + g.h()
                })
            })
            .map_or(1.0, |k| 1.0 + k.coord[0] as f64);
        assert_eq!(f, want, "cell {:?} (coarse column {coarse_i})", c.coord);
    }
}

/// The drag's nodal weights belong to each grid: the check of a model with drag runs (it
/// failed with the coarse grid's weights on the fine one) and the coefficient carries over.
#[test]
fn drag_carries_to_a_finer_grid() {
    let s = scene(&format!(
        "{}[drag]\ncoefficient = 0.5\n",
        CANTILEVER.replace("effects = [\"gravity\"]", "effects = [\"gravity\", \"drag\"]")
    ));
    let sim = s.build_simulation().unwrap();
    let mut model = sim.model.clone();
    model.drag.as_mut().expect("drag on").coefficient = 0.75;
    let fine = Grid::new(s.body_sdf_at(Some(24.0)).unwrap()).unwrap();
    let mut to = s.build_model(&fine).unwrap();
    carry_model(&model, &sim.grid, &mut to, &fine);
    let d = to.drag.as_ref().expect("drag carried");
    assert_eq!(d.coefficient, 0.75);
    assert_eq!(d.weights.len(), fine.dofs());
    assert_ne!(fine.dofs(), sim.grid.dofs());
    let check = refine_check(&s, &sim.grid, &model, &RefineParams::default(), &mut |_, _, _| {});
    let check = check.unwrap_or_else(|e| panic!("{e}"));
    assert!(
        check.difference.is_finite() && check.difference > 0.0,
        "{check:?}"
    );
}

/// An SDF file's body resampled at twice its resolution is the same body: equal volume to
/// the cut-cell accuracy, half the spacing.
#[test]
fn sdf_bodies_resample() {
    let path = format!(
        "{}/../../../shared/data/sdf/bunny_small.sdf",
        env!("CARGO_MANIFEST_DIR")
    );
    if !Path::new(&path).exists() {
        panic!("missing {path}");
    }
    let s = Scene::parse(
        &format!("[body]\nsdf = \"{path}\"\n[material]\nyoung = 1000.0\npoisson = 0.3\n"),
        Path::new("/tmp/refine-sdf.toml"),
    )
    .unwrap();
    let own = s.body_sdf().unwrap();
    let r = s.resolution().unwrap();
    assert!((r - 1.0 / own.spacing).abs() < 1e-12);
    let fine = s.body_sdf_at(Some(2.0 * r)).unwrap();
    assert!((fine.spacing - 0.5 * own.spacing).abs() < 1e-12);
    let (v0, v1) = (
        Grid::new(own).unwrap().volume(),
        Grid::new(fine).unwrap().volume(),
    );
    eprintln!("volume {v0} -> {v1}");
    assert!((v1 - v0).abs() < 0.02 * v0, "{v0} {v1}");
}

/// The refine check's `2r` run serves the diagnosis' persistence check
/// (`adjoint::diagnosis::FinerRun`): the observer sees frames `0..=steps` of a simulation on
/// the grid of twice the resolution, and the residuals it gathers from a run are those
/// `residuals::point_residuals` computes on the same run, to the bit.
#[test]
fn the_finer_run_gathers_the_residuals_of_its_run() {
    use adjoint::diagnosis::residuals::{point_residuals, rms};
    use adjoint::diagnosis::{FinerRun, Setup};
    use adjoint::observe::{synthesize, RigParams};
    let s = scene(
        "[body]\nshape = { kind = \"box\", center = [0.0, 1.0, 0.0], size = [0.8, 0.2, 0.2] }\nresolution = 6\n\
         [material]\nyoung = 800.0\npoisson = 0.3\n[gravity]\nacceleration = [0.0, -10.0, 0.0]\n\
         [[dirichlet]]\nmin = [-0.5, 0.8, -0.2]\nmax = [-0.35, 1.2, 0.2]\n\
         [time]\ndt = 0.03\nsteps = 4\n[model]\neffects = [\"gravity\"]\n",
    );
    let (obs, cams) = synthesize(&s, &RigParams::default(), 0.001, 4, |_, _| {}).unwrap();
    let eyes: Vec<[f64; 3]> = cams.iter().map(|c| c.camera.eye).collect();
    let setup = Setup {
        observations: &obs,
        eyes: &eyes,
        cameras: &cams,
        robust: adjoint::cost::Robust::Squared,
        steps: None,
        reach: None,
    };
    let sim = s.build_simulation().unwrap();
    let h = sim.grid.h();
    // the observer on the refine check's 2r run
    let mut seen = Vec::new();
    let mut finer = FinerRun::new(&setup);
    let params = RefineParams {
        no_order: true,
        ..RefineParams::default()
    };
    adjoint::refine::refine_check_observed(
        &s,
        &sim.grid,
        &sim.model,
        &params,
        &mut |_, _, _| {},
        &mut |run, t| {
            assert!((run.grid.h() - 0.5 * h).abs() < 1e-12, "the 2r grid");
            seen.push(t);
            finer.observe(run, t);
        },
    )
    .unwrap();
    assert_eq!(seen, vec![0, 1, 2, 3, 4]);
    assert!(finer.rms(4).is_some() && finer.rms(3).is_none());
    // the same gathering on a plain run equals point_residuals on it
    let mut a = s.build_simulation().unwrap();
    let model = a.model.clone();
    let mut on_plain = FinerRun::new(&setup);
    on_plain.observe(&a, 0);
    for t in 1..=4 {
        a.step().unwrap();
        on_plain.observe(&a, t);
    }
    let mut b = s.build_simulation().unwrap();
    let cost = adjoint::cost_mesh::SurfaceCost::new(
        &b.grid,
        adjoint::fit::observed_frames(&obs, &eyes),
        adjoint::cost::Robust::Squared,
    )
    .unwrap()
    .with_reach(Setup::reach(&b.grid));
    let records = point_residuals(&mut b, model, 4, &cost, &obs).unwrap();
    let (want, n) = rms(records.iter());
    let (got, m) = on_plain.rms(4).unwrap();
    assert!(n > 100 && m == n, "{n} {m}");
    assert_eq!(got.to_bits(), want.to_bits(), "{got} {want}");
}
