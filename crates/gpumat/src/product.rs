//! Dense matrix products, batched, through faer's GEMM.
//!
//! `C(:,:,b) = A(:,:,b) * B(:,:,b)`; a batch dimension of size 1 broadcasts. Products are
//! evaluated eagerly into a new matrix (as in cuMat, where a product inside an expression is
//! first evaluated into a temporary).

use crate::matrix::{Matrix, Shape};
use crate::scalar::Real;
use faer::linalg::matmul::matmul as faer_matmul;
use faer::{Accum, Par};
use rayon::prelude::*;

/// `A * B`, batched.
///
/// ```
/// use gpumat::{matmul, Matrix};
/// let a = Matrix::<f64>::from_slice(2, 2, 1, &[1.0, 3.0, 2.0, 4.0]); // [[1,2],[3,4]]
/// let b = Matrix::<f64>::from_slice(2, 1, 1, &[1.0, 1.0]);
/// assert_eq!(matmul(&a, &b).as_slice(), &[3.0, 7.0]);
/// ```
#[track_caller]
pub fn matmul<R: Real>(a: &Matrix<R>, b: &Matrix<R>) -> Matrix<R> {
    // Only the batch dimensions broadcast; rows and columns follow the product rule.
    let batches = Shape::new(1, 1, a.batches())
        .broadcast(Shape::new(1, 1, b.batches()), "matmul")
        .batches;
    let mut c = Matrix::zeros(a.rows(), b.cols(), batches);
    matmul_into(&mut c, a, b, R::ONE, false);
    c
}

/// `C = alpha A B` (or `C += alpha A B` when `accumulate`), batched.
#[track_caller]
pub fn matmul_into<R: Real>(c: &mut Matrix<R>, a: &Matrix<R>, b: &Matrix<R>, alpha: R, accumulate: bool) {
    assert_eq!(
        a.cols(),
        b.rows(),
        "gpumat::matmul: inner dimensions {} and {} differ",
        a.cols(),
        b.rows()
    );
    assert!(
        c.rows() == a.rows() && c.cols() == b.cols(),
        "gpumat::matmul: destination is {}x{}, product is {}x{}",
        c.rows(),
        c.cols(),
        a.rows(),
        b.cols()
    );
    let batches = c.batches();
    for (m, what) in [(a.batches(), "left"), (b.batches(), "right")] {
        assert!(
            m == batches || m == 1,
            "gpumat::matmul: {what} operand has {m} batches, destination {batches}"
        );
    }
    crate::stats::count_pass();
    let accum = if accumulate { Accum::Add } else { Accum::Replace };
    let (rows, cols) = (c.rows(), c.cols());
    let flops = a.rows() * a.cols() * b.cols();
    let run = |bi: usize, cb: &mut [R], par: Par| {
        let ab = if a.batches() == 1 { 0 } else { bi };
        let bb = if b.batches() == 1 { 0 } else { bi };
        let dst = faer::MatMut::from_column_major_slice_mut(cb, rows, cols);
        faer_matmul(dst, accum, a.faer_ref(ab), b.faer_ref(bb), alpha, par);
    };
    let n = rows * cols;
    if n == 0 {
        return;
    }
    if batches > 1 && flops < (1 << 18) {
        c.as_mut_slice()
            .par_chunks_mut(n)
            .enumerate()
            .for_each(|(bi, cb)| run(bi, cb, Par::Seq));
    } else {
        let par = if flops >= (1 << 18) {
            Par::rayon(0)
        } else {
            Par::Seq
        };
        for (bi, cb) in c.as_mut_slice().chunks_mut(n).enumerate() {
            run(bi, cb, par);
        }
    }
}
