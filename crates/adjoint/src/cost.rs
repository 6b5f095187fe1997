//! Cost functions (thesis sec. 5.4) and their gradients with respect to the displacements.
//!
//! * [`DisplacementCost`]: `J = sum_t w_t/2 ||u(t) - u_ref(t)||^2` (eq. 5.4.1).
//! * [`PointCloudCost`]: `J = sum_t sum_i w_ti rho(phi(t)(x_ti))` (eq. 5.4.4) for points `x_ti`
//!   observed on the surface, `rho(r) = r^2/2` or the Huber function. `phi(t)(x)` is evaluated
//!   without advection (eq. 5.4.5, Alg. 5.2): find the cell whose *deformed* corners
//!   `X_k = x_k + u_k` contain `x` by solving the trilinear map
//!   `X(a) = sum_k N_k(a) X_k = x` for `a in [0,1]^3` with Newton's method from `a = (1/2,1/2,1/2)`,
//!   then interpolate the reference SDF with the same weights: `phi = sum_k N_k(a) phi_k`.
//!   The displacements of empty nodes come from the diffusion band (sec. 4.4.5).
//!   The adjoint (the thesis' matrix view): with `J_a = dX/da` and `g_a = sum_k phi_k dN_k/da`,
//!   `dphi/du_k = -N_k(a) J_a^{-T} g_a`; the gradient on the band's slots is mapped back to the
//!   active nodes by the adjoint of the diffusion (sec. 5.5.2).
//!   Cells are found through a uniform spatial hash of the deformed cells' bounding boxes (bins
//!   of one cell size), restricted to the cells within two cells of the reference surface.
//!   A point outside every such cell gets the constant (bounded, smooth) cost
//!   `rho(outside_residual)` and no gradient; it is counted in [`FrameCost::outside`].

use crate::Error;
use cutfem::fem::advect::Diffusion;
use cutfem::fem::Grid;
use gpumat::{Mat3, Matrix, Vec3};
use rayon::prelude::*;
use std::collections::HashMap;

/// The loss applied to each residual.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Robust {
    /// `r^2 / 2`
    Squared,
    /// Huber with threshold `delta`: `r^2/2` for `|r| <= delta`, else `delta (|r| - delta/2)`
    Huber(f64),
}

impl Robust {
    /// `rho(r)`.
    pub fn value(self, r: f64) -> f64 {
        match self {
            Robust::Squared => 0.5 * r * r,
            Robust::Huber(d) if r.abs() <= d => 0.5 * r * r,
            Robust::Huber(d) => d * (r.abs() - 0.5 * d),
        }
    }
    /// `rho'(r)`.
    pub fn derivative(self, r: f64) -> f64 {
        match self {
            Robust::Squared => r,
            Robust::Huber(d) => r.clamp(-d, d),
        }
    }
    /// The IRLS weight `rho'(r) / r` (1 at `r = 0`) of the Gauss-Newton matrix.
    pub fn irls_weight(self, r: f64) -> f64 {
        if r == 0.0 {
            1.0
        } else {
            self.derivative(r) / r
        }
    }
}

/// What one frame's cost was.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameCost {
    /// the frame
    pub frame: usize,
    /// its cost
    pub cost: f64,
    /// sum of squared residuals (distances), outside points counted with the outside residual
    pub sum_squared: f64,
    /// number of points (or residual entries)
    pub count: usize,
    /// points outside every deformed cell
    pub outside: usize,
    /// `r^T W r` over the points that enter the Gauss-Newton matrix (within reach, positive
    /// weight), with the same weights `W` as that matrix: the point's weight times the loss'
    /// IRLS weight ([`crate::fit::uncertainty`])
    pub weighted_squared: f64,
    /// the number of those points (residual entries)
    pub informative: usize,
}

impl FrameCost {
    /// The totals of `frame` for its points and their residuals (`None`: outside every cell or
    /// triangle, charged `outside_residual`).
    pub fn of_residuals(
        frame: usize,
        points: &[ObservedPoint],
        residuals: impl Iterator<Item = Option<f64>>,
        robust: Robust,
        outside_residual: f64,
    ) -> Self {
        let mut fc = FrameCost {
            frame,
            count: points.len(),
            ..Default::default()
        };
        for (pt, r) in points.iter().zip(residuals) {
            fc.outside += usize::from(r.is_none());
            if let Some(r) = r.filter(|_| pt.weight > 0.0) {
                fc.weighted_squared += pt.weight * robust.irls_weight(r) * r * r;
                fc.informative += 1;
            }
            let r = r.unwrap_or(outside_residual);
            fc.cost += pt.weight * robust.value(r);
            fc.sum_squared += r * r;
        }
        fc
    }

