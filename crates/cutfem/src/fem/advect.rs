//! Level-set advection: the reference SDF moved by the displacements (thesis sec. 4.4.5, the
//! 3D version of sec. 2.5.2.5 and Alg. A.2).
//!
//! The simulation knows the displacement `u` only at the active nodes, but the level set near
//! the surface also lives on the empty nodes around the body. Two steps, as in the thesis:
//!
//! # 1. Diffusion into the empty nodes ([`Diffusion`])
//!
//! The band `B` is the set of empty (non-active) grid nodes within l1 distance 5 (in nodes) of
//! an active node `A` (sec. 4.4.5: "the nodes farther away do not influence the surface
//! location"), found once by a breadth-first search over face neighbours inside the grid. On
//! `B` the displacement solves the discrete Laplace equation `Delta u = 0` with the 7-point
//! stencil, the active nodes' displacements as Dirichlet data and homogeneous Neumann
//! conditions wherever a neighbour is missing (outer edge of the band, grid border; sec.
//! 2.5.2.5 "explicit diffusion"):
//!
//! `sum_{j in N6(n), j in A or B} (u_n - u_j) = 0` for every `n in B`, i.e. row `n` of
//! `L u_B = b` reads `L_nn = #{j in N6(n) : j in A or B}`, `L_nj = -1` for `j in N6(n)` in
//! `B`, and `b_n = sum_{j in N6(n), j in A} u_j` (`N6(n)`: the face neighbours of `n` inside
//! the grid).
//!
//! `L` is the graph Laplacian of `B` plus the Dirichlet couplings; it is symmetric positive
//! definite because every component of `B` touches `A` (each band node has a neighbour one
//! step closer to `A`). Pattern and values are built once; the three coordinates are one
//! batched right-hand side (`|B| x 1 x 3`) solved by one Jacobi-preconditioned CG in which
//! every coordinate has its own step sizes and stops on its own (gpumat's batched
//! [`gpumat::cg`]), warm-started from the previous solution.
//!
//! Constants are reproduced exactly, linear fields are not: the zero-flux condition at the
//! band's outer edge bends a linear field towards a constant in the normal direction (in 1D,
//! `u = a x` on the active side gives `u = a x_0` on the whole band). The blending below
//! carries this into the surface: rotating the benchmark cuboid by 30 degrees moves its faces
//! by up to 0.17-0.46 cells (rms 0.05-0.10) against 0.03-0.06 (rms 0.007) with exact
//! displacements (tests/fem_advect.rs).
//!
//! [`DisplacementExtension::Linear`] (not in the thesis) replaces the Laplacian by the least squares of
//! the second differences along the axes, `min sum_{q, e} (u(q - e) - 2 u(q) + u(q + e))^2`
//! over the triples inside `A u B` that touch `B`: the normal equations `D^T D u_B = -D^T D_A
//! u_A` form a symmetric positive definite 13-point system, and since every second difference
//! of a linear field vanishes, linear fields (rigid rotations, uniform strains) are extended
//! exactly, and the rotated faces above come out as with exact displacements. It costs about
//! four times the CG iterations of the Laplacian.
//!
//! # 2. Direct Forward advection ([`advect`])
//!
//! Every band node `s` (active or empty) at `x_s` carries its reference value `phi_0(x_s)`
//! to its displaced position `p_s = x_s + u_s` and blends it into the output grid nodes `y`
//! around `p_s` with a truncated Gaussian (Alg. A.2, kernel radius `tau = 1.5` cells, standard
//! deviation `tau / 3` so that about 98% of the mass lies inside the radius):
//!
//! `phi(y) = sum_s w(|y - p_s| / h) phi_0(x_s) / sum_s w(|y - p_s| / h)`,
//! `w(d) = exp(-d^2 / (2 (tau/3)^2))` for `d <= tau`.
//!
//! Nodes that receive nothing (at the corners of the output box, or in strongly stretched
//! regions) are filled by a flood fill (sec. 2.5.2.5), layer by layer from the filled nodes,
//! each taking the mean of its already filled face neighbours. The thesis' published code
//! also blends a faint outer ring (`tau < d <= 4` cells, weight `1e-5 w(d)`) to reach such
//! nodes; [`AdvectSettings::fill_radius`] and [`AdvectSettings::fill_weight`] enable it (off
//! by default: it multiplies the work by about 20 for no change near the surface).
//!
//! The output grid moves with the body (sec. 4.4.5): it has the reference spacing, its nodes on
//! the reference lattice (origin shifted by whole cells, so a translation by whole cells moves
//! values node to node), and covers the bounding box of the displaced band nodes plus
//! [`AdvectSettings::border`] cells.
//!
//! For a translation by whole cells every output node near the body sees the same symmetric
//! set of sources, so linear fields are moved exactly and a curved SDF is only blurred by the
//! kernel (about `sigma^2 / 2 Delta phi = h^2 / (4 R)` for a sphere of radius `R`). For
//! fractional translations the sources are no longer symmetric around `y` and the weighted
//! average is biased by a few hundredths of a cell.
//!
//! The splat runs in parallel over output z-planes: each plane gathers the sources whose
//! kernel reaches it (bucketed by plane), in a fixed order, so the result does not depend on
//! the thread count and needs no atomics.

