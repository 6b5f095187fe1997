//! The CUDA sources without a compiler (runs everywhere; tests/nvrtc_compile.rs compiles them):
//! the corpus covers every op of the op table for every scalar type, element type and
//! broadcast pattern; the catalogue has its 8 sources and the kernels the solvers need; every
//! `gpumat_*` helper a source calls is defined in the headers; no source uses atomics (the
//! reductions are fixed trees); entry names are unique; f32 literals carry the `f` suffix.

use gpumat::cuda::{self, KernelSource};
use gpumat::ops::{BINARY_TABLE, UNARY_TABLE};
use std::collections::HashSet;

const TAGS: [&str; 6] = ["f32", "vec3_f32", "mat3_f32", "f64", "vec3_f64", "mat3_f64"];
const PATTERNS: [&str; 5] = ["full", "bcast_rows", "bcast_cols", "bcast_batches", "bcast_all"];

fn entries(srcs: &[KernelSource]) -> Vec<&str> {
    srcs.iter()
        .flat_map(|s| s.entries.iter().map(String::as_str))
        .collect()
}

#[test]
fn corpus_covers_every_op_type_and_broadcast() {
    let corpus = cuda::corpus();
    let names = entries(&corpus);
    let has = |needle: &str| names.iter().any(|n| n.contains(needle));
    for (op, _) in UNARY_TABLE {
        for tag in TAGS {
            for p in PATTERNS {
                let want = format!("_unary_{op}_{tag}_{p}");
                assert!(names.iter().any(|n| n.ends_with(&want)), "missing {want}");
            }
        }
    }
    for (op, _) in BINARY_TABLE {
        for tag in TAGS {
            for p in PATTERNS {
                assert!(has(&format!("_binary_{op}_{tag}_full_{p}")), "{op} {tag} {p}");
            }
            assert!(
                has(&format!("_binary_{op}_{tag}_bcast_cols_bcast_rows")),
                "{op} {tag}"
            );
        }
    }
    for tag in TAGS {
        for node in [
            "scale",
            "neg",
            "dot",
            "squared_norm",
            "transpose",
            "as_diagonal",
            "identity",
            "constant",
            "compound_add",
        ] {
            assert!(has(&format!("_{node}_{tag}")), "{node} {tag}");
        }
    }
    for real in ["f32", "f64"] {
        for sp in ["spmv", "spmv_transposed", "spmv_fused", "spmv_nested"] {
            assert!(has(&format!("_{sp}_{real}_{real}")), "{sp} csr {real}");
            assert!(has(&format!("_{sp}_mat3_{real}_vec3_{real}")), "{sp} bsr {real}");
        }
        for (a, b) in [
            ("", ""),
            ("vec3_", "vec3_"),
            ("mat3_", "vec3_"),
            ("mat3_", "mat3_"),
            ("", "vec3_"),
            ("", "mat3_"),
        ] {
            assert!(has(&format!("_mul_{a}{real}_{b}{real}_")), "mul {a}{b}{real}");
        }
    }
    let unique: HashSet<&str> = names.iter().copied().collect();
    assert_eq!(unique.len(), names.len(), "corpus entry names are unique");
    // block ops go through gpumat_map / gpumat_zip; f32 literals are f32
    let src = |needle: &str| {
        &corpus
            .iter()
            .find(|k| k.entries[0].contains(needle))
            .unwrap()
            .source
    };
    assert!(src("_unary_sqrt_vec3_f32_full").contains("gpumat_map([](auto gm_x) { return sqrt(gm_x); }"));
    assert!(src("_binary_min_mat3_f64_full_full").contains("gpumat_zip("));
    assert!(src("_scale_f32_full").contains("* 0.5f)"));
    assert!(src("_scale_f64_full").contains("* 0.5)"));
    assert!(src("_scale_inf_f32").contains("__int_as_float((int)0x7f800000u)"));
    assert!(src("_spmv_mat3_f32_vec3_f32_values2_x2").contains("for (gpumat_index"));
}

