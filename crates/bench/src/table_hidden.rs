//! Table H: the diagnosis on the independent hidden-effect reference cases
//! (`tests/reference_values/independent/hidden`, made by `tools/reference/hidden.py` with
//! scikit-fem: a clamped bar in eight physical variants, three observation styles, five noise
//! levels, and a landing sphere). Every case is run as a user runs it: the `softbody diagnose` binary (built beside
//! `tables`) on the case's scene and observations, default settings, its discretisation check
//! included.
//!
//! Per case: the margin (rms of the model as given over the true noise `sigma`), the effect named
//! first, the verdict's missing effect, whether that is right (the hidden effect; nothing for the
//! controls), the rms after the named effect's refit over `sigma`, the noise floor over `sigma`,
//! the discretisation share and the parameters left on a bound. The detection curves
//! ([`curves`]): per noise level, the share of hidden-effect cases whose effect is called missing
//! and the share of controls with something called missing (false alarms), drawn by [`svg`].

use crate::progress;
use crate::report::{col, markdown_table, Fmt};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One case.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct Row {
    /// `<case>/<style>-<sigma>`
    pub case: String,
    /// the hidden effect (`null`: a control)
    pub hidden: Option<String>,
    /// observation style
    pub style: String,
    /// the true noise
    pub sigma: f64,
    /// rms of the model as given / sigma
    pub margin: Option<f64>,
    /// the effect ranked first
    pub named_first: Option<String>,
    /// the verdict's missing effect
    pub missing: Option<String>,
    /// the verdict is right (the hidden effect called missing; nothing for a control)
    pub right: Option<bool>,
    /// the hidden effect is not the one called missing but among the verdict's alternatives
    /// (the data do not tell them apart: Delta BIC within the threshold)
    pub tied: Option<bool>,
    /// rms after the missing (else the first) effect's refit / sigma
    pub rms_after_ratio: Option<f64>,
    /// stated noise floor / sigma
    pub floor_ratio: Option<f64>,
    /// discretisation share of the rms (estimate / floor)
    pub discretisation: Option<f64>,
    /// the effect called missing at `r` was withdrawn: its improvement did not persist at `2r`
    #[serde(default)]
    pub withdrew: Option<bool>,
    /// parameters of the fit as given left on a bound
    pub on_bounds: String,
    /// wall seconds
    pub seconds: f64,
    /// why it could not run, if so
    pub error: Option<String>,
}

/// The folder of the cases.
pub fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/reference_values/independent/hidden")
}

fn run_case(bin: &Path, dir: &Path, case: &Value) -> Result<Row, String> {
    let field = |k: &str| {
        case[k]
            .as_str()
            .ok_or_else(|| format!("cases.json: case without `{k}`"))
    };
    let name = field("case")?;
    let sigma = case["sigma"].as_f64().ok_or("cases.json: case without `sigma`")?;
    let hidden = case["hidden"].as_str().map(str::to_string);
    let out = std::env::temp_dir().join(format!(
        "tables-hidden-{}-{}",
        std::process::id(),
        name.replace('/', "_")
    ));
    let _ = std::fs::remove_dir_all(&out);
    progress(&format!("H: diagnose {name}"));
    let t = Instant::now();
    let o = std::process::Command::new(bin)
        .arg("diagnose")
        .arg(dir.join(field("scene")?))
        .arg("--observations")
        .arg(dir.join(field("observations")?))
        .args(["--json", "--out"])
        .arg(&out)
        .output()
        .map_err(|e| format!("{}: {e}", bin.display()))?;
    let seconds = t.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&out);
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr).trim().to_string());
    }
    let v: Value = serde_json::from_slice(&o.stdout).map_err(|e| e.to_string())?;
    let missing = v["missing_effect"].as_str().map(str::to_string);
    let named_first = v["candidates"][0]["effect"].as_str().map(str::to_string);
    let after = v["candidates"]
        .as_array()
        .and_then(|c| {
            c.iter()
                .find(|c| c["effect"].as_str() == missing.as_deref().or(named_first.as_deref()))
        })
        .and_then(|c| c["rms_after"].as_f64());
    let on_bounds: Vec<String> = v["on_bounds"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|b| Some(format!("{} ({})", b["parameter"].as_str()?, b["bound"].as_str()?)))
        .collect();
    let alternatives: Vec<&str> = v["alternatives"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(Value::as_str)
        .collect();
    Ok(Row {
        case: name.to_string(),
        right: Some(missing == hidden),
        tied: Some(missing != hidden && hidden.as_deref().is_some_and(|h| alternatives.contains(&h))),
        hidden,
        style: field("style")?.to_string(),
        sigma,
        margin: v["rms"].as_f64().map(|r| r / sigma),
        named_first,
        missing,
        rms_after_ratio: after.map(|r| r / sigma),
        floor_ratio: v["noise_floor"].as_f64().map(|f| f / sigma),
        discretisation: v["discretisation"]["share"].as_f64(),
        withdrew: v["discretisation"]["withdrew"].as_bool(),
        on_bounds: on_bounds.join(", "),
        seconds,
        error: None,
    })
}

