//! Assignment: the single place where an expression tree becomes a loop over memory.
//!
//! The output is cut into chunks of about [`CHUNK_BYTES`] of reads and writes each (by the
//! tree's [`Expr::bytes_per_element`]: a sparse product's row reads a whole row of blocks, a
//! sum of two vectors two elements). Loops that touch fewer than [`PAR_BYTES`] run on the
//! calling thread; larger ones in parallel on rayon's pool, in at least four chunks per
//! thread. Each output element is computed independently, so the result does not depend on
//! the thread count or the chunks. When no node below needs broadcasting or reordering the tree is read by linear
//! index (one contiguous stream per operand, which the compiler vectorizes); otherwise by
//! `(r, c, b)` coordinates, in runs along the rows (so broadcast leaves stay vectorizable).
//! On x86-64 CPUs with AVX2 the loops run in a copy compiled for AVX2 (runtime detection;
//! the default target has only SSE2).

use super::{Ex, Expr, SelfRef};
use crate::matrix::{Matrix, Shape};
use crate::scalar::Scalar;
use crate::stats;
use rayon::prelude::*;

/// Element count from which the sparse-value fills ([`crate::sparse`]) run in parallel.
pub const PAR_THRESHOLD: usize = 1 << 15;
/// Loops that read and write at least this many bytes run in parallel (a rayon dispatch costs
/// a few microseconds; 1 MiB takes tens).
pub const PAR_BYTES: usize = 1 << 20;
/// Bytes read and written per work item.
const CHUNK_BYTES: usize = 1 << 19;
/// Bounds of the elements per work item.
const CHUNK: usize = 1 << 13;
const MIN_CHUNK: usize = 256;
/// Outputs with at least this many rows are evaluated run by run along the rows when the tree
/// cannot be read linearly; shorter columns are walked element by element.
const MIN_RUN: usize = 16;

/// Evaluates `e` at the output positions `start..start + chunk.len()` into `chunk`.
///
/// # Safety
/// `e` broadcasts to `out`, `linear == e.linear(out)`, `out.rows > 0` and
/// `start + chunk.len() <= out.len()`.
#[inline(always)]
unsafe fn eval_chunk<T: Scalar, E: Expr<Elem = T>>(
    e: &E,
    out: Shape,
    linear: bool,
    start: usize,
    chunk: &mut [T],
) {
    if linear {
        for (j, d) in chunk.iter_mut().enumerate() {
            // SAFETY: `linear(out)` holds and `start + j < out.len()`.
            *d = unsafe { e.at_linear(start + j) };
        }
    } else if out.rows >= MIN_RUN {
        // Runs along the rows: within a run `c` and `b` are fixed, so every leaf's index is
        // affine in `r` (or constant, for a leaf broadcast over rows) and the loop vectorizes
        // like the linear one (a `1 x 1 x 1` scalar such as CG's step size no longer forces
        // element-by-element index arithmetic).
        let rows = out.rows;
        let mut done = 0;
        while done < chunk.len() {
            let i = start + done;
            let r0 = i % rows;
            let cb = i / rows;
            let (c, b) = (cb % out.cols, cb / out.cols);
            let run = (rows - r0).min(chunk.len() - done);
            for (j, d) in chunk[done..done + run].iter_mut().enumerate() {
                // SAFETY: `r0 + j < rows`, and `(c, b)` is inside the output shape because
                // `i < out.len()`; `e` broadcasts to it.
                *d = unsafe { e.at(r0 + j, c, b) };
            }
            done += run;
        }
    } else {
        let (rows, cols) = (out.rows, out.cols);
        let mut r = start % rows;
        let mut c = (start / rows) % cols;
        let mut b = start / (rows * cols);
        for d in chunk.iter_mut() {
            // SAFETY: (r, c, b) enumerates the output shape, to which `e` broadcasts.
            *d = unsafe { e.at(r, c, b) };
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
    }
}

/// [`eval_chunk`] compiled with AVX2 enabled: the default x86-64 target only has 128-bit SSE2
/// vectors, so the fused loops run about twice as fast on cache-resident data this way. The
/// arithmetic per element is the same (no FMA contraction), so results are bitwise equal.
///
/// # Safety
/// The CPU supports AVX2, and `eval_chunk`'s contract holds.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn eval_chunk_avx2<T: Scalar, E: Expr<Elem = T>>(
    e: &E,
    out: Shape,
    linear: bool,
    start: usize,
    chunk: &mut [T],
) {
    // SAFETY: forwarded contract.
    unsafe { eval_chunk(e, out, linear, start, chunk) }
}

