//! The tetrahedral baseline (thesis sec. 4.6, Table 4.1): the same body as a [`Grid`],
//! discretized by linear tetrahedra, with the same time integration and solver, so that the
//! cut-cell grid can be compared with a classical mesh FEM in accuracy and cost.
//!
//! # Mesh
//!
//! Every active cell of the grid is split into the 6 Kuhn tetrahedra around its main diagonal
//! (corner 0 to corner 7): for each permutation `(a, b, c)` of the axes the path
//! `0 -> e_a -> e_a + e_b -> e_a + e_b + e_c` spans one tetrahedron ([`KUHN`]). On a cell face
//! the split diagonal always runs from the face's lowest to its highest corner, so
//! neighbouring cells share their face triangles and the mesh is conforming. A tetrahedron is
//! kept when the trilinear interpolation of the cell's (snapped) corner SDF values at its
//! centroid is negative (`phi(centroid) < 0`, the centroid rule). The centroid of a Kuhn
//! tetrahedron has the local coordinates `{1/4, 1/2, 3/4}` (one value per axis), so a full
//! cell keeps all six and a cut cell those on the inside of its interpolated surface. The mesh
//! nodes are the grid nodes used by a kept tetrahedron, numbered in grid order.
//!
//! Counts (thesis' cuboid, Table 4.1): at resolution 10 (cell size 1/20) this keeps 19916 of
//! the 6 x 3328 = 19968 tetrahedra and 4125 of the 4131 nodes (it drops tetrahedra in the end
//! cells along the edges of the end faces); the thesis' tet meshes are structured meshes of the
//! cuboid, which match the grid's active cells exactly only where its faces fall on grid
//! lines, so at other resolutions the counts differ by a few percent.
//!
//! # Element (thesis sec. 2.5.1 in 3D)
//!
//! With reference vertices `X_0..X_3`, the edge matrix `D_m = [X_1-X_0, X_2-X_0, X_3-X_0]`,
//! volume `V = det(D_m)/6` and barycentric basis functions `N_i`, the gradients are constant:
//! `g_i = grad N_i` is row `i-1` of `D_m^{-1}` for `i = 1..3` and `g_0 = -(g_1+g_2+g_3)`.
//! The 3x3 stiffness block between vertices `i` and `j` is the exact integral of `B^T C B`:
//! `K_ij = V (lambda g_i g_j^T + mu g_j g_i^T + mu (g_i . g_j) I)`
//! ([`stiffness_block`](super::element::stiffness_block), the same integrand as the grid element). A linear displacement is
//! represented exactly and its strain energy is `V W(eps)` per element.
//!
//! Mass is lumped: each vertex gets `rho V / 4` of each tetrahedron (whatever `Model::mass`,
//! which picks the grid bodies' mass matrix). Gravity is the body force
//! `f_i = m_i g`.
//!
//! # Corotation (thesis eq. 2.7.1-2.7.3 in 3D)
//!
//! `F = D_s D_m^{-1}` with the deformed edge matrix `D_s = [x_1-x_0, x_2-x_0, x_3-x_0]`,
//! `x_i = X_i + u_i`; equivalently `F = I + sum_i u_i g_i^T`. `R = polar(F)` by
//! [`polar_rotation`](super::element::polar_rotation); the element contributes `R K R^T` to the stiffness and
//! `f_i -= sum_j R K_ij (R^T X_j - X_j)` to the force (`X` relative to vertex 0, allowed
//! since `sum_j K_ij = 0`).
//!
//! # Hard Dirichlet (thesis sec. 2.4.2)
//!
//! Nodes inside any `model.dirichlet` box are fixed at zero displacement and removed from the
//! system: the unknowns are the free nodes only, the matrix is `K_ff`, and because `u_fixed =
//! 0` the coupling `K_fd u_d` vanishes. The grid instead holds weakly (Nitsche) the surface
//! of the cut cells whose center lies in a box: for a clamped end, the end face and the
//! lateral band of the first cell layer. A box reaching one cell into the body (`x <= x_min +
//! 1.01 h`) selects exactly that layer in the grid and fixes the two node planes `x_min` and
//! `x_min + h` of the tetrahedra, so both clamp the same material (fixing only the end plane
//! makes a tetrahedral cantilever about 20% softer).
//!
//! # Ground contact (optional)
//!
//! One contact spring per free surface node (a node of a boundary triangle, a face that
//! belongs to one tetrahedron only), with the grid's softened spring law
//! ([`super::collision`]): `d = n . x - height`, `f = -k softmin_alpha(0, d) n`, in either of
//! the grid's time discretizations ([`ContactScheme`](super::collision::ContactScheme)): the thesis' prediction
//! `theta (f + dt df/dt) + (1-theta) f`, or the linearization `f(u') ~ f(u) - K_c (u' - u)`,
//! `K_c = k softmin'(d) n n^T`, whose `theta dt K_c` joins the diagonal block of `A`. The grid
//! puts a spring at each surface crossing of a grid edge instead, so the two contact
//! stiffnesses per unit area differ (both scale with the surface resolution).
//!
//! # Time integration
//!
//! Exactly the grid's Newmark-1 theta scheme with Rayleigh damping (see [`super::sim`]):
//! `A = (1/(theta dt) + alpha_1) M + (alpha_2 + theta dt) K`,
//! `b = ((1/(theta dt) + alpha_1) M + (alpha_2 - (1-theta) dt) K) u + M v / theta + dt f`,
//! each one fused gpumat expression on a BSR matrix whose pattern (free node pairs sharing a
//! tetrahedron) and gather map are built once; the values are assembled row by row in a fixed
//! order (deterministic, no atomics). `A u' = b` is solved by [`solve`](super::sim::solve) (block-Jacobi CG with
//! Cholesky fallback).
#[path = "tet_assembly.rs"]
mod assembly;
#[path = "tet_sim.rs"]
mod simulation;

