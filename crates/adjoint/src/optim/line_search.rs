//! Strong-Wolfe line search (Nocedal & Wright, *Numerical Optimization*, 2nd ed.,
//! Algorithms 3.5 and 3.6) that survives failing evaluations.
//!
//! Along a descent direction `d` at `x`, with `phi(a) = f(x + a d)`, it looks for a step
//! `a > 0` with
//!
//! ```text
//! phi(a) <= phi(0) + c1 a phi'(0)          (sufficient decrease, Armijo)
//! |phi'(a)| <= c2 |phi'(0)|                (strong curvature condition)
//! ```
//!
//! *Bracketing* (Alg. 3.5) grows the step by safeguarded cubic extrapolation (to between
//! `2.1` and `5` times the previous step) until an interval `[lo, hi]` contains such a
//! step; *zoom* (Alg. 3.6) then shrinks the interval with the minimizer of the cubic
//! interpolating `phi` and `phi'` at both ends (N&W eq. 3.59), kept at least 10% of the
//! interval away from either end, bisecting where the cubic has no minimizer.
//!
//! **Failed evaluations.** A step where the objective fails (the simulation diverged) is
//! taken as "too far": it becomes the upper end `hi` of the bracket, without a value, and
//! the next trial is `lo + 0.25 (hi - lo)`. After `max_consecutive_failures` failures in
//! a row the search reports a divergence.
//!
//! **Giving up.** When the interval collapses or `max_line_search_evaluations` are spent
//! without meeting the curvature condition, the lowest point that satisfies sufficient
//! decrease (`lo`) is accepted if it is not the start; otherwise the search fails.

use super::run::{add_scaled, dot, EvalFailure, Point, Run};
use super::types::Objective;

/// The next trial after a failed evaluation: this fraction of the way from `lo` to the
/// failed step.
pub(crate) const FAILURE_SHRINK: f64 = 0.25;

/// How a line search ended without an acceptable step.
#[derive(Clone, Debug)]
pub(crate) enum LineSearchFailure {
    /// No step with sufficient decrease was found.
    NoProgress,
    /// The evaluation budget is spent.
    Budget,
    /// The objective failed `max_consecutive_failures` times in a row.
    Diverged(String),
}

/// A point on the search line.
#[derive(Clone, Debug)]
struct Sample {
    a: f64,
    f: f64,
    df: f64,
    point: Point,
}

/// The far end of a bracket: evaluated, or a step where the objective failed.
#[derive(Clone, Debug)]
enum Far {
    Sample(Sample),
    Failed(f64),
}

impl Far {
    fn a(&self) -> f64 {
        match self {
            Far::Sample(s) => s.a,
            Far::Failed(a) => *a,
        }
    }
}

/// Minimizer of the cubic through `(a0, f0, d0)` and `(a1, f1, d1)`, if it exists.
fn cubic_min(a0: f64, f0: f64, d0: f64, a1: f64, f1: f64, d1: f64) -> Option<f64> {
    let e1 = d0 + d1 - 3.0 * (f0 - f1) / (a0 - a1);
    let disc = e1 * e1 - d0 * d1;
    if disc < 0.0 {
        return None;
    }
    let e2 = (a1 - a0).signum() * disc.sqrt();
    let a = a1 - (a1 - a0) * (d1 + e2 - e1) / (d1 - d0 + 2.0 * e2);
    a.is_finite().then_some(a)
}

struct Search<'r, 'p, 'c, O: ?Sized> {
    run: &'r mut Run<'p, 'c>,
    objective: &'r mut O,
    start: &'r Point,
    direction: &'r [f64],
    f0: f64,
    df0: f64,
    evaluations: usize,
    failures: usize,
}

