//! The joint problem of a study: the recordings' problems behind one set of coordinates
//! `X = (s, o_1, ..., o_R)` (module docs of [`super`] for the sums and the block structure).

use super::design::Current;
use super::ensemble::{assign, put_string, Ensemble, Reader, Wire};
use crate::optim::{EvalError, GaussNewtonObjective, GnEval, Objective};
use crate::params::ParamSet;
use crate::problem::{Evaluation, Problem};
use crate::statistics::Uncertainty;
use crate::Error;
use rayon::prelude::*;
use std::rc::Rc;

/// Several recordings' problems fitted with shared and per-recording coordinates.
#[derive(Debug)]
pub struct JointProblem {
    /// the recordings' names, in order
    pub names: Vec<String>,
    /// the recordings' problems; each one's coordinates are the shared ones, then its own
    pub problems: Vec<Problem>,
    /// number of shared coordinates
    shared: usize,
    /// where each recording's own coordinates start in `X`, and how many
    own: Vec<(usize, usize)>,
    /// the processes sharing the recordings ([`super::ensemble`]); `None`: this one runs all
    ensemble: Option<Rc<dyn Ensemble>>,
    /// the rank owning each recording (all 0 without an ensemble)
    owner: Vec<usize>,
}

/// One joint evaluation: the summed cost and each recording's evaluation.
#[derive(Clone, Debug)]
pub struct JointEvaluation {
    /// `sum_r J_r`, summed in the recordings' order
    pub cost: f64,
    /// the recordings' evaluations, in order
    pub recordings: Vec<Evaluation>,
    /// the joint Gauss-Newton matrix (`P x P` row-major), when the evaluation made it
    pub gauss_newton: Option<Vec<f64>>,
}

impl JointEvaluation {
    /// The root mean square residual over every observed point of every recording.
    pub fn rms(&self) -> f64 {
        let (s, n) = self
            .recordings
            .iter()
            .flat_map(|e| &e.frames)
            .fold((0.0, 0usize), |(s, n), f| (s + f.sum_squared, n + f.count));
        if n == 0 {
            0.0
        } else {
            (s / n as f64).sqrt()
        }
    }
}

impl JointProblem {
    /// Joins `problems` (named `names`) whose coordinates begin with those of `shared`: the
    /// shared set must lay out to the same labels at the start of every problem's parameters.
    pub fn new(names: Vec<String>, problems: Vec<Problem>, shared: &ParamSet) -> Result<Self, Error> {
        if problems.is_empty() || names.len() != problems.len() {
            return Err(Error::invalid(
                "a study needs one name per recording and at least one",
            ));
        }
        let mut n_shared = None;
        for (name, p) in names.iter().zip(&problems) {
            let labels = if shared.is_empty() {
                Vec::new()
            } else {
                shared
                    .layout(&p.base)
                    .map_err(|e| Error::Invalid(format!("{name}: {e}")))?
                    .labels()
            };
            let all = p.params.labels();
            if all.len() < labels.len() || all[..labels.len()] != labels[..] {
                return Err(Error::Invalid(format!(
                    "{name}: its parameters ({}) do not begin with the shared ones ({})",
                    all.join(","),
                    labels.join(",")
                )));
            }
            match n_shared {
                None => n_shared = Some(labels.len()),
                Some(n) if n != labels.len() => {
                    return Err(Error::Invalid(format!(
                        "{name}: the shared parameters have {} coordinates here, {n} in the first recording",
                        labels.len()
                    )))
                }
                Some(_) => {}
            }
        }
        let shared = n_shared.unwrap_or(0);
        let mut own = Vec::with_capacity(problems.len());
        let mut at = shared;
        for p in &problems {
            let k = p.params.len() - shared;
            own.push((at, k));
            at += k;
        }
        let owner = vec![0; problems.len()];
        Ok(Self {
            names,
            problems,
            shared,
            own,
            ensemble: None,
            owner,
        })
    }