/// Runs Table H (`quick`: the cases at noise 0.01 observed by area samples only; `only`: the
/// cases whose names start with one of these prefixes, all when empty), in `cases.json`'s order.
pub fn table(quick: bool, only: &[String]) -> Vec<Row> {
    let dir = cases_dir();
    let index: Value = match std::fs::read_to_string(dir.join("cases.json"))
        .map_err(|e| e.to_string())
        .and_then(|s| serde_json::from_str(&s).map_err(|e| e.to_string()))
    {
        Ok(v) => v,
        Err(e) => {
            progress(&format!("H: {}: {e}", dir.join("cases.json").display()));
            return Vec::new();
        }
    };
    let bin = crate::table_diagnose::softbody_binary();
    let cases = index["cases"].as_array().cloned().unwrap_or_default();
    let cases: Vec<&Value> = cases
        .iter()
        .filter(|c| !quick || (c["style"] == "samples" && c["sigma"].as_f64() == Some(0.01)))
        .filter(|c| {
            only.is_empty()
                || only
                    .iter()
                    .any(|p| c["case"].as_str().is_some_and(|n| n.starts_with(p.as_str())))
        })
        .collect();
    // two diagnoses at a time (each a process with its own threads): the cases are independent
    // and each one's result does not depend on the others
    let pool = match rayon::ThreadPoolBuilder::new().num_threads(JOBS).build() {
        Ok(p) => p,
        Err(e) => {
            progress(&format!("H: no thread pool: {e}"));
            return Vec::new();
        }
    };
    pool.install(|| {
        cases
            .par_iter()
            .map(|c| {
                let fail = |e: String| Row {
                    case: c["case"].as_str().unwrap_or("?").to_string(),
                    hidden: c["hidden"].as_str().map(str::to_string),
                    style: c["style"].as_str().unwrap_or("?").to_string(),
                    sigma: c["sigma"].as_f64().unwrap_or(f64::NAN),
                    margin: None,
                    named_first: None,
                    missing: None,
                    right: None,
                    tied: None,
                    rms_after_ratio: None,
                    floor_ratio: None,
                    discretisation: None,
                    withdrew: None,
                    on_bounds: String::new(),
                    seconds: f64::NAN,
                    error: Some(e),
                };
                match &bin {
                    Ok(bin) => run_case(bin, &dir, c).unwrap_or_else(fail),
                    Err(e) => fail(e.clone()),
                }
            })
            .collect()
    })
}

/// Diagnoses run at a time by [`table`].
const JOBS: usize = 2;

