//! The kernel corpus: every kernel shape the expression codegen can emit, generated through the
//! real codegen path ([`crate::cuda_codegen::kernel_source`] on real expression trees), so a
//! compile check of the corpus checks what an assignment would compile.
//!
//! Coverage, for each real type f32, f64 (output shape 4 x 3 x 2):
//! - every unary op of the op table (expanded with `for_each_unary_op!`) on real, `Vec3` and
//!   `Mat3` elements, with the operand full, broadcast over rows, columns, batches, or a 1x1x1;
//! - every binary op (`for_each_binary_op!`) on the three element types, with the operand pairs
//!   of [`PAIRS`] (the second broadcast in each dimension, both broadcast in different ones);
//! - the element products (real, lane-wise `Vec3`, `Mat3 * Vec3`, `Mat3 * Mat3`, real * block),
//!   scaling by a literal (finite and infinite), negation, casts (every `CastFrom`), per-element
//!   dot and squared norm, transpose, as-diagonal, identity, constants, compound assignment
//!   (the destination read back);
//! - sparse products: CSR (real) and BSR (`Mat3 * Vec3`) `A x` and `A^T x`, with shared and
//!   batched values and broadcast `x`, a sparse matrix as a dense leaf, and a fused
//!   `A x - 2 y` expression.

use super::KernelSource;
use crate::cuda_codegen::kernel_source;
use crate::expr::{Binary, Expr, SelfRef};
use crate::matrix::{Matrix, Shape};
use crate::ops::{BinaryOp, UnaryOp};
use crate::scalar::{CastFrom, Real, Scalar, ScalarMul};
use crate::sparse::SparseMatrix;
use crate::{Mat3, Vec3};

/// The output shape of the corpus kernels.
const OUT: Shape = Shape {
    rows: 4,
    cols: 3,
    batches: 2,
};

/// Operand shapes: full, broadcast over rows, columns, batches, everything.
const PATTERNS: [(&str, Shape); 5] = [
    ("full", OUT),
    ("bcast_rows", Shape::new(1, 3, 2)),
    ("bcast_cols", Shape::new(4, 1, 2)),
    ("bcast_batches", Shape::new(4, 3, 1)),
    ("bcast_all", Shape::new(1, 1, 1)),
];

/// Operand pairs of binary nodes: indices into [`PATTERNS`].
const PAIRS: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (0, 3), (0, 4), (2, 1)];

/// Collects kernels with unique entry names.
#[derive(Debug, Default)]
struct Corpus {
    kernels: Vec<KernelSource>,
}

impl Corpus {
    fn add<E: Expr>(&mut self, e: &E, out: Shape, what: &str) {
        let name = format!("gpumat_corpus_{}_{what}", self.kernels.len());
        self.kernels.push(KernelSource {
            source: kernel_source(e, out, &name),
            name: format!("{name}.cu"),
            entries: vec![name],
        });
    }
}

fn m<T: Scalar>(s: Shape) -> Matrix<T> {
    Matrix::zeros(s.rows, s.cols, s.batches)
}

/// A short tag for an element type: `f32`, `vec3_f64`, `mat3_f32`.
fn tag<T: Scalar>() -> String {
    let real = if std::mem::size_of::<T::Real>() == 4 {
        "f32"
    } else {
        "f64"
    };
    match T::LANES {
        1 => real.to_string(),
        3 => format!("vec3_{real}"),
        _ => format!("mat3_{real}"),
    }
}

fn unary<T: Scalar, Op: UnaryOp>(c: &mut Corpus) {
    for (p, s) in PATTERNS {
        let a = m::<T>(s);
        c.add(
            &a.ex().unary::<Op>().0,
            OUT,
            &format!("unary_{}_{}_{p}", Op::NAME, tag::<T>()),
        );
    }
}

fn binary<T: Scalar, Op: BinaryOp>(c: &mut Corpus) {
    for (i, j) in PAIRS {
        let (a, b) = (m::<T>(PATTERNS[i].1), m::<T>(PATTERNS[j].1));
        let e = Binary::<_, _, Op>::new(a.ex().0, b.ex().0);
        let what = format!(
            "binary_{}_{}_{}_{}",
            Op::NAME,
            tag::<T>(),
            PATTERNS[i].0,
            PATTERNS[j].0
        );
        c.add(&e, OUT, &what);
    }
}

