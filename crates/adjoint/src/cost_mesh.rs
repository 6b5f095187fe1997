//! The distance of observed points to the simulated surface mesh: the surface `softbody
//! simulate` writes and `softbody observe` renders ([`cutfem::fem::Grid::surface`]: marching
//! cubes on the body's SDF sampled `[numerics] surface_subdivision` times finer than the
//! simulation grid, each vertex moved by the trilinear displacement of its cell; with 1, the
//! default, on the grid itself, each vertex moved along its grid edge, sec. 4.5.1).
//!
//! For a point `p` and the deformed mesh, `q` is the closest point on the closest triangle
//! (barycentric `b_i` on vertices `X_i`), and the residual is the signed distance
//! `r = s |p - q|`, `s = sign(n . (p - q))` with `n` the triangle's outward normal. By the
//! envelope theorem `dr/dX_i = -b_i m` with `m = (p - q) / r` (the normal `n` where the
//! projection falls inside the triangle), and each vertex is linear in the displacements of
//! the grid nodes that move it (`X_v = x_v + sum w_i u_i`,
//! [`cutfem::surface::Embedding`]), which are degrees of freedom. No diffusion is needed.
//!
//! Compared with the thesis' level-set cost ([`crate::cost::PointCloudCost`], eq. 5.4.4-5.4.5),
//! whose zero set is the trilinear interpolant of `phi` in each deformed cell, this residual is
//! zero on exactly the surface that is shown and observed, so noise-free observations of a
//! simulation are fitted to zero residual (the level-set cost keeps an `O(h^2)` floor from the
//! difference of the two surfaces, about 0.8% of a cell on the swinging torus).
//! Triangles are found through a uniform grid of their bounding boxes (cells about one
//! triangle wide, [`bins`]), searching around the point up to the reach (`2h` by default); a
//! point farther than that from every triangle gets the constant cost `rho(reach)` and no
//! gradient.
//!
//! A point whose camera is known is measured along its viewing ray (depth noise lies along
//! it): `r = s_obs - t` with `t` the ray's first hit, `dr/dX_i = -b_i n / (n . d)`. Where that
//! hit is not on the part of the surface closest to the point ([`same_surface`]: the ray
//! passed the silhouette and met the far side) or the ray grazes ([`GRAZING`]), the
//! closest-point residual stands in.

use crate::cost::{frame_points, Cost, FrameCost, GaussNewtonColumns, ObservedPoint, Robust};
use crate::Error;
use bins::FaceBins;
use cutfem::fem::grid::INACTIVE;
use cutfem::fem::Grid;
use cutfem::surface::Surface;
use gpumat::{Matrix, Vec3};
use rayon::prelude::*;
use std::sync::Mutex;

mod bins;

/// Where a point's residual comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshHit {
    /// triangle index
    pub face: usize,
    /// barycentric coordinates of the closest point
    pub bary: [f64; 3],
    /// signed distance (positive outside)
    pub residual: f64,
    /// `dr/dq` direction: `(p - q) / r` (the face normal when `r` is zero); for a ray
    /// residual `n / (n . d)`
    pub direction: Vec3<f64>,
}

/// The surface-distance cost; see the module docs.
#[derive(Debug)]
pub struct SurfaceCost {
    surface: Surface,
    /// per vertex: the dofs of the nodes that move it and their weights
    vertex_dofs: Vec<VertexDofs>,
    h: f64,
    frames: Vec<(usize, Vec<ObservedPoint>)>,
    /// the loss
    pub robust: Robust,
    /// residual charged to a point far from every triangle
    pub outside_residual: f64,
    /// the last located hits of each frame, with the displacement and reach they were located
    /// for ([`SurfaceCost::residuals`])
    located: Mutex<Vec<Located>>,
    /// the most bytes of located hits kept (default [`LOCATED_BYTES`])
    pub located_budget: usize,
}

/// The hits of one frame for one displacement: a Gauss-Newton matrix asks for the frames of
/// the forward run whose cost was just taken, at the same displacement to the bit (the tangent
/// pass replays the stored run), and gets them without a second search.
#[derive(Debug)]
struct Located {
    frame: usize,
    reach: f64,
    u: Vec<Vec3<f64>>,
    hits: Vec<Option<MeshHit>>,
}

impl Located {
    /// Heap bytes held.
    fn bytes(&self) -> usize {
        self.u.len() * std::mem::size_of::<Vec3<f64>>()
            + self.hits.len() * std::mem::size_of::<Option<MeshHit>>()
    }
}

/// The most bytes of located hits a surface cost keeps ([`SurfaceCost::residuals`]): 64 MB,
/// the frames of a typical fit (a 30-step torus keeps about 1 MB per frame), not those of a
/// 300-step dragon gradient, whose stored trajectory is the memory that must stay.
pub const LOCATED_BYTES: usize = 64 << 20;

