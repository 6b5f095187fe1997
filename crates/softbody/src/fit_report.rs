//! The pictures of a fit report: cost per iteration, each parameter per iteration, and the rms
//! per frame before and after.

use crate::plot::{grid_of, palette, Chart, Series, Style};
use adjoint::problem::Evaluation;
use serde_json::{json, Value};
use std::path::Path;

fn save(img: &cutfem::render::Image, path: &Path) -> Result<(), String> {
    img.save_png(path).map_err(|e| format!("{}: {e}", path.display()))
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

/// Writes `cost.png`, `parameters.png` and `rms_per_frame.png`; returns their paths as JSON.
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
    save(
        &grid_of(vec![cost_chart.render(), rms_iter.render()], 2),
        &cost_path,
    )?;

    let labels: Vec<String> = initial.iter().map(|(k, _)| k.clone()).collect();
    let mut charts = Vec::new();
    for (i, name) in labels.iter().enumerate() {
        let pts: Vec<(f64, f64)> = history
            .iter()
            .map(|h| (iter_of(h), h["parameters"][name].as_f64().unwrap_or(f64::NAN)))
            .collect();
        charts.push(
            Chart {
                title: name.clone(),
                x_label: "iteration".into(),
                y_label: name.clone(),
                series: vec![Series::new(name.clone(), pts, palette(i)).with_style(Style::LineMarkers)],
                hlines: vec![(initial[i].1, "start".into(), [150, 150, 150])],
                width: 480,
                height: 320,
                ..Chart::default()
            }
            .render(),
        );
    }
    let params_path = dir.join("parameters.png");
    if !charts.is_empty() {
        let cols = charts.len().min(3);
        save(&grid_of(charts, cols), &params_path)?;
    }
    let rms_path = dir.join("rms_per_frame.png");
    save(
        &rms_chart(
            "rms per frame, before and after the fit",
            ("before (start)", ev_initial),
            ("after (fitted)", ev_final),
        )
        .render(),
        &rms_path,
    )?;
    Ok(
        json!({"cost": cost_path, "parameters": params_path, "rms_per_frame": rms_path,
              "log": dir.join("fit.log"), "summary": dir.join("fit.json")}),
    )
}
