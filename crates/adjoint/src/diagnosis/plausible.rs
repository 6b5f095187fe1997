//! Plausibility of a fitted effect (issue 50, item 2): what the fitted values imply physically,
//! judged on the fitted model's own motion over the recording, and whether a body could do it.
//! A wrong effect often explains a misfit only with values no body has: a box dropped onto a
//! ground the model lacks was explained by drag so strong that the box sank at its terminal
//! velocity, as in honey (`c = 6.3`).
//!
//! The refitted model is simulated once over the recording ([`Motion`]) and each effect reads
//! its values against it ([`super::effects::Effect::judge`]):
//!
//! | effect | what it implies | implausible when |
//! |---|---|---|
//! | `drag` (traction `-c v`) | terminal velocity `v_t = m g / (c A)` (free body under gravity); else the decay time `m / (c A)` of a rigid motion | a free body: drag holds up more than half its weight at its fastest speed, `c A v_max > m g / 2` (in air: a fraction of a percent) |
//! | `damping` (`D = a1 M + a2 K`) | the damping ratio `zeta = a1 / (2 w) + a2 w / 2` at the recorded deformation's frequency `w` (held body; `w^2 = u^T K u / u^T M u` at its most strained frame, a Rayleigh quotient); on a free body, `a1` is a drag on the rigid motion with terminal velocity `g / a1` | a free body: `a1 v_max > g / 2` (as for drag) |
//! | `ground` (`n . x >= h`) | the body's closest approach to the plane | the body never comes within `max(h_grid, 3 sigma)` of it (it cannot act), or more than 1% of the observed points lie more than `max(3 sigma, h_grid / 2)` below it (the body passes through) |
//! | `stiffness_field` (factors `s_e` on `E`) | the contrast `max s_e / min s_e` | the contrast exceeds [`MAX_CONTRAST`] (not a variation of one material) |
//! | `clamp` (springs `k` on the held surface) | the springs as a layer of the body's own material, thickness `(lambda + 2 mu) / k`; how far the held surface moves against the body's largest displacement | the held surface moves at least [`MAX_HELD_SHARE`] as far as any point of the body (it does not hold it) |
//!
//! Not judged: `gravity`, `initial_velocity` and `wind` (no bound holds in every unit system and
//! every experiment: a scene's lengths and times are the user's), `corotation` (no values) and
//! `friction` (its regularised coefficient `mu` is a Coulomb coefficient only through the
//! sliding speed at each contact, `mu_C = mu v_t`, which the motion's summary does not hold).
//!
//! The thresholds are physical, not fitted to cases: half the weight is where drag, not gravity,
//! sets the fall; 1% of points 3 sigma below a plane is 8 times what Gaussian noise puts there.

use super::effects;
use super::score::Candidate;
use crate::observations::Observations;
use crate::Error;
use cutfem::fem::Simulation;
use cutfem::scene::Scene;
use std::sync::Arc;

/// A stiffness field whose factors differ by more than this is a second material, not a
/// variation of one (healthy and diseased soft tissue differ by up to about 10x).
pub const MAX_CONTRAST: f64 = 1e3;

/// A clamp whose held surface moves this share of the body's largest displacement or more does
/// not hold the body (an imperfect clamp still holds its part more than the rest moves).
pub const MAX_HELD_SHARE: f64 = 0.5;

/// What the fitted model's own simulation over the recording shows.
#[derive(Clone, Debug)]
pub struct Motion<'a> {
    /// total mass
    pub mass: f64,
    /// `|g|` of the fitted model
    pub gravity: f64,
    /// the recording's duration (frames x frame interval)
    pub duration: f64,
    /// whether the body is held (Dirichlet boxes or a clamp)
    pub held: bool,
    /// the largest speed of the surface's centroid between two frames
    pub fastest: f64,
    /// held bodies: the frequency (rad per time) of the most strained frame's deformation,
    /// `sqrt(u^T K u / u^T M u)`
    pub frequency: Option<f64>,
    /// the surface's vertices at every frame (0 = at rest)
    pub surfaces: Vec<Vec<[f64; 3]>>,
    /// the grid spacing
    pub spacing: f64,
    /// the observations
    pub observations: &'a Observations,
    /// the noise floor, when known
    pub floor: Option<f64>,
}

/// An effect's reading of its fitted values ([`super::effects::Effect::judge`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Judgement {
    /// what the values imply, in words
    pub implies: String,
    /// why no body could do that, if so
    pub implausible: Option<String>,
}

/// The named effect's [`Judgement`], for the report.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Plausibility {
    /// the effect
    pub effect: String,
    /// what its fitted values imply
    pub implies: String,
    /// why they are implausible, if so
    pub implausible: Option<String>,
}