mod diffusion;

pub use diffusion::{Diffusion, DisplacementExtension, DIFFUSION_DISTANCE};

use super::grid::Grid;
use crate::error::Error;
use crate::sdf::{SdfGrid, MAX_NODES};
use gpumat::Vec3;
use rayon::prelude::*;

/// Parameters of the Direct Forward advection (all lengths in cells).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdvectSettings {
    /// radius `tau` of the Gaussian kernel; its standard deviation is `tau / 3` (thesis: 1.5)
    pub kernel_radius: f64,
    /// radius of the faint outer ring that fills gaps (thesis code: 4; default: 0, no ring)
    pub fill_radius: f64,
    /// weight factor of the outer ring (thesis code: `1e-5`; default: 0, no ring)
    pub fill_weight: f64,
    /// extra cells around the bounding box of the displaced band nodes
    pub border: usize,
}

impl Default for AdvectSettings {
    fn default() -> Self {
        Self {
            kernel_radius: 1.5,
            fill_radius: 0.0,
            fill_weight: 0.0,
            border: 2,
        }
    }
}

impl AdvectSettings {
    fn validate(&self) -> Result<(), Error> {
        if !(self.kernel_radius.is_finite() && self.kernel_radius > 0.0) {
            return Err(Error::Invalid(format!(
                "advection: kernel_radius must be a positive number of cells, found {}",
                self.kernel_radius
            )));
        }
        if !(self.fill_radius.is_finite() && self.fill_weight.is_finite() && self.fill_weight >= 0.0) {
            return Err(Error::Invalid(format!(
                "advection: fill_radius {} and fill_weight {} must be finite, the weight not negative",
                self.fill_radius, self.fill_weight
            )));
        }
        if self.border > 1 << 16 {
            return Err(Error::Invalid(format!(
                "advection: border of {} cells is too large",
                self.border
            )));
        }
        Ok(())
    }
}

/// The advected SDF of the deformed body with the default [`AdvectSettings`] (thesis values).
///
/// `u_nodes` holds one displacement per slot of `band` (as returned by
/// [`Diffusion::diffuse`]). Errors when the sizes do not match, a displacement is not finite,
/// or the output grid would exceed [`MAX_NODES`] nodes.
pub fn advect(grid: &Grid, band: &Diffusion, u_nodes: &[Vec3<f64>]) -> Result<SdfGrid, Error> {
    advect_with(grid, band, u_nodes, &AdvectSettings::default())
}

