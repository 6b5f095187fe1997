//! Element-wise expressions against naive `f64` loops, for `f32` and `f64`: `+ - scale`,
//! `cwise_mul/div/min/max/pow`, every unary operation of `gpumat::ops::UNARY_TABLE` on its
//! domain, casts, transpose, `as_diagonal`, the constant/zeros/identity/scalar nodes,
//! broadcasting of every dimension of size 1 (batches included, and at the assignment
//! level), compound `+= -= *= /=` and `assign_with`, on both the sequential and the parallel
//! chunked evaluation paths (linear and coordinate-wise).

mod common;

use common::*;
use gpumat::{Matrix, Real, ScalarMul};
use proptest::prelude::*;

type Dims = (usize, usize, usize);

/// `out` with the dimensions selected by the bits of `mask` set to 1.
fn masked(out: Dims, mask: u8) -> Dims {
    (
        if mask & 1 != 0 { 1 } else { out.0 },
        if mask & 2 != 0 { 1 } else { out.1 },
        if mask & 4 != 0 { 1 } else { out.2 },
    )
}

/// Calls `f(r, c, b)` for every position of `s` in column-major order.
fn for_each(s: Dims, mut f: impl FnMut(usize, usize, usize)) {
    for b in 0..s.2 {
        for c in 0..s.1 {
            for r in 0..s.0 {
                f(r, c, b);
            }
        }
    }
}

/// `d = a + s b - a.*b` with `a`, `b` broadcast along the dimensions chosen by the masks.
fn check_broadcast<R: Real + ScalarMul<Output = R>>(seed: u64, out: Dims, ma: u8, mb: u8, s: f64) {
    let mut rng = Rand::new(seed);
    let (sa, sb) = (masked(out, ma), masked(out, mb));
    let a = random_matrix::<R>(&mut rng, sa, -10.0, 10.0);
    let b = random_matrix::<R>(&mut rng, sb, -10.0, 10.0);
    let s = R::of(s);
    let mut d = Matrix::<R>::constant(out.0, out.1, out.2, R::of(123.0));
    d.assign(a.ex() + b.ex().scale(s) - a.ex().cwise_mul(b.ex()));
    let (fa, fb, fs) = (lanes_f64(&a), lanes_f64(&b), s.as_f64());
    for_each(out, |r, c, bb| {
        let (x, y) = (bget(&fa, sa, r, c, bb), bget(&fb, sb, r, c, bb));
        let want = x + fs * y - x * y;
        let mag = x.abs() + (fs * y).abs() + (x * y).abs();
        assert_close(
            d.get(r, c, bb).as_f64(),
            want,
            4.0 * eps::<R>() * mag,
            &format!("broadcast {sa:?} {sb:?} -> {out:?} at ({r},{c},{bb})"),
        );
    });
}

