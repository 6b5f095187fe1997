//! Reductions over rows, columns, batches or everything: sum, prod, min, max, dot,
//! squared norm, norm. Reductions accept whole expression trees, so `(a - b).squared_norm()`
//! makes one pass and no temporary.
//!
//! Determinism: the reduced index range of each output is cut into fixed blocks of
//! [`BLOCK`] elements; a block is reduced with 8 interleaved accumulators combined in a fixed
//! tree, and the block results are combined by a fixed pairwise tree. Nothing depends on
//! which thread ran which block, so results are bitwise identical for any thread count.

use super::{Ex, Expr};
use crate::matrix::{Matrix, Shape};
use crate::scalar::{Real, Scalar};
use crate::stats;
use num_traits::Float;
use rayon::prelude::*;

/// Elements per reduction block.
pub const BLOCK: usize = 4096;

/// A set of dimensions to reduce over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Axes {
    /// reduce over rows
    pub rows: bool,
    /// reduce over columns
    pub cols: bool,
    /// reduce over batches
    pub batches: bool,
}
impl Axes {
    /// Over rows: the result has one row.
    pub const ROWS: Axes = Axes {
        rows: true,
        cols: false,
        batches: false,
    };
    /// Over columns: the result has one column.
    pub const COLS: Axes = Axes {
        rows: false,
        cols: true,
        batches: false,
    };
    /// Over batches: the result has one batch.
    pub const BATCHES: Axes = Axes {
        rows: false,
        cols: false,
        batches: true,
    };
    /// Over everything: the result is 1x1x1.
    pub const ALL: Axes = Axes {
        rows: true,
        cols: true,
        batches: true,
    };
    fn out_shape(self, s: Shape) -> Shape {
        Shape::new(
            if self.rows { 1 } else { s.rows },
            if self.cols { 1 } else { s.cols },
            if self.batches { 1 } else { s.batches },
        )
    }
}
impl std::ops::BitOr for Axes {
    type Output = Axes;
    fn bitor(self, o: Axes) -> Axes {
        Axes {
            rows: self.rows || o.rows,
            cols: self.cols || o.cols,
            batches: self.batches || o.batches,
        }
    }
}

#[inline(always)]
fn tree8<T: Copy>(a: [T; 8], f: &impl Fn(T, T) -> T) -> T {
    f(f(f(a[0], a[1]), f(a[2], a[3])), f(f(a[4], a[5]), f(a[6], a[7])))
}

fn tree<T: Copy>(v: &[T], f: &impl Fn(T, T) -> T) -> T {
    match v.len() {
        1 => v[0],
        n => {
            let h = n.div_ceil(2);
            f(tree(&v[..h], f), tree(&v[h..], f))
        }
    }
}

/// Reduces the elements `start..end` of output `o` with 8 interleaved accumulators.
#[inline(always)]
fn block_reduce<T: Copy>(
    o: usize,
    start: usize,
    end: usize,
    id: T,
    f: &impl Fn(T, T) -> T,
    element: &impl Fn(usize, usize) -> T,
) -> T {
    let mut acc = [id; 8];
    let mut t = start;
    while t + 8 <= end {
        for k in 0..8 {
            acc[k] = f(acc[k], element(o, t + k));
        }
        t += 8;
    }
    for k in 0..end - t {
        acc[k] = f(acc[k], element(o, t + k));
    }
    tree8(acc, f)
}

