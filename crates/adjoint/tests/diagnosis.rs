//! Hidden-effect tests of the diagnosis (issue: "test this on data with a hidden effect").
//!
//! Observations come from the project's own generator (`observe::synthesize`: simulate +
//! virtual depth cameras) with the hidden effect on; the model scene lacks it. The torus' cases
//! run without noise and with camera noise; the bunny's (a scan, 12 cells across, several times
//! slower per case) with camera noise only, the harder of the two targets. Targets: the hidden
//! effect ranks first; after adding it the rms falls at least 5x without noise, or to within
//! 1.5x of the noise floor with noise; with nothing hidden, `missing_effect` is null.

use adjoint::cost::Robust;
use adjoint::diagnosis::{add_and_refit, diagnose, DiagnoseParams, Diagnosis, Refined, Setup};
use adjoint::observations::Observations;
use adjoint::observe::{synthesize, DepthCamera, RigParams};
use adjoint::params::ParamSet;
use cutfem::fem::{Grid, Model};
use cutfem::scene::Scene;
use std::path::Path;

/// Depth noise of the noisy cases, world units (torus; the bunny's is scaled with its size).
const NOISE: f64 = 0.004;
/// The noise levels of a torus case: none and [`NOISE`].
const BOTH: &[f64] = &[0.0, NOISE];
/// The noise level of a bunny case.
const NOISY: &[f64] = &[NOISE];
/// The bunny's size relative to the torus'.
const BUNNY_SCALE: f64 = 0.11;

fn bunny_mesh() -> String {
    format!(
        "{}/../../../shared/data/meshes/bunny_res3.obj",
        env!("CARGO_MANIFEST_DIR")
    )
}

/// A scene from its body, Young's modulus, physics sections, time step and effect list.
fn scene(body: &str, young: f64, physics: &str, effects: &[&str], dt: f64, steps: usize) -> Scene {
    let list: Vec<String> = effects.iter().map(|e| format!("\"{e}\"")).collect();
    let text = format!(
        "{body}\n[material]\nyoung = {young}\npoisson = 0.3\ndensity = 1.0\n{physics}\n\
         [time]\ndt = {dt}\nsteps = {steps}\ntheta = 0.6\n[model]\neffects = [{}]\n",
        list.join(", ")
    );
    Scene::parse(&text, Path::new("/tmp/hidden-effect-test.toml")).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

const TORUS: &str = "[body]\nshape = { kind = \"torus\", center = [0.0, 1.0, 0.0], axis = [0.0, 0.0, 1.0], major = 0.5, minor = 0.2 }\nresolution = 8\n";
/// Holds the left end of the torus: the surface of the two columns of cells (h = 1/8) left of
/// x = -0.5, between y = 0.75 and 1.25 (the box is clipped to the surface exactly).
const HOLD_LEFT: &str = "[[dirichlet]]\nmin = [-0.8, 0.75, -0.3]\nmax = [-0.5, 1.25, 0.3]\n";

/// The Stanford bunny scan (`bunny_res3.obj`, 0.155 x 0.151 x 0.120, open at the base) at 80
/// cells per unit (12 cells across).
fn bunny() -> String {
    format!("[body]\nmesh = \"{}\"\nresolution = 80\n", bunny_mesh())
}

/// Observations of a truth, with their cameras.
struct Case {
    shape: &'static str,
    obs: Observations,
    cams: Vec<DepthCamera>,
    eyes: Vec<[f64; 3]>,
}

impl Case {
    /// Observes `truth` (with `edit` on its model) with 4 cameras of 32x32 pixels and depth
    /// noise `sigma` (scaled with the body).
    fn observe(truth: &Scene, sigma: f64, edit: impl FnOnce(&Grid, &mut Model)) -> Case {
        // cameras at 2 body sizes (the torus is 1.4 wide, the bunny 0.155)
        let bunny = truth.body.mesh.is_some();
        let rig = RigParams {
            cameras: 4,
            pixels: 32,
            radius: if bunny { 0.33 } else { 3.0 },
            ..RigParams::default()
        };
        let sigma = if bunny { sigma * BUNNY_SCALE } else { sigma };
        let (obs, cams) = synthesize(truth, &rig, sigma, truth.time.steps, edit).expect("observations");
        let eyes = cams.iter().map(|c| c.camera.eye).collect();
        let shape = if bunny { "bunny" } else { "torus" };
        Case {
            shape,
            obs,
            cams,
            eyes,
        }
    }

    fn setup(&self) -> Setup<'_> {
        Setup {
            observations: &self.obs,
            eyes: &self.eyes,
            cameras: &self.cams,
            robust: Robust::Squared,
            steps: None,
            reach: None,
        }
    }

    /// Diagnoses `model` (fitting Young's modulus and the Poisson ratio).
    fn diagnose(&self, model: &Scene) -> Diagnosis {
        self.diagnose_fitting(model, "young,poisson")
    }

    /// Diagnoses `model`, fitting `params`.
    fn diagnose_fitting(&self, model: &Scene, params: &str) -> Diagnosis {
        let t = std::time::Instant::now();
        let d = diagnose(
            model,
            &self.setup(),
            ParamSet::parse(&[params]).unwrap(),
            &DiagnoseParams::default(),
            &mut |_, _, _| {},
        )
        .expect("diagnosis");
        eprintln!(
            "rms {:.3e} floor {:?} missing {:?} ({:.1} s)\n{}",
            d.rms,
            d.noise_floor,
            d.missing_effect,
            t.elapsed().as_secs_f64(),
            d.verdict
        );
        for p in &d.plausibility {
            eprintln!("  plausibility {p:?}");
        }
        for c in &d.candidates {
            eprintln!(
                "  {:<18} score {:>10.3e} pred {:.3e} after {:?} dBIC {:?} {:?} frees {:?}",
                c.effect, c.score, c.predicted_rms, c.rms_after, c.delta_bic, c.error, c.frees
            );
        }
        d
    }
}

