//! A step's row sweep and its last pass (see [`super`], [`super::cells`] and
//! [`super::pipeline`]).
//!
//! The row sweep computes each block of `K` on and above the diagonal as the fixed-order sum
//! of its element blocks and turns it at once into the block of the Newmark matrix
//! `A = cm M + ck K` (thesis eq. 2.6.2, [`super::newmark`]); `K` itself is stored only when
//! asked for (the adjoint's recomputed steps need it, a forward step does not). In the same
//! sweep it writes, per node, the force `f_r = m_r g` and the part of the right-hand side that
//! does not depend on the forces added later:
//! `b_r = cm m_r u_r + cv m_r v_r + sum_(e, q at r) c_(e, q)`, with the cells' shares
//! `c_(e, q)` of [`super::cells`] (the stiffness term `cu K u` and the corotation force) summed
//! in [`Assembler::cells_of`] order. [`Assembler::assemble_step`] runs the cell sweep, this
//! row sweep and the mirroring of the blocks below the diagonal (each the transpose of its
//! mirror above it) unit by unit in one parallel pass ([`super::pipeline`]). After the
//! external and ground forces have been added to `f`, the last pass
//! ([`Assembler::finish_step`]) adds `dt f_r` to `b_r`.

use super::cells::{CellSweep, CellWork};
use super::newmark::Coefficients;
use super::{Assembler, Cells, ElementBlocks, Material, RowSink};
use crate::fem::element::corner_offsets;
use crate::fem::grid::Grid;
use crate::fem::model::Model;
use gpumat::raw::SharedParts;
use gpumat::{Mat3, Matrix, Scalar, SparseMatrix, Vec3};
use std::sync::Arc;

/// The fewest units for which a step's pass runs on the rayon pool. The pass starts on the
/// calling thread and the workers join as they wake ([`super::pipeline`]), so even the
/// smallest grids of the tables (Table B.5 at r = 5: 4 units) gain from a second thread; a
/// grid of one or two units has too little work to share.
const PARALLEL_UNITS: usize = 3;

/// The state and coefficients a step's row sweep reads besides the cells.
pub(crate) struct StepState<'a> {
    /// the model (Newmark coefficients, gravity)
    pub model: &'a Model,
    /// lumped mass per dof
    pub mass: &'a Matrix<f64>,
    /// the consistent mass on the pattern, when the model has it (then `mass` is not read)
    pub mass_matrix: Option<&'a [f64]>,
    /// displacement
    pub u: &'a Matrix<Vec3<f64>>,
    /// velocity
    pub v: &'a Matrix<Vec3<f64>>,
}

/// The outputs of a step's pass: `K` when it is kept, `A`, `b`, `f`.
pub(crate) struct StepOutput<'a> {
    pub k: Option<&'a mut SparseMatrix<Mat3<f64>>>,
    pub a: &'a mut SparseMatrix<Mat3<f64>>,
    pub b: &'a mut Matrix<Vec3<f64>>,
    pub f: &'a mut Matrix<Vec3<f64>>,
}

/// The cells of a step's pass: material, element blocks, polar iterations, Dirichlet cells,
/// stiffness scale.
pub(crate) struct StepCells<'a> {
    pub grid: &'a Grid,
    pub m: &'a Material,
    pub blocks: &'a ElementBlocks,
    pub iterations: usize,
    pub dirichlet: &'a [Option<crate::fem::NitscheFace>],
    pub scale: Option<&'a [f64]>,
}

