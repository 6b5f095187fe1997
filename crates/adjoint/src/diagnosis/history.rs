//! The history of a scene's models: `fit`, `diagnose` and `demo` append one JSON line per run
//! to `SCENE.history.jsonl` beside the scene (`time`, `command`, `effects`, `parameters`,
//! `rms`, and for a diagnosis `noise_floor` and `missing_effect`), so that the report can plot
//! the rms over the user's successive models.

use crate::Error;
use serde_json::{json, Value};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The history file of a scene: `dir/name.toml` -> `dir/name.history.jsonl`.
pub fn history_path(scene: &Path) -> PathBuf {
    scene.with_extension("history.jsonl")
}

/// One run.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// UTC time, `YYYY-MM-DDTHH:MM:SSZ`
    pub time: String,
    /// `fit`, `diagnose` or `demo`
    pub command: String,
    /// effects of the model
    pub effects: Vec<String>,
    /// fitted parameters
    pub parameters: Vec<(String, f64)>,
    /// rms after the fit
    pub rms: f64,
    /// noise floor (diagnosis)
    pub noise_floor: Option<f64>,
    /// missing effect found (diagnosis)
    pub missing_effect: Option<String>,
}

impl Entry {
    /// A run now.
    pub fn now(command: &str, effects: Vec<String>, parameters: Vec<(String, f64)>, rms: f64) -> Self {
        Self {
            time: utc_now(),
            command: command.into(),
            effects,
            parameters,
            rms,
            noise_floor: None,
            missing_effect: None,
        }
    }

    fn to_json(&self) -> Value {
        let params: serde_json::Map<String, Value> = self
            .parameters
            .iter()
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect();
        json!({
            "time": self.time,
            "command": self.command,
            "effects": self.effects,
            "parameters": params,
            "rms": self.rms,
            "noise_floor": self.noise_floor,
            "missing_effect": self.missing_effect,
        })
    }

    fn from_json(v: &Value) -> Option<Self> {
        Some(Self {
            time: v["time"].as_str()?.to_string(),
            command: v["command"].as_str()?.to_string(),
            effects: v["effects"]
                .as_array()?
                .iter()
                .filter_map(|e| e.as_str().map(str::to_string))
                .collect(),
            parameters: v["parameters"]
                .as_object()
                .map(|m| {
                    m.iter()
                        .filter_map(|(k, v)| Some((k.clone(), v.as_f64()?)))
                        .collect()
                })
                .unwrap_or_default(),
            rms: v["rms"].as_f64()?,
            noise_floor: v["noise_floor"].as_f64(),
            missing_effect: v["missing_effect"].as_str().map(str::to_string),
        })
    }
}

/// Appends `entry` to `path` (created when missing).
pub fn append(path: &Path, entry: &Entry) -> Result<(), Error> {
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    writeln!(f, "{}", entry.to_json()).map_err(|e| Error::io(path, e))
}

/// Reads a history file (missing file: empty). A line that is not a history entry is an error
/// naming the file and line.
pub fn read(path: &Path) -> Result<Vec<Entry>, Error> {
    let text = match cutfem::input::read_string(path, cutfem::input::MAX_DATA_BYTES) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(Error::io(path, e)),
    };
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str::<Value>(l)
                .ok()
                .and_then(|v| Entry::from_json(&v))
                .ok_or_else(|| Error::Line {
                    path: path.to_path_buf(),
                    line: i + 1,
                    msg: "not a history entry".into(),
                })
        })
        .collect()
}

/// The current UTC time as `YYYY-MM-DDTHH:MM:SSZ`.
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    utc(secs)
}

/// Unix seconds as `YYYY-MM-DDTHH:MM:SSZ` (proleptic Gregorian; Hinnant's civil_from_days).
pub fn utc(secs: u64) -> String {
    let days = (secs / 86400) as i64;
    let rem = secs % 86400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_dates() {
        assert_eq!(utc(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc(1_795_000_000), "2026-11-18T11:06:40Z");
    }

    #[test]
    fn append_and_read() {
        let dir = std::env::temp_dir().join(format!("history-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.history.jsonl");
        let _ = std::fs::remove_file(&p);
        let mut e = Entry::now(
            "fit",
            vec!["gravity".into()],
            vec![("young".into(), 2000.0)],
            0.01,
        );
        append(&p, &e).unwrap();
        e.missing_effect = Some("ground".into());
        e.noise_floor = Some(0.001);
        append(&p, &e).unwrap();
        let r = read(&p).unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(r[1], e);
        std::fs::write(&p, "{\"x\": 1}\n").unwrap();
        assert!(read(&p).unwrap_err().to_string().contains("a.history.jsonl:1"));
    }
}
