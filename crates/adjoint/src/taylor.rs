//! The Taylor remainder test of a gradient over a sweep of steps (pyadjoint's `taylor_test`).
//!
//! For a cost `J`, a gradient `g` and steps `h_1 > h_2 > ...` (decades), the remainders
//!
//! - `r0(h) = max_± |J(x ± h) - J(x)|`, which falls as `O(h)`, and
//! - `r1(h) = max_± |J(x ± h) - J(x) ∓ h g|` (adjoint-corrected), which falls as `O(h^2)` when
//!   `g` is the derivative and `J` is smooth within `h`,
//!
//! give observed orders `log(r(h_i) / r(h_{i+1})) / log(h_i / h_{i+1})` between neighbouring
//! steps. One finite-difference step can land across a kink of a piecewise-smooth cost (the
//! ray-distance cost: rays change faces) and report a large error although the gradient is
//! right; the sweep tells the cases apart:
//!
//! - [`Smoothness::Smooth`]: some pair of steps shows the second order (`r1` order within
//!   [`ORDER_TWO`]): the gradient is verified at those steps. Larger steps whose order is off
//!   are reported as the scale from which the cost is not smooth ([`Sweep::non_smooth_from`]).
//! - [`Smoothness::Exact`]: `r1` is at round-off at every step while `r0` is not (a cost linear
//!   in the parameter): verified.
//! - [`Smoothness::NonSmooth`]: no pair shows the second order: the cost is not smooth at the
//!   steps tried (or the gradient is wrong; the report says both), and central differences
//!   cannot verify the gradient there.

/// The relative steps of the sweep: decades `1e-1 ..= 1e-8` of the parameter's scale.
pub const DECADES: [f64; 8] = [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8];

/// Observed orders within this range count as the second order of `r1`.
pub const ORDER_TWO: (f64, f64) = (1.8, 2.2);

/// Remainders below `ROUND_OFF * max(|J|)` are round-off: no order is computed from them.
pub const ROUND_OFF: f64 = 1e-14;

/// The cost at one step on both sides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// the step `h` (in the parameter's units)
    pub step: f64,
    /// `J(x + h)`
    pub plus: f64,
    /// `J(x - h)`
    pub minus: f64,
}

/// What one step of the sweep shows.
#[derive(Clone, Debug, PartialEq)]
pub struct StepResult {
    /// the step `h`
    pub step: f64,
    /// the central difference `(J(x+h) - J(x-h)) / 2h`
    pub finite_difference: f64,
    /// `|g - fd| / max(|g|, |fd|)` (0 when both vanish)
    pub rel_error: f64,
    /// `r0(h)`
    pub remainder: f64,
    /// `r1(h)` (adjoint-corrected)
    pub corrected_remainder: f64,
    /// the order of `r0` between this step and the next smaller one
    pub order: Option<f64>,
    /// the order of `r1` between this step and the next smaller one
    pub corrected_order: Option<f64>,
}

/// How smooth the cost looks over the sweep (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Smoothness {
    /// second order observed at some steps
    Smooth,
    /// `r1` at round-off at every step
    Exact,
    /// no step shows the second order
    NonSmooth,
}

impl Smoothness {
    /// `smooth`, `exact`, `non_smooth`.
    pub fn name(self) -> &'static str {
        match self {
            Smoothness::Smooth => "smooth",
            Smoothness::Exact => "exact",
            Smoothness::NonSmooth => "non_smooth",
        }
    }
}

/// The result of a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// per step, largest first
    pub steps: Vec<StepResult>,
    /// the step with the smallest relative error
    pub best: usize,
    /// the verdict
    pub smoothness: Smoothness,
    /// `(smallest, largest)` step of the pairs with the second order
    pub smooth_range: Option<(f64, f64)>,
    /// the smallest step above the smooth range whose order is off: the cost is not smooth
    /// at this scale and above
    pub non_smooth_from: Option<f64>,
    /// the observed order of `r0` nearest 1
    pub order: Option<f64>,
    /// the observed order of `r1` nearest 2
    pub corrected_order: Option<f64>,
    /// one sentence for a reader
    pub summary: String,
}

/// `|a - b| / max(|a|, |b|)`, 0 when both vanish.
pub fn rel_error(a: f64, b: f64) -> f64 {
    let den = a.abs().max(b.abs());
    if den == 0.0 {
        0.0
    } else {
        (a - b).abs() / den
    }
}