impl Assembler {
    /// A step's assembly but for the forces added afterwards, as one pass over the work units
    /// of [`super::pipeline`]: per unit, the cell sweep (the rotations into `rotations` when
    /// given, else `R = I`, and the cells' shares of `b` into `work`), the row sweep (the
    /// blocks of `A`, and of `K` when `out.k` is given, on and above the diagonal, `f = M g`
    /// and `b` without `dt f`) and the blocks below the diagonal from their mirrors. The
    /// buffers are resized to the cell count and reused from step to step.
    pub(crate) fn assemble_step(
        &self,
        c: &StepCells<'_>,
        rotations: Option<&mut Vec<Mat3<f64>>>,
        work: &mut CellWork,
        st: &StepState<'_>,
        out: StepOutput<'_>,
    ) {
        let (grid, n, nc) = (c.grid, self.pattern.rows(), c.grid.cells.len());
        let (ms, us, vs) = (st.mass.as_slice(), st.u.as_slice(), st.v.as_slice());
        assert!(
            [
                ms.len(),
                us.len(),
                vs.len(),
                out.b.as_slice().len(),
                out.f.as_slice().len(),
                grid.dofs()
            ] == [n; 6]
                && self.cell_dofs.len() == nc
                && c.dirichlet.len() == nc
                && c.scale.map_or(true, |s| s.len() == nc),
            "cutfem: step data of another size"
        );
        for mat in std::iter::once(&*out.a).chain(out.k.as_deref()) {
            assert!(
                Arc::ptr_eq(mat.pattern(), &self.pattern) && mat.batches() == 1,
                "cutfem: step matrix with a foreign pattern"
            );
        }
        let nw = Coefficients::new(st.model);
        let sweep = CellSweep {
            asm: self,
            grid,
            m: c.m,
            us,
            x: corner_offsets(grid.h()),
            cu: nw.cu,
            dt: nw.dt,
            iterations: c.iterations,
            blocks: c.blocks,
            dirichlet: c.dirichlet,
            scale: c.scale,
        };
        work.rt.resize(nc, [[0.0; 4]; 3]);
        work.rhs.resize(nc, [Vec3::default(); 8]);
        let corotated = rotations.is_some();
        let rot = rotations.map(|r| {
            r.resize(nc, Mat3::default());
            SharedParts::new(r)
        });
        let (rt, rhs) = (SharedParts::new(&mut work.rt), SharedParts::new(&mut work.rhs));
        let a = SharedParts::new(out.a.batch_values_mut(0));
        let k = out.k.map(|k| SharedParts::new(k.batch_values_mut(0)));
        let (b, f) = (
            SharedParts::new(out.b.as_mut_slice()),
            SharedParts::new(out.f.as_mut_slice()),
        );
        let rp = self.pattern.row_ptr();
        let units = &self.units;
        let cell = |u: usize| {
            let cells = units.cells(u);
            // SAFETY: the cells of unit `u` are borrowed by this stage alone; the other units'
            // row stages read them only after this stage has finished (`Units::run`).
            unsafe {
                sweep.run(
                    cells.start,
                    rot.map(|r| r.part_mut(cells.clone())),
                    rt.part_mut(cells.clone()),
                    rhs.part_mut(cells.clone()),
                );
            }
        };
        let row = |u: usize| {
            let (rows, read) = (units.rows(u), units.cells_read_by_rows(u));
            // SAFETY: the cells `read` belong to units whose cell stage has finished
            // (`Units::run`): no task writes them any more in this pass.
            let (rt, rhs) = unsafe { (rt.part(read.clone()), rhs.part(read.clone())) };
            let cells = Cells {
                grid,
                m: c.m,
                blocks: c.blocks,
                rotations: corotated.then_some(rt),
                cell_base: read.start,
                dirichlet: c.dirichlet,
                scale: c.scale,
            };
            let step_rows = StepRows {
                nw: &nw,
                gravity: st.model.gravity,
                ms,
                consistent: st.mass_matrix.map(|m| (m, rp, self.pattern.col_idx())),
                us,
                vs,
                cell_rhs: rhs,
                cell_base: read.start,
            };
            let entries = rp[rows.start]..rp[rows.end];
            // SAFETY: the blocks, `b` and `f` of unit `u`'s rows are written by this stage
            // alone; the other units' mirror stages read its blocks only after this stage has
            // finished (`Units::run`), and its own mirror stage runs after it.
            let sink = unsafe {
                StepSink {
                    rows: &step_rows,
                    base: entries.start,
                    r0: rows.start,
                    a: a.part_mut(entries.clone()),
                    k: k.map(|k| k.part_mut(entries.clone())),
                    b: b.part_mut(rows.clone()),
                    f: f.part_mut(rows.clone()),
                    acc: Vec3::ZERO,
                }
            };
            self.upper_rows(&cells, rows, sink);
        };
        // SAFETY: the blocks below the diagonal of unit `u`'s rows are written by this stage
        // alone and read by no task; their mirrors lie in rows of units whose row stage has
        // finished (`Units::run`), which no task writes any more.
        let mirror = |u: usize| unsafe { self.mirror_rows(units.rows(u), a, k) };
        units.run(units.count() >= PARALLEL_UNITS, cell, row, mirror);
    }

    /// A step's last pass, after the external and ground forces have been added to `f`:
    /// `b += dt f`.
    pub(crate) fn finish_step(&self, dt: f64, f: &Matrix<Vec3<f64>>, b: &mut Matrix<Vec3<f64>>) {
        assert!(
            b.as_slice().len() == f.as_slice().len(),
            "cutfem: vectors of another size"
        );
        for (b, f) in b.as_mut_slice().iter_mut().zip(f.as_slice()) {
            *b = b.add(f.scale(dt));
        }
    }
}

/// What the step's row sweep reads per row.
struct StepRows<'a> {
    nw: &'a Coefficients,
    gravity: Vec3<f64>,
    ms: &'a [f64],
    /// the consistent mass, the row pointers and column indices of its pattern (`A`'s)
    consistent: Option<(&'a [f64], &'a [usize], &'a [u32])>,
    us: &'a [Vec3<f64>],
    vs: &'a [Vec3<f64>],
    /// the cells' shares of `b`, from cell `cell_base` on
    cell_rhs: &'a [[Vec3<f64>; 8]],
    cell_base: usize,
}

