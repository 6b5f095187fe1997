//! The expression nodes: leaves (matrices, constants, identity, the destination itself) and
//! operations (unary, binary, product, scaling, cast, transpose, diagonal, inner products).

use super::Expr;
use crate::cuda_codegen::CudaGen;
use crate::matrix::Shape;
use crate::ops::{BinaryOp, UnaryOp};
use crate::scalar::{CastFrom, Scalar, ScalarMul};
use crate::sparse::SparsityPattern;
use std::marker::PhantomData;

pub use crate::sparse::SparseView;

/// Maps output coordinates to a leaf's linear index, repeating dimensions of size 1.
#[inline(always)]
pub(crate) fn broadcast_index(s: Shape, r: usize, c: usize, b: usize) -> usize {
    let r = if s.rows == 1 { 0 } else { r };
    let c = if s.cols == 1 { 0 } else { c };
    let b = if s.batches == 1 { 0 } else { b };
    r + s.rows * (c + s.cols * b)
}

/// Leaf: a borrowed dense matrix.
#[derive(Clone, Copy, Debug)]
pub struct MatRef<'a, T> {
    data: &'a [T],
    shape: Shape,
}

impl<'a, T: Scalar> MatRef<'a, T> {
    /// A leaf over column-major `data` of the given shape.
    #[track_caller]
    pub fn new(data: &'a [T], shape: Shape) -> Self {
        assert_eq!(
            data.len(),
            shape.len(),
            "gpumat::MatRef: data length does not match shape"
        );
        Self { data, shape }
    }
}

impl<T: Scalar> Expr for MatRef<'_, T> {
    type Elem = T;
    fn shape(&self) -> Shape {
        self.shape
    }
    fn linear(&self, out: Shape) -> bool {
        self.shape == out
    }
    #[inline(always)]
    unsafe fn at(&self, r: usize, c: usize, b: usize) -> T {
        let i = broadcast_index(self.shape, r, c, b);
        debug_assert!(i < self.data.len());
        // SAFETY: the caller keeps (r, c, b) inside an output shape this leaf broadcasts to,
        // so the broadcast index is inside `data` (its length equals `shape.len()`).
        unsafe { *self.data.get_unchecked(i) }
    }
    #[inline(always)]
    unsafe fn at_linear(&self, i: usize) -> T {
        debug_assert!(i < self.data.len());
        // SAFETY: `linear(out)` held, so `out == shape` and `i < out.len() == data.len()`.
        unsafe { *self.data.get_unchecked(i) }
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        g.load(T::CUDA_TYPE, self.shape)
    }
}

/// Leaf: a constant broadcast to a shape.
#[derive(Clone, Copy, Debug)]
pub struct Constant<T> {
    shape: Shape,
    value: T,
}
impl<T: Scalar> Constant<T> {
    /// A constant.
    pub fn new(shape: Shape, value: T) -> Self {
        Self { shape, value }
    }
}
impl<T: Scalar> Expr for Constant<T> {
    type Elem = T;
    fn bytes_per_element(&self) -> usize {
        0
    }
    fn shape(&self) -> Shape {
        self.shape
    }
    fn linear(&self, _out: Shape) -> bool {
        true
    }
    #[inline(always)]
    unsafe fn at(&self, _r: usize, _c: usize, _b: usize) -> T {
        self.value
    }
    #[inline(always)]
    unsafe fn at_linear(&self, _i: usize) -> T {
        self.value
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        g.constant(T::CUDA_TYPE, &format!("{:?}", self.value))
    }
}