    /// Shares the recordings out over `ensemble`'s ranks ([`super::ensemble::assign`], each
    /// recording's cost estimated as its integrator steps times its nodes); every rank must
    /// join the same study. Evaluations are then collectives: every rank calls them in turn.
    pub fn distribute(&mut self, ensemble: Rc<dyn Ensemble>) {
        let costs: Vec<f64> = self
            .problems
            .iter()
            .map(|p| (p.steps * p.base.substeps.max(1)) as f64 * p.sim.u.rows() as f64)
            .collect();
        self.owner = assign(&costs, ensemble.size());
        self.ensemble = Some(ensemble);
    }

    /// The rank owning each recording.
    pub fn owners(&self) -> &[usize] {
        &self.owner
    }

    /// Number of joint coordinates `P`.
    pub fn len(&self) -> usize {
        self.own.last().map_or(self.shared, |(a, k)| a + k)
    }

    /// True when nothing is fitted.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of shared coordinates.
    pub fn shared_len(&self) -> usize {
        self.shared
    }

    /// The starting point: the shared coordinates of the first recording's scene, each
    /// recording's own from its scene.
    pub fn x0(&self) -> Vec<f64> {
        let mut x = self.problems[0].x0()[..self.shared].to_vec();
        for p in &self.problems {
            x.extend_from_slice(&p.x0()[self.shared..]);
        }
        x
    }

    /// Recording `r`'s coordinates `(s, o_r)` in `x`.
    pub fn recording_x(&self, x: &[f64], r: usize) -> Vec<f64> {
        let (a, k) = self.own[r];
        let mut xr = x[..self.shared].to_vec();
        xr.extend_from_slice(&x[a..a + k]);
        xr
    }

    /// The plausible box of the joint coordinates around `x` ([`ParamSet::bounds`] of each
    /// recording at its coordinates; the shared ones from the first recording).
    pub fn bounds(&self, x: &[f64]) -> Vec<(f64, f64)> {
        let mut out = Vec::with_capacity(x.len());
        for (r, p) in self.problems.iter().enumerate() {
            let b = p.params.bounds(&self.recording_x(x, r));
            if r == 0 {
                out.extend_from_slice(&b[..self.shared]);
            }
            out.extend_from_slice(&b[self.shared..]);
        }
        out
    }

    /// Labels of `X`: the shared labels, then `name:label` for each recording's own.
    pub fn labels(&self) -> Vec<String> {
        let mut out = self.problems[0].params.labels()[..self.shared].to_vec();
        for (name, p) in self.names.iter().zip(&self.problems) {
            out.extend(
                p.params.labels()[self.shared..]
                    .iter()
                    .map(|l| format!("{name}:{l}")),
            );
        }
        out
    }

    /// The physical values at `x` under [`JointProblem::labels`] (the shared ones read in the
    /// first recording's model).
    pub fn values(&self, x: &[f64]) -> Vec<(String, f64)> {
        let mut out = Vec::new();
        for (r, (name, p)) in self.names.iter().zip(&self.problems).enumerate() {
            let vals = p.params.values(&p.model_at(&self.recording_x(x, r)));
            let (shared, own) = vals.split_at(self.shared.min(vals.len()));
            if r == 0 {
                out.extend_from_slice(shared);
            }
            out.extend(own.iter().map(|(l, v)| (format!("{name}:{l}"), *v)));
        }
        out
    }

