//! Reference values (in the style of fenris' `tests/reference_values`): numbers a test computed
//! once, committed in `tests/reference_values/NAME.json` with the tolerance they are held to,
//! and compared on every run, so that a change that moves a result is seen even where the
//! result still meets its physical target.
//!
//! A file is `{"description", "command", "values": {KEY: {"value", "rel_tol", "abs_tol"}}}`
//! (a value passes within `abs_tol + rel_tol |value|`). Running the
//! test with `SOFTBODY_UPDATE_REFERENCE=1` rewrites the values it computes (and keeps their
//! tolerances), which is how a deliberate change records its new numbers.

use serde_json::{json, Map, Value};
use std::path::PathBuf;

/// The file of reference set `name`.
pub fn path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/reference_values")
        .join(format!("{name}.json"))
}

/// Compares `values` (key, value, relative and absolute tolerance for new keys) with reference
/// set `name`;
/// panics naming every value outside its tolerance. With `SOFTBODY_UPDATE_REFERENCE` set,
/// writes them instead.
pub fn check(name: &str, description: &str, command: &str, values: &[(&str, f64, f64, f64)]) {
    let p = path(name);
    let old: Value = std::fs::read_to_string(&p)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or(json!({}));
    if std::env::var_os("SOFTBODY_UPDATE_REFERENCE").is_some() {
        let mut map = Map::new();
        for &(k, v, rel, abs) in values {
            let rel = old["values"][k]["rel_tol"].as_f64().unwrap_or(rel);
            let abs = old["values"][k]["abs_tol"].as_f64().unwrap_or(abs);
            map.insert(k.to_string(), json!({"value": v, "rel_tol": rel, "abs_tol": abs}));
        }
        let doc = json!({"description": description, "command": command, "values": map});
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, serde_json::to_string_pretty(&doc).unwrap() + "\n").unwrap();
        return;
    }
    let mut bad = Vec::new();
    for &(k, v, _, _) in values {
        let entry = &old["values"][k];
        let (Some(r), Some(rel), Some(abs)) = (
            entry["value"].as_f64(),
            entry["rel_tol"].as_f64(),
            entry["abs_tol"].as_f64(),
        ) else {
            bad.push(format!(
                "{k}: no reference value in {} (run with SOFTBODY_UPDATE_REFERENCE=1)",
                p.display()
            ));
            continue;
        };
        let err = (v - r).abs();
        if err.is_nan() || err > abs + rel * r.abs() {
            bad.push(format!(
                "{k}: {v:.9e}, reference {r:.9e} (rel_tol {rel:e}, abs_tol {abs:e})"
            ));
        }
    }
    assert!(bad.is_empty(), "{}:\n{}", p.display(), bad.join("\n"));
}