/// The rows of `earlier` with those of `fresh` in place of the rows of the same case (fresh
/// cases that `earlier` lacks added), ordered as `cases.json` lists the cases; rows of cases it
/// does not list keep their order at the end.
pub fn merge(earlier: Vec<Row>, fresh: Vec<Row>) -> Vec<Row> {
    let order: Vec<String> = std::fs::read_to_string(cases_dir().join("cases.json"))
        .ok()
        .and_then(|s| serde_json::from_str::<Value>(&s).ok())
        .and_then(|v| {
            v["cases"].as_array().map(|a| {
                a.iter()
                    .filter_map(|c| c["case"].as_str().map(str::to_string))
                    .collect()
            })
        })
        .unwrap_or_default();
    let position = |case: &str| order.iter().position(|c| c == case).unwrap_or(usize::MAX);
    let mut rows = earlier;
    for row in fresh {
        match rows.iter().position(|r| r.case == row.case) {
            Some(i) => rows[i] = row,
            None => rows.push(row),
        }
    }
    // a stable sort: rows of cases.json in its order, the others (older cases) where they were
    let mut keyed: Vec<(usize, usize, Row)> = rows
        .into_iter()
        .enumerate()
        .map(|(i, r)| (position(&r.case), i, r))
        .collect();
    keyed.sort_by_key(|(p, i, _)| (*p, *i));
    keyed.into_iter().map(|(_, _, r)| r).collect()
}

/// The rows of Table H in an earlier `tables --json` report.
pub fn rows_from_report(path: &Path) -> Result<Vec<Row>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let v: Value = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let rows = v["tables"]["H"]
        .as_array()
        .ok_or_else(|| format!("{}: no `tables.H` rows", path.display()))?;
    rows.iter()
        .enumerate()
        .map(|(i, r)| {
            serde_json::from_value(r.clone()).map_err(|e| format!("{}: tables.H[{i}]: {e}", path.display()))
        })
        .collect()
}

/// One point of the detection curves.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CurvePoint {
    /// the true noise
    pub sigma: f64,
    /// hidden-effect cases with the hidden effect called missing / hidden-effect cases
    pub detection: f64,
    /// hidden-effect cases with the hidden effect called missing or tied with the one called
    /// missing / hidden-effect cases
    pub detection_or_tied: f64,
    /// hidden-effect cases at this level
    pub hidden_cases: usize,
    /// controls with an effect called missing / controls
    pub false_alarm: f64,
    /// controls at this level
    pub controls: usize,
}

/// The detection curves of one hidden effect (`None`: every effect), from rows as JSON; an
/// effect's curve has points only at the noise levels where it has cases.
pub fn curves(rows: &[Value], effect: Option<&str>) -> Vec<CurvePoint> {
    let mut sigmas: Vec<f64> = rows.iter().filter_map(|r| r["sigma"].as_f64()).collect();
    sigmas.sort_by(f64::total_cmp);
    sigmas.dedup();
    let ran = |r: &&Value| r["right"].is_boolean();
    sigmas
        .into_iter()
        .filter_map(|s| {
            let at = rows.iter().filter(ran).filter(|r| r["sigma"].as_f64() == Some(s));
            let hidden: Vec<&Value> = at
                .clone()
                .filter(|r| r["hidden"].is_string() && effect.map_or(true, |e| r["hidden"] == e))
                .collect();
            let controls: Vec<&Value> = at.filter(|r| r["hidden"].is_null()).collect();
            let share = |v: &[&Value], f: &dyn Fn(&Value) -> bool| {
                v.iter().filter(|r| f(r)).count() as f64 / v.len().max(1) as f64
            };
            if effect.is_some() && hidden.is_empty() {
                return None;
            }
            Some(CurvePoint {
                sigma: s,
                detection: share(&hidden, &|r| r["right"] == true),
                detection_or_tied: share(&hidden, &|r| r["right"] == true || r["tied"] == true),
                hidden_cases: hidden.len(),
                false_alarm: share(&controls, &|r| r["missing"].is_string()),
                controls: controls.len(),
            })
        })
        .collect()
}

/// The hidden effects of the rows, in order of appearance.
pub fn effects(rows: &[Value]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for r in rows {
        if let Some(e) = r["hidden"].as_str() {
            if !out.iter().any(|x| x == e) {
                out.push(e.to_string());
            }
        }
    }
    out
}

