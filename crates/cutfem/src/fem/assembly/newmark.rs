//! The Newmark-1 system with Rayleigh damping (thesis eq. 2.6.2, see [`crate::fem::sim`]) in
//! one pass over the rows of `K`:
//!
//! `A = cm M + ck K`, `b = cm M u + cu K u + M v / theta + dt f` with `cm = 1/(theta dt) + a1`,
//! `ck = a2 + theta dt`, `cu = a2 - (1-theta) dt`.
//!
//! Each task owns a fixed block of rows: it reads each block of its rows once, writes the
//! row's blocks of `A` and its entry of `b`, with `(K u)_r` summed in column order, so the
//! values do not depend on the number of threads. In a grid step the pass also completes `K`:
//! the stiffness pass leaves the blocks below the diagonal to it, and it takes each as the
//! transpose of its mirror above the diagonal when it reaches it.

use super::{for_each_item, Assembler, EntryWriter, ROW_CHUNK};
use crate::fem::model::Model;
use gpumat::{Mat3, Matrix, Scalar, ScalarMul, SparseMatrix, SparsityPattern, Vec3};

/// The coefficients of `A = cm M + ck K`, `b = cm M u + cu K u + cv M v + dt f`.
pub(super) struct Coefficients {
    pub(super) cm: f64,
    pub(super) ck: f64,
    cu: f64,
    cv: f64,
    dt: f64,
    /// `(cm M)_rc` off the diagonal: `0 cm`
    pub(super) off: Mat3<f64>,
}

impl Coefficients {
    /// Those of `model`.
    pub(super) fn new(model: &Model) -> Self {
        let (dt, theta) = (model.dt, model.theta);
        let (a1, a2) = (model.damping_mass, model.damping_stiffness);
        let cm = 1.0 / (theta * dt) + a1;
        Self {
            cm,
            ck: a2 + theta * dt,
            cu: a2 - (1.0 - theta) * dt,
            cv: 1.0 / theta,
            dt,
            off: Mat3::ZERO.scale(cm),
        }
    }
    /// `(cm M)_rr` for the lumped mass `m` of row `r`.
    #[inline(always)]
    pub(super) fn diagonal(&self, m: f64) -> Mat3<f64> {
        Mat3::from_scalar(m).scale(self.cm)
    }
}

/// Where the pass reads the blocks of `K`.
trait Blocks: Sync {
    /// Whether the pass writes the blocks of `A` from the split on (else they are written).
    const UPPER_A: bool;
    /// The first entry of row `r` (entries `start..`) read by [`Blocks::upper`]; the ones
    /// before it are read by [`Blocks::lower`].
    fn split(&self, r: usize, start: usize) -> usize;
    /// Block `kk`, before the split.
    fn lower(&self, kk: usize) -> Mat3<f64>;
    /// Block `kk`, from the split on.
    fn upper(&self, kk: usize) -> Mat3<f64>;
}

/// A complete `K`.
struct Complete<'a>(&'a [Mat3<f64>]);

impl Blocks for Complete<'_> {
    const UPPER_A: bool = true;
    #[inline(always)]
    fn split(&self, _r: usize, start: usize) -> usize {
        start
    }
    #[inline(always)]
    fn lower(&self, kk: usize) -> Mat3<f64> {
        self.0[kk]
    }
    #[inline(always)]
    fn upper(&self, kk: usize) -> Mat3<f64> {
        self.0[kk]
    }
}

/// A `K` with only the blocks on and above the diagonal, and an `A` with them too: each block
/// of `K` below it is written as the transpose of its mirror when read.
struct Mirroring<'a> {
    k: EntryWriter,
    diag: &'a [u32],
    mirror: &'a [u32],
}

impl Blocks for Mirroring<'_> {
    const UPPER_A: bool = false;
    #[inline(always)]
    fn split(&self, r: usize, _start: usize) -> usize {
        self.diag[r] as usize
    }
    #[inline(always)]
    fn lower(&self, kk: usize) -> Mat3<f64> {
        // SAFETY: `rows` visits every entry once, from the one task that owns its row. The
        // mirrors (on or above the diagonal) are only read in this pass; `kk` (below it) is
        // written here, by that task alone, and read by none.
        unsafe {
            let b = self.k.read(self.mirror[kk] as usize).transpose();
            self.k.write(kk, b);
            b
        }
    }
    #[inline(always)]
    fn upper(&self, kk: usize) -> Mat3<f64> {
        // SAFETY: on or above the diagonal: only read in this pass (see above).
        unsafe { self.k.read(kk) }
    }
}

