//! Telling indistinguishable alternatives apart: when two effects explain the recording alike
//! (Delta BIC within the threshold: drag and mass damping on a slender bar), the report names
//! the motion of the experiment-design menu ([`crate::study::design::candidates`]: dropped,
//! squeezed, thrown, struck) under which their fitted models differ most.
//!
//! Each alternative's refitted model is written back into its scene
//! ([`super::effects::write_back_all`]; a stiffness field's factors, which live in the fit's
//! result, are carried over on the same grid), each menu motion is made of that scene (the same
//! edits for both: same initial velocity, ground and holds), and both are simulated. The
//! predicted difference is the rms over frames and surface vertices of the distance between
//! the two deformed surfaces (one mesh topology: one body, one grid). A motion that separates
//! them by several noise floors would tell them apart when recorded; one below the floor would
//! not.

use super::plausible::fitted;
use super::score::Candidate;
use crate::Error;
use cutfem::scene::Scene;

/// The motion that separates two alternatives most.
#[derive(Clone, Debug, PartialEq)]
pub struct Separation {
    /// the two effects
    pub effects: [String; 2],
    /// the motion's name (`drop`, `squeeze`, `throw`, `strike`)
    pub motion: String,
    /// what is done to the body
    pub what: String,
    /// the rms distance between the two fitted models' surfaces under that motion
    pub difference: f64,
    /// the same under the recorded motion (how alike they are on the data)
    pub recorded: f64,
}

/// The verdict's line for a separation, against the noise floor when known.
pub fn advice(s: &Separation, floor: Option<f64>) -> String {
    let short = super::effects::short;
    let against = match floor {
        Some(f) if f > 0.0 => format!(" ({:.1}x the noise floor)", s.difference / f),
        _ => String::new(),
    };
    format!(
        "\nto tell {} from {}: record a `{}` motion ({}); their fitted models' surfaces differ by \
         {} rms there{against}, against {} on this recording",
        s.effects[0],
        s.effects[1],
        s.motion,
        s.what,
        short(s.difference),
        short(s.recorded)
    )
}

/// The surface vertices of every frame (0..=steps) of `scene`'s simulation, with a stiffness
/// field's factors `scale` when given.
fn trajectory(scene: &Scene, scale: Option<&std::sync::Arc<[f64]>>) -> Result<Vec<Vec<[f64; 3]>>, Error> {
    let mut out = Vec::new();
    super::plausible::run(scene, scale, |_, v| out.push(v))?;
    Ok(out)
}

/// The rms distance between two trajectories of one surface (`None` when their sizes differ).
fn rms_distance(a: &[Vec<[f64; 3]>], b: &[Vec<[f64; 3]>]) -> Option<f64> {
    if a.len() != b.len() || a.iter().zip(b).any(|(x, y)| x.len() != y.len()) {
        return None;
    }
    let (mut sum, mut n) = (0.0, 0usize);
    for (fa, fb) in a.iter().zip(b) {
        for (p, q) in fa.iter().zip(fb) {
            sum += (0..3).map(|d| (p[d] - q[d]).powi(2)).sum::<f64>();
            n += 1;
        }
    }
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// The menu motion under which the refitted models of `a` and `b` differ most (module docs);
/// `None` when either has no refit or no motion could be simulated for both.
pub fn separating_motion(a: &Candidate, b: &Candidate) -> Result<Option<Separation>, Error> {
    let (Some((sa, fa)), Some((sb, fb))) = (fitted(a), fitted(b)) else {
        return Ok(None);
    };
    let (ra, rb) = (trajectory(&sa, fa.as_ref())?, trajectory(&sb, fb.as_ref())?);
    let recorded = rms_distance(&ra, &rb);
    // the reference surface's box (frame 0: at rest) places the motions, as the design does
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for v in ra.first().into_iter().flatten() {
        for d in 0..3 {
            lo[d] = lo[d].min(v[d]);
            hi[d] = hi[d].max(v[d]);
        }
    }
    let (menu_a, _) = crate::study::design::checked_candidates(&sa, lo, hi);
    let (menu_b, _) = crate::study::design::checked_candidates(&sb, lo, hi);
    let mut best: Option<Separation> = None;
    for ma in &menu_a {
        let Some(mb) = menu_b.iter().find(|m| m.name == ma.name) else {
            continue;
        };
        // a motion that cannot be simulated for one of them tells nothing
        let (Ok(ta), Ok(tb)) = (
            trajectory(&ma.scene, fa.as_ref()),
            trajectory(&mb.scene, fb.as_ref()),
        ) else {
            continue;
        };
        let Some(d) = rms_distance(&ta, &tb).filter(|d| d.is_finite()) else {
            continue;
        };
        if best.as_ref().map_or(true, |s| d > s.difference) {
            best = Some(Separation {
                effects: [a.effect.clone(), b.effect.clone()],
                motion: ma.name.to_string(),
                what: ma.what.clone(),
                difference: d,
                recorded: recorded.unwrap_or(f64::NAN),
            });
        }
    }
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A refitted candidate of the tiny clamped bar with Rayleigh mass damping `alpha`.
    fn candidate(effect: &str, alpha: f64) -> Candidate {
        let text = format!(
            "[body]\nshape = {{ kind = \"box\", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }}\nresolution = 10\n[material]\nyoung = 2000.0\npoisson = 0.3\n[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[damping]\nmass = {alpha:?}\nstiffness = 0.0\n[[dirichlet]]\nmin = [-1.0, 0.0, -1.0]\nmax = [-0.2, 2.0, 1.0]\n[time]\ndt = 0.01\nsteps = 6\n[model]\neffects = [\"gravity\", \"damping\"]\n"
        );
        let scene = Scene::parse(&text, std::path::Path::new("bar.toml")).unwrap();
        let model = scene.to_model();
        Candidate::refitted(effect, scene, model)
    }

    /// Two identical fitted models are not separated by any motion (difference 0 under the
    /// best one and on the recording); two that differ are, by the motion of the menu where
    /// they differ most, and more than on a recording they explain alike.
    #[test]
    fn the_motion_that_separates_most_is_named() {
        let a = candidate("drag", 0.5);
        let same = separating_motion(&a, &candidate("damping", 0.5))
            .unwrap()
            .unwrap();
        assert_eq!((same.difference, same.recorded), (0.0, 0.0), "{same:?}");
        let other = separating_motion(&a, &candidate("damping", 20.0))
            .unwrap()
            .unwrap();
        assert!(other.difference > 0.0 && other.recorded > 0.0, "{other:?}");
        assert!(["drop", "squeeze", "throw", "strike"].contains(&other.motion.as_str()));
        assert_eq!(other.effects, ["drag".to_string(), "damping".to_string()]);
        let line = advice(&other, Some(other.difference / 4.0));
        assert!(line.contains("to tell drag from damping: record a `"), "{line}");
        assert!(line.contains("(4.0x the noise floor)"), "{line}");
    }
}
