//! The diffusion band and its system (thesis sec. 4.4.5, first paragraph; the 2D "explicit
//! diffusion" of sec. 2.5.2.5). See the parent module for the maths.

use crate::error::Error;
use crate::fem::grid::{Grid, INACTIVE};
use gpumat::{cg, Axes, CgInfo, CgParams, Jacobi, Matrix, SparseMatrix, SparsityPattern, Vec3};
use rayon::prelude::*;
use std::collections::VecDeque;
use std::sync::Mutex;

/// The band width of the thesis: empty nodes within this l1 distance (in nodes) of an active
/// node are diffused into (sec. 4.4.5).
pub const DIFFUSION_DISTANCE: usize = 5;

/// How the displacement is extended into the empty nodes (`[numerics] diffusion`:
/// "harmonic" or "linear").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DisplacementExtension {
    /// The thesis: the 7-point Poisson equation `Delta u = 0` (graph Laplacian) with Neumann
    /// conditions at the band's edge. Reproduces constants; bends linear fields towards a
    /// constant in the direction normal to the band.
    #[default]
    Harmonic,
    /// Least squares of the second differences `u(n - e) - 2 u(n) + u(n + e)` along the three
    /// axes (a 13-point system, symmetric positive definite): reproduces linear fields, such
    /// as rotations, exactly. Not in the thesis.
    Linear,
}

/// The warm-start state: the last solution and what the last solve did.
#[derive(Debug, Default)]
struct Warm {
    x: Option<Matrix<f64>>,
    info: Option<CgInfo<f64>>,
}

/// The nodes the displacements are diffused into and the linear system that fills them,
/// built once per [`Grid`].
///
/// The band's *slots* number its nodes: slot `d < dofs` is the active node of degree of
/// freedom `d`, slot `dofs + e` the `e`-th empty node (empty nodes in increasing grid order).
/// [`Diffusion::diffuse`] returns one displacement per slot.
#[derive(Debug)]
pub struct Diffusion {
    /// node counts of the reference grid
    dims: [usize; 3],
    /// number of active nodes (degrees of freedom)
    dofs: usize,
    /// band distance used to build the band
    distance: usize,
    /// the extension
    extension: DisplacementExtension,
    /// grid node of each slot
    nodes: Vec<usize>,
    /// slot of each grid node ([`INACTIVE`] outside the band)
    slots: Vec<u32>,
    /// the system matrix on the empty nodes (one batch)
    matrix: SparseMatrix<f64>,
    /// its Jacobi preconditioner
    jacobi: Option<Jacobi<f64>>,
    /// Dirichlet couplings of empty row `r`: `dirichlet[dirichlet_ptr[r]..dirichlet_ptr[r + 1]]`
    /// are `(dof, coefficient)` of the active nodes in its stencil; `b_r = -sum coef u(dof)`
    dirichlet_ptr: Vec<u32>,
    dirichlet: Vec<(u32, f64)>,
    /// CG parameters of [`Diffusion::diffuse`] (default: relative tolerance `1e-8`, at most
    /// 2000 iterations). The tolerance applies per coordinate relative to its own `||b||`, plus
    /// the same fraction of the largest coordinate's `||b||` as an absolute floor.
    pub params: CgParams<f64>,
    warm: Mutex<Warm>,
}

/// The up to six face neighbours of node `(i, j, k)` inside the grid, in increasing index order.
fn neighbours(n: usize, dims: [usize; 3]) -> impl Iterator<Item = usize> {
    let [nx, ny, nz] = dims;
    let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
    let sxy = nx * ny;
    [
        (k > 0).then(|| n - sxy),
        (j > 0).then(|| n - nx),
        (i > 0).then(|| n - 1),
        (i + 1 < nx).then(|| n + 1),
        (j + 1 < ny).then(|| n + nx),
        (k + 1 < nz).then(|| n + sxy),
    ]
    .into_iter()
    .flatten()
}

/// What the row builders need.
struct RowContext<'a> {
    dims: [usize; 3],
    dofs: usize,
    slots: &'a [u32],
    nodes: &'a [usize],
}