/// Leaf: the identity (`T::ONE` on the diagonal).
#[derive(Clone, Copy, Debug)]
pub struct Identity<T> {
    shape: Shape,
    _t: PhantomData<T>,
}
impl<T: Scalar> Identity<T> {
    /// An identity of the given shape.
    pub fn new(shape: Shape) -> Self {
        Self {
            shape,
            _t: PhantomData,
        }
    }
}
impl<T: Scalar> Expr for Identity<T> {
    type Elem = T;
    fn bytes_per_element(&self) -> usize {
        0
    }
    fn shape(&self) -> Shape {
        self.shape
    }
    fn linear(&self, _out: Shape) -> bool {
        false
    }
    #[inline(always)]
    unsafe fn at(&self, r: usize, c: usize, _b: usize) -> T {
        if r == c {
            T::ONE
        } else {
            T::ZERO
        }
    }
    #[inline(always)]
    unsafe fn at_linear(&self, _i: usize) -> T {
        unreachable!("gpumat::Identity is never evaluated linearly")
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        let (r, c) = g.coords();
        format!(
            "({r} == {c} ? gpumat_one<{t}>() : gpumat_zero<{t}>())",
            t = T::CUDA_TYPE
        )
    }
}

/// Leaf: the current value of the destination (for `+=`, `-=`, [`crate::Matrix::assign_with`]).
#[derive(Clone, Copy, Debug)]
pub struct SelfRef<T> {
    pub(crate) ptr: *const T,
    pub(crate) shape: Shape,
}
// SAFETY: a `SelfRef` is only created by the assignment functions, which guarantee that the
// element at index `i` is read only by the thread that then writes index `i` (each thread owns
// a disjoint chunk of the destination), before that write.
unsafe impl<T: Sync> Sync for SelfRef<T> {}
// SAFETY: see `Sync` above.
unsafe impl<T: Send> Send for SelfRef<T> {}

impl<T: Scalar> Expr for SelfRef<T> {
    type Elem = T;
    const SELF_REF: bool = true;
    fn shape(&self) -> Shape {
        self.shape
    }
    fn linear(&self, out: Shape) -> bool {
        self.shape == out
    }
    #[inline(always)]
    unsafe fn at(&self, r: usize, c: usize, b: usize) -> T {
        let s = self.shape;
        // SAFETY: the destination has the output's shape, so the index is in bounds; the
        // element is owned by the evaluating thread (see the `Sync` impl).
        unsafe { *self.ptr.add(r + s.rows * (c + s.cols * b)) }
    }
    #[inline(always)]
    unsafe fn at_linear(&self, i: usize) -> T {
        // SAFETY: as in `at`.
        unsafe { *self.ptr.add(i) }
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        g.dst_load()
    }
}

/// Lane-wise unary operation.
#[derive(Clone, Copy, Debug)]
pub struct Unary<E, Op> {
    e: E,
    _op: PhantomData<Op>,
}
impl<E: Expr, Op: UnaryOp> Unary<E, Op> {
    /// The node.
    pub fn new(e: E) -> Self {
        Self { e, _op: PhantomData }
    }
}
impl<E: Expr, Op: UnaryOp> Expr for Unary<E, Op> {
    type Elem = E::Elem;
    const SELF_REF: bool = E::SELF_REF;
    fn shape(&self) -> Shape {
        self.e.shape()
    }
    fn linear(&self, out: Shape) -> bool {
        self.e.linear(out)
    }
    #[inline(always)]
    unsafe fn at(&self, r: usize, c: usize, b: usize) -> E::Elem {
        // SAFETY: forwarded contract.
        unsafe { self.e.at(r, c, b) }.map(Op::apply)
    }
    #[inline(always)]
    unsafe fn at_linear(&self, i: usize) -> E::Elem {
        // SAFETY: forwarded contract.
        unsafe { self.e.at_linear(i) }.map(Op::apply)
    }
    #[inline(always)]
    unsafe fn entry(&self, k: usize, r: usize, c: usize, b: usize) -> E::Elem {
        // SAFETY: forwarded contract.
        unsafe { self.e.entry(k, r, c, b) }.map(Op::apply)
    }
    fn sparse_compatible(&self, p: &SparsityPattern) -> bool {
        self.e.sparse_compatible(p)
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        let a = self.e.cuda(g);
        crate::cuda_codegen::unary_text::<E::Elem>(Op::CUDA, &a)
    }
    fn bytes_per_element(&self) -> usize {
        self.e.bytes_per_element()
    }
}

