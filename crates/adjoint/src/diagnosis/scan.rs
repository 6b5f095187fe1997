//! Where a diagnosis refit starts ([`super::score::refit`]): two cheap scans along the effect's
//! own coordinates, one forward run per point tried, before Levenberg-Marquardt.
//!
//! - [`magnitudes`]: log coordinates `q = e^x` (damping, drag) raised by decades while the
//!   cost `C(x)` falls; an effect probed at a tiny neutral value is many e-folds from its value.
//! - [`step`]: linear coordinates (gravity, initial velocity) stretched along the probe's
//!   Gauss-Newton step `dx = -H^{-1} g` (the score test's, [`super::score`]),
//!   doubling `x_k - x0_k` while `C` falls; the step is the linearisation's answer, and an effect
//!   that switches a nonlinearity on (a contact) is far from linear at its neutral value.

use crate::problem::Problem;

/// Decades tried per coordinate by [`magnitudes`].
const MAX_DECADES: usize = 8;

/// Raises each of the effect's log coordinates of `start` (those from `first` on) by decades
/// while the cost (`cost` at `start`) falls, at most [`MAX_DECADES`] each, within the box of
/// [`crate::params::ParamSet::bounds`]. An effect probed at a tiny neutral value (damping at 1e-4) is many
/// e-folds from its value, and a log coordinate that far off moves about one e-fold per
/// Levenberg-Marquardt iteration: the torus' mass damping (true 8) got from 1e-4 to 0.08 in the
/// 8 iterations of a short refit, which then lost to a wrong effect. One forward run per decade
/// tried.
pub(super) fn magnitudes(problem: &mut Problem, first: usize, start: &mut [f64], mut cost: f64) {
    let logs = problem.params.log_coordinates();
    let bounds = problem.params.bounds(start);
    for k in (first..start.len()).filter(|&k| logs[k]) {
        for _ in 0..MAX_DECADES {
            let mut x = start.to_vec();
            x[k] += 10f64.ln();
            if x[k] > bounds[k].1 {
                break;
            }
            match problem.evaluate(&x) {
                Ok(e) if e.cost < cost => {
                    cost = e.cost;
                    start[k] = x[k];
                }
                _ => break,
            }
        }
    }
}

/// Doublings tried per coordinate by [`step`].
const MAX_DOUBLINGS: usize = 6;

/// Stretches each of the effect's linear coordinates of `start` (those from `first` on that are
/// not log coordinates), the largest displacement first, along its displacement from the probe
/// value `x0` (the probe's step `step` where `start` has none), doubling it while the cost
/// (`cost` at `start`) falls, at most [`MAX_DOUBLINGS`] times each, within the box of
/// [`crate::params::ParamSet::bounds`] (a stiffness field's log factors are left to the fit
/// and its prior: the scan sees the data's cost alone). The probe's Gauss-Newton step is the
/// linearisation's answer at the neutral value, and an effect that switches a nonlinearity on is far from
/// linear there: gravity switched on under a body at rest just above a ground predicts
/// `|g| = 0.75` where the truth is 10 (the cost falls monotonically to it), and
/// Levenberg-Marquardt from 0.75 spent its 8 iterations on Young's modulus instead (the static
/// squash on the ground couples `g` and `E`). Per coordinate, because the step's small
/// components are its least certain: doubled with the large one, a sideways gravity made the
/// bar slide. The largest component tries every doubling and keeps the best (a contact's
/// timing makes the cost bumpy along it: a box's landing cost more at `g = 2.4` than at 1.2,
/// and least near the true 10); the others stop at the first that does not lower the cost.
/// One forward run per doubling tried.
pub(super) fn step(
    problem: &mut Problem,
    first: usize,
    x0: &[f64],
    step: &[f64],
    start: &mut [f64],
    mut cost: f64,
) {
    let logs = problem.params.log_coordinates();
    let field = problem.params.field_coordinates();
    let mut linear: Vec<(usize, f64)> = (first..start.len())
        .filter(|&k| !logs[k] && !field[k])
        .map(|k| (k, start[k] - x0[k]))
        .collect();
    if linear.iter().all(|&(_, d)| d == 0.0) && step.len() == start.len() {
        // `start` is the probe value: the first try is the step itself
        for (k, d) in linear.iter_mut() {
            *d = step[*k] / 2.0;
        }
    }
    linear.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    let bounds = problem.params.bounds(start);
    for (i, (k, mut d)) in linear.into_iter().filter(|&(_, d)| d != 0.0).enumerate() {
        let mut tried = start[k];
        for _ in 0..MAX_DOUBLINGS {
            d *= 2.0;
            let mut x = start.to_vec();
            x[k] = (x0[k] + d).clamp(bounds[k].0, bounds[k].1);
            if x[k] == tried {
                break; // on its bound
            }
            tried = x[k];
            match problem.evaluate(&x) {
                Ok(e) if e.cost < cost => {
                    cost = e.cost;
                    start[k] = x[k];
                }
                // the largest component walks the whole ladder
                _ if i == 0 => {}
                _ => break,
            }
        }
    }
}