/// The targets of a case with `hidden` hidden: it ranks first, is called missing, and after
/// adding it and fitting on (as a user would) the rms falls.
fn check(case: &Case, d: &Diagnosis, hidden: &str, sigma: f64) -> Refined {
    // named first, or as an alternative the data cannot tell from the first (Delta BIC within
    // the threshold: drag and mass damping on the torus under noise)
    let named = d.candidates[0].effect == hidden || d.alternatives.iter().any(|a| a == hidden);
    assert!(named, "{}", d.verdict);
    assert!(d.missing_effect.is_some(), "{}", d.verdict);
    let refined = add_and_refit(&case.setup(), d, hidden, 40).expect("refit");
    let after = refined.eval.rms();
    eprintln!("after adding {hidden} and fitting on: rms {} -> {after}", d.rms);
    let rank = d
        .candidates
        .iter()
        .position(|c| c.effect == hidden)
        .map_or(0, |r| r + 1);
    eprintln!(
        "CASE | {} | {hidden} | {sigma} | {rank} | {:?} | {:.3e} | {:.3e} | {:?} | {:.1} |",
        case.shape,
        d.missing_effect,
        d.rms,
        after,
        d.noise_floor,
        d.rms / after.max(1e-300)
    );
    if sigma == 0.0 {
        assert!(after * 5.0 <= d.rms, "rms {} -> {after}", d.rms);
    } else {
        assert!(
            after <= 1.5 * d.noise_floor.expect("a noise floor"),
            "rms {} -> {after}, floor {:?}",
            d.rms,
            d.noise_floor
        );
    }
    refined
}

fn torus_swing(effects: &[&str]) -> Scene {
    torus_swing_for(effects, 0.02)
}

/// [`torus_swing`] for twice as long (10 steps of 0.04): with the consistent clamp and the
/// incompatible element the hidden damping's noise-free misfit over 0.2 s (rms 1.18e-3 after
/// the base fit) is a third of the camera noise, so the noisy case's margin (rms without the
/// effect over the rms with it) was only 1.05, inside the noise floor's own error; damping
/// needs time to show.
fn torus_swing_long(effects: &[&str]) -> Scene {
    torus_swing_for(effects, 0.04)
}

fn torus_swing_for(effects: &[&str], dt: f64) -> Scene {
    scene(
        TORUS,
        2000.0,
        &format!("[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[damping]\nmass = 8.0\nstiffness = 0.0\n{HOLD_LEFT}"),
        effects,
        dt,
        10,
    )
}

/// [`torus_swing_long`] with linear air drag (`c = 1`, about the slowing of the mass damping 8
/// there: the tube's mass per area is `r / 2 = 0.1`) instead of Rayleigh damping.
fn torus_drag(effects: &[&str]) -> Scene {
    scene(
        TORUS,
        2000.0,
        &format!("[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[drag]\ncoefficient = 1.0\n{HOLD_LEFT}"),
        effects,
        0.04,
        10,
    )
}

