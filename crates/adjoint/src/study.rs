//! Studies: several recordings of one body fitted jointly (one material for all of them).
//!
//! A study file (TOML, `docs/study.md`) names the recordings (a scene, its observations and
//! optionally its camera file and step count each) and splits the fitted parameters into
//! those **shared** by every recording (the material, the damping, gravity) and those each
//! recording has **its own** copy of (its initial velocity, its ground plane):
//!
//! ```toml
//! [study]
//! shared = ["young", "poisson"]
//! per_recording = ["initial_velocity"]   # optional
//!
//! [[recording]]
//! name = "drop"                          # optional (default: the scene file's stem)
//! scene = "drop.toml"
//! observations = "drop.csv"
//! ```
//!
//! # The joint objective
//!
//! With recordings `r = 1..R`, shared coordinates `s` and each recording's own `o_r`, the joint
//! coordinates are `X = (s, o_1, ..., o_R)` and recording `r` is evaluated at `x_r = (s, o_r)`
//! (its problem's parameters are the shared ones followed by its own). The cost is the sum
//! `J(X) = sum_r J_r(x_r)` of the recordings' weighted least-squares costs, so the statistics
//! of one fit carry over (`crate::statistics`: one unknown `sigma^2` for every point of every
//! recording). The gradient and the Gauss-Newton matrix are sums with a block structure:
//!
//! ```text
//! dJ/ds = sum_r dJ_r/ds,            dJ/do_r = dJ_r/do_r,
//! H_ss  = sum_r H_r,ss,  H_s,o_r = H_r,so,  H_o_r,o_r = H_r,oo,  H_o_r,o_q = 0 (r != q).
//! ```
//!
//! The recordings are evaluated in parallel (rayon); the sums are taken afterwards in the
//! recordings' order, so the result is bit-identical whatever the thread count, and a study of
//! one recording gives its single problem's numbers to the bit ([`joint`]). Across processes
//! (MPI ranks) each rank evaluates the recordings it owns and the results are exchanged before
//! the same ordered sums ([`ensemble`]), so the rank count does not change a bit either. After a
//! fit, [`design`] predicts which further motion would shrink the largest standard error most,
//! and [`starts`] spreads multi-start fits over the plausible box.

pub mod design;
pub mod ensemble;
pub mod joint;
pub mod starts;

use crate::params::{Param, ParamSet};
use crate::Error;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The `[study]` table.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct Section {
    shared: Option<Vec<String>>,
    per_recording: Option<Vec<String>>,
    cost: Option<String>,
    optimizer: Option<String>,
    iterations: Option<usize>,
}

/// One `[[recording]]` as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    name: Option<String>,
    scene: PathBuf,
    observations: PathBuf,
    cameras: Option<PathBuf>,
    steps: Option<usize>,
}

/// The file as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    study: Option<Section>,
    recording: Vec<Entry>,
}

/// One recording of a study; paths are resolved against the study file's folder.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// unique name (the report's key)
    pub name: String,
    /// the scene file
    pub scene: PathBuf,
    /// the observation CSV
    pub observations: PathBuf,
    /// the camera file, when given
    pub cameras: Option<PathBuf>,
    /// steps to simulate (default: the scene's)
    pub steps: Option<usize>,
}

/// A parsed and checked study file.
#[derive(Clone, Debug)]
pub struct Study {
    /// the file
    pub path: PathBuf,
    /// parameters shared by every recording (names as in `--params`)
    pub shared: Vec<String>,
    /// parameters each recording has its own copy of
    pub per_recording: Vec<String>,
    /// `surface` | `levelset` (default: surface)
    pub cost: Option<String>,
    /// the optimizer (default: the fit's)
    pub optimizer: Option<String>,
    /// maximum iterations (default: the fit's)
    pub iterations: Option<usize>,
    /// the recordings, in the file's order
    pub recordings: Vec<Recording>,
}

/// True when the TOML text is meant as a study file (it has `[[recording]]` tables or a
/// `[study]` section, of whatever shape: [`Study::parse`] then says what is wrong with them),
/// not a scene (no scene has either key). Text that is not TOML is neither: the scene reader
/// names its line.
pub fn is_study(text: &str) -> bool {
    text.parse::<toml::Table>()
        .map(|t| t.contains_key("recording") || t.contains_key("study"))
        .unwrap_or(false)
}

/// The longest recording name, in characters.
pub const MAX_NAME_CHARS: usize = 100;