/// Runs `scene`'s simulation with a stiffness field's factors `scale`, calling `visit` with the
/// simulation and its deformed surface's vertices at every frame (0..=steps).
pub(super) fn run(
    scene: &Scene,
    scale: Option<&Arc<[f64]>>,
    mut visit: impl FnMut(&Simulation, Vec<[f64; 3]>),
) -> Result<(), Error> {
    let mut sim = scene.build_simulation()?;
    let mut model = sim.model.clone();
    if let Some(s) = scale {
        model.stiffness_scale = Some(Arc::clone(s));
    }
    let surface = sim.grid.surface()?;
    sim.reset(model)?;
    let v = sim.grid.deformed(&surface, &sim.u).vertices;
    visit(&sim, v);
    for t in 1..=scene.time.steps {
        sim.step().map_err(|e| Error::step(format!("step {t}"), e))?;
        let v = sim.grid.deformed(&surface, &sim.u).vertices;
        visit(&sim, v);
    }
    Ok(())
}

/// A candidate's refitted scene (its values written back) and its field's factors.
pub(super) fn fitted(c: &Candidate) -> Option<(Scene, Option<Arc<[f64]>>)> {
    let (scene, model) = (c.scene.as_ref()?, c.model.as_ref()?);
    let mut s = scene.clone();
    effects::write_back_all(&mut s, model);
    Some((s, model.stiffness_scale.clone()))
}

/// The mean of a point set.
fn centroid(points: &[[f64; 3]]) -> [f64; 3] {
    let n = points.len().max(1) as f64;
    let mut c = [0.0; 3];
    for p in points {
        for d in 0..3 {
            c[d] += p[d] / n;
        }
    }
    c
}

/// Simulates the refitted candidate `c` over the recording and reads its effect's values
/// against that motion; `None` when `c` has no refit or its effect says nothing.
pub fn judge(
    c: &Candidate,
    observations: &Observations,
    floor: Option<f64>,
) -> Result<Option<Plausibility>, Error> {
    let (Some((scene, scale)), Some(model)) = (fitted(c), c.model.as_ref()) else {
        return Ok(None);
    };
    let Some(effect) = effects::effect(&c.effect) else {
        return Ok(None);
    };
    let held = !model.dirichlet.is_empty();
    let (mut surfaces, mut mass, mut spacing) = (Vec::new(), 0.0, 0.0);
    // the most strained frame's Rayleigh quotient
    let (mut strain, mut frequency) = (0.0f64, None);
    run(&scene, scale.as_ref(), |sim, vertices| {
        if surfaces.is_empty() {
            mass = sim.total_mass();
            spacing = sim.grid.h();
        }
        if held {
            let energy = sim.elastic_energy();
            let mu = sim.mass_times(&sim.u);
            let inertia: f64 = mu
                .as_slice()
                .iter()
                .zip(sim.u.as_slice())
                .map(|(a, b)| a.dot(*b))
                .sum();
            if energy > strain && inertia > 0.0 {
                strain = energy;
                frequency = Some((2.0 * energy / inertia).sqrt());
            }
        }
        surfaces.push(vertices);
    })?;
    let dt = scene.time.dt;
    let centroids: Vec<[f64; 3]> = surfaces.iter().map(|s| centroid(s)).collect();
    let fastest = centroids
        .windows(2)
        .map(|w| (0..3).map(|d| (w[1][d] - w[0][d]).powi(2)).sum::<f64>().sqrt() / dt)
        .fold(0.0, f64::max);
    let g = model.gravity;
    let motion = Motion {
        mass,
        gravity: (g.x * g.x + g.y * g.y + g.z * g.z).sqrt(),
        duration: dt * scene.time.steps as f64,
        held,
        fastest,
        frequency,
        surfaces,
        spacing,
        observations,
        floor,
    };
    Ok(effect.judge(model, &motion).map(|j| Plausibility {
        effect: c.effect.clone(),
        implies: j.implies,
        implausible: j.implausible,
    }))
}

/// A velocity-proportional force of `per_speed` (force per unit speed) on the body's rigid
/// motion, read against `motion` ([`drag`] and the mass term of [`damping`]): its terminal
/// velocity under gravity, or its decay time; implausible on a free body when it holds up more
/// than half the weight at the fastest speed.
pub fn terminal(what: &str, per_speed: f64, motion: &Motion) -> Judgement {
    let short = effects::short;
    let weight = motion.mass * motion.gravity;
    if per_speed <= 0.0 || !per_speed.is_finite() {
        return Judgement {
            implies: format!("{what} is off (coefficient 0)"),
            implausible: None,
        };
    }
    if motion.held || weight <= 0.0 {
        return Judgement {
            implies: format!(
                "{what} stops a rigid motion within a decay time m / c = {} (recording {})",
                short(motion.mass / per_speed),
                short(motion.duration)
            ),
            implausible: None,
        };
    }
    let v_t = weight / per_speed;
    let share = per_speed * motion.fastest / weight;
    let implies = format!(
        "{what} gives the free body a terminal velocity of {} (its fastest speed here {}): it holds \
         up {:.0}% of the weight at that speed",
        short(v_t),
        short(motion.fastest),
        100.0 * share
    );
    let implausible = (share > 0.5).then(|| {
        format!(
            "{what} holds up {:.0}% of the body's weight at its fastest speed: the body sinks at its \
             terminal velocity, as in a liquid (in air a fraction of a percent); a ground or \
             support the model lacks can stop a body alike",
            100.0 * share
        )
    });
    Judgement { implies, implausible }
}