fn order(r: (f64, f64), h: (f64, f64), floor: f64) -> Option<f64> {
    (r.0 > floor && r.1 > floor && h.0 > h.1).then(|| (r.0 / r.1).ln() / (h.0 / h.1).ln())
}

fn nearest(values: impl Iterator<Item = f64>, to: f64) -> Option<f64> {
    values.min_by(|a, b| (a - to).abs().total_cmp(&(b - to).abs()))
}

/// Analyses the samples (any order; steps distinct and positive) of a cost `j0 = J(x)` with
/// gradient `gradient` (module docs). `None` without a sample.
pub fn analyse(j0: f64, gradient: f64, samples: &[Sample]) -> Option<Sweep> {
    let mut samples = samples.to_vec();
    samples.sort_by(|a, b| b.step.total_cmp(&a.step));
    samples.dedup_by(|a, b| a.step == b.step);
    let scale = samples
        .iter()
        .fold(j0.abs(), |m, s| m.max(s.plus.abs()).max(s.minus.abs()));
    let floor = ROUND_OFF * scale + f64::MIN_POSITIVE;
    let mut steps: Vec<StepResult> = samples
        .iter()
        .map(|s| {
            let h = s.step;
            let fd = (s.plus - s.minus) / (2.0 * h);
            StepResult {
                step: h,
                finite_difference: fd,
                rel_error: rel_error(gradient, fd),
                remainder: (s.plus - j0).abs().max((s.minus - j0).abs()),
                corrected_remainder: (s.plus - j0 - h * gradient)
                    .abs()
                    .max((s.minus - j0 + h * gradient).abs()),
                order: None,
                corrected_order: None,
            }
        })
        .collect();
    for i in 0..steps.len().saturating_sub(1) {
        let h = (steps[i].step, steps[i + 1].step);
        steps[i].order = order((steps[i].remainder, steps[i + 1].remainder), h, floor);
        steps[i].corrected_order = order(
            (steps[i].corrected_remainder, steps[i + 1].corrected_remainder),
            h,
            floor,
        );
    }
    let best = (0..steps.len()).min_by(|&a, &b| steps[a].rel_error.total_cmp(&steps[b].rel_error))?;
    let two = |p: f64| (ORDER_TWO.0..=ORDER_TWO.1).contains(&p);
    let second: Vec<usize> = (0..steps.len())
        .filter(|&i| steps[i].corrected_order.is_some_and(two))
        .collect();
    let smooth_range = match (second.first(), second.last()) {
        (Some(&first), Some(&last)) => Some((steps[last + 1].step, steps[first].step)),
        _ => None,
    };
    // above the smooth range: the smallest step whose pair is off the second order
    let non_smooth_from = second.first().and_then(|&first| {
        (0..first)
            .rev()
            .find(|&i| steps[i].corrected_order.is_some_and(|p| !two(p)))
            .map(|i| steps[i].step)
    });
    let exact =
        steps.iter().all(|s| s.corrected_remainder <= floor) && steps.iter().any(|s| s.remainder > floor);
    let smoothness = if !second.is_empty() {
        Smoothness::Smooth
    } else if exact {
        Smoothness::Exact
    } else {
        Smoothness::NonSmooth
    };
    let b = &steps[best];
    let orders: Vec<String> = steps
        .iter()
        .filter_map(|s| s.corrected_order.map(|p| format!("{p:.2}")))
        .collect();
    let summary = match smoothness {
        Smoothness::Smooth => {
            let (lo, hi) = smooth_range.expect("second order found");
            let mut s = format!(
                "second-order Taylor remainder at steps {lo:.0e}..{hi:.0e}: the gradient is verified \
                 (best agreement {:.1e} at step {:.0e})",
                b.rel_error, b.step
            );
            if let Some(h) = non_smooth_from {
                s.push_str(&format!(
                    "; the cost is not smooth at steps of {h:.0e} and above (a kink within that \
                     distance), so a single step there would disagree"
                ));
            }
            s
        }
        Smoothness::Exact => format!(
            "the adjoint-corrected remainder is at round-off at every step (the cost is linear \
             here): the gradient is verified (best agreement {:.1e})",
            b.rel_error
        ),
        Smoothness::NonSmooth => format!(
            "the cost is not smooth at the steps tried ({:.0e}..{:.0e}): the adjoint-corrected \
             remainder never falls at second order (orders [{}]), so finite differences cannot \
             verify the gradient here (or it is wrong); best agreement {:.1e} at step {:.0e}",
            steps.last().map_or(0.0, |s| s.step),
            steps[0].step,
            orders.join(", "),
            b.rel_error,
            b.step
        ),
    };
    Some(Sweep {
        order: nearest(steps.iter().filter_map(|s| s.order), 1.0),
        corrected_order: nearest(steps.iter().filter_map(|s| s.corrected_order), 2.0),
        steps,
        best,
        smoothness,
        smooth_range,
        non_smooth_from,
        summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sweep(f: impl Fn(f64) -> f64, x: f64, g: f64) -> Sweep {
        let samples: Vec<Sample> = DECADES
            .iter()
            .map(|&r| Sample {
                step: r,
                plus: f(x + r),
                minus: f(x - r),
            })
            .collect();
        analyse(f(x), g, &samples).unwrap()
    }

    #[test]
    fn a_smooth_cost_shows_the_second_order() {
        let f = |x: f64| (2.0 * x).sin() + x * x * x;
        let x = 0.7;
        let s = sweep(f, x, 2.0 * (2.0 * x).cos() + 3.0 * x * x);
        assert_eq!(s.smoothness, Smoothness::Smooth, "{}", s.summary);
        let p = s.corrected_order.unwrap();
        assert!((1.8..=2.2).contains(&p), "order {p}");
        assert!((s.order.unwrap() - 1.0).abs() < 0.2);
        assert!(s.steps[s.best].rel_error < 1e-8, "{:?}", s.steps[s.best]);
        assert!(s.non_smooth_from.is_none(), "{}", s.summary);
    }

    #[test]
    fn a_wrong_gradient_is_not_verified() {
        let f = |x: f64| (2.0 * x).sin() + x * x * x;
        let x = 0.7;
        let s = sweep(f, x, 1.1 * (2.0 * (2.0 * x).cos() + 3.0 * x * x));
        assert_eq!(s.smoothness, Smoothness::NonSmooth, "{}", s.summary);
        assert!(s.steps[s.best].rel_error > 0.05);
    }

    #[test]
    fn a_kink_near_the_point_is_named_not_called_a_wrong_gradient() {
        // a kink 5e-5 from x: a step of 1e-4 (the old default) crosses it
        let x = 1.0;
        let f = |y: f64| y * y + 0.5 * (y - (x + 5e-5)).abs();
        let g = 2.0 * x - 0.5;
        let h = 1e-4;
        let single = rel_error(g, (f(x + h) - f(x - h)) / (2.0 * h));
        assert!(single > 0.1, "one step across the kink disagrees: {single}");
        let s = sweep(f, x, g);
        assert_eq!(s.smoothness, Smoothness::Smooth, "{}", s.summary);
        let (lo, hi) = s.smooth_range.unwrap();
        assert!(hi <= 1e-5 && lo < hi, "{:?}", s.smooth_range);
        assert_eq!(s.non_smooth_from, Some(1e-4), "{}", s.summary);
        assert!(s.summary.contains("not smooth at steps of 1e-4"), "{}", s.summary);
        assert!(s.steps[s.best].rel_error < 1e-8);
    }

    #[test]
    fn a_cost_kinked_at_the_point_is_non_smooth() {
        // a kink at x itself: the remainder falls at first order at every step
        let x = 0.3;
        let f = |y: f64| y * y + 0.5 * (y - x).abs();
        let s = sweep(f, x, 2.0 * x);
        assert_eq!(s.smoothness, Smoothness::NonSmooth, "{}", s.summary);
        assert!(s.summary.contains("not smooth"), "{}", s.summary);
        let p = s.corrected_order.unwrap();
        assert!((p - 1.0).abs() < 0.1, "order {p}");
    }

    #[test]
    fn a_linear_cost_is_exact() {
        let s = sweep(|y| 3.0 * y + 1.0, 0.5, 3.0);
        assert_eq!(s.smoothness, Smoothness::Exact, "{}", s.summary);
    }
}