/// `A` and `b` of the Newmark system for a complete `K` ([`crate::fem::sim::newmark_system`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn fill_newmark(
    model: &Model,
    mass: &Matrix<f64>,
    k: &SparseMatrix<Mat3<f64>>,
    u: &Matrix<Vec3<f64>>,
    v: &Matrix<Vec3<f64>>,
    f: &Matrix<Vec3<f64>>,
    a: &mut SparseMatrix<Mat3<f64>>,
    b: &mut Matrix<Vec3<f64>>,
) {
    assert!(k.batches() == 1, "cutfem::newmark_system: K has one batch");
    let p = k.pattern().clone();
    rows(model, &Complete(k.values()), &p, mass, u, v, f, a, b);
}

impl Assembler {
    /// `b` and the blocks of `A` below the diagonal of the Newmark system of a step, completing
    /// `k` in the same pass (the blocks on and above the diagonal of both are
    /// [`Assembler::assemble_upper_with_forces`]'s).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn newmark(
        &self,
        model: &Model,
        mass: &Matrix<f64>,
        k: &mut SparseMatrix<Mat3<f64>>,
        u: &Matrix<Vec3<f64>>,
        v: &Matrix<Vec3<f64>>,
        f: &Matrix<Vec3<f64>>,
        a: &mut SparseMatrix<Mat3<f64>>,
        b: &mut Matrix<Vec3<f64>>,
    ) {
        assert!(
            std::sync::Arc::ptr_eq(k.pattern(), &self.pattern),
            "cutfem: stiffness matrix has a foreign pattern"
        );
        let values = k.batch_values_mut(0);
        let blocks = Mirroring {
            k: EntryWriter(values.as_mut_ptr(), values.len()),
            diag: &self.diag,
            mirror: &self.mirror,
        };
        rows(model, &blocks, &self.pattern, mass, u, v, f, a, b);
    }
}

/// The pass over the rows of `p`, reading `K` from `kb`.
#[allow(clippy::too_many_arguments)]
fn rows<B: Blocks>(
    model: &Model,
    kb: &B,
    p: &SparsityPattern,
    mass: &Matrix<f64>,
    u: &Matrix<Vec3<f64>>,
    v: &Matrix<Vec3<f64>>,
    f: &Matrix<Vec3<f64>>,
    a: &mut SparseMatrix<Mat3<f64>>,
    b: &mut Matrix<Vec3<f64>>,
) {
    let Coefficients {
        cm,
        ck,
        cu,
        cv,
        dt,
        off,
    } = Coefficients::new(model);
    let n = p.rows();
    assert!(
        (std::ptr::eq(a.pattern().as_ref(), p) || a.pattern().as_ref() == p) && a.batches() == 1,
        "cutfem::newmark_system: A must have K's pattern and one batch"
    );
    let (ms, us, vs, fs) = (mass.as_slice(), u.as_slice(), v.as_slice(), f.as_slice());
    assert!(
        p.cols() == n && [ms.len(), us.len(), vs.len(), fs.len(), b.as_slice().len()] == [n; 5],
        "cutfem::newmark_system: vectors of another size than K"
    );
    let (rp, cols) = (p.row_ptr(), p.col_idx());
    let items: Vec<_> = p
        .split_rows_mut(a.batch_values_mut(0), ROW_CHUNK)
        .into_iter()
        .zip(b.as_mut_slice().chunks_mut(ROW_CHUNK))
        .collect();
    let parallel = p.nnz() >= gpumat::expr::PAR_THRESHOLD;
    for_each_item(parallel, items, |((r0, av), bc)| {
        gpumat::simd::with_avx2(
            #[inline(always)]
            || {
                let base = rp[r0];
                for (o, br) in bc.iter_mut().enumerate() {
                    let r = r0 + o;
                    let mut ku = Vec3::ZERO;
                    // a macro, so that the entry code inlines into this AVX2 function
                    macro_rules! entry {
                        ($kk:expr, $k:expr, $write_a:expr) => {{
                            let (kk, k): (usize, Mat3<f64>) = ($kk, $k);
                            let c = cols[kk] as usize;
                            ku = ku.add(k.smul(us[c]));
                            if $write_a {
                                let m = if c == r {
                                    Mat3::from_scalar(ms[r]).scale(cm)
                                } else {
                                    off
                                };
                                av[kk - base] = m.add(k.scale(ck));
                            }
                        }};
                    }
                    let split = kb.split(r, rp[r]);
                    for kk in rp[r]..split {
                        entry!(kk, kb.lower(kk), true);
                    }
                    for kk in split..rp[r + 1] {
                        entry!(kk, kb.upper(kk), B::UPPER_A);
                    }
                    *br = us[r]
                        .scale(ms[r])
                        .scale(cm)
                        .add(ku.scale(cu))
                        .add(vs[r].scale(ms[r]).scale(cv))
                        .add(fs[r].scale(dt));
                }
            },
        )
    });
}