/// The degrees of freedom that move one surface vertex, `u = sum w_i u_i` (unused entries:
/// [`INACTIVE`], weight 0).
#[derive(Clone, Copy, Debug)]
struct VertexDofs {
    dofs: [u32; 8],
    weights: [f64; 8],
}

impl VertexDofs {
    /// `sum w_i u_i` of the dof vector `u`.
    fn apply(&self, u: &[Vec3<f64>]) -> Vec3<f64> {
        self.moved(Vec3::default(), u)
    }

    /// `x + sum w_i u_i`, summed in that order.
    fn moved(&self, x: Vec3<f64>, u: &[Vec3<f64>]) -> Vec3<f64> {
        let mut s = x;
        for (&d, &w) in self.dofs.iter().zip(&self.weights) {
            if d != INACTIVE {
                s = s + node_u(u, d) * w;
            }
        }
        s
    }
}

/// The closest point of triangle `(a, b, c)` to `p`, as barycentric coordinates (Ericson,
/// Real-Time Collision Detection, 5.1.5).
pub fn closest_on_triangle(p: Vec3<f64>, a: Vec3<f64>, b: Vec3<f64>, c: Vec3<f64>) -> [f64; 3] {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    [1.0 - v - w, v, w]
}

/// The displacement of dof `d` (zero for a node without one).
fn node_u(u: &[Vec3<f64>], d: u32) -> Vec3<f64> {
    if d == INACTIVE {
        Vec3::default()
    } else {
        u[d as usize]
    }
}

/// Rays meeting a triangle at `|n . d|` below this use the closest-point residual instead.
pub const GRAZING: f64 = 0.1;

/// Whether a ray residual `r` belongs to the part of the surface closest to the point (at
/// distance `closest`; grid cell `h`): a ray that meets the closest part at `|n . d| >=`
/// [`GRAZING`] gives `|r| <= closest / GRAZING`. A larger one hit another part of the
/// surface behind it: near a silhouette the ray to an observed point can pass the surface it
/// was seen on and meet the far side, and a displacement of `1e-5` of the body then moved one
/// point's residual from `4e-4` to `0.058` (a held bunny seen by 4 cameras): the cost jumped.
/// Such a point takes the closest-point residual, continuous across the silhouette. The
/// `1e-9 h` absorbs rounding of points on the surface.
pub fn same_surface(r: f64, closest: f64, h: f64) -> bool {
    r.abs() <= closest / GRAZING + 1e-9 * h
}

/// The intersection of the ray `o + t d` with triangle `(a, b, c)` (Moller-Trumbore): `(t,
/// barycentric)` with `t > 0`, or `None`.
pub fn ray_triangle(
    o: Vec3<f64>,
    d: Vec3<f64>,
    a: Vec3<f64>,
    b: Vec3<f64>,
    c: Vec3<f64>,
) -> Option<(f64, [f64; 3])> {
    let (e1, e2) = (b - a, c - a);
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let tv = o - a;
    let u = tv.dot(pv) * inv;
    let eps = 1e-12;
    if !(-eps..=1.0 + eps).contains(&u) {
        return None;
    }
    let qv = tv.cross(e1);
    let v = d.dot(qv) * inv;
    if v < -eps || u + v > 1.0 + eps {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t > 0.0).then_some((t, [1.0 - u - v, u, v]))
}

impl SurfaceCost {
    /// The cost of the observed `frames` against the marching-cubes surface of `grid`'s SDF.
    pub fn new(grid: &Grid, frames: Vec<(usize, Vec<ObservedPoint>)>, robust: Robust) -> Result<Self, Error> {
        if grid.dofs() == 0 {
            return Err(Error::invalid("surface cost: the body has no degrees of freedom"));
        }
        let surface = grid.surface()?;
        // a node without a degree of freedom (an edge touching the surface only within the
        // snapping tolerance) does not move, as in `softbody simulate`
        let vertex_dofs = surface
            .vertex_nodes
            .iter()
            .map(|e| {
                let mut d = VertexDofs {
                    dofs: [INACTIVE; 8],
                    weights: [0.0; 8],
                };
                for (i, (n, w)) in e.terms().enumerate() {
                    d.dofs[i] = grid.node_dofs[n];
                    d.weights[i] = w;
                }
                d
            })
            .collect();
        let h = grid.h();
        Ok(Self {
            surface,
            vertex_dofs,
            h,
            frames,
            robust,
            outside_residual: 2.0 * h,
            located: Mutex::new(Vec::new()),
            located_budget: LOCATED_BYTES,
        })
    }