    /// Root mean square residual of the frame.
    pub fn rms(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            (self.sum_squared / self.count as f64).sqrt()
        }
    }
}

/// A cost that is a sum over frames of a function of the frame's displacement.
pub trait Cost: Send + Sync + std::fmt::Debug {
    /// The frames that carry a cost, increasing.
    fn frames(&self) -> Vec<usize>;
    /// The cost of `frame` for the active nodes' displacement `u`; with `grad`, adds `dJ/du`.
    fn frame_cost(
        &self,
        frame: usize,
        u: &Matrix<Vec3<f64>>,
        grad: Option<&mut Matrix<Vec3<f64>>>,
    ) -> Result<FrameCost, Error>;

    /// The Gauss-Newton matrix contribution `J^T W J` of `frame` (`n x n`, row-major) for the
    /// displacement sensitivities `du[k] = du/dx_k` (tangent-linear), with `W` the IRLS
    /// weights of the loss (`rho'(r)/r`).
    fn frame_gauss_newton(
        &self,
        frame: usize,
        u: &Matrix<Vec3<f64>>,
        du: &[Matrix<Vec3<f64>>],
    ) -> Result<Vec<f64>, Error>;
}

/// The Gauss-Newton matrix `J^T W J` of one frame, gathered point by point: every cost pushes,
/// for each point it uses, the weight `w_i` (point weight times the loss' IRLS weight) and the
/// residual's derivatives `J_ik` along the directions `k`.
pub(crate) struct GaussNewtonColumns {
    /// `cols[k][i] = J_ik`
    cols: Vec<Vec<f64>>,
    w: Vec<f64>,
}

impl GaussNewtonColumns {
    /// An empty gathering for `directions` directions and up to `points` points.
    pub(crate) fn new(directions: usize, points: usize) -> Self {
        GaussNewtonColumns {
            cols: vec![Vec::with_capacity(points); directions],
            w: Vec::with_capacity(points),
        }
    }

    /// A point of weight `w` whose residual has the derivative `derivative(k)` along `k`.
    pub(crate) fn push(&mut self, w: f64, derivative: impl Fn(usize) -> f64) {
        self.w.push(w);
        for (k, col) in self.cols.iter_mut().enumerate() {
            col.push(derivative(k));
        }
    }

    /// `J^T W J` (`n x n`, row-major).
    pub(crate) fn matrix(&self) -> Vec<f64> {
        let n = self.cols.len();
        let mut h = vec![0.0; n * n];
        for a in 0..n {
            for b in 0..=a {
                let s: f64 = self.cols[a]
                    .iter()
                    .zip(&self.cols[b])
                    .zip(&self.w)
                    .map(|((x, y), w)| w * x * y)
                    .sum();
                h[a * n + b] = s;
                h[b * n + a] = s;
            }
        }
        h
    }
}

/// `sum_t w_t/2 ||u(t) - u_ref(t)||^2` (eq. 5.4.1) over the given reference frames.
#[derive(Clone, Debug)]
pub struct DisplacementCost {
    /// `(frame, weight, reference displacement)`
    pub reference: Vec<(usize, f64, Matrix<Vec3<f64>>)>,
}

impl Cost for DisplacementCost {
    fn frames(&self) -> Vec<usize> {
        self.reference.iter().map(|r| r.0).collect()
    }
    fn frame_cost(
        &self,
        frame: usize,
        u: &Matrix<Vec3<f64>>,
        grad: Option<&mut Matrix<Vec3<f64>>>,
    ) -> Result<FrameCost, Error> {
        let Some((_, w, r)) = self.reference.iter().find(|r| r.0 == frame) else {
            return Ok(FrameCost {
                frame,
                ..Default::default()
            });
        };
        let d = Matrix::eval(u - r);
        let ss: f64 = d.ex().cwise_squared_norm().sum();
        if let Some(g) = grad {
            g.assign_with(|g| g + d.ex() * *w);
        }
        Ok(FrameCost {
            frame,
            cost: 0.5 * w * ss,
            sum_squared: ss,
            count: u.rows(),
            outside: 0,
            weighted_squared: w * ss,
            informative: if *w > 0.0 { 3 * u.rows() } else { 0 },
        })
    }

