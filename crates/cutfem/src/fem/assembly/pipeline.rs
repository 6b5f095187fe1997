//! A step's assembly as one parallel pass over work units (see [`super`]).
//!
//! The three sweeps of a step (cells, rows, mirror) depend on each other only locally: the
//! blocks of row `r` need the rotations and right-hand-side shares of the cells touching node
//! `r`, and the blocks below the diagonal of row `r` are the transposes of blocks above the
//! diagonal of rows `c < r` that share a cell with it. So the cells are cut into units of
//! [`UNIT_CELLS`] consecutive cells (cells and nodes are numbered x fastest, so a unit is a
//! slab of the grid) and each row joins the unit of its last cell, kept nondecreasing so that
//! a unit's rows are consecutive too. Unit `u` runs three stages:
//!
//! 1. `C(u)`: the cell sweep ([`super::cells`]) over its cells;
//! 2. `R(u)`: the row sweep ([`super::step`]) over its rows, once `C(v)` is done for every
//!    unit `v` of their cells (`cell_dep[u] <= v <= u`);
//! 3. `M(u)`: the blocks below the diagonal of its rows from their mirrors, once `R(v)` is done
//!    for every unit `v` of those mirrors (`row_dep[u] <= v <= u`).
//!
//! The workers take the units in order from a shared counter and run the three stages of each;
//! a stage that needs an earlier unit waits (spinning) until that unit has published the
//! stage. A unit only ever waits on units taken before it by workers that are running
//! (they never wait on later units), so the pass cannot deadlock, and on one thread it runs
//! the units in order without waiting. The calling thread starts on the first unit at once
//! while the pool's workers join: one fork-join per step instead of one per sweep (waking a
//! worker costs tens to hundreds of microseconds on a busy virtual machine), and a unit's cell
//! data and blocks are still in the cache when its rows and mirrors read them.
//!
//! Measured against three plain rayon sweeps over the same units (cells, then rows, then
//! mirrors; one fork-join each), on Table B.5's cuboid (`bench --example assembly_profile`,
//! 2 cores, 2 runs each): at r = 10 the pass takes 2.0 / 1.7 ms per step against 2.9 / 3.3 ms
//! for the sweeps (steps alone, about 25 ms each) and 2.4 / 2.5 ms against 3.2 / 4.1 ms with the
//! level-set advection between steps; at r = 20, 16.0 / 18.2 ms against 26.8 / 24.9 ms (steps
//! alone) and 19.1 / 19.6 against 18.1 / 17.3 ms (with advection), of a 1.2-1.6 s step. So it
//! is kept for the small grids of the fits (3-5% of a step at r = 10) and is neutral at r = 20.
//! The disjoint parts of the shared buffers are borrowed through gpumat's raw-buffer primitive
//! ([`gpumat::raw::SharedParts`]).
//!
//! Every value is computed by one stage of one unit with the sweeps' fixed order of
//! operations, so the results do not depend on which worker runs which unit or on the number
//! of threads.

use gpumat::SparsityPattern;
use std::ops::Range;
use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};

/// Cells per unit.
pub(super) const UNIT_CELLS: usize = 128;

/// The units of a step's pass (module docs), built once per grid.
#[derive(Clone, Debug, Default)]
pub(crate) struct Units {
    /// unit `u`'s rows: `rows[u]..rows[u + 1]`
    rows: Vec<u32>,
    /// `R(u)` reads the cells of units `cell_dep[u]..=u`
    cell_dep: Vec<u32>,
    /// `M(u)` reads the blocks of the rows of units `row_dep[u]..=u`
    row_dep: Vec<u32>,
    /// the cell count
    cells: usize,
}

impl Units {
    /// The units of `cells` cells and the pattern (diagonal entries `diag`) whose rows touch
    /// the cells `node_cells[node_ptr[r]..node_ptr[r + 1]]` (in cell order).
    pub(super) fn new(
        cells: usize,
        pattern: &SparsityPattern,
        diag: &[u32],
        node_ptr: &[u32],
        node_cells: &[(u32, u8)],
    ) -> Self {
        let count = cells.div_ceil(UNIT_CELLS).max(1);
        let n = pattern.rows();
        let row_cells = |r: usize| &node_cells[node_ptr[r] as usize..node_ptr[r + 1] as usize];
        // each row in the unit of its last cell, nondecreasing
        let mut unit_of_row = Vec::with_capacity(n);
        let mut last = 0usize;
        for r in 0..n {
            let own = row_cells(r).iter().map(|&(e, _)| e as usize / UNIT_CELLS).max();
            last = last.max(own.unwrap_or(0));
            unit_of_row.push(last);
        }
        let mut rows = vec![0u32; count + 1];
        for u in 0..=count {
            rows[u] = unit_of_row.partition_point(|&v| v < u) as u32;
        }
        let mut cell_dep: Vec<u32> = (0..count as u32).collect();
        let mut row_dep = cell_dep.clone();
        let cols = pattern.col_idx();
        let rp = pattern.row_ptr();
        for r in 0..n {
            let u = unit_of_row[r];
            for &(e, _) in row_cells(r) {
                cell_dep[u] = cell_dep[u].min((e as usize / UNIT_CELLS) as u32);
            }
            for &c in &cols[rp[r]..diag[r] as usize] {
                row_dep[u] = row_dep[u].min(unit_of_row[c as usize] as u32);
            }
        }
        Self {
            rows,
            cell_dep,
            row_dep,
            cells,
        }
    }

