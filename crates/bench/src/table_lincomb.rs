//! Tables B.1 (k = 2, n varies) and B.2 (n = 10^6, k = 1..10): the linear combination
//! `d = sum_i alpha_i v_i` in f32 with gpumat fused and unfused, Eigen and numpy.

use crate::lincomb::{faer_ops, fused, fused_bytes, to_faer, unfused, unfused_bytes};
use crate::peers::PeerOutput;
use crate::problems::{checksum, lincomb_inputs};
use crate::report::{col, Col, Fmt};
use crate::timing::{best_of, measure_interleaved, Policy};
use crate::{progress, ratio, thesis, Ctx};
use gpumat::Matrix;
use serde::Serialize;
use std::hint::black_box;

/// One row of B.1 or B.2.
#[derive(Clone, Debug, Serialize)]
pub struct LincombRow {
    /// `k=..,n=..`
    pub case: String,
    /// vector length
    pub n: usize,
    /// number of terms
    pub k: usize,
    /// gpumat, one fused `assign`, seconds per run
    pub gpumat_s: f64,
    /// gpumat, one pass per term (BLAS-style scal + axpy), seconds per run
    pub gpumat_unfused_s: f64,
    /// Eigen expression into a preallocated vector (single-threaded)
    pub eigen_s: Option<f64>,
    /// faer operators, `Scale(a_i) * &v_i` summed into a new column (in-process)
    pub faer_s: f64,
    /// numpy f32, `a0*v0 + a1*v1 + ...` with temporaries
    pub numpy_f32_s: Option<f64>,
    /// numpy f64 (the same numbers widened; twice the bytes), as numpy users write it
    pub numpy_f64_s: Option<f64>,
    /// bytes the fused pass moves: `4 (k + 1) n`
    pub bytes: usize,
    /// bytes the unfused passes move: `4 n (3k - 1)`
    pub unfused_bytes: usize,
    /// `bytes / gpumat_s`, GB/s
    pub gpumat_gbs: f64,
    /// `unfused_bytes / gpumat_unfused_s`, GB/s
    pub gpumat_unfused_gbs: f64,
    /// `bytes / eigen_s`, GB/s
    pub eigen_gbs: Option<f64>,
    /// the STREAM triad bandwidth this row is compared with (the better sample around its
    /// table), GB/s
    pub stream_triad_gbs: f64,
    /// `gpumat_gbs / stream_triad_gbs`
    pub fraction_of_stream: f64,
    /// `gpumat_unfused_s / gpumat_s`
    pub fused_speedup: f64,
    /// `unfused_bytes / bytes`: the speedup fusion gives when every pass streams from DRAM
    /// (less when the destination stays in cache between the unfused passes)
    pub traffic_ratio: f64,
    /// `fused_speedup / traffic_ratio`: the fraction of the fusion ceiling reached
    pub fraction_of_fusion_ceiling: f64,
    /// `eigen_s / gpumat_s` (> 1: gpumat faster)
    pub speedup_vs_eigen: Option<f64>,
    /// `numpy_f32_s / gpumat_s`
    pub speedup_vs_numpy: Option<f64>,
    /// `faer_s / gpumat_s`
    pub speedup_vs_faer: f64,
    /// fused, unfused and the peers' results agree (checksums within 1e-4 of sum |d|)
    pub results_agree: bool,
    /// thesis, cuBLAS on a GTX 1060, ms
    pub thesis_cublas_ms: Option<f64>,
    /// thesis, cuMat on a GTX 1060, ms
    pub thesis_cumat_ms: Option<f64>,
    /// thesis, Eigen on an i7-6700, ms
    pub thesis_eigen_ms: Option<f64>,
    /// thesis, numpy on an i7-6700, ms
    pub thesis_numpy_ms: Option<f64>,
}

