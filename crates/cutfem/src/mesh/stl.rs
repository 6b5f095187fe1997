//! STL reader, ASCII and binary. A file is binary when its length is exactly
//! `84 + 50 n` for the triangle count `n` stored at byte 80 (binary files may also start with
//! "solid"); otherwise it must be ASCII (`solid`, `facet normal`, `outer loop`, 3 x `vertex x y
//! z`, `endloop`, `endfacet`, `endsolid`). Bit-identical vertices are merged.

use super::TriMesh;
use crate::Error;
use std::collections::HashMap;
use std::path::Path;

/// Collects triangles, merging bit-identical vertices.
#[derive(Default)]
struct Builder {
    mesh: TriMesh,
    seen: HashMap<[u64; 3], u32>,
}

impl Builder {
    fn vertex(&mut self, p: [f64; 3]) -> u32 {
        let key = p.map(|x| if x == 0.0 { 0 } else { x.to_bits() });
        *self.seen.entry(key).or_insert_with(|| {
            self.mesh.vertices.push(p);
            (self.mesh.vertices.len() - 1) as u32
        })
    }
    fn triangle(&mut self, t: [[f64; 3]; 3]) {
        let f = t.map(|p| self.vertex(p));
        self.mesh.faces.push(f);
    }
}

/// Parses an STL file's bytes; errors name the file and the line (ASCII) or triangle (binary).
pub(crate) fn parse(path: &Path, bytes: &[u8]) -> Result<TriMesh, Error> {
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        if bytes.len() as u64 == 84 + 50 * n {
            return parse_binary(path, bytes, n as usize);
        }
    }
    let start = bytes
        .iter()
        .position(|c| !c.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    if !bytes[start..].starts_with(b"solid") {
        return Err(Error::format(
            path,
            format!(
                "neither binary STL (84 + 50 n bytes) nor ASCII STL (starting with 'solid'); {} bytes",
                bytes.len()
            ),
        ));
    }
    parse_ascii(path, &String::from_utf8_lossy(bytes))
}

fn parse_binary(path: &Path, bytes: &[u8], n: usize) -> Result<TriMesh, Error> {
    let mut b = Builder::default();
    for t in 0..n {
        let rec = &bytes[84 + 50 * t..84 + 50 * (t + 1)];
        let f = |k: usize| {
            let at = 12 + 4 * k;
            f32::from_le_bytes([rec[at], rec[at + 1], rec[at + 2], rec[at + 3]]) as f64
        };
        let tri = [[f(0), f(1), f(2)], [f(3), f(4), f(5)], [f(6), f(7), f(8)]];
        if tri.iter().flatten().any(|x| !x.is_finite()) {
            return Err(Error::format(
                path,
                format!("triangle {t}: non-finite vertex coordinate"),
            ));
        }
        b.triangle(tri);
    }
    Ok(b.mesh)
}

fn parse_ascii(path: &Path, text: &str) -> Result<TriMesh, Error> {
    let mut b = Builder::default();
    let mut loop_vertices: Option<(Vec<[f64; 3]>, usize)> = None;
    for (n, line) in text.lines().enumerate() {
        let lineno = n + 1;
        let err = |msg: String| Error::format(path, format!("line {lineno}: {msg}"));
        let mut tok = line.split_whitespace();
        match tok.next() {
            Some("outer") => {
                if loop_vertices.is_some() {
                    return Err(err("'outer loop' inside another loop".into()));
                }
                loop_vertices = Some((Vec::with_capacity(3), lineno));
            }
            Some("vertex") => {
                let (vs, _) = loop_vertices
                    .as_mut()
                    .ok_or_else(|| err("'vertex' outside 'outer loop'".into()))?;
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
                vs.push(p);
            }
            Some("endloop") => {
                let (vs, start) = loop_vertices
                    .take()
                    .ok_or_else(|| err("'endloop' without 'outer loop'".into()))?;
                if vs.len() < 3 {
                    return Err(Error::format(
                        path,
                        format!("line {start}: facet loop has {} vertices, needs 3", vs.len()),
                    ));
                }
                for k in 1..vs.len() - 1 {
                    b.triangle([vs[0], vs[k], vs[k + 1]]);
                }
            }
            Some("solid" | "endsolid" | "facet" | "endfacet") | None => {}
            Some(other) => return Err(err(format!("unexpected keyword '{other}'"))),
        }
    }
    if let Some((_, start)) = loop_vertices {
        return Err(Error::format(
            path,
            format!("line {start}: 'outer loop' never closed"),
        ));
    }
    Ok(b.mesh)
}
