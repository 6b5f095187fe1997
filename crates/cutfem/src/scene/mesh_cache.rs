//! The SDFs of meshes built in this process (a fit or a diagnosis builds the same scene's body
//! many times, and the winding-number SDF of a mesh costs seconds).

use std::path::{Path, PathBuf};

/// The SDFs of meshes built in this process, by file (path, size, modification time) and
/// resolution: a fit or a diagnosis builds the same scene's body many times, and the
/// winding-number SDF of a mesh costs seconds.
type MeshKey = (PathBuf, u64, Option<std::time::SystemTime>, u64);
static MESH_SDFS: std::sync::Mutex<Vec<(MeshKey, crate::SdfGrid)>> = std::sync::Mutex::new(Vec::new());
/// Meshes kept.
const MESH_CACHE: usize = 4;

fn mesh_key(path: &Path, resolution: f64) -> Option<MeshKey> {
    let meta = std::fs::metadata(path).ok()?;
    Some((
        path.to_path_buf(),
        meta.len(),
        meta.modified().ok(),
        resolution.to_bits(),
    ))
}

pub(super) fn mesh_cache_get(path: &Path, resolution: f64) -> Option<crate::SdfGrid> {
    let key = mesh_key(path, resolution)?;
    let cache = MESH_SDFS.lock().ok()?;
    cache.iter().find(|(k, _)| *k == key).map(|(_, s)| s.clone())
}

pub(super) fn mesh_cache_put(path: &Path, resolution: f64, sdf: &crate::SdfGrid) {
    let (Some(key), Ok(mut cache)) = (mesh_key(path, resolution), MESH_SDFS.lock()) else {
        return;
    };
    if cache.len() >= MESH_CACHE {
        cache.remove(0);
    }
    cache.push((key, sdf.clone()));
}
