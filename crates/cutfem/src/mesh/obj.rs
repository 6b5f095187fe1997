//! Wavefront OBJ reader: `v x y z [w]` vertices and `f` faces whose corners are `v`, `v/vt`,
//! `v//vn` or `v/vt/vn` (1-based, negative = relative to the vertices read so far); polygons
//! are fan-triangulated; every other line (`vt`, `vn`, `o`, `g`, `s`, `usemtl`, comments, ...)
//! is ignored.

use super::TriMesh;
use crate::Error;
use std::path::Path;

/// Parses OBJ text; errors name the file and the 1-based line.
pub(crate) fn parse(path: &Path, text: &str) -> Result<TriMesh, Error> {
    let mut mesh = TriMesh::default();
    // faces with their line, indices checked once all vertices are known
    let mut pending: Vec<([i64; 3], usize)> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let lineno = n + 1;
        let err = |msg: String| Error::format(path, format!("line {lineno}: {msg}"));
        let line = line.split('#').next().unwrap_or("");
        let mut tok = line.split_whitespace();
        match tok.next() {
            Some("v") => {
                let mut p = [0.0; 3];
                for (a, c) in p.iter_mut().enumerate() {
                    let t = tok
                        .next()
                        .ok_or_else(|| err(format!("vertex needs 3 coordinates, found {a}")))?;
                    *c = t
                        .parse::<f64>()
                        .map_err(|_| err(format!("bad vertex coordinate '{t}'")))?;
                    if !c.is_finite() {
                        return Err(err(format!("vertex coordinate '{t}' is not finite")));
                    }
                }
                mesh.vertices.push(p);
            }
            Some("f") => {
                let mut corners = Vec::with_capacity(4);
                for t in tok {
                    let first = t.split('/').next().unwrap_or("");
                    let i: i64 = first.parse().map_err(|_| err(format!("bad face index '{t}'")))?;
                    let idx = if i > 0 {
                        i - 1
                    } else if i < 0 {
                        let r = mesh.vertices.len() as i64 + i;
                        if r < 0 {
                            return Err(err(format!(
                                "relative index {i} points before the first vertex ({} read so far)",
                                mesh.vertices.len()
                            )));
                        }
                        r
                    } else {
                        return Err(err("face index 0 is invalid (OBJ indices start at 1)".into()));
                    };
                    corners.push(idx);
                }
                if corners.len() < 3 {
                    return Err(err(format!(
                        "face needs at least 3 vertices, found {}",
                        corners.len()
                    )));
                }
                for k in 1..corners.len() - 1 {
                    pending.push(([corners[0], corners[k], corners[k + 1]], lineno));
                }
            }
            _ => {}
        }
    }
    let nv = mesh.vertices.len() as i64;
    for (f, lineno) in pending {
        if let Some(&bad) = f.iter().find(|&&i| i >= nv || i > u32::MAX as i64) {
            return Err(Error::format(
                path,
                format!(
                    "line {lineno}: face index {} out of range (the file has {nv} vertices)",
                    bad + 1
                ),
            ));
        }
        mesh.faces.push(f.map(|i| i as u32));
    }
    Ok(mesh)
}
