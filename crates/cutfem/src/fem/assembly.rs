//! Assembly of the stiffness matrix and the element forces (thesis sec. 4.4.1-4.4.2).
//!
//! Pattern once, values every step (sec. 4.3.3): the BSR pattern of K (node pairs sharing an
//! active cell) and the gather map (for each stored block, the list of element blocks
//! `(e, i, j)` that sum into it) depend only on the reference grid and are built once.
//! Each step, the values are computed row by row in parallel: a block is the fixed-order sum
//! of its element contributions, so there are no atomics, no races and the result does not
//! depend on the thread count.
//!
//! A step's assembly is three sweeps: one over the cells ([`Assembler::rotations_and_cell_forces`]:
//! rotation `R_e`, four cells at a time, and the eight corotation corner forces while the
//! cell's blocks are at hand), one over the rows (the upper-triangle blocks of `K`, the same
//! blocks of the Newmark matrix `A` while they are in cache, and the force `f_r = m_r g + sum`
//! of the corner forces of the node), then, after the ground forces, the Newmark pass
//! (`Assembler::newmark`), which completes `K` and `A` (each lower block is the transpose of
//! its mirror) while it writes `b`. Every pass works on fixed chunks of rows or cells, writes
//! each value from exactly one task and sums in a fixed order, so the results are
//! bit-identical whatever the number of threads (and equal to those of the plain passes:
//! [`Assembler::assemble_stiffness`], [`crate::fem::sim::newmark_system`]). The hot loops are
//! written once over [`gpumat::simd::Simd4`] and run in AVX2 registers where the CPU has them
//! (same values).
//!
//! Element block (e, i, j): `R_e K_ij(e) R_e^T` (corotation, eq. 4.4.7/4.4.10) plus, for a
//! Dirichlet cell, the Nitsche terms (eq. 4.4.16-4.4.17), added after the rotation as the
//! thesis prescribes. The corotation force of corner `i` is
//! `f_i -= sum_j R_e K_ij (R_e^T x_j - x_j)` (eq. 4.4.6/4.4.10); because `sum_j K_ij = 0`
//! the corner positions may be taken relative to the cell.

mod cells;
mod newmark;

pub use cells::CellWork;
pub(crate) use newmark::fill_newmark;
use newmark::Coefficients;