/// The outputs of one chunk of rows, from row `r0` (whose first entry is `base`).
struct StepSink<'a> {
    rows: &'a StepRows<'a>,
    base: usize,
    r0: usize,
    a: &'a mut [Mat3<f64>],
    k: Option<&'a mut [Mat3<f64>]>,
    b: &'a mut [Vec3<f64>],
    f: &'a mut [Vec3<f64>],
    /// `b_r` of the row being swept
    acc: Vec3<f64>,
}

impl RowSink for StepSink<'_> {
    #[inline(always)]
    fn block(&mut self, r: usize, kk: usize, diagonal: bool, k: Mat3<f64>) {
        let nw = self.rows.nw;
        let m = match self.rows.consistent {
            Some((mv, ..)) if diagonal => nw.diagonal(r, mv[kk]),
            Some((mv, ..)) => Mat3::from_scalar(mv[kk] * nw.cm),
            None if diagonal => nw.diagonal(r, self.rows.ms[r]),
            None => nw.off,
        };
        if let Some(kv) = self.k.as_deref_mut() {
            kv[kk - self.base] = k;
        }
        self.a[kk - self.base] = m.add(k.scale(nw.ck));
    }

    #[inline(always)]
    fn row_start(&mut self, r: usize) {
        let (w, nw) = (self.rows, self.rows.nw);
        self.acc = match w.consistent {
            // `cm (M u)_r + cv (M v)_r` in column order, the drag's `c w_r u_r` on its own
            Some((mv, rp, cols)) => {
                let (mut mu, mut mvv) = (Vec3::ZERO, Vec3::ZERO);
                for k in rp[r]..rp[r + 1] {
                    let c = cols[k] as usize;
                    mu = mu.add(w.us[c].scale(mv[k]));
                    mvv = mvv.add(w.vs[c].scale(mv[k]));
                }
                nw.mass_u(r, 0.0, w.us[r])
                    .add(mu.scale(nw.cm))
                    .add(mvv.scale(nw.cv))
            }
            None => {
                let m = w.ms[r];
                nw.mass_u(r, m, w.us[r]).add(w.vs[r].scale(m).scale(nw.cv))
            }
        };
    }

    #[inline(always)]
    fn cell(&mut self, e: usize, i: usize) {
        self.acc = self.acc.add(self.rows.cell_rhs[e - self.rows.cell_base][i]);
    }

    #[inline(always)]
    fn row_done(&mut self, r: usize) {
        self.b[r - self.r0] = self.acc;
        self.f[r - self.r0] = self.rows.gravity.scale(self.rows.ms[r]);
    }
}

#[cfg(test)]
mod tests {
    use crate::fem::{Aabb, Grid, MassMatrix, Model, Simulation};
    use crate::shapes::Shape;
    use gpumat::{Mat3, Matrix, SparseMatrix, Vec3};

    fn bits_m(m: &SparseMatrix<Mat3<f64>>) -> Vec<u64> {
        m.values()
            .iter()
            .flat_map(|b| b.m.into_iter().flatten())
            .map(f64::to_bits)
            .collect()
    }
    fn bits_v(v: &Matrix<Vec3<f64>>) -> Vec<u64> {
        v.as_slice()
            .iter()
            .flat_map(|x| x.to_array())
            .map(f64::to_bits)
            .collect()
    }

