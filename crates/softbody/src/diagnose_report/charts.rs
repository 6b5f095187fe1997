//! The charts of a diagnosis report: rms per frame, the residual direction, the history of
//! the user's models and the candidate effects.

use super::{key_row, text_block, INK, REF_GREY, WHITE};
use crate::plot::axis::fmt_compact;
use crate::plot::{palette, BarChart, Canvas, Chart, Figure, Picture, Series, Style, SvgCanvas};
use adjoint::diagnosis::history::Entry;
use adjoint::diagnosis::Diagnosis;
use cutfem::render::Image;

/// True when the positive finite `values` span more than a decade.
pub(super) fn spans_decade(values: impl Iterator<Item = f64>) -> bool {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    hi > 10.0 * lo
}

/// A reference line when `y` can be drawn (finite, and positive on a log axis).
pub(super) fn hline(y: f64, label: &str, color: [u8; 3], log: bool) -> Option<(f64, String, [u8; 3])> {
    (y.is_finite() && (!log || y > 0.0)).then(|| (y, label.to_string(), color))
}

/// Picture 1: rms per frame with the noise floor (a chart alone: written as PNG and SVG).
pub(super) fn rms_over_time(d: &Diagnosis) -> Chart {
    let pts: Vec<(f64, f64)> = d.per_frame.iter().map(|&(f, r, _)| (f as f64, r)).collect();
    let log = spans_decade(pts.iter().map(|p| p.1).chain([d.noise_floor.unwrap_or(f64::NAN)]));
    let worst: Vec<(f64, f64)> = pts
        .iter()
        .filter(|p| p.0 == d.worst_frame as f64)
        .copied()
        .collect();
    let label = format!("model as given (rms {})", fmt_compact(d.rms));
    Chart {
        title: "rms per frame of the fitted model".into(),
        x_label: "frame".into(),
        y_label: "rms distance".into(),
        log_y: log,
        series: vec![
            Series::new(label, pts, palette(0)).with_style(Style::LineMarkers),
            Series::new(format!("worst frame {}", d.worst_frame), worst, palette(3))
                .with_style(Style::Markers),
        ],
        hlines: hline(d.noise_floor.unwrap_or(f64::NAN), "noise floor", REF_GREY, log)
            .into_iter()
            .collect(),
        width: 800,
        height: 440,
        ..Chart::default()
    }
}

/// The direction analysis in words.
pub(super) fn direction_words(d: &Diagnosis, gravity: Option<[f64; 3]>) -> String {
    let dir = &d.direction;
    let p = dir.principal;
    let trend = if dir.rms_slope >= 0.0 { "grows" } else { "falls" };
    let mut s = format!(
        "principal direction ({}, {}, {}) carries {:.0}% of the residual; a uniform shift \
         explains {:.0}%; rms {trend} {} per frame",
        fixed2(p[0]),
        fixed2(p[1]),
        fixed2(p[2]),
        100.0 * dir.principal_share,
        100.0 * dir.shift_share,
        fmt_compact(dir.rms_slope.abs()),
    );
    if let Some(g) = gravity.and_then(unit) {
        let c = (0..3).map(|k| g[k] * p[k]).sum::<f64>().abs().min(1.0);
        s.push_str(&format!("; angle to gravity {:.0} deg", c.acos().to_degrees()));
    }
    s
}

/// `x` with two decimals, without a minus sign on zero.
fn fixed2(x: f64) -> String {
    let s = format!("{x:.2}");
    if s == "-0.00" {
        "0.00".into()
    } else {
        s
    }
}

fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    (n > 0.0 && n.is_finite()).then(|| v.map(|x| x / n))
}

