//! Assembly of the stiffness matrix and the element forces (thesis sec. 4.4.1-4.4.2).
//!
//! Pattern once, values every step (sec. 4.3.3): the BSR pattern of K (node pairs sharing an
//! active cell) and the gather map (for each node, its cells in cell order and, for each of
//! them, where its element blocks `(i, j)` go among the node's row of blocks) depend only on
//! the reference grid and are built once. Each step, the values are computed row by row in
//! parallel: a block is the fixed-order sum of its element contributions (in cell order), so
//! there are no atomics, no races and the result does not depend on the thread count.
//!
//! Element block (e, i, j): `R_e K_ij(e) R_e^T` (corotation, eq. 4.4.7/4.4.10) plus, for a
//! Dirichlet cell, the Nitsche terms (eq. 4.4.16-4.4.17), added after the rotation as the
//! thesis prescribes. The corotation force of corner `i` is
//! `f_i -= sum_j R_e K_ij (R_e^T x_j - x_j)` (eq. 4.4.6/4.4.10); because `sum_j K_ij = 0`
//! the corner positions may be taken relative to the cell.
//!
//! A time step needs the Newmark matrix `A = cm M + ck K` and right-hand side
//! `b = cm M u + cu K u + cv M v + dt f` ([`newmark`]), not `K` itself: writing `K` and
//! reading it again for `b` and the lower half of `A` would double the memory traffic of the
//! assembly. A step's assembly is three sweeps, run together in one parallel pass over work
//! units of consecutive cells and rows ([`pipeline`], [`Assembler::assemble_step`]):
//! 1. over the cells ([`cells`]): the rotation `R_e`, four cells at a time, and, while the
//!    cell's blocks are at hand, its share of `b` at its corners: `cu K u` and `dt` times the
//!    corotation force in one product per cell;
//! 2. over the rows ([`step`]): the blocks of `A` on and above the diagonal, each from the
//!    block of `K` summed in registers (and stored too where the caller keeps `K`, as the
//!    adjoint's recomputed steps do), `f = M g` and `b` without `dt f`;
//! 3. the blocks of `A` (and `K`) below the diagonal as the transposes of their mirrors.
//!
//! After the external and ground forces, a last pass adds `dt f` to `b`.
//!
//! Every pass works on fixed chunks or units of rows or cells, writes each value from exactly
//! one task and sums in a fixed order, so the results are bit-identical whatever the number of
//! threads; `K` and `A` are those of the plain passes ([`Assembler::assemble_stiffness`],
//! [`crate::fem::sim::newmark_system`]) bit for bit, `b` equals theirs up to rounding (it
//! sums the same terms in another order). The hot loops are written once over
//! [`gpumat::simd::Simd4`] and run in AVX2 registers where the CPU has them (same values).

mod cells;
pub mod mass;
mod mirror;
mod newmark;
mod pipeline;
mod step;

pub(crate) use cells::CellWork;
pub use newmark::newmark_system;
pub(crate) use step::{StepCells, StepOutput, StepState};

use super::element::{lanes3, padded_transpose, rotate_add, PaddedBlock, StiffnessTables};
pub use super::element::{rotate_block, ElementBlocks};
use super::grid::Grid;
use super::sim::NitscheFace;
use gpumat::simd::{dispatch, Kernel, Simd4};
use gpumat::{Mat3, Matrix, SparseMatrix, SparsityPattern};
use rayon::prelude::*;
use std::sync::Arc;

/// Rows per task of the parallel row passes. The chunking never changes a value: each entry,
/// row and cell is computed by one task in a fixed order, whatever the number of threads.
pub(crate) const ROW_CHUNK: usize = 64;
/// The most blocks on and above the diagonal of a row: a node and the 13 neighbours after it
/// in its 3x3x3 neighbourhood.
const MAX_UPPER: usize = 14;
/// [`Assembler`]'s mark of a corner pair with no block of its own in the row sweep.
const NO_BLOCK: u8 = u8::MAX;

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

