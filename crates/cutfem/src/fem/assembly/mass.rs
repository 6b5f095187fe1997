//! The consistent mass matrix (thesis eq. 2.5.14 before lumping): `M_ij = rho int N_i N_j`
//! over the inside part of every cell, on the stiffness matrix' pattern (`[numerics] mass =
//! "consistent"`, [`crate::fem::MassMatrix`]).
//!
//! Why: the lumped mass puts each cell's mass on its corners. Translation sees the right mass
//! (the row sums of `M` are the lumped masses, `sum_j int N_i N_j = int N_i`), rotation does
//! not: a corner sits up to `h / 2` farther from the axis than the material it carries, and a
//! uniform rod's second moment grows from `a^2 / 12` to `a^2 / 12 + h^2 / 6` per axis. For a
//! square bar of side `a` twisting about its axis the polar moment of inertia is `2 h^2 / a^2`
//! too large (10% for the 0.22 bar at `h = 0.05`), its torsion frequencies are 5% too low and a
//! fit makes up for it with a 10% larger shear modulus (Poisson's ratio 0.22 for a true 0.35,
//! `tests/reference_values/independent/README.md`, the `twist` case). The consistent mass is
//! exact for every field the trilinear cell represents (`x^T M x = rho int x^2` for linear `x`):
//! its inertia converges with the stiffness, as `h^2` in the frequencies.
//!
//! On the unit cube, `N_i(xi) = prod_k p_(i,k)(xi_k)` with `p = 1 - t` or `t` by the corner's bit
//! `k`; per axis `p_(i,k) p_(j,k)` is `(1 - t)^2 = 1 - 2t + t^2`, `t^2` or `t (1 - t) = t - t^2`,
//! so `int N_i N_j = sum_(a, b, c) C_x[a] C_y[b] C_z[c] m_abc` with the cell's exact moments
//! `m_abc = int xi^a eta^b zeta^c` over its inside part ([`CellIntegrals::moments`], degree 6
//! at most), times `h^3`.

use super::Assembler;
use crate::cutcell::{moment_index, CellIntegrals};
use crate::fem::grid::Grid;

/// The coefficients of `p_i(t) p_j(t)` in `1, t, t^2` for corner bits `bi`, `bj` of one axis.
fn axis_product(bi: usize, bj: usize) -> [f64; 3] {
    match (bi, bj) {
        (0, 0) => [1.0, -2.0, 1.0],
        (1, 1) => [0.0, 0.0, 1.0],
        _ => [0.0, 1.0, -1.0],
    }
}

/// `int N_i N_j` over the inside part of a cell of size `h` (world units, `h^3`), corners
/// numbered x fastest as [`crate::fem::Cell::dofs`].
pub fn cell_mass(integrals: &CellIntegrals, h: f64) -> [[f64; 8]; 8] {
    let h3 = h * h * h;
    let m = &integrals.moments;
    let mut out = [[0.0; 8]; 8];
    for i in 0..8 {
        for j in i..8 {
            let c: [[f64; 3]; 3] = std::array::from_fn(|k| axis_product((i >> k) & 1, (j >> k) & 1));
            let mut s = 0.0;
            for (zc, &cz) in c[2].iter().enumerate() {
                for (yc, &cy) in c[1].iter().enumerate() {
                    for (xc, &cx) in c[0].iter().enumerate() {
                        if cx != 0.0 && cy != 0.0 && cz != 0.0 {
                            s += cx * cy * cz * m[moment_index(xc, yc, zc)];
                        }
                    }
                }
            }
            out[i][j] = s * h3;
            out[j][i] = s * h3;
        }
    }
    out
}

impl Assembler {
    /// The consistent mass `rho int N_i N_j` on [`Assembler::pattern`]: one value per entry
    /// (the block's `M_rc I`), summed over the cells in cell order (the same bits on any
    /// number of threads).
    pub fn consistent_mass(&self, grid: &Grid, density: f64) -> Vec<f64> {
        let p = &self.pattern;
        let (rp, cols) = (p.row_ptr(), p.col_idx());
        let mut values = vec![0.0; p.nnz()];
        let entry = |r: usize, c: usize| -> usize {
            let row = &cols[rp[r]..rp[r + 1]];
            rp[r]
                + row
                    .binary_search(&(c as _))
                    .expect("a cell's corners share a block")
        };
        for (e, cell) in grid.cells.iter().enumerate() {
            let me = cell_mass(&cell.integrals, grid.h());
            let dofs = &self.cell_dofs[e];
            for i in 0..8 {
                for j in 0..8 {
                    values[entry(dofs[i] as usize, dofs[j] as usize)] += density * me[i][j];
                }
            }
        }
        values
    }
}
