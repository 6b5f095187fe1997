//! Lazy expressions, fused into one pass at assignment (thesis sec. 3.2, cuMat's expression
//! templates; Eigen's `call_assignment`).
//!
//! An expression is a tree of nodes implementing [`Expr`]; building it computes nothing.
//! [`crate::Matrix::assign`] is the single place where a tree becomes a loop: every output
//! element `d(r,c,b)` is computed by evaluating the tree at `(r,c,b)` and written once, so
//! `d = a + 2 b + sqrt(c)` reads `a`, `b`, `c` once and writes `d` once, with no temporary.
//!
//! Broadcasting: a dimension of size 1 in an operand is repeated along the output's
//! dimension (rows, columns and batches alike).
//!
//! Expressions are wrapped in [`Ex`] so that the arithmetic operators can be implemented on
//! them: `a.ex() + b.ex() * 2.0 + c.ex().sqrt()`, or `&a + &b` on matrices directly.

mod assign;
mod nodes;
mod overload;
mod reduce;

pub use assign::{PAR_BYTES, PAR_THRESHOLD};
pub use nodes::*;
pub use reduce::Axes;

use crate::cuda_codegen::CudaGen;
use crate::matrix::Shape;
use crate::ops::{self, UnaryOp};
use crate::scalar::{CastFrom, Scalar, ScalarMul};
use crate::sparse::SparsityPattern;

/// A node of a lazy expression tree.
///
/// # Safety contract of the evaluation methods
/// `at(r, c, b)` may only be called with `r < out.rows`, `c < out.cols`, `b < out.batches`
/// for an output shape `out` to which [`Expr::shape`] broadcasts; `at_linear(i)` only with
/// `i < out.len()` for an `out` for which [`Expr::linear`] returned true; `entry(k, ..)` only
/// with `k` a valid entry of a pattern for which [`Expr::sparse_compatible`] returned true.
/// The assignment functions check these conditions once, before the loop.
pub trait Expr: Sync + Sized {
    /// The element type.
    type Elem: Scalar;
    /// True when the tree reads the destination it is assigned to ([`SelfRef`]); such a tree
    /// may only be evaluated element by element, never gathered (SpMV, transpose).
    const SELF_REF: bool = false;
    /// The shape of the value (dimensions of size 1 broadcast).
    fn shape(&self) -> Shape;
    /// True when the element at output position `(r,c,b)` of shape `out` can be read with the
    /// output's linear index (no broadcasting or reordering below this node).
    fn linear(&self, out: Shape) -> bool;
    /// The element at output coordinates `(r, c, b)`.
    ///
    /// # Safety
    /// See the trait docs.
    unsafe fn at(&self, r: usize, c: usize, b: usize) -> Self::Elem;
    /// The element at output linear index `i`.
    ///
    /// # Safety
    /// See the trait docs.
    unsafe fn at_linear(&self, i: usize) -> Self::Elem;
    /// The element at entry `k` = `(r, c)` of a sparsity pattern, batch `b` (sparse view).
    ///
    /// # Safety
    /// See the trait docs.
    #[inline(always)]
    unsafe fn entry(&self, _k: usize, r: usize, c: usize, b: usize) -> Self::Elem {
        // SAFETY: forwarded contract; (r, c) is inside the pattern's shape.
        unsafe { self.at(r, c, b) }
    }
    /// True when every sparse leaf of the tree has exactly `pattern` (so [`Expr::entry`]
    /// reads them by entry index).
    fn sparse_compatible(&self, _pattern: &SparsityPattern) -> bool {
        true
    }
    /// Emits the CUDA text that computes this node's element (see [`crate::cuda_codegen`]).
    fn cuda(&self, g: &mut CudaGen) -> String;
    /// Bytes this tree reads per output element: an estimate that only schedules the loop
    /// (on the calling thread or in parallel, and how many elements make one work item), never
    /// what is computed. A leaf reads its element, an operator node adds its operands', a
    /// sparse product a row's blocks, column indices and vector elements.
    fn bytes_per_element(&self) -> usize {
        std::mem::size_of::<Self::Elem>()
    }
}

/// The wrapper that gives expressions their operators and methods.
#[derive(Clone, Copy, Debug)]
pub struct Ex<E>(pub E);

