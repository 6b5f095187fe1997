//! The cell sweep of a step: per cell, the rotation `R_e` (eq. 4.4.8-4.4.9), its padded
//! transpose (for [`rotate_add`](super::super::element::rotate_add)) and the cell's share of the
//! Newmark right-hand side at its eight corners, computed while the cell's blocks are at hand.
//!
//! The right-hand side `b = cm M u + cu K u + cv M v + dt f` (see [`super::newmark`]) holds
//! the stiffness twice: in `cu K u` and in the corotation force
//! `f_rot,i = -sum_j R K_ij (R^T x_j - x_j)` (eq. 4.4.6/4.4.10). Both are one product per cell:
//! with `K u = sum_e (R_e s_e K(e) R_e^T + N(e)) u` (`s_e` the cell's stiffness scale, `N(e)`
//! its Nitsche blocks, added after the rotation), the cell's share at corner `i` is
//!
//! `c_i = s_e R sum_j K_ij z_j + cu sum_j N_ij u_j`, `z_j = cu R^T u_j - dt (R^T x_j - x_j)`,
//!
//! and `b_r = cm m_r u_r + cv m_r v_r + sum_(e, q at r) c_(e, q) + dt f_r`, where `f` keeps only
//! the body, external and contact forces. So a step never needs `K` as a matrix: the row
//! sweep writes `A` alone. Because `sum_j K_ij = 0`, the corner positions may be taken
//! relative to the cell ([`corner_offsets`]). Without corotation `R = I` and `z_j = cu u_j`.

use super::super::element::{
    cell_rotations4, comb, corner_offsets, lanes3, padded_transpose, ElementBlocks, PaddedBlock, CORNER_SIGNS,
};
use super::super::grid::{Cell, Grid};
use super::{Assembler, Material};
use gpumat::simd::{dispatch, Kernel, Portable, Simd4};
use gpumat::{Mat3, Matrix, Vec3};
use rayon::prelude::*;

impl Assembler {
    /// Per-cell rotations from the displacement `u` (eq. 4.4.8-4.4.9, with the element's
    /// gradient weights, [`ElementSet::gradient_weights`](super::super::element::ElementSet::gradient_weights)).
    pub fn rotations(
        &self,
        grid: &Grid,
        blocks: &ElementBlocks,
        u: &Matrix<Vec3<f64>>,
        iterations: usize,
    ) -> Vec<Mat3<f64>> {
        let us = u.as_slice();
        grid.cells
            .par_iter()
            .enumerate()
            .map(|(e, c)| cell_rotation(grid, us, c, blocks.set(e).gradient_weights(), iterations))
            .collect()
    }