    fn frame_gauss_newton(
        &self,
        frame: usize,
        _u: &Matrix<Vec3<f64>>,
        du: &[Matrix<Vec3<f64>>],
    ) -> Result<Vec<f64>, Error> {
        let n = du.len();
        let Some((_, w, _)) = self.reference.iter().find(|r| r.0 == frame) else {
            return Ok(vec![0.0; n * n]);
        };
        let mut h = vec![0.0; n * n];
        for a in 0..n {
            for b in 0..=a {
                let s = w * du[a].ex().dot(du[b].ex());
                h[a * n + b] = s;
                h[b * n + a] = s;
            }
        }
        Ok(h)
    }
}

/// One observed point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObservedPoint {
    /// world position
    pub position: Vec3<f64>,
    /// weight
    pub weight: f64,
    /// the eye of the camera that saw it, when known: the residual is then measured along the
    /// viewing ray ([`crate::cost_mesh`])
    pub eye: Option<Vec3<f64>>,
}

/// The points of `frame` in a per-frame list (none when the frame is not observed).
pub fn frame_points(frames: &[(usize, Vec<ObservedPoint>)], frame: usize) -> &[ObservedPoint] {
    frames
        .iter()
        .find(|f| f.0 == frame)
        .map_or(&[], |f| f.1.as_slice())
}

/// A candidate cell of the point-cloud cost: its corners' band slots, reference positions and
/// reference SDF values.
#[derive(Clone, Copy, Debug)]
struct ObsCell {
    slots: [u32; 8],
    corner0: Vec3<f64>,
    phi: [f64; 8],
}

/// Where a point landed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointHit {
    /// index of the candidate cell
    pub cell: usize,
    /// trilinear coordinates in the cell
    pub alpha: [f64; 3],
    /// `phi(t)(x)`: the signed distance of the point to the simulated surface (approximately)
    pub residual: f64,
}

/// The sparse point-cloud cost (eq. 5.4.4, Alg. 5.2); see the module docs.
#[derive(Debug)]
pub struct PointCloudCost {
    band: Diffusion,
    cells: Vec<ObsCell>,
    h: f64,
    origin: Vec3<f64>,
    frames: Vec<(usize, Vec<ObservedPoint>)>,
    /// the loss
    pub robust: Robust,
    /// the residual charged to a point outside every cell
    pub outside_residual: f64,
}

/// Trilinear weights `N_k(a)` and their derivatives `dN_k/da`.
fn trilinear(a: [f64; 3]) -> ([f64; 8], [[f64; 3]; 8]) {
    let mut n = [0.0; 8];
    let mut dn = [[0.0; 3]; 8];
    for k in 0..8 {
        let f: [f64; 3] = std::array::from_fn(|d| if (k >> d) & 1 == 1 { a[d] } else { 1.0 - a[d] });
        let s: [f64; 3] = std::array::from_fn(|d| if (k >> d) & 1 == 1 { 1.0 } else { -1.0 });
        n[k] = f[0] * f[1] * f[2];
        dn[k] = [s[0] * f[1] * f[2], f[0] * s[1] * f[2], f[0] * f[1] * s[2]];
    }
    (n, dn)
}

/// `J_a = dX/da = sum_k X_k (dN_k/da)^T` of the trilinear map.
fn trilinear_jacobian(x: &[Vec3<f64>; 8], dn: &[[f64; 3]; 8]) -> Mat3<f64> {
    let mut cols = [Vec3::default(); 3];
    for k in 0..8 {
        for (d, c) in cols.iter_mut().enumerate() {
            *c = *c + x[k] * dn[k][d];
        }
    }
    Mat3::from_cols(cols[0], cols[1], cols[2])
}

/// Solves `sum_k N_k(a) X_k = p` by Newton from the cell center; `Some(a)` when it converges
/// to a point inside the closed cell.
fn invert_trilinear(x: &[Vec3<f64>; 8], p: Vec3<f64>, h: f64) -> Option<[f64; 3]> {
    let mut a = [0.5; 3];
    for _ in 0..30 {
        let (n, dn) = trilinear(a);
        let pos = (0..8).fold(Vec3::default(), |s, k| s + x[k] * n[k]);
        let r = pos - p;
        let inv = trilinear_jacobian(x, &dn).inverse()?;
        let step = (inv * r).to_array();
        for d in 0..3 {
            a[d] -= step[d];
        }
        if a.iter().any(|v| !v.is_finite() || v.abs() > 10.0) {
            return None;
        }
        if r.norm() < 1e-12 * h && step.iter().all(|s| s.abs() < 1e-12) {
            break;
        }
    }
    let tol = 1e-9;
    a.iter().all(|&v| v >= -tol && v <= 1.0 + tol).then_some(a)
}

