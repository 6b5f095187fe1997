//! The compile check: every CUDA kernel gpumat can emit (the build-time catalogue and the
//! generated expression corpus) compiles with NVRTC to compute_80 PTX and to sm_90 CUBIN, and
//! every entry point shows up in ptxas' report. Prints the kernel counts, the compile time and
//! the register / spill ranges `ptxas -v` reports for the CUBINs.
//!
//! NVRTC comes from `GPUMAT_NVRTC_DIR` (the folder `crates/gpumat/tools/nvrtc.sh` prints; the
//! library is loaded from there by path) or from `LD_LIBRARY_PATH`. Without it the test skips
//! and says so, except with `CI=true`, where a missing NVRTC fails it (`.ci/run` installs it).
//! No GPU is needed.

use gpumat::cuda::nvrtc::{self, Resources, Target};
use gpumat::cuda::{self, KernelSource};
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

/// Corpus kernels per NVRTC program (one program parses the headers once).
const BATCH: usize = 96;

fn nvrtc_or_skip() -> Option<(i32, i32)> {
    let dir = std::env::var_os("GPUMAT_NVRTC_DIR").map(PathBuf::from);
    let ci = std::env::var("CI").is_ok_and(|v| v == "true");
    match nvrtc::load(dir.as_deref()) {
        Ok(v) => Some(v),
        Err(e) if ci => panic!("CI=true and NVRTC is missing: {e}"),
        Err(e) => {
            eprintln!(
                "SKIPPED nvrtc_compile: {e} (run crates/gpumat/tools/nvrtc.sh and set GPUMAT_NVRTC_DIR)"
            );
            None
        }
    }
}

/// Compiles `srcs` for both targets in parallel; returns the CUBIN resources and the errors.
fn compile_all(srcs: &[KernelSource]) -> (Vec<Resources>, Vec<String>) {
    let jobs: Vec<(&KernelSource, Target)> = srcs
        .iter()
        .flat_map(|s| [(s, Target::Ptx(80)), (s, Target::Cubin(90))])
        .collect();
    let results: Vec<Result<Vec<Resources>, String>> = jobs
        .par_iter()
        .map(|(s, t)| {
            let c = nvrtc::compile(s, *t, &[]).map_err(|e| e.to_string())?;
            if c.image.is_empty() {
                return Err(format!("{}: empty image for {t:?}", s.name));
            }
            Ok(nvrtc::resources(&c.log))
        })
        .collect();
    let mut res = Vec::new();
    let mut errs = Vec::new();
    for r in results {
        match r {
            Ok(r) => res.extend(r),
            Err(e) => errs.push(e),
        }
    }
    (res, errs)
}

fn summary(what: &str, entries: usize, res: &[Resources]) {
    let regs = res.iter().map(|r| r.registers);
    let (lo, hi) = (regs.clone().min().unwrap_or(0), regs.max().unwrap_or(0));
    let spilling: Vec<&Resources> = res
        .iter()
        .filter(|r| r.spill_stores > 0 || r.spill_loads > 0)
        .collect();
    let stack = res.iter().map(|r| r.stack).max().unwrap_or(0);
    let smem = res.iter().map(|r| r.shared).max().unwrap_or(0);
    println!(
        "{what}: {entries} kernels, sm_90 registers {lo}..{hi} per thread, max stack {stack} B, \
         max static smem {smem} B, {} kernels spill",
        spilling.len()
    );
    for r in spilling {
        println!(
            "  spill: {} stores {} B, loads {} B",
            r.kernel, r.spill_stores, r.spill_loads
        );
    }
    let mut top: Vec<&Resources> = res.iter().collect();
    top.sort_by_key(|r| std::cmp::Reverse(r.registers));
    for r in top.iter().take(3) {
        println!("  most registers: {} ({})", r.kernel, r.registers);
    }
}

