//! Sparse products and the sparse leaf as expression nodes.
//!
//! `y = A x`: `y(r, c, b) = sum_{k in row r} A_k(b) * x(col_k, c, b)`, where `*` is the block
//! product ([`ScalarMul`]): `Mat3 * Vec3` for BSR. Each output row is computed by one thread
//! from its own row of the pattern, so no atomics are needed and the result is deterministic.
//! `A^T x` uses the cached [`super::TransposeMap`] to do the same row by row. The CUDA text
//! (see [`crate::cuda_codegen`]) is the same row loop over the CSR arrays, passed as kernel
//! parameters (`row_ptr` as `unsigned long long`, `col_idx` as `unsigned int`, the values).

use super::matrix::SparseMatrix;
use super::pattern::SparsityPattern;
use crate::cuda_codegen::CudaGen;
use crate::expr::Expr;
use crate::matrix::Shape;
use crate::scalar::{Scalar, ScalarMul};

/// `A * x` with a sparse `A` and a dense expression `x` (`cols(A) x k x batches`).
///
/// The CSR arrays are borrowed once at construction: the evaluation loop then reads them
/// straight from the node instead of chasing `matrix -> Arc<pattern> -> Vec` on every row,
/// which kept the memory-bound product at about half the STREAM bandwidth.
#[derive(Clone, Copy, Debug)]
pub struct SpMV<'a, T: Scalar, E> {
    a: &'a SparseMatrix<T>,
    row_ptr: &'a [usize],
    col_idx: &'a [u32],
    /// the values of the batch every output batch reads when `A` has one batch, else all
    values: &'a [T],
    /// `nnz` when `A` is batched (batch `b` reads `values[b * nnz..]`), 0 when it broadcasts
    batch_stride: usize,
    x: E,
    shape: Shape,
}

fn product_shape(a: Shape, x: Shape, op: &str) -> Shape {
    assert_eq!(
        a.cols, x.rows,
        "gpumat::{op}: matrix has {} columns, vector has {} rows",
        a.cols, x.rows
    );
    let batches = Shape::new(1, 1, a.batches)
        .broadcast(Shape::new(1, 1, x.batches), op)
        .batches;
    Shape::new(a.rows, x.cols, batches)
}

impl<'a, T: Scalar, E: Expr> SpMV<'a, T, E>
where
    T: ScalarMul<E::Elem>,
{
    /// The node; panics when the shapes do not match.
    #[track_caller]
    pub fn new(a: &'a SparseMatrix<T>, x: E) -> Self {
        const { assert!(!E::SELF_REF, "gpumat: SpMV cannot read the destination it writes") };
        let shape = product_shape(a.shape(), x.shape(), "spmv");
        let p = a.pattern();
        Self {
            a,
            row_ptr: p.row_ptr(),
            col_idx: p.col_idx(),
            values: a.values(),
            batch_stride: if a.batches() == 1 { 0 } else { a.nnz() },
            x,
            shape,
        }
    }
}