/// [`torus_swing_long`] held by an imperfect clamp: springs of `k = 2e4` (stress per length) on
/// the held surface instead of the rigid hold (the rigid hold's penalty is about 100x that).
fn torus_clamp(effects: &[&str]) -> Scene {
    scene(
        TORUS,
        2000.0,
        &format!(
            "[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[damping]\nmass = 8.0\nstiffness = 0.0\n\
             [clamp]\nstiffness = 2e4\n{HOLD_LEFT}"
        ),
        effects,
        0.04,
        10,
    )
}

/// A free torus falling onto the ground (its lowest point 0.1 above it), pushed sideways.
fn torus_drop(effects: &[&str]) -> Scene {
    scene(
        TORUS,
        2000.0,
        "[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[ground]\nheight = 0.2\n\
         [initial]\nvelocity = [1.0, -0.5, 0.0]\nangular_velocity = [0.0, 0.0, 1.0]\n",
        effects,
        0.02,
        10,
    )
}

/// [`torus_drop`] with ground friction (`mu = 1`: at the contact force of the torus' weight
/// the sliding slows by about `e^{-mu g t}`, a third in its 0.1 s on the ground).
fn torus_friction(effects: &[&str]) -> Scene {
    scene(
        TORUS,
        2000.0,
        "[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[ground]\nheight = 0.2\n[friction]\ncoefficient = 1.0\n\
         [initial]\nvelocity = [1.0, -0.5, 0.0]\nangular_velocity = [0.0, 0.0, 1.0]\n",
        effects,
        0.02,
        10,
    )
}

/// The bunny scan falling onto the ground (its lowest point 0.008 above it, contact after 6 of
/// the 10 steps), pushed sideways.
fn bunny_drop(effects: &[&str]) -> Scene {
    bunny_drop_for(effects, 0.005)
}

/// [`bunny_drop`] for twice as long (damping needs time to show).
fn bunny_drop_long(effects: &[&str]) -> Scene {
    bunny_drop_for(effects, 0.01)
}

fn bunny_drop_for(effects: &[&str], dt: f64) -> Scene {
    scene(
        &bunny(),
        20.0,
        "[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[ground]\nheight = 0.025\n\
         [damping]\nmass = 10.0\nstiffness = 0.0\n\
         [initial]\nvelocity = [0.2, -0.1, 0.0]\nangular_velocity = [0.0, 2.0, 0.0]\n",
        effects,
        dt,
        10,
    )
}

/// The bunny held at its base, bent by a sideways gravity.
fn bunny_held(effects: &[&str]) -> Scene {
    scene(
        &bunny(),
        20.0,
        "[gravity]\nacceleration = [-10.0, -5.0, 0.0]\n[damping]\nmass = 10.0\nstiffness = 0.0\n\
         [[dirichlet]]\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 0.05, 1.0]\n",
        effects,
        0.01,
        10,
    )
}

/// A stiff spherical inclusion: factor 5 on the cells whose center lies within `r` of `c`.
fn inclusion(c: [f64; 3], r: f64) -> impl FnOnce(&Grid, &mut Model) {
    move |grid, model| {
        let h = grid.h();
        let s: Vec<f64> = grid
            .cells
            .iter()
            .map(|cell| {
                let x = (grid.cell_origin(cell) + gpumat::Vec3::splat(0.5 * h)).to_array();
                let d2: f64 = (0..3).map(|k| (x[k] - c[k]).powi(2)).sum();
                if d2 <= r * r {
                    5.0
                } else {
                    1.0
                }
            })
            .collect();
        model.stiffness_scale = Some(s.into());
    }
}

/// Runs `hidden` hidden at the noise levels `sigmas`.
fn hidden_case(make: fn(&[&str]) -> Scene, truth: &[&str], hidden: &str, sigmas: &[f64]) {
    for &sigma in sigmas {
        let model: Vec<&str> = truth.iter().copied().filter(|e| *e != hidden).collect();
        eprintln!("== {hidden} hidden, noise {sigma}");
        let case = Case::observe(&make(truth), sigma, |_, _| {});
        let d = case.diagnose(&make(&model));
        check(&case, &d, hidden, sigma);
    }
}