impl<O: Objective + ?Sized> Search<'_, '_, '_, O> {
    /// Evaluates `phi(a)`. `Ok(None)` is a failed evaluation that may be retried closer.
    fn sample(&mut self, a: f64) -> Result<Option<Sample>, LineSearchFailure> {
        self.evaluations += 1;
        let x = add_scaled(&self.start.x, a, self.direction);
        match self.run.eval(self.objective, &x) {
            Ok(point) => {
                self.failures = 0;
                Ok(Some(Sample {
                    a,
                    f: point.cost,
                    df: dot(&point.gradient, self.direction),
                    point,
                }))
            }
            Err(EvalFailure::Budget) => Err(LineSearchFailure::Budget),
            Err(EvalFailure::Failed(message)) => {
                self.failures += 1;
                if self.failures > self.run.params.max_consecutive_failures {
                    Err(LineSearchFailure::Diverged(message))
                } else {
                    Ok(None)
                }
            }
        }
    }

    fn armijo(&self, s: &Sample) -> bool {
        s.f <= self.f0 + self.run.params.wolfe_c1 * s.a * self.df0
    }

    fn curvature(&self, s: &Sample) -> bool {
        s.df.abs() <= -self.run.params.wolfe_c2 * self.df0
    }

    fn out_of_budget(&self) -> bool {
        self.evaluations >= self.run.params.max_line_search_evaluations
    }

    /// The fallback when the search cannot finish: `lo` if it moved, else `failure`.
    fn give_up(lo: Sample, failure: LineSearchFailure) -> Result<(f64, Point), LineSearchFailure> {
        if lo.a > 0.0 {
            Ok((lo.a, lo.point))
        } else {
            Err(failure)
        }
    }

    /// N&W Alg. 3.5.
    fn bracket(mut self, a1: f64) -> Result<(f64, Point), LineSearchFailure> {
        let mut prev = Sample {
            a: 0.0,
            f: self.f0,
            df: self.df0,
            point: self.start.clone(),
        };
        let mut a = a1;
        loop {
            let s = match self.sample(a) {
                Ok(Some(s)) => s,
                Ok(None) => return self.zoom(prev, Far::Failed(a)),
                Err(e) => return Self::give_up(prev, e),
            };
            if !self.armijo(&s) || (prev.a > 0.0 && s.f >= prev.f) {
                return self.zoom(prev, Far::Sample(s));
            }
            if self.curvature(&s) {
                return Ok((s.a, s.point));
            }
            if s.df >= 0.0 {
                return self.zoom(s, Far::Sample(prev));
            }
            if self.out_of_budget() {
                return Ok((s.a, s.point));
            }
            let width = s.a - prev.a;
            let (lower, upper) = (s.a + 1.1 * width, s.a + 4.0 * width);
            a = cubic_min(prev.a, prev.f, prev.df, s.a, s.f, s.df)
                .filter(|&c| c > s.a)
                .map_or(upper, |c| c.clamp(lower, upper));
            prev = s;
        }
    }

    /// N&W Alg. 3.6; `lo` satisfies sufficient decrease and has the lowest cost so far.
    fn zoom(mut self, mut lo: Sample, mut hi: Far) -> Result<(f64, Point), LineSearchFailure> {
        loop {
            let width = hi.a() - lo.a;
            if self.out_of_budget() || width.abs() <= 1e-14 * lo.a.abs().max(hi.a().abs()) {
                return Self::give_up(lo, LineSearchFailure::NoProgress);
            }
            let a = match &hi {
                Far::Failed(ha) => lo.a + FAILURE_SHRINK * (ha - lo.a),
                Far::Sample(h) => {
                    let (min, max) = (lo.a + 0.1 * width, hi.a() - 0.1 * width);
                    let (min, max) = if min <= max { (min, max) } else { (max, min) };
                    cubic_min(lo.a, lo.f, lo.df, h.a, h.f, h.df)
                        .map_or(0.5 * (lo.a + h.a), |c| c.clamp(min, max))
                }
            };
            let s = match self.sample(a) {
                Ok(Some(s)) => s,
                Ok(None) => {
                    hi = Far::Failed(a);
                    continue;
                }
                Err(e) => return Self::give_up(lo, e),
            };
            if !self.armijo(&s) || s.f >= lo.f {
                hi = Far::Sample(s);
            } else {
                if self.curvature(&s) {
                    return Ok((s.a, s.point));
                }
                if s.df * (hi.a() - lo.a) >= 0.0 {
                    hi = Far::Sample(lo);
                }
                lo = s;
            }
        }
    }
}

/// Searches along the descent direction `d` from `start`, trying step `a1` first.
/// Returns the accepted step length and the new point.
pub(crate) fn strong_wolfe<O: Objective + ?Sized>(
    run: &mut Run<'_, '_>,
    objective: &mut O,
    start: &Point,
    d: &[f64],
    a1: f64,
) -> Result<(f64, Point), LineSearchFailure> {
    let df0 = dot(&start.gradient, d);
    debug_assert!(df0 < 0.0, "strong_wolfe: not a descent direction");
    Search {
        run,
        objective,
        start,
        direction: d,
        f0: start.cost,
        df0,
        evaluations: 0,
        failures: 0,
    }
    .bracket(a1)
}
