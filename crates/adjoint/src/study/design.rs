//! Experiment design: which additional recording would shrink the study's largest standard
//! error most.
//!
//! After a joint fit at `X*` with Gauss-Newton matrix `H` (`P x P`, [`super::joint`]) and
//! residual variance `s^2 = r^T W r / (n - P)` (`crate::statistics`), the covariance of the
//! estimate is `C = s^2 H^-1`. A further recording `c` of the same body, simulated at the
//! fitted material, adds its own Gauss-Newton matrix `H_c = J_c^T W_c J_c` (over its shared
//! coordinates and its own) with the block structure of a study:
//!
//! ```text
//! H' = [ H_ss + H_c,ss   H_s,o     H_c,s,oc ]
//!      [ H_o,s           H_o,o     0        ]
//!      [ H_c,oc,s        0         H_c,oc,oc ]
//! ```
//!
//! and the predicted covariance is `C' = s^2 H'^-1` (the noise level of the study; the
//! candidate is simulated noise-free, so its residuals add `s^2` per informative point,
//! keeping `s^2`). Its own coordinates (e.g. its launch velocity) are fitted too, so their
//! correlation with the material costs information as it would in a real fit.
//!
//! The candidates are motions of the study's first scene from a short menu
//! ([`candidates`]): dropped onto a ground, thrown sideways with a spin, squeezed (thrown down
//! onto the ground), and held and struck sideways. Each is observed by a rig of virtual depth
//! cameras ([`crate::observe`]) at the fitted parameters and its Gauss-Newton matrix is made
//! at that point, exactly as a fit would.

use crate::cost::Robust;
use crate::fit::{scene_problem, CostKind};
use crate::observe::{observe_run, RigParams};
use crate::params::{Param, ParamSet};
use crate::statistics::{uncertainty_of, Uncertainty};
use crate::Error;
use cutfem::scene::{GroundSection, InitialSection, Scene};

/// One candidate motion.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// short name (`drop`, `throw`, `squeeze`, `strike`)
    pub name: &'static str,
    /// what is done to the body, in words
    pub what: String,
    /// the scene of the motion (the study's first scene, changed)
    pub scene: Scene,
}

fn add_effect(scene: &mut Scene, effect: &str) {
    if let Some(m) = &mut scene.model {
        if !m.effects.iter().any(|e| e == effect) {
            m.effects.push(effect.to_string());
        }
    }
}

fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    (n > 0.0 && n.is_finite()).then(|| v.map(|c| c / n))
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn scaled(a: [f64; 3], s: f64) -> [f64; 3] {
    a.map(|c| c * s)
}

