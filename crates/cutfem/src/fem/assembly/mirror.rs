//! The blocks below the diagonal of a symmetric matrix (`K`, `A`) as the transposes of their
//! mirrors above it: the assembly computes the blocks on and above the diagonal only (every
//! element block satisfies `K_ji = K_ij^T`, rotated or not, and so do the Nitsche terms).

use super::{for_each_item, Assembler, ROW_CHUNK};
use gpumat::raw::SharedParts;
use gpumat::Mat3;

impl Assembler {
    /// Each block below the diagonal of `k` from its mirror above it, in place.
    pub(super) fn mirror_lower(&self, parallel: bool, k: &mut [Mat3<f64>]) {
        let n = self.pattern.rows();
        assert!(k.len() == self.pattern.nnz(), "cutfem: values of another pattern");
        let kw = SharedParts::new(k);
        let items: Vec<usize> = (0..n.div_ceil(ROW_CHUNK)).collect();
        for_each_item(parallel, items, |ci| {
            let rows = ci * ROW_CHUNK..((ci + 1) * ROW_CHUNK).min(n);
            // SAFETY: the blocks below the diagonal of `rows` are written by this task alone;
            // their mirrors lie on or above the diagonal, written by the finished row sweep and
            // only read in this pass.
            unsafe { self.mirror_rows(rows, kw, None) }
        });
    }

    /// The blocks below the diagonal of the rows `rows` of `a` (and `k`) from their mirrors.
    ///
    /// # Safety
    /// No other task reads or writes the blocks below the diagonal of `rows`, and no task
    /// writes their mirrors (the blocks on or above the diagonal of the rows they belong to)
    /// while this runs.
    pub(super) unsafe fn mirror_rows(
        &self,
        rows: std::ops::Range<usize>,
        a: SharedParts<'_, Mat3<f64>>,
        k: Option<SharedParts<'_, Mat3<f64>>>,
    ) {
        let rp = self.pattern.row_ptr();
        gpumat::simd::with_avx2(
            #[inline(always)]
            || {
                for r in rows {
                    for kk in rp[r]..self.diag[r] as usize {
                        let m = self.mirror[kk] as usize;
                        // SAFETY: the caller's contract.
                        unsafe {
                            a.write(kk, a.read(m).transpose());
                            if let Some(k) = &k {
                                k.write(kk, k.read(m).transpose());
                            }
                        }
                    }
                }
            },
        )
    }
}
