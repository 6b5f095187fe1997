//! The history of a scene's models: `fit`, `diagnose` and `demo` append one JSON line per run
//! to `SCENE.history.jsonl` beside the scene (`time`, `command`, `effects`, `parameters`,
//! `rms`, and for a diagnosis `noise_floor` and `missing_effect`), so that the report can plot
//! the rms over the user's successive models.

use crate::Error;
use serde_json::{json, Value};
use std::io::{Read, Seek, SeekFrom, Write};
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
    /// the observations' fingerprint
    /// ([`crate::observations::Observations::fingerprint`]): runs on other observations (or
    /// of an older softbody, without one) are not compared with this one's rms
    pub observations: Option<String>,
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
            observations: None,
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
            "observations": self.observations,
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
            observations: v["observations"].as_str().map(str::to_string),
        })
    }
}

/// Appends `entry` to `path` (created when missing) as one line, written with one `write`
/// (runs appending at once do not interleave within a line); after a line cut short by a
/// killed run it starts a line of its own.
pub fn append(path: &Path, entry: &Entry) -> Result<(), Error> {
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .read(true)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut line = String::new();
    if len > 0 {
        let mut last = [0u8; 1];
        f.seek(SeekFrom::End(-1))
            .and_then(|_| f.read_exact(&mut last))
            .map_err(|e| Error::io(path, e))?;
        if last[0] != b'\n' {
            line.push('\n');
        }
    }
    line.push_str(&entry.to_json().to_string());
    line.push('\n');
    f.write_all(line.as_bytes()).map_err(|e| Error::io(path, e))
}

/// A history file's entries, and the numbers of the lines that were not entries (a line cut
/// short by a killed run, an edit).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct History {
    /// the entries, in the file's order
    pub entries: Vec<Entry>,
    /// 1-based numbers of the lines left out
    pub bad_lines: Vec<usize>,
}

/// Reads a history file (missing file: empty); lines that are not history entries are left
/// out and counted ([`History::bad_lines`]).
pub fn read(path: &Path) -> Result<History, Error> {
    let text = match cutfem::input::read_string(path, cutfem::input::MAX_DATA_BYTES) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(History::default()),
        Err(e) => return Err(Error::io(path, e)),
    };
    let mut h = History::default();
    for (i, l) in text.lines().enumerate() {
        if l.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<Value>(l)
            .ok()
            .and_then(|v| Entry::from_json(&v))
        {
            Some(e) => h.entries.push(e),
            None => h.bad_lines.push(i + 1),
        }
    }
    Ok(h)
}

/// What [`record`] did: the history to show (the file's entries, `entry` last) and what went
/// wrong with the file, as warnings to say.
#[derive(Clone, Debug)]
pub struct Recorded {
    /// the history with the new entry last
    pub entries: Vec<Entry>,
    /// whether the entry is in the file
    pub written: bool,
    /// one line each: the file could not be written or read, or had lines that are not entries
    pub warnings: Vec<String>,
}