/// The menu of candidate motions for `base` (its body, material, time and cameras unchanged;
/// `lo`, `hi`: the bounding box of its reference surface). Motions that need gravity (a drop)
/// are left out when the scene has none.
pub fn candidates(base: &Scene, lo: [f64; 3], hi: [f64; 3]) -> Vec<Candidate> {
    let span = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    let duration = base.time.dt * base.time.steps as f64;
    let gravity = base
        .gravity
        .as_ref()
        .filter(|_| base.effect_on("gravity"))
        .map(|g| g.acceleration);
    let g_mag = gravity.map_or(0.0, |g| dot(g, g).sqrt());
    // "down": along gravity, else -y
    let down = gravity.and_then(unit).unwrap_or([0.0, -1.0, 0.0]);
    // a horizontal direction (perpendicular to down) and a spin axis perpendicular to both
    let side = unit([down[1], -down[0], 0.0])
        .or_else(|| unit([0.0, down[2], -down[1]]))
        .unwrap_or([1.0, 0.0, 0.0]);
    let axis = [
        down[1] * side[2] - down[2] * side[1],
        down[2] * side[0] - down[0] * side[2],
        down[0] * side[1] - down[1] * side[0],
    ];
    // the lowest point of the body along `down`
    let lowest = (0..8)
        .map(|c| {
            let p = [0, 1, 2].map(|d| if c >> d & 1 == 1 { hi[d] } else { lo[d] });
            dot(p, down)
        })
        .fold(f64::MIN, f64::max);
    let up = scaled(down, -1.0);
    // the body released from its holds with a launch
    let launched = |velocity: [f64; 3], angular_velocity: [f64; 3]| {
        let mut scene = base.clone();
        scene.dirichlet.clear();
        add_effect(&mut scene, "initial_velocity");
        scene.initial = Some(InitialSection {
            velocity,
            angular_velocity,
        });
        scene
    };
    let ground_at = |scene: &mut Scene, gap: f64| {
        // the ground is `up . x >= height`, `gap` below the body
        scene.ground = Some(GroundSection {
            normal: up,
            height: -(lowest + gap),
            stiffness: None,
            softness: None,
            scheme: Default::default(),
        });
        add_effect(scene, "ground");
    };
    let mut out = Vec::new();
    if g_mag > 0.0 && duration > 0.0 {
        // falls for half the recording, then lands
        let gap = g_mag * duration * duration / 8.0;
        let mut s = launched([0.0; 3], [0.0; 3]);
        ground_at(&mut s, gap);
        out.push(Candidate {
            name: "drop",
            what: format!("released at rest {gap:.3} above a ground and dropped on it"),
            scene: s,
        });
    }
    if duration > 0.0 {
        // thrown down onto the ground: lands after a quarter of the recording, fast
        let gap = 0.25 * span;
        let speed = 4.0 * gap / duration;
        let mut s = launched(scaled(down, speed), [0.0; 3]);
        ground_at(&mut s, gap);
        out.push(Candidate {
            name: "squeeze",
            what: format!("thrown down at {speed:.3} onto a ground {gap:.3} below: squeezed on impact"),
            scene: s,
        });
        // thrown sideways one body length over the recording, half a turn of spin
        let (speed, spin) = (span / duration, std::f64::consts::PI / duration);
        let mut s = launched(scaled(side, speed), scaled(axis, spin));
        s.ground = None;
        out.push(Candidate {
            name: "throw",
            what: format!("thrown sideways at {speed:.3} spinning at {spin:.3} rad/s (free flight)"),
            scene: s,
        });
        if !base.dirichlet.is_empty() {
            // held as in the study and struck sideways
            let mut s = base.clone();
            add_effect(&mut s, "initial_velocity");
            s.initial = Some(InitialSection {
                velocity: scaled(side, 0.5 * span / duration),
                angular_velocity: [0.0; 3],
            });
            out.push(Candidate {
                name: "strike",
                what: format!(
                    "held as recorded and struck sideways at {:.3}",
                    0.5 * span / duration
                ),
                scene: s,
            });
        }
    }
    out
}

/// The menu's scenes made consistent and checked ([`Scene::derived`]): a released body has no
/// clamp, a free flight no ground or friction. A candidate that still fails a check is dropped
/// from the menu with its reason.
pub fn checked_candidates(base: &Scene, lo: [f64; 3], hi: [f64; 3]) -> (Vec<Candidate>, Vec<Prediction>) {
    let (mut ok, mut failed) = (Vec::new(), Vec::new());
    for c in candidates(base, lo, hi) {
        match c.scene.clone().derived(&format!("design candidate `{}`", c.name)) {
            Ok(scene) => ok.push(Candidate { scene, ..c }),
            Err(e) => failed.push(Prediction {
                name: c.name,
                what: c.what,
                points: 0,
                std_errors: None,
                error: Some(e.to_string()),
            }),
        }
    }
    (ok, failed)
}

/// What adding one candidate recording would give.
#[derive(Clone, Debug)]
pub struct Prediction {
    /// the candidate's name
    pub name: &'static str,
    /// what it does
    pub what: String,
    /// observed points of the simulated candidate (informative ones)
    pub points: usize,
    /// the predicted standard errors of the shared coordinates' values with it (the study's
    /// labels); `None` when the candidate could not be simulated or observed
    pub std_errors: Option<Vec<f64>>,
    /// why not, when it could not
    pub error: Option<String>,
}

/// The study's Gauss-Newton picture to extend: the joint matrix `h` (`P x P`), `r^T W r`, the
/// informative point count, the coordinate scales and labels (as for
/// [`crate::statistics::uncertainty_of`]), and the number of shared coordinates first in them.
#[derive(Clone, Debug)]
pub struct Current {
    /// joint Gauss-Newton matrix, row-major
    pub h: Vec<f64>,
    /// `r^T W r` at the fit
    pub rwr: f64,
    /// informative residual entries
    pub n: usize,
    /// `dvalue/dx` per coordinate
    pub scales: Vec<f64>,
    /// labels
    pub labels: Vec<String>,
    /// shared coordinates (the first ones)
    pub shared: usize,
}