#[test]
fn every_kernel_compiles_with_nvrtc() {
    let Some((major, minor)) = nvrtc_or_skip() else {
        return;
    };
    let catalogue = cuda::catalogue();
    let corpus = cuda::corpus();
    let batches: Vec<KernelSource> = corpus
        .chunks(BATCH)
        .enumerate()
        .map(|(i, c)| cuda::join(&format!("corpus_{i}.cu"), c))
        .collect();
    let n_cat: usize = catalogue.iter().map(|s| s.entries.len()).sum();
    let n_corpus: usize = batches.iter().map(|s| s.entries.len()).sum();
    let t0 = Instant::now();
    let (cat_res, cat_err) = compile_all(&catalogue);
    let t_cat = t0.elapsed();
    let (cor_res, cor_err) = compile_all(&batches);
    let t_all = t0.elapsed();
    println!(
        "NVRTC {major}.{minor}, {} threads: catalogue {} sources / {n_cat} kernels in {:.1} s, \
         corpus {} kernels in {} programs in {:.1} s (compute_80 PTX + sm_90 CUBIN each)",
        rayon::current_num_threads(),
        catalogue.len(),
        t_cat.as_secs_f64(),
        n_corpus,
        batches.len(),
        (t_all - t_cat).as_secs_f64()
    );
    let errors: Vec<String> = cat_err.into_iter().chain(cor_err).collect();
    assert!(
        errors.is_empty(),
        "{} compile failures, first: {:?}",
        errors.len(),
        &errors[..errors.len().min(5)]
    );
    summary("catalogue", n_cat, &cat_res);
    summary("corpus", n_corpus, &cor_res);
    // every entry point was compiled to sm_90 machine code
    for (srcs, res) in [(&catalogue, &cat_res), (&batches, &cor_res)] {
        let compiled: std::collections::HashSet<&str> = res.iter().map(|r| r.kernel.as_str()).collect();
        for e in srcs.iter().flat_map(|s| &s.entries) {
            assert!(compiled.contains(e.as_str()), "{e} is not in ptxas' report");
        }
        assert_eq!(res.len(), srcs.iter().map(|s| s.entries.len()).sum::<usize>());
    }
    assert!(n_cat >= 80 && n_corpus >= 1000, "{n_cat} / {n_corpus}");
}

#[test]
fn a_broken_source_is_one_clear_error() {
    if nvrtc_or_skip().is_none() {
        return;
    }
    let bad = KernelSource {
        name: "broken.cu".into(),
        source:
            "#include \"gpumat.cuh\"\nextern \"C\" __global__ void k(float* x) { x[0] = no_such_fn(1.0f); }\n"
                .into(),
        entries: vec!["k".into()],
    };
    let e = nvrtc::compile(&bad, Target::Ptx(80), &[]).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, gpumat::Error::Compile(_)), "{msg}");
    assert!(
        msg.contains("broken.cu") && msg.contains("no_such_fn") && !msg.contains('\n'),
        "{msg}"
    );
}

#[test]
fn kernels_are_compiled_once_and_cached_by_content() {
    if nvrtc_or_skip().is_none() {
        return;
    }
    use gpumat::cuda::cache::KernelCache;
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("kcache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let src = &cuda::corpus()[0];
    let cache = KernelCache::new(Some(dir.clone()));
    let a = cache.get_or_compile(src, Target::Cubin(90)).unwrap();
    let b = cache.get_or_compile(src, Target::Cubin(90)).unwrap();
    assert!(
        std::sync::Arc::ptr_eq(&a, &b),
        "the second request comes from memory"
    );
    assert_eq!(cache.compiles(), 1);
    cache.get_or_compile(src, Target::Ptx(80)).unwrap();
    assert_eq!(cache.compiles(), 2, "the target is part of the key");
    // a new cache on the same folder reads the images from disk
    let again = KernelCache::new(Some(dir.clone()));
    let c = again.get_or_compile(src, Target::Cubin(90)).unwrap();
    assert_eq!((again.compiles(), again.disk_hits()), (0, 1));
    assert_eq!(c.image, a.image);
    // a different source has a different key
    let other = &cuda::corpus()[1];
    assert_ne!(
        KernelCache::key(src, Target::Cubin(90)),
        KernelCache::key(other, Target::Cubin(90))
    );
    let _ = std::fs::remove_dir_all(&dir);
}