impl<E: Expr> Ex<E> {
    /// The expression's shape.
    pub fn shape(&self) -> Shape {
        self.0.shape()
    }
    /// Applies a unary operation of the op table lane by lane.
    pub fn unary<Op: UnaryOp>(self) -> Ex<Unary<E, Op>> {
        Ex(Unary::new(self.0))
    }
    /// `sqrt`, lane-wise.
    pub fn sqrt(self) -> Ex<Unary<E, ops::Sqrt>> {
        self.unary()
    }
    /// `1/sqrt`, lane-wise.
    pub fn rsqrt(self) -> Ex<Unary<E, ops::Rsqrt>> {
        self.unary()
    }
    /// `abs`, lane-wise.
    pub fn abs(self) -> Ex<Unary<E, ops::Abs>> {
        self.unary()
    }
    /// `exp`, lane-wise.
    pub fn exp(self) -> Ex<Unary<E, ops::Exp>> {
        self.unary()
    }
    /// natural `log`, lane-wise.
    pub fn log(self) -> Ex<Unary<E, ops::Log>> {
        self.unary()
    }
    /// `log1p`, lane-wise.
    pub fn log1p(self) -> Ex<Unary<E, ops::Log1p>> {
        self.unary()
    }
    /// `sin`, lane-wise.
    pub fn sin(self) -> Ex<Unary<E, ops::Sin>> {
        self.unary()
    }
    /// `cos`, lane-wise.
    pub fn cos(self) -> Ex<Unary<E, ops::Cos>> {
        self.unary()
    }
    /// `tan`, lane-wise.
    pub fn tan(self) -> Ex<Unary<E, ops::Tan>> {
        self.unary()
    }
    /// `tanh`, lane-wise.
    pub fn tanh(self) -> Ex<Unary<E, ops::Tanh>> {
        self.unary()
    }
    /// `x^2`, lane-wise.
    pub fn square(self) -> Ex<Unary<E, ops::Square>> {
        self.unary()
    }
    /// `x^3`, lane-wise.
    pub fn cube(self) -> Ex<Unary<E, ops::Cube>> {
        self.unary()
    }
    /// `1/x`, lane-wise.
    pub fn inverse(self) -> Ex<Unary<E, ops::Inverse>> {
        self.unary()
    }
    /// `floor`, lane-wise.
    pub fn floor(self) -> Ex<Unary<E, ops::Floor>> {
        self.unary()
    }
    /// `ceil`, lane-wise.
    pub fn ceil(self) -> Ex<Unary<E, ops::Ceil>> {
        self.unary()
    }
    /// sign, lane-wise.
    pub fn sign(self) -> Ex<Unary<E, ops::Sign>> {
        self.unary()
    }
    /// Element-wise quotient (lane-wise).
    #[track_caller]
    pub fn cwise_div<B: Expr<Elem = E::Elem>>(self, b: Ex<B>) -> Ex<Binary<E, B, ops::DivOp>> {
        Ex(Binary::new(self.0, b.0))
    }
    /// Element-wise minimum (lane-wise).
    #[track_caller]
    pub fn cwise_min<B: Expr<Elem = E::Elem>>(self, b: Ex<B>) -> Ex<Binary<E, B, ops::MinOp>> {
        Ex(Binary::new(self.0, b.0))
    }
    /// Element-wise maximum (lane-wise).
    #[track_caller]
    pub fn cwise_max<B: Expr<Elem = E::Elem>>(self, b: Ex<B>) -> Ex<Binary<E, B, ops::MaxOp>> {
        Ex(Binary::new(self.0, b.0))
    }
    /// Element-wise power (lane-wise).
    #[track_caller]
    pub fn cwise_pow<B: Expr<Elem = E::Elem>>(self, b: Ex<B>) -> Ex<Binary<E, B, ops::PowOp>> {
        Ex(Binary::new(self.0, b.0))
    }
    /// Element-wise product with the scalar's own product ([`ScalarMul`]): lane-wise for
    /// reals and `Vec3`, block products for `Mat3 * Vec3` and `Mat3 * Mat3`, scaling for
    /// `real * block`.
    #[track_caller]
    pub fn cwise_mul<B: Expr>(self, b: Ex<B>) -> Ex<CwiseMul<E, B>>
    where
        E::Elem: ScalarMul<B::Elem>,
    {
        Ex(CwiseMul::new(self.0, b.0))
    }
    /// Multiplies every element by the real `s`.
    pub fn scale(self, s: <E::Elem as Scalar>::Real) -> Ex<Scale<E>> {
        Ex(Scale::new(self.0, s))
    }
    /// Converts the element type ([`CastFrom`]).
    pub fn cast<U: CastFrom<E::Elem>>(self) -> Ex<Cast<E, U>> {
        Ex(Cast::new(self.0))
    }
    /// The transpose (rows and columns swapped, each block transposed).
    pub fn transpose(self) -> Ex<Transpose<E>> {
        Ex(Transpose::new(self.0))
    }
    /// A vector `n x 1` (or `1 x n`) as the diagonal of an `n x n` matrix.
    #[track_caller]
    pub fn as_diagonal(self) -> Ex<AsDiagonal<E>> {
        Ex(AsDiagonal::new(self.0))
    }
    /// Per-element inner product ([`Scalar::dot`]) with `b`: a real-valued expression.
    #[track_caller]
    pub fn cwise_dot<B: Expr<Elem = E::Elem>>(self, b: Ex<B>) -> Ex<DotElem<E, B>> {
        Ex(DotElem::new(self.0, b.0))
    }
    /// Per-element squared norm: a real-valued expression.
    pub fn cwise_squared_norm(self) -> Ex<SquaredNormElem<E>> {
        Ex(SquaredNormElem::new(self.0))
    }
    /// Restricts the evaluation of this expression to the entries of `pattern`: assigning
    /// the result to a [`crate::SparseMatrix`] with that pattern writes only its entries
    /// (thesis sec. 4.4.3: `a M.as_diagonal() + b K` stays sparse on K's pattern).
    pub fn sparse_view(self, pattern: &std::sync::Arc<SparsityPattern>) -> SparseView<E> {
        SparseView::new(self.0, pattern.clone())
    }
}

/// A constant expression: `value` broadcast to `rows x cols x batches`.
pub fn constant<T: Scalar>(rows: usize, cols: usize, batches: usize, value: T) -> Ex<Constant<T>> {
    Ex(Constant::new(Shape::new(rows, cols, batches), value))
}
/// A scalar constant (shape 1x1x1) that broadcasts to anything.
pub fn scalar<T: Scalar>(value: T) -> Ex<Constant<T>> {
    constant(1, 1, 1, value)
}
/// A zero expression.
pub fn zeros<T: Scalar>(rows: usize, cols: usize, batches: usize) -> Ex<Constant<T>> {
    constant(rows, cols, batches, T::ZERO)
}
/// The identity: `T::ONE` on the diagonal, zero elsewhere.
pub fn identity<T: Scalar>(rows: usize, cols: usize, batches: usize) -> Ex<Identity<T>> {
    Ex(Identity::new(Shape::new(rows, cols, batches)))
}
