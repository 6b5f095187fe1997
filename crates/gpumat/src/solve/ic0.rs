//! Block incomplete Cholesky IC(0) on a 3x3 BSR pattern: `A ~ (D + L) D^-1 (D + L^T)` with
//! `L^T = U` the strict upper block triangle kept on `A`'s own pattern (no fill) and `D` the
//! 3x3 pivot blocks.
//!
//! The factor is computed row by row (left-looking): `D_i = A_ii - sum_k U_ki^T D_k^-1 U_ki`
//! and `U_ij = A_ij - sum_k U_ki^T D_k^-1 U_kj` over the earlier rows `k < i` coupled to `i`,
//! dropping every update outside the pattern. Only the upper triangle of `A` is read (`A` is
//! taken as symmetric). Applying the preconditioner is one forward and one backward block
//! substitution over the stored upper triangle, sequential and therefore deterministic.
//!
//! Options ([`Ic0Params`]): a relaxation `omega` in `[0, 1]` gives the relaxed *modified*
//! IC(0): every dropped update `F` at `(i, j)` is, symmetrized, moved onto the pivot blocks
//! of rows `i` and `j` scaled by `omega` (`omega = 1`: MIC(0), which keeps the row sums, i.e.
//! `M` acts like `A` on constant fields such as rigid translations). On the Table B.5
//! cuboid `omega = 0.95` needs about 40% fewer CG iterations than plain IC(0). A `shift`
//! factors `A + shift diag(A)` (a Manteuffel shift), which exists for a large enough shift.
//! A pivot block that is not positive definite gives [`Error::NotPositiveDefinite`]; while
//! every pivot is, `M` is symmetric positive definite whatever the options.

use super::Preconditioner;
use crate::block::{Mat3, Vec3};
use crate::error::Error;
use crate::matrix::Matrix;
use crate::scalar::{Real, Scalar};
use crate::sparse::SparseMatrix;

/// Options of [`BlockIc0::with_params`] (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Ic0Params {
    /// relative diagonal shift: factor `A + shift diag(A)`
    pub shift: f64,
    /// fraction of the dropped fill moved onto the pivot blocks (0: IC(0), 1: MIC(0))
    pub relaxation: f64,
}

/// Block IC(0) of every batch of a symmetric positive definite BSR matrix.
#[derive(Clone, Debug)]
pub struct BlockIc0<R: Real> {
    rows: usize,
    batches: usize,
    /// strict upper part: row pointers into `col`/`upper`
    ptr: Vec<usize>,
    col: Vec<u32>,
    /// `U`, batch after batch (`ptr[rows]` blocks each)
    upper: Vec<Mat3<R>>,
    /// `D^-1`, batch after batch
    dinv: Vec<Mat3<R>>,
}

/// `M^T v`.
#[inline(always)]
fn mul_t<R: Real>(m: &Mat3<R>, v: Vec3<R>) -> Vec3<R> {
    let m = &m.m;
    Vec3::new(
        m[0][0] * v.x + m[1][0] * v.y + m[2][0] * v.z,
        m[0][1] * v.x + m[1][1] * v.y + m[2][1] * v.z,
        m[0][2] * v.x + m[1][2] * v.y + m[2][2] * v.z,
    )
}

/// The first lane whose leading minor of the (symmetric part of the) 3x3 block is not
/// positive, if any.
fn not_spd<R: Real>(d: &Mat3<R>) -> Option<usize> {
    let m = &d.m;
    let m1 = m[0][0];
    let m2 = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    let m3 = d.determinant();
    [m1, m2, m3].iter().position(|&x| !(x > R::ZERO && x.is_finite()))
}