/// Generates the plumbing of a node with two operands `a`, `b` combined by `$f`.
macro_rules! binary_node_impl {
    ($node:ident<$($g:ident),*> where [$($bounds:tt)*], Elem = $elem:ty, |$x:ident, $y:ident| $f:expr, cuda = |$s:ident, $ca:ident, $cb:ident| $cuda:expr) => {
        impl<$($g),*> Expr for $node<$($g),*> where $($bounds)* {
            type Elem = $elem;
            const SELF_REF: bool = A::SELF_REF || B::SELF_REF;
            fn shape(&self) -> Shape {
                self.shape
            }
            fn bytes_per_element(&self) -> usize {
                self.a.bytes_per_element() + self.b.bytes_per_element()
            }
            fn linear(&self, out: Shape) -> bool {
                self.a.linear(out) && self.b.linear(out)
            }
            #[inline(always)]
            unsafe fn at(&self, r: usize, c: usize, bb: usize) -> $elem {
                // SAFETY: forwarded contract (both operands broadcast to this node's shape).
                let ($x, $y) = unsafe { (self.a.at(r, c, bb), self.b.at(r, c, bb)) };
                $f
            }
            #[inline(always)]
            unsafe fn at_linear(&self, i: usize) -> $elem {
                // SAFETY: forwarded contract (`linear` holds for both operands).
                let ($x, $y) = unsafe { (self.a.at_linear(i), self.b.at_linear(i)) };
                $f
            }
            #[inline(always)]
            unsafe fn entry(&self, k: usize, r: usize, c: usize, bb: usize) -> $elem {
                // SAFETY: forwarded contract.
                let ($x, $y) = unsafe { (self.a.entry(k, r, c, bb), self.b.entry(k, r, c, bb)) };
                $f
            }
            fn sparse_compatible(&self, p: &SparsityPattern) -> bool {
                self.a.sparse_compatible(p) && self.b.sparse_compatible(p)
            }
            fn cuda(&self, g: &mut CudaGen) -> String {
                let $ca = self.a.cuda(g);
                let $cb = self.b.cuda(g);
                let $s = self;
                let _ = $s;
                $cuda
            }
        }
    };
}

/// Lane-wise binary operation of two operands of the same element type.
#[derive(Clone, Copy, Debug)]
pub struct Binary<A, B, Op> {
    a: A,
    b: B,
    shape: Shape,
    _op: PhantomData<Op>,
}
impl<A: Expr, B: Expr<Elem = A::Elem>, Op: BinaryOp> Binary<A, B, Op> {
    /// The node; panics when the shapes do not broadcast.
    #[track_caller]
    pub fn new(a: A, b: B) -> Self {
        let shape = a.shape().broadcast(b.shape(), Op::NAME);
        Self {
            a,
            b,
            shape,
            _op: PhantomData,
        }
    }
}
binary_node_impl!(Binary<A, B, Op> where [A: Expr, B: Expr<Elem = A::Elem>, Op: BinaryOp],
    Elem = A::Elem, |x, y| x.zip(y, Op::apply),
    cuda = |s, a, b| crate::cuda_codegen::binary_text::<A::Elem>(Op::CUDA, &a, &b));

/// Element product with the scalar's own product ([`ScalarMul`]).
#[derive(Clone, Copy, Debug)]
pub struct CwiseMul<A, B> {
    a: A,
    b: B,
    shape: Shape,
}
impl<A: Expr, B: Expr> CwiseMul<A, B>
where
    A::Elem: ScalarMul<B::Elem>,
{
    /// The node; panics when the shapes do not broadcast.
    #[track_caller]
    pub fn new(a: A, b: B) -> Self {
        let shape = a.shape().broadcast(b.shape(), "cwise_mul");
        Self { a, b, shape }
    }
}
binary_node_impl!(CwiseMul<A, B> where [A: Expr, B: Expr, A::Elem: ScalarMul<B::Elem>],
    Elem = <A::Elem as ScalarMul<B::Elem>>::Output, |x, y| x.smul(y),
    cuda = |s, a, b| <A::Elem as ScalarMul<B::Elem>>::cuda_mul(&a, &b));

