//! The world grid (thesis sec. 4.3.1-4.3.2): active cells (cells with at least one inside
//! corner), active nodes (corners of active cells, the degrees of freedom, numbered in
//! increasing grid order with x fastest), and per active cell the data the assembly needs:
//! corner SDF values, the partial integrals `w_v(e,i)`, `w_b(e,i)` and the normal (sec. 4.2),
//! and the degree of freedom of each corner.

use crate::cutcell::{cell_active, refined_cell_integrals, snap, CellIntegrals};
use crate::error::Error;
use crate::sdf::SdfGrid;
use gpumat::Vec3;
use rayon::prelude::*;

/// Marks a grid node that is not a degree of freedom.
pub const INACTIVE: u32 = u32::MAX;

/// One active cell.
#[derive(Clone, Debug)]
pub struct Cell {
    /// grid coordinates of corner 0
    pub coord: [usize; 3],
    /// degree of freedom of each corner (corner c at offset (c&1, (c>>1)&1, (c>>2)&1))
    pub dofs: [u32; 8],
    /// SDF values at the corners, snapped ([`crate::cutcell::snap`]: `|phi| < 1e-5 h` is 0,
    /// and 0 counts as outside)
    pub phi: [f64; 8],
    /// partial integrals ([`crate::cutcell::refined_cell_integrals`]: the tricubic refinement of
    /// the SDF on the cell's 4x4x4 node stencil)
    pub integrals: CellIntegrals,
}

impl Cell {
    /// True when the cell lies completely inside the body (no interface).
    pub fn is_full(&self) -> bool {
        self.phi.iter().all(|&p| p < 0.0)
    }
}

/// The simulation grid derived from a reference SDF.
#[derive(Clone, Debug)]
pub struct Grid {
    /// the reference SDF
    pub sdf: SdfGrid,
    /// active cells, in increasing grid order
    pub cells: Vec<Cell>,
    /// grid node index of each degree of freedom
    pub dof_nodes: Vec<usize>,
    /// degree of freedom of each grid node ([`INACTIVE`] if none)
    pub node_dofs: Vec<u32>,
    /// reference position of each degree of freedom
    pub positions: Vec<Vec3<f64>>,
    /// the body's SDF sampled finer than [`Grid::sdf`], from which the observed surface is
    /// extracted ([`Grid::surface`]); `None`: the surface comes from `sdf` itself
    pub surface_sdf: Option<SdfGrid>,
    /// how the observed surface is extracted ([`Grid::surface`])
    pub surface_method: crate::surface::SurfaceMethod,
}

/// Memory (bytes) one active node costs in the simulation: the 27 BSR blocks of K and A in
/// f64, the scatter/gather maps and about ten vectors.
pub const BYTES_PER_NODE: usize = 27 * 2 * 72 + 27 * 8 + 64 * 8 + 12 * 32;