macro_rules! corpus_unary {
    ($($(#[$doc:meta])* $ty:ident, $name:literal, $cuda:literal, |$($x:ident),*| $body:expr;)*) => {
        fn all_unary<T: Scalar>(c: &mut Corpus) {
            $(unary::<T, crate::ops::$ty>(c);)*
        }
    };
}
for_each_unary_op!(corpus_unary);

macro_rules! corpus_binary {
    ($($(#[$doc:meta])* $ty:ident, $name:literal, $cuda:literal, |$($x:ident),*| $body:expr;)*) => {
        fn all_binary<T: Scalar>(c: &mut Corpus) {
            $(binary::<T, crate::ops::$ty>(c);)*
        }
    };
}
for_each_binary_op!(corpus_binary);

/// Element products `a * b` over the operand pairs.
fn products<A: ScalarMul<B>, B: Scalar>(c: &mut Corpus) {
    for (i, j) in PAIRS {
        let (a, b) = (m::<A>(PATTERNS[i].1), m::<B>(PATTERNS[j].1));
        let what = format!(
            "mul_{}_{}_{}_{}",
            tag::<A>(),
            tag::<B>(),
            PATTERNS[i].0,
            PATTERNS[j].0
        );
        c.add(&a.ex().cwise_mul(b.ex()).0, OUT, &what);
    }
}

fn cast<T: Scalar, U: CastFrom<T>>(c: &mut Corpus) {
    let a = m::<T>(OUT);
    c.add(
        &a.ex().cast::<U>().0,
        OUT,
        &format!("cast_{}_to_{}", tag::<T>(), tag::<U>()),
    );
}

/// The nodes other than the op table's, on one element type.
fn nodes<T: Scalar>(c: &mut Corpus) {
    let t = tag::<T>();
    let a = m::<T>(OUT);
    for (p, s) in PATTERNS {
        let b = m::<T>(s);
        let half = <T::Real as Real>::of(0.5);
        c.add(&b.ex().scale(half).0, OUT, &format!("scale_{t}_{p}"));
        c.add(&(-b.ex()).0, OUT, &format!("neg_{t}_{p}"));
        c.add(&a.ex().cwise_dot(b.ex()).0, OUT, &format!("dot_{t}_{p}"));
        c.add(
            &b.ex().cwise_squared_norm().0,
            OUT,
            &format!("squared_norm_{t}_{p}"),
        );
    }
    let inf = <T::Real as num_traits::Float>::infinity();
    c.add(&a.ex().scale(inf).0, OUT, &format!("scale_inf_{t}"));
    c.add(&a.ex().scale(-inf).0, OUT, &format!("scale_neg_inf_{t}"));
    let at = m::<T>(OUT.transposed());
    c.add(&at.ex().transpose().0, OUT, &format!("transpose_{t}"));
    c.add(
        &(at.ex().transpose() + a.ex()).0,
        OUT,
        &format!("transpose_sum_{t}"),
    );
    let v = m::<T>(Shape::new(4, 1, 2));
    c.add(
        &v.ex().as_diagonal().0,
        Shape::new(4, 4, 2),
        &format!("as_diagonal_{t}"),
    );
    let sq = Shape::new(4, 4, 2);
    c.add(&crate::identity::<T>(4, 4, 2).0, sq, &format!("identity_{t}"));
    c.add(&crate::constant(4, 3, 2, T::ONE).0, OUT, &format!("constant_{t}"));
    c.add(
        &(a.ex() + crate::scalar(T::ONE)).0,
        OUT,
        &format!("plus_constant_{t}"),
    );
    // compound assignment: dst = dst + a (the destination read back)
    let dst = SelfRef::<T> {
        ptr: std::ptr::null(),
        shape: OUT,
    };
    let e = Binary::<_, _, crate::ops::AddOp>::new(dst, a.ex().0);
    c.add(&e, OUT, &format!("compound_add_{t}"));
}

/// A small 4 x 4 pattern with a full diagonal and two off-diagonal entries per row.
fn sparse<T: Scalar>(batches: usize) -> SparseMatrix<T> {
    let mut triplets = Vec::new();
    for r in 0..4 {
        for c in [r, (r + 1) % 4, (r + 3) % 4] {
            triplets.push((r, c, T::ONE));
        }
    }
    let one = SparseMatrix::from_triplets(4, 4, &triplets);
    let values = (0..batches).flat_map(|_| one.values().to_vec()).collect();
    SparseMatrix::from_values(one.pattern().clone(), batches, values)
}

/// Sparse products of a matrix with element `M` and vectors with element `V`.
fn sparse_products<M: ScalarMul<V, Output = V>, V: Scalar>(c: &mut Corpus) {
    let t = format!("{}_{}", tag::<M>(), tag::<V>());
    for (mb, xb) in [(1, 2), (2, 2), (2, 1)] {
        let a = sparse::<M>(mb);
        let x = m::<V>(Shape::new(4, 3, xb));
        let out = Shape::new(4, 3, 2);
        let what = format!("{t}_values{mb}_x{xb}");
        c.add(&a.mul(x.ex()).0, out, &format!("spmv_{what}"));
        c.add(
            &a.transpose_mul(x.ex()).0,
            out,
            &format!("spmv_transposed_{what}"),
        );
    }
    let a = sparse::<M>(2);
    let (x, y) = (m::<V>(Shape::new(4, 1, 2)), m::<V>(Shape::new(4, 1, 2)));
    let two = <V::Real as Real>::of(2.0);
    let fused = a.mul(x.ex()) - y.ex().scale(two);
    c.add(&fused.0, Shape::new(4, 1, 2), &format!("spmv_fused_{t}"));
    c.add(
        &a.mul(a.mul(x.ex())).0,
        Shape::new(4, 1, 2),
        &format!("spmv_nested_{t}"),
    );
    c.add(
        &a.ex().0,
        Shape::new(4, 4, 2),
        &format!("sparse_leaf_{}", tag::<M>()),
    );
}

fn one_real<R>(c: &mut Corpus)
where
    Vec3<R>: Scalar<Real = R> + ScalarMul<Output = Vec3<R>> + CastFrom<R>,
    Mat3<R>: Scalar<Real = R>
        + ScalarMul<Vec3<R>, Output = Vec3<R>>
        + ScalarMul<Output = Mat3<R>>
        + CastFrom<R>
        + CastFrom<Vec3<R>>,
    R: Real + ScalarMul<Output = R> + ScalarMul<Vec3<R>> + ScalarMul<Mat3<R>> + CastFrom<R>,
{
    all_unary::<R>(c);
    all_unary::<Vec3<R>>(c);
    all_unary::<Mat3<R>>(c);
    all_binary::<R>(c);
    all_binary::<Vec3<R>>(c);
    all_binary::<Mat3<R>>(c);
    products::<R, R>(c);
    products::<Vec3<R>, Vec3<R>>(c);
    products::<Mat3<R>, Vec3<R>>(c);
    products::<Mat3<R>, Mat3<R>>(c);
    products::<R, Vec3<R>>(c);
    products::<R, Mat3<R>>(c);
    nodes::<R>(c);
    nodes::<Vec3<R>>(c);
    nodes::<Mat3<R>>(c);
    cast::<R, R>(c);
    cast::<R, Vec3<R>>(c);
    cast::<R, Mat3<R>>(c);
    cast::<Vec3<R>, Mat3<R>>(c);
    sparse_products::<R, R>(c);
    sparse_products::<Mat3<R>, Vec3<R>>(c);
}

/// Every kernel the expression codegen can emit, one source per kernel (see the module docs).
pub fn corpus() -> Vec<KernelSource> {
    let mut c = Corpus::default();
    one_real::<f32>(&mut c);
    one_real::<f64>(&mut c);
    // precision changes
    cast::<f32, f64>(&mut c);
    cast::<f64, f32>(&mut c);
    cast::<Vec3<f32>, Vec3<f64>>(&mut c);
    cast::<Vec3<f64>, Vec3<f32>>(&mut c);
    cast::<Mat3<f32>, Mat3<f64>>(&mut c);
    cast::<Mat3<f64>, Mat3<f32>>(&mut c);
    c.kernels
}
