//! The unrotated element blocks of every cell of a grid, shared between cells of the same
//! geometry (see [`ElementBlocks`]).

use super::enhanced::{Element, ElementSet};
use super::{padded_transpose, PaddedBlock};
use crate::cutcell::CellIntegrals;
use crate::fem::grid::Grid;
use gpumat::Mat3;
use rayon::prelude::*;

/// The unrotated element blocks `K_ij(e)` for one material and element: one shared set for all
/// full cells and one set per distinct cut geometry (the integrals the element reads: the
/// corner weights for the corner rule, the moments for exact integration). Cells cut alike,
/// e.g. along a flat face, share theirs: bit-identical inputs give bit-identical blocks, and a
/// smaller table is less memory traffic in every assembly. Rebuilt only when the material or
/// the element changes.
#[derive(Clone, Debug)]
pub struct ElementBlocks {
    /// Lame lambda the blocks were built for
    pub lambda: f64,
    /// Lame mu the blocks were built for
    pub mu: f64,
    /// the element they were built for
    pub element: Element,
    /// the sets: the full cells' first, then one per distinct cut geometry
    sets: Vec<ElementSet>,
    /// per cell: its index into `sets` (0 for a full cell)
    set_of: Vec<u32>,
    /// the same blocks transposed and padded ([`padded_transpose`]): their columns as
    /// vectors, for the cell sweep of a step (`assembly::cells`)
    columns: Vec<[[PaddedBlock; 8]; 8]>,
}

/// The bits of the integrals `element` reads.
fn key(ci: &CellIntegrals, element: Element) -> Vec<u64> {
    if element.exact() {
        ci.moments.iter().map(|x| x.to_bits()).collect()
    } else {
        ci.volume.iter().map(|x| x.to_bits()).collect()
    }
}

impl ElementBlocks {
    /// Builds the blocks of every cell of `grid` for `(lambda, mu)` and `element`.
    pub fn new(grid: &Grid, element: Element, lambda: f64, mu: f64) -> Self {
        Self::build(grid, element, lambda, mu, true)
    }

    /// [`ElementBlocks::new`], on the rayon pool when `parallel` (else on the calling thread
    /// alone; the same values).
    pub(crate) fn build(grid: &Grid, element: Element, lambda: f64, mu: f64, parallel: bool) -> Self {
        let h = grid.h();
        let full = CellIntegrals::full(h);
        // distinct cut geometries in order of first appearance (deterministic)
        let mut set_of = vec![0u32; grid.cells.len()];
        let mut seen: std::collections::HashMap<Vec<u64>, u32> = std::collections::HashMap::new();
        let mut inputs: Vec<&CellIntegrals> = vec![&full];
        for (e, c) in grid.cells.iter().enumerate() {
            if !c.is_full() {
                let ci = &c.integrals;
                set_of[e] = *seen.entry(key(ci, element)).or_insert_with(|| {
                    inputs.push(ci);
                    (inputs.len() - 1) as u32
                });
            }
        }
        let make = |ci: &&CellIntegrals| ElementSet::of_cell(ci, h, element, lambda, mu);
        let sets: Vec<ElementSet> = if parallel {
            inputs.par_iter().map(make).collect()
        } else {
            inputs.iter().map(make).collect()
        };
        let columns = sets
            .iter()
            .map(|set| set.k.map(|row| row.map(|b| padded_transpose(&b))))
            .collect();
        Self {
            lambda,
            mu,
            element,
            sets,
            set_of,
            columns,
        }
    }
    /// Whether these blocks are those of `(lambda, mu)` and `element`.
    pub fn is_for(&self, element: Element, lambda: f64, mu: f64) -> bool {
        self.element == element && self.lambda == lambda && self.mu == mu
    }
    /// Number of distinct cut-cell block sets stored.
    pub fn cut_sets(&self) -> usize {
        self.sets.len() - 1
    }
    /// `K_ij(e)`.
    #[inline(always)]
    pub fn get(&self, e: usize, i: usize, j: usize) -> Mat3<f64> {
        self.cell(e)[i][j]
    }
    /// All 64 blocks of cell `e`.
    #[inline(always)]
    pub fn cell(&self, e: usize) -> &[[Mat3<f64>; 8]; 8] {
        &self.sets[self.set_of[e] as usize].k
    }
    /// The element of cell `e` (its blocks and their Lame derivatives).
    pub fn set(&self, e: usize) -> &ElementSet {
        &self.sets[self.set_of[e] as usize]
    }
    /// All 64 blocks of cell `e`, transposed and padded (their columns as vectors).
    #[inline(always)]
    pub fn cell_columns(&self, e: usize) -> &[[PaddedBlock; 8]; 8] {
        &self.columns[self.set_of[e] as usize]
    }
}

/// The element blocks of the last few materials, newest last: a Gauss-Newton tangent
/// alternates between a material and its perturbations `E (1 +- eps)`, `nu +- eps` every step,
/// and each would otherwise rebuild (and condense) every cell's blocks. Holds at most
/// [`BlockCache::MAX_MATERIALS`] materials and [`BlockCache::MAX_BYTES`] bytes, dropping the
/// oldest.
#[derive(Clone, Debug, Default)]
pub struct BlockCache {
    recent: Vec<ElementBlocks>,
}

impl BlockCache {
    /// Most materials kept (a material and the two sides of two parameters, and one spare).
    pub const MAX_MATERIALS: usize = 6;
    /// Most bytes kept.
    pub const MAX_BYTES: usize = 256 << 20;

    /// Removes and returns the blocks of `(element, lambda, mu)`, if kept.
    pub fn take(&mut self, element: Element, lambda: f64, mu: f64) -> Option<ElementBlocks> {
        let i = self.recent.iter().position(|b| b.is_for(element, lambda, mu))?;
        Some(self.recent.remove(i))
    }

    /// The kept blocks of `(element, lambda, mu)`.
    pub fn get(&self, element: Element, lambda: f64, mu: f64) -> Option<&ElementBlocks> {
        self.recent.iter().rev().find(|b| b.is_for(element, lambda, mu))
    }

    /// The blocks kept last.
    pub fn last(&self) -> Option<&ElementBlocks> {
        self.recent.last()
    }

    /// Keeps `blocks` as the newest (replacing those of the same material), then drops the
    /// oldest beyond the limits; the newest is always kept.
    pub fn keep(&mut self, blocks: ElementBlocks) {
        self.recent
            .retain(|b| !b.is_for(blocks.element, blocks.lambda, blocks.mu));
        self.recent.push(blocks);
        let mut bytes: usize = self.recent.iter().map(ElementBlocks::bytes).sum();
        while self.recent.len() > 1 && (self.recent.len() > Self::MAX_MATERIALS || bytes > Self::MAX_BYTES) {
            bytes -= self.recent.remove(0).bytes();
        }
    }
}

impl ElementBlocks {
    /// Approximate heap bytes of these blocks.
    fn bytes(&self) -> usize {
        self.sets.len() * (std::mem::size_of::<ElementSet>() + std::mem::size_of::<[[PaddedBlock; 8]; 8]>())
            + self.set_of.len() * std::mem::size_of::<u32>()
    }
}