pub use assembly::TetAssembler;
pub use simulation::{AssemblyTimes, TetSimulation};

use super::grid::{Grid, INACTIVE};
use super::model::Model;
use crate::error::Error;
use gpumat::{Mat3, Vec3};
use rayon::prelude::*;

/// The 6 Kuhn tetrahedra of a cell as corner indices (corner `c` at offset
/// `(c&1, (c>>1)&1, (c>>2)&1)`), each positively oriented. Rows: axis orders xyz, yzx, zxy
/// (even permutations, `[0, a, a+b, 7]`) and xzy, yxz, zyx (odd, last two vertices swapped).
pub const KUHN: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 1, 7, 5],
    [0, 2, 7, 3],
    [0, 4, 7, 6],
];

/// Trilinear interpolation of corner values at local coordinates `t` in `[0,1]^3`.
fn trilinear(phi: &[f64; 8], t: [f64; 3]) -> f64 {
    (0..8)
        .map(|c| {
            let w: f64 = (0..3)
                .map(|d| if (c >> d) & 1 == 1 { t[d] } else { 1.0 - t[d] })
                .product();
            w * phi[c]
        })
        .sum()
}

/// A linear tetrahedral mesh of a body, with its fixed nodes and per-element geometry.
#[derive(Clone, Debug)]
pub struct TetMesh {
    /// reference position of each node
    pub positions: Vec<Vec3<f64>>,
    /// the vertices of each tetrahedron, positively oriented
    pub tets: Vec<[u32; 4]>,
    /// true for a node held at zero displacement (inside a Dirichlet box)
    pub fixed: Vec<bool>,
    /// true for a node on the boundary (a vertex of a face that belongs to one tetrahedron)
    pub surface: Vec<bool>,
    /// the grid degree of freedom each node comes from
    pub grid_dofs: Vec<u32>,
    /// the free degree of freedom of each node ([`INACTIVE`] for fixed nodes)
    pub node_dofs: Vec<u32>,
    /// the node of each free degree of freedom
    pub free_nodes: Vec<u32>,
    /// the volume of each tetrahedron
    pub volumes: Vec<f64>,
    /// the basis gradients `grad N_i` of each tetrahedron (constant per element)
    pub gradients: Vec<[Vec3<f64>; 4]>,
}