/// Binary lane-wise operations and operator spellings, each a single rounding: the result
/// must equal the `f64` result rounded to `R` exactly (or within a few ulps for div/pow).
fn check_binary<R: Real + ScalarMul<Output = R>>(seed: u64, s: Dims) {
    let mut rng = Rand::new(seed);
    let a = random_matrix::<R>(&mut rng, s, -10.0, 10.0);
    let b = Matrix::<R>::from_fn(s.0, s.1, s.2, |_, _, _| {
        let m = rng.uniform(0.1, 10.0);
        R::of(if rng.unit() < 0.5 { -m } else { m })
    });
    let pos = random_matrix::<R>(&mut rng, s, 0.1, 10.0);
    let ex = random_matrix::<R>(&mut rng, s, -3.0, 3.0);
    let (fa, fb, fp, fe) = (lanes_f64(&a), lanes_f64(&b), lanes_f64(&pos), lanes_f64(&ex));
    type Case<R> = (&'static str, Matrix<R>, fn(f64, f64) -> f64, bool);
    let cases: Vec<Case<R>> = vec![
        ("add", Matrix::eval(a.ex() + b.ex()), |x, y| x + y, true),
        ("sub", Matrix::eval(a.ex() - b.ex()), |x, y| x - y, true),
        ("mul", Matrix::eval(a.ex().cwise_mul(b.ex())), |x, y| x * y, true),
        ("min", Matrix::eval(a.ex().cwise_min(b.ex())), f64::min, true),
        ("max", Matrix::eval(a.ex().cwise_max(b.ex())), f64::max, true),
        ("div", Matrix::eval(a.ex().cwise_div(b.ex())), |x, y| x / y, false),
    ];
    for (name, got, f, exact) in cases {
        for i in 0..got.len() {
            let want = f(fa[i], fb[i]);
            let g = got.as_slice()[i].as_f64();
            if exact {
                assert_eq!(g, R::of(want).as_f64(), "{name}[{i}] of {} and {}", fa[i], fb[i]);
            } else {
                assert_close(g, want, eps::<R>() * want.abs(), &format!("{name}[{i}]"));
            }
        }
    }
    let pow = Matrix::eval(pos.ex().cwise_pow(ex.ex()));
    for i in 0..pow.len() {
        let want = fp[i].powf(fe[i]);
        assert_close(pow.as_slice()[i].as_f64(), want, 4.0 * eps::<R>() * want, "pow");
    }
    // Negation and scaling are exact.
    let neg = Matrix::eval(-a.ex());
    let half = Matrix::eval(a.ex().scale(R::of(0.5)));
    for i in 0..a.len() {
        assert_eq!(neg.as_slice()[i].as_f64(), -fa[i]);
        assert_eq!(half.as_slice()[i].as_f64(), 0.5 * fa[i]);
    }
}

/// One unary operation: its name in the op table, input domain, `f64` reference and the
/// `Ex` method that applies it (for both real types).
struct UnaryCase {
    name: &'static str,
    lo: f64,
    hi: f64,
    reference: fn(f64) -> f64,
    f32_eval: fn(&Matrix<f32>) -> Matrix<f32>,
    f64_eval: fn(&Matrix<f64>) -> Matrix<f64>,
}

macro_rules! unary_case {
    ($name:literal, $m:ident, $lo:expr, $hi:expr, $r:expr) => {
        UnaryCase {
            name: $name,
            lo: $lo,
            hi: $hi,
            reference: $r,
            f32_eval: |a| Matrix::eval(a.ex().$m()),
            f64_eval: |a| Matrix::eval(a.ex().$m()),
        }
    };
}

fn unary_cases() -> Vec<UnaryCase> {
    vec![
        UnaryCase {
            name: "neg",
            lo: -100.0,
            hi: 100.0,
            reference: |x| -x,
            f32_eval: |a| Matrix::eval(-a.ex()),
            f64_eval: |a| Matrix::eval(-a.ex()),
        },
        unary_case!("sqrt", sqrt, 0.0, 100.0, f64::sqrt),
        unary_case!("rsqrt", rsqrt, 0.01, 100.0, |x| 1.0 / x.sqrt()),
        unary_case!("abs", abs, -100.0, 100.0, f64::abs),
        unary_case!("exp", exp, -20.0, 20.0, f64::exp),
        unary_case!("log", log, 1e-3, 1e3, f64::ln),
        unary_case!("log1p", log1p, -0.9, 100.0, f64::ln_1p),
        unary_case!("sin", sin, -10.0, 10.0, f64::sin),
        unary_case!("cos", cos, -10.0, 10.0, f64::cos),
        unary_case!("tan", tan, -1.4, 1.4, f64::tan),
        unary_case!("tanh", tanh, -10.0, 10.0, f64::tanh),
        unary_case!("square", square, -100.0, 100.0, |x| x * x),
        unary_case!("cube", cube, -20.0, 20.0, |x| x * x * x),
        unary_case!("inverse", inverse, 0.01, 100.0, |x| 1.0 / x),
        unary_case!("floor", floor, -100.0, 100.0, f64::floor),
        unary_case!("ceil", ceil, -100.0, 100.0, f64::ceil),
        unary_case!("sign", sign, -100.0, 100.0, |x| if x > 0.0 {
            1.0
        } else if x < 0.0 {
            -1.0
        } else {
            0.0
        }),
    ]
}

/// Inputs of a unary case: uniform in its domain, a random sign for `inverse` (whose domain
/// excludes zero), and exact zeros and integers mixed in where the domain allows them.
fn unary_inputs(case: &UnaryCase, rng: &mut Rand, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let x = rng.uniform(case.lo, case.hi);
            match (case.name, i % 5) {
                ("inverse", _) if rng.unit() < 0.5 => -x,
                (_, 0) if case.lo <= 0.0 && case.hi >= 0.0 => 0.0,
                (_, 1) if case.lo <= -2.0 && case.hi >= 2.0 => x.round(),
                _ => x,
            }
        })
        .collect()
}

