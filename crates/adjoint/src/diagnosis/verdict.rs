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
    bounded(bounds, x)
        .into_iter()
        .map(|(k, side)| {
            let (name, value) = values.get(k).cloned().unwrap_or((format!("x[{k}]"), x[k]));
            (name, value, side)
        })
        .collect()
}

/// `(coordinate, "lower" | "upper")` of the coordinates of `x` on a bound of `bounds` (within
/// 1e-6, relative).
pub(super) fn bounded(bounds: &[(f64, f64)], x: &[f64]) -> Vec<(usize, &'static str)> {
    let mut out = Vec::new();
    for (k, (&xk, &(lo, hi))) in x.iter().zip(bounds).enumerate() {
        let tol = 1e-6 * (1.0 + xk.abs());
        if xk <= lo + tol {
            out.push((k, "lower"));
        } else if xk >= hi - tol {
            out.push((k, "upper"));
        }
    }
    out
}

/// Whether candidate `c` could move a coordinate of `bounded` off its bound: its probe's
/// Gauss-Newton step points into the box there, or it was switched on without a step (no
/// prediction: it might).
pub(super) fn could_free(c: &Candidate, bounded: &[(usize, &'static str)]) -> bool {
    c.step.is_empty()
        || bounded.iter().any(|&(k, side)| {
            c.step
                .get(k)
                .is_some_and(|&s| if side == "lower" { s > 0.0 } else { s < 0.0 })
        })
}

/// The coordinates of `bounded` that candidate `c`'s refit moved off their bound of `bounds`,
/// with their names and refitted physical values; none when the refit fits worse than the
/// model as given (`Delta BIC >= 0`: a refit that lost its way frees nothing).
pub(super) fn freed(
    c: &Candidate,
    bounded: &[(usize, &'static str)],
    bounds: &[(f64, f64)],
) -> Vec<(String, f64)> {
    if c.rms_after.is_none() || !c.delta_bic.is_some_and(|d| d < 0.0) {
        return Vec::new();
    }
    let still = self::bounded(bounds, &c.x[..c.x.len().min(bounds.len())]);
    bounded
        .iter()
        .filter(|(k, _)| *k < c.x.len() && !still.iter().any(|(j, _)| j == k))
        .filter_map(|&(k, _)| c.values.get(k).cloned())
        .collect()
}

/// The verdict's line on the parameters the fit as given left on a bound: which refitted
/// candidates moved them off it (every candidate that could was refitted), and whether the
/// named effect (`missing`) does. Empty when nothing was on a bound.
pub(super) fn freeing(
    on_bounds: &[(String, f64, &'static str)],
    candidates: &[Candidate],
    missing: Option<&Candidate>,
) -> String {
    if on_bounds.is_empty() {
        return String::new();
    }
    let list: Vec<String> = on_bounds
        .iter()
        .map(|(p, v, side)| format!("{p} = {} on its {side} bound", effects::short(*v)))
        .collect();
    let refitted: Vec<&Candidate> = candidates.iter().filter(|c| c.rms_after.is_some()).collect();
    let frees: Vec<String> = refitted
        .iter()
        .filter(|c| !c.frees.is_empty())
        .map(|c| {
            let vals: Vec<String> = c
                .frees
                .iter()
                .map(|(p, v)| format!("{p} = {}", effects::short(*v)))
                .collect();
            let bic = c.delta_bic.map_or("-".into(), |d| format!("{d:.1}"));
            format!("{} frees it ({}; Delta BIC {bic})", c.effect, vals.join(", "))
        })
        .collect();
    let stay: Vec<&str> = refitted
        .iter()
        .filter(|c| c.frees.is_empty())
        .map(|c| c.effect.as_str())
        .collect();
    let (leave, fit) = if stay.len() == 1 {
        ("leaves", "fits")
    } else {
        ("leave", "fit")
    };
    let mut line = format!(
        "\n(the fit as given ended with {}; every candidate that could free it was refitted: ",
        list.join(", ")
    );
    line.push_str(&match (frees.is_empty(), stay.is_empty()) {
        (true, true) => "none could".to_string(),
        (true, false) => format!(
            "none frees it ({} {leave} it there or {fit} worse)",
            stay.join(", ")
        ),
        (false, true) => frees.join("; "),
        (false, false) => format!(
            "{}; {} {leave} it there or {fit} worse",
            frees.join("; "),
            stay.join(", ")
        ),
    });
    if let Some(m) = missing {
        if m.frees.is_empty() {
            line.push_str(&format!(
                "; the short refit with {} leaves it there: check that a fit with it on frees it, \
                 else the model is not clean yet",
                m.effect
            ));
        }
    }
    line.push(')');
    line
}

/// The verdict's line on the named effect's plausibility (`judged[0]`) and on an alternative
/// passed over because its values are implausible (`passed_over`).
pub(super) fn plausibility(
    judged: Option<&super::plausible::Plausibility>,
    passed_over: Option<&super::plausible::Plausibility>,
    refitted_all: bool,
) -> String {
    let mut line = String::new();
    if let Some(p) = judged {
        match &p.implausible {
            None => line.push_str(&format!("\n({}: {})", p.effect, p.implies)),
            Some(why) => line.push_str(&format!(
                "\nimplausible values: {} explains the data only so: {why}; {}",
                p.effect,
                if refitted_all {
                    "every other candidate was refitted, and none explains the data alike with \
                     plausible values"
                } else {
                    "no other candidate could be refitted"
                }
            )),
        }
    }
    if let Some(p) = passed_over {
        line.push_str(&format!(
            "\n({} fits alike, but not as a body can: {})",
            p.effect,
            p.implausible.as_deref().unwrap_or(&p.implies)
        ));
    }
    line
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
                "nothing missing from the catalogue: rms {} exceeds the noise floor {}, but {}; the \
                 misfit may come from an effect outside the catalogue",
                effects::short(rms),
                effects::short(floor),
                match c.rms_after {
                    Some(r) => format!(
                        "the best candidate ({}) only reaches {}",
                        c.effect,
                        effects::short(r)
                    ),
                    // none was refitted: no score beat its BIC penalty
                    None => format!(
                        "no candidate's score beats its BIC penalty (the best, {}, scores {})",
                        c.effect,
                        effects::short(c.score)
                    ),
                }
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
            frees: Vec::new(),
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
                assert!(v.contains("the best candidate (drag) only reaches 0.0099"), "{v}");
                let mut unrefitted = ok.clone();
                unrefitted.rms_after = None;
                let u = verdict(None, rms, floor, precision, fails, &[unrefitted]);
                assert!(
                    u.contains("no candidate's score beats its BIC penalty (the best, drag, scores 10)"),
                    "{u}"
                );
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

    /// A candidate could free a bounded coordinate when its probe's step points into the box
    /// there (or it has no step); its refit frees it when the refitted coordinate left the
    /// bound; the verdict's line names which did, which did not, and a named effect that
    /// leaves it there.
    #[test]
    fn every_candidate_that_could_free_a_bound_is_named_with_what_it_did() {
        let bounds = [(0.0, 10.0), (-3.0, 3.0)];
        let bounded = super::bounded(&bounds, &[5.0, -3.0]);
        assert_eq!(bounded, vec![(1, "lower")]);
        let mut up = candidate("clamp", Some(0.01), None);
        up.step = vec![0.1, 0.5, 1.0];
        let mut down = candidate("drag", Some(0.02), None);
        down.step = vec![0.1, -0.5, 1.0];
        let switch = candidate("corotation", Some(0.03), None);
        assert!(super::could_free(&up, &bounded));
        assert!(!super::could_free(&down, &bounded));
        assert!(super::could_free(&switch, &bounded), "no step: no prediction");
        up.x = vec![5.0, 0.2, 1.0];
        up.values = vec![
            ("young".into(), 2000.0),
            ("poisson".into(), 0.28),
            ("clamp".into(), 1e4),
        ];
        down.x = vec![5.0, -3.0, 1.0];
        down.values = vec![
            ("young".into(), 2100.0),
            ("poisson".into(), 0.01),
            ("drag".into(), 1.0),
        ];
        assert_eq!(
            super::freed(&up, &bounded, &bounds),
            vec![("poisson".to_string(), 0.28)]
        );
        assert!(super::freed(&down, &bounded, &bounds).is_empty());
        let mut not_refitted = up.clone();
        not_refitted.rms_after = None;
        assert!(super::freed(&not_refitted, &bounded, &bounds).is_empty());
        let mut worse = up.clone();
        worse.delta_bic = Some(12.0);
        assert!(
            super::freed(&worse, &bounded, &bounds).is_empty(),
            "a worse fit frees nothing"
        );
        up.frees = super::freed(&up, &bounded, &bounds);
        let on = [("poisson".to_string(), 0.01, "lower")];
        let line = super::freeing(&on, &[up.clone(), down.clone()], Some(&down));
        assert!(
            line.starts_with("\n(the fit as given ended with poisson = 0.01 on its lower bound; every candidate that could free it was refitted: clamp frees it (poisson = 0.28; Delta BIC -50.0); drag leaves it there or fits worse; the short refit with drag leaves it there"),
            "{line}"
        );
        assert!(super::freeing(&on, &[down.clone()], None)
            .contains("none frees it (drag leaves it there or fits worse)"));
        assert!(super::freeing(&[], &[up, down], None).is_empty());
    }

    /// The named effect's plausibility is stated; implausible values are said in words, with
    /// whether the rest of the search was refitted, and an alternative passed over for them is
    /// named with its reason.
    #[test]
    fn implausible_values_are_said_in_words() {
        use super::super::plausible::Plausibility;
        let ok = Plausibility {
            effect: "ground".into(),
            implies: "the plane comes within 0.001 of the fitted body (frame 7)".into(),
            implausible: None,
        };
        let bad = Plausibility {
            effect: "drag".into(),
            implies: String::new(),
            implausible: Some("drag holds up 95% of the body's weight".into()),
        };
        assert_eq!(
            super::plausibility(Some(&ok), None, false),
            "\n(ground: the plane comes within 0.001 of the fitted body (frame 7))"
        );
        let v = super::plausibility(Some(&bad), None, true);
        assert!(
            v.starts_with("\nimplausible values: drag explains the data only so: drag holds up 95%"),
            "{v}"
        );
        assert!(v.contains("every other candidate was refitted"), "{v}");
        let v = super::plausibility(Some(&ok), Some(&bad), true);
        assert!(
            v.ends_with("\n(drag fits alike, but not as a body can: drag holds up 95% of the body's weight)"),
            "{v}"
        );
        assert!(super::plausibility(None, None, false).is_empty());
    }
}
