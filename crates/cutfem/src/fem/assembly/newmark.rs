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

use super::{Assembler, EntryWriter, ROW_CHUNK};
use crate::fem::model::Model;
use gpumat::{Mat3, Matrix, Scalar, ScalarMul, SparseMatrix, SparsityPattern, Vec3};
use rayon::prelude::*;

/// Where the pass reads the blocks of `K`.
trait Blocks: Sync {
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

/// A `K` with only the blocks on and above the diagonal: each block below it is written as the
/// transpose of its mirror when read.
struct Mirroring<'a> {
    k: EntryWriter,
    diag: &'a [u32],
    mirror: &'a [u32],
}

impl Blocks for Mirroring<'_> {
    #[inline(always)]
    fn split(&self, r: usize, _start: usize) -> usize {
        self.diag[r] as usize
    }
    #[inline(always)]
    fn lower(&self, kk: usize) -> Mat3<f64> {
        // SAFETY: entries on or above the diagonal (the mirrors) are only read in this pass;
        // each entry below it is in one row, whose task alone writes it, once, and no task
        // reads it.
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
    /// `A` and `b` of the Newmark system of a step, completing `k` (whose blocks on and above
    /// the diagonal [`Assembler::assemble_upper_with_forces`] wrote) in the same pass.
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
    let (dt, theta) = (model.dt, model.theta);
    let (a1, a2) = (model.damping_mass, model.damping_stiffness);
    let cm = 1.0 / (theta * dt) + a1;
    let ck = a2 + theta * dt;
    let cu = a2 - (1.0 - theta) * dt;
    let cv = 1.0 / theta;
    // `(cm M)_rc` off the diagonal: `0 cm`
    let off = Mat3::ZERO.scale(cm);
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
    let chunks = p.split_rows_mut(a.batch_values_mut(0), ROW_CHUNK);
    chunks
        .into_par_iter()
        .zip(b.as_mut_slice().par_chunks_mut(ROW_CHUNK))
        .for_each(|((r0, av), bc)| {
            gpumat::simd::with_avx2(
                #[inline(always)]
                || {
                    let base = rp[r0];
                    for (o, br) in bc.iter_mut().enumerate() {
                        let r = r0 + o;
                        let mut ku = Vec3::ZERO;
                        // a macro, so that the entry code inlines into this AVX2 function
                        macro_rules! entry {
                            ($kk:expr, $k:expr) => {{
                                let (kk, k): (usize, Mat3<f64>) = ($kk, $k);
                                let c = cols[kk] as usize;
                                ku = ku.add(k.smul(us[c]));
                                let m = if c == r {
                                    Mat3::from_scalar(ms[r]).scale(cm)
                                } else {
                                    off
                                };
                                av[kk - base] = m.add(k.scale(ck));
                            }};
                        }
                        let split = kb.split(r, rp[r]);
                        for kk in rp[r]..split {
                            entry!(kk, kb.lower(kk));
                        }
                        for kk in split..rp[r + 1] {
                            entry!(kk, kb.upper(kk));
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
