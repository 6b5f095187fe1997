//! `softbody fit STUDY.toml --design`: after the joint fit, which additional recording (from a
//! short menu of motions of the first recording's body: dropped, squeezed against the ground,
//! thrown with a spin, held and struck) would shrink the study's largest relative standard
//! error most (`adjoint::study::design`: each candidate is simulated at the fitted material,
//! observed noise-free by virtual depth cameras like the first recording's, and its
//! Gauss-Newton matrix is added to the study's). The report's `design` entry lists every candidate's predicted standard
//! errors; `design.png` shows the largest one now and with each candidate, and `design/NAME.toml`
//! holds each candidate's scene.

use crate::plot::{palette, BarChart, Figure};
use adjoint::camera_file::CameraFile;
use adjoint::fit::cameras_path;
use adjoint::observe::RigParams;
use adjoint::params::ParamSet;
use adjoint::study::design::{checked_candidates, predict, Current, Prediction};
use adjoint::study::{Recording, Study};
use rayon::prelude::*;
use serde_json::{json, Value};
use std::path::Path;

/// The relative standard error of value `v` (the absolute one when `v` is 0).
fn relative(se: f64, v: f64) -> f64 {
    if v != 0.0 {
        se / v.abs()
    } else {
        se
    }
}

/// The candidates' rig: like the first recording's cameras (their count, image side, field of
/// view and mean distance from the body's centre) when its camera file says, else 4 cameras of
/// 32 x 32 pixels at distance 3 (`observe`'s defaults). Also where it came from.
fn rig_like(rec: &Recording, center: [f64; 3]) -> (RigParams, Option<std::path::PathBuf>) {
    let path = rec
        .cameras
        .clone()
        .unwrap_or_else(|| cameras_path(&rec.observations));
    let mut rig = RigParams::default();
    let Ok(file) = CameraFile::read(&path) else {
        return (rig, None);
    };
    let cams = &file.cameras;
    if cams.is_empty() {
        return (rig, None);
    }
    rig.cameras = cams.len();
    if let Some(w) = cams.iter().filter_map(|c| c.width.max(c.height)).max() {
        rig.pixels = w;
    }
    let mean = |v: Vec<f64>| (v.len() == cams.len()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    let dist = mean(
        cams.iter()
            .map(|c| (0..3).map(|d| (c.eye[d] - center[d]).powi(2)).sum::<f64>().sqrt())
            .collect(),
    );
    if let Some(r) = dist.filter(|r| r.is_finite() && *r > 0.0) {
        rig.radius = r;
    }
    if let Some(f) = mean(cams.iter().filter_map(|c| c.fov_y).collect()) {
        rig.fov_y = f;
    }
    (rig, Some(path))
}

/// Runs the design for `study` fitted at shared coordinates `shared_x` (values `values`, in the
/// order of `current`'s shared labels; `grid`: the first recording's, whose reference surface
/// places the candidates), writes `design.png` into `out` and returns the report entry and a
/// one-line advice.
pub fn design(
    study: &Study,
    grid: &cutfem::fem::Grid,
    current: &Current,
    shared_x: &[f64],
    values: &[f64],
    out: &Path,
) -> Result<(Value, String), String> {
    let s = current.shared;
    let now = current.uncertainty().ok_or(
        "the study's Gauss-Newton matrix is singular at the fit (a parameter the data do not determine)",
    )?;
    let rel_now: Vec<f64> = (0..s).map(|i| relative(now.std_errors[i], values[i])).collect();
    let worst = (0..s)
        .max_by(|&a, &b| rel_now[a].total_cmp(&rel_now[b]))
        .ok_or("the study shares no parameter")?;
    let first = &study.recordings[0];
    let scene = cutfem::scene::Scene::load(&first.scene).map_err(|e| e.to_string())?;
    let surface = grid
        .surface()
        .map_err(|e| format!("{}: {e}", first.scene.display()))?;
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for v in &surface.mesh.vertices {
        for d in 0..3 {
            lo[d] = lo[d].min(v[d]);
            hi[d] = hi[d].max(v[d]);
        }
    }
    let shared = ParamSet::parse(&study.shared).map_err(|e| e.to_string())?;
    let center = [0, 1, 2].map(|d| 0.5 * (lo[d] + hi[d]));
    let (rig, rig_file) = rig_like(first, center);
    let (menu, unusable) = checked_candidates(&scene, lo, hi);
    let bar = crate::progress::bar(menu.len() as u64, "design", false);
    let mut predictions: Vec<Prediction> = menu
        .par_iter()
        .map(|c| {
            let p = predict(c, &shared, &study.per_recording, shared_x, current, &rig);
            bar.inc(1);
            p
        })
        .collect();
    predictions.extend(unusable);
    bar.finish_and_clear();
    let label = &current.labels[worst];
    let best = predictions
        .iter()
        .filter_map(|p| {
            p.std_errors
                .as_ref()
                .map(|se| (p, relative(se[worst], values[worst])))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let pct = |r: f64| format!("{:.2}%", 100.0 * r);
    let advice = match best {
        Some((p, r)) => format!(
            "experiment design: the largest relative standard error is {label}'s ({}); a `{}` recording ({}) would bring it to {} ({})",
            pct(rel_now[worst]),
            p.name,
            p.what,
            pct(r),
            predictions
                .iter()
                .map(|q| match &q.std_errors {
                    Some(se) => format!("{}: {}", q.name, pct(relative(se[worst], values[worst]))),
                    None => format!("{}: failed", q.name),
                })
                .collect::<Vec<_>>()
                .join(", ")
        ),
        None => format!(
            "experiment design: no candidate motion could be simulated ({})",
            predictions
                .iter()
                .map(|q| format!("{}: {}", q.name, q.error.clone().unwrap_or_default()))
                .collect::<Vec<_>>()
                .join("; ")
        ),
    };
    // each motion as a scene file (the first recording's scene, material as given there), to
    // record it, or observe it
    let scenes = out.join("design");
    std::fs::create_dir_all(&scenes).map_err(|e| format!("{}: {e}", scenes.display()))?;
    let mut files = Vec::with_capacity(menu.len());
    for c in &menu {
        let path = scenes.join(format!("{}.toml", c.name));
        c.scene.write(&path).map_err(|e| e.to_string())?;
        files.push(path);
    }
    let picture = out.join("design.png");
    let mut bars = vec![("now".to_string(), 100.0 * rel_now[worst], palette(1))];
    bars.extend(predictions.iter().map(|p| {
        let r = p
            .std_errors
            .as_ref()
            .map_or(f64::NAN, |se| relative(se[worst], values[worst]));
        (format!("+ {}", p.name), 100.0 * r, palette(0))
    }));
    BarChart {
        title: format!("{label}: standard error now and with one more recording"),
        y_label: "standard error (% of the value)".into(),
        bars,
        ..BarChart::default()
    }
    .picture()
    .save(&picture)?;
    let labelled = |se: &[f64]| -> Value {
        (0..s)
            .map(|i| (current.labels[i].clone(), json!(se[i])))
            .collect::<serde_json::Map<_, _>>()
            .into()
    };
    let entry = json!({
        "parameter": label,
        "relative_std_error": rel_now[worst],
        "std_errors": labelled(&now.std_errors),
        "rig": {"cameras": rig.cameras, "pixels": rig.pixels, "radius": rig.radius,
                "fov_degrees": rig.fov_y.to_degrees(), "like": rig_file},
        "candidates": predictions.iter().zip(&files).map(|(p, file)| json!({
            "name": p.name,
            "scene": file,
            "motion": p.what,
            "points": p.points,
            "std_errors": p.std_errors.as_deref().map(labelled),
            "relative_std_error": p.std_errors.as_ref().map(|se| relative(se[worst], values[worst])),
            "error": p.error,
        })).collect::<Vec<_>>(),
        "best": best.map(|(p, _)| p.name),
        "picture": picture,
    });
    Ok((entry, advice))
}