    /// The observed points of `frame`.
    pub fn points(&self, frame: usize) -> &[ObservedPoint] {
        frame_points(&self.frames, frame)
    }

    /// Points farther than `reach` from every triangle are charged `reach` (constant, no
    /// gradient); the default is two cells. A diagnosis uses a larger reach, so that a model
    /// that is far off still sees where the points are.
    pub fn with_reach(mut self, reach: f64) -> Self {
        self.outside_residual = reach.max(self.outside_residual);
        self
    }

    /// The reference surface (marching cubes on the body's SDF).
    pub fn surface(&self) -> &Surface {
        &self.surface
    }

    /// The deformed vertex positions for the dof displacement `u`.
    pub fn vertices(&self, u: &Matrix<Vec3<f64>>) -> Vec<Vec3<f64>> {
        let us = u.as_slice();
        self.surface
            .mesh
            .vertices
            .iter()
            .zip(&self.vertex_dofs)
            .map(|(x, d)| d.moved(Vec3::from_array(*x), us))
            .collect()
    }

    /// The closest triangle of each point of `frame` for deformed vertices `x`.
    pub fn locate(&self, frame: usize, x: &[Vec3<f64>]) -> Vec<Option<MeshHit>> {
        let points = self.points(frame);
        if points.is_empty() {
            return Vec::new();
        }
        // block bins of half the reach: the 5x5x5 block a ray's hit must lie in covers it
        let faces = &self.surface.mesh.faces;
        let bins = FaceBins::new(faces, x, self.h.max(0.5 * self.outside_residual));
        let reach = self.outside_residual;
        points
            .par_iter()
            .map(|pt| {
                let p = pt.position;
                let best = bins.closest(p, reach, |fi| {
                    let [a, b, cc] = faces[fi as usize].map(|v| x[v as usize]);
                    let bary = closest_on_triangle(p, a, b, cc);
                    let q = a * bary[0] + b * bary[1] + cc * bary[2];
                    ((p - q).dot(p - q), bary)
                });
                // along the viewing ray: the first hit among the triangles near the point,
                // unless it lies on another part of the surface than the closest one (a ray
                // that passes the silhouette)
                if let Some(eye) = pt.eye {
                    if let Some(hit) = self.ray_hit(&bins, x, eye, p) {
                        let closest = best.map_or(f64::INFINITY, |b| b.0.sqrt());
                        if same_surface(hit.residual, closest, self.h) {
                            return Some(hit);
                        }
                    }
                }
                let (d2, face, bary) = best?;
                if d2.sqrt() > reach {
                    return None;
                }
                let [a, b, cc] = faces[face].map(|v| x[v as usize]);
                let q = a * bary[0] + b * bary[1] + cc * bary[2];
                let n = (b - a).cross(cc - a);
                let n = n * (1.0 / n.norm().max(f64::MIN_POSITIVE));
                let d = (p - q).norm();
                let (residual, direction) = if d > 1e-14 * self.h {
                    let s = if n.dot(p - q) >= 0.0 { 1.0 } else { -1.0 };
                    (s * d, (p - q) * (1.0 / (s * d)))
                } else {
                    (0.0, n)
                };
                Some(MeshHit {
                    face,
                    bary,
                    residual,
                    direction,
                })
            })
            .collect()
    }

    /// The ray residual of a point `p` seen from `eye` (module docs): the first intersection
    /// of the ray with the triangles in the bins around `p`, if it is not grazing.
    fn ray_hit(&self, bins: &FaceBins, x: &[Vec3<f64>], eye: Vec3<f64>, p: Vec3<f64>) -> Option<MeshHit> {
        let faces = &self.surface.mesh.faces;
        let s_obs = (p - eye).norm();
        if s_obs <= 0.0 {
            return None;
        }
        let d = (p - eye) * (1.0 / s_obs);
        let best = bins.first_hit(p, eye, d, |fi| {
            let [a, b, cc] = faces[fi as usize].map(|v| x[v as usize]);
            ray_triangle(eye, d, a, b, cc)
        });
        let (t, face, bary) = best?;
        let [a, b, cc] = faces[face].map(|v| x[v as usize]);
        let n = (b - a).cross(cc - a);
        let n = n * (1.0 / n.norm().max(f64::MIN_POSITIVE));
        let nd = n.dot(d);
        if nd.abs() < GRAZING || (t - s_obs).abs() > self.outside_residual {
            return None;
        }
        // r = s_obs - t;  dt/dX_i = b_i n / (n . d)  =>  dr/dX_i = -b_i n / (n . d)
        Some(MeshHit {
            face,
            bary,
            residual: s_obs - t,
            direction: n * (1.0 / nd),
        })
    }

