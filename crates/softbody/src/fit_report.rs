//! The pictures of a fit report: cost per iteration, each parameter per iteration, and the rms
//! per frame before and after.

use crate::plot::{palette, Chart, Figure, Picture, Series, Style};
use adjoint::problem::Evaluation;
use serde_json::{json, Value};
use std::path::Path;

/// Writes `charts`, `columns` per row ([`Picture::grid`]; one chart alone as it is), as the PNG
/// `path` and its SVG twin (`path` with the extension `svg`).
pub fn save_charts(charts: &[Chart], columns: usize, path: &Path) -> Result<(), String> {
    // each chart drawn once, into both forms
    let mut pictures: Vec<Picture> = charts.iter().map(Figure::picture).collect();
    let picture = match pictures.len() {
        1 => pictures.remove(0),
        _ => Picture::grid(pictures, columns),
    };
    picture.save(path)
}

/// The rms-per-frame chart of two evaluations.
pub fn rms_chart(title: &str, before: (&str, &Evaluation), after: (&str, &Evaluation)) -> Chart {
    let pts = |ev: &Evaluation| -> Vec<(f64, f64)> {
        ev.frames.iter().map(|f| (f.frame as f64, f.rms())).collect()
    };
    Chart {
        title: title.into(),
        x_label: "frame".into(),
        y_label: "rms distance".into(),
        log_y: true,
        series: vec![
            Series::new(before.0, pts(before.1), palette(0)).with_style(Style::LineMarkers),
            Series::new(after.0, pts(after.1), palette(1)).with_style(Style::LineMarkers),
        ],
        ..Chart::default()
    }
}

/// Writes `cost.png`, `parameters.png` and `rms_per_frame.png` (each with its SVG twin);
/// returns the PNGs' paths as JSON.
pub fn write(
    dir: &Path,
    history: &[Value],
    initial: &[(String, f64)],
    ev_initial: &Evaluation,
    ev_final: &Evaluation,
) -> Result<Value, String> {
    let iter_of = |h: &Value| h["iteration"].as_f64().unwrap_or(f64::NAN);
    let cost: Vec<(f64, f64)> = history
        .iter()
        .map(|h| (iter_of(h), h["cost"].as_f64().unwrap_or(f64::NAN)))
        .collect();
    let rms: Vec<(f64, f64)> = history
        .iter()
        .map(|h| (iter_of(h), h["rms"].as_f64().unwrap_or(f64::NAN)))
        .collect();
    let cost_chart = Chart {
        title: "cost per iteration".into(),
        x_label: "iteration".into(),
        y_label: "cost".into(),
        log_y: true,
        series: vec![Series::new("cost", cost, palette(0)).with_style(Style::LineMarkers)],
        ..Chart::default()
    };
    let rms_iter = Chart {
        title: "rms per iteration".into(),
        x_label: "iteration".into(),
        y_label: "rms distance".into(),
        log_y: true,
        series: vec![Series::new("rms", rms, palette(1)).with_style(Style::LineMarkers)],
        ..Chart::default()
    };
    let cost_path = dir.join("cost.png");
    save_charts(&[cost_chart, rms_iter], 2, &cost_path)?;

    let labels: Vec<String> = initial.iter().map(|(k, _)| k.clone()).collect();
    let mut charts = Vec::new();
    for (i, name) in labels.iter().enumerate() {
        let pts: Vec<(f64, f64)> = history
            .iter()
            .map(|h| (iter_of(h), h["parameters"][name].as_f64().unwrap_or(f64::NAN)))
            .collect();
        charts.push(Chart {
            title: name.clone(),
            x_label: "iteration".into(),
            y_label: name.clone(),
            series: vec![Series::new(name.clone(), pts, palette(i)).with_style(Style::LineMarkers)],
            hlines: vec![(initial[i].1, "start".into(), [150, 150, 150])],
            width: 480,
            height: 320,
            ..Chart::default()
        });
    }
    let params_path = dir.join("parameters.png");
    if !charts.is_empty() {
        let cols = charts.len().min(3);
        save_charts(&charts, cols, &params_path)?;
    }
    let rms_path = dir.join("rms_per_frame.png");
    let rms = rms_chart(
        "rms per frame, before and after the fit",
        ("before (start)", ev_initial),
        ("after (fitted)", ev_final),
    );
    save_charts(&[rms], 1, &rms_path)?;
    Ok(
        json!({"cost": cost_path, "parameters": params_path, "rms_per_frame": rms_path,
              "log": dir.join("fit.log"), "summary": dir.join("fit.json")}),
    )
}

/// For a two-parameter fit: the 1, 2 and 3 sigma ellipses of the first-order covariance around
/// the result (the cost valley's shape: `cost ~ cost* + s^2/2 chi^2` on the k-sigma ellipse),
/// in the reported quantities, with the optimizer's path.
pub fn uncertainty_picture(
    path: &Path,
    u: &adjoint::fit::Uncertainty,
    history: &[Value],
) -> Result<(), String> {
    let (c00, c01, c11) = (u.cov_x[0], u.cov_x[1], u.cov_x[3]);
    // 2x2 Cholesky of the covariance
    let l00 = c00.max(0.0).sqrt();
    let l10 = if l00 > 0.0 { c01 / l00 } else { 0.0 };
    let l11 = (c11 - l10 * l10).max(0.0).sqrt();
    let centre = (u.scales[0], u.scales[1]);
    // first order: quantity = value + scale * (x - x*)
    let values: Vec<f64> = u
        .labels
        .iter()
        .map(|l| {
            history
                .last()
                .and_then(|h| h["parameters"][l].as_f64())
                .unwrap_or(f64::NAN)
        })
        .collect();
    let mut series = Vec::new();
    for (k, sig) in [1.0, 2.0, 3.0].iter().enumerate() {
        let pts: Vec<(f64, f64)> = (0..=96)
            .map(|i| {
                let t = i as f64 / 96.0 * std::f64::consts::TAU;
                let (a, b) = (t.cos() * sig, t.sin() * sig);
                let dx0 = l00 * a;
                let dx1 = l10 * a + l11 * b;
                (values[0] + centre.0 * dx0, values[1] + centre.1 * dx1)
            })
            .collect();
        series.push(Series::new(format!("{sig:.0} sigma"), pts, palette(k)));
    }
    let path_pts: Vec<(f64, f64)> = history
        .iter()
        .map(|h| {
            (
                h["parameters"][&u.labels[0]].as_f64().unwrap_or(f64::NAN),
                h["parameters"][&u.labels[1]].as_f64().unwrap_or(f64::NAN),
            )
        })
        .collect();
    let tail: Vec<(f64, f64)> = path_pts.iter().rev().take(1).copied().collect();
    series.push(Series::new("result", tail, [0, 0, 0]).with_style(Style::Markers));
    let chart = Chart {
        title: "uncertainty of the result (first order)".into(),
        x_label: u.labels[0].clone(),
        y_label: u.labels[1].clone(),
        series,
        ..Chart::default()
    };
    let path_chart = Chart {
        title: "optimizer path".into(),
        x_label: u.labels[0].clone(),
        y_label: u.labels[1].clone(),
        series: vec![Series::new("iterates", path_pts, palette(3)).with_style(Style::LineMarkers)],
        ..Chart::default()
    };
    save_charts(&[chart, path_chart], 2, path)
}