impl PointCloudCost {
    /// The cost of the observed `frames` (`(frame, points)`) on `grid`, with the diffusion
    /// band `band` (built on the same grid).
    pub fn new(
        grid: &Grid,
        band: Diffusion,
        frames: Vec<(usize, Vec<ObservedPoint>)>,
        robust: Robust,
    ) -> Self {
        let sdf = &grid.sdf;
        let h = sdf.spacing;
        let [nx, ny, nz] = sdf.dims;
        let reach = 2.0 * h;
        let mut cells = Vec::new();
        for k in 0..nz - 1 {
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let node = |c: usize| (i + (c & 1)) + nx * ((j + ((c >> 1) & 1)) + ny * (k + (c >> 2)));
                    let phi: [f64; 8] = std::array::from_fn(|c| sdf.values[node(c)]);
                    let lo = phi.iter().copied().fold(f64::INFINITY, f64::min);
                    let hi = phi.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    if lo > reach || hi < -reach {
                        continue;
                    }
                    let slots: Option<Vec<u32>> =
                        (0..8).map(|c| band.slot(node(c)).map(|s| s as u32)).collect();
                    let Some(slots) = slots else { continue };
                    let o = sdf.origin;
                    cells.push(ObsCell {
                        slots: slots.try_into().expect("8 corners"),
                        corner0: Vec3::new(o[0] + i as f64 * h, o[1] + j as f64 * h, o[2] + k as f64 * h),
                        phi,
                    });
                }
            }
        }
        let o = sdf.origin;
        Self {
            band,
            cells,
            h,
            origin: Vec3::new(o[0], o[1], o[2]),
            frames,
            robust,
            outside_residual: reach,
        }
    }

    /// Number of candidate cells.
    pub fn candidate_cells(&self) -> usize {
        self.cells.len()
    }

    /// The observed points of `frame`.
    pub fn points(&self, frame: usize) -> &[ObservedPoint] {
        frame_points(&self.frames, frame)
    }

    /// The diffusion band.
    pub fn band(&self) -> &Diffusion {
        &self.band
    }

    fn corners(&self, c: &ObsCell, u: &[Vec3<f64>]) -> [Vec3<f64>; 8] {
        std::array::from_fn(|k| {
            let off = Vec3::new((k & 1) as f64, ((k >> 1) & 1) as f64, (k >> 2) as f64) * self.h;
            c.corner0 + off + u[c.slots[k] as usize]
        })
    }

    /// Locates each point of `frame` for the band displacement `u_slots` (one per slot).
    pub fn locate(&self, frame: usize, u_slots: &[Vec3<f64>]) -> Vec<Option<PointHit>> {
        let points = self.points(frame);
        if points.is_empty() {
            return Vec::new();
        }
        let inv_h = 1.0 / self.h;
        let bin = |p: Vec3<f64>| -> [i64; 3] {
            let q = ((p - self.origin) * inv_h).to_array();
            q.map(|v| v.floor() as i64)
        };
        // spatial hash of the deformed cells' bounding boxes
        let boxes: Vec<([i64; 3], [i64; 3])> = self
            .cells
            .par_iter()
            .map(|c| {
                let x = self.corners(c, u_slots);
                let mut lo = x[0];
                let mut hi = x[0];
                for p in &x[1..] {
                    let (a, b, q) = (lo.to_array(), hi.to_array(), p.to_array());
                    lo = Vec3::new(a[0].min(q[0]), a[1].min(q[1]), a[2].min(q[2]));
                    hi = Vec3::new(b[0].max(q[0]), b[1].max(q[1]), b[2].max(q[2]));
                }
                (bin(lo), bin(hi))
            })
            .collect();
        let mut hash: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (ci, (lo, hi)) in boxes.iter().enumerate() {
            if (0..3).any(|d| hi[d] - lo[d] > 8) {
                continue; // a degenerate (exploded) cell: skip rather than flood the hash
            }
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        hash.entry([x, y, z]).or_default().push(ci as u32);
                    }
                }
            }
        }
        points
            .par_iter()
            .map(|pt| {
                let cands = hash.get(&bin(pt.position))?;
                cands.iter().find_map(|&ci| {
                    let c = &self.cells[ci as usize];
                    let x = self.corners(c, u_slots);
                    let a = invert_trilinear(&x, pt.position, self.h)?;
                    let (n, _) = trilinear(a);
                    let residual = (0..8).map(|k| n[k] * c.phi[k]).sum();
                    Some(PointHit {
                        cell: ci as usize,
                        alpha: a,
                        residual,
                    })
                })
            })
            .collect()
    }

    /// The residual's linearization at a hit: `dr/du_k = -N_k(a) q` for the 8 corners, with
    /// `q = J_a^{-T} g_a` (module docs); `None` for a singular deformed cell.
    fn linearization(&self, hit: &PointHit, u_slots: &[Vec3<f64>]) -> Option<([f64; 8], Vec3<f64>)> {
        let c = &self.cells[hit.cell];
        let x = self.corners(c, u_slots);
        let (n, dn) = trilinear(hit.alpha);
        let ga = (0..8).fold(Vec3::default(), |s, k| {
            s + Vec3::new(dn[k][0], dn[k][1], dn[k][2]) * c.phi[k]
        });
        let jinv = trilinear_jacobian(&x, &dn).inverse()?;
        Some((n, jinv.transpose() * ga))
    }

    /// The cost of `frame` for band displacements `u_slots`; with `grad_slots`, adds the
    /// gradient per slot.
    pub fn frame_cost_slots(
        &self,
        frame: usize,
        u_slots: &[Vec3<f64>],
        grad_slots: Option<&mut [Vec3<f64>]>,
    ) -> (FrameCost, Vec<Option<PointHit>>) {
        let points = self.points(frame);
        let hits = self.locate(frame, u_slots);
        let residuals = hits.iter().map(|h| h.map(|h| h.residual));
        let fc = FrameCost::of_residuals(frame, points, residuals, self.robust, self.outside_residual);
        if let Some(g) = grad_slots {
            for (pt, hit) in points.iter().zip(&hits) {
                let Some(hit) = hit else { continue };
                let c = &self.cells[hit.cell];
                let Some((n, q)) = self.linearization(hit, u_slots) else {
                    continue;
                };
                let s = pt.weight * self.robust.derivative(hit.residual);
                for k in 0..8 {
                    let slot = c.slots[k] as usize;
                    g[slot] = g[slot] - q * (s * n[k]);
                }
            }
        }
        (fc, hits)
    }
}

