//! Assignment: the single place where an expression tree becomes a loop over memory.
//!
//! The output is cut into fixed chunks of [`CHUNK`] elements. Below [`PAR_THRESHOLD`]
//! elements the chunks run on the calling thread; above, in parallel on rayon's pool. Each
//! output element is computed independently, so the result does not depend on the thread
//! count. When no node below needs broadcasting or reordering the tree is read by linear
//! index (one contiguous stream per operand, which the compiler vectorizes); otherwise by
//! `(r, c, b)` coordinates.

use super::{Ex, Expr, SelfRef};
use crate::matrix::{Matrix, Shape};
use crate::scalar::Scalar;
use crate::stats;
use rayon::prelude::*;

/// Outputs with at least this many elements are evaluated in parallel.
pub const PAR_THRESHOLD: usize = 1 << 15;
/// Elements per work item.
const CHUNK: usize = 1 << 13;

/// Evaluates `e` into `dst` (shape `out`). `e` must broadcast to `out`.
#[track_caller]
pub(crate) fn assign_slice<T: Scalar, E: Expr<Elem = T>>(dst: &mut [T], out: Shape, e: &E, op: &str) {
    let es = e.shape();
    assert!(
        es.broadcasts_to(out),
        "gpumat::{op}: expression of shape {es:?} does not fit destination {out:?}"
    );
    assert_eq!(dst.len(), out.len());
    stats::count_pass();
    let linear = e.linear(out);
    let run = |start: usize, chunk: &mut [T]| {
        if linear {
            for (j, d) in chunk.iter_mut().enumerate() {
                // SAFETY: `linear(out)` holds and `start + j < out.len()`.
                *d = unsafe { e.at_linear(start + j) };
            }
        } else {
            let (rows, cols) = (out.rows, out.cols);
            let mut i = start;
            let mut r = i % rows;
            let mut c = (i / rows) % cols;
            let mut b = i / (rows * cols);
            for d in chunk.iter_mut() {
                // SAFETY: (r, c, b) enumerates the output shape, to which `e` broadcasts.
                *d = unsafe { e.at(r, c, b) };
                i += 1;
                r += 1;
                if r == rows {
                    r = 0;
                    c += 1;
                    if c == cols {
                        c = 0;
                        b += 1;
                    }
                }
            }
            let _ = i;
        }
    };
    if dst.len() >= PAR_THRESHOLD {
        dst.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(k, chunk)| run(k * CHUNK, chunk));
    } else {
        for (k, chunk) in dst.chunks_mut(CHUNK).enumerate() {
            run(k * CHUNK, chunk);
        }
    }
}

impl<T: Scalar> Matrix<T> {
    /// `self = e`, evaluated in one pass. The shape of `e` must broadcast to `self`'s.
    ///
    /// ```
    /// use gpumat::Matrix;
    /// let a = Matrix::<f32>::from_slice(3, 1, 1, &[1.0, 4.0, 9.0]);
    /// let b = Matrix::<f32>::from_slice(3, 1, 1, &[1.0, 1.0, 1.0]);
    /// let mut d = Matrix::<f32>::zeros(3, 1, 1);
    /// d.assign(a.ex() + b.ex() * 2.0 + a.ex().sqrt());
    /// assert_eq!(d.as_slice(), &[4.0, 8.0, 14.0]);
    /// ```
    #[track_caller]
    pub fn assign<E: Expr<Elem = T>>(&mut self, e: Ex<E>) {
        let out = self.shape();
        assign_slice(self.as_mut_slice(), out, &e.0, "assign");
    }

    /// `self = f(self)`, evaluated in one pass: `f` receives the destination's current value
    /// as an expression leaf, usable element-wise only (gathers such as SpMV or transpose of
    /// it are refused at compile time).
    ///
    /// ```
    /// use gpumat::Matrix;
    /// let z = Matrix::<f64>::from_slice(2, 1, 1, &[1.0, 2.0]);
    /// let mut p = Matrix::<f64>::from_slice(2, 1, 1, &[10.0, 20.0]);
    /// p.assign_with(|p| z.ex() + p * 0.5); // p = z + 0.5 p
    /// assert_eq!(p.as_slice(), &[6.0, 12.0]);
    /// ```
    #[track_caller]
    pub fn assign_with<E, F>(&mut self, f: F)
    where
        E: Expr<Elem = T>,
        F: FnOnce(Ex<SelfRef<T>>) -> Ex<E>,
    {
        let out = self.shape();
        let slice = self.as_mut_slice();
        let leaf = SelfRef {
            ptr: slice.as_ptr(),
            shape: out,
        };
        let e = f(Ex(leaf));
        assign_slice(slice, out, &e.0, "assign_with");
    }
}

macro_rules! compound {
    ($tr:ident, $m:ident, $op:tt) => {
        impl<T: Scalar, E: Expr<Elem = T>> std::ops::$tr<Ex<E>> for Matrix<T> {
            /// Compound assignment in one pass.
            #[track_caller]
            fn $m(&mut self, e: Ex<E>) {
                self.assign_with(|d| d $op e);
            }
        }
        impl<'a, T: Scalar> std::ops::$tr<&'a Matrix<T>> for Matrix<T> {
            /// Compound assignment in one pass.
            #[track_caller]
            fn $m(&mut self, m: &'a Matrix<T>) {
                self.assign_with(|d| d $op m.ex());
            }
        }
    };
}
compound!(AddAssign, add_assign, +);
compound!(SubAssign, sub_assign, -);

macro_rules! compound_scale {
    ($r:ty) => {
        impl<T: Scalar<Real = $r>> std::ops::MulAssign<$r> for Matrix<T> {
            /// `self *= s` in one pass.
            fn mul_assign(&mut self, s: $r) {
                self.assign_with(|d| d * s);
            }
        }
        impl<T: Scalar<Real = $r>> std::ops::DivAssign<$r> for Matrix<T> {
            /// `self /= s` in one pass.
            fn div_assign(&mut self, s: $r) {
                self.assign_with(|d| d * (1.0 / s));
            }
        }
    };
}
compound_scale!(f32);
compound_scale!(f64);