/// A stiff inclusion: ranked first, and the refitted field's stiffest cell lies inside it,
/// give or take one cell.
fn inclusion_case(make: fn(&[&str]) -> Scene, c: [f64; 3], r: f64, sigmas: &[f64]) {
    for &sigma in sigmas {
        eprintln!("== stiff inclusion at {c:?}, noise {sigma}");
        let effects = ["gravity", "corotation"];
        let case = Case::observe(&make(&effects), sigma, inclusion(c, r));
        let d = case.diagnose(&make(&effects));
        let refined = check(&case, &d, "stiffness_field", sigma);
        let sim = refined.scene.build_simulation().unwrap();
        let grid = &sim.grid;
        let s = refined.model.stiffness_scale.as_deref().expect("field");
        let k = (0..s.len()).max_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap();
        let h = grid.h();
        let x = (grid.cell_origin(&grid.cells[k]) + gpumat::Vec3::splat(0.5 * h)).to_array();
        let dist = (0..3).map(|i| (x[i] - c[i]).powi(2)).sum::<f64>().sqrt();
        eprintln!(
            "stiffest cell at {x:?} (factor {:.2}), {dist:.4} from the center",
            s[k]
        );
        assert!(
            dist <= r + h,
            "stiffest cell {x:?} lies {dist} from {c:?} (radius {r}, cell {h})"
        );
    }
}

#[test]
fn torus_hidden_gravity() {
    hidden_case(torus_swing, &["gravity", "corotation"], "gravity", BOTH);
}

#[test]
fn torus_hidden_damping() {
    hidden_case(
        torus_swing_long,
        &["gravity", "corotation", "damping"],
        "damping",
        BOTH,
    );
}

#[test]
fn torus_hidden_drag() {
    hidden_case(torus_drag, &["gravity", "corotation", "drag"], "drag", BOTH);
}

#[test]
fn torus_hidden_clamp() {
    hidden_case(
        torus_clamp,
        &["gravity", "corotation", "damping", "clamp"],
        "clamp",
        BOTH,
    );
}

#[test]
fn torus_hidden_friction() {
    hidden_case(
        torus_friction,
        &["gravity", "corotation", "ground", "initial_velocity", "friction"],
        "friction",
        BOTH,
    );
}

#[test]
fn torus_hidden_corotation() {
    hidden_case(torus_swing, &["gravity", "corotation"], "corotation", BOTH);
}

#[test]
fn torus_hidden_ground() {
    hidden_case(
        torus_drop,
        &["gravity", "corotation", "ground", "initial_velocity"],
        "ground",
        BOTH,
    );
}

#[test]
fn torus_hidden_initial_velocity() {
    hidden_case(
        torus_drop,
        &["gravity", "corotation", "ground", "initial_velocity"],
        "initial_velocity",
        BOTH,
    );
}

#[test]
fn torus_hidden_stiffness_field() {
    inclusion_case(torus_swing, [0.0, 1.5, 0.0], 0.25, &[0.0]);
}

#[test]
fn torus_hidden_stiffness_field_noisy() {
    inclusion_case(torus_swing, [0.0, 1.5, 0.0], 0.25, &[NOISE]);
}

#[test]
fn bunny_hidden_ground() {
    hidden_case(
        bunny_drop,
        &["gravity", "corotation", "ground", "initial_velocity"],
        "ground",
        NOISY,
    );
}

#[test]
fn bunny_hidden_initial_velocity() {
    hidden_case(
        bunny_drop,
        &["gravity", "corotation", "ground", "initial_velocity"],
        "initial_velocity",
        NOISY,
    );
}

#[test]
fn bunny_hidden_gravity() {
    hidden_case(bunny_held, &["gravity", "corotation"], "gravity", NOISY);
}

#[test]
fn bunny_hidden_damping() {
    hidden_case(
        bunny_drop_long,
        &["gravity", "corotation", "initial_velocity", "damping"],
        "damping",
        NOISY,
    );
}

#[test]
fn bunny_hidden_corotation() {
    hidden_case(bunny_held, &["gravity", "corotation"], "corotation", NOISY);
}

#[test]
fn bunny_hidden_stiffness_field() {
    inclusion_case(bunny_held, [-0.02, 0.08, 0.0], 0.05, NOISY);
}

/// Gravity and corotation hidden (the model: linear elasticity, no gravity): gravity is found
/// first; after adding it, corotation.
#[test]
fn torus_two_hidden_effects() {
    for sigma in [0.0, NOISE] {
        eprintln!("== gravity and corotation hidden, noise {sigma}");
        let case = Case::observe(&torus_swing(&["gravity", "corotation"]), sigma, |_, _| {});
        let d = case.diagnose(&torus_swing(&[]));
        assert_eq!(d.missing_effect.as_deref(), Some("gravity"), "{}", d.verdict);
        let refined = add_and_refit(&case.setup(), &d, "gravity", 20).expect("refit");
        // the user's next model: gravity on with the fitted values, and fitted
        let mut next = torus_swing(&["gravity"]);
        next.gravity.as_mut().unwrap().acceleration = refined.model.gravity.to_array();
        let d2 = case.diagnose_fitting(&next, "young,poisson,gravity");
        check(&case, &d2, "corotation", sigma);
    }
}

