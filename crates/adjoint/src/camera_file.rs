//! Camera files: the cameras that saw an observation CSV's points, read and checked in one
//! place for every command (`fit`, `gradcheck`, `diagnose`).
//!
//! # Format
//!
//! `softbody observe` writes one beside its CSV (`obs.csv` -> `obs.cameras.json`):
//!
//! ```text
//! {"cameras": [{"id": 0, "eye": [x, y, z], "target": [x, y, z], "up": [x, y, z],
//!               "fov_y": 0.8, "width": 64, "height": 64}, ...]}
//! ```
//!
//! Every camera needs an `eye` (a finite 3-vector); its `id` (default: its position in the
//! list) is a non-negative integer, each id once, and the ids are `0..N` for `N` cameras (the id
//! indexes the camera). The intrinsics are optional for a fit (it needs only the eyes, for the
//! viewing rays) and required for `diagnose`'s pictures; where given they are checked:
//! `target` and `up` finite 3-vectors, `target` not the eye, `fov_y` in `(0, pi)` radians
//! ([`Camera::is_valid_fov_y`]), `width` and `height` integers in `1..=`[`MAX_CAMERA_PIXELS`].
//!
//! [`CameraFile::check_used`] then checks the file against the CSV: every camera id a point
//! names must be in the file (a point whose camera is unknown would silently be measured to the
//! closest surface point instead of along its ray). Every error names the file, the camera
//! (`cameras[i]`, its id) and the key.

use crate::observations::Observations;
use crate::observe::DepthCamera;
use crate::Error;
use cutfem::render::Camera;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The largest image side of a camera file (as `observe --pixels`): residual pictures are
/// rendered at that size.
pub const MAX_CAMERA_PIXELS: u64 = 8192;

/// One camera of a file.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraEntry {
    /// the eye (centre of projection)
    pub eye: [f64; 3],
    /// the point looked at
    pub target: Option<[f64; 3]>,
    /// the world up direction
    pub up: Option<[f64; 3]>,
    /// vertical field of view, radians
    pub fov_y: Option<f64>,
    /// image width, pixels
    pub width: Option<usize>,
    /// image height, pixels
    pub height: Option<usize>,
}

/// A checked camera file (module docs); `cameras[id]` is the camera of that id.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraFile {
    /// the file
    pub path: PathBuf,
    /// the cameras, indexed by id
    pub cameras: Vec<CameraEntry>,
}

impl CameraFile {
    /// Reads and checks a camera file (bounded like every configuration file).
    pub fn read(path: &Path) -> Result<Self, Error> {
        let text = cutfem::input::read_string(path, cutfem::input::MAX_CONFIG_BYTES)
            .map_err(|e| Error::io(path, e))?;
        Self::parse(&text, path)
    }