fn check_unary<R: Real>(case: &UnaryCase, x: &[f64], got: &Matrix<R>) {
    // sin/cos/tan near their zeros: the result is small, so a tiny absolute slack of one
    // epsilon on values of order one; everything else is checked relatively.
    let atol = if ["sin", "cos", "tan"].contains(&case.name) {
        eps::<R>()
    } else {
        0.0
    };
    for (i, &xi) in x.iter().enumerate() {
        let xr = R::of(xi).as_f64(); // the input as the matrix stores it
        let want = (case.reference)(xr);
        let tol = 4.0 * eps::<R>() * want.abs() + atol;
        assert_close(
            got.as_slice()[i].as_f64(),
            want,
            tol,
            &format!("{}({xr})", case.name),
        );
        // The table's function by name is the same operation.
        let by_name = gpumat::ops::unary_by_name(case.name, R::of(xr)).expect("name in table");
        assert_eq!(
            by_name.to_bits_f64(),
            got.as_slice()[i].to_bits_f64(),
            "{}",
            case.name
        );
    }
}

trait Bits {
    fn to_bits_f64(self) -> u64;
}
impl<R: Real> Bits for R {
    fn to_bits_f64(self) -> u64 {
        self.as_f64().to_bits()
    }
}

#[test]
fn every_table_unary_op_has_a_case() {
    let cases: Vec<&str> = unary_cases().iter().map(|c| c.name).collect();
    let table: Vec<&str> = gpumat::ops::UNARY_TABLE.iter().map(|e| e.0).collect();
    assert_eq!(cases, table, "unary cases and the op table differ");
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn broadcast_every_dimension(
        seed in any::<u64>(),
        out in (1usize..6, 1usize..6, 1usize..4),
        ma in 0u8..8,
        mb in 0u8..8,
        s in -3.0f64..3.0,
    ) {
        check_broadcast::<f32>(seed, out, ma, mb, s);
        check_broadcast::<f64>(seed, out, ma, mb, s);
    }

    /// Tall outputs (at least 16 rows) with broadcast operands: the row-run evaluation path.
    #[test]
    fn broadcast_tall_outputs(
        seed in any::<u64>(),
        out in (16usize..40, 1usize..5, 1usize..4),
        ma in 0u8..8,
        mb in 0u8..8,
    ) {
        check_broadcast::<f32>(seed, out, ma, mb, 1.5);
        check_broadcast::<f64>(seed, out, ma, mb, -0.75);
    }

    #[test]
    fn binary_operations(seed in any::<u64>(), s in (1usize..6, 1usize..6, 1usize..4)) {
        check_binary::<f32>(seed, s);
        check_binary::<f64>(seed, s);
    }

    #[test]
    fn unary_operations(seed in any::<u64>(), s in (1usize..5, 1usize..4, 1usize..3)) {
        let mut rng = Rand::new(seed);
        for case in unary_cases() {
            let x = unary_inputs(&case, &mut rng, s.0 * s.1 * s.2);
            let a32 = Matrix::from_fn(s.0, s.1, s.2, |r, c, b| x[r + s.0 * (c + s.1 * b)] as f32);
            let a64 = Matrix::from_vec(s.0, s.1, s.2, x.clone());
            check_unary(&case, &x, &(case.f32_eval)(&a32));
            check_unary(&case, &x, &(case.f64_eval)(&a64));
        }
    }

    #[test]
    fn casts_and_operator_spellings(seed in any::<u64>(), s in (1usize..6, 1usize..6, 1usize..4)) {
        let mut rng = Rand::new(seed);
        let a = random_matrix::<f64>(&mut rng, s, -1e3, 1e3);
        let b = random_matrix::<f64>(&mut rng, s, -1e3, 1e3);
        let down = Matrix::<f32>::eval(a.ex().cast::<f32>());
        let up = Matrix::<f64>::eval(down.ex().cast::<f64>());
        for i in 0..a.len() {
            assert_eq!(down.as_slice()[i], a.as_slice()[i] as f32);
            assert_eq!(up.as_slice()[i], down.as_slice()[i] as f64);
        }
        // Operators on matrices and on expressions mean the same thing.
        let e1 = Matrix::eval(&a + &b);
        let e2 = Matrix::eval(a.ex() + &b);
        let e3 = Matrix::eval(&a - b.ex());
        let e4 = Matrix::eval(2.0 * &a - &a * 0.5 + (-&b) + b.ex() / 4.0 + 3.0 * a.ex());
        for i in 0..a.len() {
            let (x, y) = (a.as_slice()[i], b.as_slice()[i]);
            assert_eq!(e1.as_slice()[i], x + y);
            assert_eq!(e2.as_slice()[i], x + y);
            assert_eq!(e3.as_slice()[i], x - y);
            let want = 2.0 * x - 0.5 * x - y + y / 4.0 + 3.0 * x;
            assert_close(e4.as_slice()[i], want, 8.0 * f64::EPSILON * (6.5 * x.abs() + 1.25 * y.abs()), "ops");
        }
    }

    #[test]
    fn transpose_and_diagonal(seed in any::<u64>(), s in (1usize..6, 1usize..6, 1usize..4), mb in 0u8..8) {
        let mut rng = Rand::new(seed);
        let a = random_matrix::<f32>(&mut rng, s, -10.0, 10.0);
        let t = Matrix::eval(a.ex().transpose());
        assert_eq!(t.shape(), gpumat::Shape::new(s.1, s.0, s.2));
        for_each(s, |r, c, b| assert_eq!(t.get(c, r, b), a.get(r, c, b)));
        // Transposed operand broadcast against another operand of the transposed shape.
        let st = masked((s.1, s.0, s.2), mb);
        let o = random_matrix::<f32>(&mut rng, st, -10.0, 10.0);
        let mut d = Matrix::<f32>::zeros(s.1, s.0, s.2);
        d.assign(a.ex().transpose() + o.ex());
        let fo = lanes_f64(&o);
        for_each((s.1, s.0, s.2), |r, c, b| {
            let want = a.get(c, r, b) as f64 + bget(&fo, st, r, c, b);
            assert_eq!(d.get(r, c, b), want as f32, "transpose + broadcast at ({r},{c},{b})");
        });
        // A column vector (n x 1) and a row vector (1 x n) as diagonals, batches broadcast.
        let n = s.0;
        let col = random_matrix::<f32>(&mut rng, (n, 1, s.2), -10.0, 10.0);
        let row = random_matrix::<f32>(&mut rng, (1, n, 1), -10.0, 10.0);
        let mut dd = Matrix::<f32>::zeros(n, n, s.2);
        dd.assign(col.ex().as_diagonal() + row.ex().as_diagonal());
        for_each((n, n, s.2), |r, c, b| {
            let want = if r == c { col.get(r, 0, b) as f64 + row.get(0, r, 0) as f64 } else { 0.0 };
            assert_eq!(dd.get(r, c, b), want as f32, "as_diagonal at ({r},{c},{b})");
        });
        // Vector transpose (read linearly) plus a vector of the transposed shape.
        let v = random_matrix::<f32>(&mut rng, (n, 1, s.2), -10.0, 10.0);
        let w = random_matrix::<f32>(&mut rng, (1, n, s.2), -10.0, 10.0);
        let vt = Matrix::eval(v.ex().transpose() + w.ex());
        for_each((1, n, s.2), |_, c, b| {
            assert_eq!(vt.get(0, c, b), ((v.get(c, 0, b) as f64 + w.get(0, c, b) as f64) as f32));
        });
    }

    #[test]
    fn constant_zeros_identity_nodes(seed in any::<u64>(), s in (1usize..6, 1usize..6, 1usize..4), v in -5.0f64..5.0) {
        let mut rng = Rand::new(seed);
        let a = random_matrix::<f64>(&mut rng, s, -10.0, 10.0);
        let mut d = Matrix::<f64>::constant(s.0, s.1, s.2, 7.0);
        d.assign(gpumat::zeros(s.0, s.1, s.2));
        assert!(d.as_slice().iter().all(|&x| x == 0.0));
        d.assign(gpumat::constant(s.0, s.1, 1, v)); // batches broadcast
        assert!(d.as_slice().iter().all(|&x| x == v));
        d.assign(gpumat::identity(s.0, s.1, 1));
        for_each(s, |r, c, b| assert_eq!(d.get(r, c, b), if r == c { 1.0 } else { 0.0 }));
        d.assign(a.ex() + gpumat::identity::<f64>(s.0, s.1, s.2).scale(v) - gpumat::scalar(v));
        for_each(s, |r, c, b| {
            let want = a.get(r, c, b) + if r == c { v } else { 0.0 } - v;
            assert_close(d.get(r, c, b), want, 4.0 * f64::EPSILON * (a.get(r, c, b).abs() + 2.0 * v.abs()), "identity");
        });
        let k = Matrix::<f32>::eval(gpumat::constant(s.0, 1, s.2, v as f32) + gpumat::zeros(s.0, 1, s.2));
        assert!(k.as_slice().iter().all(|&x| x == v as f32));
        assert_eq!(k.shape(), gpumat::Shape::new(s.0, 1, s.2));
    }

    #[test]
    fn compound_assignments(seed in any::<u64>(), out in (1usize..6, 1usize..6, 1usize..4), ma in 0u8..8, s in -3.0f64..3.0) {
        let mut rng = Rand::new(seed);
        let sa = masked(out, ma);
        let a = random_matrix::<f64>(&mut rng, sa, -10.0, 10.0);
        let b = random_matrix::<f64>(&mut rng, out, -10.0, 10.0);
        let d0 = random_matrix::<f64>(&mut rng, out, -10.0, 10.0);
        let fa = lanes_f64(&a);
        let mut d = d0.clone();
        d += a.ex().scale(s); // broadcast operand
        d -= &b;
        d *= s;
        d /= 4.0;
        let mut e = d0.clone();
        e.assign_with(|e| e.cwise_mul(a.ex()) + e.abs().sqrt() - b.ex());
        let mut f = Matrix::<f32>::eval(d0.ex().cast::<f32>());
        f += a.ex().cast::<f32>();
        f *= 2.0f32;
        for_each(out, |r, c, bb| {
            let (x0, ai, bi) = (d0.get(r, c, bb), bget(&fa, sa, r, c, bb), b.get(r, c, bb));
            let want = (x0 + s * ai - bi) * s / 4.0;
            let mag = (x0.abs() + (s * ai).abs() + bi.abs()) * s.abs() / 4.0;
            assert_close(d.get(r, c, bb), want, 8.0 * f64::EPSILON * mag, "+= -= *= /=");
            let want_e = x0 * ai + x0.abs().sqrt() - bi;
            let mag_e = (x0 * ai).abs() + x0.abs().sqrt() + bi.abs();
            assert_close(e.get(r, c, bb), want_e, 4.0 * f64::EPSILON * mag_e, "assign_with");
            let want_f = 2.0 * ((x0 as f32) as f64 + (ai as f32) as f64);
            let mag_f = 2.0 * (x0.abs() + ai.abs());
            assert_close(f.get(r, c, bb) as f64, want_f, 2.0 * f32::EPSILON as f64 * mag_f, "f32 +=");
        });
    }
}