impl TetMesh {
    /// Splits every active cell of `grid` into the 6 Kuhn tetrahedra, keeps those whose
    /// centroid is inside (see the module docs) and fixes the nodes inside `model.dirichlet`.
    /// Errors: no tetrahedron kept, a Dirichlet box holding no node, every node fixed.
    pub fn from_grid(grid: &Grid, model: &Model) -> Result<Self, Error> {
        let centroids: [[f64; 3]; 6] = std::array::from_fn(|t| {
            std::array::from_fn(|d| KUHN[t].iter().map(|&c| ((c >> d) & 1) as f64).sum::<f64>() / 4.0)
        });
        let mut grid_tets = Vec::with_capacity(grid.cells.len() * 6);
        for cell in &grid.cells {
            for (t, k) in KUHN.iter().enumerate() {
                if trilinear(&cell.phi, centroids[t]) < 0.0 {
                    grid_tets.push(k.map(|c| cell.dofs[c]));
                }
            }
        }
        if grid_tets.is_empty() {
            return Err(Error::Invalid(
                "body: no tetrahedron has its centroid inside the body".into(),
            ));
        }
        let mut node_of = vec![INACTIVE; grid.dofs()];
        for t in &grid_tets {
            for &d in t {
                node_of[d as usize] = 0;
            }
        }
        let mut grid_dofs = Vec::new();
        for (d, n) in node_of.iter_mut().enumerate() {
            if *n != INACTIVE {
                *n = grid_dofs.len() as u32;
                grid_dofs.push(d as u32);
            }
        }
        let tets: Vec<[u32; 4]> = grid_tets.iter().map(|t| t.map(|d| node_of[d as usize])).collect();
        let positions: Vec<Vec3<f64>> = grid_dofs.iter().map(|&d| grid.positions[d as usize]).collect();
        let mut fixed = vec![false; positions.len()];
        for (bi, bx) in model.dirichlet.iter().enumerate() {
            let mut any = false;
            for (p, f) in positions.iter().zip(fixed.iter_mut()) {
                if bx.contains(*p) {
                    *f = true;
                    any = true;
                }
            }
            if !any {
                return Err(Error::Invalid(format!(
                    "dirichlet[{bi}]: the box {:?}..{:?} holds no node of the tetrahedral mesh (no material is held)",
                    bx.min, bx.max
                )));
            }
        }
        let mut node_dofs = vec![INACTIVE; positions.len()];
        let mut free_nodes = Vec::new();
        for (n, d) in node_dofs.iter_mut().enumerate() {
            if !fixed[n] {
                *d = free_nodes.len() as u32;
                free_nodes.push(n as u32);
            }
        }
        if free_nodes.is_empty() {
            return Err(Error::Invalid(
                "dirichlet: every node of the tetrahedral mesh is fixed".into(),
            ));
        }
        let (volumes, gradients): (Vec<f64>, Vec<[Vec3<f64>; 4]>) = tets
            .par_iter()
            .map(|t| {
                let x = t.map(|n| positions[n as usize]);
                element_geometry(&x)
            })
            .collect::<Vec<_>>()
            .into_iter()
            .unzip();
        if let Some(t) = volumes.iter().position(|&v| v.is_nan() || v <= 0.0) {
            return Err(Error::Invalid(format!(
                "body: tetrahedron {t} is degenerate or inverted"
            )));
        }
        let surface = surface_nodes(&tets, positions.len());
        Ok(Self {
            positions,
            tets,
            fixed,
            surface,
            grid_dofs,
            node_dofs,
            free_nodes,
            volumes,
            gradients,
        })
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.positions.len()
    }
    /// Number of free nodes (the unknowns).
    pub fn dofs(&self) -> usize {
        self.free_nodes.len()
    }
    /// Number of fixed nodes.
    pub fn fixed_nodes(&self) -> usize {
        self.fixed.iter().filter(|&&f| f).count()
    }
    /// Total volume.
    pub fn volume(&self) -> f64 {
        self.volumes.iter().sum()
    }
}

/// Volume and basis gradients of a tetrahedron with vertices `x`.
pub fn element_geometry(x: &[Vec3<f64>; 4]) -> (f64, [Vec3<f64>; 4]) {
    let dm = Mat3::from_cols(x[1] - x[0], x[2] - x[0], x[3] - x[0]);
    let vol = dm.determinant() / 6.0;
    match dm.inverse() {
        Some(inv) => {
            let (g1, g2, g3) = (inv.row(0), inv.row(1), inv.row(2));
            (vol, [-(g1 + g2 + g3), g1, g2, g3])
        }
        None => (0.0, [Vec3::default(); 4]),
    }
}

/// Marks the vertices of the boundary faces (faces of exactly one tetrahedron).
fn surface_nodes(tets: &[[u32; 4]], nodes: usize) -> Vec<bool> {
    const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];
    let mut faces: Vec<[u32; 3]> = tets
        .iter()
        .flat_map(|t| {
            FACES.iter().map(move |f| {
                let mut v = f.map(|i| t[i]);
                v.sort_unstable();
                v
            })
        })
        .collect();
    faces.par_sort_unstable();
    let mut surface = vec![false; nodes];
    let mut i = 0;
    while i < faces.len() {
        let mut j = i + 1;
        while j < faces.len() && faces[j] == faces[i] {
            j += 1;
        }
        if j - i == 1 {
            for &n in &faces[i] {
                surface[n as usize] = true;
            }
        }
        i = j;
    }
    surface
}
