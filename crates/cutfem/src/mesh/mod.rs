//! Triangle meshes: loading (`.obj`, `.stl`, `.ply`), measures, and conversion to a signed
//! distance grid.
//!
//! # Mesh to SDF
//!
//! [`TriMesh::to_sdf`] samples, at every node `q` of a grid of spacing `1 / resolution`,
//!
//! `phi(q) = s(q) min_t |q - closest_t(q)|`, `s(q) = -1 if w(q) > 1/2 else +1`,
//!
//! where `closest_t` is the exact closest point on triangle `t` (Ericson's Voronoi-region
//! method, see [`distance`]) found through a BVH, and `w` is the generalized winding number
//! `w(q) = (1 / 4 pi) sum_t Omega_t(q)` of Jacobson et al. 2013 (see [`winding`]), which is
//! 1 inside and 0 outside a closed surface and degrades gracefully on meshes with holes.
//! The magnitude is exact; the winding number is evaluated hierarchically (dipole far field).
//!
//! Along each grid row the previous node's distance `d` bounds the next one by `d + h`
//! (the distance is 1-Lipschitz), which prunes the BVH search from the start.

pub mod distance;
mod obj;
mod ply;
mod stl;
pub mod winding;

use crate::{Error, SdfGrid};
use distance::{cross, dot, norm, sub, Bvh};
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::Path;
use winding::WindingTree;

/// An indexed triangle mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// vertex positions
    pub vertices: Vec<[f64; 3]>,
    /// triangles as vertex indices (counter-clockwise seen from outside)
    pub faces: Vec<[u32; 3]>,
}

use crate::input::{read_text, Input, MAX_DATA_BYTES as MAX};

/// The bytes of an STL file, bounded ([`crate::input`]): a regular file up to [`MAX`]; a
/// stream that does not start with `solid` to the size its triangle count implies and one byte
/// more (which [`stl::parse`] refuses as not binary), any other up to [`MAX`].
fn read_stl(path: &Path) -> Result<Vec<u8>, Error> {
    let io = |e| Error::io(path, e);
    let mut input = Input::open(path).map_err(io)?;
    let regular = input.size().is_some();
    let head = input.head(84).map_err(io)?;
    let ascii = head.trim_ascii_start().starts_with(b"solid");
    if ascii || head.len() < 84 || regular {
        return input.rest(MAX).map_err(io);
    }
    // a stream that claims to be binary: what its count implies and one byte more
    let n = u32::from_le_bytes([head[80], head[81], head[82], head[83]]) as u64;
    let bytes = input.head((85 + 50 * n).min(MAX + 1) as usize).map_err(io)?;
    if bytes.len() as u64 > MAX {
        return Err(Error::format(
            path,
            format!("more than {MAX} bytes: not a regular file?"),
        ));
    }
    Ok(bytes.to_vec())
}

/// The bytes of a PLY file, bounded ([`crate::input`]): its header must end within the first
/// 64 KiB (an endless stream of anything else is refused there), the body is read up to
/// [`MAX`].
fn read_ply(path: &Path) -> Result<Vec<u8>, Error> {
    const HEADER: usize = 1 << 16;
    let io = |e| Error::io(path, e);
    let mut input = Input::open(path).map_err(io)?;
    let head = input.head(HEADER).map_err(io)?;
    if !head.windows(10).any(|w| w == b"end_header") {
        return Err(Error::format(
            path,
            format!(
                "no 'end_header' within the first {} bytes: not a PLY file",
                head.len()
            ),
        ));
    }
    input.rest(MAX).map_err(io)
}

impl TriMesh {
    /// Loads a mesh, choosing the reader by extension (case-insensitive): `.obj`, `.stl`
    /// (ASCII or binary) or `.ply` (ASCII, binary little- or big-endian). Errors name the file and
    /// the line (or element/byte for binary files).
    pub fn load(path: impl AsRef<Path>) -> Result<TriMesh, Error> {
        let path = path.as_ref();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let io = |e| Error::io(path, e);
        let mesh = match ext.as_deref() {
            Some("obj") => obj::parse(path, &String::from_utf8_lossy(&read_text(path, MAX).map_err(io)?))?,
            Some("stl") => stl::parse(path, &read_stl(path)?)?,
            Some("ply") => ply::parse(path, &read_ply(path)?)?,
            other => {
                let msg =
                    crate::scene::extension_error("mesh", path, other.unwrap_or(""), ".obj, .stl, .ply");
                return Err(Error::format(path, msg));
            }
        };
        if mesh.faces.is_empty() {
            return Err(Error::format(path, "the mesh has no triangles"));
        }
        Ok(mesh)
    }