/// Reduces `e` over `axes` with the associative `f` and its identity `id`.
pub(crate) fn reduce<E, T, F>(e: &E, axes: Axes, id: T, f: F) -> Matrix<T>
where
    E: Expr<Elem = T>,
    T: Scalar,
    F: Fn(T, T) -> T + Sync,
{
    stats::count_pass();
    let s = e.shape();
    let out = axes.out_shape(s);
    let len = (if axes.rows { s.rows } else { 1 })
        * (if axes.cols { s.cols } else { 1 })
        * (if axes.batches { s.batches } else { 1 });
    if len == 0 || out.is_empty() {
        return Matrix::constant(out.rows, out.cols, out.batches, id);
    }
    // Each output's reduced elements are one contiguous linear range when the reduced axes
    // are rows, rows+cols, or everything.
    let contiguous =
        e.linear(s) && (axes == Axes::ROWS || axes == (Axes::ROWS | Axes::COLS) || axes == Axes::ALL);
    let blocks = len.div_ceil(BLOCK);
    let general = |o: usize, t: usize| -> T {
        let (or, oc, ob) = (o % out.rows, (o / out.rows) % out.cols, o / (out.rows * out.cols));
        let mut t = t;
        let r = if axes.rows {
            let v = t % s.rows;
            t /= s.rows;
            v
        } else {
            or
        };
        let c = if axes.cols {
            let v = t % s.cols;
            t /= s.cols;
            v
        } else {
            oc
        };
        let b = if axes.batches { t } else { ob };
        // SAFETY: (r, c, b) lies inside `s`, the expression's own shape.
        unsafe { e.at(r, c, b) }
    };
    let linear = |o: usize, t: usize| -> T {
        // SAFETY: `linear(s)` holds and `o * len + t < s.len()` (the outputs tile the input).
        unsafe { e.at_linear(o * len + t) }
    };
    let block = |task: usize| -> T {
        let (o, j) = (task / blocks, task % blocks);
        let start = j * BLOCK;
        let end = (start + BLOCK).min(len);
        if contiguous {
            block_reduce(o, start, end, id, &f, &linear)
        } else {
            block_reduce(o, start, end, id, &f, &general)
        }
    };
    let tasks = out.len() * blocks;
    // the blocks are fixed whatever runs them, so the bits do not depend on this choice
    let bytes = (out.len() * len).saturating_mul(e.bytes_per_element().max(1));
    let partials: Vec<T> = if tasks > 1 && super::assign::worth_parallel(bytes) {
        (0..tasks).into_par_iter().map(block).collect()
    } else {
        (0..tasks).map(block).collect()
    };
    let data: Vec<T> = partials.chunks(blocks).map(|p| tree(p, &f)).collect();
    Matrix::from_vec(out.rows, out.cols, out.batches, data)
}

impl<E: Expr> Ex<E> {
    /// Sum over `axes`.
    pub fn sum_over(&self, axes: Axes) -> Matrix<E::Elem> {
        reduce(&self.0, axes, E::Elem::ZERO, |a: E::Elem, b| a.add(b))
    }
    /// Sum of all elements.
    pub fn sum(&self) -> E::Elem {
        self.sum_over(Axes::ALL).as_slice()[0]
    }
    /// Inner products ([`Scalar::dot`]) with `b` over `axes`.
    #[track_caller]
    pub fn dot_over<B: Expr<Elem = E::Elem>>(
        self,
        b: Ex<B>,
        axes: Axes,
    ) -> Matrix<<E::Elem as Scalar>::Real> {
        self.cwise_dot(b).sum_over(axes)
    }
    /// The inner product of everything with `b`.
    #[track_caller]
    pub fn dot<B: Expr<Elem = E::Elem>>(self, b: Ex<B>) -> <E::Elem as Scalar>::Real {
        self.cwise_dot(b).sum()
    }
    /// Squared norms over `axes`.
    pub fn squared_norm_over(self, axes: Axes) -> Matrix<<E::Elem as Scalar>::Real> {
        self.cwise_squared_norm().sum_over(axes)
    }
    /// Squared Euclidean (Frobenius) norm of everything.
    pub fn squared_norm(self) -> <E::Elem as Scalar>::Real {
        self.cwise_squared_norm().sum()
    }
    /// Norms over `axes`.
    pub fn norm_over(self, axes: Axes) -> Matrix<<E::Elem as Scalar>::Real> {
        let mut m = self.squared_norm_over(axes);
        for v in m.as_mut_slice() {
            *v = num_traits::Float::sqrt(*v);
        }
        m
    }
    /// Euclidean (Frobenius) norm of everything.
    pub fn norm(self) -> <E::Elem as Scalar>::Real {
        num_traits::Float::sqrt(self.squared_norm())
    }
}

impl<E: Expr> Ex<E>
where
    E::Elem: Real,
{
    /// Product over `axes`.
    pub fn prod_over(&self, axes: Axes) -> Matrix<E::Elem> {
        reduce(&self.0, axes, E::Elem::ONE, |a: E::Elem, b| a * b)
    }
    /// Product of all elements.
    pub fn prod(&self) -> E::Elem {
        self.prod_over(Axes::ALL).as_slice()[0]
    }
    /// Minimum over `axes` (NaN elements are ignored unless all are NaN).
    pub fn min_over(&self, axes: Axes) -> Matrix<E::Elem> {
        reduce(&self.0, axes, E::Elem::infinity(), |a: E::Elem, b| a.min(b))
    }
    /// Minimum of all elements.
    pub fn min(&self) -> E::Elem {
        self.min_over(Axes::ALL).as_slice()[0]
    }
    /// Maximum over `axes`.
    pub fn max_over(&self, axes: Axes) -> Matrix<E::Elem> {
        reduce(&self.0, axes, E::Elem::neg_infinity(), |a: E::Elem, b| a.max(b))
    }
    /// Maximum of all elements.
    pub fn max(&self) -> E::Elem {
        self.max_over(Axes::ALL).as_slice()[0]
    }
}