    /// Runs `f` on every recording (in parallel) at its coordinates; results in order, the
    /// first error (in the recordings' order) named by its recording. With an ensemble, this
    /// rank runs the recordings it owns and the results are exchanged (a collective).
    fn each<T: Send + Wire>(
        &mut self,
        x: &[f64],
        f: impl Fn(&mut Problem, &[f64]) -> Result<T, Error> + Sync,
    ) -> Result<Vec<T>, Error> {
        let xs: Vec<Vec<f64>> = (0..self.problems.len()).map(|r| self.recording_x(x, r)).collect();
        let rank = self.ensemble.as_ref().map_or(0, |e| e.rank());
        let mut results: Vec<Option<Result<T, Error>>> = self
            .problems
            .par_iter_mut()
            .zip(&xs)
            .zip(&self.owner)
            .map(|((p, xr), &o)| (o == rank).then(|| f(p, xr)))
            .collect();
        if let Some(ensemble) = &self.ensemble {
            let mut mine = Vec::new();
            for (r, res) in results.iter().enumerate() {
                let Some(res) = res else { continue };
                mine.extend_from_slice(&(r as u64).to_le_bytes());
                match res {
                    Ok(t) => {
                        mine.push(1);
                        t.put(&mut mine);
                    }
                    Err(e) => {
                        mine.push(0);
                        put_string(&mut mine, &e.to_string());
                    }
                }
            }
            for bytes in ensemble.all_gather(&mine) {
                let mut input = Reader::new(&bytes);
                while !input.is_empty() {
                    let r = input.usize()?;
                    if r >= results.len() {
                        return Err(Error::invalid("a rank sent a result for a recording this study does not have (the ranks read different studies?)"));
                    }
                    let ok = input.byte()?;
                    let model = self.problems[r].model_at(&xs[r]);
                    results[r] = Some(if ok == 1 {
                        Ok(T::take(&mut input, &model)?)
                    } else {
                        Err(Error::Invalid(input.string()?))
                    });
                }
            }
        }
        results
            .into_iter()
            .zip(&self.names)
            .map(|(res, name)| {
                res.unwrap_or_else(|| Err(Error::invalid("no rank evaluated it")))
                    .map_err(|e| Error::Invalid(format!("recording `{name}`: {e}")))
            })
            .collect()
    }

    /// Adds recording `r`'s gradient into the joint one.
    fn add_gradient(&self, r: usize, g: &[f64], out: &mut [f64]) {
        let (a, k) = self.own[r];
        for i in 0..self.shared {
            out[i] += g[i];
        }
        out[a..a + k].copy_from_slice(&g[self.shared..]);
    }

    /// Adds recording `r`'s Gauss-Newton matrix (`p_r x p_r`) into the joint one (`P x P`).
    fn add_hessian(&self, r: usize, h: &[f64], out: &mut [f64]) {
        let (a, k) = self.own[r];
        let (s, pr, pj) = (self.shared, self.shared + k, self.len());
        let joint = |i: usize| if i < s { i } else { a + i - s };
        for i in 0..pr {
            for j in 0..pr {
                out[joint(i) * pj + joint(j)] += h[i * pr + j];
            }
        }
    }

    /// The joint cost and each recording's evaluation at `x` (no gradient).
    pub fn evaluate(&mut self, x: &[f64]) -> Result<JointEvaluation, Error> {
        let evs = self.each(x, |p, xr| p.evaluate(xr))?;
        Ok(JointEvaluation {
            cost: evs.iter().map(|e| e.cost).sum(),
            recordings: evs,
            gauss_newton: None,
        })
    }

    /// The joint cost and its adjoint gradient at `x`.
    pub fn gradient(&mut self, x: &[f64]) -> Result<(JointEvaluation, Vec<f64>), Error> {
        let results = self.each(x, |p, xr| p.gradient(xr).map(|(ev, g, _)| (ev, g)))?;
        Ok(self.summed(results.into_iter().map(|(ev, g)| (ev, g, None))))
    }

    /// The joint cost, gradient and Gauss-Newton matrix at `x`.
    pub fn gauss_newton(&mut self, x: &[f64]) -> Result<(JointEvaluation, Vec<f64>, Vec<f64>), Error> {
        let results = self.each(x, |p, xr| p.gauss_newton(xr))?;
        let (ev, g) = self.summed(results.into_iter().map(|(ev, g, h)| (ev, g, Some(h))));
        let h = ev.gauss_newton.clone().expect("every recording made its matrix");
        Ok((ev, g, h))
    }

    /// The recordings' evaluations, gradients (and Gauss-Newton matrices) summed in the
    /// recordings' order with the block structure.
    fn summed(
        &self,
        results: impl Iterator<Item = (Evaluation, Vec<f64>, Option<Vec<f64>>)>,
    ) -> (JointEvaluation, Vec<f64>) {
        let n = self.len();
        let mut g = vec![0.0; n];
        let mut h: Option<Vec<f64>> = None;
        let mut evs = Vec::with_capacity(self.problems.len());
        for (r, (ev, gr, hr)) in results.enumerate() {
            self.add_gradient(r, &gr, &mut g);
            if let Some(hr) = hr {
                self.add_hessian(r, &hr, h.get_or_insert_with(|| vec![0.0; n * n]));
            }
            evs.push(ev);
        }
        let cost = evs.iter().map(|e| e.cost).sum();
        (
            JointEvaluation {
                cost,
                recordings: evs,
                gauss_newton: h,
            },
            g,
        )
    }