impl<T: Scalar, E: Expr> Expr for SpMV<'_, T, E>
where
    T: ScalarMul<E::Elem>,
{
    type Elem = <T as ScalarMul<E::Elem>>::Output;
    fn shape(&self) -> Shape {
        self.shape
    }
    fn linear(&self, _out: Shape) -> bool {
        false
    }
    fn bytes_per_element(&self) -> usize {
        // a row's blocks, their column indices and the vector elements they meet
        let per_entry = std::mem::size_of::<T>() + 4 + self.x.bytes_per_element();
        self.a.nnz().div_ceil(self.a.rows().max(1)) * per_entry
    }
    #[inline(always)]
    unsafe fn at(&self, r: usize, c: usize, b: usize) -> Self::Elem {
        let mut acc = Self::Elem::ZERO;
        // SAFETY: `r < rows` (the caller stays inside the output shape) and the pattern was
        // validated, so `row_ptr` has `rows + 1` entries, `start <= end <= nnz = col_idx.len()`
        // and every column is `< cols = x.rows`. `b < out.batches`, and `batch_stride` is
        // non-zero only when `A` has `out.batches` batches, so `b * batch_stride + k` is inside
        // `values` (`nnz * batches` entries).
        unsafe {
            let start = *self.row_ptr.get_unchecked(r);
            let end = *self.row_ptr.get_unchecked(r + 1);
            let values = self.values.get_unchecked(b * self.batch_stride..);
            let cols = self.col_idx.get_unchecked(start..end);
            let vals = values.get_unchecked(start..end);
            for (&col, &v) in cols.iter().zip(vals) {
                acc = acc.add(v.smul(self.x.at(col as usize, c, b)));
            }
        }
        acc
    }
    #[inline(always)]
    unsafe fn at_linear(&self, _i: usize) -> Self::Elem {
        unreachable!("gpumat::SpMV is never evaluated linearly")
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        let (row, c) = g.coords();
        let row_ptr = g.buffer("gpumat_index");
        let col_idx = g.buffer("unsigned int");
        let vals = g.buffer(T::CUDA_TYPE);
        let (k, col, acc) = (g.fresh("k"), g.fresh("col"), g.fresh("acc"));
        g.push_rc(col.clone(), c);
        let x = self.x.cuda(g);
        g.restore_rc();
        let v = format!("{vals}[{k}{}]", batch_offset(self.a));
        let prod = <T as ScalarMul<E::Elem>>::cuda_mul(&v, &x);
        format!(
            "([&]() {{ {out} {acc} = gpumat_zero<{out}>(); \
             for (gpumat_index {k} = {row_ptr}[{row}]; {k} < {row_ptr}[({row}) + 1]; ++{k}) {{ \
             const gpumat_index {col} = {col_idx}[{k}]; {acc} = {acc} + {prod}; }} \
             return {acc}; }}())",
            out = <Self::Elem as Scalar>::CUDA_TYPE,
        )
    }
}

/// `A^T * x` (blocks transposed), evaluated row by row through the transpose map.
#[derive(Clone, Copy, Debug)]
pub struct SpMVT<'a, T: Scalar, E> {
    a: &'a SparseMatrix<T>,
    x: E,
    shape: Shape,
}

impl<'a, T: Scalar, E: Expr> SpMVT<'a, T, E>
where
    T: ScalarMul<E::Elem>,
{
    /// The node; panics when the shapes do not match.
    #[track_caller]
    pub fn new(a: &'a SparseMatrix<T>, x: E) -> Self {
        const { assert!(!E::SELF_REF, "gpumat: SpMV cannot read the destination it writes") };
        let shape = product_shape(a.shape().transposed(), x.shape(), "spmv_transposed");
        a.pattern().transpose_map();
        Self { a, x, shape }
    }
}

