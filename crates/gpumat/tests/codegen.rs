//! The op table and the CUDA kernel text generated from it: every unary entry has CUDA text
//! with the operand `{0}` (binary: `{0}` and `{1}`), names are unique, the Rust functions are
//! reachable by name; every operation's text is what appears in the kernel of an expression
//! using it; and the kernel of `a + 2b + sqrt(c)` is one store `dst[i] = ...` reading three
//! inputs `in0`, `in1`, `in2` once each (broadcast inputs indexed with 0 in their size-1
//! dimensions, transposed inputs with swapped coordinates, constants passed as parameters).

use gpumat::cuda_codegen::kernel_source;
use gpumat::expr::{Binary, Ex, Expr};
use gpumat::ops::{self, fill_cuda, BinaryOp, UnaryOp, BINARY_TABLE, UNARY_TABLE};
use gpumat::{Matrix, Shape, Vec3};
use std::collections::HashSet;

fn count(hay: &str, needle: &str) -> usize {
    hay.matches(needle).count()
}

/// The line that stores the result.
fn body(src: &str) -> &str {
    src.lines()
        .find(|l| l.trim_start().starts_with("dst[i] = "))
        .expect("kernel stores dst[i]")
}

#[test]
fn op_table_entries_are_well_formed() {
    assert!(!UNARY_TABLE.is_empty() && !BINARY_TABLE.is_empty());
    let mut names = HashSet::new();
    for (name, cuda) in UNARY_TABLE {
        assert!(!name.is_empty() && !cuda.is_empty(), "{name}");
        assert!(cuda.contains("{0}"), "{name}: {cuda}");
        assert!(!cuda.contains("{1}"), "{name}: unary text uses a second operand");
        assert!(names.insert(*name), "duplicate op name {name}");
        let filled = fill_cuda(cuda, &["x"]);
        assert!(!filled.contains('{') && filled.contains('x'), "{name}: {filled}");
        assert_eq!(
            count(&filled, "("),
            count(&filled, ")"),
            "{name}: unbalanced {filled}"
        );
        assert!(
            ops::unary_by_name(name, 0.5f64).is_some(),
            "{name} not reachable by name"
        );
    }
    for (name, cuda) in BINARY_TABLE {
        assert!(!name.is_empty() && !cuda.is_empty(), "{name}");
        assert!(cuda.contains("{0}") && cuda.contains("{1}"), "{name}: {cuda}");
        assert!(names.insert(*name), "duplicate op name {name}");
        let filled = fill_cuda(cuda, &["x", "y"]);
        assert!(
            !filled.contains('{') && filled.find('x') < filled.find('y'),
            "{name}: {filled}"
        );
    }
    assert_eq!(ops::unary_by_name("no such op", 1.0f32), None);
}

const A_LOAD: &str = "in0[(r) + 4ull * ((c) + 3ull * (b))]";

fn unary_kernel<Op: UnaryOp>(a: &Matrix<f32>) -> (&'static str, String) {
    let e = a.ex().unary::<Op>();
    (Op::NAME, kernel_source(&e.0, a.shape(), "k"))
}

fn binary_kernel<Op: BinaryOp>(a: &Matrix<f32>) -> (&'static str, String) {
    let e = Binary::<_, _, Op>::new(a.ex().0, a.ex().0);
    (Op::NAME, kernel_source(&e, a.shape(), "k"))
}

/// Each table entry's text is exactly what the kernel of an expression using it evaluates.
#[test]
fn every_op_text_reaches_the_kernel() {
    let a = Matrix::<f32>::zeros(4, 3, 2);
    let unary = [
        unary_kernel::<ops::Neg>(&a),
        unary_kernel::<ops::Sqrt>(&a),
        unary_kernel::<ops::Rsqrt>(&a),
        unary_kernel::<ops::Abs>(&a),
        unary_kernel::<ops::Exp>(&a),
        unary_kernel::<ops::Log>(&a),
        unary_kernel::<ops::Log1p>(&a),
        unary_kernel::<ops::Sin>(&a),
        unary_kernel::<ops::Cos>(&a),
        unary_kernel::<ops::Tan>(&a),
        unary_kernel::<ops::Tanh>(&a),
        unary_kernel::<ops::Square>(&a),
        unary_kernel::<ops::Cube>(&a),
        unary_kernel::<ops::Inverse>(&a),
        unary_kernel::<ops::Floor>(&a),
        unary_kernel::<ops::Ceil>(&a),
        unary_kernel::<ops::Sign>(&a),
    ];
    let names: Vec<&str> = unary.iter().map(|u| u.0).collect();
    let table: Vec<&str> = UNARY_TABLE.iter().map(|u| u.0).collect();
    assert_eq!(names, table, "every unary op is covered");
    for ((name, src), (_, cuda)) in unary.iter().zip(UNARY_TABLE) {
        assert_eq!(
            body(src).trim(),
            format!("dst[i] = {};", fill_cuda(cuda, &[A_LOAD])),
            "{name}"
        );
    }
    let binary = [
        binary_kernel::<ops::AddOp>(&a),
        binary_kernel::<ops::SubOp>(&a),
        binary_kernel::<ops::DivOp>(&a),
        binary_kernel::<ops::MinOp>(&a),
        binary_kernel::<ops::MaxOp>(&a),
        binary_kernel::<ops::PowOp>(&a),
    ];
    let names: Vec<&str> = binary.iter().map(|u| u.0).collect();
    let table: Vec<&str> = BINARY_TABLE.iter().map(|u| u.0).collect();
    assert_eq!(names, table, "every binary op is covered");
    let b_load = A_LOAD.replace("in0", "in1");
    for ((name, src), (_, cuda)) in binary.iter().zip(BINARY_TABLE) {
        let want = format!("dst[i] = {};", fill_cuda(cuda, &[A_LOAD, &b_load]));
        assert_eq!(body(src).trim(), want, "{name}");
    }
}