/// Appends `entry` to the history file `path` and reads the history back. The history is a
/// by-product of a run (its report plots it), so nothing about the file fails the run: a file
/// that cannot be written (a read-only data folder) or read, or lines that are not entries,
/// become warnings, and the history shown is what could be read with `entry` last. Runs on
/// other observations than `entry`'s (by [`Entry::observations`]; older entries have none) are
/// left out of it with a note: their rms is of another recording.
pub fn record(path: &Path, entry: &Entry) -> Recorded {
    let mut warnings = Vec::new();
    let written = match append(path, entry) {
        Ok(()) => true,
        Err(e) => {
            warnings.push(format!("the run is not in the scene's history ({e})"));
            false
        }
    };
    let mut entries = match read(path) {
        Ok(h) => {
            if !h.bad_lines.is_empty() {
                let n = h.bad_lines.len();
                let which = match n {
                    1 => format!("line {} is not a history entry", h.bad_lines[0]),
                    _ => format!(
                        "{n} lines are not history entries (the first: line {})",
                        h.bad_lines[0]
                    ),
                };
                warnings.push(format!("{}: {which}; left out", path.display()));
            }
            h.entries
        }
        Err(e) => {
            if written {
                warnings.push(format!("the scene's history could not be read back ({e})"));
            }
            Vec::new()
        }
    };
    // read back, the file ends with the entry; else it is shown after what could be read
    if !written || entries.is_empty() {
        entries.push(entry.clone());
    }
    if let Some(fp) = &entry.observations {
        let before = entries.len();
        entries.retain(|e| e.observations.as_ref() == Some(fp));
        let other = before - entries.len();
        if other > 0 {
            warnings.push(format!(
                "{}: {other} earlier run(s) on other observations (or without their fingerprint) left out of the history picture: their rms is of another recording",
                path.display()
            ));
        }
    }
    Recorded {
        entries,
        written,
        warnings,
    }
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
        assert_eq!(r.entries.len(), 2);
        assert_eq!(r.entries[1], e);
        assert!(r.bad_lines.is_empty());
        std::fs::write(&p, "{\"x\": 1}\n").unwrap();
        assert_eq!(read(&p).unwrap().bad_lines, [1]);
        std::fs::remove_dir_all(&dir).ok();
    }

    /// The history is a by-product: a line cut short by a killed run is left out (and the
    /// next entry starts its own line), a file that cannot be written costs only the entry.
    #[test]
    fn a_broken_or_unwritable_history_costs_the_run_nothing() {
        let dir = std::env::temp_dir().join(format!("history-broken-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let e = |rms: f64| Entry::now("fit", vec!["gravity".into()], vec![("young".into(), 1.0)], rms);
        let p = dir.join("torn.history.jsonl");
        append(&p, &e(0.1)).unwrap();
        let whole = std::fs::read_to_string(&p).unwrap();
        std::fs::write(&p, format!("{whole}{}", &whole[..whole.len() / 2])).unwrap();
        let r = record(&p, &e(0.2));
        assert!(r.written);
        assert_eq!(r.entries.iter().map(|e| e.rms).collect::<Vec<_>>(), [0.1, 0.2]);
        assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
        assert!(r.warnings[0].contains("line 2"), "{:?}", r.warnings);
        let h = read(&p).unwrap();
        assert_eq!((h.entries.len(), h.bad_lines.clone()), (2, vec![2]));
        // a history that cannot be written (here: a folder in its place)
        let p = dir.join("folder.history.jsonl");
        std::fs::create_dir_all(&p).unwrap();
        let x = e(0.3);
        let r = record(&p, &x);
        assert!(!r.written);
        assert_eq!(r.entries, [x]);
        assert!(
            r.warnings[0].contains("not in the scene's history"),
            "{:?}",
            r.warnings
        );
        std::fs::remove_dir_all(&dir).ok();
    }

    /// Issue 51: a history mixes no two problems: the runs on other observations (or without a
    /// fingerprint) are left out of what a run shows, with a note, and stay in the file.
    #[test]
    fn runs_on_other_observations_are_not_compared() {
        let dir = std::env::temp_dir().join(format!("history-mixed-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("m.history.jsonl");
        let _ = std::fs::remove_file(&p);
        let e = |rms: f64, obs: Option<&str>| Entry {
            observations: obs.map(str::to_string),
            ..Entry::now("diagnose", vec![], vec![], rms)
        };
        for (rms, obs) in [(0.1, None), (0.2, Some("a")), (0.3, Some("b")), (0.4, Some("a"))] {
            append(&p, &e(rms, obs)).unwrap();
        }
        let r = record(&p, &e(0.5, Some("a")));
        assert_eq!(
            r.entries.iter().map(|e| e.rms).collect::<Vec<_>>(),
            [0.2, 0.4, 0.5]
        );
        assert!(
            r.warnings
                .iter()
                .any(|w| w.contains("2 earlier run(s) on other observations")),
            "{:?}",
            r.warnings
        );
        assert_eq!(read(&p).unwrap().entries.len(), 5);
        std::fs::remove_dir_all(&dir).ok();
    }
}