/// The ground plane `n . x >= height` read against `motion`: its closest approach to the
/// fitted body and the observed points below it (module docs).
pub fn plane(normal: [f64; 3], height: f64, motion: &Motion) -> Judgement {
    let short = effects::short;
    let above = |p: &[f64; 3]| normal[0] * p[0] + normal[1] * p[1] + normal[2] * p[2] - height;
    let (mut closest, mut frame) = (f64::INFINITY, 0);
    for (f, s) in motion.surfaces.iter().enumerate() {
        let c = s.iter().map(above).fold(f64::INFINITY, f64::min);
        if c < closest {
            (closest, frame) = (c, f);
        }
    }
    let sigma = motion.floor.unwrap_or(0.0);
    let reach = motion.spacing.max(3.0 * sigma);
    let depth = (3.0 * sigma).max(0.5 * motion.spacing);
    let (mut below, mut total, mut deepest) = (0usize, 0usize, 0.0f64);
    for (_, points) in motion.observations.frames() {
        for p in points {
            let d = above(&p.position);
            total += 1;
            if d < -depth {
                below += 1;
            }
            deepest = deepest.max(-d);
        }
    }
    let implies = if closest >= 0.0 {
        format!(
            "the plane comes within {} of the fitted body (frame {frame})",
            short(closest)
        )
    } else {
        format!(
            "the fitted body rests on the plane, its surface {} into it at the deepest (frame {frame})",
            short(-closest)
        )
    };
    let implausible = if closest > reach {
        Some(format!(
            "the fitted plane stays {} below the body at every frame (more than {}): it never \
             touches it, so it cannot be what stops it",
            short(closest),
            short(reach)
        ))
    } else if total > 0 && below as f64 > 0.01 * total as f64 {
        Some(format!(
            "{below} observed points ({:.1}%) lie more than {} below the fitted plane (deepest {}): \
             the body passes through it",
            100.0 * below as f64 / total as f64,
            short(depth),
            short(deepest)
        ))
    } else {
        None
    };
    Judgement { implies, implausible }
}

/// A clamp's springs `stiffness` (traction per unit displacement) on the surface the `boxes` hold,
/// for a material of P-wave modulus `p_modulus` (`lambda + 2 mu`), read against `motion`: the
/// springs as a layer of the body's material, and how far the held part of the rest surface
/// moves against the body's largest displacement (module docs).
pub fn held(boxes: &[cutfem::fem::Aabb], stiffness: f64, p_modulus: f64, motion: &Motion) -> Judgement {
    let short = effects::short;
    let Some(rest) = motion.surfaces.first() else {
        return Judgement {
            implies: "no motion to read the clamp against".into(),
            implausible: None,
        };
    };
    // which rest vertices the boxes hold, once
    let holds: Vec<bool> = rest
        .iter()
        .map(|p| boxes.iter().any(|b| b.contains(gpumat::Vec3::from_array(*p))))
        .collect();
    let (mut held, mut largest) = (0.0f64, 0.0f64);
    for frame in &motion.surfaces[1..] {
        for ((p, q), &h) in rest.iter().zip(frame).zip(&holds) {
            let d = (0..3).map(|a| (q[a] - p[a]).powi(2)).sum::<f64>().sqrt();
            largest = largest.max(d);
            if h {
                held = held.max(d);
            }
        }
    }
    let layer = p_modulus / stiffness;
    let share = if largest > 0.0 { held / largest } else { 0.0 };
    let implies = format!(
        "the clamp's springs are as stiff as a layer {} thick of the body's own material; the held          surface moves up to {}, {:.0}% of the body's largest displacement {}",
        short(layer),
        short(held),
        100.0 * share,
        short(largest)
    );
    let implausible = (largest > 0.0 && share >= MAX_HELD_SHARE).then(|| {
        format!(
            "the clamp lets the held surface move {:.0}% as far as any point of the body: it does              not hold it (a clamp holds its part more than the rest moves); a support or a motion              the model lacks can move a body alike",
            100.0 * share
        )
    });
    Judgement { implies, implausible }
}

/// A stiffness field's `factors` (on Young's modulus): their contrast.
pub fn contrast(factors: &[f64]) -> Judgement {
    let (lo, hi) = factors
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &s| (lo.min(s), hi.max(s)));
    if factors.is_empty() || lo <= 0.0 {
        return Judgement {
            implies: "no stiffness factors".into(),
            implausible: None,
        };
    }
    let c = hi / lo;
    Judgement {
        implies: format!(
            "Young's modulus varies {}x over the body (factors {} to {})",
            effects::short(c),
            effects::short(lo),
            effects::short(hi)
        ),
        implausible: (c > MAX_CONTRAST).then(|| {
            format!(
                "Young's modulus varies {}x over the body: a second material, not a variation of \
                 one (more than {}x)",
                effects::short(c),
                effects::short(MAX_CONTRAST)
            )
        }),
    }
}

#[cfg(test)]
mod tests;