/// Nothing hidden: no false alarm, with and without noise, on both shapes.
#[test]
fn nothing_hidden() {
    for sigma in [0.0, NOISE] {
        for make in [torus_swing as fn(&[&str]) -> Scene, bunny_drop] {
            let effects = ["gravity", "corotation"];
            let case = Case::observe(&make(&effects), sigma, |_, _| {});
            let d = case.diagnose(&make(&effects));
            eprintln!(
                "CASE | {} | none | {sigma} | - | {:?} | {:.3e} | - | {:?} | - |",
                case.shape, d.missing_effect, d.rms, d.noise_floor
            );
            assert_eq!(d.missing_effect, None, "{}", d.verdict);
            assert!(d.verdict.starts_with("nothing missing"), "{}", d.verdict);
        }
    }
}

/// A box of 0.4 x 0.3 x 0.3 at rest 2 cm above a ground (height 0.83), under gravity 10 with
/// Rayleigh damping, 30 steps of 0.02 at resolution 12, with `effects` on.
fn dropped_box(effects: &[&str]) -> Scene {
    scene(
        "[body]\nshape = { kind = \"box\", center = [0.0, 1.0, 0.0], size = [0.4, 0.3, 0.3] }\nresolution = 12\n",
        3000.0,
        "[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[ground]\nheight = 0.83\n\
         [damping]\nmass = 0.5\nstiffness = 0.001\n",
        effects,
        0.02,
        30,
    )
}

/// A box dropped 2 cm onto a ground the model lacks (issue 50: such a box was once called
/// `missing: drag`, a drag so strong that it sank at its terminal velocity). The ground is
/// named and plausible (the fitted body rests on the plane); drag, refitted too, explains the
/// landing only by holding up most of the weight, and its values are judged implausible.
#[test]
fn box_dropped_onto_a_missing_ground() {
    let case = Case::observe(
        &dropped_box(&["gravity", "ground", "damping", "corotation"]),
        0.002,
        |_, _| {},
    );
    let d = case.diagnose(&dropped_box(&["gravity", "damping", "corotation"]));
    assert_eq!(d.missing_effect.as_deref(), Some("ground"), "{}", d.verdict);
    let named = &d.plausibility[0];
    assert_eq!(named.effect, "ground");
    assert!(named.implausible.is_none(), "{named:?}");
    let drag = d
        .candidates
        .iter()
        .find(|c| c.effect == "drag")
        .expect("drag probed");
    assert!(drag.rms_after.is_some(), "drag refitted: {}", d.verdict);
    let judged = adjoint::diagnosis::plausible::judge(drag, &case.obs, d.noise_floor)
        .unwrap()
        .expect("drag is judged");
    eprintln!("drag: {judged:?}");
    assert!(
        judged
            .implausible
            .as_deref()
            .is_some_and(|w| w.contains("terminal velocity")),
        "{judged:?}"
    );
}

/// The same box with gravity hidden instead (issue 50's calibration draw of 2026-12-07c: a
/// box, a bar and a sphere dropped onto a ground with gravity hidden were all called
/// `missing: initial_velocity`). Switched on under a body at rest just above the ground,
/// gravity's probe predicts a fraction of its value (the linearisation knows nothing of the
/// landing) and a short refit from there ended far short; the refit's start scan along the
/// probe's step (`diagnosis::scan::step`) brings it to the truth, and gravity is named.
#[test]
fn box_dropped_with_gravity_hidden() {
    let case = Case::observe(
        &dropped_box(&["gravity", "ground", "damping", "corotation"]),
        0.002,
        |_, _| {},
    );
    let d = case.diagnose(&dropped_box(&["ground", "damping", "corotation"]));
    let gravity = d
        .candidates
        .iter()
        .find(|c| c.effect == "gravity")
        .expect("gravity probed");
    eprintln!("{}\ngravity: {:?}", d.verdict, gravity.values);
    assert_eq!(d.missing_effect.as_deref(), Some("gravity"), "{}", d.verdict);
    let g = gravity
        .values
        .iter()
        .find(|(name, _)| name == "gravity.y")
        .expect("g_y fitted")
        .1;
    assert!((g + 10.0).abs() < 0.5, "fitted g_y {g}");
}
