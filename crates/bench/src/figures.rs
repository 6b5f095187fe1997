//! The report's pictures, drawn from the tables' JSON rows with the softbody charts (PNG with
//! the report font, and an SVG twin):
//!
//! - `b1_time_vs_n.png`: Table B.1, time of `d = a1 v1 + a2 v2` against the length `n` for every
//!   implementation, with the time the fused pass would take at the STREAM triad bandwidth
//!   (`4 (k + 1) n` bytes / triad GB/s), the memory-bound floor.
//! - `b2_time_vs_k.png`: Table B.2, time against the number of terms `k` at `n = 1e6`, with the
//!   traffic bounds of the fused pass (`4 (k + 1) n` bytes) and of the unfused passes
//!   (`4 n (3k - 1)` bytes) at the triad bandwidth: their ratio is the fusion ceiling.
//! - `scaling.png`: Table `scaling`, step time (and the gradient's time per step) against active
//!   nodes on log-log axes, each with its least-squares power law `t = c nodes^p` dashed and `p`
//!   in the legend.
//!
//! Drawn from JSON so that an earlier `--json` report can be redrawn without measuring again.

use crate::table_scaling::log_slope;
use serde_json::{Map, Value};
use softbody::plot::{palette, Chart, Figure, Series, Style};
use std::path::{Path, PathBuf};

fn num(row: &Value, key: &str) -> Option<f64> {
    row.get(key).and_then(Value::as_f64).filter(|x| x.is_finite())
}

/// `(x, y)` of every row where both keys hold numbers, `y` scaled by `scale`.
fn points(rows: &[Value], x: &str, y: &str, scale: f64) -> Vec<(f64, f64)> {
    rows.iter()
        .filter_map(|r| Some((num(r, x)?, num(r, y)? * scale)))
        .collect()
}

/// The implementations of B.1/B.2: JSON key and legend label.
const LINCOMB_SERIES: [(&str, &str); 6] = [
    ("gpumat_s", "gpumat fused (one pass)"),
    ("gpumat_unfused_s", "gpumat unfused (one pass per term)"),
    ("eigen_s", "Eigen (expression, 1 thread)"),
    ("faer_s", "faer (operators)"),
    ("numpy_f32_s", "numpy f32"),
    ("numpy_f64_s", "numpy f64"),
];

/// Time (ms) at the triad bandwidth for the row's `bytes_key`.
fn bound_ms(r: &Value, bytes_key: &str) -> Option<f64> {
    Some(num(r, bytes_key)? / (num(r, "stream_triad_gbs")? * 1e9) * 1e3)
}

fn lincomb_chart(rows: &[Value], x: &str, title: &str, x_label: &str, log_x: bool) -> Chart {
    let mut series: Vec<Series> = LINCOMB_SERIES
        .iter()
        .enumerate()
        .map(|(i, (key, label))| {
            Series::new(*label, points(rows, x, key, 1e3), palette(i)).with_style(Style::LineMarkers)
        })
        .filter(|s| !s.points.is_empty())
        .collect();
    let bound = |key: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .filter_map(|r| Some((num(r, x)?, bound_ms(r, key)?)))
            .collect()
    };
    series.push(
        Series::new("fused traffic at STREAM triad", bound("bytes"), [90, 90, 90]).with_style(Style::Dashed),
    );
    if !log_x {
        series.push(
            Series::new(
                "unfused traffic at STREAM triad",
                bound("unfused_bytes"),
                [170, 170, 170],
            )
            .with_style(Style::Dashed),
        );
    }
    Chart {
        title: title.into(),
        x_label: x_label.into(),
        y_label: "time per evaluation (ms)".into(),
        log_x,
        log_y: true,
        series,
        width: 760,
        height: 480,
        ..Chart::default()
    }
}

/// Table B.1's chart: time against `n` (log-log).
pub fn b1_chart(rows: &[Value]) -> Chart {
    lincomb_chart(
        rows,
        "n",
        "B.1: d = a1 v1 + a2 v2 (f32), time against vector length",
        "vector length n",
        true,
    )
}

/// Table B.2's chart: time against `k` with both traffic bounds.
pub fn b2_chart(rows: &[Value]) -> Chart {
    lincomb_chart(
        rows,
        "k",
        "B.2: d = sum of k terms a_i v_i (f32, n = 1e6), time against k",
        "number of terms k",
        false,
    )
}

/// Least-squares power law through `pts` (log-log): `(p, points of the line at the data's x)`.
fn power_law(pts: &[(f64, f64)]) -> Option<(f64, Vec<(f64, f64)>)> {
    let p = log_slope(pts)?;
    let n = pts.len() as f64;
    let mx = pts.iter().map(|q| q.0.ln()).sum::<f64>() / n;
    let my = pts.iter().map(|q| q.1.ln()).sum::<f64>() / n;
    let line = pts
        .iter()
        .map(|q| (q.0, (my + p * (q.0.ln() - mx)).exp()))
        .collect();
    Some((p, line))
}