impl Current {
    /// The standard errors now.
    pub fn uncertainty(&self) -> Option<Uncertainty> {
        uncertainty_of(
            &self.h,
            self.rwr,
            self.n,
            self.scales.clone(),
            self.labels.clone(),
        )
    }

    /// The standard errors with a candidate whose Gauss-Newton matrix over `(s, o_c)` is `hc`
    /// (`p_c x p_c`, its first `shared` coordinates the shared ones), `scales_c` its own
    /// coordinates' scales, over `nc` informative points (module docs).
    pub fn with(&self, hc: &[f64], scales_c: &[f64], nc: usize) -> Option<Uncertainty> {
        let p = self.scales.len();
        let pc = (hc.len() as f64).sqrt().round() as usize;
        let k = pc.checked_sub(self.shared)?;
        if pc * pc != hc.len() || scales_c.len() != k {
            return None;
        }
        let q = p + k;
        let mut h = vec![0.0; q * q];
        for i in 0..p {
            h[i * q..i * q + p].copy_from_slice(&self.h[i * p..(i + 1) * p]);
        }
        let at = |i: usize| if i < self.shared { i } else { p + i - self.shared };
        for i in 0..pc {
            for j in 0..pc {
                h[at(i) * q + at(j)] += hc[i * pc + j];
            }
        }
        let s2 = self.rwr / (self.n.checked_sub(p)?.max(1)) as f64;
        let n = self.n + nc;
        let rwr = s2 * (n.checked_sub(q)?) as f64;
        let mut scales = self.scales.clone();
        scales.extend_from_slice(scales_c);
        let mut labels = self.labels.clone();
        labels.extend((0..k).map(|i| format!("candidate:{i}")));
        uncertainty_of(&h, rwr, n, scales, labels)
    }
}

/// Simulates `candidate` with the shared coordinates `shared_x` (the fit's), observes it with
/// `rig` (noise-free) and predicts the standard errors with it added to `current`. `params`:
/// the shared parameters, then the candidate's own ones (those of the study's that its model
/// has, else none).
pub fn predict(
    candidate: &Candidate,
    shared: &ParamSet,
    own: &[String],
    shared_x: &[f64],
    current: &Current,
    rig: &RigParams,
) -> Prediction {
    let fail = |e: String| Prediction {
        name: candidate.name,
        what: candidate.what.clone(),
        points: 0,
        std_errors: None,
        error: Some(e),
    };
    match try_predict(candidate, shared, own, shared_x, current, rig) {
        Ok((points, u)) => Prediction {
            name: candidate.name,
            what: candidate.what.clone(),
            points,
            std_errors: Some(u.std_errors[..current.shared].to_vec()),
            error: None,
        },
        Err(e) => fail(e.to_string()),
    }
}