impl RowContext<'_> {
    /// Slot of the node `n + delta * e_axis`, if inside the grid and the band.
    fn step(&self, n: usize, axis: usize, delta: i64) -> Option<usize> {
        let [nx, ny, nz] = self.dims;
        let c = [n % nx, (n / nx) % ny, n / (nx * ny)];
        let stride = [1, nx, nx * ny][axis];
        let t = c[axis] as i64 + delta;
        if t < 0 || t >= [nx, ny, nz][axis] as i64 {
            return None;
        }
        let m = (n as i64 + delta * stride as i64) as usize;
        let s = self.slots[m];
        (s != INACTIVE).then_some(s as usize)
    }

    /// Sorts by slot and merges duplicates.
    fn merge(mut e: Vec<(u32, f64)>) -> Vec<(u32, f64)> {
        e.sort_by_key(|x| x.0);
        let mut out: Vec<(u32, f64)> = Vec::with_capacity(e.len());
        for (s, v) in e {
            match out.last_mut() {
                Some(last) if last.0 == s => last.1 += v,
                _ => out.push((s, v)),
            }
        }
        out
    }

    /// `sum_j (u_p - u_j)` over the face neighbours `j` in the band.
    fn harmonic_row(&self, p: usize) -> Vec<(u32, f64)> {
        let n = self.nodes[p];
        let mut e = vec![(p as u32, 0.0)];
        for axis in 0..3 {
            for delta in [-1, 1] {
                if let Some(j) = self.step(n, axis, delta) {
                    e[0].1 += 1.0;
                    e.push((j as u32, -1.0));
                }
            }
        }
        Self::merge(e)
    }

    /// Row `p` of `D^T D`, `D` the second differences `(q - e, q, q + e)` inside the band that
    /// touch an empty node. A node in no such triple (possible only at the band's edge on the
    /// grid border) falls back to its harmonic row, which keeps the matrix symmetric because
    /// its neighbours' rows get the matching edge terms below.
    fn linear_row(&self, p: usize) -> Vec<(u32, f64)> {
        let mut e = Vec::with_capacity(19);
        if !self.add_triples(p, &mut e) {
            return self.harmonic_row(p);
        }
        // Edge terms of neighbouring nodes that fell back to the harmonic row.
        let n = self.nodes[p];
        for axis in 0..3 {
            for delta in [-1, 1] {
                if let Some(j) = self.step(n, axis, delta) {
                    if j >= self.dofs && !self.add_triples(j, &mut Vec::new()) {
                        e.push((p as u32, 1.0));
                        e.push((j as u32, -1.0));
                    }
                }
            }
        }
        Self::merge(e)
    }

    /// Adds the `D^T D` entries of row `p` to `e`; false when `p` is in no triple.
    fn add_triples(&self, p: usize, e: &mut Vec<(u32, f64)>) -> bool {
        const C: [f64; 3] = [1.0, -2.0, 1.0];
        let n = self.nodes[p];
        let mut any = false;
        for axis in 0..3 {
            // p at position `at` (0, 1, 2) of the triple (q - e, q, q + e)
            for at in 0..3i64 {
                let tri: [Option<usize>; 3] = std::array::from_fn(|t| {
                    if t as i64 == at {
                        Some(p)
                    } else {
                        self.step(n, axis, t as i64 - at)
                    }
                });
                let [Some(a), Some(b), Some(c)] = tri else {
                    continue;
                };
                let tri = [a, b, c];
                any = true;
                let cp = C[at as usize];
                for (t, &q) in tri.iter().enumerate() {
                    e.push((q as u32, cp * C[t]));
                }
            }
        }
        any
    }
}

impl Diffusion {
    /// The band and system of the thesis: [`DIFFUSION_DISTANCE`] = 5, [`DisplacementExtension::Harmonic`].
    pub fn new(grid: &Grid) -> Result<Self, Error> {
        Self::with_distance(grid, DIFFUSION_DISTANCE, DisplacementExtension::Harmonic)
    }