impl Cost for PointCloudCost {
    fn frames(&self) -> Vec<usize> {
        self.frames.iter().map(|f| f.0).collect()
    }
    fn frame_cost(
        &self,
        frame: usize,
        u: &Matrix<Vec3<f64>>,
        grad: Option<&mut Matrix<Vec3<f64>>>,
    ) -> Result<FrameCost, Error> {
        let u_slots = self.band.diffuse(u)?;
        match grad {
            None => Ok(self.frame_cost_slots(frame, &u_slots, None).0),
            Some(g) => {
                let mut gs = vec![Vec3::default(); u_slots.len()];
                let (fc, _) = self.frame_cost_slots(frame, &u_slots, Some(&mut gs));
                let ga = self.band.diffuse_adjoint(&gs)?;
                g.assign_with(|g| g + ga.ex());
                Ok(fc)
            }
        }
    }

    fn frame_gauss_newton(
        &self,
        frame: usize,
        u: &Matrix<Vec3<f64>>,
        du: &[Matrix<Vec3<f64>>],
    ) -> Result<Vec<f64>, Error> {
        let u_slots = self.band.diffuse(u)?;
        let d_slots: Vec<Vec<Vec3<f64>>> = du
            .iter()
            .map(|d| self.band.diffuse(d))
            .collect::<Result<_, _>>()?;
        let points = self.points(frame);
        let hits = self.locate(frame, &u_slots);
        let mut gn = GaussNewtonColumns::new(du.len(), points.len());
        for (pt, hit) in points.iter().zip(&hits) {
            let Some(hit) = hit else { continue };
            let c = &self.cells[hit.cell];
            let Some((n, q)) = self.linearization(hit, &u_slots) else {
                continue;
            };
            gn.push(pt.weight * self.robust.irls_weight(hit.residual), |d| {
                (0..8)
                    .map(|k| -n[k] * q.dot(d_slots[d][c.slots[k] as usize]))
                    .sum()
            });
        }
        Ok(gn.matrix())
    }
}