    /// The number of units.
    pub(super) fn count(&self) -> usize {
        self.cell_dep.len()
    }
    /// The cells of unit `u`.
    pub(super) fn cells(&self, u: usize) -> Range<usize> {
        (u * UNIT_CELLS).min(self.cells)..((u + 1) * UNIT_CELLS).min(self.cells)
    }
    /// The rows of unit `u`.
    pub(super) fn rows(&self, u: usize) -> Range<usize> {
        self.rows[u] as usize..self.rows[u + 1] as usize
    }
    /// The cells whose stage `C` the stage `R(u)` reads: those of units `cell_dep[u]..=u`.
    pub(super) fn cells_read_by_rows(&self, u: usize) -> Range<usize> {
        self.cells(self.cell_dep[u] as usize).start..self.cells(u).end
    }

    /// Runs the three stages `cell`, `row`, `mirror` of every unit (module docs) on the rayon
    /// pool when `parallel`, else in order on the calling thread. `row(u)` runs after
    /// `cell(v)` has finished for every unit `v` of the cells it reads, `mirror(u)` after
    /// `row(v)` for every unit `v` of its mirrors (and after `row(u)`).
    pub(super) fn run(
        &self,
        parallel: bool,
        cell: impl Fn(usize) + Sync,
        row: impl Fn(usize) + Sync,
        mirror: impl Fn(usize) + Sync,
    ) {
        let stage: Vec<AtomicU8> = (0..self.count()).map(|_| AtomicU8::new(0)).collect();
        let next = AtomicUsize::new(0);
        let worker = || loop {
            let u = next.fetch_add(1, Ordering::Relaxed);
            if u >= self.count() {
                break;
            }
            let wait = Wait {
                units: self,
                stage: &stage,
                u,
            };
            cell(u);
            wait.cells_done();
            row(u);
            wait.rows_done();
            mirror(u);
        };
        if parallel {
            let worker = &worker;
            rayon::in_place_scope(|s| {
                for _ in 1..rayon::current_num_threads() {
                    s.spawn(move |_| worker());
                }
                worker();
            });
        } else {
            worker();
        }
    }
}

/// The stage of a unit: its cells are done (`CELLS`), its rows (`ROWS`).
const CELLS: u8 = 1;
const ROWS: u8 = 2;

/// Unit `u`'s view of the progress of the others (module docs).
struct Wait<'a> {
    units: &'a Units,
    stage: &'a [AtomicU8],
    u: usize,
}

impl Wait<'_> {
    /// Publishes `C(u)` and waits until the cells `R(u)` reads are done.
    fn cells_done(&self) {
        self.publish(CELLS);
        self.wait(self.units.cell_dep[self.u] as usize, CELLS);
    }
    /// Publishes `R(u)` and waits until the rows `M(u)` reads are done.
    fn rows_done(&self) {
        self.publish(ROWS);
        self.wait(self.units.row_dep[self.u] as usize, ROWS);
    }
    fn publish(&self, s: u8) {
        // Release: the unit's writes before it are seen by whoever acquires the stage.
        self.stage[self.u].store(s, Ordering::Release);
    }
    /// Waits until units `from..u` have reached stage `s`. They were taken before `u` by
    /// running workers that never wait on later units, so this ends.
    fn wait(&self, from: usize, s: u8) {
        for v in from..self.u {
            let mut spins = 0u32;
            while self.stage[v].load(Ordering::Acquire) < s {
                if spins < 1 << 12 {
                    std::hint::spin_loop();
                    spins += 1;
                } else {
                    std::thread::yield_now();
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::fem::{Assembler, Grid};
    use crate::shapes::Shape;

    /// Every cell and row is in exactly one unit, rows only need cells and mirrors of their
    /// own and earlier units, and the dependencies cover every cell and mirror a row reads.
    #[test]
    fn units_cover_the_grid_and_only_look_back() {
        for (shape, res) in [
            (
                Shape::Box {
                    center: [0.0, 1.0, 0.0],
                    size: [1.29, 0.4, 0.8],
                },
                20.0,
            ),
            (
                Shape::Torus {
                    center: [0.0, 0.0, 0.0],
                    axis: [0.3, 1.0, 0.2],
                    major: 0.5,
                    minor: 0.2,
                },
                16.0,
            ),
        ] {
            let grid = Grid::new(shape.to_sdf(res, 3).unwrap()).unwrap();
            let asm = Assembler::new(&grid);
            let units = &asm.units;
            assert!(units.count() > 2);
            let (mut cells, mut rows) = (0, 0);
            let unit_of_cell = |e: usize| (0..units.count()).find(|&u| units.cells(u).contains(&e)).unwrap();
            let unit_of_row = |r: usize| (0..units.count()).find(|&u| units.rows(u).contains(&r)).unwrap();
            for u in 0..units.count() {
                assert_eq!(units.cells(u).start, cells);
                assert_eq!(units.rows(u).start, rows);
                (cells, rows) = (units.cells(u).end, units.rows(u).end);
                for r in units.rows(u) {
                    for &(e, _) in asm.cells_of(r) {
                        assert!(units.cells_read_by_rows(u).contains(&(e as usize)));
                        assert!(unit_of_cell(e as usize) <= u);
                    }
                    let p = asm.pattern();
                    for kk in p.row_range(r) {
                        let c = p.col_idx()[kk] as usize;
                        if c < r {
                            let v = unit_of_row(c);
                            assert!(units.row_dep[u] as usize <= v && v <= u);
                        }
                    }
                }
            }
            assert_eq!((cells, rows), (grid.cells.len(), grid.dofs()));
        }
    }
}
