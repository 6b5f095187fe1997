//! The logic check of the expression kernels (emulated CUDA, see tests/emulated.rs): the kernel
//! [`gpumat::cuda_codegen::kernel_source`] emits for an assignment, built with the system C++
//! compiler and launched one thread per output element, gives the CPU loop's values on random
//! inputs, for every unary and binary op of the op table on real, `Vec3` and `Mat3` elements in
//! f32 and f64 with broadcasting in every dimension, and for element products, casts, inner
//! products, transposes, diagonals, identity, compound assignment and sparse products (CSR and
//! BSR, transposed, fused, nested, a sparse leaf).

mod emu;

use emu::{rnd, Args, Emu};
use gpumat::cuda::{launch, KernelSource};
use gpumat::cuda_codegen::kernel_source;
use gpumat::expr::{Binary, Ex, Expr};
use gpumat::ops::{self, BinaryOp, UnaryOp, BINARY_TABLE, UNARY_TABLE};
use gpumat::{Mat3, Matrix, Real, Scalar, ScalarMul, Shape, SparseMatrix, Vec3};

/// The output shape: 555 elements, three blocks of 256 threads.
const OUT: Shape = Shape::new(37, 5, 3);
const PATTERNS: [(&str, Shape); 5] = [
    ("full", OUT),
    ("bcast_rows", Shape::new(1, 5, 3)),
    ("bcast_cols", Shape::new(37, 1, 3)),
    ("bcast_batches", Shape::new(37, 5, 1)),
    ("bcast_all", Shape::new(1, 1, 1)),
];

/// Random matrix of shape `s`; lanes in [0.25, 2.25) when `positive`, else in [-2, 2).
fn random<T: Scalar>(s: Shape, seed: u64, positive: bool) -> Matrix<T> {
    let mut k = 0usize;
    let data: Vec<T> = (0..s.len())
        .map(|_| {
            T::from_lanes(|_| {
                k += 1;
                let v = rnd(seed, k);
                <T::Real as Real>::of(if positive { 1.25 + v } else { 2.0 * v })
            })
        })
        .collect();
    Matrix::from_vec(s.rows, s.cols, s.batches, data)
}

/// Collects the kernel sources (first pass) or runs and compares them (second pass).
struct Run<'a> {
    emu: Option<&'a Emu>,
    sources: Vec<KernelSource>,
    checked: usize,
}

impl Run<'_> {
    fn check<E: Expr + Copy>(&mut self, what: &str, e: E, leaves: impl FnOnce(Args) -> Args) {
        let name = format!("k{}_{what}", self.sources.len() + self.checked);
        let out = e.shape();
        let Some(emu) = self.emu else {
            self.sources.push(KernelSource {
                source: kernel_source(&e, out, &name),
                name: format!("{name}.cu"),
                entries: vec![name],
            });
            return;
        };
        self.checked += 1;
        let cpu = Matrix::eval(Ex(e));
        let mut dst = vec![E::Elem::ZERO; out.len()];
        emu.launch(
            &name,
            launch::elementwise(out.len()),
            leaves(Args::default().out(&mut dst)),
        );
        let tol = if std::mem::size_of::<<E::Elem as Scalar>::Real>() == 4 {
            2e-5
        } else {
            1e-12
        };
        for (i, (g, c)) in dst.iter().zip(cpu.as_slice()).enumerate() {
            for l in 0..E::Elem::LANES {
                let (g, c) = (g.lane(l).as_f64(), c.lane(l).as_f64());
                let ok = (g.is_nan() && c.is_nan()) || g == c || (g - c).abs() <= tol * (1.0 + c.abs());
                assert!(ok, "{name}: element {i} lane {l}: emulated {g}, cpu {c}");
            }
        }
    }
}

fn positive(op: &str) -> bool {
    matches!(op, "sqrt" | "rsqrt" | "log" | "log1p" | "pow")
}

fn unary<T: Scalar, Op: UnaryOp>(run: &mut Run, names: &mut Vec<&'static str>) {
    names.push(Op::NAME);
    let a = random::<T>(OUT, 1, positive(Op::NAME));
    run.check(&format!("unary_{}", Op::NAME), a.ex().unary::<Op>().0, |x| {
        x.buf(a.as_slice())
    });
}

