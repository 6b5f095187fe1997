//! Sparse matrices with a shared sparsity pattern (thesis sec. 3.3 and 4.4.1).
//!
//! A [`SparsityPattern`] (CSR: row pointers and sorted column indices) is built once from the
//! reference configuration and shared through an `Arc`; a [`SparseMatrix<T>`] holds only the
//! values, batch after batch. With `T = Mat3<R>` it is a 3x3 block-sparse (BSR) matrix. The
//! product `A * x` is an expression ([`SpMV`]) that fuses with its surroundings, so
//! `b.assign(&a * u.ex() + v.ex() * c)` makes one pass.

mod faer_conv;
mod matrix;
mod pattern;
mod spmv;
mod view;

pub use faer_conv::BlockScalar;
pub use matrix::SparseMatrix;
pub use pattern::{SparsityPattern, TransposeMap};
pub use spmv::{SpMV, SpMVT, SparseRef};
pub use view::SparseView;
