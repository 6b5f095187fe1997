//! The search for the missing effect ([`super::diagnose`], stage 3): every effect that is off
//! is probed (a score statistic, [`score::probe`]), the best are refitted briefly
//! ([`score::refit`]), and the noise floor is read again at the best refit ([`refit_floor`]).
//! A candidate is skipped by its prediction only once a refit has brought the model within the
//! fail ratio of the noise floor and the prediction says it cannot win; while the model still
//! fails, every candidate whose score beats the BIC penalty is refitted (issue 50).

use super::effects::{DataContext, Effect, Probe};
use super::score::{BaseFit, Candidate};
use super::{floor, residuals, score, DiagnoseParams, Progress, Setup};
use crate::cost_mesh::SurfaceCost;
use crate::observations::Observations;
use crate::Error;
use rayon::prelude::*;

/// A candidate whose prediction is reliable (see [`Search::candidates`]) and whose
/// predicted rms is more than this factor above a confirmed candidate's rms is not refitted.
pub(super) const CLOSE_FACTOR: f64 = 1.2;

/// The search for the missing effect among those switched off.
pub(super) struct Search<'a> {
    pub(super) setup: &'a Setup<'a>,
    pub(super) base: &'a BaseFit,
    pub(super) off: &'a [Box<dyn Effect>],
    pub(super) settings: &'a DiagnoseParams,
    /// the residual count (the BIC penalty per parameter is its log)
    pub(super) points: usize,
    /// the noise floor stated before the search (the fail ratio's reference)
    pub(super) floor: f64,
}