/// Measures one case.
pub fn lincomb_row(ctx: &mut Ctx, n: usize, k: usize, th: Option<(f64, f64, f64, f64)>) -> LincombRow {
    progress(&format!("lincomb n={n} k={k}"));
    let p = ctx.policy;
    let one = Policy { rounds: 1, ..p };
    let (vs, alphas) = lincomb_inputs(n, k);
    let mut d = Matrix::<f32>::zeros(n, 1, 1);
    let mut du = Matrix::<f32>::zeros(n, 1, 1);
    let fvs = to_faer(&vs);
    let mut dfaer = faer::Col::<f32>::zeros(0);
    let case = vec![n.to_string(), k.to_string()];
    let mut mfaer = None;
    let (mut mf, mut mu, mut eigen, mut numpy, mut numpy64) = (None, None, None, None, None);
    // Rounds side by side: fused, unfused, Eigen, numpy in turn, each keeping its best.
    for _ in 0..p.rounds.max(1) {
        let m = measure_interleaved(
            &one,
            &mut [
                &mut || fused(black_box(&mut d), black_box(&vs), black_box(&alphas)),
                &mut || unfused(black_box(&mut du), black_box(&vs), black_box(&alphas)),
                &mut || dfaer = faer_ops(black_box(&fvs), black_box(&alphas)),
            ],
        );
        mf = Some(best_of(mf, m[0]));
        mu = Some(best_of(mu, m[1]));
        mfaer = Some(best_of(mfaer, m[2]));
        if let Some(r) = ctx.peers.eigen.as_ref().map(|e| e.run("lincomb", &case, &one)) {
            eigen = PeerOutput::faster(eigen, ctx.peers.take(r));
        }
        if let Some(r) = ctx.peers.numpy.as_ref().map(|np| np.lincomb(n, k, "f32", &one)) {
            numpy = PeerOutput::faster(numpy, ctx.peers.take(r));
        }
        if let Some(r) = ctx.peers.numpy.as_ref().map(|np| np.lincomb(n, k, "f64", &one)) {
            numpy64 = PeerOutput::faster(numpy64, ctx.peers.take(r));
        }
    }
    let (mf, mu, mfaer) = (
        mf.expect("one round"),
        mu.expect("one round"),
        mfaer.expect("one round"),
    );
    let fused_sum = checksum(d.as_slice());
    let scale: f64 = d
        .as_slice()
        .iter()
        .map(|&x| x.abs() as f64)
        .sum::<f64>()
        .max(1e-30);
    let agree = |s: Option<f64>| s.map_or(true, |s| (s - fused_sum).abs() <= 1e-4 * scale);
    let faer_sum = checksum(&(0..n).map(|i| dfaer[i]).collect::<Vec<f32>>());
    let mut ok = agree(Some(checksum(du.as_slice()))) && agree(Some(faer_sum));
    drop((vs, d, du, fvs, dfaer));
    for (name, out) in [("eigen", &eigen), ("numpy", &numpy), ("numpy f64", &numpy64)] {
        if let Some(o) = out {
            if !agree(o.f64("checksum")) {
                ok = false;
                ctx.peers.notes.push(format!(
                    "lincomb n={n} k={k}: {name} checksum {:?} differs from gpumat's {fused_sum}",
                    o.f64("checksum")
                ));
            }
        }
    }
    let eigen_s = eigen.and_then(|o| o.f64("time_s"));
    let numpy_s = numpy.and_then(|o| o.f64("time_s"));
    let numpy64_s = numpy64.and_then(|o| o.f64("time_s"));
    let bytes = fused_bytes(n, k);
    let ubytes = unfused_bytes(n, k);
    let gbs = bytes as f64 / mf.seconds / 1e9;
    LincombRow {
        case: format!("k={k},n={n}"),
        n,
        k,
        gpumat_s: mf.seconds,
        gpumat_unfused_s: mu.seconds,
        eigen_s,
        faer_s: mfaer.seconds,
        numpy_f32_s: numpy_s,
        numpy_f64_s: numpy64_s,
        bytes,
        unfused_bytes: ubytes,
        gpumat_gbs: gbs,
        gpumat_unfused_gbs: ubytes as f64 / mu.seconds / 1e9,
        eigen_gbs: eigen_s.map(|t| bytes as f64 / t / 1e9),
        stream_triad_gbs: ctx.stream_gbs,
        fraction_of_stream: gbs / ctx.stream_gbs,
        fused_speedup: mu.seconds / mf.seconds,
        traffic_ratio: ubytes as f64 / bytes as f64,
        fraction_of_fusion_ceiling: (mu.seconds / mf.seconds) / (ubytes as f64 / bytes as f64),
        speedup_vs_eigen: ratio(eigen_s, Some(mf.seconds)),
        speedup_vs_numpy: ratio(numpy_s, Some(mf.seconds)),
        speedup_vs_faer: mfaer.seconds / mf.seconds,
        results_agree: ok,
        thesis_cublas_ms: th.map(|t| t.0),
        thesis_cumat_ms: th.map(|t| t.1),
        thesis_eigen_ms: th.map(|t| t.2),
        thesis_numpy_ms: th.map(|t| t.3),
    }
}