/// Material and boundary constants of one assembly.
#[derive(Clone, Copy, Debug)]
pub struct Material {
    /// Lame lambda
    pub lambda: f64,
    /// Lame mu
    pub mu: f64,
    /// the fixed part of the Nitsche penalty ([`crate::fem::NitschePenalty::terms`])
    pub eta: f64,
    /// the part of the Nitsche penalty per unit of `lambda + 2 mu`
    pub eta_per_modulus: f64,
    /// the grid element
    pub element: super::element::Element,
    /// the stiffness of springs replacing the Nitsche hold ([`crate::fem::Model::support`])
    pub support: Option<f64>,
}

impl Material {
    /// The Nitsche penalty of a held cell whose Young's modulus is scaled by `se`, with the
    /// cell's [`NitscheFace::penalty_factor`] `factor` (which scales only the part per modulus).
    #[inline(always)]
    pub fn penalty(&self, se: f64, factor: f64) -> f64 {
        self.eta + self.eta_per_modulus * (self.lambda + 2.0 * self.mu) * se * factor
    }
    /// Block `(i, j)` of the held surface `f` in a cell whose Young's modulus is scaled by
    /// `se`: the Nitsche block ([`NitscheFace::block`]), or with an elastic support its springs
    /// `k P_ij I` instead (the Nitsche block without its traction terms and with `k` for the
    /// penalty; the fixture's springs do not scale with the material).
    #[inline(always)]
    pub fn held_block(&self, f: &NitscheFace, i: usize, j: usize, se: f64) -> Mat3<f64> {
        match self.support {
            Some(k) => f.block(i, j, 0.0, 0.0, k),
            None => f.block(
                i,
                j,
                self.lambda * se,
                self.mu * se,
                self.penalty(se, f.penalty_factor),
            ),
        }
    }
}

