//! Binary little-endian PLY output of triangle meshes.

use crate::{Error, TriMesh};
use std::io::Write;
use std::path::Path;

/// Writes `mesh` to `path` as a binary little-endian PLY 1.0 file: `float x, y, z` per vertex
/// and `list uchar int vertex_indices` per face.
pub fn write_ply(mesh: &TriMesh, path: &Path) -> Result<(), Error> {
    write(mesh, None, path)
}

/// Like [`write_ply`], with one more per-vertex `float` property called `name` (e.g. a
/// residual, for colouring in a viewer). `values.len()` must equal the vertex count and `name`
/// must be a non-empty word of ASCII letters, digits and `_`.
pub fn write_ply_with_scalar(mesh: &TriMesh, values: &[f64], name: &str, path: &Path) -> Result<(), Error> {
    if values.len() != mesh.vertices.len() {
        return Err(Error::Invalid(format!(
            "write_ply_with_scalar: {} values for {} vertices",
            values.len(),
            mesh.vertices.len()
        )));
    }
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(Error::Invalid(format!(
            "write_ply_with_scalar: property name {name:?} must be a word of ASCII letters, digits and _"
        )));
    }
    write(mesh, Some((values, name)), path)
}

fn write(mesh: &TriMesh, scalar: Option<(&[f64], &str)>, path: &Path) -> Result<(), Error> {
    let nv = mesh.vertices.len();
    if nv > i32::MAX as usize {
        return Err(Error::Invalid(format!(
            "write_ply: {nv} vertices do not fit int indices"
        )));
    }
    if let Some(f) = mesh.faces.iter().find(|f| f.iter().any(|&v| v as usize >= nv)) {
        return Err(Error::Invalid(format!(
            "write_ply: face {f:?} refers to a vertex beyond the {nv} vertices"
        )));
    }
    let mut header = String::from("ply\nformat binary_little_endian 1.0\ncomment written by cutfem\n");
    header += &format!("element vertex {nv}\nproperty float x\nproperty float y\nproperty float z\n");
    if let Some((_, name)) = scalar {
        header += &format!("property float {name}\n");
    }
    header += &format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.faces.len()
    );
    let per_vertex = 12 + if scalar.is_some() { 4 } else { 0 };
    let mut buf = Vec::with_capacity(header.len() + nv * per_vertex + mesh.faces.len() * 13);
    buf.extend_from_slice(header.as_bytes());
    for (v, p) in mesh.vertices.iter().enumerate() {
        for &c in p {
            buf.extend_from_slice(&(c as f32).to_le_bytes());
        }
        if let Some((values, _)) = scalar {
            buf.extend_from_slice(&(values[v] as f32).to_le_bytes());
        }
    }
    for f in &mesh.faces {
        buf.push(3);
        for &v in f {
            buf.extend_from_slice(&(v as i32).to_le_bytes());
        }
    }
    let mut file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    file.write_all(&buf).map_err(|e| Error::io(path, e))?;
    file.flush().map_err(|e| Error::io(path, e))
}