/// The markdown of Table H: every case, then the detection curves per effect.
pub fn markdown(rows: &[Value]) -> String {
    let mut s = markdown_table(
        "Table H: diagnosis of the independent hidden-effect cases",
        "`tests/reference_values/independent/hidden` (tools/reference/hidden.py, scikit-fem); \
         `softbody diagnose` with default settings. margin = rms of the model as given / true noise \
         sigma; after = rms after the missing (else first) effect's refit / sigma; floor = stated \
         noise floor / sigma; disc. = discretisation share of the rms (estimate / floor); \
         withdrawn = the effect called missing at the scene's resolution did not keep its \
         improvement at twice the resolution.",
        rows,
        &[
            col("case", "case", Fmt::Plain),
            col("hidden", "hidden", Fmt::Plain),
            col("margin", "margin", Fmt::Ratio),
            col("named first", "named_first", Fmt::Plain),
            col("missing", "missing", Fmt::Plain),
            col("right", "right", Fmt::Plain),
            col("tied", "tied", Fmt::Plain),
            col("after", "rms_after_ratio", Fmt::Ratio),
            col("floor", "floor_ratio", Fmt::Ratio),
            col("disc.", "discretisation", Fmt::Ratio),
            col("withdrawn", "withdrew", Fmt::Plain),
            col("on a bound", "on_bounds", Fmt::Plain),
            col("s", "seconds", Fmt::Ratio),
            col("error", "error", Fmt::Plain),
        ],
    );
    let mut curve_rows = Vec::new();
    let names = effects(rows);
    for e in names
        .iter()
        .map(|e| Some(e.as_str()))
        .chain(std::iter::once(None))
    {
        for p in curves(rows, e) {
            let mut v = serde_json::to_value(&p).expect("curve point");
            v["effect"] = Value::from(e.unwrap_or("every effect"));
            curve_rows.push(v);
        }
    }
    s.push_str(&markdown_table(
        "Table H.curves: detection and false alarms against the noise level",
        "Per hidden effect and noise level sigma, over the observation styles: detection = share of \
         its cases with the hidden effect called missing; or tied = also counting the cases where the \
         verdict names it as an alternative the data cannot tell from the one called missing (Delta \
         BIC within 10); false alarm = share of the controls \
         (nothing hidden: the bar as it is, with a stiff inclusion too small to see, the complete \
         models of the variants with the effect in their scene, the landing sphere with its \
         ground, the sliding box with its friction) with an effect called missing.",
        &curve_rows,
        &[
            col("effect", "effect", Fmt::Plain),
            col("sigma", "sigma", Fmt::Plain),
            col("detection", "detection", Fmt::Percent),
            col("or tied", "detection_or_tied", Fmt::Percent),
            col("cases", "hidden_cases", Fmt::Plain),
            col("false alarm", "false_alarm", Fmt::Percent),
            col("controls", "controls", Fmt::Plain),
        ],
    ));
    let ran: Vec<&Value> = rows.iter().filter(|r| r["right"].is_boolean()).collect();
    let controls = ran.iter().filter(|r| r["hidden"].is_null()).count();
    let alarms = ran
        .iter()
        .filter(|r| r["hidden"].is_null() && r["missing"].is_string())
        .count();
    s.push_str(&format!(
        "\nFalse alarms over every control: {alarms} of {controls} (95% upper bound on the rate, \
         Clopper-Pearson: {:.1}%).\n",
        100.0 * upper_bound(alarms, controls, 0.05)
    ));
    s
}

