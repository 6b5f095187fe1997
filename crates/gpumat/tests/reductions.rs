//! Reductions against naive `f64` loops: `sum/prod/min/max/dot/squared_norm/norm` and their
//! `_over` forms over every combination of ROWS, COLS and BATCHES (none, single axes, pairs,
//! ALL), for `f32` and `f64`, on matrix leaves (contiguous path) and on broadcast expressions
//! (coordinate path), on small shapes and on shapes large enough for several blocks and the
//! parallel path. Sums are checked against the rigorous bound `n eps sum|x|`, products against
//! `(n+1) eps |prod|`, min/max exactly.

mod common;

use common::*;
use gpumat::{Axes, Matrix, Real, Shape};
use proptest::prelude::*;

type Dims = (usize, usize, usize);

/// Every set of axes, from none to all.
fn all_axes() -> Vec<Axes> {
    (0..8u8)
        .map(|m| Axes {
            rows: m & 1 != 0,
            cols: m & 2 != 0,
            batches: m & 4 != 0,
        })
        .collect()
}

/// For each output element of reducing a `s`-shaped array over `axes` (in the output's
/// column-major order), the linear indices of the input elements it reduces.
fn groups(s: Dims, axes: Axes) -> (Dims, Vec<Vec<usize>>) {
    let out = (
        if axes.rows { 1 } else { s.0 },
        if axes.cols { 1 } else { s.1 },
        if axes.batches { 1 } else { s.2 },
    );
    let mut g = vec![Vec::new(); out.0 * out.1 * out.2];
    for b in 0..s.2 {
        for c in 0..s.1 {
            for r in 0..s.0 {
                let o = bget_index(out, r, c, b);
                g[o].push(r + s.0 * (c + s.1 * b));
            }
        }
    }
    (out, g)
}

fn bget_index(s: Dims, r: usize, c: usize, b: usize) -> usize {
    let r = if s.0 == 1 { 0 } else { r };
    let c = if s.1 == 1 { 0 } else { c };
    let b = if s.2 == 1 { 0 } else { b };
    r + s.0 * (c + s.1 * b)
}

#[track_caller]
fn check_shape<T: gpumat::Scalar>(m: &Matrix<T>, out: Dims, what: &str) {
    assert_eq!(m.shape(), Shape::new(out.0, out.1, out.2), "{what}: output shape");
}

/// Checks every reduction of the element values `x` (and `y` for dot), which the library sees
/// through the expressions given by the closures, over every set of axes.
#[allow(clippy::type_complexity)]
fn check_all<R: Real>(
    s: Dims,
    x: &[f64],
    y: &[f64],
    pos: &[f64],
    sum: &dyn Fn(Axes) -> Matrix<R>,
    prod: &dyn Fn(Axes) -> Matrix<R>,
    min: &dyn Fn(Axes) -> Matrix<R>,
    max: &dyn Fn(Axes) -> Matrix<R>,
    dot: &dyn Fn(Axes) -> Matrix<R>,
    sq: &dyn Fn(Axes) -> Matrix<R>,
    norm: &dyn Fn(Axes) -> Matrix<R>,
) {
    let e = eps::<R>();
    for axes in all_axes() {
        let (out, g) = groups(s, axes);
        let (rs, rp, rmin, rmax, rd, rsq, rn) = (
            sum(axes),
            prod(axes),
            min(axes),
            max(axes),
            dot(axes),
            sq(axes),
            norm(axes),
        );
        for (name, m) in [("sum", &rs), ("prod", &rp), ("min", &rmin), ("max", &rmax)] {
            check_shape(m, out, name);
        }
        for (name, m) in [("dot", &rd), ("squared_norm", &rsq), ("norm", &rn)] {
            check_shape(m, out, name);
        }
        for (o, idx) in g.iter().enumerate() {
            let n = idx.len() as f64;
            let what = |op: &str| format!("{op} over {axes:?} of {s:?}, output {o}");
            let want: f64 = idx.iter().map(|&i| x[i]).sum();
            let abs: f64 = idx.iter().map(|&i| x[i].abs()).sum();
            assert_close(rs.as_slice()[o].as_f64(), want, n * e * abs, &what("sum"));
            let want: f64 = idx.iter().map(|&i| pos[i]).product();
            assert_close(
                rp.as_slice()[o].as_f64(),
                want,
                (n + 1.0) * e * want,
                &what("prod"),
            );
            let want = idx.iter().map(|&i| x[i]).fold(f64::INFINITY, f64::min);
            assert_eq!(rmin.as_slice()[o].as_f64(), want, "{}", what("min"));
            let want = idx.iter().map(|&i| x[i]).fold(f64::NEG_INFINITY, f64::max);
            assert_eq!(rmax.as_slice()[o].as_f64(), want, "{}", what("max"));
            let want: f64 = idx.iter().map(|&i| x[i] * y[i]).sum();
            let abs: f64 = idx.iter().map(|&i| (x[i] * y[i]).abs()).sum();
            assert_close(rd.as_slice()[o].as_f64(), want, (n + 1.0) * e * abs, &what("dot"));
            let want: f64 = idx.iter().map(|&i| x[i] * x[i]).sum();
            assert_close(
                rsq.as_slice()[o].as_f64(),
                want,
                (n + 1.0) * e * want,
                &what("sq"),
            );
            let want = want.sqrt();
            assert_close(
                rn.as_slice()[o].as_f64(),
                want,
                (n + 3.0) * e * want,
                &what("norm"),
            );
        }
    }
}