#[test]
fn fused_kernel_has_one_store_and_three_loads() {
    let a = Matrix::<f32>::zeros(4, 3, 2);
    let b = Matrix::<f32>::zeros(4, 3, 2);
    let c = Matrix::<f32>::zeros(4, 3, 2);
    let e = a.ex() + b.ex() * 2.0 + c.ex().sqrt();
    let src = kernel_source(&e.0, a.shape(), "fused");
    assert_eq!(count(&src, "dst[i] ="), 1, "{src}");
    assert_eq!(count(&src, "dst["), 1, "the destination is only written: {src}");
    for (k, input) in ["in0[", "in1[", "in2["].iter().enumerate() {
        assert_eq!(count(&src, input), 1, "input {k} is read once: {src}");
        assert_eq!(
            count(&src, &format!("const float* __restrict__ in{k}")),
            1,
            "{src}"
        );
    }
    assert!(!src.contains("in3"), "{src}");
    assert_eq!(count(&src, "__restrict__"), 4, "dst and three inputs: {src}");
    assert!(
        src.contains("extern \"C\" __global__ void fused(float* __restrict__ dst"),
        "{src}"
    );
    assert!(src.contains("if (i >= 24ull) return;"), "{src}");
    let line = body(&src);
    let (p0, p1, p2) = (
        line.find("in0").unwrap(),
        line.find("in1").unwrap(),
        line.find("in2").unwrap(),
    );
    assert!(p0 < p1 && p1 < p2, "operands in tree order: {line}");
    assert!(
        line.contains("(in1[(r) + 4ull * ((c) + 3ull * (b))] * 2.0f)"),
        "{line}"
    );
    assert!(
        line.contains("sqrt(in2[(r) + 4ull * ((c) + 3ull * (b))])"),
        "{line}"
    );
}

#[test]
fn kernel_indexing_follows_broadcasting_transpose_and_types() {
    // b broadcasts over columns, c over rows and batches.
    let a = Matrix::<f64>::zeros(4, 3, 2);
    let b = Matrix::<f64>::zeros(4, 1, 2);
    let c = Matrix::<f64>::zeros(1, 3, 1);
    let src = kernel_source(&(a.ex() + b.ex() - c.ex()).0, a.shape(), "k");
    let line = body(&src);
    assert!(line.contains("in1[(r) + 4ull * ((0) + 1ull * (b))]"), "{line}");
    assert!(line.contains("in2[(0) + 1ull * ((c) + 3ull * (0))]"), "{line}");
    assert!(src.contains("double* __restrict__ dst") && src.contains("const double* __restrict__ in2"));
    // Transpose swaps the coordinates of the load; a constant is a by-value parameter.
    let t = Matrix::<f32>::zeros(3, 4, 2);
    let src = kernel_source(
        &(t.ex().transpose() + gpumat::scalar(1.5f32)).0,
        Shape::new(4, 3, 2),
        "k",
    );
    let line = body(&src);
    assert!(line.contains("in0[(c) + 3ull * ((r) + 4ull * (b))]"), "{line}");
    assert!(line.contains("k0") && src.contains("const float k0"), "{src}");
    // Block elements use their CUDA type.
    let v = Matrix::<Vec3<f32>>::zeros(5, 1, 1);
    let src = kernel_source(&(v.ex() * 2.0f32).0, v.shape(), "k");
    assert!(
        src.contains("float4* __restrict__ dst") && src.contains("const float4* __restrict__ in0"),
        "{src}"
    );
    // The output shape decides the decoded coordinates.
    assert!(src.contains("r = i % 5ull"), "{src}");
}

#[test]
fn expressions_report_their_shapes() {
    let a = Matrix::<f32>::zeros(4, 1, 3);
    let b = Matrix::<f32>::zeros(1, 5, 1);
    let e: Ex<_> = a.ex() + b.ex();
    assert_eq!(e.shape(), Shape::new(4, 5, 3));
    assert_eq!(e.0.shape(), Shape::new(4, 5, 3));
    assert_eq!(a.ex().transpose().shape(), Shape::new(1, 4, 3));
    assert_eq!(a.ex().as_diagonal().shape(), Shape::new(4, 4, 3));
}