    /// Residuals of `frame` (outside points: `None`). The last hits of each frame are kept
    /// with their displacement: asked again for the same `u` (equal to the bit) and reach, the
    /// frame is not searched again. The kept hits are bounded ([`LOCATED_BYTES`]): a frame
    /// beyond the budget is not kept (the frames kept first stay), so a long run's memory
    /// grows by its stored trajectory only.
    pub fn residuals(&self, frame: usize, u: &Matrix<Vec3<f64>>) -> Vec<Option<MeshHit>> {
        let (us, reach) = (u.as_slice(), self.outside_residual);
        let bits = |v: &Vec3<f64>| v.to_array().map(f64::to_bits);
        let same = |l: &Located| {
            l.frame == frame
                && l.reach.to_bits() == reach.to_bits()
                && l.u.len() == us.len()
                && l.u.iter().zip(us).all(|(a, b)| bits(a) == bits(b))
        };
        if let Some(l) = self.cache().iter().find(|l| same(l)) {
            return l.hits.clone();
        }
        let hits = self.locate(frame, &self.vertices(u));
        let entry = Located {
            frame,
            reach,
            u: us.to_vec(),
            hits: hits.clone(),
        };
        let mut cache = self.cache();
        match cache.iter_mut().find(|l| l.frame == frame) {
            Some(l) => *l = entry,
            None => {
                if cache.iter().map(Located::bytes).sum::<usize>() + entry.bytes() <= self.located_budget {
                    cache.push(entry);
                }
            }
        }
        hits
    }

    /// Bytes of located hits kept now.
    pub fn kept_bytes(&self) -> usize {
        self.cache().iter().map(Located::bytes).sum()
    }

    /// The located hits (a poisoned lock only means another thread panicked mid-update of a
    /// cache: start it afresh).
    fn cache(&self) -> std::sync::MutexGuard<'_, Vec<Located>> {
        self.located.lock().unwrap_or_else(|p| {
            let mut g = p.into_inner();
            g.clear();
            g
        })
    }

    /// Adds `s * dr/du` for one hit to `g`.
    fn scatter(&self, hit: &MeshHit, s: f64, g: &mut [Vec3<f64>]) {
        let f = self.surface.mesh.faces[hit.face];
        for (k, &v) in f.iter().enumerate() {
            let vd = &self.vertex_dofs[v as usize];
            let dv = hit.direction * (-s * hit.bary[k]);
            for (&d, &w) in vd.dofs.iter().zip(&vd.weights) {
                if d != INACTIVE {
                    g[d as usize] = g[d as usize] + dv * w;
                }
            }
        }
    }

    /// `dr/du . du` for one hit.
    fn directional(&self, hit: &MeshHit, du: &[Vec3<f64>]) -> f64 {
        let f = self.surface.mesh.faces[hit.face];
        let mut s = 0.0;
        for (k, &v) in f.iter().enumerate() {
            let dx = self.vertex_dofs[v as usize].apply(du);
            s -= hit.bary[k] * hit.direction.dot(dx);
        }
        s
    }
}

impl Cost for SurfaceCost {
    fn frames(&self) -> Vec<usize> {
        self.frames.iter().map(|f| f.0).collect()
    }

    fn frame_cost(
        &self,
        frame: usize,
        u: &Matrix<Vec3<f64>>,
        grad: Option<&mut Matrix<Vec3<f64>>>,
    ) -> Result<FrameCost, Error> {
        let points = self.points(frame);
        let hits = self.residuals(frame, u);
        let residuals = hits.iter().map(|h| h.map(|h| h.residual));
        let fc = FrameCost::of_residuals(frame, points, residuals, self.robust, self.outside_residual);
        if let Some(g) = grad {
            let gs = g.as_mut_slice();
            for (pt, hit) in points.iter().zip(&hits) {
                if let Some(hit) = hit {
                    self.scatter(hit, pt.weight * self.robust.derivative(hit.residual), gs);
                }
            }
        }
        Ok(fc)
    }

    fn frame_gauss_newton(
        &self,
        frame: usize,
        u: &Matrix<Vec3<f64>>,
        du: &[Matrix<Vec3<f64>>],
    ) -> Result<Vec<f64>, Error> {
        let points = self.points(frame);
        let hits = self.residuals(frame, u);
        let mut gn = GaussNewtonColumns::new(du.len(), points.len());
        for (pt, hit) in points.iter().zip(&hits) {
            let Some(hit) = hit else { continue };
            gn.push(pt.weight * self.robust.irls_weight(hit.residual), |d| {
                self.directional(hit, du[d].as_slice())
            });
        }
        Ok(gn.matrix())
    }
}