impl<R: Real> BlockIc0<R>
where
    Mat3<R>: Scalar,
    Vec3<R>: Scalar,
{
    /// Plain IC(0) of every batch of `a` (square, with every diagonal block stored).
    pub fn new(a: &SparseMatrix<Mat3<R>>) -> Result<Self, Error> {
        Self::with_params(a, Ic0Params::default())
    }

    /// The factorization with a shift and a relaxation (module docs).
    pub fn with_params(a: &SparseMatrix<Mat3<R>>, params: Ic0Params) -> Result<Self, Error> {
        let p = a.pattern();
        if p.rows() != p.cols() {
            return Err(Error::NotSquare {
                rows: p.rows(),
                cols: p.cols(),
            });
        }
        let rows = p.rows();
        let diag = p.diagonal_entries();
        if let Some(row) = diag.iter().position(Option::is_none) {
            return Err(Error::MissingDiagonal { row });
        }
        // The strict upper part, and its columns (k, entry) with k < i for every column i.
        let mut ptr = Vec::with_capacity(rows + 1);
        let mut col = Vec::new();
        let mut src = Vec::new();
        ptr.push(0);
        for r in 0..rows {
            for k in p.row_range(r) {
                let c = p.col_idx()[k];
                if c as usize > r {
                    col.push(c);
                    src.push(k);
                }
            }
            ptr.push(col.len());
        }
        let mut cptr = vec![0usize; rows + 1];
        for &c in &col {
            cptr[c as usize + 1] += 1;
        }
        for i in 0..rows {
            cptr[i + 1] += cptr[i];
        }
        let mut fill = cptr.clone();
        let mut centry = vec![(0u32, 0usize); col.len()];
        for r in 0..rows {
            for (e, &c) in col.iter().enumerate().take(ptr[r + 1]).skip(ptr[r]) {
                centry[fill[c as usize]] = (r as u32, e);
                fill[c as usize] += 1;
            }
        }
        let nu = col.len();
        let mut this = Self {
            rows,
            batches: a.batches(),
            ptr,
            col,
            upper: Vec::with_capacity(nu * a.batches()),
            dinv: Vec::with_capacity(rows * a.batches()),
        };
        let scale = R::of(1.0 + params.shift);
        let omega = R::of(params.relaxation);
        let half = R::of(0.5);
        let mut pos = vec![usize::MAX; rows];
        // dropped fill moved onto later pivots (relaxed modified IC)
        let mut moved = vec![Mat3::<R>::default(); rows];
        for b in 0..a.batches() {
            let vals = a.batch_values(b);
            let base = this.upper.len();
            let dbase = this.dinv.len();
            this.upper.extend(src.iter().map(|&k| vals[k]));
            let u = &mut this.upper[base..];
            moved.iter_mut().for_each(|m| *m = Mat3::default());
            for i in 0..rows {
                let (s, e) = (this.ptr[i], this.ptr[i + 1]);
                for (q, &c) in this.col[s..e].iter().enumerate() {
                    pos[c as usize] = s + q;
                }
                let mut d = vals[diag[i].expect("checked above")];
                for l in 0..3 {
                    d.m[l][l] *= scale;
                }
                d = d - moved[i];
                for &(k, eki) in &centry[cptr[i]..cptr[i + 1]] {
                    let k = k as usize;
                    let uki = u[eki];
                    let w = uki.transpose() * this.dinv[dbase + k];
                    d = d - w * uki;
                    for f in eki + 1..this.ptr[k + 1] {
                        let t = pos[this.col[f] as usize];
                        if t != usize::MAX {
                            u[t] = u[t] - w * u[f];
                        } else if omega != R::ZERO {
                            let g = w * u[f];
                            let g = (g + g.transpose()) * (half * omega);
                            d = d - g;
                            let j = this.col[f] as usize;
                            moved[j] = moved[j] + g;
                        }
                    }
                }
                for &c in &this.col[s..e] {
                    pos[c as usize] = usize::MAX;
                }
                if let Some(l) = not_spd(&d) {
                    return Err(Error::NotPositiveDefinite {
                        batch: b,
                        pivot: 3 * i + l,
                    });
                }
                let inv = d.inverse().ok_or(Error::NotPositiveDefinite {
                    batch: b,
                    pivot: 3 * i,
                })?;
                this.dinv.push(inv);
            }
        }
        Ok(this)
    }

    /// Number of factored batches.
    pub fn batches(&self) -> usize {
        self.batches
    }

    /// Stored blocks of the strict upper factor `U` (per batch).
    pub fn upper_blocks(&self) -> usize {
        self.col.len()
    }

    /// `z = M^-1 z` in place for batch `b` of the factor.
    fn solve_batch(&self, b: usize, z: &mut [Vec3<R>]) {
        let nu = self.col.len();
        let u = &self.upper[b * nu..(b + 1) * nu];
        let dinv = &self.dinv[b * self.rows..(b + 1) * self.rows];
        // (D + U^T) w = r, column by column: w_k = D_k^-1 t_k, then t_j -= U_kj^T w_k.
        for k in 0..self.rows {
            let w = dinv[k] * z[k];
            z[k] = w;
            let (s, e) = (self.ptr[k], self.ptr[k + 1]);
            for (m, &c) in u[s..e].iter().zip(&self.col[s..e]) {
                let c = c as usize;
                z[c] = z[c] - mul_t(m, w);
            }
        }
        // (D + U) z = D w: z_i = w_i - D_i^-1 sum_j U_ij z_j.
        for i in (0..self.rows).rev() {
            let (s, e) = (self.ptr[i], self.ptr[i + 1]);
            let mut acc = Vec3::new(R::ZERO, R::ZERO, R::ZERO);
            for (m, &c) in u[s..e].iter().zip(&self.col[s..e]) {
                acc = acc + *m * z[c as usize];
            }
            z[i] = z[i] - dinv[i] * acc;
        }
    }
}

impl<R: Real> Preconditioner<Vec3<R>> for BlockIc0<R>
where
    Mat3<R>: Scalar,
    Vec3<R>: Scalar,
{
    #[track_caller]
    fn apply(&self, r: &Matrix<Vec3<R>>, z: &mut Matrix<Vec3<R>>) {
        assert!(
            r.rows() == self.rows && r.cols() == 1 && (self.batches == 1 || self.batches == r.batches()),
            "gpumat::BlockIc0: residual is {:?} for {} rows and {} factors",
            r.shape(),
            self.rows,
            self.batches
        );
        z.assign(r.ex());
        for b in 0..r.batches() {
            let f = if self.batches == 1 { 0 } else { b };
            self.solve_batch(f, z.batch_mut(b));
        }
    }
}
