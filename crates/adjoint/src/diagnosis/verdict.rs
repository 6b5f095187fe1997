//! The verdict in words (module docs of [`super`], "Verdict"): the named effect or "nothing
//! missing", the candidates that could not be checked ("undecided"), a fit that ended on a
//! bound ("not a clean model"), and the discretisation guard's "unverified at 2r".

use super::effects;
use super::score::Candidate;
use super::Diagnosis;

/// The coordinates of `x` on a bound of the fit's box `bounds` (within 1e-6, relative), with
/// the physical `values` of the same coordinates.
pub(super) fn on_bounds(
    values: &[(String, f64)],
    bounds: &[(f64, f64)],
    x: &[f64],
) -> Vec<(String, f64, &'static str)> {
    let mut out = Vec::new();
    for (k, (&xk, &(lo, hi))) in x.iter().zip(bounds).enumerate() {
        let tol = 1e-6 * (1.0 + xk.abs());
        let side = if xk <= lo + tol {
            "lower"
        } else if xk >= hi - tol {
            "upper"
        } else {
            continue;
        };
        let (name, value) = values.get(k).cloned().unwrap_or((format!("x[{k}]"), xk));
        out.push((name, value, side));
    }
    out
}

/// The candidates whose probe or refit failed: `(effect, error)`, in their order.
pub fn failed(candidates: &[Candidate]) -> impl Iterator<Item = (&str, &str)> {
    candidates
        .iter()
        .filter_map(|c| c.error.as_deref().map(|e| (c.effect.as_str(), e)))
}

/// The effects whose probe or refit failed, with their errors: "effect (error); ...".
pub fn unchecked(candidates: &[Candidate]) -> Option<String> {
    let failed: Vec<String> = failed(candidates).map(|(c, e)| format!("{c} ({e})")).collect();
    (!failed.is_empty()).then(|| failed.join("; "))
}

/// Marks the verdict of `d` as not confirmed at resolution `resolution`: the check that the
/// named effect's improvement persists there could not run (`reason`). The guard fails closed:
/// the verdict says in words that the effect is unverified (JSON `unverified`), instead of
/// standing as if it had passed.
pub fn mark_unverified(d: &mut Diagnosis, resolution: f64, reason: &str) {
    let Some(name) = d.missing_effect.as_deref() else {
        return;
    };
    let why =
        format!("the check that its improvement persists at resolution {resolution} could not run: {reason}");
    d.verdict = format!(
        "unverified at 2r: {name} is named at this grid, but {why}; it may fit the model's own \
         discretisation error (diagnose again with a finer [body] resolution)\n{}",
        d.verdict
    );
    d.unverified = Some(why);
}

