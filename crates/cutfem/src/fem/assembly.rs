//! Assembly of the stiffness matrix and the element forces (thesis sec. 4.4.1-4.4.2).
//!
//! Pattern once, values every step (sec. 4.3.3): the BSR pattern of K (node pairs sharing an
//! active cell) and the gather map (for each stored block, the list of element blocks
//! `(e, i, j)` that sum into it) depend only on the reference grid and are built once.
//! Each step, the values are computed row by row in parallel: a block is the fixed-order sum
//! of its element contributions, so there are no atomics, no races and the result does not
//! depend on the thread count.
//!
//! Element block (e, i, j): `R_e K_ij(e) R_e^T` (corotation, eq. 4.4.7/4.4.10) plus, for a
//! Dirichlet cell, the Nitsche terms (eq. 4.4.16-4.4.17), added after the rotation as the
//! thesis prescribes. The corotation force of corner `i` is
//! `f_i -= sum_j R_e K_ij (R_e^T x_j - x_j)` (eq. 4.4.6/4.4.10); because `sum_j K_ij = 0`
//! the corner positions may be taken relative to the cell.

use super::element::{corner_offsets, StiffnessTables};
use super::grid::Grid;
use gpumat::{Mat3, Matrix, SparseMatrix, SparsityPattern, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

/// `R B R^T` with plain loops (the hot spot of the corotated assembly).
#[inline(always)]
pub fn rotate_block(r: &Mat3<f64>, b: &Mat3<f64>) -> Mat3<f64> {
    let (r, b) = (&r.m, &b.m);
    // t = B R^T
    let mut t = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            t[i][j] = b[i][0] * r[j][0] + b[i][1] * r[j][1] + b[i][2] * r[j][2];
        }
    }
    let mut o = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            o[i][j] = r[i][0] * t[0][j] + r[i][1] * t[1][j] + r[i][2] * t[2][j];
        }
    }
    Mat3 { m: o }
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

/// The unrotated element blocks `K_ij(e)` for one material: one shared set for all full
/// cells (their weights are all `h^3/8`) and one set per distinct weight vector of the cut
/// cells (cells cut alike, e.g. along a flat face, share theirs: bit-identical weights give
/// bit-identical blocks, and a smaller table is less memory traffic in every assembly).
/// Rebuilt only when the material changes.
#[derive(Clone, Debug)]
pub struct ElementBlocks {
    /// Lame lambda the blocks were built for
    pub lambda: f64,
    /// Lame mu the blocks were built for
    pub mu: f64,
    full: Box<[[Mat3<f64>; 8]; 8]>,
    /// per cell: index into `cut`, or `u32::MAX` for a full cell
    cut_index: Vec<u32>,
    cut: Vec<[[Mat3<f64>; 8]; 8]>,
}

impl ElementBlocks {
    /// Builds the blocks of every cell of `grid` for `(lambda, mu)`.
    pub fn new(tables: &StiffnessTables, grid: &Grid, lambda: f64, mu: f64) -> Self {
        let w = [grid.h().powi(3) / 8.0; 8];
        let block_set = |w: &[f64; 8]| -> [[Mat3<f64>; 8]; 8] {
            std::array::from_fn(|i| std::array::from_fn(|j| tables.block(w, i, j, lambda, mu)))
        };
        let full = Box::new(block_set(&w));
        // distinct weight vectors in order of first appearance (deterministic)
        let mut cut_index = vec![u32::MAX; grid.cells.len()];
        let mut seen: std::collections::HashMap<[u64; 8], u32> = std::collections::HashMap::new();
        let mut weights: Vec<&[f64; 8]> = Vec::new();
        for (e, c) in grid.cells.iter().enumerate() {
            if !c.is_full() {
                let v = &c.integrals.volume;
                cut_index[e] = *seen.entry(v.map(f64::to_bits)).or_insert_with(|| {
                    weights.push(v);
                    (weights.len() - 1) as u32
                });
            }
        }
        let cut = weights.par_iter().map(|w| block_set(w)).collect();
        Self {
            lambda,
            mu,
            full,
            cut_index,
            cut,
        }
    }
    /// Number of distinct cut-cell block sets stored.
    pub fn cut_sets(&self) -> usize {
        self.cut.len()
    }
    /// `K_ij(e)`.
    #[inline(always)]
    pub fn get(&self, e: usize, i: usize, j: usize) -> Mat3<f64> {
        match self.cut_index[e] {
            u32::MAX => self.full[i][j],
            c => self.cut[c as usize][i][j],
        }
    }
    /// All 64 blocks of cell `e`.
    #[inline(always)]
    pub fn cell(&self, e: usize) -> &[[Mat3<f64>; 8]; 8] {
        match self.cut_index[e] {
            u32::MAX => &self.full,
            c => &self.cut[c as usize],
        }
    }
}