    /// The band of empty nodes within l1 distance `distance` (in nodes, measured inside the
    /// grid) of an active node, and its system. `distance = 0` gives an empty band (the
    /// active nodes only).
    pub fn with_distance(
        grid: &Grid,
        distance: usize,
        extension: DisplacementExtension,
    ) -> Result<Self, Error> {
        let dims = grid.sdf.dims;
        let total = grid.sdf.node_count();
        if grid.node_dofs.len() != total {
            return Err(Error::Invalid(
                "diffusion: the grid's node map does not match its SDF".into(),
            ));
        }
        let dofs = grid.dofs();
        // Multi-source BFS from the active nodes over face neighbours: l1 distance on the grid.
        let limit = u8::try_from(distance.min(254)).unwrap_or(254);
        let mut dist = vec![u8::MAX; total];
        let mut queue = VecDeque::with_capacity(dofs);
        for &n in &grid.dof_nodes {
            dist[n] = 0;
            queue.push_back(n);
        }
        while let Some(n) = queue.pop_front() {
            let d = dist[n];
            if d >= limit {
                continue;
            }
            for m in neighbours(n, dims) {
                if dist[m] == u8::MAX {
                    dist[m] = d + 1;
                    queue.push_back(m);
                }
            }
        }
        let mut nodes = grid.dof_nodes.clone();
        let mut slots = vec![INACTIVE; total];
        for (d, &n) in grid.dof_nodes.iter().enumerate() {
            slots[n] = d as u32;
        }
        for (n, &d) in dist.iter().enumerate() {
            if d != 0 && d != u8::MAX {
                slots[n] = nodes.len() as u32;
                nodes.push(n);
            }
        }
        if nodes.len() >= INACTIVE as usize {
            return Err(Error::Invalid(
                "diffusion: too many band nodes for 32-bit indices".into(),
            ));
        }
        let m = nodes.len() - dofs;
        // One row per empty node: its entries (slot, coefficient) over the whole band, the
        // diagonal included, from which the Dirichlet part moves to the right-hand side.
        let ctx = RowContext {
            dims,
            dofs,
            slots: &slots,
            nodes: &nodes,
        };
        let rows: Vec<Vec<(u32, f64)>> = (0..m)
            .into_par_iter()
            .with_min_len(256)
            .map(|r| match extension {
                DisplacementExtension::Harmonic => ctx.harmonic_row(dofs + r),
                DisplacementExtension::Linear => ctx.linear_row(dofs + r),
            })
            .collect();
        let mut row_ptr = Vec::with_capacity(m + 1);
        let mut col_idx = Vec::with_capacity(13 * m);
        let mut values = Vec::with_capacity(13 * m);
        let mut dirichlet_ptr = Vec::with_capacity(m + 1);
        let mut dirichlet = Vec::new();
        row_ptr.push(0);
        dirichlet_ptr.push(0u32);
        for row in rows {
            for (s, v) in row {
                let s = s as usize;
                if s < dofs {
                    dirichlet.push((s as u32, v));
                } else {
                    col_idx.push(s - dofs);
                    values.push(v);
                }
            }
            row_ptr.push(col_idx.len());
            dirichlet_ptr.push(dirichlet.len() as u32);
        }
        let pattern = SparsityPattern::new(m, m, row_ptr, col_idx)?;
        let matrix = SparseMatrix::from_values(pattern, 1, values);
        let jacobi = if m > 0 { Some(Jacobi::new(&matrix)?) } else { None };
        Ok(Self {
            dims,
            dofs,
            distance,
            extension,
            nodes,
            slots,
            matrix,
            jacobi,
            dirichlet_ptr,
            dirichlet,
            params: CgParams {
                max_iterations: 2000,
                tolerance: 1e-8,
                absolute_tolerance: 0.0,
            },
            warm: Mutex::new(Warm::default()),
        })
    }