/// The range of the factors of products: wide for small shapes, close to 1 for large ones
/// so that products of tens of thousands of factors neither overflow nor underflow.
fn prod_range(s: Dims) -> (f64, f64) {
    if s.0 * s.1 * s.2 <= 256 {
        (0.5, 2.0)
    } else {
        (0.999, 1.001)
    }
}

/// Reductions of matrix leaves (read contiguously where the axes allow it).
fn check_leaves<R: Real + gpumat::ScalarMul<Output = R>>(seed: u64, s: Dims) {
    let mut rng = Rand::new(seed);
    let a = random_matrix::<R>(&mut rng, s, -10.0, 10.0);
    let b = random_matrix::<R>(&mut rng, s, -10.0, 10.0);
    let (lo, hi) = prod_range(s);
    let p = random_matrix::<R>(&mut rng, s, lo, hi);
    let (x, y, pos) = (lanes_f64(&a), lanes_f64(&b), lanes_f64(&p));
    check_all::<R>(
        s,
        &x,
        &y,
        &pos,
        &|ax| a.ex().sum_over(ax),
        &|ax| p.ex().prod_over(ax),
        &|ax| a.ex().min_over(ax),
        &|ax| a.ex().max_over(ax),
        &|ax| a.ex().dot_over(b.ex(), ax),
        &|ax| a.ex().squared_norm_over(ax),
        &|ax| a.ex().norm_over(ax),
    );
    // The scalar forms are the reductions over everything.
    let e = eps::<R>();
    let n = x.len() as f64;
    let abs: f64 = x.iter().map(|v| v.abs()).sum();
    assert_close(a.ex().sum().as_f64(), x.iter().sum(), n * e * abs, "sum()");
    let want: f64 = pos.iter().product();
    assert_close(p.ex().prod().as_f64(), want, (n + 1.0) * e * want, "prod()");
    assert_eq!(
        a.ex().min().as_f64(),
        x.iter().copied().fold(f64::INFINITY, f64::min)
    );
    assert_eq!(
        a.ex().max().as_f64(),
        x.iter().copied().fold(f64::NEG_INFINITY, f64::max)
    );
    let dabs: f64 = x.iter().zip(&y).map(|(u, v)| (u * v).abs()).sum();
    let d: f64 = x.iter().zip(&y).map(|(u, v)| u * v).sum();
    assert_close(a.ex().dot(b.ex()).as_f64(), d, (n + 1.0) * e * dabs, "dot()");
    let sq: f64 = x.iter().map(|v| v * v).sum();
    assert_close(
        a.ex().squared_norm().as_f64(),
        sq,
        (n + 1.0) * e * sq,
        "squared_norm()",
    );
    assert_close(
        a.ex().norm().as_f64(),
        sq.sqrt(),
        (n + 3.0) * e * sq.sqrt(),
        "norm()",
    );
}

