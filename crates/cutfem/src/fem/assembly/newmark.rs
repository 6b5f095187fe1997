//! The Newmark-1 system with Rayleigh damping (thesis eq. 2.6.2, see [`crate::fem::sim`]):
//!
//! `A = cm M + ck K`, `b = cm M u + cu K u + M v / theta + dt f` with `cm = 1/(theta dt) + a1`,
//! `ck = a2 + theta dt`, `cu = a2 - (1-theta) dt`. A nodal damping force `-c W v`
//! ([`crate::fem::NodalDamping`], the `drag` effect) joins the mass damping `a1 M`: `A += c W`,
//! `b += c W u`.
//!
//! [`newmark_system`] fills both from a complete `K` in one pass over its rows (the tet
//! simulation's path): each task owns a fixed block of rows, reads each block of its rows
//! once, writes the row's blocks of `A` and its entry of `b`, with `(K u)_r` summed in column
//! order, so the values do not depend on the number of threads. A grid step never stores `K`
//! for this: its cell sweep computes `cu K u` with the corotation force cell by cell
//! ([`super::cells`]) and its row sweep writes `A` ([`super::step`]).

use super::{for_each_item, ROW_CHUNK};
use crate::fem::model::{Model, NodalDamping};
use gpumat::{Mat3, Matrix, Scalar, ScalarMul, SparseMatrix, Vec3};
use std::sync::Arc;

/// The coefficients of `A = cm M + ck K`, `b = cm M u + cu K u + cv M v + dt f`.
pub(crate) struct Coefficients {
    pub(crate) cm: f64,
    pub(crate) ck: f64,
    pub(crate) cu: f64,
    pub(crate) cv: f64,
    pub(crate) dt: f64,
    /// `(cm M)_rc` off the diagonal: `0 cm`
    pub(crate) off: Mat3<f64>,
    /// the model's nodal damping, if any
    pub(crate) drag: Option<NodalDamping>,
}

impl Coefficients {
    /// Those of `model`.
    pub(crate) fn new(model: &Model) -> Self {
        let c = model.newmark();
        Self {
            cm: c.cm,
            ck: c.ck,
            cu: c.cu,
            cv: c.cv,
            dt: c.dt,
            off: Mat3::ZERO.scale(c.cm),
            drag: model.drag.clone(),
        }
    }
    /// `(cm M + c W)_rr` for the lumped mass `m` of row `r`.
    #[inline(always)]
    pub(crate) fn diagonal(&self, r: usize, m: f64) -> Mat3<f64> {
        let d = Mat3::from_scalar(m).scale(self.cm);
        match &self.drag {
            Some(n) => d.add(Mat3::from_scalar(n.coefficient * n.weights[r])),
            None => d,
        }
    }
    /// `(cm M u + c W u)_r` for the lumped mass `m` and displacement `u` of row `r`.
    #[inline(always)]
    pub(crate) fn mass_u(&self, r: usize, m: f64, u: Vec3<f64>) -> Vec3<f64> {
        let d = u.scale(m).scale(self.cm);
        match &self.drag {
            Some(n) => d.add(u.scale(n.coefficient * n.weights[r])),
            None => d,
        }
    }
}

/// The Newmark-1 system with Rayleigh damping (module docs, eq. 2.6.2): `A` on `K`'s pattern
/// and `b`, in one fused pass over the rows of `K` (each block of `K` read once; fixed row
/// blocks per task and sums in column order, so the values do not depend on the number of
/// threads). Shared by the grid and the tet simulations.
#[allow(clippy::too_many_arguments)]
pub fn newmark_system(
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
    let nw = Coefficients::new(model);
    let (ck, cu, cv, dt, off) = (nw.ck, nw.cu, nw.cv, nw.dt, nw.off);
    let p = k.pattern().clone();
    let kv = k.values();
    let n = p.rows();
    assert!(
        (Arc::ptr_eq(a.pattern(), &p) || a.pattern().as_ref() == p.as_ref()) && a.batches() == 1,
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
                    for kk in rp[r]..rp[r + 1] {
                        let (k, c) = (kv[kk], cols[kk] as usize);
                        ku = ku.add(k.smul(us[c]));
                        let m = if c == r { nw.diagonal(r, ms[r]) } else { off };
                        av[kk - base] = m.add(k.scale(ck));
                    }
                    *br = nw
                        .mass_u(r, ms[r], us[r])
                        .add(ku.scale(cu))
                        .add(vs[r].scale(ms[r]).scale(cv))
                        .add(fs[r].scale(dt));
                }
            },
        )
    });
}