    /// Number of band slots: active plus empty nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }
    /// True when the band holds no node (never for a valid grid, which has active nodes).
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }
    /// Number of active nodes (the first slots).
    pub fn dofs(&self) -> usize {
        self.dofs
    }
    /// Number of empty nodes filled by the diffusion (Table 4.1, "Grid: # empty nodes").
    pub fn empty_count(&self) -> usize {
        self.nodes.len() - self.dofs
    }
    /// The band distance (l1, in nodes) this band was built with.
    pub fn distance(&self) -> usize {
        self.distance
    }
    /// The extension this system was built with.
    pub fn extension(&self) -> DisplacementExtension {
        self.extension
    }
    /// Node counts of the reference grid the band was built on.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }
    /// The grid node (flat index into the reference SDF) of every slot.
    pub fn nodes(&self) -> &[usize] {
        &self.nodes
    }
    /// The slot of grid node `n`, if it is in the band.
    pub fn slot(&self, n: usize) -> Option<usize> {
        self.slots.get(n).filter(|&&s| s != INACTIVE).map(|&s| s as usize)
    }
    /// The system matrix of the empty nodes (rows and columns in empty-node order, i.e. slot minus
    /// [`Diffusion::dofs`]).
    pub fn matrix(&self) -> &SparseMatrix<f64> {
        &self.matrix
    }
    /// The Jacobi preconditioner of [`Diffusion::matrix`] (`None` when there is no empty node).
    pub fn preconditioner(&self) -> Option<&Jacobi<f64>> {
        self.jacobi.as_ref()
    }

    fn check(&self, u_active: &Matrix<Vec3<f64>>) -> Result<(), Error> {
        let s = u_active.shape();
        if s.rows != self.dofs || s.cols != 1 || s.batches != 1 {
            return Err(Error::Invalid(format!(
                "diffusion: displacement is {}x{}x{}, expected {} x 1 x 1 (one per active node)",
                s.rows, s.cols, s.batches, self.dofs
            )));
        }
        Ok(())
    }

    /// The right-hand side `b` (`empty x 1 x 3`, batch `c` = coordinate `c`): the couplings
    /// to the active nodes (for [`DisplacementExtension::Harmonic`], the sum of the active neighbours'
    /// displacements).
    pub fn rhs(&self, u_active: &Matrix<Vec3<f64>>) -> Result<Matrix<f64>, Error> {
        self.check(u_active)?;
        let m = self.empty_count();
        let u = u_active.as_slice();
        let sums: Vec<Vec3<f64>> = (0..m)
            .into_par_iter()
            .with_min_len(1024)
            .map(|r| {
                let (a, b) = (self.dirichlet_ptr[r] as usize, self.dirichlet_ptr[r + 1] as usize);
                self.dirichlet[a..b]
                    .iter()
                    .fold(Vec3::default(), |acc, &(d, c)| acc - u[d as usize] * c)
            })
            .collect();
        let mut data = vec![0.0; 3 * m];
        let (bx, rest) = data.split_at_mut(m);
        let (by, bz) = rest.split_at_mut(m);
        for (r, s) in sums.iter().enumerate() {
            bx[r] = s.x;
            by[r] = s.y;
            bz[r] = s.z;
        }
        Ok(Matrix::from_vec(m, 1, 3, data))
    }

    /// Diffuses the active nodes' displacements into the empty nodes: one batched,
    /// Jacobi-preconditioned CG solve for x, y and z, warm-started from the previous solution.
    /// Returns one displacement per slot (the first [`Diffusion::dofs`] copy `u_active`).
    pub fn diffuse(&self, u_active: &Matrix<Vec3<f64>>) -> Result<Vec<Vec3<f64>>, Error> {
        Ok(self.diffuse_info(u_active)?.0)
    }

    /// [`Diffusion::diffuse`], also returning the per-coordinate CG iterations and residuals.
    pub fn diffuse_info(&self, u_active: &Matrix<Vec3<f64>>) -> Result<(Vec<Vec3<f64>>, CgInfo<f64>), Error> {
        let b = self.rhs(u_active)?;
        let m = self.empty_count();
        let mut out = Vec::with_capacity(self.len());
        out.extend_from_slice(u_active.as_slice());
        let Some(jacobi) = &self.jacobi else {
            let info = CgInfo {
                iterations: vec![0; 3],
                residual: vec![0.0; 3],
                converged: vec![true; 3],
            };
            return Ok((out, info));
        };
        let warm = self.warm.lock().unwrap_or_else(|e| e.into_inner()).x.take();
        let mut x = warm
            .filter(|x| x.shape() == b.shape())
            .unwrap_or_else(|| Matrix::zeros(m, 1, 3));
        // The tolerance is relative to each coordinate's ||b|| plus the same fraction of the
        // largest one: a coordinate whose right-hand side vanishes (a rotation about z has no
        // z displacement) would otherwise have to reach a zero residual from a warm start.
        let bmax = b
            .ex()
            .norm_over(Axes::ROWS)
            .into_vec()
            .into_iter()
            .fold(0.0, f64::max);
        let params = CgParams {
            absolute_tolerance: self.params.absolute_tolerance.max(self.params.tolerance * bmax),
            ..self.params
        };
        let info = cg(&self.matrix, &b, &mut x, jacobi, &params)
            .map_err(|e| Error::Invalid(format!("diffusion: {e}")))?;
        let (xs, ys, zs) = (x.batch(0), x.batch(1), x.batch(2));
        out.extend((0..m).map(|r| Vec3::new(xs[r], ys[r], zs[r])));
        let mut w = self.warm.lock().unwrap_or_else(|e| e.into_inner());
        w.x = Some(x);
        w.info = Some(info.clone());
        Ok((out, info))
    }

    /// The adjoint (transpose) of [`Diffusion::diffuse`] (thesis sec. 5.5.2): for a gradient
    /// `g` per slot, returns the gradient per active node. `diffuse` is the linear map
    /// `u -> (u, L^{-1} C u)` with `C` the (negated) couplings to the active nodes, so its
    /// transpose is `g -> g_active + C^T L^{-1} g_empty` (`L` symmetric): one batched CG solve.
    pub fn diffuse_adjoint(&self, g: &[Vec3<f64>]) -> Result<Matrix<Vec3<f64>>, Error> {
        if g.len() != self.len() {
            return Err(Error::Invalid(format!(
                "diffusion adjoint: {} gradients for {} slots",
                g.len(),
                self.len()
            )));
        }
        let mut out = Matrix::from_fn(self.dofs, 1, 1, |d, _, _| g[d]);
        let m = self.empty_count();
        let Some(jacobi) = &self.jacobi else {
            return Ok(out);
        };
        let ge = &g[self.dofs..];
        let mut data = vec![0.0; 3 * m];
        for (r, v) in ge.iter().enumerate() {
            data[r] = v.x;
            data[m + r] = v.y;
            data[2 * m + r] = v.z;
        }
        let b = Matrix::from_vec(m, 1, 3, data);
        let bmax = b
            .ex()
            .norm_over(Axes::ROWS)
            .into_vec()
            .into_iter()
            .fold(0.0, f64::max);
        if bmax == 0.0 {
            return Ok(out);
        }
        let params = CgParams {
            absolute_tolerance: self.params.absolute_tolerance.max(self.params.tolerance * bmax),
            ..self.params
        };
        let mut y = Matrix::zeros(m, 1, 3);
        cg(&self.matrix, &b, &mut y, jacobi, &params)
            .map_err(|e| Error::Invalid(format!("diffusion adjoint: {e}")))?;
        let (ys, yy, yz) = (y.batch(0), y.batch(1), y.batch(2));
        let os = out.as_mut_slice();
        for r in 0..m {
            let yr = Vec3::new(ys[r], yy[r], yz[r]);
            let (a, b) = (self.dirichlet_ptr[r] as usize, self.dirichlet_ptr[r + 1] as usize);
            for &(d, c) in &self.dirichlet[a..b] {
                os[d as usize] = os[d as usize] - yr * c;
            }
        }
        Ok(out)
    }

    /// What the last successful [`Diffusion::diffuse`] did, if any.
    pub fn last_info(&self) -> Option<CgInfo<f64>> {
        self.warm.lock().unwrap_or_else(|e| e.into_inner()).info.clone()
    }

    /// Forgets the warm start: the next solve starts from zero.
    pub fn reset_warm_start(&self) {
        let mut w = self.warm.lock().unwrap_or_else(|e| e.into_inner());
        *w = Warm::default();
    }
}