/// Outputs above the parallel threshold, cut into chunks that start in the middle of a row,
/// column and batch: the coordinate path (broadcast operands), the linear path and a compound
/// assignment must all agree with the naive loop element by element.
#[test]
fn large_assignments_on_the_parallel_path() {
    let out = (37, 29, 33); // 35409 > PAR_THRESHOLD, not a multiple of the chunk size
    assert!(out.0 * out.1 * out.2 >= gpumat::expr::PAR_THRESHOLD);
    let mut rng = Rand::new(7);
    let a = random_matrix::<f32>(&mut rng, out, -10.0, 10.0);
    let col = random_matrix::<f32>(&mut rng, (out.0, 1, 1), -10.0, 10.0);
    let row = random_matrix::<f32>(&mut rng, (1, out.1, out.2), -10.0, 10.0);
    let mut d = Matrix::<f32>::zeros(out.0, out.1, out.2);
    d.assign(col.ex() + row.ex().scale(2.0) - a.ex());
    for_each(out, |r, c, b| {
        let (x, y, z) = (
            col.get(r, 0, 0) as f64,
            row.get(0, c, b) as f64,
            a.get(r, c, b) as f64,
        );
        let tol = 4.0 * f32::EPSILON as f64 * (x.abs() + 2.0 * y.abs() + z.abs());
        assert_close(d.get(r, c, b) as f64, x + 2.0 * y - z, tol, "coordinate path");
    });
    let lin = Matrix::<f32>::eval(a.ex().abs().sqrt() + d.ex().cwise_mul(a.ex()));
    let mut comp = d.clone();
    comp += a.ex().square();
    for i in 0..a.len() {
        let (x, y) = (a.as_slice()[i] as f64, d.as_slice()[i] as f64);
        let tol = 4.0 * f32::EPSILON as f64 * (x.abs().sqrt() + (x * y).abs());
        assert_close(
            lin.as_slice()[i] as f64,
            x.abs().sqrt() + x * y,
            tol,
            "linear path",
        );
        let want = y + x * x;
        assert_close(
            comp.as_slice()[i] as f64,
            want,
            4.0 * f32::EPSILON as f64 * (y.abs() + x * x),
            "+=",
        );
    }
}