    /// Adds the corotation forces `f_i -= s_e sum_j R K_ij (R^T x_j - x_j)` to `f`.
    pub fn add_corotation_forces(
        &self,
        grid: &Grid,
        blocks: &ElementBlocks,
        rotations: &[Mat3<f64>],
        scale: Option<&[f64]>,
        f: &mut Matrix<Vec3<f64>>,
    ) {
        let x = corner_offsets(grid.h());
        let zero = [Vec3::default(); 8];
        // per cell: the 8 corner forces (the share of `dt f_rot` with `dt = 1`, no `K u`)
        let cell_forces: Vec<[Vec3<f64>; 8]> = (0..grid.cells.len())
            .into_par_iter()
            .map(|e| {
                let (r, s) = (&rotations[e], scale.map_or(1.0, |s| s[e]));
                let kc = blocks.cell_columns(e);
                cell_rhs(Portable, kc, r, &padded_transpose(r), &x, &zero, (0.0, 1.0), s)
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

/// Per-cell data of a step, filled by the cell sweep ([`CellSweep`]) and reused from step
/// to step: the padded transposed rotations (for the rotation kernel) and each cell's
/// share of the Newmark right-hand side at its corners.
#[derive(Clone, Debug, Default)]
pub(crate) struct CellWork {
    pub(super) rt: Vec<PaddedBlock>,
    pub(super) rhs: Vec<[Vec3<f64>; 8]>,
}

/// The inputs of the cell sweep (module docs): displacement `us`, corner offsets `x`
/// ([`corner_offsets`]), coefficients `cu` and `dt`, polar iterations, per-cell data.
pub(super) struct CellSweep<'a> {
    pub(super) asm: &'a Assembler,
    pub(super) grid: &'a Grid,
    pub(super) m: &'a Material,
    pub(super) us: &'a [Vec3<f64>],
    pub(super) x: [Vec3<f64>; 8],
    pub(super) cu: f64,
    pub(super) dt: f64,
    pub(super) iterations: usize,
    pub(super) blocks: &'a ElementBlocks,
    pub(super) dirichlet: &'a [Option<crate::fem::NitscheFace>],
    pub(super) scale: Option<&'a [f64]>,
}

impl CellSweep<'_> {
    /// The sweep over the cells `e0..e0 + rt.len()`: with `r`, their rotations `R_e`
    /// (eq. 4.4.8-4.4.9) into it (else `R_e = I`), their padded `R_e^T` into `rt` and their
    /// shares `c_(e, i)` of the Newmark right-hand side into `c`, four cells at a time in
    /// AVX2 registers where the CPU has them (the same values on every backend).
    pub(super) fn run(
        &self,
        e0: usize,
        r: Option<&mut [Mat3<f64>]>,
        rt: &mut [PaddedBlock],
        c: &mut [[Vec3<f64>; 8]],
    ) {
        assert!(
            e0 + rt.len() <= self.grid.cells.len()
                && c.len() == rt.len()
                && r.as_ref().map_or(true, |r| r.len() == rt.len()),
            "cutfem: cell sweep buffers of another size"
        );
        dispatch(Chunk {
            sweep: self,
            e0,
            r,
            rt,
            c,
        })
    }
}

/// Cells `e0..e0 + rt.len()` of the sweep, in AVX2 registers where the CPU has them (same
/// operations, same values).
struct Chunk<'a> {
    sweep: &'a CellSweep<'a>,
    e0: usize,
    /// the rotations to compute (`None`: `R = I`)
    r: Option<&'a mut [Mat3<f64>]>,
    rt: &'a mut [PaddedBlock],
    c: &'a mut [[Vec3<f64>; 8]],
}

impl Kernel for Chunk<'_> {
    type Output = ();
    #[inline(always)]
    fn run<S: Simd4>(self, s: S) {
        let w = self.sweep;
        let n = self.rt.len();
        let mut r = self.r;
        // the corner displacements and, four cells at a time, the rotations (lanes past the
        // end get a zero displacement)
        for g in (0..n).step_by(4) {
            let mut u = [[Vec3::default(); 8]; 4];
            let mut a = [CORNER_SIGNS; 4];
            let lanes = (n - g).min(4);
            for (l, ul) in u.iter_mut().enumerate().take(lanes) {
                let dofs = &w.asm.cell_dofs[self.e0 + g + l];
                for q in 0..8 {
                    ul[q] = w.us[dofs[q] as usize];
                }
            }
            let r4 = match r.as_deref_mut() {
                Some(rs) => {
                    for (l, al) in a.iter_mut().enumerate().take(lanes) {
                        *al = *w.blocks.set(self.e0 + g + l).gradient_weights();
                    }
                    let r4 = cell_rotations4(s, &u, &a, w.grid.h(), w.iterations);
                    rs[g..g + lanes].copy_from_slice(&r4[..lanes]);
                    r4
                }
                None => [Mat3::identity(); 4],
            };
            for l in 0..lanes {
                let e = self.e0 + g + l;
                let rt = padded_transpose(&r4[l]);
                self.rt[g + l] = rt;
                let sc = w.scale.map_or(1.0, |sc| sc[e]);
                let kc = w.blocks.cell_columns(e);
                let mut c = cell_rhs(s, kc, &r4[l], &rt, &w.x, &u[l], (w.cu, w.dt), sc);
                if let Some(f) = &w.dirichlet[e] {
                    w.add_nitsche(f, &u[l], sc, &mut c);
                }
                self.c[g + l] = c;
            }
        }
    }
}

impl CellSweep<'_> {
    /// `c_i += cu sum_j N_ij u_j` for the held surface's blocks `N_ij` of cell `e` (Young's
    /// modulus scaled by `sc`; [`crate::fem::assembly::Material::held_block`]).
    #[inline(never)]
    fn add_nitsche(&self, f: &crate::fem::NitscheFace, u: &[Vec3<f64>; 8], sc: f64, c: &mut [Vec3<f64>; 8]) {
        for (i, ci_out) in c.iter_mut().enumerate() {
            let mut acc = Vec3::default();
            for (j, uj) in u.iter().enumerate() {
                acc = acc + self.m.held_block(f, i, j, sc) * *uj;
            }
            *ci_out = *ci_out + acc * self.cu;
        }
    }
}