/// Reductions of broadcast expressions `col + row` (`rows x 1 x 1` plus `1 x cols x batches`),
/// read by coordinates; the element values are the sums rounded to `R`.
fn check_broadcast_expr<R: Real + gpumat::ScalarMul<Output = R>>(seed: u64, s: Dims) {
    let mut rng = Rand::new(seed);
    let col = random_matrix::<R>(&mut rng, (s.0, 1, 1), -10.0, 10.0);
    let row = random_matrix::<R>(&mut rng, (1, s.1, s.2), -10.0, 10.0);
    let other = random_matrix::<R>(&mut rng, (s.0, s.1, 1), -10.0, 10.0);
    let (lo, hi) = prod_range(s);
    let pc = random_matrix::<R>(&mut rng, (s.0, 1, s.2), lo.sqrt(), hi.sqrt());
    let pr = random_matrix::<R>(&mut rng, (1, s.1, 1), lo.sqrt(), hi.sqrt());
    let mut x = Vec::new();
    let mut y = Vec::new();
    let mut pos = Vec::new();
    for b in 0..s.2 {
        for c in 0..s.1 {
            for r in 0..s.0 {
                x.push((col.get(r, 0, 0) + row.get(0, c, b)).as_f64());
                y.push(other.get(r, c, 0).as_f64());
                pos.push((pc.get(r, 0, b) * pr.get(0, c, 0)).as_f64());
            }
        }
    }
    let e = || col.ex() + row.ex();
    let p = || pc.ex().cwise_mul(pr.ex());
    check_all::<R>(
        s,
        &x,
        &y,
        &pos,
        &|ax| e().sum_over(ax),
        &|ax| p().prod_over(ax),
        &|ax| e().min_over(ax),
        &|ax| e().max_over(ax),
        &|ax| e().dot_over(other.ex(), ax),
        &|ax| e().squared_norm_over(ax),
        &|ax| e().norm_over(ax),
    );
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn reductions_of_leaves(seed in any::<u64>(), s in (1usize..7, 1usize..7, 1usize..5)) {
        check_leaves::<f32>(seed, s);
        check_leaves::<f64>(seed, s);
    }

    #[test]
    fn reductions_of_broadcast_expressions(seed in any::<u64>(), s in (1usize..7, 1usize..7, 1usize..5)) {
        check_broadcast_expr::<f32>(seed, s);
        check_broadcast_expr::<f64>(seed, s);
    }
}

/// Shapes with several reduction blocks per output and enough work for the parallel path.
#[test]
fn large_reductions_over_every_axis_set() {
    for (seed, s) in [(1u64, (5000, 3, 4)), (2, (3, 7000, 2)), (3, (17, 5, 900))] {
        check_leaves::<f32>(seed, s);
        check_leaves::<f64>(seed, s);
    }
    check_broadcast_expr::<f32>(4, (600, 30, 3));
}

/// Empty reductions give the operation's identity; reducing over no axis copies.
#[test]
fn degenerate_reductions() {
    let a = Matrix::<f64>::zeros(0, 3, 2);
    assert_eq!(a.ex().sum_over(Axes::ROWS).as_slice(), &[0.0; 6]);
    assert_eq!(a.ex().prod_over(Axes::ROWS).as_slice(), &[1.0; 6]);
    assert_eq!(a.ex().max(), f64::NEG_INFINITY);
    assert_eq!(a.ex().min(), f64::INFINITY);
    let b = Matrix::<f32>::from_fn(2, 3, 2, |r, c, k| (r + 10 * c + 100 * k) as f32);
    let none = Axes {
        rows: false,
        cols: false,
        batches: false,
    };
    assert_eq!(b.ex().sum_over(none), b);
    // min ignores NaN unless everything is NaN.
    let n = Matrix::<f32>::from_slice(3, 1, 1, &[f32::NAN, 2.0, -1.0]);
    assert_eq!(n.ex().min(), -1.0);
    assert_eq!(n.ex().max(), 2.0);
}

/// `(a - b).squared_norm()` is a reduction of a whole expression tree: same value as reducing
/// the evaluated difference, bit for bit (same elements, same order).
#[test]
fn reducing_an_expression_equals_reducing_its_value() {
    let mut rng = Rand::new(11);
    let a = random_matrix::<f32>(&mut rng, (300, 40, 3), -1e3, 1e3);
    let b = random_matrix::<f32>(&mut rng, (300, 40, 3), -1e-3, 1e-3);
    let diff = Matrix::eval(a.ex() - b.ex());
    for axes in all_axes() {
        assert_eq!(
            (a.ex() - b.ex()).squared_norm_over(axes),
            diff.ex().squared_norm_over(axes),
            "{axes:?}"
        );
        assert_eq!(
            (a.ex() - b.ex()).sum_over(axes),
            diff.ex().sum_over(axes),
            "{axes:?}"
        );
    }
}
