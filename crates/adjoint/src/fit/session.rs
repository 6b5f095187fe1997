//! A fit session's log: `fit.log`, one JSON object per line and iteration
//! (`{"iteration", "cost", "rms", "gradient_norm", "evaluations", "parameters": {name: value},
//! "x"}`), appended and flushed as the optimizer goes, so that a killed fit can be resumed.
//!
//! Resuming ([`FitLog::begin`] with the earlier log): the earlier entries are copied into the
//! new log, the optimizer restarts from the last entry's `x` (the log must be of the same
//! problem, by the fingerprint every entry carries as `problem` (a digest of the scene, the
//! observations, the parameters, the steps and the cost, `softbody::problem_args`), of the same
//! parameters, by the names of its `parameters`, and `x` must have as many finite values as
//! the fit has coordinates), iteration numbers continue from the last one, and the restarted
//! optimizer's iteration 0 (a repeat of the last entry) is not logged again. Each entry is
//! written with one `write`, so a kill cuts at most the last line short; such a line (no
//! newline, not JSON) is left out when the log is read.

use crate::fit::FitObjective;
use crate::optim::{minimize, IterationRecord, OptimInfo, OptimParams, Optimizer};
use crate::problem::{Evaluation, Problem};
use crate::Error;
use cutfem::fem::Model;
use serde_json::{json, Map, Value};
use std::io::Write;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

/// `{name: value}` of physical parameters (the log's and the reports' `parameters`).
pub fn values_json(values: &[(String, f64)]) -> Value {
    Value::Object(
        values
            .iter()
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect::<Map<_, _>>(),
    )
}

/// Reads a fit log: its entries, blank lines skipped; errors name the file and line. A last
/// line without its newline that is not JSON is an entry cut short when its run was killed:
/// it is left out (the entry before it is the state to continue from).
pub fn read_log(path: &Path) -> Result<Vec<Value>, Error> {
    load_log(path).map(|(entries, _)| entries)
}

/// [`parse_log`] of the file at `path`.
fn load_log(path: &Path) -> Result<(Vec<Value>, String), Error> {
    let text =
        cutfem::input::read_string(path, cutfem::input::MAX_DATA_BYTES).map_err(|e| Error::io(path, e))?;
    parse_log(&text, path)
}

/// The entries of log text and the text they stand in (`text` less a torn last line, with a
/// final newline).
fn parse_log(text: &str, path: &Path) -> Result<(Vec<Value>, String), Error> {
    let torn = !text.is_empty() && !text.ends_with('\n');
    let lines: Vec<&str> = text.lines().collect();
    let mut entries = Vec::new();
    let mut whole = text.to_string();
    for (i, l) in lines.iter().enumerate() {
        if l.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<Value>(l) {
            Ok(v) if v.is_object() => entries.push(v),
            // the cut-short last line: the text before it is whole
            _ if torn && i + 1 == lines.len() => {
                whole.truncate(text.len() - l.len());
                return Ok((entries, whole));
            }
            Ok(_) => {
                return Err(Error::Line {
                    path: path.to_path_buf(),
                    line: i + 1,
                    msg: "not a log entry (a JSON object)".into(),
                })
            }
            Err(e) => {
                return Err(Error::Line {
                    path: path.to_path_buf(),
                    line: i + 1,
                    msg: e.to_string(),
                })
            }
        }
    }
    if torn {
        whole.push('\n');
    }
    Ok((entries, whole))
}

/// An open fit log (module docs).
#[derive(Debug)]
pub struct FitLog {
    path: PathBuf,
    file: std::fs::File,
    history: Vec<Value>,
    offset: usize,
    resumed: bool,
    problem: String,
}

impl FitLog {
    /// Opens the log at `path` (appending). With `earlier` (a resumed fit), its entries are
    /// copied into `path` (as written, less a line cut short by a kill) and `x0` becomes the
    /// last entry's `x`. `names` are the physical values this fit logs (the keys of an entry's
    /// `parameters`): the earlier log must have been written for the same ones, with as many
    /// coordinates as `x0`, or the start would be another fit's point; and for the same
    /// `problem` (the fingerprint of the scene, observations and settings each entry carries),
    /// or two problems would mix in one history.
    pub fn begin(
        path: &Path,
        earlier: Option<&Path>,
        names: &[String],
        problem: &str,
        x0: &mut Vec<f64>,
    ) -> Result<FitLog, Error> {
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        let mut history = Vec::new();
        if let Some(earlier) = earlier {
            let (entries, whole) = load_log(earlier)?;
            if let Some(last) = entries.last() {
                // the parameters first (the more specific words), then the whole problem
                let x = resume_point(last, names, x0.len())
                    .map_err(|e| Error::Invalid(format!("{}: {e}", earlier.display())))?;
                same_problem(last, problem)
                    .map_err(|e| Error::Invalid(format!("{}: {e}", earlier.display())))?;
                *x0 = x;
            }
            file.write_all(whole.as_bytes())
                .and_then(|()| file.flush())
                .map_err(|e| Error::io(path, e))?;
            history = entries;
        }
        let offset = history
            .last()
            .and_then(|h| h["iteration"].as_u64())
            .map_or(0, |v| v as usize);
        Ok(FitLog {
            path: path.to_path_buf(),
            file,
            resumed: !history.is_empty(),
            history,
            offset,
            problem: problem.to_string(),
        })
    }