/// Picture 4: the per-frame mean residual vector.
pub(super) fn residual_direction(d: &Diagnosis, gravity: Option<[f64; 3]>) -> Picture {
    let pf = &d.direction.per_frame;
    let comp = |k: usize| -> Vec<(f64, f64)> { pf.iter().map(|(f, v, _)| (*f as f64, v[k])).collect() };
    let mut series = vec![
        Series::new("x", comp(0), palette(0)).with_style(Style::LineMarkers),
        Series::new("y", comp(1), palette(2)).with_style(Style::LineMarkers),
        Series::new("z", comp(2), palette(4)).with_style(Style::LineMarkers),
    ];
    if let Some(g) = gravity.and_then(unit) {
        let along = pf
            .iter()
            .map(|(f, v, _)| (*f as f64, (0..3).map(|k| g[k] * v[k]).sum::<f64>()))
            .collect();
        series.push(Series::new("along gravity", along, palette(3)).with_style(Style::Dashed));
    }
    let chart = Chart {
        title: "mean residual vector per frame (observed minus simulated)".into(),
        x_label: "frame".into(),
        y_label: "mean residual".into(),
        series,
        hlines: vec![(0.0, String::new(), [170, 170, 170])],
        width: 800,
        height: 440,
        ..Chart::default()
    }
    .picture();
    let words = text_block(chart.png.width, &direction_words(d, gravity), 2, false);
    Picture::stack(&[chart, words])
}

/// An effect list written in full: its names joined by ` + `, or "(none)".
pub(super) fn effect_list(effects: &[String]) -> String {
    if effects.is_empty() {
        return "(none)".into();
    }
    effects.join(" + ")
}

/// What changed from `before` to `after`: `+added -removed`, names in full.
pub(super) fn change(before: &[String], after: &[String]) -> String {
    let added: Vec<String> = after.iter().filter(|e| !before.contains(e)).cloned().collect();
    let removed: Vec<String> = before.iter().filter(|e| !after.contains(e)).cloned().collect();
    let mut parts = Vec::new();
    if !added.is_empty() {
        parts.push(format!("+{}", effect_list(&added)));
    }
    if !removed.is_empty() {
        parts.push(format!("-{}", effect_list(&removed)));
    }
    parts.join(" ")
}

/// Picture 5: rms per run over the user's models.
pub(super) fn history(runs: &[Entry]) -> Picture {
    let rms: Vec<(f64, f64)> = runs
        .iter()
        .enumerate()
        .map(|(i, e)| ((i + 1) as f64, e.rms))
        .collect();
    let floor: Vec<(f64, f64)> = runs
        .iter()
        .enumerate()
        .filter_map(|(i, e)| Some(((i + 1) as f64, e.noise_floor?)))
        .collect();
    let log = spans_decade(rms.iter().chain(&floor).map(|p| p.1));
    let mut series =
        vec![Series::new("rms after the fit", rms.clone(), palette(0)).with_style(Style::LineMarkers)];
    if !floor.is_empty() {
        series.push(Series::new("noise floor", floor, REF_GREY).with_style(Style::Markers));
    }
    let chart = Chart {
        title: "rms over your successive models".into(),
        x_label: "run".into(),
        y_label: "rms distance".into(),
        log_y: log,
        series,
        // integer ticks: a span of at least 6
        x_range: Some((0.0, runs.len().max(5) as f64 + 1.0)),
        width: 800,
        height: 440,
        ..Chart::default()
    };
    let mut img = SvgCanvas::new(chart.width, chart.height, WHITE);
    chart.draw(&mut img);
    // where the effect list changes: what changed, over the point
    let ([x0, y0, x1, y1], [ya, xa]) = chart.plot_area();
    let changes: Vec<(usize, String)> = (0..runs.len())
        .filter_map(|i| match i {
            0 => Some((i, effect_list(&runs[0].effects))),
            _ if runs[i].effects != runs[i - 1].effects => {
                Some((i, change(&runs[i - 1].effects, &runs[i].effects)))
            }
            _ => None,
        })
        .collect();
    let s = if changes.len() > 8 { 1 } else { 2 };
    for (i, text) in &changes {
        let (Some(fx), Some(fy)) = (xa.frac(rms[*i].0), ya.frac(rms[*i].1)) else {
            continue;
        };
        let x = x0 as f64 + fx * (x1 - x0) as f64;
        let y = y1 as f64 - fy * (y1 - y0) as f64;
        let (tw, th) = Image::text_size(text, s);
        let tx = (x as usize)
            .saturating_sub(tw / 2)
            .clamp(x0 + 2, x1.saturating_sub(tw + 2).max(x0 + 2));
        // above the point, or below where there is no room above
        let above = (y as usize).checked_sub(th + 10).filter(|&t| t >= y0 + 2);
        let ty = above.unwrap_or((y as usize + 10).min(y1.saturating_sub(th + 2)));
        img.draw_text(tx, ty, text, INK, s);
    }
    // the effect lists in full, per run of equal lists (the last eight)
    let mut spans: Vec<(usize, usize)> = Vec::new();
    for (i, _) in &changes {
        if let Some(last) = spans.last_mut() {
            last.1 = i - 1;
        }
        spans.push((*i, runs.len() - 1));
    }
    let skipped = spans.len().saturating_sub(8);
    let mut lines: Vec<String> = Vec::new();
    if skipped > 0 {
        lines.push(format!("({skipped} earlier model changes not listed)"));
    }
    for &(a, b) in &spans[skipped..] {
        let which = if a == b {
            format!("run {}", a + 1)
        } else {
            format!("runs {}-{}", a + 1, b + 1)
        };
        let effects = if runs[a].effects.is_empty() {
            "no effect".into()
        } else {
            runs[a].effects.join(", ")
        };
        let missing = runs[b]
            .missing_effect
            .as_ref()
            .map_or(String::new(), |m| format!(" (missing: {m})"));
        lines.push(format!("{which}: {effects}{missing}"));
    }
    let words = text_block(chart.width, &lines.join("\n"), 2, false);
    Picture::stack(&[img.into_picture(), words])
}