/// The pattern, gather maps and tables, built once per grid.
#[derive(Clone, Debug)]
pub struct Assembler {
    pattern: Arc<SparsityPattern>,
    /// the diagonal entry of each row: the row's entries from it on are computed, the ones
    /// before it (below the diagonal) are the transposes of their mirrors
    diag: Vec<u32>,
    /// the entry of `(c, r)` for each entry `(r, c)`
    mirror: Vec<u32>,
    /// cells touching each dof: `node_cells[node_ptr[d]..node_ptr[d+1]]` as `(cell, corner)`,
    /// in cell order
    node_ptr: Vec<u32>,
    node_cells: Vec<(u32, u8)>,
    /// per entry of `node_cells`, `(cell e, corner i)` of node `r`: for each corner `j`, the
    /// place of block `(r, dofs[j])` among the row's blocks from the diagonal on, or
    /// [`NO_BLOCK`] where that block lies below the diagonal
    upper: Vec<[u8; 8]>,
    /// the corner dofs of each cell (the cells' `dofs`, packed for the cell sweep)
    cell_dofs: Vec<[u32; 8]>,
    /// the work units of a step's pass ([`pipeline`])
    units: pipeline::Units,
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
            assert!(
                pattern.row_range(r).end - diag[r] as usize <= MAX_UPPER,
                "cutfem: a node with more than 13 neighbours above it"
            );
            for kk in pattern.row_range(r) {
                let c = pattern.col_idx()[kk] as usize;
                mirror[kk] = pattern.find(c, r).expect("cell pairs give a symmetric pattern") as u32;
            }
        }
        // The gather map of the row sweep.
        let upper = (0..n)
            .flat_map(|r| {
                node_cells[node_ptr[r] as usize..node_ptr[r + 1] as usize]
                    .iter()
                    .map(move |&ec| (r, ec))
            })
            .map(|(r, (e, _))| {
                let dofs = &grid.cells[e as usize].dofs;
                std::array::from_fn(|j| {
                    let c = dofs[j] as usize;
                    if c < r {
                        return NO_BLOCK;
                    }
                    let kk = pattern.find(r, c).expect("pattern holds every cell pair");
                    (kk - diag[r] as usize) as u8
                })
            })
            .collect();
        let units = pipeline::Units::new(grid.cells.len(), &pattern, &diag, &node_ptr, &node_cells);
        Self {
            pattern,
            diag,
            mirror,
            node_ptr,
            node_cells,
            upper,
            cell_dofs: grid.cells.iter().map(|c| c.dofs).collect(),
            units,
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
        ElementBlocks::new(grid, m.element, m.lambda, m.mu)
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
        dirichlet: &[Option<NitscheFace>],
        scale: Option<&[f64]>,
        k: &mut SparseMatrix<Mat3<f64>>,
    ) {
        let c = (grid, m, blocks, rotations, dirichlet, scale);
        self.stiffness_values(c, k, self.parallel());
    }

    /// [`Assembler::assemble_stiffness`] on the calling thread alone (never waits on the rayon
    /// pool: safe inside a lazy initialization that a rayon job may reach).
    pub(crate) fn assemble_stiffness_serial(&self, c: StiffnessInputs<'_>, k: &mut SparseMatrix<Mat3<f64>>) {
        self.stiffness_values(c, k, false);
    }

    fn stiffness_values(&self, c: StiffnessInputs<'_>, k: &mut SparseMatrix<Mat3<f64>>, parallel: bool) {
        let (grid, m, blocks, rotations, dirichlet, scale) = c;
        let rt: Vec<PaddedBlock> = match rotations {
            Some(r) if parallel => r.par_iter().map(padded_transpose).collect(),
            Some(r) => r.iter().map(padded_transpose).collect(),
            None => Vec::new(),
        };
        let cells = Cells {
            grid,
            m,
            blocks,
            rotations: rotations.map(|_| &rt[..]),
            cell_base: 0,
            dirichlet,
            scale,
        };
        self.assemble_values(&cells, k, parallel);
    }

    /// All blocks of `k`: the upper ones by the row sweep, the lower ones by mirroring, on
    /// the rayon pool when `parallel`.
    fn assemble_values(&self, c: &Cells<'_>, k: &mut SparseMatrix<Mat3<f64>>, parallel: bool) {
        assert!(
            Arc::ptr_eq(k.pattern(), &self.pattern) && k.batches() == 1,
            "cutfem: stiffness matrix has a foreign pattern"
        );
        c.check();
        // K is symmetric (every element block satisfies K_ji = K_ij^T, rotated or not, and so
        // do the Nitsche terms): compute the upper triangle, mirror the rest.
        let values = k.batch_values_mut(0);
        let rp = self.pattern.row_ptr();
        let chunks = self.pattern.split_rows_mut(values, ROW_CHUNK);
        let n = self.pattern.rows();
        for_each_item(parallel, chunks, |(r0, vals)| {
            let r1 = (r0 + ROW_CHUNK).min(n);
            self.upper_rows(c, r0..r1, Values { base: rp[r0], vals })
        });
        self.mirror_lower(parallel, values);
    }

    /// Whether the passes of this pattern run on the rayon pool (see [`for_each_item`]).
    fn parallel(&self) -> bool {
        self.pattern.nnz() >= gpumat::expr::PAR_THRESHOLD
    }

    /// The upper blocks (from each row's diagonal on) of the rows `rows` into `sink`, in
    /// AVX2 registers where the CPU has them (the same operations in the same order: the
    /// values do not depend on it).
    fn upper_rows<K: RowSink>(&self, c: &Cells<'_>, rows: std::ops::Range<usize>, sink: K) {
        struct Rows<'a, K> {
            asm: &'a Assembler,
            c: &'a Cells<'a>,
            rows: std::ops::Range<usize>,
            sink: K,
        }
        impl<K: RowSink> Kernel for Rows<'_, K> {
            type Output = ();
            #[inline(always)]
            fn run<S: Simd4>(self, s: S) {
                self.asm.upper_rows_with(s, self.c, self.rows, self.sink)
            }
        }
        dispatch(Rows {
            asm: self,
            c,
            rows,
            sink,
        })
    }

    #[inline(always)]
    fn upper_rows_with<S: Simd4, K: RowSink>(
        &self,
        s: S,
        c: &Cells<'_>,
        rows: std::ops::Range<usize>,
        mut sink: K,
    ) {
        let rp = self.pattern.row_ptr();
        // everything called here is inlined into this function and compiled with its target
        // features
        for r in rows {
            let d = self.diag[r] as usize;
            let len = rp[r + 1] - d;
            sink.row_start(r);
            match (c.rotations, c.scale) {
                (Some(rt), None) => {
                    let acc = self.rotated_row::<S, false, K>(s, c, rt, &[], r, &mut sink);
                    for (o, a) in acc.iter().enumerate().take(len) {
                        sink.block(r, d + o, o == 0, Mat3::from_rows(a.map(|v| lanes3(s, v))));
                    }
                }
                (Some(rt), Some(sc)) => {
                    let acc = self.rotated_row::<S, true, K>(s, c, rt, sc, r, &mut sink);
                    for (o, a) in acc.iter().enumerate().take(len) {
                        sink.block(r, d + o, o == 0, Mat3::from_rows(a.map(|v| lanes3(s, v))));
                    }
                }
                (None, sc) => {
                    let acc = self.plain_row(c, sc, r, &mut sink);
                    for (o, a) in acc.iter().enumerate().take(len) {
                        sink.block(r, d + o, o == 0, *a);
                    }
                }
            }
            sink.row_done(r);
        }
    }

    /// The cells of row `r` with, for each, where its blocks `(i, j)` go among the row's blocks
    /// from the diagonal on ([`Assembler::upper`]).
    #[inline(always)]
    fn row_cells(&self, r: usize) -> (&[(u32, u8)], &[[u8; 8]]) {
        let range = self.node_ptr[r] as usize..self.node_ptr[r + 1] as usize;
        (&self.node_cells[range.clone()], &self.upper[range])
    }

    /// The held surface's terms of element block `(e, i, j)`, Young's modulus scaled by `se`
    /// ([`Material::held_block`]).
    #[inline(always)]
    fn nitsche(&self, c: &Cells<'_>, e: usize, i: usize, j: usize, se: f64) -> Mat3<f64> {
        match &c.dirichlet[e] {
            Some(f) => c.m.held_block(f, i, j, se),
            None => Mat3::default(),
        }
    }

    /// The blocks of row `r` from the diagonal on without rotation: each the sum of its
    /// element blocks (scaled by `scale[e]`, plus the Nitsche terms of Dirichlet cells) in
    /// cell order.
    #[inline(always)]
    fn plain_row<K: RowSink>(
        &self,
        c: &Cells<'_>,
        scale: Option<&[f64]>,
        r: usize,
        sink: &mut K,
    ) -> [Mat3<f64>; MAX_UPPER] {
        let mut acc = [Mat3::default(); MAX_UPPER];
        let (cells, upper) = self.row_cells(r);
        for (&(e, i), up) in cells.iter().zip(upper) {
            let (e, i) = (e as usize, i as usize);
            sink.cell(e, i);
            let se = scale.map_or(1.0, |s| s[e]);
            for (j, &o) in up.iter().enumerate() {
                if o == NO_BLOCK {
                    continue;
                }
                let mut b = c.blocks.get(e, i, j);
                if se != 1.0 {
                    b = b * se;
                }
                if c.dirichlet[e].is_some() {
                    b = b + self.nitsche(c, e, i, j, se);
                }
                acc[o as usize] = acc[o as usize] + b;
            }
        }
        acc
    }

    /// The blocks of row `r` from the diagonal on of the corotated stiffness, each the sum of
    /// its element blocks `R_e (s_e K_ij) R_e^T` plus the Nitsche terms of Dirichlet cells
    /// ([`rotate_add`]) in cell order, as rows of vectors.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn rotated_row<S: Simd4, const SCALE: bool, K: RowSink>(
        &self,
        s: S,
        c: &Cells<'_>,
        rt: &[PaddedBlock],
        scale: &[f64],
        r: usize,
        sink: &mut K,
    ) -> [[S::V; 3]; MAX_UPPER] {
        let mut acc = [[s.splat(0.0); 3]; MAX_UPPER];
        let (cells, upper) = self.row_cells(r);
        for (&(e, i), up) in cells.iter().zip(upper) {
            let (e, i) = (e as usize, i as usize);
            sink.cell(e, i);
            // the blocks as padded columns: the table the cell sweep reads too
            let (bs, rt) = (&c.blocks.cell_columns(e)[i], &rt[e - c.cell_base]);
            if SCALE || c.dirichlet[e].is_some() {
                // the rarer cells: scaled blocks, Nitsche terms
                let se = if SCALE { scale[e] } else { 1.0 };
                for (j, &o) in up.iter().enumerate() {
                    if o != NO_BLOCK {
                        let b = if se != 1.0 {
                            bs[j].map(|l| l.map(|x| x * se))
                        } else {
                            bs[j]
                        };
                        let nitsche = c.dirichlet[e].is_some().then(|| self.nitsche(c, e, i, j, se));
                        rotate_add(s, &mut acc[o as usize], rt, &b, nitsche.as_ref());
                    }
                }
            } else {
                for (j, &o) in up.iter().enumerate() {
                    if o != NO_BLOCK {
                        rotate_add(s, &mut acc[o as usize], rt, &bs[j], None);
                    }
                }
            }
        }
        acc
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

/// The inputs of [`Assembler::assemble_stiffness`]: grid, material, element blocks, rotations,
/// Dirichlet cells, stiffness scale.
pub(crate) type StiffnessInputs<'a> = (
    &'a Grid,
    &'a Material,
    &'a ElementBlocks,
    Option<&'a [Mat3<f64>]>,
    &'a [Option<NitscheFace>],
    Option<&'a [f64]>,
);

