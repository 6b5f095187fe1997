//! Generates the catalogue of CUDA kernels gpumat always needs into `OUT_DIR` (read by
//! `gpumat::cuda::catalogue()`): reductions, CG vector updates and fused dots, CSR and 3x3 BSR
//! SpMV (and their transposes), the Newmark A/b expressions and the Jacobi / block-Jacobi
//! preconditioners, for f32 and f64. Four sources per real type: reduce, cg, spmv, precond.
//!
//! The device building blocks come from `kernels/*.cuh`; every element-wise combination in the
//! entry points (`+`, `-`, `/`, `min`, `max`, `abs`, `1/x`) is the op table's text
//! (`src/op_table.rs`, through the same rules as the expression codegen, `src/cuda_text.rs`).
//! Needs no nvcc, no GPU and no network: it only writes text.

use std::fmt::Write as _;
use std::path::PathBuf;

include!("src/op_table.rs");
#[path = "src/cuda_text.rs"]
#[allow(dead_code)]
mod cuda_text;
use cuda_text::{binary_text, unary_text};

macro_rules! collect_ops {
    ($($(#[$doc:meta])* $ty:ident, $name:literal, $cuda:literal, |$($x:ident),*| $body:expr;)*) => {
        &[$(($name, $cuda)),*]
    };
}
const UNARY: &[(&str, &str)] = for_each_unary_op!(collect_ops);
const BINARY: &[(&str, &str)] = for_each_binary_op!(collect_ops);

fn op(name: &str) -> &'static str {
    UNARY
        .iter()
        .chain(BINARY)
        .find(|(n, _)| *n == name)
        .map(|(_, t)| *t)
        .unwrap_or_else(|| panic!("build.rs: op {name} is not in the op table"))
}
/// The op table's binary entry `name` on elements with `lanes` lanes.
fn bin(name: &str, lanes: usize, a: &str, b: &str) -> String {
    binary_text(lanes, op(name), a, b)
}
/// The op table's unary entry `name` on elements with `lanes` lanes.
fn un(name: &str, lanes: usize, a: &str) -> String {
    unary_text(lanes, op(name), a)
}

/// One real type: suffix, real, vector (Vec3) and block (Mat3) CUDA types, +infinity.
struct Ty {
    s: &'static str,
    t: &'static str,
    v: &'static str,
    m: &'static str,
    inf: &'static str,
}
const TYPES: [Ty; 2] = [
    Ty {
        s: "f32",
        t: "float",
        v: "float4",
        m: "gpumat_mat3f",
        inf: "__int_as_float(0x7f800000)",
    },
    Ty {
        s: "f64",
        t: "double",
        v: "double4",
        m: "gpumat_mat3d",
        inf: "__longlong_as_double(0x7ff0000000000000ull)",
    },
];

/// Generates one source of a real type.
type Stage = fn(&Ty) -> Source;

#[derive(Default)]
struct Source {
    text: String,
    entries: Vec<String>,
}
impl Source {
    fn kernel(&mut self, name: String, params: &str, body: &str) {
        let _ = write!(
            self.text,
            "extern \"C\" __global__ void {name}({params}) {{\n{body}\n}}\n\n"
        );
        self.entries.push(name);
    }
}

/// The element variants of vectors: (name infix, CUDA type, lanes).
fn elems(ty: &Ty) -> [(&'static str, &'static str, usize); 2] {
    [("", ty.t, 1), ("vec3_", ty.v, 3)]
}

/// The per-element prologue: `i` over n x batches, `b` its batch; `guard` returns early.
const ELEMENT: &str =
    "  const gpumat_index i = gpumat_thread_index();\n  if (i >= n * batches) return;\n  const gpumat_index b = i / n;\n  (void)b;\n";

fn reduce(ty: &Ty) -> Source {
    let (t, s) = (ty.t, ty.s);
    let mut src = Source::default();
    let add_t = format!(
        "[](const {t} a, const {t} c) {{ return {}; }}",
        bin("add", 1, "a", "c")
    );
    for (e, et, lanes) in elems(ty) {
        let add = format!(
            "[](const {et} a, const {et} c) {{ return {}; }}",
            bin("add", lanes, "a", "c")
        );
        src.kernel(
            format!("gpumat_reduce_sum_partial_{e}{s}"),
            &format!("const {et}* __restrict__ x, gpumat_index n, {et}* __restrict__ partials"),
            &format!("  gpumat_reduce_partial<{et}>([&](gpumat_index i, gpumat_index b) {{ return x[i + n * b]; }}, n, gpumat_zero<{et}>(), {add}, partials);"),
        );
        src.kernel(
            format!("gpumat_reduce_sum_finish_{e}{s}"),
            &format!("const {et}* __restrict__ partials, gpumat_index parts, {et}* __restrict__ out"),
            &format!("  gpumat_reduce_finish<{et}>(partials, parts, gpumat_zero<{et}>(), {add}, out);"),
        );
        src.kernel(
            format!("gpumat_reduce_squared_norm_partial_{e}{s}"),
            &format!("const {et}* __restrict__ x, gpumat_index n, {t}* __restrict__ partials"),
            &format!("  gpumat_reduce_partial<{t}>([&](gpumat_index i, gpumat_index b) {{ return gpumat_squared_norm(x[i + n * b]); }}, n, {t}(0), {add_t}, partials);"),
        );
        let abs = |a: &str| un("abs", 1, a);
        let max_abs = if lanes == 1 {
            abs("v")
        } else {
            let xy = bin("max", 1, &abs("v.x"), &abs("v.y"));
            bin("max", 1, &xy, &abs("v.z"))
        };
        src.kernel(
            format!("gpumat_reduce_max_abs_partial_{e}{s}"),
            &format!("const {et}* __restrict__ x, gpumat_index n, {t}* __restrict__ partials"),
            &format!("  gpumat_reduce_partial<{t}>([&](gpumat_index i, gpumat_index b) {{ const {et} v = x[i + n * b]; return {max_abs}; }}, n, {t}(0), [](const {t} a, const {t} c) {{ return {}; }}, partials);", bin("max", 1, "a", "c")),
        );
    }
    for (name, identity) in [("min", ty.inf.to_string()), ("max", format!("-{}", ty.inf))] {
        let f = format!(
            "[](const {t} a, const {t} c) {{ return {}; }}",
            bin(name, 1, "a", "c")
        );
        src.kernel(
            format!("gpumat_reduce_{name}_partial_{s}"),
            &format!("const {t}* __restrict__ x, gpumat_index n, {t}* __restrict__ partials"),
            &format!("  gpumat_reduce_partial<{t}>([&](gpumat_index i, gpumat_index b) {{ return x[i + n * b]; }}, n, {identity}, {f}, partials);"),
        );
        src.kernel(
            format!("gpumat_reduce_{name}_finish_{s}"),
            &format!("const {t}* __restrict__ partials, gpumat_index parts, {t}* __restrict__ out"),
            &format!("  gpumat_reduce_finish<{t}>(partials, parts, {identity}, {f}, out);"),
        );
    }
    src
}

fn cg(ty: &Ty) -> Source {
    let (t, s) = (ty.t, ty.s);
    let mut src = Source::default();
    let add_t = format!(
        "[](const {t} a, const {t} c) {{ return {}; }}",
        bin("add", 1, "a", "c")
    );
    let pair = format!("gpumat_pair<{t}>");
    let add_pair = format!(
        "[](const {pair} p, const {pair} q) {{ {pair} o; o.a = {}; o.b = {}; return o; }}",
        bin("add", 1, "p.a", "q.a"),
        bin("add", 1, "p.b", "q.b")
    );
    for (e, et, lanes) in elems(ty) {
        let vec = |name: &str| format!("{et}* __restrict__ {name}");
        let cvec = |name: &str| format!("const {et}* __restrict__ {name}");
        src.kernel(
            format!("gpumat_cg_dot_partial_{e}{s}"),
            &format!("{}, {}, gpumat_index n, {t}* __restrict__ partials", cvec("x"), cvec("y")),
            &format!("  gpumat_reduce_partial<{t}>([&](gpumat_index i, gpumat_index b) {{ return gpumat_dot(x[i + n * b], y[i + n * b]); }}, n, {t}(0), {add_t}, partials);"),
        );
        // (r . z, r . r) in one pass: the two dots CG needs per iteration
        src.kernel(
            format!("gpumat_cg_dot2_partial_{e}{s}"),
            &format!("{}, {}, gpumat_index n, {pair}* __restrict__ partials", cvec("r"), cvec("z")),
            &format!("  gpumat_reduce_partial<{pair}>([&](gpumat_index i, gpumat_index b) {{ {pair} o; o.a = gpumat_dot(r[i + n * b], z[i + n * b]); o.b = gpumat_dot(r[i + n * b], r[i + n * b]); return o; }}, n, gpumat_pair_zero<{t}>(), {add_pair}, partials);"),
        );
        let masked = format!("{ELEMENT}  if (!active[b]) return;\n");
        src.kernel(
            format!("gpumat_cg_update_xr_{e}{s}"),
            &format!("{}, {}, {}, {}, const {t}* __restrict__ alpha, const unsigned int* __restrict__ active, gpumat_index n, gpumat_index batches", vec("x"), vec("r"), cvec("p"), cvec("ap")),
            &format!("{masked}  const {t} a = alpha[b];\n  x[i] = {};\n  r[i] = {};", bin("add", lanes, "x[i]", "(p[i] * a)"), bin("sub", lanes, "r[i]", "(ap[i] * a)")),
        );
        src.kernel(
            format!("gpumat_cg_update_p_{e}{s}"),
            &format!("{}, {}, const {t}* __restrict__ beta, const unsigned int* __restrict__ active, gpumat_index n, gpumat_index batches", vec("p"), cvec("z")),
            &format!("{masked}  p[i] = {};", bin("add", lanes, "z[i]", "(p[i] * beta[b])")),
        );
        src.kernel(
            format!("gpumat_axpy_{e}{s}"),
            &format!(
                "{}, {}, const {t}* __restrict__ alpha, gpumat_index n, gpumat_index batches",
                vec("y"),
                cvec("x")
            ),
            &format!(
                "{ELEMENT}  y[i] = {};",
                bin("add", lanes, "y[i]", "(x[i] * alpha[b])")
            ),
        );
        src.kernel(
            format!("gpumat_cg_residual_{e}{s}"),
            &format!(
                "{}, {}, {}, gpumat_index n, gpumat_index batches",
                vec("r"),
                cvec("rhs"),
                cvec("ax")
            ),
            &format!("{ELEMENT}  r[i] = {};", bin("sub", lanes, "rhs[i]", "ax[i]")),
        );
    }
    src.kernel(
        format!("gpumat_reduce_sum_finish_pair_{s}"),
        &format!("const {pair}* __restrict__ partials, gpumat_index parts, {pair}* __restrict__ out"),
        &format!(
            "  gpumat_reduce_finish<{pair}>(partials, parts, gpumat_pair_zero<{t}>(), {add_pair}, out);"
        ),
    );
    // per-batch scalars: alpha = (r.z) / (p.Ap); beta = (r.z)_new / (r.z)_old, with the batch's
    // convergence test |r|^2 <= tol2 (each batch stops on its own)
    src.kernel(
        format!("gpumat_cg_alpha_{s}"),
        &format!("const {pair}* __restrict__ rz_rr, const {t}* __restrict__ pap, const unsigned int* __restrict__ active, {t}* __restrict__ alpha, gpumat_index batches"),
        &format!("  const gpumat_index b = gpumat_thread_index();\n  if (b >= batches) return;\n  alpha[b] = (active[b] && pap[b] != {t}(0)) ? {} : {t}(0);", bin("div", 1, "rz_rr[b].a", "pap[b]")),
    );
    src.kernel(
        format!("gpumat_cg_beta_{s}"),
        &format!("const {pair}* __restrict__ rz_rr, {t}* __restrict__ rz_old, const {t}* __restrict__ tol2, unsigned int* __restrict__ active, unsigned int* __restrict__ iterations, {t}* __restrict__ beta, gpumat_index batches"),
        &format!("  const gpumat_index b = gpumat_thread_index();\n  if (b >= batches) return;\n  if (!active[b]) {{ beta[b] = {t}(0); return; }}\n  iterations[b] += 1;\n  const {t} rz = rz_rr[b].a;\n  if (rz_rr[b].b <= tol2[b] || !isfinite(rz)) {{ active[b] = 0; beta[b] = {t}(0); }}\n  else beta[b] = {};\n  rz_old[b] = rz;", bin("div", 1, "rz", "rz_old[b]")),
    );
    src
}

fn spmv(ty: &Ty) -> Source {
    let (t, s) = (ty.t, ty.s);
    let mut src = Source::default();
    let csr = "const gpumat_index* __restrict__ row_ptr, const unsigned int* __restrict__ col_idx";
    let csc = "const gpumat_index* __restrict__ col_ptr, const gpumat_index* __restrict__ row_idx, const gpumat_index* __restrict__ entry";
    for (e, mt, vt, lanes) in [("csr", t, t, 1), ("bsr3", ty.m, ty.v, 9)] {
        src.kernel(
            format!("gpumat_{e}_spmv_{s}"),
            &format!("{csr}, const {mt}* __restrict__ vals, gpumat_index vals_stride, const {vt}* __restrict__ x, {vt}* __restrict__ y, gpumat_index rows, gpumat_index cols, gpumat_index batches"),
            "  const gpumat_index i = gpumat_thread_index();\n  if (i >= rows * batches) return;\n  const gpumat_index r = i % rows, b = i / rows;\n  y[i] = gpumat_spmv_row(row_ptr, col_idx, vals + vals_stride * b, x + cols * b, r);",
        );
        src.kernel(
            format!("gpumat_{e}_spmv_transposed_{s}"),
            &format!("{csc}, const {mt}* __restrict__ vals, gpumat_index vals_stride, const {vt}* __restrict__ x, {vt}* __restrict__ y, gpumat_index rows, gpumat_index cols, gpumat_index batches"),
            "  const gpumat_index i = gpumat_thread_index();\n  if (i >= cols * batches) return;\n  const gpumat_index c = i % cols, b = i / cols;\n  y[i] = gpumat_spmv_col(col_ptr, row_idx, entry, vals + vals_stride * b, x + rows * b, c);",
        );
        // Newmark-1 (theta scheme): A = cm M + ck K on the shared pattern's values, and
        // b = (cm M + cb K) u + cv M v + dt f with cm = 1/(theta dt) + a1,
        // cb = a2 - (1 - theta) dt, cv = 1/theta (architecture.md, thesis eq. 4.3)
        let a_val = bin("add", lanes, "(m[i] * cm)", "(k[i] * ck)");
        src.kernel(
            format!("gpumat_newmark_a_{e}_{s}"),
            &format!("const {mt}* __restrict__ m, const {mt}* __restrict__ k, {mt}* __restrict__ a, {t} cm, {t} ck, gpumat_index len"),
            &format!("  const gpumat_index i = gpumat_thread_index();\n  if (i >= len) return;\n  a[i] = {a_val};"),
        );
        let vlanes = if lanes == 1 { 1 } else { 3 };
        let term = bin(
            "add",
            vlanes,
            "(((mv[j] * cm) + (kv[j] * cb)) * u[col])",
            "((mv[j] * cv) * v[col])",
        );
        src.kernel(
            format!("gpumat_newmark_b_{e}_{s}"),
            &format!("{csr}, const {mt}* __restrict__ mvals, const {mt}* __restrict__ kvals, gpumat_index vals_stride, const {vt}* __restrict__ u_all, const {vt}* __restrict__ v_all, const {vt}* __restrict__ f, {vt}* __restrict__ out, {t} cm, {t} cb, {t} cv, {t} dt, gpumat_index rows, gpumat_index batches"),
            &format!("  const gpumat_index i = gpumat_thread_index();\n  if (i >= rows * batches) return;\n  const gpumat_index r = i % rows, b = i / rows;\n  const {mt}* mv = mvals + vals_stride * b;\n  const {mt}* kv = kvals + vals_stride * b;\n  const {vt}* u = u_all + rows * b;\n  const {vt}* v = v_all + rows * b;\n  {vt} acc = gpumat_zero<{vt}>();\n  for (gpumat_index j = row_ptr[r]; j < row_ptr[r + 1]; ++j) {{\n    const gpumat_index col = col_idx[j];\n    acc = {};\n  }}\n  out[i] = {};", bin("add", vlanes, "acc", &term), bin("add", vlanes, "acc", "(f[i] * dt)")),
        );
    }
    src
}

fn precond(ty: &Ty) -> Source {
    let (t, s, v, m) = (ty.t, ty.s, ty.v, ty.m);
    let mut src = Source::default();
    let setup = "const gpumat_index* __restrict__ diag, gpumat_index vals_stride, unsigned int* __restrict__ bad, gpumat_index rows, gpumat_index batches";
    let head = "  const gpumat_index i = gpumat_thread_index();\n  if (i >= rows * batches) return;\n  const gpumat_index r = i % rows, b = i / rows;\n";
    let lane_ok = |x: &str| format!("({x} != {t}(0) && isfinite({x}))");
    // Jacobi: inv = 1/diag lane by lane (the op table's `inverse`); `bad` flags a zero or
    // non-finite lane, as the CPU's Error::SingularDiagonal
    src.kernel(
        format!("gpumat_jacobi_setup_csr_{s}"),
        &format!("const {t}* __restrict__ vals, {t}* __restrict__ inv, {setup}"),
        &format!(
            "{head}  const {t} d = vals[vals_stride * b + diag[r]];\n  bad[i] = !{};\n  inv[i] = {};",
            lane_ok("d"),
            un("inverse", 1, "d")
        ),
    );
    src.kernel(
        format!("gpumat_jacobi_setup_bsr3_{s}"),
        &format!("const {m}* __restrict__ vals, {v}* __restrict__ inv, {setup}"),
        &format!("{head}  const {v} d = gpumat_block_diagonal(vals[vals_stride * b + diag[r]]);\n  bad[i] = !({} && {} && {});\n  inv[i] = {};", lane_ok("d.x"), lane_ok("d.y"), lane_ok("d.z"), un("inverse", 3, "d")),
    );
    for (e, et, _) in elems(ty) {
        src.kernel(
            format!("gpumat_jacobi_apply_{e}{s}"),
            &format!("const {et}* __restrict__ inv, const {et}* __restrict__ r, {et}* __restrict__ z, gpumat_index len"),
            "  const gpumat_index i = gpumat_thread_index();\n  if (i >= len) return;\n  z[i] = inv[i] * r[i];",
        );
    }
    src.kernel(
        format!("gpumat_block_jacobi_setup_{s}"),
        &format!("const {m}* __restrict__ vals, {m}* __restrict__ inv, {setup}"),
        &format!("{head}  bool ok;\n  inv[i] = gpumat_inverse3(vals[vals_stride * b + diag[r]], &ok);\n  bad[i] = !ok;"),
    );
    src.kernel(
        format!("gpumat_block_jacobi_apply_{s}"),
        &format!(
            "const {m}* __restrict__ inv, const {v}* __restrict__ r, {v}* __restrict__ z, gpumat_index len"
        ),
        "  const gpumat_index i = gpumat_thread_index();\n  if (i >= len) return;\n  z[i] = inv[i] * r[i];",
    );
    src
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=src/op_table.rs");
    println!("cargo:rerun-if-changed=src/cuda_text.rs");
    println!("cargo:rerun-if-changed=kernels");
    let mut out = String::from(
        "/// The build-time kernel catalogue: (source name, CUDA source, entry points).\n\
         pub const CATALOGUE: &[(&str, &str, &[&str])] = &[\n",
    );
    for ty in &TYPES {
        let stages: [(&str, Stage); 4] = [
            ("reduce", reduce),
            ("cg", cg),
            ("spmv", spmv),
            ("precond", precond),
        ];
        for (stage, f) in stages {
            let src = f(ty);
            let text = format!(
                "// generated by gpumat's build.rs: {stage} kernels, {}\n#include \"solver.cuh\"\n\n{}",
                ty.s, src.text
            );
            let _ = writeln!(
                out,
                "    ({:?}, {:?}, &{:?}),",
                format!("{stage}_{}.cu", ty.s),
                text,
                src.entries
            );
        }
    }
    out.push_str("];\n");
    let dir = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    std::fs::write(dir.join("kernel_catalogue.rs"), out).expect("write OUT_DIR/kernel_catalogue.rs");
}