fn try_predict(
    candidate: &Candidate,
    shared: &ParamSet,
    own: &[String],
    shared_x: &[f64],
    current: &Current,
    rig: &RigParams,
) -> Result<(usize, Uncertainty), Error> {
    let scene = &candidate.scene;
    let mut sim = scene.build_simulation()?;
    // the study's own parameters that this motion's model has (a thrown body has no ground)
    let mut names: Vec<String> = shared.params.iter().map(|p| p.name().to_string()).collect();
    let with_own: Vec<String> = names.iter().chain(own).cloned().collect();
    let params = match ParamSet::parse(&with_own).and_then(|p| p.layout(&sim.model).map(|_| p)) {
        Ok(p) => p,
        Err(_) => {
            names.retain(|n| n != Param::StiffnessField.name());
            ParamSet::parse(&names)?
        }
    };
    let layout = params.layout(&sim.model)?;
    let mut x = layout.to_x(&sim.model);
    if x.len() < shared_x.len() {
        return Err(Error::invalid("the candidate lacks a shared parameter"));
    }
    x[..shared_x.len()].copy_from_slice(shared_x);
    layout.apply(&x, &mut sim.model);
    let steps = scene.time.steps;
    let frames: Vec<usize> = (1..=steps).collect();
    let run = observe_run(&mut sim, rig, 0.0, &frames, |_| {})?;
    if run.observations.is_empty() {
        return Err(Error::invalid("the cameras saw nothing of it"));
    }
    let eyes: Vec<[f64; 3]> = run.cameras.iter().map(|c| c.camera.eye).collect();
    let mut problem = scene_problem(
        scene,
        &run.observations,
        params,
        Robust::Squared,
        Some(steps),
        CostKind::Surface,
        &eyes,
    )?;
    let (ev, _, hc) = problem.gauss_newton(&x)?;
    let nc: usize = ev.frames.iter().map(|f| f.informative).sum();
    let scales = problem.params.x_scales(&problem.model_at(&x));
    let u = current
        .with(&hc, &scales[current.shared..], nc)
        .ok_or_else(|| Error::invalid("its Gauss-Newton matrix leaves the study's singular"))?;
    Ok((nc, u))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_candidate_adds_information_by_the_block_structure() {
        // one shared coordinate, one own: H = [[4, 1], [1, 2]], 102 points, r^T W r = 100
        let cur = Current {
            h: vec![4.0, 1.0, 1.0, 2.0],
            rwr: 100.0,
            n: 102,
            scales: vec![1.0, 1.0],
            labels: vec!["a".into(), "b".into()],
            shared: 1,
        };
        let se0 = cur.uncertainty().unwrap().std_errors[0];
        // s^2 = 1; C = H^-1: C_aa = 2 / 7
        assert!((se0 - (2.0f64 / 7.0).sqrt()).abs() < 1e-12);
        // a candidate seeing only the shared coordinate, H_c = [[3]]: H' = [[7, 1], [1, 2]]
        let with = cur.with(&[3.0], &[], 50).unwrap();
        assert!((with.std_errors[0] - (2.0f64 / 13.0).sqrt()).abs() < 1e-12);
        // one with its own coordinate fully correlated with the shared one adds nothing
        let none = cur.with(&[1.0, 1.0, 1.0, 1.0], &[1.0], 50).unwrap();
        assert!(
            (none.std_errors[0] - se0).abs() < 1e-9,
            "{} {se0}",
            none.std_errors[0]
        );
        // wrong sizes are refused
        assert!(cur.with(&[1.0, 2.0], &[], 5).is_none());
    }

    /// Issue 51: every candidate of the menu, for a scene with each hold and contact the menu
    /// edits (a ground with friction, a clamp on its box, both), is a consistent scene that
    /// builds its simulation: a released body loses its clamp, a free flight its ground and
    /// friction (`--design` failed for any scene with a ground or a clamp).
    #[test]
    fn every_candidate_of_every_scene_builds() {
        let base = "[body]\nshape = { kind = \"box\", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }\nresolution = 10\n[material]\nyoung = 2000.0\npoisson = 0.3\n[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[time]\ndt = 0.01\nsteps = 4\n";
        let ground = "[ground]\nnormal = [0.0, 1.0, 0.0]\nheight = 0.5\n[friction]\ncoefficient = 0.3\n";
        let clamp =
            "[[dirichlet]]\nmin = [-1.0, 0.0, -1.0]\nmax = [-0.2, 2.0, 1.0]\n[clamp]\nstiffness = 1e4\n";
        for (extra, effects) in [
            (ground.to_string(), "\"ground\", \"friction\""),
            (clamp.to_string(), "\"clamp\""),
            (format!("{ground}{clamp}"), "\"ground\", \"friction\", \"clamp\""),
        ] {
            let text = format!("{base}{extra}[model]\neffects = [\"gravity\", {effects}]\n");
            let scene = Scene::parse(&text, std::path::Path::new("user.toml")).unwrap();
            let (ok, failed) = checked_candidates(&scene, [-0.3, 0.9, -0.15], [0.3, 1.1, 0.15]);
            assert!(
                failed.is_empty(),
                "{effects}: {:?}",
                failed.iter().map(|p| &p.error).collect::<Vec<_>>()
            );
            assert!(ok.len() >= 3, "{effects}");
            for c in &ok {
                c.scene
                    .build_simulation()
                    .unwrap_or_else(|e| panic!("{effects}: `{}`: {e}", c.name));
            }
        }
        // an edit that leaves a scene inconsistent is caught where it is made, named
        let mut s = Scene::parse(
            &format!("{base}[model]\neffects = [\"gravity\"]\n"),
            std::path::Path::new("user.toml"),
        )
        .unwrap();
        s.time.theta = 0.2;
        let e = s.derived("design candidate `x`").unwrap_err().to_string();
        assert!(
            e.starts_with("design candidate `x` (derived from user.toml): time.theta"),
            "{e}"
        );
    }
}