use super::element::{lanes3, padded_transpose, rotate_add, PaddedBlock, StiffnessTables, OPPOSITE};
pub use super::element::{rotate_block, ElementBlocks};
use super::grid::Grid;
use super::model::Model;
use gpumat::simd::{dispatch, Kernel, Simd4};
use gpumat::{Mat3, Matrix, Scalar, SparseMatrix, SparsityPattern, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

/// Rows per task of the parallel row passes. The chunking never changes a value: each entry,
/// row and cell is computed by one task in a fixed order, whatever the number of threads.
pub(crate) const ROW_CHUNK: usize = 64;
/// Cells per task of the parallel cell pass.
const CELL_CHUNK: usize = 64;

/// Runs `f` on every work item, on the rayon pool when `parallel`, else in order on the
/// calling thread (small problems: waking the pool costs more than their work, as for
/// gpumat's fused loops below [`gpumat::expr::PAR_THRESHOLD`]). Each item writes its own
/// values, so they do not depend on it.
fn for_each_item<T: Send>(parallel: bool, items: Vec<T>, f: impl Fn(T) + Send + Sync) {
    if parallel {
        items.into_par_iter().for_each(f);
    } else {
        items.into_iter().for_each(f);
    }
}

/// The values of a sparse matrix shared by parallel tasks that write disjoint entries
/// ([`Assembler::assemble_stiffness`]).
#[derive(Clone, Copy)]
struct EntryWriter(*mut Mat3<f64>, usize);

// SAFETY: the pointer is only dereferenced through `write`/`read`, whose callers guarantee
// that no entry is written by two tasks or read while written (see their call sites).
unsafe impl Send for EntryWriter {}
// SAFETY: as above.
unsafe impl Sync for EntryWriter {}

impl EntryWriter {
    /// # Safety
    /// `k` is written by no other task and read by none while this runs.
    #[inline(always)]
    unsafe fn write(&self, k: usize, v: Mat3<f64>) {
        assert!(k < self.1);
        // SAFETY: in bounds (checked) and exclusive (the caller's contract).
        unsafe { self.0.add(k).write(v) }
    }
    /// # Safety
    /// `k` is written by no task while this runs.
    #[inline(always)]
    unsafe fn read(&self, k: usize) -> Mat3<f64> {
        assert!(k < self.1);
        // SAFETY: in bounds (checked), initialized and not written concurrently (contract).
        unsafe { self.0.add(k).read() }
    }
}

/// Material and boundary constants of one assembly.
#[derive(Clone, Copy, Debug)]
pub struct Material {
    /// Lame lambda
    pub lambda: f64,
    /// Lame mu
    pub mu: f64,
    /// Nitsche penalty eta
    pub eta: f64,
}

/// The pattern, gather maps and tables, built once per grid.
#[derive(Clone, Debug)]
pub struct Assembler {
    pattern: Arc<SparsityPattern>,
    /// contributions of each stored block: `contrib[contrib_ptr[k]..contrib_ptr[k+1]]`
    contrib_ptr: Vec<u32>,
    /// `(cell, 8 i + j)`
    contrib: Vec<(u32, u8)>,
    /// the diagonal entry of each row: the row's entries from it on are computed, the ones
    /// before it (below the diagonal) are the transposes of their mirrors
    diag: Vec<u32>,
    /// the entry of `(c, r)` for each entry `(r, c)`
    mirror: Vec<u32>,
    /// cells touching each dof: `node_cells[node_ptr[d]..node_ptr[d+1]]` as `(cell, corner)`
    node_ptr: Vec<u32>,
    node_cells: Vec<(u32, u8)>,
    tables: StiffnessTables,
}

impl Assembler {
    /// Builds the BSR pattern and gather maps of `grid`.
    pub fn new(grid: &Grid) -> Self {
        let n = grid.dofs();
        let entries = grid.cells.iter().flat_map(|c| {
            c.dofs
                .iter()
                .flat_map(move |&a| c.dofs.iter().map(move |&b| (a as usize, b as usize)))
        });
        let pattern = SparsityPattern::from_entries(n, n, entries);
        // Gather map: count, then fill in cell order (deterministic order of summation).
        // Opposite corners (`i ^ j = 7`) share no quadrature corner where both basis
        // gradients are nonzero: their stiffness and Nitsche blocks are exactly zero and are
        // left out (adding a zero block to a sum that starts at +0 never changes it).
        let mut count = vec![0u32; pattern.nnz() + 1];
        let mut slot = Vec::with_capacity(grid.cells.len() * 64);
        for c in &grid.cells {
            for i in 0..8 {
                for j in 0..8 {
                    if i ^ j == OPPOSITE {
                        slot.push(u32::MAX);
                        continue;
                    }
                    let k = pattern
                        .find(c.dofs[i] as usize, c.dofs[j] as usize)
                        .expect("pattern holds every cell pair");
                    count[k + 1] += 1;
                    slot.push(k as u32);
                }
            }
        }
        for k in 0..pattern.nnz() {
            count[k + 1] += count[k];
        }
        let contrib_ptr = count.clone();
        let mut next = count;
        let mut contrib = vec![(0u32, 0u8); contrib_ptr[pattern.nnz()] as usize];
        for (e, chunk) in slot.chunks(64).enumerate() {
            for (ij, &k) in chunk.iter().enumerate().filter(|(_, &k)| k != u32::MAX) {
                contrib[next[k as usize] as usize] = (e as u32, ij as u8);
                next[k as usize] += 1;
            }
        }
        let mut ncount = vec![0u32; n + 1];
        for c in &grid.cells {
            for &d in &c.dofs {
                ncount[d as usize + 1] += 1;
            }
        }
        for d in 0..n {
            ncount[d + 1] += ncount[d];
        }
        let node_ptr = ncount.clone();
        let mut nnext = ncount;
        let mut node_cells = vec![(0u32, 0u8); grid.cells.len() * 8];
        for (e, c) in grid.cells.iter().enumerate() {
            for (q, &d) in c.dofs.iter().enumerate() {
                node_cells[nnext[d as usize] as usize] = (e as u32, q as u8);
                nnext[d as usize] += 1;
            }
        }
        // the diagonal of each row and the mirror of each entry
        let mut diag = Vec::with_capacity(n);
        let mut mirror = vec![0u32; pattern.nnz()];
        for r in 0..n {
            diag.push(pattern.find(r, r).expect("every dof is in a cell") as u32);
            for kk in pattern.row_range(r) {
                let c = pattern.col_idx()[kk] as usize;
                mirror[kk] = pattern.find(c, r).expect("cell pairs give a symmetric pattern") as u32;
            }
        }
        Self {
            pattern,
            contrib_ptr,
            contrib,
            diag,
            mirror,
            node_ptr,
            node_cells,
            tables: StiffnessTables::new(grid.h()),
        }
    }

    /// The shared BSR pattern.
    pub fn pattern(&self) -> &Arc<SparsityPattern> {
        &self.pattern
    }
    /// The per-corner stiffness tables.
    pub fn tables(&self) -> &StiffnessTables {
        &self.tables
    }

    /// The element blocks of `grid` for material `m`.
    pub fn element_blocks(&self, grid: &Grid, m: &Material) -> ElementBlocks {
        ElementBlocks::new(&self.tables, grid, m.lambda, m.mu)
    }

    /// Writes the stiffness values into `k` (whose pattern must be [`Assembler::pattern`]).
    /// `rotations[e]` is the corotation of cell `e` (or `None` for plain linear elasticity);
    /// `dirichlet[e]` marks cells with Nitsche boundary terms; `scale[e]` multiplies cell `e`'s
    /// Young's modulus (a heterogeneous material, `None`: homogeneous). The Nitsche traction
    /// terms scale with it, the penalty does not.
    #[allow(clippy::too_many_arguments)]
    pub fn assemble_stiffness(
        &self,
        grid: &Grid,
        m: &Material,
        blocks: &ElementBlocks,
        rotations: Option<&[Mat3<f64>]>,
        dirichlet: &[bool],
        scale: Option<&[f64]>,
        k: &mut SparseMatrix<Mat3<f64>>,
    ) {
        let rt: Vec<PaddedBlock> =
            rotations.map_or_else(Vec::new, |r| r.par_iter().map(padded_transpose).collect());
        let cells = Cells {
            grid,
            m,
            blocks,
            rotations: rotations.map(|r| (r, &rt[..])),
            dirichlet,
            scale,
        };
        self.assemble_values(&cells, k, None);
    }

    /// A step's stiffness values and forces in one row sweep: the blocks of `k` on and above
    /// the diagonal (as [`Assembler::assemble_stiffness`]), the same blocks of the Newmark
    /// matrix `a` of `model` (while the row's blocks are in cache) and `f_r = m_r g + sum` of
    /// the corner forces of node `r` (its cells in [`Assembler::cells_of`] order). The blocks
    /// below the diagonal and `b` are left to the step's Newmark pass ([`Assembler::newmark`]),
    /// which mirrors them. `corotation`: the rotations and the cell data of
    /// [`Assembler::rotations_and_cell_forces`] (`None`: no corotation, gravity only).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn assemble_upper_with_forces(
        &self,
        grid: &Grid,
        m: &Material,
        blocks: &ElementBlocks,
        corotation: Option<(&[Mat3<f64>], &CellWork)>,
        dirichlet: &[bool],
        scale: Option<&[f64]>,
        k: &mut SparseMatrix<Mat3<f64>>,
        mass: &Matrix<f64>,
        gravity: Vec3<f64>,
        f: &mut Matrix<Vec3<f64>>,
        model: &Model,
        a: &mut SparseMatrix<Mat3<f64>>,
    ) {
        let cells = Cells {
            grid,
            m,
            blocks,
            rotations: corotation.map(|(r, w)| (r, &w.rt[..])),
            dirichlet,
            scale,
        };
        let forces = Forces {
            mass: mass.as_slice(),
            gravity,
            cell_forces: corotation.map(|(_, w)| &w.forces[..]),
            newmark: Coefficients::new(model),
        };
        assert!(
            Arc::ptr_eq(a.pattern(), &self.pattern) && a.batches() == 1,
            "cutfem: Newmark matrix has a foreign pattern"
        );
        let step = (forces, f.as_mut_slice(), a.batch_values_mut(0));
        self.assemble_values(&cells, k, Some(step));
    }

    /// The upper blocks (and a step's forces and upper Newmark blocks, when given; else the
    /// lower blocks too, by mirroring).
    fn assemble_values(&self, c: &Cells<'_>, k: &mut SparseMatrix<Mat3<f64>>, step: Option<StepOutput<'_>>) {
        assert!(
            Arc::ptr_eq(k.pattern(), &self.pattern),
            "cutfem: stiffness matrix has a foreign pattern"
        );
        let (n, cells) = (self.pattern.rows(), c.grid.cells.len());
        if let Some((r, rt)) = c.rotations {
            assert!(
                r.len() == cells && rt.len() == cells,
                "cutfem: one rotation per cell"
            );
        }
        // K is symmetric (every element block satisfies K_ji = K_ij^T, rotated or not, and so
        // do the Nitsche terms): compute the upper triangle, mirror the rest.
        let values = k.batch_values_mut(0);
        let chunks = self.pattern.split_rows_mut(values, ROW_CHUNK);
        let parallel = self.parallel();
        let Some((fo, f, a)) = step else {
            for_each_item(parallel, chunks, |(r0, vals)| self.upper_rows(c, r0, vals));
            self.mirror_lower(values);
            return;
        };
        assert!(
            f.len() == n && fo.mass.len() == n,
            "cutfem: forces of another size"
        );
        assert!(
            fo.cell_forces.map_or(true, |cf| cf.len() == cells),
            "cutfem: corner forces per cell"
        );
        let rp = self.pattern.row_ptr();
        let items: Vec<_> = chunks
            .into_iter()
            .zip(self.pattern.split_rows_mut(a, ROW_CHUNK))
            .zip(f.chunks_mut(ROW_CHUNK))
            .collect();
        for_each_item(parallel, items, |(((r0, vals), (_, av)), fc)| {
            self.upper_rows(c, r0, vals);
            gpumat::simd::with_avx2(
                #[inline(always)]
                || {
                    let (base, nw) = (rp[r0], &fo.newmark);
                    for (o, out) in fc.iter_mut().enumerate() {
                        let r = r0 + o;
                        *out = self.node_force(&fo, r);
                        let d = self.diag[r] as usize;
                        for kk in d..rp[r + 1] {
                            let m = if kk == d { nw.diagonal(fo.mass[r]) } else { nw.off };
                            av[kk - base] = m.add(vals[kk - base].scale(nw.ck));
                        }
                    }
                },
            )
        });
    }

    /// Whether the passes of this pattern run on the rayon pool (see [`for_each_item`]).
    fn parallel(&self) -> bool {
        self.pattern.nnz() >= gpumat::expr::PAR_THRESHOLD
    }

    /// Each block below the diagonal of `values` from its mirror above it, in place.
    fn mirror_lower(&self, values: &mut [Mat3<f64>]) {
        let (n, rp) = (self.pattern.rows(), self.pattern.row_ptr());
        let out = EntryWriter(values.as_mut_ptr(), values.len());
        for_each_item(self.parallel(), (0..n.div_ceil(ROW_CHUNK)).collect(), |ci| {
            for r in ci * ROW_CHUNK..((ci + 1) * ROW_CHUNK).min(n) {
                for kk in rp[r]..self.diag[r] as usize {
                    // SAFETY: the `kk` are distinct entries below the diagonal, each written by
                    // one task; their mirrors lie on or above it, written in the finished pass
                    // before this one and only read here, so no entry is both read and written.
                    unsafe { out.write(kk, out.read(self.mirror[kk] as usize).transpose()) };
                }
            }
        });
    }

    /// `m_r g` plus the corner forces of node `r`, summed in [`Assembler::cells_of`] order.
    #[inline]
    fn node_force(&self, fo: &Forces<'_>, r: usize) -> Vec3<f64> {
        let mut acc = gpumat::Scalar::scale(fo.gravity, fo.mass[r]);
        if let Some(cf) = fo.cell_forces {
            for &(e, q) in self.cells_of(r) {
                acc = acc + cf[e as usize][q as usize];
            }
        }
        acc
    }

    /// The upper blocks (from each row's diagonal on) of the rows from `r0` into `vals` (the
    /// values of those rows), in AVX2 registers where the CPU has them (the same operations
    /// in the same order: the values do not depend on it).
    fn upper_rows(&self, c: &Cells<'_>, r0: usize, vals: &mut [Mat3<f64>]) {
        struct Rows<'a> {
            asm: &'a Assembler,
            c: &'a Cells<'a>,
            r0: usize,
            vals: &'a mut [Mat3<f64>],
        }
        impl Kernel for Rows<'_> {
            type Output = ();
            #[inline(always)]
            fn run<S: Simd4>(self, s: S) {
                self.asm.upper_rows_with(s, self.c, self.r0, self.vals)
            }
        }
        dispatch(Rows {
            asm: self,
            c,
            r0,
            vals,
        })
    }

    #[inline(always)]
    fn upper_rows_with<S: Simd4>(&self, s: S, c: &Cells<'_>, r0: usize, vals: &mut [Mat3<f64>]) {
        let rp = self.pattern.row_ptr();
        let (base, r1) = (rp[r0], (r0 + ROW_CHUNK).min(self.pattern.rows()));
        // plain loops (no iterator adapters), so that everything inlines into this function
        // and is compiled with its target features
        macro_rules! rows {
            ($block:expr) => {
                for r in r0..r1 {
                    for kk in self.diag[r] as usize..rp[r + 1] {
                        vals[kk - base] = $block(kk);
                    }
                }
            };
        }
        match (c.rotations, c.scale) {
            (Some((rot, rt)), None) => rows!(|kk| self.rotated_block::<S, false>(s, c, rot, rt, &[], kk)),
            (Some((rot, rt)), Some(sc)) => rows!(|kk| self.rotated_block::<S, true>(s, c, rot, rt, sc, kk)),
            (None, sc) => rows!(|kk| self.plain_block(c, sc, kk)),
        }
    }

    /// The element blocks `(cell, 8 i + j)` summing into entry `kk`, in cell order.
    #[inline(always)]
    fn contributions(&self, kk: usize) -> &[(u32, u8)] {
        &self.contrib[self.contrib_ptr[kk] as usize..self.contrib_ptr[kk + 1] as usize]
    }

    /// The Nitsche terms of element block `(e, i, j)`, Young's modulus scaled by `se`.
    #[inline(always)]
    fn nitsche(&self, c: &Cells<'_>, e: usize, i: usize, j: usize, se: f64) -> Mat3<f64> {
        let ci = &c.grid.cells[e].integrals;
        let n = Vec3::from_array(ci.normal);
        self.tables
            .nitsche_block(&ci.boundary, n, i, j, c.m.lambda * se, c.m.mu * se, c.m.eta)
    }

    /// Entry `kk` without rotation: the fixed-order sum of its element blocks (scaled by
    /// `scale[e]`, plus the Nitsche terms of Dirichlet cells).
    #[inline(always)]
    fn plain_block(&self, c: &Cells<'_>, scale: Option<&[f64]>, kk: usize) -> Mat3<f64> {
        let mut acc = Mat3::default();
        for &(e, ij) in self.contributions(kk) {
            let (e, i, j) = (e as usize, (ij / 8) as usize, (ij % 8) as usize);
            let mut b = c.blocks.get(e, i, j);
            let se = scale.map_or(1.0, |s| s[e]);
            if se != 1.0 {
                b = b * se;
            }
            if c.dirichlet[e] {
                b = b + self.nitsche(c, e, i, j, se);
            }
            acc = acc + b;
        }
        acc
    }

    /// Entry `kk` of the corotated stiffness: the fixed-order sum of its element blocks
    /// `R_e (s_e K_ij) R_e^T` plus the Nitsche terms of Dirichlet cells ([`rotate_add`]).
    #[inline(always)]
    fn rotated_block<S: Simd4, const SCALE: bool>(
        &self,
        s: S,
        c: &Cells<'_>,
        rot: &[Mat3<f64>],
        rt: &[PaddedBlock],
        scale: &[f64],
        kk: usize,
    ) -> Mat3<f64> {
        let mut acc = [s.splat(0.0); 3];
        for &(e, ij) in self.contributions(kk) {
            let (e, i, j) = (e as usize, (ij / 8) as usize, (ij % 8) as usize);
            let b = &c.blocks.cell(e)[i][j];
            let (r, rt) = (&rot[e], &rt[e]);
            if SCALE || c.dirichlet[e] {
                // the rarer cells: scaled blocks, Nitsche terms
                let se = if SCALE { scale[e] } else { 1.0 };
                let b = if se != 1.0 { *b * se } else { *b };
                let nitsche = c.dirichlet[e].then(|| self.nitsche(c, e, i, j, se));
                rotate_add(s, &mut acc, r, rt, &b, nitsche.as_ref());
            } else {
                rotate_add(s, &mut acc, r, rt, b, None);
            }
        }
        Mat3 {
            m: [lanes3(s, acc[0]), lanes3(s, acc[1]), lanes3(s, acc[2])],
        }
    }

    /// Lumped mass per dof: `density * sum_e w_v(e, i)` (thesis eq. 2.5.14 lumped, sec. 4.4.2).
    pub fn lumped_mass(&self, grid: &Grid, density: f64) -> Matrix<f64> {
        let n = grid.dofs();
        Matrix::from_fn(n, 1, 1, |dof, _, _| {
            let mut s = 0.0;
            for &(e, q) in &self.node_cells[self.node_ptr[dof] as usize..self.node_ptr[dof + 1] as usize] {
                s += grid.cells[e as usize].integrals.volume[q as usize];
            }
            density * s
        })
    }

    /// The cells touching a dof, as `(cell, corner)`.
    pub fn cells_of(&self, dof: usize) -> &[(u32, u8)] {
        &self.node_cells[self.node_ptr[dof] as usize..self.node_ptr[dof + 1] as usize]
    }
}

/// What the stiffness passes read per cell: `rotations` is `(R_e, padded R_e^T)`.
struct Cells<'a> {
    grid: &'a Grid,
    m: &'a Material,
    blocks: &'a ElementBlocks,
    rotations: Option<(&'a [Mat3<f64>], &'a [PaddedBlock])>,
    dirichlet: &'a [bool],
    scale: Option<&'a [f64]>,
}

/// What a step's row sweep reads for the node forces and Newmark blocks, and the forces and
/// values of `A` it writes.
type StepOutput<'a> = (Forces<'a>, &'a mut [Vec3<f64>], &'a mut [Mat3<f64>]);

/// What the node forces and Newmark blocks of [`Assembler::assemble_upper_with_forces`] read.
struct Forces<'a> {
    mass: &'a [f64],
    gravity: Vec3<f64>,
    cell_forces: Option<&'a [[Vec3<f64>; 8]]>,
    newmark: Coefficients,
}