/// [`advect`] with explicit settings.
pub fn advect_with(
    grid: &Grid,
    band: &Diffusion,
    u_nodes: &[Vec3<f64>],
    settings: &AdvectSettings,
) -> Result<SdfGrid, Error> {
    settings.validate()?;
    let sdf = &grid.sdf;
    if band.dims() != sdf.dims || band.dofs() != grid.dofs() {
        return Err(Error::Invalid(
            "advection: the diffusion band was built for another grid".into(),
        ));
    }
    if u_nodes.len() != band.len() {
        return Err(Error::Invalid(format!(
            "advection: {} displacements for {} band nodes",
            u_nodes.len(),
            band.len()
        )));
    }
    let h = sdf.spacing;
    let [nx, ny, _] = sdf.dims;
    // Displaced positions in reference lattice units.
    let targets: Vec<[f64; 3]> = band
        .nodes()
        .par_iter()
        .zip(u_nodes.par_iter())
        .map(|(&n, u)| {
            let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
            [i as f64 + u.x / h, j as f64 + u.y / h, k as f64 + u.z / h]
        })
        .collect();
    if let Some(s) = targets.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
        return Err(Error::Invalid(format!(
            "advection: the displacement of band node {} (grid node {}) is not finite",
            s,
            band.nodes()[s]
        )));
    }
    let (lo, dims) = output_lattice(&targets, settings.border)?;
    let origin: [f64; 3] = std::array::from_fn(|a| sdf.origin[a] + h * lo[a] as f64);
    // Sources in output lattice units, with their values.
    let sources: Vec<([f64; 3], f64)> = targets
        .iter()
        .zip(band.nodes())
        .map(|(p, &n)| (std::array::from_fn(|a| p[a] - lo[a] as f64), sdf.values[n]))
        .collect();
    let (mut values, filled) = splat(&sources, dims, settings);
    flood_fill(&mut values, &filled, dims);
    Ok(SdfGrid {
        exact: None,
        origin,
        spacing: h,
        dims,
        values,
    })
}

/// The output lattice: first node (in reference lattice units) and node counts covering the
/// targets plus `border` cells.
fn output_lattice(targets: &[[f64; 3]], border: usize) -> Result<([i64; 3], [usize; 3]), Error> {
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for p in targets {
        for a in 0..3 {
            min[a] = min[a].min(p[a]);
            max[a] = max[a].max(p[a]);
        }
    }
    if targets.is_empty() {
        return Err(Error::Invalid("advection: the band is empty".into()));
    }
    // Snap bounds within 1e-3 cells of a node, so that a translation by whole cells gives the
    // same lattice despite round-off and the CG error of the diffused displacements.
    let snap = |x: f64| {
        if (x - x.round()).abs() <= 1e-3 {
            x.round()
        } else {
            x
        }
    };
    let b = border as f64;
    let mut lo = [0i64; 3];
    let mut dims = [0usize; 3];
    let mut total = 1.0f64;
    for a in 0..3 {
        let first = snap(min[a]).floor() - b;
        let last = snap(max[a]).ceil() + b;
        let n = (last - first + 1.0).max(2.0);
        total *= n;
        if !(total <= MAX_NODES as f64 && first.abs() < 1e15) {
            return Err(Error::Invalid(format!(
                "advection: the displaced body spans {:?} .. {:?} cells, more than {MAX_NODES} output nodes",
                min, max
            )));
        }
        lo[a] = first as i64;
        dims[a] = n as usize;
    }
    Ok((lo, dims))
}