/// The one-sided exact (Clopper-Pearson) upper confidence bound, level `1 - alpha`, on a rate
/// of which `k` events in `n` trials were seen: the `p` with `P(X <= k | n, p) = alpha`.
pub fn upper_bound(k: usize, n: usize, alpha: f64) -> f64 {
    if n == 0 || k >= n {
        return 1.0;
    }
    // P(X <= k) falls with p: bisect on it
    let cdf = |p: f64| {
        let (mut term, mut sum) = ((1.0 - p).powi(n as i32), 0.0);
        for i in 0..=k {
            sum += term;
            term *= (n - i) as f64 / (i + 1) as f64 * p / (1.0 - p);
        }
        sum
    };
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// An SVG picture of the detection curves: detection rate per effect and the false-alarm rate
/// against the noise level (log axis), rates 0..1.
pub fn svg(rows: &[Value]) -> String {
    let (w, h, l, r, t, b) = (720.0, 420.0, 70.0, 200.0, 40.0, 60.0);
    let all = curves(rows, None);
    let (smin, smax) = match (all.first(), all.last()) {
        (Some(a), Some(z)) if z.sigma > a.sigma => (a.sigma.ln(), z.sigma.ln()),
        (Some(a), _) => (a.sigma.ln() - 1.0, a.sigma.ln() + 1.0),
        _ => (0.0, 1.0),
    };
    let x = |s: f64| l + (s.ln() - smin) / (smax - smin) * (w - l - r);
    let y = |v: f64| h - b - v * (h - t - b);
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{}\" y=\"22\" text-anchor=\"middle\" font-size=\"14\">Hidden-effect detection on the independent reference (Table H)</text>\n",
        (l + w - r) / 2.0
    );
    for k in 0..=4 {
        let v = k as f64 / 4.0;
        out.push_str(&format!(
            "<line x1=\"{l}\" x2=\"{}\" y1=\"{y0:.1}\" y2=\"{y0:.1}\" stroke=\"#ddd\"/><text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{:.0}%</text>\n",
            w - r,
            l - 6.0,
            y(v) + 4.0,
            v * 100.0,
            y0 = y(v)
        ));
    }
    for p in &all {
        out.push_str(&format!(
            "<line x1=\"{x0:.1}\" x2=\"{x0:.1}\" y1=\"{t}\" y2=\"{}\" stroke=\"#eee\"/><text x=\"{x0:.1}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
            h - b,
            h - b + 18.0,
            p.sigma,
            x0 = x(p.sigma)
        ));
    }
    out.push_str(&format!(
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">true noise sigma (log scale)</text>\n\
         <text x=\"18\" y=\"{}\" text-anchor=\"middle\" transform=\"rotate(-90 18 {})\">rate</text>\n",
        (l + w - r) / 2.0,
        h - 18.0,
        (t + h - b) / 2.0,
        (t + h - b) / 2.0
    ));
    let colors = [
        "#1f77b4", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f",
    ];
    // (label, colour, points, dash pattern)
    type Series = (String, String, Vec<(f64, f64)>, &'static str);
    let mut series: Vec<Series> = effects(rows)
        .into_iter()
        .enumerate()
        .map(|(i, e)| {
            let pts = curves(rows, Some(&e))
                .iter()
                .map(|p| (p.sigma, p.detection))
                .collect();
            (
                format!("{e} detected"),
                colors[i % colors.len()].to_string(),
                pts,
                "",
            )
        })
        .collect();
    series.push((
        "false alarms (controls)".into(),
        "#d62728".into(),
        all.iter().map(|p| (p.sigma, p.false_alarm)).collect(),
        "6,4",
    ));
    for (i, (label, color, pts, dash)) in series.iter().enumerate() {
        // small vertical offsets keep coinciding curves apart
        let off = (i as f64 - series.len() as f64 / 2.0) * 1.5;
        let path: Vec<String> = pts
            .iter()
            .map(|&(s, v)| format!("{:.1},{:.1}", x(s), y(v) + off))
            .collect();
        out.push_str(&format!(
            "<polyline fill=\"none\" stroke=\"{color}\" stroke-width=\"2\" stroke-dasharray=\"{dash}\" points=\"{}\"/>\n",
            path.join(" ")
        ));
        for &(s, v) in pts {
            out.push_str(&format!(
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{color}\"/>\n",
                x(s),
                y(v) + off
            ));
        }
        let ly = t + 10.0 + 18.0 * i as f64;
        out.push_str(&format!(
            "<line x1=\"{}\" x2=\"{}\" y1=\"{ly}\" y2=\"{ly}\" stroke=\"{color}\" stroke-width=\"2\" stroke-dasharray=\"{dash}\"/><text x=\"{}\" y=\"{}\">{label}</text>\n",
            w - r + 10.0,
            w - r + 34.0,
            w - r + 40.0,
            ly + 4.0
        ));
    }
    out.push_str("</svg>\n");
    out
}

#[cfg(test)]
mod tests;