/// What the stiffness passes read per cell.
struct Cells<'a> {
    grid: &'a Grid,
    m: &'a Material,
    blocks: &'a ElementBlocks,
    /// the padded transposed rotations (`None`: no corotation) of the cells from `cell_base`
    /// on
    rotations: Option<&'a [PaddedBlock]>,
    /// the first cell of `rotations` (a step's pass hands each unit of rows the finished
    /// rotations only, see [`pipeline`])
    cell_base: usize,
    dirichlet: &'a [Option<NitscheFace>],
    scale: Option<&'a [f64]>,
}

impl Cells<'_> {
    /// Checks the sizes of the per-cell data.
    fn check(&self) {
        let nc = self.grid.cells.len();
        if let Some(rt) = self.rotations {
            assert!(self.cell_base + rt.len() <= nc, "cutfem: one rotation per cell");
        }
        assert!(
            self.dirichlet.len() == nc && self.scale.map_or(true, |s| s.len() == nc),
            "cutfem: cell data of another size"
        );
    }
}

/// Where the row sweep ([`Assembler::upper_rows`]) puts the blocks it computes. The methods
/// are inlined into the sweep's vector code. Per row `r`: `row_start`, `cell` for each cell
/// of the row (corner `i` of cell `e`, in [`Assembler::cells_of`] order), `block` for each
/// block from the diagonal on, `row_done`.
trait RowSink {
    /// Before row `r`.
    fn row_start(&mut self, r: usize);
    /// Cell `e` of the row, whose corner `i` is the row's node.
    fn cell(&mut self, e: usize, i: usize);
    /// Block `kk` of row `r`, on (`diagonal`) or above the diagonal.
    fn block(&mut self, r: usize, kk: usize, diagonal: bool, k: Mat3<f64>);
    /// After the blocks of row `r`.
    fn row_done(&mut self, r: usize);
}

/// The values of `K` of the rows from the one whose first entry is `base`.
struct Values<'a> {
    base: usize,
    vals: &'a mut [Mat3<f64>],
}

impl RowSink for Values<'_> {
    #[inline(always)]
    fn block(&mut self, _r: usize, kk: usize, _diagonal: bool, k: Mat3<f64>) {
        self.vals[kk - self.base] = k;
    }
    #[inline(always)]
    fn row_start(&mut self, _r: usize) {}
    #[inline(always)]
    fn cell(&mut self, _e: usize, _i: usize) {}
    #[inline(always)]
    fn row_done(&mut self, _r: usize) {}
}
