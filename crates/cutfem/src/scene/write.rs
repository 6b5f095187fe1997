//! Writing a scene back to TOML: the library's one writer of scene files (a fitted or
//! diagnosed scene is written from a [`Scene`] value, never by editing scene text).
//!
//! The text holds every core section that is set (through serde, the same field names as
//! [`Scene::parse`] reads), `[numerics]` only when it differs from the defaults, and the
//! extension sections ([`Scene::extensions`]) as they are. Relative file paths of `[body]` are
//! relative to the scene's folder: written to another folder they become absolute. The text is
//! checked by parsing it back before anything is written: [`Scene::parse`] of it gives the same
//! scene (up to the extensions' line numbers).

use super::Scene;
use crate::error::Error;
use std::path::{Path, PathBuf};

impl Scene {
    /// The scene as TOML for a file at `target` (module docs).
    pub fn to_toml(&self, target: &Path) -> Result<String, Error> {
        let mut scene = self.clone();
        let target_dir = target.parent().map(Path::to_path_buf).unwrap_or_default();
        for p in [&mut scene.body.sdf, &mut scene.body.mesh].into_iter().flatten() {
            *p = rebase(p, &self.dir, &target_dir);
        }
        let mut text = toml::to_string(&scene)
            .map_err(|e| Error::format(target, format!("cannot write the scene: {e}")))?;
        if !scene.extensions.is_empty() {
            let extensions: toml::Table = (scene.extensions.iter())
                .map(|(name, x)| (name.clone(), toml::Value::Table(x.table.clone())))
                .collect();
            let more = toml::to_string(&extensions)
                .map_err(|e| Error::format(target, format!("cannot write the scene: {e}")))?;
            text = format!("{text}\n{more}");
        }
        // the text must read back as this scene
        let mut back = Scene::parse(&text, target)?;
        for ext in back.extensions.values_mut() {
            ext.line = 0;
        }
        scene.path = back.path.clone();
        scene.dir = back.dir.clone();
        for ext in scene.extensions.values_mut() {
            ext.line = 0;
        }
        if back != scene {
            return Err(Error::format(
                target,
                "the written scene does not read back as the same scene",
            ));
        }
        Ok(text)
    }

    /// Writes the scene to `path` ([`Scene::to_toml`]) through a temporary file in the same
    /// folder renamed over `path`: a failed write leaves no half-written file.
    pub fn write(&self, path: &Path) -> Result<(), Error> {
        let text = self.to_toml(path)?;
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
        std::fs::write(&tmp, text).map_err(|e| Error::io(&tmp, e))?;
        std::fs::rename(&tmp, path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            Error::io(path, e)
        })
    }
}

/// `p` (relative to `from`, or absolute) as written in a scene file in folder `to`: unchanged
/// when absolute or when both folders are the same, else absolute.
fn rebase(p: &Path, from: &Path, to: &Path) -> PathBuf {
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    };
    let folder = |d: &Path| {
        if d.as_os_str().is_empty() {
            Path::new(".").to_path_buf()
        } else {
            d.to_path_buf()
        }
    };
    if p.is_absolute() || same(&folder(from), &folder(to)) {
        return p.to_path_buf();
    }
    let joined = folder(from).join(p);
    std::path::absolute(&joined).unwrap_or(joined)
}