/// Per-element inner product ([`Scalar::dot`]), real-valued.
#[derive(Clone, Copy, Debug)]
pub struct DotElem<A, B> {
    a: A,
    b: B,
    shape: Shape,
}
impl<A: Expr, B: Expr<Elem = A::Elem>> DotElem<A, B> {
    /// The node; panics when the shapes do not broadcast.
    #[track_caller]
    pub fn new(a: A, b: B) -> Self {
        let shape = a.shape().broadcast(b.shape(), "dot");
        Self { a, b, shape }
    }
}
binary_node_impl!(DotElem<A, B> where [A: Expr, B: Expr<Elem = A::Elem>],
    Elem = <A::Elem as Scalar>::Real, |x, y| x.dot(y),
    cuda = |s, a, b| format!("gpumat_dot({a}, {b})"));

/// Generates the plumbing of a node with one operand `e` mapped by `$f`.
macro_rules! map_node_impl {
    ($node:ident<$($g:ident),*> where [$($bounds:tt)*], Elem = $elem:ty, |$s:ident, $x:ident| $f:expr, cuda = |$cs:ident, $ca:ident| $cuda:expr) => {
        impl<$($g),*> Expr for $node<$($g),*> where $($bounds)* {
            type Elem = $elem;
            const SELF_REF: bool = E::SELF_REF;
            fn shape(&self) -> Shape {
                self.e.shape()
            }
            fn bytes_per_element(&self) -> usize {
                self.e.bytes_per_element()
            }
            fn linear(&self, out: Shape) -> bool {
                self.e.linear(out)
            }
            #[inline(always)]
            unsafe fn at(&self, r: usize, c: usize, b: usize) -> $elem {
                let $s = self;
                // SAFETY: forwarded contract.
                let $x = unsafe { self.e.at(r, c, b) };
                $f
            }
            #[inline(always)]
            unsafe fn at_linear(&self, i: usize) -> $elem {
                let $s = self;
                // SAFETY: forwarded contract.
                let $x = unsafe { self.e.at_linear(i) };
                $f
            }
            #[inline(always)]
            unsafe fn entry(&self, k: usize, r: usize, c: usize, b: usize) -> $elem {
                let $s = self;
                // SAFETY: forwarded contract.
                let $x = unsafe { self.e.entry(k, r, c, b) };
                $f
            }
            fn sparse_compatible(&self, p: &SparsityPattern) -> bool {
                self.e.sparse_compatible(p)
            }
            fn cuda(&self, g: &mut CudaGen) -> String {
                let $ca = self.e.cuda(g);
                let $cs = self;
                $cuda
            }
        }
    };
}

/// Multiplication by a real constant.
#[derive(Clone, Copy, Debug)]
pub struct Scale<E: Expr> {
    e: E,
    s: <E::Elem as Scalar>::Real,
}
impl<E: Expr> Scale<E> {
    /// The node.
    pub fn new(e: E, s: <E::Elem as Scalar>::Real) -> Self {
        Self { e, s }
    }
}
map_node_impl!(Scale<E> where [E: Expr], Elem = E::Elem, |s, x| x.scale(s.s),
    cuda = |s, a| format!("({a} * {})", crate::scalar::Real::cuda_literal(s.s)));

/// Element type conversion.
#[derive(Clone, Copy, Debug)]
pub struct Cast<E, U> {
    e: E,
    _u: PhantomData<U>,
}
impl<E: Expr, U: CastFrom<E::Elem>> Cast<E, U> {
    /// The node.
    pub fn new(e: E) -> Self {
        Self { e, _u: PhantomData }
    }
}
map_node_impl!(Cast<E, U> where [E: Expr, U: CastFrom<E::Elem>], Elem = U, |_s, x| U::cast_from(x),
    cuda = |_s, a| format!("gpumat_cast<{}>({a})", U::CUDA_TYPE));