/// Table `scaling`'s chart: step and gradient time per step against active nodes, per body.
pub fn scaling_chart(rows: &[Value]) -> Chart {
    // one group per body and preconditioner (rows without the column: the default's)
    let group = |r: &Value| -> Option<String> {
        let body = r.get("body")?.as_str()?;
        match r.get("preconditioner").and_then(Value::as_str) {
            Some(p) if p != "block_ic0" => Some(format!("{body} ({p})")),
            _ => Some(body.to_string()),
        }
    };
    let mut bodies: Vec<String> = rows.iter().filter_map(group).collect();
    bodies.dedup();
    let mut series = Vec::new();
    let mut colour = 0;
    for body in bodies {
        let of_body: Vec<Value> = rows
            .iter()
            .filter(|r| group(r).as_deref() == Some(body.as_str()))
            .cloned()
            .collect();
        for (key, what) in [("step_s", "step"), ("gradient_s", "gradient per step")] {
            let pts = points(&of_body, "nodes", key, 1.0);
            if pts.is_empty() {
                continue;
            }
            let c = palette(colour);
            colour += 1;
            match power_law(&pts) {
                Some((p, line)) => {
                    // one legend entry per series: the fit's exponent in the markers' label
                    let label = format!("{body} {what}: nodes^{p:.2}");
                    series.push(Series::new(label, pts, c).with_style(Style::Markers));
                    series.push(Series::new(String::new(), line, c).with_style(Style::Dashed));
                }
                None => series.push(Series::new(format!("{body} {what}"), pts, c).with_style(Style::Markers)),
            }
        }
    }
    // room above the data for the legend: its share of the plot's height (about 20 pixels an
    // entry of about 400) left free at the top of the log axis
    let ys = series.iter().flat_map(|s| s.points.iter().map(|p| p.1));
    let (lo, hi) = ys
        .filter(|y| *y > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), y| (lo.min(y), hi.max(y)));
    let entries = series.iter().filter(|s| !s.label.is_empty()).count();
    let free = ((entries as f64 * 20.0 + 16.0) / 400.0).min(0.6);
    let y_range = (hi > 0.0).then(|| {
        let lo = lo / 1.5;
        (lo, lo * (hi / lo).powf(1.0 / (1.0 - free)))
    });
    Chart {
        title: "scaling: time per step against active nodes (dashed: power-law fit)".into(),
        x_label: "active nodes".into(),
        y_label: "seconds per step".into(),
        log_x: true,
        log_y: true,
        series,
        y_range,
        width: 760,
        height: 520,
        ..Chart::default()
    }
}

/// Writes the charts of the tables present in `tables` (ids as in the JSON report) into `dir`
/// as PNG with an SVG twin; returns the PNG paths written.
pub fn write(tables: &Map<String, Value>, dir: &Path) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut written = Vec::new();
    type Draw = fn(&[Value]) -> Chart;
    let charts: [(&str, &str, Draw); 3] = [
        ("B.1", "b1_time_vs_n.png", b1_chart),
        ("B.2", "b2_time_vs_k.png", b2_chart),
        ("scaling", "scaling.png", scaling_chart),
    ];
    for (id, file, chart) in charts {
        let Some(rows) = tables.get(id).and_then(Value::as_array) else {
            continue;
        };
        let path = dir.join(file);
        chart(rows).picture().save(&path)?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn power_law_recovers_the_exponent() {
        let pts: Vec<(f64, f64)> = [1e3, 1e4, 1e5]
            .iter()
            .map(|&n: &f64| (n, 2e-6 * n.powf(1.3)))
            .collect();
        let (p, line) = power_law(&pts).unwrap();
        assert!((p - 1.3).abs() < 1e-12);
        for (a, b) in pts.iter().zip(&line) {
            assert!((a.1 / b.1 - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn charts_skip_missing_peers_and_draw_the_bounds() {
        let rows = vec![
            json!({"n": 1000, "k": 2, "gpumat_s": 1e-6, "gpumat_unfused_s": 2e-6, "eigen_s": null,
                   "faer_s": 3e-6, "bytes": 12000, "unfused_bytes": 20000, "stream_triad_gbs": 20.0}),
            json!({"n": 10000, "k": 2, "gpumat_s": 1e-5, "gpumat_unfused_s": 2e-5, "eigen_s": null,
                   "faer_s": 3e-5, "bytes": 120000, "unfused_bytes": 200000, "stream_triad_gbs": 20.0}),
        ];
        let c = b1_chart(&rows);
        let labels: Vec<&str> = c.series.iter().map(|s| s.label.as_str()).collect();
        assert!(!labels.iter().any(|l| l.starts_with("Eigen")), "{labels:?}");
        assert!(labels.contains(&"faer (operators)"));
        let bound = c
            .series
            .iter()
            .find(|s| s.label.starts_with("fused traffic"))
            .unwrap();
        // 12000 bytes at 20 GB/s = 0.6 us = 6e-4 ms
        assert!((bound.points[0].1 - 6e-4).abs() < 1e-12);
        let img = c.render();
        assert_eq!((img.width, img.height), (760, 480));
    }
}