impl Search<'_> {
    /// Probes every effect that is off (a score each), refits the best whose score beats the
    /// BIC penalty, and returns the candidates: the refitted ones by Delta BIC, then the rest
    /// by score.
    pub(super) fn candidates(
        &self,
        data: &DataContext<'_>,
        progress: Progress,
        total: usize,
    ) -> Vec<Candidate> {
        let (setup, base, off, settings) = (self.setup, self.base, self.off, self.settings);
        // the probes are independent (each its own problem, deterministic whatever the thread
        // count): they run side by side, in the effects' order in the result
        progress(&format!("score {} effects", off.len()), 2, total);
        let mut candidates: Vec<Candidate> = off
            .par_iter()
            .map(|e| score::probe(setup, base, e.as_ref(), data))
            .collect();
        // refit the candidates whose score beats the BIC penalty, best first
        self.sort_by_rank(&mut candidates);
        for i in 0..settings.refits.min(candidates.len()) {
            if candidates[i].error.is_some() || self.rank(&candidates[i]) <= 0.0 {
                continue;
            }
            // a candidate predicted far worse than one already confirmed cannot win, unless it
            // has fewer parameters (at equal rms its Delta BIC is lower). "Far": 2x, or
            // [`CLOSE_FACTOR`] when the prediction is reliable, a score probe of parameters that
            // are not log coordinates (the cost is near quadratic in them: initial velocities,
            // the stiffness field's log factors about 0); a log coordinate probed near 0 (drag,
            // damping, friction) or a data-driven start moves far, and its prediction is a poor
            // bound: it is compared with the confirmed candidate's own prediction too (the larger
            // of its prediction and its refit), for two probes alike predict alike. On the 80-step
            // bar the two hopeless refits skipped so were 200 of 268 s; on the independent bar
            // with hidden mass damping (noise 0.0025) drag, refitted first to 0.0032 from a
            // prediction as poor as damping's, otherwise kept damping from its refit.
            let best = candidates[..i]
                .iter()
                .filter(|c| c.rms_after.is_some())
                .min_by(|a, b| {
                    a.rms_after
                        .unwrap_or(f64::INFINITY)
                        .total_cmp(&b.rms_after.unwrap_or(f64::INFINITY))
                });
            let effect = self.effect(&candidates[i].effect);
            let reliable = effect.probe() == Probe::Score && effect.params().iter().all(|p| !p.is_log());
            // pruning is allowed only once a refit has brought the model within the fail
            // ratio of the noise floor: while the best refit still leaves it failing, every
            // candidate whose score beats the BIC penalty is refitted (a prediction is no bound:
            // a box dropped onto a ground the model lacked, whose ground was predicted just
            // over twice drag's refit, was called `missing: drag`)
            let passes = |b: &&Candidate| b.rms_after.is_some_and(|r| r <= settings.fail_ratio * self.floor);
            if let Some(b) = best.filter(passes) {
                let confirmed = b.rms_after.unwrap_or(f64::INFINITY);
                let (far, reference) = if reliable {
                    (CLOSE_FACTOR, confirmed)
                } else {
                    (2.0, confirmed.max(b.predicted_rms))
                };
                let worse = candidates[i].predicted_rms > far * reference;
                if worse && candidates[i].params.len() >= b.params.len() {
                    continue;
                }
            }
            self.refit(&mut candidates[i], (2 + off.len() + i, total), progress);
        }
        self.sort(&mut candidates);
        candidates
    }

    /// `LM - p ln N`: a candidate's score less its BIC penalty.
    pub(super) fn rank(&self, c: &Candidate) -> f64 {
        c.score - c.params.len() as f64 * (self.points.max(1) as f64).ln()
    }

    /// Best rank first (ties by name).
    fn sort_by_rank(&self, candidates: &mut [Candidate]) {
        candidates.sort_by(|a, b| {
            self.rank(b)
                .total_cmp(&self.rank(a))
                .then(a.effect.cmp(&b.effect))
        });
    }

    /// Refitted candidates by Delta BIC, then the rest by rank.
    fn sort(&self, candidates: &mut [Candidate]) {
        candidates.sort_by(|a, b| match (a.delta_bic, b.delta_bic) {
            (Some(x), Some(y)) => x.total_cmp(&y),
            (Some(_), None) => std::cmp::Ordering::Less,
            (None, Some(_)) => std::cmp::Ordering::Greater,
            (None, None) => self.rank(b).total_cmp(&self.rank(a)),
        });
    }

    /// The effect of a candidate (every candidate is one of `off`).
    fn effect(&self, name: &str) -> &dyn Effect {
        self.off
            .iter()
            .find(|e| e.name() == name)
            .map(|e| e.as_ref())
            .expect("a candidate is an effect that is off")
    }

    /// Refits candidate `c` ([`score::refit`]), reporting `(done, total)`.
    fn refit(&self, c: &mut Candidate, (done, total): (usize, usize), progress: Progress) {
        progress(&format!("refit with {}", c.effect), done.min(total), total);
        score::refit(
            self.setup,
            self.base,
            self.effect(&c.effect),
            c,
            self.settings.refit_iterations,
        );
    }

    /// Refits every candidate not refitted yet, probed without error, that `pick` chooses
    /// (beyond [`DiagnoseParams::refits`]: a parameter on its bound or an implausible winner
    /// asks for the whole search), and sorts them again. Returns how many were refitted.
    pub(super) fn refit_more(
        &self,
        candidates: &mut [Candidate],
        pick: impl Fn(&Candidate) -> bool,
        progress: Progress,
        total: usize,
    ) -> usize {
        let mut done = 0;
        for c in candidates.iter_mut() {
            if c.rms_after.is_none() && c.error.is_none() && pick(c) {
                self.refit(c, (total, total), progress);
                done += 1;
            }
        }
        self.sort(candidates);
        done
    }
}

/// The residual noise floor ([`floor::residual_floor`]) at the refit of the candidate with the
/// smallest rms after its refit, if one was refitted.
pub(super) fn refit_floor(
    candidates: &[Candidate],
    steps: usize,
    cost: &SurfaceCost,
    observations: &Observations,
) -> Result<Option<floor::FloorEstimate>, Error> {
    let best = candidates
        .iter()
        .filter(|c| c.rms_after.is_some() && c.model.is_some() && c.scene.is_some())
        .min_by(|a, b| {
            a.rms_after
                .unwrap_or(f64::INFINITY)
                .total_cmp(&b.rms_after.unwrap_or(f64::INFINITY))
        });
    let Some((Some(scene), Some(model))) = best.map(|c| (&c.scene, &c.model)) else {
        return Ok(None);
    };
    let mut sim = scene.build_simulation()?;
    let records = residuals::point_residuals(&mut sim, model.clone(), steps, cost, observations)?;
    Ok(floor::residual_floor(&records))
}