    /// First-order standard errors and covariance of the joint estimate at `x` (one `sigma^2`
    /// for every point of every recording; `crate::statistics`), from the evaluation's joint
    /// Gauss-Newton matrix or a new one. `None` as for one fit.
    pub fn uncertainty(&mut self, x: &[f64], ev: &JointEvaluation) -> Result<Option<Uncertainty>, Error> {
        Ok(self.picture(x, ev)?.and_then(|c| c.uncertainty()))
    }

    /// What the standard errors at `x` are made of (the joint Gauss-Newton matrix from the
    /// evaluation or a new one, `r^T W r`, the point count, the scales and labels), for
    /// [`JointProblem::uncertainty`] and the experiment design ([`super::design`]). `None` when
    /// there are no more informative points than coordinates.
    pub fn picture(&mut self, x: &[f64], ev: &JointEvaluation) -> Result<Option<Current>, Error> {
        let n: usize = ev
            .recordings
            .iter()
            .flat_map(|e| &e.frames)
            .map(|f| f.informative)
            .sum();
        let rwr: f64 = ev
            .recordings
            .iter()
            .flat_map(|e| &e.frames)
            .map(|f| f.weighted_squared)
            .sum();
        let p = self.len();
        if n <= p {
            return Ok(None);
        }
        let h = match &ev.gauss_newton {
            Some(h) if h.len() == p * p => h.clone(),
            _ => self.gauss_newton(x)?.2,
        };
        let mut scales = Vec::with_capacity(p);
        for (r, prob) in self.problems.iter().enumerate() {
            let s = prob.params.x_scales(&prob.model_at(&self.recording_x(x, r)));
            if r == 0 {
                scales.extend_from_slice(&s[..self.shared]);
            }
            scales.extend_from_slice(&s[self.shared..]);
        }
        Ok(Some(Current {
            h,
            rwr,
            n,
            scales,
            labels: self.labels(),
            shared: self.shared,
        }))
    }
}

/// The optimizer's view of a [`JointProblem`], keeping every evaluation by `x`.
#[derive(Debug)]
pub struct JointObjective<'a> {
    /// the joint problem
    pub joint: &'a mut JointProblem,
    /// evaluations done, in order
    pub evaluations: Vec<(Vec<f64>, JointEvaluation)>,
}

impl<'a> JointObjective<'a> {
    /// Wraps a joint problem.
    pub fn new(joint: &'a mut JointProblem) -> Self {
        Self {
            joint,
            evaluations: Vec::new(),
        }
    }

    /// The evaluation made at exactly `x`, if any.
    pub fn evaluation_at(&self, x: &[f64]) -> Option<&JointEvaluation> {
        self.evaluations
            .iter()
            .rev()
            .find(|(xe, _)| xe == x)
            .map(|(_, e)| e)
    }
}

impl Objective for JointObjective<'_> {
    fn eval(&mut self, x: &[f64]) -> Result<(f64, Vec<f64>), EvalError> {
        let (ev, g) = self
            .joint
            .gradient(x)
            .map_err(|e| EvalError::new(e.to_string()))?;
        let cost = ev.cost;
        self.evaluations.push((x.to_vec(), ev));
        Ok((cost, g))
    }
}

impl GaussNewtonObjective for JointObjective<'_> {
    fn eval_gn(&mut self, x: &[f64]) -> Result<GnEval, EvalError> {
        let (ev, gradient, hessian) = self
            .joint
            .gauss_newton(x)
            .map_err(|e| EvalError::new(e.to_string()))?;
        let cost = ev.cost;
        self.evaluations.push((x.to_vec(), ev));
        Ok(GnEval {
            cost,
            gradient,
            hessian,
        })
    }
}