/// A verdict without a named effect, when the fit as given ended with parameters on a bound of
/// the plausible box: such a model is not clean (a slab on a soft support fitted nu 0.01 and
/// was called "nothing missing"), and the verdict begins by saying so.
fn on_a_bound(on_bounds: &[(String, f64, &'static str)], text: String) -> String {
    if on_bounds.is_empty() {
        return text;
    }
    let list: Vec<String> = on_bounds
        .iter()
        .map(|(p, v, side)| format!("{p} = {} on its {side} bound", effects::short(*v)))
        .collect();
    format!(
        "not a clean model: the fit as given ended with {}; a model that fits only there lacks \
         something (an effect outside the catalogue, a support, clamp or ground that is not \
         the body's), so nothing is called missing, but the model is not confirmed either: {text}",
        list.join(", ")
    )
}

/// The verdict `text` with the candidates that could not be probed or refitted named in it:
/// "nothing missing" is not said while one failed ("undecided"). `missing`: an effect is named;
/// `at_precision`: the model fits to the simulation's numerical precision.
fn with_unchecked(text: String, missing: bool, at_precision: bool, candidates: &[Candidate]) -> String {
    match (unchecked(candidates), missing) {
        // a model at numerical precision leaves nothing for an effect to explain
        (_, false) if at_precision => text,
        (None, _) => text,
        (Some(u), true) => format!("{text}\n(could not be checked: {u})"),
        (Some(u), false) => format!(
            "undecided: {u} could not be checked, so nothing is called missing, but the \
             search is incomplete; of the effects checked: {text}"
        ),
    }
}

/// The whole verdict: [`verdict`], with the unchecked candidates ([`with_unchecked`]) and,
/// when no effect is named, a parameter on its bound ([`on_a_bound`]).
pub(super) fn full(
    missing: Option<&Candidate>,
    rms: f64,
    (floor, method): (Option<f64>, &str),
    precision: f64,
    fails: bool,
    candidates: &[Candidate],
    on_bounds: &[(String, f64, &'static str)],
) -> String {
    let text = match floor {
        Some(floor) => verdict(
            missing,
            rms,
            floor,
            precision,
            fails,
            candidates.iter().find(|c| c.error.is_none()),
        ),
        None => without_floor(missing, rms, precision, method),
    };
    let text = with_unchecked(text, missing.is_some(), rms <= precision, candidates);
    if missing.is_none() && rms > precision {
        on_a_bound(on_bounds, text)
    } else {
        text
    }
}

/// The verdict when the noise floor cannot be estimated (`why`): whether the rms is noise
/// cannot be judged, so neither "nothing missing" nor "exact" is said; an effect the data name
/// by their likelihood alone (Delta BIC) is still named.
fn without_floor(missing: Option<&Candidate>, rms: f64, precision: f64, why: &str) -> String {
    let floor = format!("the noise floor {why}");
    match missing {
        None if rms <= precision => format!(
            "nothing missing: rms {} is at the simulation's numerical precision ({}; {floor})",
            effects::short(rms),
            effects::short(precision)
        ),
        Some(c) => format!(
            "missing: {}. rms {} -> {} after adding it ({floor}, so how close either is to the \
             noise is not judged). Add `{}` to [model].effects",
            c.effect,
            effects::short(rms),
            effects::short(c.rms_after.unwrap_or(rms)),
            c.effect
        ),
        None => format!(
            "undecided: {floor}, so whether rms {} is noise or a missing effect cannot be judged; \
             no candidate explains it by its likelihood alone",
            effects::short(rms)
        ),
    }
}

/// The verdict in plain words, over the candidates that were checked (`best_checked`: the
/// first of them).
fn verdict(
    missing: Option<&Candidate>,
    rms: f64,
    floor: f64,
    precision: f64,
    fails: bool,
    best_checked: Option<&Candidate>,
) -> String {
    match missing {
        None if rms <= precision => format!(
            "nothing missing: rms {} is at the simulation's numerical precision ({}; noise floor {})",
            effects::short(rms),
            effects::short(precision),
            effects::short(floor)
        ),
        Some(c) => format!(
            "missing: {}. rms {} -> {} after adding it (noise floor {}). Add `{}` to [model].effects{}",
            c.effect,
            effects::short(rms),
            effects::short(c.rms_after.unwrap_or(rms)),
            effects::short(floor),
            c.effect,
            if c.suggestion.starts_with('(') {
                format!(" {}", c.suggestion)
            } else {
                format!(" and this section (suggested values):\n{}", c.suggestion)
            }
        ),
        None if !fails => format!(
            "nothing missing: rms {} is within {:.2}x the noise floor {}",
            effects::short(rms),
            rms / floor.max(f64::MIN_POSITIVE),
            effects::short(floor)
        ),
        None => match best_checked {
            Some(c) => format!(
                "nothing missing from the catalogue: rms {} exceeds the noise floor {}, but the best \
                 candidate ({}) only reaches {}; the misfit may come from an effect outside the \
                 catalogue",
                effects::short(rms),
                effects::short(floor),
                c.effect,
                c.rms_after.map_or("-".into(), effects::short)
            ),
            None => format!(
                "nothing missing from the catalogue: every effect is on; rms {} vs noise floor {}",
                effects::short(rms),
                effects::short(floor)
            ),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::effects::Probe;
    use super::Candidate;

    fn candidate(effect: &str, rms_after: Option<f64>, error: Option<&str>) -> Candidate {
        Candidate {
            effect: effect.into(),
            probe: Probe::Score,
            params: Vec::new(),
            score: if error.is_some() { f64::NEG_INFINITY } else { 10.0 },
            predicted_rms: 0.01,
            rms_after,
            delta_bic: rms_after.map(|_| -50.0),
            values: Vec::new(),
            suggestion: String::new(),
            error: error.map(str::to_string),
            model: None,
            step: Vec::new(),
            x: Vec::new(),
            scene: None,
        }
    }

    fn verdict(
        m: Option<&Candidate>,
        rms: f64,
        floor: f64,
        precision: f64,
        fails: bool,
        cs: &[Candidate],
    ) -> String {
        super::full(m, rms, (Some(floor), "test"), precision, fails, cs, &[])
    }

    /// Every verdict without a named effect says "undecided" and names each candidate whose
    /// probe or refit failed, with its error, instead of "nothing missing"; with a named effect
    /// the failures are listed beside it; a model at numerical precision needs no search.
    #[test]
    fn a_failed_candidate_is_never_hidden_behind_nothing_missing() {
        let ok = candidate("drag", Some(0.0099), None);
        let failed = candidate("ground", None, Some("the simulation diverged"));
        let (floor, precision) = (0.01, 1e-12);
        for (rms, fails) in [(0.0105, false), (0.05, true)] {
            let clean = verdict(None, rms, floor, precision, fails, std::slice::from_ref(&ok));
            assert!(clean.starts_with("nothing missing"), "{clean}");
            let v = verdict(None, rms, floor, precision, fails, &[ok.clone(), failed.clone()]);
            assert!(
                v.starts_with("undecided: ground (the simulation diverged)"),
                "{v}"
            );
            assert!(!v.starts_with("nothing missing"), "{v}");
            // the checked candidate is the one the text reports on
            if fails {
                assert!(v.contains("the best candidate (drag)"), "{v}");
            }
        }
        let named = candidate("damping", Some(0.0101), None);
        let v = verdict(
            Some(&named),
            0.05,
            floor,
            precision,
            true,
            &[named.clone(), failed.clone()],
        );
        assert!(v.starts_with("missing: damping"), "{v}");
        assert!(
            v.contains("could not be checked: ground (the simulation diverged)"),
            "{v}"
        );
        let v = verdict(None, 1e-14, floor, precision, false, &[failed]);
        assert!(
            v.starts_with("nothing missing: rms") && v.contains("numerical precision"),
            "{v}"
        );
    }
    /// A fit that ended on a bound is never a clean "nothing missing"; without one the text
    /// is unchanged.
    #[test]
    fn a_parameter_on_its_bound_is_not_a_clean_model() {
        let text = "nothing missing: rms 0.0101 is within 1.01x the noise floor 0.01".to_string();
        assert_eq!(super::on_a_bound(&[], text.clone()), text);
        let v = super::on_a_bound(&[("poisson".to_string(), 0.01, "lower")], text.clone());
        assert!(
            v.starts_with("not a clean model: the fit as given ended with poisson = 0.01 on its lower bound"),
            "{v}"
        );
        assert!(v.ends_with(&text), "{v}");
    }

    /// Only the coordinates on (or numerically at) a bound are named, with their side.
    #[test]
    fn on_bounds_names_the_coordinates_on_a_bound() {
        let values = vec![
            ("young".to_string(), 2000.0),
            ("poisson".to_string(), 0.01),
            ("damping_mass".to_string(), 1e4),
        ];
        let bounds = [(0.0, 10.0), (-3.0, 3.0), (-13.8, 9.2)];
        let x = [5.0, -3.0 + 1e-9, 9.2];
        let got = super::on_bounds(&values, &bounds, &x);
        assert_eq!(
            got,
            vec![
                ("poisson".to_string(), 0.01, "lower"),
                ("damping_mass".to_string(), 1e4, "upper")
            ]
        );
        assert!(super::on_bounds(&values, &bounds, &[5.0, 0.0, 0.0]).is_empty());
    }
}