/// Checks a recording's name: it names the recording's folder in a study's report, so it must
/// be one portable file name: not `.` or `..`, not hidden (a leading `.`), no path separator,
/// no control character, none of the characters Windows refuses in file names (`<>:"/\|?*`),
/// at most [`MAX_NAME_CHARS`] characters.
pub fn check_name(name: &str) -> Result<(), String> {
    let shown: String = name.escape_debug().collect();
    if name.starts_with('.') {
        return Err(format!(
            "`{shown}` must not start with '.' (it names the recording's folder in the report)"
        ));
    }
    if let Some(c) = name
        .chars()
        .find(|c| c.is_control() || "<>:\"/\\|?*".contains(*c))
    {
        return Err(format!(
            "`{shown}` must not contain {:?} (it names the recording's folder in the report; use letters, digits, spaces, '-', '_', '.')",
            c
        ));
    }
    if name.chars().count() > MAX_NAME_CHARS {
        return Err(format!(
            "`{}...` is longer than {MAX_NAME_CHARS} characters",
            name.chars().take(20).collect::<String>()
        ));
    }
    Ok(())
}

impl Study {
    /// Reads and checks a study file.
    pub fn load(path: &Path) -> Result<Study, Error> {
        let text = cutfem::input::read_string(path, cutfem::input::MAX_CONFIG_BYTES)
            .map_err(|e| Error::Invalid(format!("{}: {e}", path.display())))?;
        let study = Self::parse(&text, path)?;
        study.check_repeats()?;
        Ok(study)
    }

    /// Errors when two recordings are one: the same scene and the same observations (the same
    /// files, or files of the same bytes). Fitted twice, every point would count twice and the
    /// standard errors would shrink by sqrt(2). Unreadable files are left to their reader.
    pub fn check_repeats(&self) -> Result<(), Error> {
        let id = |p: &Path| {
            cutfem::input::file_digest(p).map_or_else(
                || {
                    format!(
                        "path {}",
                        std::fs::canonicalize(p)
                            .unwrap_or_else(|_| p.to_path_buf())
                            .display()
                    )
                },
                |d| format!("bytes {d:016x}"),
            )
        };
        let ids: Vec<(String, String)> = self
            .recordings
            .iter()
            .map(|r| (id(&r.scene), id(&r.observations)))
            .collect();
        for (j, b) in ids.iter().enumerate() {
            if let Some(i) = ids[..j].iter().position(|a| a == b) {
                let (ri, rj) = (&self.recordings[i], &self.recordings[j]);
                return Err(Error::Invalid(format!(
                    "{}: recording[{j}] (`{}`) repeats recording[{i}] (`{}`): the same scene and the same observations ({}); fitted twice, every point would count twice",
                    self.path.display(),
                    rj.name,
                    ri.name,
                    rj.observations.display()
                )));
            }
        }
        Ok(())
    }