    /// A cuboid held at one end (Nitsche cells), large enough for the parallel passes, a few
    /// steps in, assembled again with `K` kept; corotated or not, with a heterogeneous
    /// stiffness or not, with the lumped or the consistent mass.
    fn sim(threads: usize, (corotation, scaled, mass): (bool, bool, MassMatrix)) -> Simulation {
        let shape = Shape::Box {
            center: [0.0, 1.0, 0.0],
            size: [1.29, 0.4, 0.8],
        };
        let grid = Grid::new(shape.to_sdf(16.0, 6).unwrap()).unwrap();
        let cells = grid.cells.len();
        let model = Model {
            young: 2000.0,
            gravity: Vec3::new(0.0, -10.0, 0.0),
            corotation,
            damping_mass: 0.1,
            damping_stiffness: 0.01,
            dirichlet: vec![Aabb {
                min: [-0.9, 0.6, -0.6],
                max: [-0.55, 1.4, 0.6],
            }],
            stiffness_scale: scaled.then(|| (0..cells).map(|e| 0.5 + (e % 7) as f64 * 0.25).collect()),
            dt: 0.01,
            mass,
            ..Model::default()
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut sim = Simulation::new(grid, model).unwrap();
            assert!(sim.assembler.pattern().nnz() >= gpumat::expr::PAR_THRESHOLD);
            for _ in 0..3 {
                sim.step().unwrap();
            }
            sim.assemble_system();
            sim
        })
    }

    /// The step's passes give the same bits on 1, 3 and 8 threads; `K` and `A` are bit for bit
    /// those of the plain stiffness assembly and of the Newmark system as gpumat expressions.
    /// `b` sums its terms in another order than the plain expression (the stiffness and
    /// corotation terms per cell, then per node), so it agrees to rounding: 1e-12 relative.
    #[test]
    fn step_assembly_is_thread_independent_and_matches_the_plain_passes() {
        let (lumped, consistent) = (MassMatrix::Lumped, MassMatrix::Consistent);
        for case in [
            (true, false, lumped),
            (true, true, lumped),
            (false, true, lumped),
            (true, true, consistent),
        ] {
            let one = sim(1, case);
            // 8 threads on fewer cores: workers are preempted mid-unit and the others wait
            for other in [sim(3, case), sim(8, case)] {
                assert_eq!(bits_m(one.stiffness()), bits_m(other.stiffness()));
                assert_eq!(bits_m(one.newmark_matrix()), bits_m(other.newmark_matrix()));
                assert_eq!(bits_v(one.newmark_rhs()), bits_v(other.newmark_rhs()));
                assert_eq!(bits_v(one.force()), bits_v(other.force()));
            }

            let s = &one;
            let m = s.material();
            let scale = s.model.stiffness_scale.as_deref();
            let mut k = SparseMatrix::zeros(s.assembler.pattern().clone(), 1);
            let blocks = s.element_blocks().unwrap();
            s.assembler
                .assemble_stiffness(&s.grid, &m, blocks, s.rotations(), &s.dirichlet, scale, &mut k);
            assert_eq!(bits_m(&k), bits_m(s.stiffness()));

            let (model, dt, theta) = (&s.model, s.model.dt, s.model.theta);
            let cm = 1.0 / (theta * dt) + model.damping_mass;
            let mut a = SparseMatrix::zeros(k.pattern().clone(), 1);
            match &s.mass_matrix {
                None => a.assign(
                    (s.mass.ex().cast::<Mat3<f64>>().as_diagonal() * cm
                        + k.ex() * (model.damping_stiffness + theta * dt))
                        .sparse_view(k.pattern()),
                ),
                Some(mv) => {
                    let mut m3 = SparseMatrix::zeros(k.pattern().clone(), 1);
                    for (b, &x) in m3.batch_values_mut(0).iter_mut().zip(mv) {
                        *b = Mat3::from_scalar(x);
                    }
                    a.assign(
                        (m3.ex() * cm + k.ex() * (model.damping_stiffness + theta * dt))
                            .sparse_view(k.pattern()),
                    );
                }
            }
            assert_eq!(bits_m(&a), bits_m(s.newmark_matrix()));
            // the full force: f plus the corotation forces
            let mut f = s.force().clone();
            if let Some(r) = s.rotations() {
                s.assembler
                    .add_corotation_forces(&s.grid, blocks, r, scale, &mut f);
            }
            let mut b = Matrix::zeros(k.rows(), 1, 1);
            let (mu, mv) = (s.mass_times(&s.u), s.mass_times(&s.v));
            b.assign(
                mu.ex() * cm
                    + (&k * &s.u) * (model.damping_stiffness - (1.0 - theta) * dt)
                    + mv.ex() * (1.0 / theta)
                    + f.ex() * dt,
            );
            let d = Matrix::eval(b.ex() - s.newmark_rhs().ex());
            let (err, size) = (
                d.ex().cwise_squared_norm().max(),
                b.ex().cwise_squared_norm().max(),
            );
            assert!(
                err.sqrt() <= 1e-12 * size.sqrt(),
                "b differs by {} of {}",
                err.sqrt(),
                size.sqrt()
            );
        }
    }

    /// A forward step's assembly (no `K` stored) gives the bits of `A` and `b` of
    /// `assemble_system`, and the `K` computed on demand afterwards is the kept one.
    #[test]
    fn step_without_k_matches_assemble_system() {
        let mut s = sim(2, (true, false, MassMatrix::Lumped));
        let (k, a, b, f) = (
            s.stiffness().clone(),
            s.newmark_matrix().clone(),
            s.newmark_rhs().clone(),
            s.force().clone(),
        );
        s.assemble_system_with(false);
        assert_eq!(bits_m(&a), bits_m(s.newmark_matrix()));
        assert_eq!(bits_v(&b), bits_v(s.newmark_rhs()));
        assert_eq!(bits_v(&f), bits_v(s.force()));
        assert_eq!(bits_m(&k), bits_m(s.stiffness()));
    }
}