#[cfg(test)]
mod tests {
    use crate::fem::{Aabb, Grid, Model, Simulation};
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

    /// A corotated cuboid held at one end (Nitsche cells), large enough for the parallel
    /// passes, a few steps in.
    fn sim(threads: usize) -> Simulation {
        let shape = Shape::Box {
            center: [0.0, 1.0, 0.0],
            size: [1.29, 0.4, 0.8],
        };
        let grid = Grid::new(shape.to_sdf(16.0, 6).unwrap()).unwrap();
        let model = Model {
            young: 2000.0,
            gravity: Vec3::new(0.0, -10.0, 0.0),
            corotation: true,
            dirichlet: vec![Aabb {
                min: [-0.9, 0.6, -0.6],
                max: [-0.55, 1.4, 0.6],
            }],
            dt: 0.01,
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

    /// The step's fused passes give the same bits on 1 and 3 threads, and the same bits as
    /// the plain two-pass stiffness assembly and the Newmark system as gpumat expressions.
    #[test]
    fn step_assembly_is_thread_independent_and_matches_the_plain_passes() {
        let (one, three) = (sim(1), sim(3));
        assert_eq!(bits_m(one.stiffness()), bits_m(three.stiffness()));
        assert_eq!(bits_m(one.newmark_matrix()), bits_m(three.newmark_matrix()));
        assert_eq!(bits_v(one.newmark_rhs()), bits_v(three.newmark_rhs()));
        assert_eq!(bits_v(one.force()), bits_v(three.force()));

        let s = &one;
        let (lambda, mu) = s.model.lame();
        let m = crate::fem::Material {
            lambda,
            mu,
            eta: s.model.nitsche_eta,
        };
        let mut k = SparseMatrix::zeros(s.assembler.pattern().clone(), 1);
        let blocks = s.element_blocks().unwrap();
        s.assembler
            .assemble_stiffness(&s.grid, &m, blocks, s.rotations(), &s.dirichlet, None, &mut k);
        assert_eq!(bits_m(&k), bits_m(s.stiffness()));

        let (model, dt, theta) = (&s.model, s.model.dt, s.model.theta);
        let cm = 1.0 / (theta * dt) + model.damping_mass;
        let mut a = SparseMatrix::zeros(k.pattern().clone(), 1);
        a.assign(
            (s.mass.ex().cast::<Mat3<f64>>().as_diagonal() * cm
                + k.ex() * (model.damping_stiffness + theta * dt))
                .sparse_view(k.pattern()),
        );
        assert_eq!(bits_m(&a), bits_m(s.newmark_matrix()));
        let mut b = Matrix::zeros(k.rows(), 1, 1);
        b.assign(
            s.mass.ex().cwise_mul(s.u.ex()) * cm
                + (&k * &s.u) * (model.damping_stiffness - (1.0 - theta) * dt)
                + s.mass.ex().cwise_mul(s.v.ex()) * (1.0 / theta)
                + s.force().ex() * dt,
        );
        assert_eq!(bits_v(&b), bits_v(s.newmark_rhs()));
    }
}