#[test]
fn catalogue_has_the_solver_kernels() {
    let cat = cuda::catalogue();
    let files: Vec<&str> = cat.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        files,
        [
            "reduce_f32.cu",
            "cg_f32.cu",
            "spmv_f32.cu",
            "precond_f32.cu",
            "reduce_f64.cu",
            "cg_f64.cu",
            "spmv_f64.cu",
            "precond_f64.cu"
        ]
    );
    let names = entries(&cat);
    let unique: HashSet<&str> = names.iter().copied().collect();
    assert_eq!(unique.len(), names.len(), "catalogue entry names are unique");
    for s in ["f32", "f64"] {
        for k in [
            "reduce_sum_partial_",
            "reduce_sum_finish_",
            "reduce_sum_partial_vec3_",
            "reduce_min_partial_",
            "reduce_max_finish_",
            "reduce_squared_norm_partial_vec3_",
            "reduce_max_abs_partial_",
            "cg_dot_partial_vec3_",
            "cg_dot2_partial_",
            "reduce_sum_finish_pair_",
            "cg_alpha_",
            "cg_beta_",
            "cg_update_xr_vec3_",
            "cg_update_p_",
            "cg_residual_vec3_",
            "axpy_",
            "csr_spmv_",
            "bsr3_spmv_",
            "csr_spmv_transposed_",
            "bsr3_spmv_transposed_",
            "newmark_a_bsr3_",
            "newmark_b_bsr3_",
            "newmark_b_csr_",
            "jacobi_setup_csr_",
            "jacobi_setup_bsr3_",
            "jacobi_apply_vec3_",
            "block_jacobi_setup_",
            "block_jacobi_apply_",
        ] {
            let want = format!("gpumat_{k}{s}");
            assert!(unique.contains(want.as_str()), "missing {want}");
        }
    }
    for src in &cat {
        for e in &src.entries {
            assert!(
                src.source.contains(&format!("extern \"C\" __global__ void {e}(")),
                "{e}"
            );
        }
    }
    assert!(names.len() >= 80, "{}", names.len());
    // the reductions' tree assumes the launch geometry's block size
    let gpumat_cuh = cuda::headers()[0].1;
    let block = format!("#define GPUMAT_BLOCK {}", gpumat::cuda::launch::BLOCK);
    assert!(
        gpumat_cuh.contains(&block),
        "GPUMAT_BLOCK differs from launch::BLOCK"
    );
}

/// A call of a CUDA atomic (`atomicAdd`, `atomicCAS`, ...); comments may say "atomics".
fn uses_atomics(src: &str) -> bool {
    src.match_indices("atomic")
        .any(|(i, _)| src[i + 6..].starts_with(|c: char| c.is_ascii_uppercase()))
}

/// Every `gpumat_*` function or type a generated source uses is defined in the headers, and
/// nothing uses atomics (deterministic reductions).
#[test]
fn sources_only_call_defined_helpers_and_no_atomics() {
    let headers: String = cuda::headers().iter().map(|h| h.1).collect();
    let mut all = cuda::catalogue();
    all.extend(cuda::corpus());
    let entry_names: HashSet<String> = all.iter().flat_map(|s| s.entries.clone()).collect();
    let mut used = HashSet::new();
    for s in &all {
        assert!(!uses_atomics(&s.source), "{} uses atomics", s.name);
        let b = s.source.as_bytes();
        let mut i = 0;
        while let Some(p) = s.source[i..].find("gpumat_") {
            let start = i + p;
            let mut end = start;
            while end < b.len() && (b[end].is_ascii_alphanumeric() || b[end] == b'_') {
                end += 1;
            }
            let id = &s.source[start..end];
            let inside_word = start > 0 && b[start - 1].is_ascii_alphanumeric();
            if !(entry_names.contains(id) || inside_word) {
                used.insert(id.to_string());
            }
            i = end;
        }
    }
    for id in &used {
        assert!(
            headers.contains(id.as_str()),
            "{id} is used but not defined in kernels/"
        );
    }
    assert!(!uses_atomics(&headers), "headers use atomics");
    for id in [
        "gpumat_map",
        "gpumat_zip",
        "gpumat_reduce_partial",
        "gpumat_spmv_row",
        "gpumat_csr_get",
    ] {
        assert!(used.contains(id), "{id} is never used: the scan is broken");
    }
}