fn binary<T: Scalar, Op: BinaryOp>(run: &mut Run, names: &mut Vec<&'static str>) {
    names.push(Op::NAME);
    let pos = positive(Op::NAME);
    for (i, (pa, sa)) in [PATTERNS[0], PATTERNS[2]].into_iter().enumerate() {
        for (pb, sb) in &PATTERNS[i..] {
            let (a, b) = (random::<T>(sa, 2, pos), random::<T>(*sb, 3, pos));
            let e = Binary::<_, _, Op>::new(a.ex().0, b.ex().0);
            run.check(&format!("binary_{}_{pa}_{pb}", Op::NAME), e, |x| {
                x.buf(a.as_slice()).buf(b.as_slice())
            });
        }
    }
}

macro_rules! each_op {
    ($run:ident, $f:ident, $t:ty, $names:ident: $($op:ident)*) => {
        $($f::<$t, ops::$op>($run, &mut $names);)*
    };
}

fn ops_on<T: Scalar>(run: &mut Run) {
    let mut names = Vec::new();
    each_op!(run, unary, T, names: Neg Sqrt Rsqrt Abs Exp Log Log1p Sin Cos Tan Tanh Square Cube Inverse Floor Ceil Sign);
    let table: Vec<&str> = UNARY_TABLE.iter().map(|u| u.0).collect();
    assert_eq!(names, table, "every unary op is checked");
    names.clear();
    each_op!(run, binary, T, names: AddOp SubOp DivOp MinOp MaxOp PowOp);
    let table: Vec<&str> = BINARY_TABLE.iter().map(|u| u.0).collect();
    assert_eq!(names, table, "every binary op is checked");
    // nodes outside the op table
    let (a, b) = (random::<T>(OUT, 4, false), random::<T>(PATTERNS[1].1, 5, false));
    let half = <T::Real as Real>::of(0.5);
    run.check("scale_neg_plus", (a.ex().scale(half) - b.ex()).0, |x| {
        x.buf(a.as_slice()).buf(b.as_slice())
    });
    run.check("dot", a.ex().cwise_dot(b.ex()).0, |x| {
        x.buf(a.as_slice()).buf(b.as_slice())
    });
    run.check("squared_norm", b.ex().cwise_squared_norm().0, |x| {
        x.buf(b.as_slice())
    });
    let at = random::<T>(OUT.transposed(), 6, false);
    run.check("transpose", (at.ex().transpose() + a.ex()).0, |x| {
        x.buf(at.as_slice()).buf(a.as_slice())
    });
    let v = random::<T>(Shape::new(9, 1, 3), 7, false);
    run.check(
        "as_diagonal",
        (v.ex().as_diagonal() + gpumat::identity::<T>(9, 9, 3)).0,
        |x| x.buf(v.as_slice()),
    );
    let c = random::<T>(Shape::new(1, 1, 1), 8, false).get(0, 0, 0);
    run.check("constant", (a.ex() + gpumat::scalar(c)).0, |x| {
        x.buf(a.as_slice()).val(c)
    });
}

fn products<A: ScalarMul<B>, B: Scalar>(run: &mut Run, what: &str) {
    let a = random::<A>(PATTERNS[2].1, 9, false);
    let b = random::<B>(PATTERNS[1].1, 10, false);
    run.check(&format!("mul_{what}"), a.ex().cwise_mul(b.ex()).0, |x| {
        x.buf(a.as_slice()).buf(b.as_slice())
    });
}

/// A random sparse matrix (`n x n`, three entries per row) with `batches` value sets.
fn sparse<T: Scalar>(n: usize, batches: usize, seed: u64) -> SparseMatrix<T> {
    let mut t = Vec::new();
    for r in 0..n {
        for c in [r, (r + 1) % n, (r + 7) % n] {
            t.push((r, c, T::ZERO));
        }
    }
    let one = SparseMatrix::from_triplets(n, n, &t);
    let vals = random::<T>(Shape::new(one.nnz(), 1, batches), seed, false);
    SparseMatrix::from_values(one.pattern().clone(), batches, vals.into_vec())
}