/// Per-element squared norm, real-valued.
#[derive(Clone, Copy, Debug)]
pub struct SquaredNormElem<E> {
    e: E,
}
impl<E: Expr> SquaredNormElem<E> {
    /// The node.
    pub fn new(e: E) -> Self {
        Self { e }
    }
}
map_node_impl!(SquaredNormElem<E> where [E: Expr], Elem = <E::Elem as Scalar>::Real, |_s, x| x.dot(x),
    cuda = |_s, a| format!("gpumat_squared_norm({a})"));

/// Transpose: rows and columns swapped, each block transposed.
#[derive(Clone, Copy, Debug)]
pub struct Transpose<E> {
    e: E,
}
impl<E: Expr> Transpose<E> {
    /// The node. Transposing an expression that reads its own destination is refused at
    /// compile time (it would read elements other threads write).
    pub fn new(e: E) -> Self {
        const {
            assert!(
                !E::SELF_REF,
                "gpumat: cannot transpose an expression that reads its destination"
            )
        };
        Self { e }
    }
}
impl<E: Expr> Expr for Transpose<E> {
    type Elem = E::Elem;
    fn bytes_per_element(&self) -> usize {
        self.e.bytes_per_element()
    }
    fn shape(&self) -> Shape {
        self.e.shape().transposed()
    }
    fn linear(&self, out: Shape) -> bool {
        (out.rows == 1 || out.cols == 1) && self.e.linear(out.transposed())
    }
    #[inline(always)]
    unsafe fn at(&self, r: usize, c: usize, b: usize) -> E::Elem {
        // SAFETY: (c, r, b) lies in the transposed output shape, to which `e` broadcasts.
        unsafe { self.e.at(c, r, b) }.transpose()
    }
    #[inline(always)]
    unsafe fn at_linear(&self, i: usize) -> E::Elem {
        // SAFETY: for a vector-shaped output the transposed linear index is the same.
        unsafe { self.e.at_linear(i) }.transpose()
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        g.swap_rc();
        let a = self.e.cuda(g);
        g.restore_rc();
        format!("gpumat_transpose({a})")
    }
}

/// A vector as the diagonal of a square matrix.
#[derive(Clone, Copy, Debug)]
pub struct AsDiagonal<E> {
    e: E,
    n: usize,
}
impl<E: Expr> AsDiagonal<E> {
    /// The node; panics unless `e` is a vector.
    #[track_caller]
    pub fn new(e: E) -> Self {
        const {
            assert!(
                !E::SELF_REF,
                "gpumat: as_diagonal of an expression that reads its destination"
            )
        };
        let s = e.shape();
        assert!(
            s.rows == 1 || s.cols == 1,
            "gpumat::as_diagonal: {s:?} is not a vector"
        );
        Self {
            e,
            n: s.rows.max(s.cols),
        }
    }
}
impl<E: Expr> Expr for AsDiagonal<E> {
    type Elem = E::Elem;
    fn bytes_per_element(&self) -> usize {
        self.e.bytes_per_element()
    }
    fn shape(&self) -> Shape {
        Shape::new(self.n, self.n, self.e.shape().batches)
    }
    fn linear(&self, _out: Shape) -> bool {
        false
    }
    #[inline(always)]
    unsafe fn at(&self, r: usize, c: usize, b: usize) -> E::Elem {
        if r == c {
            // SAFETY: the vector is n x 1 or 1 x n; the dimension of size 1 is repeated, so
            // (r, r, b) reads element r.
            unsafe { self.e.at(r, r, b) }
        } else {
            E::Elem::ZERO
        }
    }
    #[inline(always)]
    unsafe fn at_linear(&self, _i: usize) -> E::Elem {
        unreachable!("gpumat::AsDiagonal is never evaluated linearly")
    }
    fn cuda(&self, g: &mut CudaGen) -> String {
        let (r, c) = g.coords();
        g.diag_rc();
        let a = self.e.cuda(g);
        g.restore_rc();
        format!("({r} == {c} ? {a} : gpumat_zero<{}>())", E::Elem::CUDA_TYPE)
    }
}