/// Blends every source into the output nodes around it; returns the normalized values and
/// which nodes received any weight.
fn splat(sources: &[([f64; 3], f64)], dims: [usize; 3], s: &AdvectSettings) -> (Vec<f64>, Vec<bool>) {
    let [nx, ny, nz] = dims;
    let tau = s.kernel_radius;
    let reach = if s.fill_weight > 0.0 {
        s.fill_radius.max(tau)
    } else {
        tau
    };
    let (tau2, reach2) = (tau * tau, reach * reach);
    let denom = 1.0 / (2.0 * (tau / 3.0) * (tau / 3.0));
    // Bucket the sources by the output plane below them (counting sort, stable).
    let plane = |p: &[f64; 3]| (p[2].floor().max(0.0) as usize).min(nz - 1);
    let mut ptr = vec![0usize; nz + 1];
    for (p, _) in sources {
        ptr[plane(p) + 1] += 1;
    }
    for k in 0..nz {
        ptr[k + 1] += ptr[k];
    }
    let mut next = ptr.clone();
    let mut order = vec![0u32; sources.len()];
    for (i, (p, _)) in sources.iter().enumerate() {
        let k = plane(p);
        order[next[k]] = i as u32;
        next[k] += 1;
    }
    let r_cells = reach.ceil() as usize + 1;
    let plane_len = nx * ny;
    let mut acc = vec![0.0; plane_len * nz];
    let mut wsum = vec![0.0; plane_len * nz];
    acc.par_chunks_mut(plane_len)
        .zip(wsum.par_chunks_mut(plane_len))
        .enumerate()
        .for_each(|(k, (acc, wsum))| {
            let (b0, b1) = (k.saturating_sub(r_cells), (k + r_cells + 1).min(nz));
            for &si in &order[ptr[b0]..ptr[b1]] {
                let (p, v) = sources[si as usize];
                let dz = k as f64 - p[2];
                let rz2 = reach2 - dz * dz;
                if rz2 < 0.0 {
                    continue;
                }
                let ry = rz2.sqrt();
                let (y0, y1) = (
                    ((p[1] - ry).ceil().max(0.0)) as usize,
                    (p[1] + ry).floor().min((ny - 1) as f64),
                );
                if y1 < 0.0 {
                    continue;
                }
                for y in y0..=y1 as usize {
                    let dy = y as f64 - p[1];
                    let rx2 = rz2 - dy * dy;
                    if rx2 < 0.0 {
                        continue;
                    }
                    let rx = rx2.sqrt();
                    let (x0, x1) = (
                        ((p[0] - rx).ceil().max(0.0)) as usize,
                        (p[0] + rx).floor().min((nx - 1) as f64),
                    );
                    if x1 < 0.0 {
                        continue;
                    }
                    for x in x0..=x1 as usize {
                        let dx = x as f64 - p[0];
                        let d2 = dx * dx + dy * dy + dz * dz;
                        let w = if d2 <= tau2 {
                            (-d2 * denom).exp()
                        } else if d2 <= reach2 {
                            s.fill_weight * (-d2 * denom).exp()
                        } else {
                            continue;
                        };
                        acc[x + nx * y] += w * v;
                        wsum[x + nx * y] += w;
                    }
                }
            }
        });
    let filled: Vec<bool> = wsum.iter().map(|&w| w > 0.0).collect();
    acc.par_iter_mut().zip(wsum.par_iter()).for_each(|(a, &w)| {
        if w > 0.0 {
            *a /= w;
        }
    });
    (acc, filled)
}

/// Fills the nodes that received no weight, breadth first from the filled ones: each takes the
/// mean of its face neighbours filled in earlier layers (thesis sec. 2.5.2.5, "simple flood
/// fill"). Deterministic: a layer reads only earlier layers.
fn flood_fill(values: &mut [f64], filled: &[bool], dims: [usize; 3]) {
    if filled.iter().all(|&f| f) || !filled.iter().any(|&f| f) {
        return;
    }
    let [nx, ny, nz] = dims;
    let sxy = nx * ny;
    let mut layer: Vec<u32> = filled.iter().map(|&f| if f { 0 } else { u32::MAX }).collect();
    let nbrs = |n: usize| {
        let (i, j, k) = (n % nx, (n / nx) % ny, n / sxy);
        [
            (i > 0).then(|| n - 1),
            (i + 1 < nx).then(|| n + 1),
            (j > 0).then(|| n - nx),
            (j + 1 < ny).then(|| n + nx),
            (k > 0).then(|| n - sxy),
            (k + 1 < nz).then(|| n + sxy),
        ]
    };
    let mut frontier: Vec<usize> = (0..values.len())
        .filter(|&n| layer[n] == u32::MAX && nbrs(n).iter().flatten().any(|&m| layer[m] == 0))
        .collect();
    let mut current = 1u32;
    while !frontier.is_empty() {
        for &n in &frontier {
            layer[n] = current;
        }
        for &n in &frontier {
            let (mut s, mut c) = (0.0, 0.0);
            for &m in nbrs(n).iter().flatten() {
                if layer[m] < current {
                    s += values[m];
                    c += 1.0;
                }
            }
            values[n] = s / c;
        }
        let mut next: Vec<usize> = frontier
            .iter()
            .flat_map(|&n| nbrs(n).into_iter().flatten())
            .filter(|&m| layer[m] == u32::MAX)
            .collect();
        next.sort_unstable();
        next.dedup();
        frontier = next;
        current += 1;
    }
}