impl LincombRow {
    /// Recomputes the fractions of STREAM for the bandwidth `stream_gbs`.
    pub fn set_stream(&mut self, stream_gbs: f64) {
        self.stream_triad_gbs = stream_gbs;
        self.fraction_of_stream = self.gpumat_gbs / stream_gbs;
    }
}

/// The vector lengths of B.1.
pub fn b1_sizes(quick: bool) -> Vec<usize> {
    let mut v = vec![100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000];
    if !quick {
        v.push(50_000_000);
    }
    v
}

/// Table B.1: k = 2, n from 1e2 to 5e7 (quick: 1e7).
pub fn table_b1(ctx: &mut Ctx) -> Vec<LincombRow> {
    b1_sizes(ctx.quick)
        .into_iter()
        .map(|n| lincomb_row(ctx, n, 2, thesis::b1(n)))
        .collect()
}

/// Table B.2: n = 1e6, k = 1..10.
pub fn table_b2(ctx: &mut Ctx) -> Vec<LincombRow> {
    (1..=10)
        .map(|k| lincomb_row(ctx, 1_000_000, k, thesis::b2(k)))
        .collect()
}

/// Table B.2-dram: B.2's k = 2, 5 and 10 at n = 1e7 (quick: k = 10 only), where every vector
/// streams from memory (40 MB each; at the thesis' n = 1e6 they partly stay in this machine's
/// cache between the unfused passes, so the traffic ratio is not the ceiling there).
pub fn table_b2_dram(ctx: &mut Ctx) -> Vec<LincombRow> {
    let ks: &[usize] = if ctx.quick { &[10] } else { &[2, 5, 10] };
    ks.iter()
        .map(|&k| lincomb_row(ctx, 10_000_000, k, None))
        .collect()
}

/// Markdown columns of B.1/B.2 (`first` is the varying parameter).
pub fn columns(first: Col) -> Vec<Col> {
    vec![
        first,
        col("gpumat ms", "gpumat_s", Fmt::SecondsAsMs),
        col("unfused ms", "gpumat_unfused_s", Fmt::SecondsAsMs),
        col("Eigen ms", "eigen_s", Fmt::SecondsAsMs),
        col("faer ms", "faer_s", Fmt::SecondsAsMs),
        col("numpy f32 ms", "numpy_f32_s", Fmt::SecondsAsMs),
        col("numpy f64 ms", "numpy_f64_s", Fmt::SecondsAsMs),
        col("gpumat GB/s", "gpumat_gbs", Fmt::Gbs),
        col("of STREAM", "fraction_of_stream", Fmt::Percent),
        col("fused speedup", "fused_speedup", Fmt::Ratio),
        col("traffic ratio", "traffic_ratio", Fmt::Ratio),
        col("of fusion ceiling", "fraction_of_fusion_ceiling", Fmt::Percent),
        col("vs Eigen", "speedup_vs_eigen", Fmt::Ratio),
        col("vs faer", "speedup_vs_faer", Fmt::Ratio),
        col("thesis cuBLAS ms", "thesis_cublas_ms", Fmt::Ms),
        col("thesis cuMat ms", "thesis_cumat_ms", Fmt::Ms),
        col("thesis Eigen ms", "thesis_eigen_ms", Fmt::Ms),
        col("thesis numpy ms", "thesis_numpy_ms", Fmt::Ms),
    ]
}