fn sparse_products<M: ScalarMul<V, Output = V>, V: Scalar>(run: &mut Run, what: &str) {
    let n = 40;
    for (mb, xb) in [(1, 3), (3, 3), (3, 1)] {
        let a = sparse::<M>(n, mb, 11);
        let x = random::<V>(Shape::new(n, 2, xb), 12, false);
        let rp: Vec<u64> = a.pattern().row_ptr().iter().map(|&v| v as u64).collect();
        let ci = a.pattern().col_idx().to_vec();
        let vals = a.values().to_vec();
        run.check(&format!("spmv_{what}_{mb}_{xb}"), a.mul(x.ex()).0, |k| {
            k.buf(&rp).buf(&ci).buf(&vals).buf(x.as_slice())
        });
        let t = a.pattern().transpose_map();
        let (cp, ri, en): (Vec<u64>, Vec<u64>, Vec<u64>) = (
            t.col_ptr.iter().map(|&v| v as u64).collect(),
            t.row_idx.iter().map(|&v| v as u64).collect(),
            t.entry.iter().map(|&v| v as u64).collect(),
        );
        run.check(
            &format!("spmv_t_{what}_{mb}_{xb}"),
            a.transpose_mul(x.ex()).0,
            |k| k.buf(&cp).buf(&ri).buf(&en).buf(&vals).buf(x.as_slice()),
        );
    }
    // A (A x) - 2 y: one kernel, nested row loops
    let a = sparse::<M>(n, 3, 13);
    let (x, y) = (
        random::<V>(Shape::new(n, 1, 3), 14, false),
        random::<V>(Shape::new(n, 1, 3), 15, false),
    );
    let rp: Vec<u64> = a.pattern().row_ptr().iter().map(|&v| v as u64).collect();
    let ci = a.pattern().col_idx().to_vec();
    let vals = a.values().to_vec();
    let two = <V::Real as Real>::of(2.0);
    let e = (a.mul(a.mul(x.ex())) - y.ex().scale(two)).0;
    run.check(&format!("spmv_nested_{what}"), e, |k| {
        k.buf(&rp)
            .buf(&ci)
            .buf(&vals)
            .buf(&rp)
            .buf(&ci)
            .buf(&vals)
            .buf(x.as_slice())
            .buf(y.as_slice())
    });
    run.check(&format!("sparse_leaf_{what}"), a.ex().0, |k| {
        k.buf(&rp).buf(&ci).buf(&vals)
    });
}

fn all(run: &mut Run) {
    ops_on::<f32>(run);
    ops_on::<f64>(run);
    ops_on::<Vec3<f32>>(run);
    ops_on::<Vec3<f64>>(run);
    ops_on::<Mat3<f32>>(run);
    ops_on::<Mat3<f64>>(run);
    products::<Mat3<f64>, Vec3<f64>>(run, "mat3_vec3_f64");
    products::<Mat3<f32>, Mat3<f32>>(run, "mat3_mat3_f32");
    products::<Vec3<f32>, Vec3<f32>>(run, "vec3_vec3_f32");
    products::<f64, Mat3<f64>>(run, "f64_mat3");
    let a = random::<Vec3<f32>>(OUT, 16, false);
    run.check(
        "cast_vec3_f32_mat3_f64",
        a.ex().cast::<Mat3<f32>>().cast::<Mat3<f64>>().0,
        |x| x.buf(a.as_slice()),
    );
    sparse_products::<f64, f64>(run, "csr_f64");
    sparse_products::<f32, f32>(run, "csr_f32");
    sparse_products::<Mat3<f32>, Vec3<f32>>(run, "bsr_f32");
    sparse_products::<Mat3<f64>, Vec3<f64>>(run, "bsr_f64");
}

#[test]
fn expression_kernels_match_the_cpu_loop() {
    if !emu::compiler_available() {
        return;
    }
    let mut collect = Run {
        emu: None,
        sources: Vec::new(),
        checked: 0,
    };
    all(&mut collect);
    let emu = Emu::build(&collect.sources);
    let mut run = Run {
        emu: Some(&emu),
        sources: Vec::new(),
        checked: 0,
    };
    all(&mut run);
    assert_eq!(run.checked, collect.sources.len());
    println!("{} expression kernels checked against the CPU loop", run.checked);
}