impl<T: Scalar, E: Expr> Expr for SpMVT<'_, T, E>
where
    T: ScalarMul<E::Elem>,
{
    type Elem = <T as ScalarMul<E::Elem>>::Output;
    fn shape(&self) -> Shape {
        self.shape
    }
    fn linear(&self, _out: Shape) -> bool {
        false
    }
    fn bytes_per_element(&self) -> usize {
        // a column's blocks, the transpose map's three indices and the vector elements
        let per_entry = std::mem::size_of::<T>() + 24 + self.x.bytes_per_element();
        self.a.nnz().div_ceil(self.a.cols().max(1)) * per_entry
    }
    #[inline(always)]
    unsafe fn at(&self, r: usize, c: usize, b: usize) -> Self::Elem {
        let p = self.a.pattern();
        let t = p.transpose_map();
        let nnz = p.nnz();
        let bv = if self.a.batches() == 1 { 0 } else { b };
        let values = self.a.values();
        let mut acc = Self::Elem::ZERO;
        // SAFETY: `r < cols(A)`; the transpose map is built from the validated pattern, so its
        // pointers and indices are in range, and `row < rows(A) = x.rows`.
        unsafe {
            let (start, end) = (*t.col_ptr.get_unchecked(r), *t.col_ptr.get_unchecked(r + 1));
            for j in start..end {
                let row = *t.row_idx.get_unchecked(j);
                let k = *t.entry.get_unchecked(j);
                let v = values.get_unchecked(bv * nnz + k).transpose();
                acc = acc.add(v.smul(self.x.at(row, c, b)));
            }
        }
        acc
    }
    #[inline(always)]
    unsafe fn at_linear(&self, _i: usize) -> Self::Elem {
        unreachable!("gpumat::SpMVT is never evaluated linearly")
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        // the transpose map: entries of column `r` of A are `col_ptr[r]..col_ptr[r + 1]`, with
        // their rows in `row_idx` and their entry index in `entry`
        let (r, c) = g.coords();
        let col_ptr = g.buffer("gpumat_index");
        let row_idx = g.buffer("gpumat_index");
        let entry = g.buffer("gpumat_index");
        let vals = g.buffer(T::CUDA_TYPE);
        let (j, row, acc) = (g.fresh("j"), g.fresh("row"), g.fresh("acc"));
        g.push_rc(row.clone(), c);
        let x = self.x.cuda(g);
        g.restore_rc();
        let v = format!("gpumat_transpose({vals}[{entry}[{j}]{}])", batch_offset(self.a));
        let prod = <T as ScalarMul<E::Elem>>::cuda_mul(&v, &x);
        format!(
            "([&]() {{ {out} {acc} = gpumat_zero<{out}>(); \
             for (gpumat_index {j} = {col_ptr}[{r}]; {j} < {col_ptr}[({r}) + 1]; ++{j}) {{ \
             const gpumat_index {row} = {row_idx}[{j}]; {acc} = {acc} + {prod}; }} \
             return {acc}; }}())",
            out = <Self::Elem as Scalar>::CUDA_TYPE,
        )
    }
}

/// ` + nnz * b` when `a` has one value set per batch, nothing when its values broadcast.
fn batch_offset<T: Scalar>(a: &SparseMatrix<T>) -> String {
    if a.batches() == 1 {
        String::new()
    } else {
        format!(" + {}ull * b", a.nnz())
    }
}

/// Leaf: a sparse matrix read element-wise (zero off the pattern). In a sparse view over the
/// same pattern it is read by entry index, without searching.
#[derive(Clone, Copy, Debug)]
pub struct SparseRef<'a, T: Scalar> {
    a: &'a SparseMatrix<T>,
}
impl<'a, T: Scalar> SparseRef<'a, T> {
    /// The leaf.
    pub fn new(a: &'a SparseMatrix<T>) -> Self {
        Self { a }
    }
}
impl<T: Scalar> Expr for SparseRef<'_, T> {
    type Elem = T;
    fn shape(&self) -> Shape {
        self.a.shape()
    }
    fn linear(&self, _out: Shape) -> bool {
        false
    }
    #[inline(always)]
    unsafe fn at(&self, r: usize, c: usize, b: usize) -> T {
        let bv = if self.a.batches() == 1 { 0 } else { b };
        self.a.get(r, c, bv)
    }
    #[inline(always)]
    unsafe fn at_linear(&self, _i: usize) -> T {
        unreachable!("gpumat::SparseRef is never evaluated linearly")
    }
    #[inline(always)]
    unsafe fn entry(&self, k: usize, _r: usize, _c: usize, b: usize) -> T {
        let bv = if self.a.batches() == 1 { 0 } else { b };
        // SAFETY: `sparse_compatible` held, so `k < nnz` indexes this matrix's own pattern.
        unsafe { *self.a.values().get_unchecked(bv * self.a.nnz() + k) }
    }
    fn sparse_compatible(&self, p: &SparsityPattern) -> bool {
        std::ptr::eq(&**self.a.pattern(), p) || **self.a.pattern() == *p
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        let (r, c) = g.coords();
        let row_ptr = g.buffer("gpumat_index");
        let col_idx = g.buffer("unsigned int");
        let vals = g.buffer(T::CUDA_TYPE);
        let batch = batch_offset(self.a);
        format!("gpumat_csr_get({row_ptr}, {col_idx}, {vals}{batch}, {r}, {c})")
    }
}