    /// The three corner positions of face `f`.
    pub fn triangle(&self, f: usize) -> [[f64; 3]; 3] {
        self.faces[f].map(|v| self.vertices[v as usize])
    }

    /// Axis-aligned bounding box `(min, max)` of the vertices used by faces; `None` when the
    /// mesh has no face.
    pub fn bounding_box(&self) -> Option<([f64; 3], [f64; 3])> {
        let first = self.vertices[*self.faces.first()?.first()? as usize];
        let (mut lo, mut hi) = (first, first);
        for f in &self.faces {
            for &v in f {
                let p = self.vertices[v as usize];
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
        }
        Some((lo, hi))
    }

    /// Area `|(b - a) x (c - a)| / 2` of face `f`.
    pub fn triangle_area(&self, f: usize) -> f64 {
        let [a, b, c] = self.triangle(f);
        0.5 * norm(cross(sub(b, a), sub(c, a)))
    }

    /// Total surface area (the sum of [`TriMesh::triangle_area`]).
    pub fn area(&self) -> f64 {
        (0..self.faces.len()).map(|f| self.triangle_area(f)).sum()
    }

    /// Boundary half-edges `[a, b]`: a face uses `a -> b` more often than any face uses
    /// `b -> a` (repeated by the excess). Empty for a closed, consistently oriented mesh.
    pub fn boundary_edges(&self) -> Vec<[u32; 2]> {
        let mut count: HashMap<(u32, u32), i64> = HashMap::new();
        for f in &self.faces {
            for k in 0..3 {
                *count.entry((f[k], f[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        let mut out = Vec::new();
        for (&(a, b), &c) in &count {
            let excess = c - count.get(&(b, a)).copied().unwrap_or(0);
            for _ in 0..excess.max(0) {
                out.push([a, b]);
            }
        }
        out.sort_unstable();
        out
    }

    /// Signed enclosed volume by the divergence theorem, `sum_t a.(b x c) / 6` (positive for a
    /// closed outward-oriented surface).
    ///
    /// An open mesh (see [`TriMesh::boundary_edges`]) is first closed: the boundary edges are
    /// grouped into connected components (holes), and each boundary edge `a -> b` gets a cap
    /// triangle `(c, b, a)` with `c` the centroid of its hole's vertices. The result no longer
    /// depends on the origin and, for nearly planar holes, is the volume with flat caps.
    pub fn signed_volume(&self) -> f64 {
        let Some((lo, hi)) = self.bounding_box() else {
            return 0.0;
        };
        let o = [
            0.5 * (lo[0] + hi[0]),
            0.5 * (lo[1] + hi[1]),
            0.5 * (lo[2] + hi[2]),
        ];
        let tet = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
            let (a, b, c) = (sub(a, o), sub(b, o), sub(c, o));
            dot(a, cross(b, c)) / 6.0
        };
        let mut vol: f64 = (0..self.faces.len())
            .map(|f| {
                let [a, b, c] = self.triangle(f);
                tet(a, b, c)
            })
            .sum();
        let edges = self.boundary_edges();
        if edges.is_empty() {
            return vol;
        }
        // union-find over the boundary vertices
        let mut parent: HashMap<u32, u32> = HashMap::new();
        fn root(parent: &HashMap<u32, u32>, mut v: u32) -> u32 {
            while let Some(&p) = parent.get(&v) {
                if p == v {
                    break;
                }
                v = p;
            }
            v
        }
        for &[a, b] in &edges {
            parent.entry(a).or_insert(a);
            parent.entry(b).or_insert(b);
            let (ra, rb) = (root(&parent, a), root(&parent, b));
            if ra != rb {
                parent.insert(ra, rb);
            }
        }
        let mut centroid: HashMap<u32, ([f64; 3], f64)> = HashMap::new();
        let verts: Vec<u32> = parent.keys().copied().collect();
        for v in verts {
            let r = root(&parent, v);
            let e = centroid.entry(r).or_insert(([0.0; 3], 0.0));
            let p = self.vertices[v as usize];
            e.0 = [e.0[0] + p[0], e.0[1] + p[1], e.0[2] + p[2]];
            e.1 += 1.0;
        }
        for &[a, b] in &edges {
            let (s, n) = centroid[&root(&parent, a)];
            let c = [s[0] / n, s[1] / n, s[2] / n];
            vol += tet(c, self.vertices[b as usize], self.vertices[a as usize]);
        }
        vol
    }

    /// Checks that the mesh has triangles, finite vertices and in-range indices.
    pub fn validate(&self) -> Result<(), Error> {
        if self.faces.is_empty() {
            return Err(Error::Invalid("body: the mesh has no triangles".into()));
        }
        if let Some(v) = self
            .vertices
            .iter()
            .position(|p| p.iter().any(|x| !x.is_finite()))
        {
            return Err(Error::Invalid(format!("body: mesh vertex {v} is not finite")));
        }
        let n = self.vertices.len();
        if let Some(f) = self.faces.iter().position(|f| f.iter().any(|&v| v as usize >= n)) {
            return Err(Error::Invalid(format!(
                "body: mesh face {f} has a vertex index out of range (mesh has {n} vertices)"
            )));
        }
        Ok(())
    }

    /// Samples the signed distance of the mesh on a grid of spacing `1 / resolution` that covers
    /// the bounding box plus `padding_cells` cells (lattice-aligned, see
    /// [`SdfGrid::covering_grid`]): exact unsigned distance, sign from the generalized winding
    /// number (inside when `w > 1/2`). Refuses more than [`crate::sdf::MAX_NODES`] nodes
    /// before allocating.
    pub fn to_sdf(&self, resolution: f64, padding_cells: usize) -> Result<SdfGrid, Error> {
        self.validate()?;
        let (lo, hi) = self
            .bounding_box()
            .ok_or_else(|| Error::Invalid("body: empty mesh".into()))?;
        let (origin, dims) = SdfGrid::covering_grid(lo, hi, resolution, padding_cells)?;
        let query = MeshQuery::new(self)?;
        let h = 1.0 / resolution;
        let mut grid = SdfGrid {
            exact: None,
            origin,
            spacing: h,
            dims,
            values: Vec::new(),
        };
        let mut values = vec![0.0; grid.node_count()];
        values.par_chunks_mut(dims[0]).enumerate().for_each(|(row, out)| {
            let (j, k) = (row % dims[1], row / dims[1]);
            let mut prev: Option<f64> = None;
            for (i, v) in out.iter_mut().enumerate() {
                let q = grid.node_position(i, j, k);
                let d = match prev {
                    Some(p) => {
                        let bound = (p + h) * (1.0 + 1e-9) + 1e-300;
                        query
                            .bvh
                            .nearest2(q, bound * bound)
                            .map_or_else(|| query.distance(q), f64::sqrt)
                    }
                    None => query.distance(q),
                };
                prev = Some(d);
                *v = if query.winding_number(q) > 0.5 { -d } else { d };
            }
        });
        grid.values = values;
        Ok(grid)
    }
}

/// Point queries against a fixed mesh: exact unsigned distance through a BVH, generalized
/// winding number (hierarchical or exact), and their combination as a signed distance.
#[derive(Clone, Debug)]
pub struct MeshQuery {
    bvh: Bvh,
    tree: WindingTree,
}

impl MeshQuery {
    /// Builds the BVH and winding-number tree of `mesh` (validated first).
    pub fn new(mesh: &TriMesh) -> Result<MeshQuery, Error> {
        mesh.validate()?;
        let tris = (0..mesh.faces.len()).map(|f| mesh.triangle(f)).collect();
        let bvh = Bvh::new(tris);
        let tree = WindingTree::new(&bvh);
        Ok(MeshQuery { bvh, tree })
    }

    /// Exact distance from `p` to the mesh surface.
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        self.bvh
            .nearest2(p, f64::INFINITY)
            .unwrap_or(f64::INFINITY)
            .sqrt()
    }

    /// Generalized winding number at `p`, hierarchical approximation (see [`winding`]).
    pub fn winding_number(&self, p: [f64; 3]) -> f64 {
        self.tree.winding_number(&self.bvh, p)
    }

    /// Generalized winding number at `p`, exact sum over all triangles (slow: O(triangles)).
    pub fn winding_number_exact(&self, p: [f64; 3]) -> f64 {
        winding::winding_number_exact(&self.bvh.tris, p)
    }

    /// Signed distance at `p`: [`MeshQuery::distance`], negative where the winding number
    /// exceeds 1/2.
    pub fn signed_distance(&self, p: [f64; 3]) -> f64 {
        let d = self.distance(p);
        if self.winding_number(p) > 0.5 {
            -d
        } else {
            d
        }
    }
}