/// True when the fused loops may use [`eval_chunk_avx2`] (detected once, then cached by std).
#[inline]
fn use_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

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
    if dst.is_empty() {
        return;
    }
    let linear = e.linear(out);
    let avx2 = use_avx2();
    let run = |start: usize, chunk: &mut [T]| {
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: AVX2 was detected on this CPU; `e` broadcasts to `out` (checked above),
            // `linear` is `e.linear(out)`, `out` is not empty, and the chunk starting at
            // `start` lies inside `dst`, which has `out.len()` elements.
            unsafe { eval_chunk_avx2(e, out, linear, start, chunk) };
            return;
        }
        let _ = avx2;
        // SAFETY: as above, without the AVX2 requirement.
        unsafe { eval_chunk(e, out, linear, start, chunk) };
    };
    let bytes = e.bytes_per_element() + std::mem::size_of::<T>();
    let (parallel, size) = schedule(dst.len(), bytes);
    if parallel {
        dst.par_chunks_mut(size)
            .enumerate()
            .for_each(|(k, chunk)| run(k * size, chunk));
    } else {
        for (k, chunk) in dst.chunks_mut(size).enumerate() {
            run(k * size, chunk);
        }
    }
}

/// True when a loop that reads and writes `bytes` in all should run on rayon's pool.
pub(crate) fn worth_parallel(bytes: usize) -> bool {
    rayon::current_num_threads() > 1 && bytes >= PAR_BYTES
}

/// How a loop over `len` elements that each read and write `bytes` runs: in parallel or not,
/// and the elements per work item (about [`CHUNK_BYTES`] each, at least four items per thread
/// when parallel).
pub(crate) fn schedule(len: usize, bytes: usize) -> (bool, usize) {
    let threads = rayon::current_num_threads();
    let parallel = len > 1 && worth_parallel(len.saturating_mul(bytes));
    let mut size = (CHUNK_BYTES / bytes.max(1)).clamp(MIN_CHUNK, CHUNK);
    if parallel {
        size = size.min(len.div_ceil(4 * threads)).max(16);
    }
    (parallel, size.min(len).max(1))
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

#[cfg(test)]
mod tests {
    use super::{schedule, CHUNK, PAR_BYTES};
    use crate::Matrix;

    /// The run-by-run path (rows >= MIN_RUN, a leaf broadcast over rows, chunks starting in
    /// the middle of a column, parallel) gives exactly the element-by-element values.
    #[test]
    fn broadcast_runs_match_elementwise_values() {
        let (rows, cols, batches) = (21, 3, 700);
        let a = Matrix::<f32>::from_fn(rows, cols, batches, |r, c, b| (r + 7 * c + 13 * b) as f32 * 0.25);
        let s = Matrix::<f32>::from_fn(1, cols, batches, |_, c, b| 1.0 + (c + b) as f32);
        let mut d = Matrix::<f32>::zeros(rows, cols, batches);
        d.assign(a.ex() + s.ex().cwise_mul(a.ex()));
        for b in 0..batches {
            for c in 0..cols {
                for r in 0..rows {
                    let (x, y) = (a.get(r, c, b), s.get(0, c, b));
                    assert_eq!(d.get(r, c, b), x + y * x, "at ({r}, {c}, {b})");
                }
            }
        }
        let mut short = Matrix::<f32>::zeros(3, 2, 1);
        let col = Matrix::<f32>::from_slice(3, 1, 1, &[1.0, 2.0, 3.0]);
        short.assign(col.ex() + crate::scalar(1.0f32));
        assert_eq!(short.as_slice(), &[2.0, 3.0, 4.0, 2.0, 3.0, 4.0]);
    }

    /// Small loops stay on the calling thread; a loop is parallel by the bytes it touches, not
    /// its element count (a sparse product's few long rows go parallel), in at least four
    /// items per thread; the items cover the output.
    #[test]
    fn loops_are_scheduled_by_the_bytes_they_touch() {
        let threads = rayon::current_num_threads();
        assert_eq!(schedule(1000, 12), (false, 1000));
        assert!(!schedule(PAR_BYTES / 12 - 1, 12).0);
        assert!(!schedule(0, 12).0 && schedule(0, 12).1 >= 1);
        let (par, size) = schedule(4000, 2700);
        assert_eq!(par, threads > 1, "4000 rows of a stiffness matrix");
        if par {
            assert!(4000usize.div_ceil(size) >= 4 * threads);
        }
        let (par, size) = schedule(1 << 24, 12);
        assert_eq!(par, threads > 1);
        assert!(size <= CHUNK && (1usize << 24).div_ceil(size) >= 4 * threads);
    }
}