/// Memory available to this process (Linux `MemAvailable`), if known.
pub fn available_memory() -> Option<usize> {
    let s = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = s.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: usize = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

impl Grid {
    /// Builds the grid. Errors: invalid SDF, empty body, body touching the grid border (the
    /// body must lie inside the grid), or a memory estimate above what is available.
    pub fn new(sdf: SdfGrid) -> Result<Self, Error> {
        let [nx, ny, nz] = sdf.dims;
        if nx < 2 || ny < 2 || nz < 2 {
            return Err(Error::Invalid(format!(
                "body: the SDF grid {nx}x{ny}x{nz} needs at least 2 nodes per axis"
            )));
        }
        if !(sdf.spacing > 0.0 && sdf.spacing.is_finite()) {
            return Err(Error::Invalid(format!(
                "body: grid spacing {} must be positive",
                sdf.spacing
            )));
        }
        if sdf.values.len() != nx * ny * nz {
            return Err(Error::Invalid(
                "body: SDF value count does not match its dimensions".into(),
            ));
        }
        if let Some(i) = sdf.values.iter().position(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!(
                "body: SDF value at node {i} is not finite"
            )));
        }
        let node = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
        let (cx, cy, cz) = (nx - 1, ny - 1, nz - 1);
        let h = sdf.spacing;
        // Pass 1: which cells are active (cheap; decides the memory estimate).
        let active: Vec<bool> = (0..cx * cy * cz)
            .into_par_iter()
            .map(|c| {
                let (i, j, k) = (c % cx, (c / cx) % cy, c / (cx * cy));
                let phi: [f64; 8] = std::array::from_fn(|q| {
                    sdf.values[node(i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1))]
                });
                cell_active(&phi, h)
            })
            .collect();
        let n_active = active.iter().filter(|&&a| a).count();
        if n_active == 0 {
            return Err(Error::Invalid(format!(
                "body: no grid cell holds enough of the body to simulate (empty body, or thinner \
                 than a cell of {h:.3e}); raise the resolution or check the body's units"
            )));
        }
        let mut node_dofs = vec![INACTIVE; nx * ny * nz];
        for (c, _) in active.iter().enumerate().filter(|(_, &a)| a) {
            let (i, j, k) = (c % cx, (c / cx) % cy, c / (cx * cy));
            if i == 0 || j == 0 || k == 0 || i + 1 == cx || j + 1 == cy || k + 1 == cz {
                return Err(Error::Invalid(format!(
                    "body: the body touches the border of its grid (cell {i},{j},{k}); pad the SDF by at least one cell"
                )));
            }
            for q in 0..8 {
                node_dofs[node(i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1))] = 0;
            }
        }
        let mut dof_nodes = Vec::new();
        for (n, d) in node_dofs.iter_mut().enumerate() {
            if *d != INACTIVE {
                *d = dof_nodes.len() as u32;
                dof_nodes.push(n);
            }
        }
        let estimate = dof_nodes.len() * BYTES_PER_NODE + n_active * std::mem::size_of::<Cell>();
        if let Some(avail) = available_memory() {
            if estimate > avail {
                return Err(Error::Invalid(format!(
                    "body: the grid needs about {} MB ({} nodes, {} cells) but only {} MB are available; lower the resolution",
                    estimate >> 20,
                    dof_nodes.len(),
                    n_active,
                    avail >> 20
                )));
            }
        }
        let cells: Vec<Cell> = active
            .par_iter()
            .enumerate()
            .filter(|(_, &a)| a)
            .map(|(c, _)| {
                let (i, j, k) = (c % cx, (c / cx) % cy, c / (cx * cy));
                let corner = |q: usize| node(i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1));
                let phi: [f64; 8] = snap(&std::array::from_fn(|q| sdf.values[corner(q)]), h);
                let dofs: [u32; 8] = std::array::from_fn(|q| node_dofs[corner(q)]);
                Cell {
                    coord: [i, j, k],
                    dofs,
                    phi,
                    integrals: refined_cell_integrals(&sdf, [i, j, k]),
                }
            })
            .collect();
        let positions = dof_nodes
            .iter()
            .map(|&n| {
                let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
                Vec3::new(
                    sdf.origin[0] + h * i as f64,
                    sdf.origin[1] + h * j as f64,
                    sdf.origin[2] + h * k as f64,
                )
            })
            .collect();
        Ok(Self {
            sdf,
            cells,
            dof_nodes,
            node_dofs,
            positions,
            surface_sdf: None,
            surface_method: Default::default(),
        })
    }

    /// The grid with the body's surface taken from `fine`, the same body's SDF sampled finer
    /// (for example `[numerics] surface_subdivision` times; [`Grid::surface`]).
    pub fn with_surface_sdf(mut self, fine: SdfGrid) -> Self {
        self.surface_sdf = Some(fine);
        self
    }

    /// The grid whose observed surface is extracted by `method`.
    pub fn with_surface_method(mut self, method: crate::surface::SurfaceMethod) -> Self {
        self.surface_method = method;
        self
    }

    /// The body's surface as it is shown, observed and compared with measurements: marching
    /// cubes or dual contouring ([`Grid::surface_method`]) on [`Grid::surface_sdf`] (else on
    /// [`Grid::sdf`]), every vertex moved by the trilinear displacement field of the
    /// simulation cell that holds it ([`crate::surface::embed`]; a marching-cubes vertex of
    /// the grid itself by its edge).
    pub fn surface(&self) -> Result<crate::surface::Surface, Error> {
        use crate::surface::{dual_contour, extract_surface, SurfaceMethod};
        let sdf = self.surface_sdf.as_ref().unwrap_or(&self.sdf);
        let surface = match self.surface_method {
            SurfaceMethod::MarchingCubes if self.surface_sdf.is_none() => {
                return Ok(extract_surface(&self.sdf))
            }
            SurfaceMethod::MarchingCubes => extract_surface(sdf),
            SurfaceMethod::DualContouring => dual_contour(sdf),
        };
        surface
            .embedded_in(&self.sdf, |n| self.node_dofs[n] != INACTIVE)
            .map_err(Error::Invalid)
    }

    /// `surface` (from [`Grid::surface`]) moved by the displacements `u` of this grid's
    /// degrees of freedom (grid nodes without one do not move): the body's surface in state `u`.
    pub fn deformed(
        &self,
        surface: &crate::surface::Surface,
        u: &gpumat::Matrix<Vec3<f64>>,
    ) -> crate::TriMesh {
        surface.deformed(|node| match self.node_dofs[node] {
            INACTIVE => [0.0; 3],
            d => u.get(d as usize, 0, 0).to_array(),
        })
    }

    /// Number of degrees of freedom (active nodes).
    pub fn dofs(&self) -> usize {
        self.dof_nodes.len()
    }
    /// Cell size.
    pub fn h(&self) -> f64 {
        self.sdf.spacing
    }
    /// World position of corner 0 of a cell.
    pub fn cell_origin(&self, cell: &Cell) -> Vec3<f64> {
        let o = self.sdf.origin;
        let h = self.h();
        Vec3::new(
            o[0] + h * cell.coord[0] as f64,
            o[1] + h * cell.coord[1] as f64,
            o[2] + h * cell.coord[2] as f64,
        )
    }
    /// Number of cut cells (cells with an interface).
    pub fn cut_cells(&self) -> usize {
        self.cells.iter().filter(|c| !c.is_full()).count()
    }
    /// Total inside volume.
    pub fn volume(&self) -> f64 {
        self.cells
            .iter()
            .map(|c| c.integrals.volume.iter().sum::<f64>())
            .sum()
    }
}