/// The share `c_i = sc R sum_j K_ij z_j`, `z_j = cu R^T u_j - dt (R^T x_j - x_j)` (module
/// docs, Nitsche terms left out) of a cell at its eight corners, from the columns `kc` of its
/// blocks ([`ElementBlocks::cell_columns`]), its rotation `r` and padded transpose `rt`
/// ([`padded_transpose`]), the corner offsets `x` ([`corner_offsets`]), the corner
/// displacements `u` and the stiffness scale `sc`, with the vectors of `s`: lane `p` of each
/// vector step is the component `p` of the formula (`R^T y = sum_k R_k y_k` over the rows
/// `R_k`, `K z = sum_l K_(.l) z_l` over the columns), so every backend gives the same bits. The
/// zero blocks of opposite corners are skipped (a sum that starts at +0 is not changed by
/// adding zeros). With `cu = 0`, `dt = 1` it is the corotation force.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn cell_rhs<S: Simd4>(
    s: S,
    kc: &[[PaddedBlock; 8]; 8],
    r: &Mat3<f64>,
    rt: &PaddedBlock,
    x: &[Vec3<f64>; 8],
    u: &[Vec3<f64>; 8],
    (cu, dt): (f64, f64),
    sc: f64,
) -> [Vec3<f64>; 8] {
    let load3 = |v: &PaddedBlock| [s.load(&v[0]), s.load(&v[1]), s.load(&v[2])];
    let m = &r.m;
    let row = |p: usize| s.set([m[p][0], m[p][1], m[p][2], 0.0]);
    let rows = [row(0), row(1), row(2)];
    let (cuv, dtv) = (s.splat(cu), s.splat(dt));
    let mut z = [[0.0; 3]; 8];
    for j in 0..8 {
        let (xj, uj) = (x[j].to_array(), u[j].to_array());
        let d = s.sub(comb(s, &xj, &rows), s.set([xj[0], xj[1], xj[2], 0.0]));
        let ru = comb(s, &uj, &rows);
        z[j] = lanes3(s, s.sub(s.mul(cuv, ru), s.mul(dtv, d)));
    }
    let rtv = load3(rt);
    let mut c = [Vec3::default(); 8];
    for i in 0..8 {
        let mut sum = s.splat(0.0);
        for j in 0..8 {
            sum = s.add(sum, comb(s, &z[j], &load3(&kc[i][j])));
        }
        let rs = lanes3(s, comb(s, &lanes3(s, sum), &rtv));
        c[i] = Vec3::new(rs[0] * sc, rs[1] * sc, rs[2] * sc);
    }
    c
}

/// The rotation of cell `c` (eq. 4.4.8-4.4.9).
#[inline(always)]
fn cell_rotation(
    grid: &Grid,
    us: &[Vec3<f64>],
    c: &Cell,
    a: &[Vec3<f64>; 8],
    iterations: usize,
) -> Mat3<f64> {
    let mut ue = [Vec3::default(); 8];
    for q in 0..8 {
        ue[q] = us[c.dofs[q] as usize];
    }
    super::super::element::polar_rotation(
        super::super::element::deformation_gradient_with(&ue, a, grid.h()),
        iterations,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vector kernel on every backend of this CPU gives the bits of the textbook loops.
    fn check<S: Simd4>(s: S) {
        let mut seed = 11u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        let mut mat = || Mat3::from_rows(std::array::from_fn(|_| std::array::from_fn(|_| next())));
        let k: [[Mat3<f64>; 8]; 8] = std::array::from_fn(|_| std::array::from_fn(|_| mat()));
        let r = mat();
        let u: [Vec3<f64>; 8] = std::array::from_fn(|_| Vec3::from_array(mat().m[0]));
        let kc = k.map(|row| row.map(|b| padded_transpose(&b)));
        let x = corner_offsets(0.25);
        let (cu, dt, sc) = (0.3, 0.01, 1.5);
        let got = cell_rhs(s, &kc, &r, &padded_transpose(&r), &x, &u, (cu, dt), sc);
        for i in 0..8 {
            let mut sum = Vec3::default();
            for j in 0..8 {
                let z = (r.transpose() * u[j]) * cu - (r.transpose() * x[j] - x[j]) * dt;
                sum = sum + k[i][j] * z;
            }
            assert_eq!(
                got[i].to_array().map(f64::to_bits),
                ((r * sum) * sc).to_array().map(f64::to_bits)
            );
        }
    }

    #[test]
    fn cell_rhs_matches_the_plain_loops_bitwise() {
        check(Portable);
        #[cfg(target_arch = "x86_64")]
        if let Some(s) = gpumat::simd::Avx2::detect() {
            check(s);
        }
    }
}