    /// Logs one iteration of the optimizer with its rms (when known) and the physical
    /// parameter values at its `x`; a resumed fit's iteration 0 is skipped.
    pub fn record(
        &mut self,
        rec: &IterationRecord,
        rms: Option<f64>,
        values: &[(String, f64)],
    ) -> Result<(), Error> {
        if self.resumed && rec.iteration == 0 {
            return Ok(());
        }
        let entry = json!({
            "iteration": self.offset + rec.iteration,
            "cost": rec.cost,
            "rms": rms,
            "gradient_norm": rec.gradient_norm,
            "evaluations": rec.evaluations,
            "parameters": values_json(values),
            "x": rec.x,
            "problem": self.problem,
        });
        // one write of the whole line: a kill cuts at most this line short
        self.file
            .write_all(format!("{entry}\n").as_bytes())
            .and_then(|()| self.file.flush())
            .map_err(|e| Error::io(&self.path, e))?;
        self.history.push(entry);
        Ok(())
    }

    /// The entries so far, the earlier run's included.
    pub fn history(&self) -> &[Value] {
        &self.history
    }

    /// The entries, closing the log.
    pub fn into_history(self) -> Vec<Value> {
        self.history
    }
}

/// Errors unless the earlier log's `last` entry was written for `problem` (module docs).
fn same_problem(last: &Value, problem: &str) -> Result<(), String> {
    match last["problem"].as_str() {
        Some(p) if p == problem => Ok(()),
        Some(p) => Err(format!(
            "the log is of another problem (fingerprint {p}: another scene, observations, \
             parameters, steps or cost), this fit's is {problem}; resume with the same inputs, \
             or fit into another --out"
        )),
        None => Err(format!(
            "the log carries no fingerprint of its problem (written by an older softbody), so \
             it cannot be tied to this fit's ({problem}); fit into another --out"
        )),
    }
}

/// The point a resumed fit starts from: the `x` of the earlier log's `last` entry, when that
/// log was written for the parameters `names` (its `parameters` keys) with `n` coordinates.
fn resume_point(last: &Value, names: &[String], n: usize) -> Result<Vec<f64>, String> {
    let mut logged: Vec<&str> = last["parameters"]
        .as_object()
        .map(|m| m.keys().map(String::as_str).collect())
        .unwrap_or_default();
    let mut now: Vec<&str> = names.iter().map(String::as_str).collect();
    logged.sort_unstable();
    now.sort_unstable();
    if logged != now {
        return Err(format!(
            "the log is of a fit of {}, this fit is of {}; resume with the same --params, or fit into another --out",
            if logged.is_empty() { "unnamed parameters".to_string() } else { logged.join(",") },
            now.join(",")
        ));
    }
    let xs: Option<Vec<f64>> = last["x"]
        .as_array()
        .and_then(|a| a.iter().map(Value::as_f64).collect());
    match xs {
        Some(xs) if xs.len() == n && xs.iter().all(|v| v.is_finite()) => Ok(xs),
        _ => Err(format!(
            "the last entry's `x` is not {n} finite numbers (the coordinates of {})",
            now.join(",")
        )),
    }
}

/// What [`run_logged`] gives: the best point, the optimizer's account, the evaluation and the
/// model there.
#[derive(Debug)]
pub struct LoggedFit {
    /// the best point (unconstrained coordinates)
    pub x: Vec<f64>,
    /// the optimizer's account (termination, evaluations)
    pub info: OptimInfo,
    /// the evaluation at `x`
    pub evaluation: Evaluation,
    /// the model at `x`
    pub model: Model,
}