/// Picture 6: predicted and refitted rms per candidate effect.
pub(super) fn candidates(d: &Diagnosis) -> Picture {
    let (pred, refit) = (palette(0), palette(2));
    let shown = &d.candidates[..d.candidates.len().min(8)];
    // full names: the chart writes them smaller, or turned, when they don't fit under their bars
    let mut bars = Vec::new();
    for c in shown {
        // a candidate without a prediction (NaN) shows its refit alone, under its name
        let predicted = c.predicted_rms.is_finite();
        if predicted {
            bars.push((c.effect.clone(), c.predicted_rms, pred));
        }
        if let Some(r) = c.rms_after {
            let label = if predicted {
                "refit".to_string()
            } else {
                c.effect.clone()
            };
            bars.push((label, r, refit));
        }
    }
    let values = bars
        .iter()
        .map(|b| b.1)
        .chain([d.rms, d.noise_floor.unwrap_or(f64::NAN)]);
    let log = spans_decade(values);
    let chart = BarChart {
        title: "candidate effects: rms after adding each".into(),
        y_label: "rms distance".into(),
        bars,
        log_y: log,
        hlines: [
            hline(d.rms, "", palette(3), log),
            hline(d.noise_floor.unwrap_or(f64::NAN), "", REF_GREY, log),
        ]
        .into_iter()
        .flatten()
        .collect(),
        width: 800,
        height: 440,
    }
    .picture();
    let key = key_row(
        chart.png.width,
        &[
            ("predicted", pred, false),
            ("after refit", refit, false),
            ("model as given", palette(3), true),
            ("noise floor", REF_GREY, true),
        ],
    );
    let verdict = match (&d.missing_effect, d.candidates.is_empty()) {
        (_, true) => "no candidate: every effect of the catalogue is on".to_string(),
        (Some(m), _) => format!("missing effect: {m}"),
        (None, _) => "no effect is called missing".to_string(),
    };
    let note = format!(
        "predicted: Gauss-Newton prediction of the score test; after refit: a short refit with the \
         effect.\n{verdict}"
    );
    let words = text_block(chart.png.width, &note, 2, true);
    Picture::stack(&[chart, key, words])
}
