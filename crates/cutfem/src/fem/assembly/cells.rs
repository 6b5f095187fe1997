//! The cell sweep of a step: per cell, the rotation `R_e` (eq. 4.4.8-4.4.9), its padded
//! transpose (for [`rotate_add`](super::super::element::rotate_add)) and the corotation forces at
//! the eight corners (eq. 4.4.6/4.4.10), computed while the cell's blocks are at hand.

use super::super::element::{
    cell_rotations4, corner_offsets, corotation_forces, padded_transpose, ElementBlocks, PaddedBlock,
};
use super::super::grid::{Cell, Grid};
use super::{for_each_item, Assembler, CELL_CHUNK};
use gpumat::simd::{dispatch, Kernel, Portable, Simd4};
use gpumat::{Mat3, Matrix, Vec3};
use rayon::prelude::*;

impl Assembler {
    /// Per-cell rotations from the displacement `u` (eq. 4.4.8-4.4.9).
    pub fn rotations(&self, grid: &Grid, u: &Matrix<Vec3<f64>>, iterations: usize) -> Vec<Mat3<f64>> {
        let us = u.as_slice();
        grid.cells
            .par_iter()
            .map(|c| cell_rotation(grid, us, c, iterations))
            .collect()
    }

    /// One sweep over the cells: the rotation `R_e` (eq. 4.4.8-4.4.9) into `rotations` and,
    /// with the cell's blocks at hand, its corner forces ([`corotation_forces`], scaled by
    /// `scale[e]`) and padded `R_e^T` into `work`. The buffers are resized to the cell count and
    /// reused from step to step.
    #[allow(clippy::too_many_arguments)]
    pub fn rotations_and_cell_forces(
        &self,
        grid: &Grid,
        u: &Matrix<Vec3<f64>>,
        iterations: usize,
        blocks: &ElementBlocks,
        scale: Option<&[f64]>,
        rotations: &mut Vec<Mat3<f64>>,
        work: &mut CellWork,
    ) {
        let nc = grid.cells.len();
        rotations.resize(nc, Mat3::default());
        work.rt.resize(nc, [[0.0; 4]; 3]);
        work.forces.resize(nc, [Vec3::default(); 8]);
        let sweep = CellSweep {
            grid,
            us: u.as_slice(),
            x: corner_offsets(grid.h()),
            iterations,
            blocks,
            scale,
        };
        let items: Vec<_> = rotations
            .chunks_mut(CELL_CHUNK)
            .zip(work.rt.chunks_mut(CELL_CHUNK))
            .zip(work.forces.chunks_mut(CELL_CHUNK))
            .enumerate()
            .collect();
        for_each_item(self.parallel(), items, |(ci, ((r, rt), f))| {
            sweep.run(ci * CELL_CHUNK, r, rt, f)
        });
    }

    /// Adds the corotation forces `f_i -= sum_j R K_ij (R^T x_j - x_j)` to `f`.
    pub fn add_corotation_forces(
        &self,
        grid: &Grid,
        blocks: &ElementBlocks,
        rotations: &[Mat3<f64>],
        scale: Option<&[f64]>,
        f: &mut Matrix<Vec3<f64>>,
    ) {
        let x = corner_offsets(grid.h());
        // per cell: the 8 corner forces
        let cell_forces: Vec<[Vec3<f64>; 8]> = (0..grid.cells.len())
            .into_par_iter()
            .map(|e| {
                let (r, s) = (&rotations[e], scale.map_or(1.0, |s| s[e]));
                corotation_forces(Portable, blocks.cell_columns(e), r, &padded_transpose(r), &x, s)
            })
            .collect();
        let fs = f.as_mut_slice();
        fs.par_iter_mut().enumerate().for_each(|(dof, out)| {
            for &(e, q) in self.cells_of(dof) {
                *out = *out + cell_forces[e as usize][q as usize];
            }
        });
    }
}

/// Per-cell data of a corotated step, filled by [`Assembler::rotations_and_cell_forces`] and
/// reused from step to step: the padded transposed rotations (for the rotation kernel) and
/// the corotation forces at the corners of each cell.
#[derive(Clone, Debug, Default)]
pub struct CellWork {
    pub(super) rt: Vec<PaddedBlock>,
    pub(super) forces: Vec<[Vec3<f64>; 8]>,
}

impl CellWork {
    /// The corner forces of each cell from the last sweep.
    pub fn forces(&self) -> &[[Vec3<f64>; 8]] {
        &self.forces
    }
}

/// The inputs of the cell sweep of [`Assembler::rotations_and_cell_forces`].
struct CellSweep<'a> {
    grid: &'a Grid,
    us: &'a [Vec3<f64>],
    x: [Vec3<f64>; 8],
    iterations: usize,
    blocks: &'a ElementBlocks,
    scale: Option<&'a [f64]>,
}

impl CellSweep<'_> {
    /// Cells `e0..e0 + r.len()`, in AVX2 registers where the CPU has them (same operations,
    /// same values).
    fn run(&self, e0: usize, r: &mut [Mat3<f64>], rt: &mut [PaddedBlock], f: &mut [[Vec3<f64>; 8]]) {
        struct Chunk<'a> {
            sweep: &'a CellSweep<'a>,
            e0: usize,
            r: &'a mut [Mat3<f64>],
            rt: &'a mut [PaddedBlock],
            f: &'a mut [[Vec3<f64>; 8]],
        }
        impl Kernel for Chunk<'_> {
            type Output = ();
            #[inline(always)]
            fn run<S: Simd4>(self, s: S) {
                let w = self.sweep;
                let n = self.r.len();
                // rotations four cells at a time (lanes past the end get a zero displacement)
                for g in (0..n).step_by(4) {
                    let mut u = [[Vec3::default(); 8]; 4];
                    for (l, ul) in u.iter_mut().enumerate().take(n - g) {
                        let dofs = &w.grid.cells[self.e0 + g + l].dofs;
                        for q in 0..8 {
                            ul[q] = w.us[dofs[q] as usize];
                        }
                    }
                    let r4 = cell_rotations4(s, &u, w.grid.h(), w.iterations);
                    for (l, r) in r4.into_iter().enumerate().take(n - g) {
                        self.r[g + l] = r;
                    }
                }
                for (o, ((r, rt), f)) in self
                    .r
                    .iter()
                    .zip(self.rt.iter_mut())
                    .zip(self.f.iter_mut())
                    .enumerate()
                {
                    let e = self.e0 + o;
                    *rt = padded_transpose(r);
                    let sc = w.scale.map_or(1.0, |sc| sc[e]);
                    *f = corotation_forces(s, w.blocks.cell_columns(e), r, rt, &w.x, sc);
                }
            }
        }
        dispatch(Chunk {
            sweep: self,
            e0,
            r,
            rt,
            f,
        })
    }
}

/// The rotation of cell `c` (eq. 4.4.8-4.4.9).
#[inline(always)]
fn cell_rotation(grid: &Grid, us: &[Vec3<f64>], c: &Cell, iterations: usize) -> Mat3<f64> {
    let mut ue = [Vec3::default(); 8];
    for q in 0..8 {
        ue[q] = us[c.dofs[q] as usize];
    }
    super::super::element::polar_rotation(
        super::super::element::deformation_gradient(&ue, grid.h()),
        iterations,
    )
}