/// Runs `optimizer` on `problem` from `x0` for at most `iterations` iterations, recording every
/// iteration in `log` (the cost, the rms of the evaluation made at that point, the physical
/// values) and reporting `(iteration, cost)` to `progress`; then the evaluation at the best
/// point (the optimizer's own when it made one there). The session of `softbody fit`.
pub fn run_logged(
    problem: &mut Problem,
    optimizer: Optimizer,
    iterations: usize,
    x0: &[f64],
    log: &mut FitLog,
    mut progress: impl FnMut(usize, f64),
) -> Result<LoggedFit, Error> {
    let params = problem.params.clone();
    let base = problem.base.clone();
    let model_at = |x: &[f64]| {
        let mut m = base.clone();
        params.apply(x, &mut m);
        m
    };
    let mut objective = FitObjective::new(problem);
    let evaluations = objective.evaluations.clone();
    let oparams = OptimParams {
        max_iterations: iterations,
        ..OptimParams::default()
    };
    let mut log_error = None;
    let result = minimize(optimizer, &mut objective, x0, &oparams, &mut |rec| {
        let ev = crate::fit::find_evaluation(&evaluations, &rec.x);
        let values = params.values(&model_at(&rec.x));
        if let Err(e) = log.record(rec, ev.as_ref().map(Evaluation::rms), &values) {
            log_error = Some(e);
            return ControlFlow::Break(());
        }
        progress(rec.iteration, rec.cost);
        ControlFlow::Continue(())
    });
    if let Some(e) = log_error {
        return Err(e);
    }
    let (x, info) = result.map_err(|e| Error::Invalid(format!("fit: {e}")))?;
    let evaluation = match objective.evaluation_at(&x) {
        Some(e) => e,
        None => objective
            .problem
            .evaluate(&x)
            .map_err(|e| Error::Invalid(format!("the fitted model: {e}")))?,
    };
    let model = objective.problem.model_at(&x);
    Ok(LoggedFit {
        x,
        info,
        evaluation,
        model,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(iteration: usize, x: f64) -> IterationRecord {
        IterationRecord {
            iteration,
            cost: 1.0 / (1.0 + iteration as f64),
            gradient_norm: 0.5,
            step_norm: 0.0,
            x: vec![x, 2.0 * x],
            evaluations: iteration + 1,
        }
    }

    #[test]
    fn a_resumed_log_continues_numbers_and_start_point() {
        let dir = std::env::temp_dir().join(format!("adjoint-fitlog-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (first, second) = (dir.join("a.log"), dir.join("b.log"));
        let labels = ["young".to_string()];
        let mut x0 = vec![0.0, 0.0];
        let mut log = FitLog::begin(&first, None, &labels, "p", &mut x0).unwrap();
        for i in 0..3 {
            log.record(&rec(i, i as f64), Some(0.1), &[("young".into(), 10.0 * i as f64)])
                .unwrap();
        }
        assert_eq!(x0, vec![0.0, 0.0]);
        assert_eq!(read_log(&first).unwrap().len(), 3);
        // resume: restart from the last x, skip the repeated iteration 0, continue numbering
        let mut x0 = vec![0.0, 0.0];
        let mut log = FitLog::begin(&second, Some(&first), &labels, "p", &mut x0).unwrap();
        assert_eq!(x0, vec![2.0, 4.0]);
        log.record(&rec(0, 2.0), None, &[]).unwrap();
        log.record(&rec(1, 3.0), None, &[]).unwrap();
        let entries = read_log(&second).unwrap();
        let numbers: Vec<u64> = entries.iter().map(|e| e["iteration"].as_u64().unwrap()).collect();
        assert_eq!(numbers, vec![0, 1, 2, 3]);
        assert_eq!(log.history().len(), 4);
        assert_eq!(entries[1]["parameters"]["young"], json!(10.0));
        // a log of other parameters, or of another count, is refused, naming them
        let both = ["young".to_string(), "poisson".to_string()];
        let err = FitLog::begin(&dir.join("c.log"), Some(&first), &both, "p", &mut vec![0.0; 2])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("a fit of young, this fit is of poisson,young"),
            "{err}"
        );
        let err = FitLog::begin(&dir.join("c.log"), Some(&first), &labels, "p", &mut vec![0.0; 3])
            .unwrap_err()
            .to_string();
        assert!(err.contains("not 3 finite numbers"), "{err}");
        // a log of another problem (same parameter names) is refused, naming both fingerprints
        let err = FitLog::begin(&dir.join("c.log"), Some(&first), &labels, "q", &mut vec![0.0; 2])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("another problem (fingerprint p") && err.contains("this fit's is q"),
            "{err}"
        );
        // a last line cut short by a kill is left out, and the resumed log stays whole
        let good = std::fs::read_to_string(&first).unwrap();
        let torn = dir.join("torn.log");
        std::fs::write(&torn, format!("{good}{{\"iteration\": 3, \"x\": [7.0, 1")).unwrap();
        assert_eq!(read_log(&torn).unwrap().len(), 3);
        let (mut x0, resumed) = (vec![0.0, 0.0], dir.join("d.log"));
        let mut log = FitLog::begin(&resumed, Some(&torn), &labels, "p", &mut x0).unwrap();
        assert_eq!(x0, vec![2.0, 4.0]);
        log.record(&rec(1, 5.0), None, &[("young".into(), 1.0)]).unwrap();
        let entries = read_log(&resumed).unwrap();
        assert_eq!(entries.len(), 4);
        assert_eq!(entries[3]["iteration"], json!(3));
        // a whole last line without its newline is an entry like any other
        std::fs::write(&torn, good.trim_end()).unwrap();
        let mut log = FitLog::begin(&dir.join("e.log"), Some(&torn), &labels, "p", &mut x0).unwrap();
        log.record(&rec(1, 5.0), None, &[]).unwrap();
        assert_eq!(read_log(&dir.join("e.log")).unwrap().len(), 4);
        // a broken line before the last names the file and line
        std::fs::write(&first, "{\"x\": [1, 2]}\nnot json\n").unwrap();
        let err = read_log(&first).unwrap_err().to_string();
        assert!(err.contains("a.log:2"), "{err}");
        std::fs::write(&first, "{\"x\": [1, 2]}\n[1]\n{\"x\": [1, 2]}").unwrap();
        let err = read_log(&first).unwrap_err().to_string();
        assert!(
            err.contains("a.log:2") && err.contains("not a log entry"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}