    /// Parses and checks camera file text; `path` names the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, Error> {
        let bad = |msg: String| Error::format(path, msg);
        let v: Value = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        let cams = v["cameras"]
            .as_array()
            .ok_or_else(|| bad("no `cameras` list".into()))?;
        let n = cams.len();
        let mut slots: Vec<Option<(usize, CameraEntry)>> = vec![None; n];
        for (i, c) in cams.iter().enumerate() {
            let id = match &c["id"] {
                Value::Null => i,
                v => match v.as_u64() {
                    Some(id) if (id as usize) < n => id as usize,
                    Some(id) => {
                        return Err(bad(format!(
                            "cameras[{i}].id: {id}, but the {n} cameras need the ids 0..={} (the id indexes the camera)",
                            n - 1
                        )))
                    }
                    None => {
                        return Err(bad(format!(
                            "cameras[{i}].id: not a non-negative integer: {}",
                            cutfem::scene::quote(&v.to_string(), 40)
                        )))
                    }
                },
            };
            let at = |key: &str| format!("cameras[{i}].{key}");
            let cam = format!("(camera id {id})");
            if let Some((j, _)) = &slots[id] {
                return Err(bad(format!(
                    "{}: {id} is used twice (cameras[{j}] and cameras[{i}]); every camera needs its own id",
                    at("id")
                )));
            }
            let vector = |key: &str| -> Result<Option<[f64; 3]>, Error> {
                match &c[key] {
                    Value::Null => Ok(None),
                    Value::Array(a) if a.len() == 3 => {
                        let xs: Option<Vec<f64>> = a.iter().map(Value::as_f64).collect();
                        match xs {
                            Some(x) if x.iter().all(|x| x.is_finite()) => Ok(Some([x[0], x[1], x[2]])),
                            _ => Err(bad(format!("{}: not three finite numbers {cam}", at(key)))),
                        }
                    }
                    _ => Err(bad(format!("{}: not a list [x, y, z] {cam}", at(key)))),
                }
            };
            let eye = vector("eye")?.ok_or_else(|| {
                bad(format!(
                    "{}: missing: every camera needs an eye [x, y, z] {cam}",
                    at("eye")
                ))
            })?;
            let target = vector("target")?;
            if target == Some(eye) {
                return Err(bad(format!(
                    "{}: equals the eye: the camera looks nowhere {cam}",
                    at("target")
                )));
            }
            let up = vector("up")?;
            // the picture's up: not zero, not along the viewing direction (the default y
            // included: a camera looking straight down needs its own)
            let up_used = up.unwrap_or([0.0, 1.0, 0.0]);
            let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let view = target.map_or([0.0; 3], |t| [t[0] - eye[0], t[1] - eye[1], t[2] - eye[2]]);
            let cross = [
                view[1] * up_used[2] - view[2] * up_used[1],
                view[2] * up_used[0] - view[0] * up_used[2],
                view[0] * up_used[1] - view[1] * up_used[0],
            ];
            let along = target.is_some() && norm(cross) <= 1e-9 * norm(view) * norm(up_used);
            if norm(up_used) == 0.0 || along {
                return Err(bad(format!(
                    "{}: {} {cam}",
                    at("up"),
                    if norm(up_used) == 0.0 {
                        "is zero: the picture has no up".to_string()
                    } else if up.is_none() {
                        "not given, and the default [0, 1, 0] lies along the viewing direction: give the picture's up".to_string()
                    } else {
                        "lies along the viewing direction: the picture has no up".to_string()
                    }
                )));
            }
            let fov_y = match &c["fov_y"] {
                Value::Null => None,
                v => match v.as_f64() {
                    Some(f) if Camera::is_valid_fov_y(f) => Some(f),
                    _ => {
                        return Err(bad(format!(
                            "{}: must be an angle in (0, pi) radians, found {} {cam}",
                            at("fov_y"),
                            cutfem::scene::quote(&v.to_string(), 40)
                        )))
                    }
                },
            };
            let pixels = |key: &str| match &c[key] {
                Value::Null => Ok(None),
                v => match v.as_u64() {
                    Some(p @ 1..=MAX_CAMERA_PIXELS) => Ok(Some(p as usize)),
                    _ => Err(bad(format!(
                        "{}: not an integer in 1..={MAX_CAMERA_PIXELS} {cam}",
                        at(key)
                    ))),
                },
            };
            let entry = CameraEntry {
                eye,
                target,
                up,
                fov_y,
                width: pixels("width")?,
                height: pixels("height")?,
            };
            slots[id] = Some((i, entry));
        }
        // n entries with distinct ids below n fill every slot
        let cameras = slots.into_iter().flatten().map(|(_, c)| c).collect();
        Ok(CameraFile {
            path: path.to_path_buf(),
            cameras,
        })
    }

    /// The text of the camera file of `cameras` (ids = positions), with the depth noise and
    /// seed they observed with: what `softbody observe` writes beside its CSV and
    /// [`CameraFile::parse`] reads back.
    pub fn text(cameras: &[DepthCamera], noise: f64, seed: u64) -> String {
        let cams: Vec<Value> = cameras
            .iter()
            .enumerate()
            .map(|(i, d)| {
                let c = &d.camera;
                serde_json::json!({
                    "id": i, "eye": c.eye, "target": c.target, "up": c.up, "fov_y": c.fov_y,
                    "width": d.width, "height": d.height,
                })
            })
            .collect();
        let v = serde_json::json!({"cameras": cams, "noise": noise, "seed": seed});
        // a Value of numbers, strings and lists always serializes
        serde_json::to_string_pretty(&v).unwrap_or_default()
    }

    /// The eyes, indexed by camera id.
    pub fn eyes(&self) -> Vec<[f64; 3]> {
        self.cameras.iter().map(|c| c.eye).collect()
    }

    /// The cameras with their intrinsics, indexed by id; errors naming the camera and key when
    /// one lacks `target`, `fov_y`, `width` or `height` (`up` defaults to +y).
    pub fn cameras(&self) -> Result<Vec<DepthCamera>, Error> {
        self.cameras
            .iter()
            .enumerate()
            .map(|(id, c)| -> Result<DepthCamera, Error> {
                let missing = |key: &str| {
                    Error::format(
                        &self.path,
                        format!(
                            "camera id {id}: `{key}` missing (pictures need target, fov_y, width and height)"
                        ),
                    )
                };
                Ok(DepthCamera {
                    camera: Camera {
                        eye: c.eye,
                        target: c.target.ok_or_else(|| missing("target"))?,
                        up: c.up.unwrap_or([0.0, 1.0, 0.0]),
                        fov_y: c.fov_y.ok_or_else(|| missing("fov_y"))?,
                    },
                    width: c.width.ok_or_else(|| missing("width"))?,
                    height: c.height.ok_or_else(|| missing("height"))?,
                })
            })
            .collect()
    }

    /// Errors unless every camera id that a point of `observations` (read from `csv`) names is
    /// in the file; the message names both files, the id and the CSV line that uses it.
    pub fn check_used(&self, observations: &Observations, csv: &Path) -> Result<(), Error> {
        let missing = observations
            .frames()
            .flat_map(|(_, p)| p.iter())
            .filter_map(|p| p.camera)
            .filter(|&c| c as usize >= self.cameras.len())
            .min();
        let Some(id) = missing else { return Ok(()) };
        let line = crate::fit::first_line_with(csv, "camera", u64::from(id))
            .map_or(String::new(), |l| format!(":{l}"));
        Err(Error::Invalid(format!(
            "{}{line}: camera {id}: no camera with `id` {id} in {} (it has {} cameras, ids 0..{}); \
             give the camera file that belongs to these observations (--cameras)",
            csv.display(),
            self.path.display(),
            self.cameras.len(),
            self.cameras.len()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<CameraFile, Error> {
        CameraFile::parse(text, Path::new("c.json"))
    }

    /// A camera file saved by a Windows editor (a byte order mark first) reads as without it.
    #[test]
    fn a_byte_order_mark_is_read_past() {
        let path = std::env::temp_dir().join(format!("adjoint-cameras-bom-{}.json", std::process::id()));
        std::fs::write(&path, "\u{feff}{\"cameras\": [{\"eye\": [1, 2, 3]}]}").unwrap();
        let f = CameraFile::read(&path).unwrap();
        assert_eq!(f.eyes(), vec![[1.0, 2.0, 3.0]]);
        std::fs::remove_file(&path).ok();
    }

    #[test]
    fn ids_index_the_cameras_once_each() {
        let f = parse(r#"{"cameras": [{"id": 1, "eye": [1, 0, 0]}, {"id": 0, "eye": [0, 0, 0]}]}"#).unwrap();
        assert_eq!(f.eyes(), vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
        let f = parse(r#"{"cameras": [{"eye": [1, 0, 0]}, {"eye": [2, 0, 0]}]}"#).unwrap();
        assert_eq!(f.eyes()[1], [2.0, 0.0, 0.0]);
        let e = parse(r#"{"cameras": [{"id": 0, "eye": [1, 0, 0]}, {"id": 0, "eye": [2, 0, 0]}]}"#)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("c.json: cameras[1].id: 0 is used twice (cameras[0] and cameras[1])"),
            "{e}"
        );
        let e = parse(r#"{"cameras": [{"id": 5, "eye": [1, 0, 0]}]}"#)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("c.json: cameras[0].id: 5, but the 1 cameras need the ids 0..=0"),
            "{e}"
        );
        let e = parse(r#"{"cameras": [{"id": -1, "eye": [1, 0, 0]}]}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cameras[0].id: not a non-negative integer"), "{e}");
    }

    #[test]
    fn poses_and_intrinsics_are_finite_and_positive() {
        let cam = |extra: &str| format!(r#"{{"cameras": [{{"id": 0, "eye": [0, 3, 0]{extra}}}]}}"#);
        for (extra, needle) in [
            (r#", "target": [0, 3, 0]"#, "cameras[0].target: equals the eye"),
            (
                r#", "target": [0, "a", 0]"#,
                "cameras[0].target: not three finite numbers (camera id 0)",
            ),
            (r#", "up": [0, 1]"#, "cameras[0].up: not a list [x, y, z]"),
            (
                r#", "fov_y": 0"#,
                "cameras[0].fov_y: must be an angle in (0, pi) radians, found 0",
            ),
            (
                r#", "fov_y": 4.0"#,
                "cameras[0].fov_y: must be an angle in (0, pi)",
            ),
            (r#", "width": 0"#, "cameras[0].width: not an integer in 1..=8192"),
            (
                r#", "height": 1.5"#,
                "cameras[0].height: not an integer in 1..=8192",
            ),
        ] {
            let e = parse(&cam(extra)).unwrap_err().to_string();
            assert!(e.contains(needle), "{extra}: {e}");
            assert!(e.starts_with("c.json: "), "{e}");
        }
        let e = parse(r#"{"cameras": [{"id": 0, "eye": [0, 1e400, 0]}]}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("c.json"), "{e}");
        let e = parse(r#"{"cameras": [{"id": 0}]}"#).unwrap_err().to_string();
        assert!(e.contains("cameras[0].eye: missing"), "{e}");
        // a fit needs only the eyes; pictures need the intrinsics
        let f = parse(&cam("")).unwrap();
        assert!(f
            .cameras()
            .unwrap_err()
            .to_string()
            .contains("camera id 0: `target` missing"));
        // (looking straight down: the picture's up is given, the default y would lie along
        // the view)
        let f = parse(&cam(
            r#", "target": [0, 0, 0], "up": [0, 0, 1], "fov_y": 0.8, "width": 8, "height": 6"#,
        ))
        .unwrap();
        assert_eq!(f.cameras().unwrap()[0].height, 6);
    }

    #[test]
    fn every_camera_the_csv_uses_is_in_the_file() {
        let f = parse(r#"{"cameras": [{"id": 0, "eye": [0, 3, 0]}]}"#).unwrap();
        let mut obs = Observations::new();
        let mut p = crate::observations::ObservedPoint::new([0.0; 3]);
        p.camera = Some(0);
        obs.push(1, p);
        f.check_used(&obs, Path::new("none.csv")).unwrap();
        p.camera = Some(3);
        obs.push(2, p);
        let e = f.check_used(&obs, Path::new("none.csv")).unwrap_err().to_string();
        assert!(
            e.starts_with("none.csv: camera 3: no camera with `id` 3 in c.json"),
            "{e}"
        );
    }
}