    /// Parses study text; `path` names the file in errors and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Study, Error> {
        let at = |msg: String| Error::Invalid(format!("{}: {msg}", path.display()));
        let file: File = toml::from_str(text).map_err(|e| {
            let line = e
                .span()
                .map(|s| {
                    format!(
                        "line {}: ",
                        text[..s.start.min(text.len())].matches('\n').count() + 1
                    )
                })
                .unwrap_or_default();
            at(format!("{line}{}", e.message().replace('\n', " ")))
        })?;
        let section = file.study.unwrap_or_default();
        let shared = section.shared.unwrap_or_default();
        let per_recording = section.per_recording.unwrap_or_default();
        let parse = |names: &[String], key: &str| -> Result<Vec<Param>, Error> {
            if names.iter().all(|n| n.trim().is_empty()) {
                return Ok(Vec::new());
            }
            ParamSet::parse(names)
                .map(|s| s.params)
                .map_err(|e| at(format!("study.{key}: {e}")))
        };
        let (sp, op) = (parse(&shared, "shared")?, parse(&per_recording, "per_recording")?);
        if sp.is_empty() && op.is_empty() {
            return Err(at(
                "study.shared: no parameters to fit (name them in study.shared and/or study.per_recording)"
                    .into(),
            ));
        }
        if let Some(p) = sp.iter().find(|p| op.contains(p)) {
            return Err(at(format!("study: `{p}` is both in shared and in per_recording")));
        }
        if sp.contains(&Param::StiffnessField) {
            return Err(at(
                "study.shared: stiffness_field cannot be shared (its basis follows each recording's grid); fit it per recording".into(),
            ));
        }
        if let Some(o) = &section.optimizer {
            o.parse::<crate::optim::Optimizer>()
                .map_err(|e| at(format!("study.optimizer: {e}")))?;
        }
        if let Some(c) = &section.cost {
            c.parse::<crate::fit::CostKind>()
                .map_err(|e| at(format!("study.cost: {e}")))?;
        }
        if section.iterations == Some(0) {
            return Err(at("study.iterations: must be at least 1".into()));
        }
        if file.recording.is_empty() {
            return Err(at("no [[recording]]: a study needs at least one".into()));
        }
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut recordings: Vec<Recording> = Vec::with_capacity(file.recording.len());
        for (i, e) in file.recording.into_iter().enumerate() {
            let given = e.name.is_some();
            let name = e
                .name
                .map(|n| n.trim().to_string())
                .or_else(|| e.scene.file_stem().map(|s| s.to_string_lossy().into_owned()))
                .filter(|n| !n.is_empty())
                .unwrap_or_else(|| format!("recording-{}", i + 1));
            let key = if !given {
                format!("recording[{i}].name (not given: the scene's file name)")
            } else {
                format!("recording[{i}].name")
            };
            check_name(&name).map_err(|e| at(format!("{key}: {e}")))?;
            if let Some(r) = recordings
                .iter()
                .find(|r| r.name.to_lowercase() == name.to_lowercase())
            {
                let how = if r.name == name {
                    String::new()
                } else {
                    format!(
                        " (as `{}`: names that differ only in case are one folder on macOS and Windows)",
                        r.name
                    )
                };
                return Err(at(format!(
                    "{key}: `{name}` names two recordings{how}; give each a unique name"
                )));
            }
            let paths = [
                ("scene", Some(&e.scene)),
                ("observations", Some(&e.observations)),
                ("cameras", e.cameras.as_ref()),
            ];
            if let Some((key, _)) = paths
                .iter()
                .find(|(_, p)| p.is_some_and(|p| p.as_os_str().is_empty()))
            {
                return Err(at(format!(
                    "recording[{i}].{key}: empty (name a file, relative to the study file)"
                )));
            }
            if e.steps == Some(0) {
                return Err(at(format!("recording[{i}].steps: must be at least 1")));
            }
            if let Some(n) = e.steps {
                cutfem::scene::check_steps(n, &format!("recording[{i}].steps")).map_err(at)?;
            }
            recordings.push(Recording {
                name,
                scene: dir.join(e.scene),
                observations: dir.join(e.observations),
                cameras: e.cameras.map(|c| dir.join(c)),
                steps: e.steps,
            });
        }
        Ok(Study {
            path: path.to_path_buf(),
            shared,
            per_recording,
            cost: section.cost,
            optimizer: section.optimizer,
            iterations: section.iterations,
            recordings,
        })
    }

    /// The parameters of one recording's problem: the shared ones, then its own.
    pub fn recording_params(&self) -> Vec<String> {
        self.shared
            .iter()
            .chain(&self.per_recording)
            .filter(|n| !n.trim().is_empty())
            .cloned()
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Study, String> {
        Study::parse(text, Path::new("/data/s.toml")).map_err(|e| e.to_string())
    }

    const TWO: &str = "[study]\nshared = [\"young\", \"poisson\"]\nper_recording = [\"initial_velocity\"]\n\n\
        [[recording]]\nscene = \"drop.toml\"\nobservations = \"drop.csv\"\n\n\
        [[recording]]\nname = \"throw\"\nscene = \"sub/throw.toml\"\nobservations = \"throw.csv\"\ncameras = \"c.json\"\nsteps = 20\n";

    /// Issue 51: two recordings of the same scene and observations (the same files, or
    /// copies of the same bytes) are refused on load, naming both; the same scene with other
    /// observations, or other scenes with the same observations, are two recordings.
    #[test]
    fn a_repeated_recording_is_refused() {
        let dir = std::env::temp_dir().join(format!("study-repeat-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (name, text) in [
            ("a.toml", "scene a"),
            ("b.toml", "scene b"),
            ("x.csv", "frame,x,y,z\n1,0,0,0\n"),
            ("copy.csv", "frame,x,y,z\n1,0,0,0\n"),
            ("y.csv", "frame,x,y,z\n1,1,0,0\n"),
        ] {
            std::fs::write(dir.join(name), text).unwrap();
        }
        let study = |recs: &[(&str, &str)]| {
            let mut text = "[study]\nshared = [\"young\"]\n".to_string();
            for (k, (scene, obs)) in recs.iter().enumerate() {
                text.push_str(&format!(
                    "[[recording]]\nname = \"r{k}\"\nscene = \"{scene}\"\nobservations = \"{obs}\"\n"
                ));
            }
            let path = dir.join("s.toml");
            std::fs::write(&path, text).unwrap();
            Study::load(&path).map(|_| ()).map_err(|e| e.to_string())
        };
        for repeat in [
            [("a.toml", "x.csv"), ("a.toml", "x.csv")],
            [("a.toml", "x.csv"), ("a.toml", "copy.csv")],
        ] {
            let e = study(&repeat).unwrap_err();
            assert!(
                e.contains("recording[1] (`r1`) repeats recording[0] (`r0`)"),
                "{e}"
            );
        }
        assert!(study(&[("a.toml", "x.csv"), ("a.toml", "y.csv")]).is_ok());
        assert!(study(&[("a.toml", "x.csv"), ("b.toml", "x.csv")]).is_ok());
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_study_resolves_paths_and_names() {
        assert!(is_study(TWO));
        assert!(!is_study("[time]\nsteps = 3\n"));
        // a study written wrongly is still a study (its parser names the mistake)
        for wrong in [
            "recording = 3\n",
            "[recording]\nscene = \"a.toml\"\n",
            "[study]\n",
        ] {
            assert!(is_study(wrong), "{wrong}");
        }
        assert!(!is_study("[[recording]\n"));
        let s = parse(TWO).unwrap();
        assert_eq!(s.recordings.len(), 2);
        assert_eq!(s.recordings[0].name, "drop");
        assert_eq!(s.recordings[0].scene, Path::new("/data/drop.toml"));
        assert_eq!(
            s.recordings[1].cameras.as_deref(),
            Some(Path::new("/data/c.json"))
        );
        assert_eq!(s.recordings[1].steps, Some(20));
        assert_eq!(s.recording_params(), vec!["young", "poisson", "initial_velocity"]);
    }

    #[test]
    fn bad_studies_name_the_file_and_key() {
        let cases = [
            (
                TWO.replace("shared = [\"young\", \"poisson\"]", "shared = [\"youngs\"]"),
                "study.shared",
            ),
            (
                TWO.replace("[\"initial_velocity\"]", "[\"young\"]"),
                "both in shared",
            ),
            (
                TWO.replace("name = \"throw\"", "name = \"drop\""),
                "names two recordings",
            ),
            (TWO.replace("steps = 20", "steps = 0"), "recording[1].steps"),
            (
                TWO.replace("\"sub/throw.toml\"", "\"\""),
                "recording[1].scene: empty",
            ),
            (TWO.replace("\"c.json\"", "\"\""), "recording[1].cameras: empty"),
            (
                TWO.replace("[study]\n", "[study]\noptimizer = \"adam\"\n"),
                "study.optimizer: unknown optimizer `adam`",
            ),
            (
                "[study]\nshared = [\"young\"]\n[recording]\nscene = \"a.toml\"\nobservations = \"a.csv\"\n"
                    .to_string(),
                "line 3: invalid type: map, expected a sequence",
            ),
            (
                TWO.replace("steps = 20", "steps = 1000001"),
                "recording[1].steps: 1000001 steps is more than",
            ),
            (
                TWO.replace("steps = 20", "step = 20"),
                "line 14: unknown field `step`",
            ),
            (
                TWO.replace(
                    "shared = [\"young\", \"poisson\"]",
                    "shared = [\"stiffness_field\"]",
                ),
                "cannot be shared",
            ),
            (
                "[study]\nshared = [\"young\"]\n".to_string(),
                "missing field `recording`",
            ),
            (
                "recording = []\n[study]\nshared = [\"young\"]\n".to_string(),
                "no [[recording]]",
            ),
            (
                TWO.replace("per_recording = [\"initial_velocity\"]\n", "")
                    .replace("[\"young\", \"poisson\"]", "[]"),
                "no parameters",
            ),
        ];
        for (text, want) in cases {
            let e = parse(&text).unwrap_err();
            assert!(e.starts_with("/data/s.toml: ") && e.contains(want), "{want}: {e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }

    /// A recording's name becomes a folder of the study's report: names that would leave the
    /// report (`..`), hide in it, hold a separator, or collide on a case-blind file system are
    /// refused; ordinary names (spaces, accents, dots inside) are kept.
    #[test]
    fn recording_names_are_portable_folder_names() {
        let with = |name: &str| TWO.replace("name = \"throw\"", &format!("name = {name:?}"));
        let refused = [
            ("..", "must not start with '.'"),
            (".", "must not start with '.'"),
            (".softbody-out", "must not start with '.'"),
            ("../../etc", "must not start with '.'"),
            ("a/b", "must not contain '/'"),
            ("a\\b", "must not contain '\\\\'"),
            ("c:x", "must not contain ':'"),
            ("what?", "must not contain '?'"),
            ("line\nbreak", "must not contain '\\n'"),
            ("Drop", "differ only in case"),
            (&"x".repeat(101), "longer than 100"),
        ];
        for (name, want) in refused {
            let e = parse(&with(name)).unwrap_err();
            assert!(
                e.contains("recording[1].name") && e.contains(want),
                "{name:?}: {e}"
            );
            assert!(!e.contains('\n'), "{e}");
        }
        for name in ["throw 2", "Würfe (weich)", "v1.2", "-x", &"x".repeat(100)] {
            assert_eq!(parse(&with(name)).unwrap().recordings[1].name, name);
        }
        // a default name (the scene's file stem) is checked too
        let hidden = TWO.replace(
            "name = \"throw\"\nscene = \"sub/throw.toml\"",
            "scene = \"sub/.throw.toml\"",
        );
        assert!(parse(&hidden).unwrap_err().contains("must not start with '.'"));
    }
}