/// The pattern, gather maps and tables, built once per grid.
#[derive(Clone, Debug)]
pub struct Assembler {
    pattern: Arc<SparsityPattern>,
    /// contributions of each stored block: `contrib[contrib_ptr[k]..contrib_ptr[k+1]]`
    contrib_ptr: Vec<u32>,
    /// `(cell, 8 i + j)`
    contrib: Vec<(u32, u8)>,
    /// entries on or above the diagonal (computed; the others are their transposes)
    upper: Vec<u32>,
    /// entries below the diagonal and their mirror entries above it: `(entry, mirror)`
    lower: Vec<(u32, u32)>,
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
        let mut count = vec![0u32; pattern.nnz() + 1];
        let mut slot = Vec::with_capacity(grid.cells.len() * 64);
        for c in &grid.cells {
            for i in 0..8 {
                for j in 0..8 {
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
        let mut contrib = vec![(0u32, 0u8); slot.len()];
        for (e, chunk) in slot.chunks(64).enumerate() {
            for (ij, &k) in chunk.iter().enumerate() {
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
        // upper-triangle entries and the mirror map of the others
        let mut upper = Vec::with_capacity(pattern.nnz() / 2 + n);
        let mut lower = Vec::with_capacity(pattern.nnz() / 2);
        for r in 0..n {
            for kk in pattern.row_range(r) {
                let c = pattern.col_idx()[kk] as usize;
                if c >= r {
                    upper.push(kk as u32);
                } else {
                    let mirror = pattern.find(c, r).expect("cell pairs give a symmetric pattern");
                    lower.push((kk as u32, mirror as u32));
                }
            }
        }
        Self {
            pattern,
            contrib_ptr,
            contrib,
            upper,
            lower,
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
        assert!(
            Arc::ptr_eq(k.pattern(), &self.pattern),
            "cutfem: stiffness matrix has a foreign pattern"
        );
        // K is symmetric (every element block satisfies K_ji = K_ij^T, rotated or not, and so
        // do the Nitsche terms): compute the upper triangle, mirror the rest.
        let block = |kk: usize| -> Mat3<f64> {
            let mut acc = Mat3::default();
            for &(e, ij) in &self.contrib[self.contrib_ptr[kk] as usize..self.contrib_ptr[kk + 1] as usize] {
                let (e, i, j) = (e as usize, (ij / 8) as usize, (ij % 8) as usize);
                let mut b = blocks.get(e, i, j);
                let se = scale.map_or(1.0, |s| s[e]);
                if se != 1.0 {
                    b = b * se;
                }
                if let Some(r) = rotations {
                    b = rotate_block(&r[e], &b);
                }
                if dirichlet[e] {
                    let ci = &grid.cells[e].integrals;
                    let n = Vec3::from_array(ci.normal);
                    b = b + self
                        .tables
                        .nitsche_block(&ci.boundary, n, i, j, m.lambda * se, m.mu * se, m.eta);
                }
                acc = acc + b;
            }
            acc
        };
        // In place, without a buffer: the upper entries, then each lower one from its mirror.
        let values = k.batch_values_mut(0);
        let out = EntryWriter(values.as_mut_ptr(), values.len());
        self.upper.par_iter().with_min_len(256).for_each(|&kk| {
            let b = block(kk as usize);
            // SAFETY: `upper` lists distinct entries of the pattern (`< values.len()`), so
            // every task writes its own entry and nothing reads them during this pass.
            unsafe { out.write(kk as usize, b) };
        });
        self.lower
            .par_iter()
            .with_min_len(1024)
            .for_each(|&(kk, mirror)| {
                // SAFETY: the `kk` are distinct entries below the diagonal, each written by one
                // task; the `mirror`s are entries above it, written in the finished pass above and
                // only read here, so no entry is both read and written in this pass.
                unsafe { out.write(kk as usize, out.read(mirror as usize).transpose()) };
            });
    }

    /// Per-cell rotations from the displacement `u` (eq. 4.4.8-4.4.9).
    pub fn rotations(&self, grid: &Grid, u: &Matrix<Vec3<f64>>, iterations: usize) -> Vec<Mat3<f64>> {
        let h = grid.h();
        let us = u.as_slice();
        grid.cells
            .par_iter()
            .map(|c| {
                let ue: [Vec3<f64>; 8] = std::array::from_fn(|q| us[c.dofs[q] as usize]);
                super::element::polar_rotation(super::element::deformation_gradient(&ue, h), iterations)
            })
            .collect()
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
        let cell_forces: Vec<[Vec3<f64>; 8]> = grid
            .cells
            .par_iter()
            .enumerate()
            .map(|(e, _)| {
                let r = rotations[e];
                let rt = r.transpose();
                let d: [Vec3<f64>; 8] = std::array::from_fn(|j| rt * x[j] - x[j]);
                let k = blocks.cell(e);
                std::array::from_fn(|i| {
                    let mut s = Vec3::default();
                    for j in 0..8 {
                        s = s + k[i][j] * d[j];
                    }
                    -(r * s) * scale.map_or(1.0, |s| s[e])
                })
            })
            .collect();
        let fs = f.as_mut_slice();
        fs.par_iter_mut().enumerate().for_each(|(dof, out)| {
            for &(e, q) in &self.node_cells[self.node_ptr[dof] as usize..self.node_ptr[dof + 1] as usize] {
                *out = *out + cell_forces[e as usize][q as usize];
            }
        });
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
