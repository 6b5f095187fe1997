//! # gpumat
//!
//! A cuMat-style linear-algebra library (thesis ch. 3): batched dense matrices, lazy
//! expressions fused into one pass, reductions, 3x3 block scalars, block-sparse (BSR)
//! matrices on a shared pattern, batched preconditioned CG (Jacobi, block-Jacobi, block
//! incomplete Cholesky IC(0)) and a direct sparse Cholesky (AMD or nested-dissection order).
//! The CPU backend runs the fused loops on rayon. For CUDA, every fused assignment also lowers
//! to a CUDA kernel from the same op table ([`cuda_codegen`]), `build.rs` generates the kernels
//! the solvers need ([`cuda::catalogue`]), and with feature `cuda` NVRTC compiles them
//! ([`cuda::nvrtc`]; `tests/nvrtc_compile.rs` compiles every kernel to PTX and CUBIN).
//! [`device`] holds data on a device and runs the catalogue's kernels there: block-sparse
//! matrices, block-Jacobi and the batched CG, on CUDA (feature `cuda`) or on a host emulation of
//! CUDA (feature `emulate`, for tests). [`raw::SharedParts`] lends disjoint parts of one buffer to parallel tasks
//! whose parts are not regular chunks (cutfem's step assembly); gpumat's `unsafe` lives in
//! the backend modules and there.
//!
//! ```
//! use gpumat::{Matrix, Axes};
//! let a = Matrix::<f32>::from_fn(4, 1, 2, |r, _, b| (r + 4 * b) as f32);
//! let b = Matrix::<f32>::constant(4, 1, 1, 1.0); // one batch, broadcast to two
//! let mut d = Matrix::<f32>::zeros(4, 1, 2);
//! d.assign(a.ex() + b.ex() * 2.0 + a.ex().sqrt()); // one pass, no temporary
//! assert_eq!(d.get(3, 0, 1), 7.0 + 2.0 + 7f32.sqrt());
//! let per_batch = d.ex().sum_over(Axes::ROWS); // 1 x 1 x 2
//! assert_eq!(per_batch.batches(), 2);
//! ```
//!
//! Block scalars work everywhere a real does:
//!
//! ```
//! use gpumat::{Mat3, SparseMatrix, Matrix, Vec3};
//! let a = SparseMatrix::from_triplets(2, 2, &[(0, 0, Mat3::<f64>::identity()), (1, 1, Mat3::from_scalar(2.0))]);
//! let x = Matrix::column(&[Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 1.0, 1.0)]);
//! let y = Matrix::eval(&a * &x); // BSR SpMV
//! assert_eq!(y.get(1, 0, 0), Vec3::splat(2.0));
//! ```

// The op table (visitor macros); first, so that every module below can expand it.
#[macro_use]
mod op_table;

pub mod backend;
mod block;
pub mod cuda;
pub mod cuda_codegen;
pub mod cuda_text;
pub mod device;
mod error;
pub mod expr;
mod matrix;
pub mod ops;
mod product;
pub mod raw;
mod scalar;
pub mod simd;
pub mod solve;
pub mod sparse;
pub mod stats;

pub use block::{Mat3, Mat3d, Mat3f, Vec3, Vec3d, Vec3f};
pub use error::Error;
pub use expr::{constant, identity, scalar, zeros, Axes, Ex, Expr};
pub use matrix::{Matrix, Shape};
pub use product::{matmul, matmul_into};
pub use scalar::{CastFrom, Real, Scalar, ScalarMul};
pub use solve::{
    cg, nested_dissection, BlockIc0, BlockJacobi, CgError, CgInfo, CgParams, Ic0Params,
    IdentityPreconditioner, Jacobi, LinearOperator, Multigrid, MultigridParams, Preconditioner,
    SparseCholesky, Transposed,
};
pub use sparse::{BlockScalar, SparseMatrix, SparsityPattern};
