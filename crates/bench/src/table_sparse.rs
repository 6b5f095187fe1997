//! Tables B.3 (CSR SpMV on the 2D Poisson matrix) and B.4 (Jacobi-preconditioned CG on 2D
//! diffusion), f32, gpumat, Eigen and scipy (`crates/bench/python/sparse2d.py`).

use crate::peers::PeerOutput;
use crate::problems::{boundary_rhs, checksum, poisson_matrix, random_vector, SPMV_X_SEED};
use crate::report::{col, Col, Fmt};
use crate::timing::{best_of, measure, Policy};
use crate::{progress, ratio, thesis, Ctx};
use gpumat::{cg, CgError, CgParams, Jacobi, Matrix, SparseMatrix};
use serde::Serialize;
use std::hint::black_box;

/// CG relative tolerance (cuMat's benchmark code: `setTolerance(1e-4)`).
pub const CG_TOLERANCE: f32 = 1e-4;

/// `y = A x` by faer, as a faer user writes it: `sparse_dense_matmul` (with `one` = 1) on all
/// rayon threads.
pub fn faer_spmv<T: faer::traits::ComplexField>(
    y: faer::MatMut<'_, T>,
    a: faer::sparse::SparseRowMatRef<'_, usize, T>,
    x: faer::MatRef<'_, T>,
    one: T,
) {
    faer::sparse::linalg::matmul::sparse_dense_matmul(
        y,
        faer::Accum::Replace,
        a,
        x,
        one,
        faer::Par::rayon(0),
    );
}

/// Bytes one f32 CSR SpMV moves: values (4), column indices and row pointers (`index` bytes
/// each), x read once and y written once (4 each). Eigen's are `spmv_bytes(n, nnz, 4)`.
pub fn spmv_bytes(n: usize, nnz: usize, index: usize) -> usize {
    nnz * (4 + index) + (n + 1) * index + 8 * n
}

/// Bytes gpumat's SpMV with `a` moves: its values, column indices and row pointers as stored
/// (whatever their index widths), x read once and y written once.
pub fn gpumat_spmv_bytes(a: &SparseMatrix<f32>) -> usize {
    let p = a.pattern();
    std::mem::size_of_val(a.values())
        + std::mem::size_of_val(p.col_idx())
        + std::mem::size_of_val(p.row_ptr())
        + 8 * a.rows()
}

/// One row of B.3.
#[derive(Clone, Debug, Serialize)]
pub struct SpmvRow {
    /// `g=..`
    pub case: String,
    /// grid size g (the matrix is g^2 x g^2)
    pub grid: usize,
    /// rows
    pub n: usize,
    /// stored entries
    pub nnz: usize,
    /// gpumat `y.assign(&a * &x)`, seconds per product
    pub gpumat_s: f64,
    /// Eigen `y.noalias() = a * x` (row-major, int indices, OpenMP)
    pub eigen_s: Option<f64>,
    /// scipy `csr_matrix @ x` (f32, one thread)
    pub scipy_s: Option<f64>,
    /// faer `sparse_dense_matmul` with the same CSR matrix (`Par::rayon(0)`, in-process)
    pub faer_s: f64,
    /// bytes of gpumat's product (its index widths as stored in `SparsityPattern`)
    pub bytes: usize,
    /// bytes of Eigen's product (4-byte indices)
    pub eigen_bytes: usize,
    /// `bytes / gpumat_s`
    pub gpumat_gbs: f64,
    /// `eigen_bytes / eigen_s`
    pub eigen_gbs: Option<f64>,
    /// the STREAM triad bandwidth this row is compared with (the better sample around its
    /// table), GB/s
    pub stream_triad_gbs: f64,
    /// `gpumat_gbs / stream_triad_gbs`
    pub fraction_of_stream: f64,
    /// `eigen_gbs / stream_triad_gbs`
    pub eigen_fraction_of_stream: Option<f64>,
    /// `eigen_s / gpumat_s`
    pub speedup_vs_eigen: Option<f64>,
    /// `scipy_s / gpumat_s`
    pub speedup_vs_scipy: Option<f64>,
    /// `faer_s / gpumat_s`
    pub speedup_vs_faer: f64,
    /// Eigen's, scipy's and faer's `sum(y)` match gpumat's
    pub results_agree: bool,
    /// thesis, cuSPARSE on a GTX 1060, ms
    pub thesis_cusparse_ms: Option<f64>,
    /// thesis, cuMat on a GTX 1060, ms
    pub thesis_cumat_ms: Option<f64>,
    /// thesis, Eigen on an i7-6700, ms
    pub thesis_eigen_ms: Option<f64>,
}

/// Measures one SpMV case.
pub fn spmv_row(ctx: &mut Ctx, g: usize) -> SpmvRow {
    progress(&format!("spmv g={g}"));
    let p = ctx.policy;
    let one = Policy { rounds: 1, ..p };
    let a = poisson_matrix(g);
    let n = g * g;
    let x = random_vector(SPMV_X_SEED, n);
    let mut y = Matrix::<f32>::zeros(n, 1, 1);
    let af = a.to_faer_csr(0);
    let mut yf = faer::Mat::<f32>::zeros(n, 1);
    let (mut m, mut mf, mut eigen, mut scipy) = (None, None, None, None);
    for _ in 0..p.rounds.max(1) {
        let mg = measure(&one, || {
            black_box(&mut y).assign(black_box(&a) * black_box(&x));
        });
        m = Some(best_of(m, mg));
        let mfa = measure(&one, || faer_spmv(yf.as_mut(), af.as_ref(), x.faer_ref(0), 1.0));
        mf = Some(best_of(mf, mfa));
        if let Some(r) = ctx.peers.skfem.as_ref().map(|s| s.sparse2d("spmv", g, &one)) {
            scipy = PeerOutput::faster(scipy, ctx.peers.take(r));
        }
        if let Some(r) = ctx
            .peers
            .eigen
            .as_ref()
            .map(|e| e.run("spmv", &[g.to_string()], &one))
        {
            eigen = PeerOutput::faster(eigen, ctx.peers.take(r));
        }
    }
    let m = m.expect("one round");
    let sum = checksum(y.as_slice());
    let scale: f64 = y
        .as_slice()
        .iter()
        .map(|&v| v.abs() as f64)
        .sum::<f64>()
        .max(1e-30);
    let nnz = a.nnz();
    let bytes = gpumat_spmv_bytes(&a);
    drop((a, x, y));
    let faer_sum: f64 = (0..n).map(|i| yf[(i, 0)] as f64).sum();
    let mut ok = (faer_sum - sum).abs() <= 1e-4 * scale;
    if !ok {
        ctx.peers.notes.push(format!(
            "spmv g={g}: faer's sum(y) {faer_sum} differs from gpumat's {sum}"
        ));
    }
    let faer_s = mf.expect("one round").seconds;
    for (who, out) in [("Eigen", &eigen), ("scipy", &scipy)] {
        if let Some(o) = out {
            if o.f64("checksum").map_or(true, |s| (s - sum).abs() > 1e-4 * scale)
                || o.usize("nnz") != Some(nnz)
            {
                ok = false;
                ctx.peers.notes.push(format!(
                    "spmv g={g}: {who}'s result differs from gpumat's ({:?})",
                    o.0
                ));
            }
        }
    }
    let eigen_s = eigen.and_then(|o| o.f64("time_s"));
    let scipy_s = scipy.and_then(|o| o.f64("time_s"));
    let eigen_bytes = spmv_bytes(n, nnz, 4);
    let gbs = bytes as f64 / m.seconds / 1e9;
    let eigen_gbs = eigen_s.map(|t| eigen_bytes as f64 / t / 1e9);
    let th = thesis::b3(g);
    SpmvRow {
        case: format!("g={g}"),
        grid: g,
        n,
        nnz,
        gpumat_s: m.seconds,
        eigen_s,
        scipy_s,
        faer_s,
        bytes,
        eigen_bytes,
        gpumat_gbs: gbs,
        eigen_gbs,
        stream_triad_gbs: ctx.stream_gbs,
        fraction_of_stream: gbs / ctx.stream_gbs,
        eigen_fraction_of_stream: eigen_gbs.map(|b| b / ctx.stream_gbs),
        speedup_vs_eigen: ratio(eigen_s, Some(m.seconds)),
        speedup_vs_scipy: ratio(scipy_s, Some(m.seconds)),
        speedup_vs_faer: faer_s / m.seconds,
        results_agree: ok,
        thesis_cusparse_ms: th.map(|t| t.0),
        thesis_cumat_ms: th.map(|t| t.1),
        thesis_eigen_ms: th.map(|t| t.2),
    }
}

impl SpmvRow {
    /// Recomputes the fractions of STREAM for the bandwidth `stream_gbs`.
    pub fn set_stream(&mut self, stream_gbs: f64) {
        self.stream_triad_gbs = stream_gbs;
        self.fraction_of_stream = self.gpumat_gbs / stream_gbs;
        self.eigen_fraction_of_stream = self.eigen_gbs.map(|b| b / stream_gbs);
    }
}

/// Table B.3: g in {10, 100, 1000}.
pub fn table_b3(ctx: &mut Ctx) -> Vec<SpmvRow> {
    [10, 100, 1000].into_iter().map(|g| spmv_row(ctx, g)).collect()
}

/// One row of B.4.
#[derive(Clone, Debug, Serialize)]
pub struct CgRow {
    /// `g=..`
    pub case: String,
    /// grid size g
    pub grid: usize,
    /// unknowns g^2
    pub n: usize,
    /// stored entries
    pub nnz: usize,
    /// relative residual tolerance
    pub tolerance: f64,
    /// gpumat: Jacobi setup + `gpumat::cg` from x = 0, seconds per solve
    pub gpumat_s: f64,
    /// gpumat's iterations
    pub gpumat_iterations: usize,
    /// `gpumat_s / gpumat_iterations`
    pub gpumat_per_iteration_s: f64,
    /// gpumat's final relative residual
    pub gpumat_residual: f64,
    /// gpumat converged
    pub gpumat_converged: bool,
    /// Eigen: `ConjugateGradient<.., Lower|Upper, DiagonalPreconditioner>` setup + solve
    pub eigen_s: Option<f64>,
    /// Eigen's iterations counted as gpumat counts them (updates of x; Eigen's own
    /// `iterations()` leaves out the final, converging one)
    pub eigen_iterations: Option<usize>,
    /// Eigen's `cg.iterations()` as reported
    pub eigen_reported_iterations: Option<usize>,
    /// `eigen_s / eigen_iterations`
    pub eigen_per_iteration_s: Option<f64>,
    /// Eigen's final relative residual (`cg.error()`)
    pub eigen_residual: Option<f64>,
    /// scipy: `scipy.sparse.linalg.cg` with a Jacobi `LinearOperator`, setup + solve
    pub scipy_s: Option<f64>,
    /// scipy's iterations (updates of x, its callback's count)
    pub scipy_iterations: Option<usize>,
    /// `scipy_s / scipy_iterations`
    pub scipy_per_iteration_s: Option<f64>,
    /// `eigen_s / gpumat_s`
    pub speedup_vs_eigen: Option<f64>,
    /// `scipy_s / gpumat_s`
    pub speedup_vs_scipy: Option<f64>,
    /// `eigen_per_iteration_s / gpumat_per_iteration_s` (>= 1: gpumat's iteration is no slower)
    pub per_iteration_speedup_vs_eigen: Option<f64>,
    /// bytes one gpumat CG iteration moves: its SpMV (indices as stored) and 7 vector passes
    /// (17 n f32: two dots, a norm, three updates, the Jacobi product)
    pub bytes: usize,
    /// bytes one Eigen CG iteration moves (4-byte indices, the same vector passes)
    pub eigen_bytes: usize,
    /// `bytes / gpumat_per_iteration_s`
    pub gpumat_gbs: f64,
    /// the STREAM triad bandwidth this row is compared with (the better sample around its
    /// table), GB/s
    pub stream_triad_gbs: f64,
    /// `gpumat_gbs / stream_triad_gbs`
    pub fraction_of_stream: f64,
    /// Eigen's right-hand side checksum equals gpumat's (same system solved)
    pub same_rhs: Option<bool>,
    /// thesis, cuMat on a GTX 1060, ms
    pub thesis_cumat_ms: Option<f64>,
    /// thesis, Eigen on an i7-6700, ms
    pub thesis_eigen_ms: Option<f64>,
}

/// Measures one CG case.
pub fn cg_row(ctx: &mut Ctx, g: usize) -> CgRow {
    progress(&format!("cg g={g}"));
    let p = ctx.policy;
    let a = poisson_matrix(g);
    let n = g * g;
    let b = boundary_rhs(g);
    let params = CgParams {
        max_iterations: 2 * n,
        tolerance: CG_TOLERANCE,
        absolute_tolerance: 0.0,
    };
    let mut x = Matrix::<f32>::zeros(n, 1, 1);
    let mut last = None;
    // A large solve takes seconds: 3 repetitions per round are enough there.
    let one = Policy {
        rounds: 1,
        min_samples: p.min_samples.min(3),
        ..p
    };
    let (mut m, mut eigen, mut scipy) = (None, None, None);
    for _ in 0..p.rounds.max(1) {
        if let Some(r) = ctx.peers.skfem.as_ref().map(|s| s.sparse2d("cg", g, &one)) {
            scipy = PeerOutput::faster(scipy, ctx.peers.take(r));
        }
        let mg = measure(&one, || {
            let pre = Jacobi::new(black_box(&a)).expect("the Poisson matrix has a positive diagonal");
            x.as_mut_slice().fill(0.0);
            last = Some(cg(&a, black_box(&b), &mut x, &pre, &params));
            black_box(&mut x);
        });
        m = Some(best_of(m, mg));
        if let Some(r) = ctx
            .peers
            .eigen
            .as_ref()
            .map(|e| e.run("cg", &[g.to_string()], &one))
        {
            eigen = PeerOutput::faster(eigen, ctx.peers.take(r));
        }
    }
    let m = m.expect("one round");
    let (info, converged) = match last.expect("measure ran the solve") {
        Ok(info) => (info, true),
        Err(CgError::NoConvergence { info }) => (info, false),
        Err(e) => panic!("gpumat::cg failed on the Poisson matrix: {e}"),
    };
    let rhs_sum = checksum(b.as_slice());
    let nnz = a.nnz();
    let spmv_bytes_a = gpumat_spmv_bytes(&a);
    drop((a, b, x));
    let same_rhs = eigen.as_ref().map(|o| {
        o.f64("rhs_checksum")
            .is_some_and(|s| (s - rhs_sum).abs() <= 1e-6 * rhs_sum.abs())
    });
    if same_rhs == Some(false) {
        ctx.peers
            .notes
            .push(format!("cg g={g}: Eigen's right-hand side differs"));
    }
    if let Some(o) = &scipy {
        let same = o
            .f64("rhs_checksum")
            .is_some_and(|s| (s - rhs_sum).abs() <= 1e-6 * rhs_sum.abs());
        if !same || o.usize("converged") != Some(1) {
            ctx.peers.notes.push(format!(
                "cg g={g}: scipy solved another system or did not converge ({:?})",
                o.0
            ));
        }
    }
    let scipy_s = scipy.as_ref().and_then(|o| o.f64("time_s"));
    let scipy_its = scipy.as_ref().and_then(|o| o.usize("iterations"));
    let its = info.iterations[0];
    let per_it = m.seconds / its.max(1) as f64;
    let eigen_s = eigen.as_ref().and_then(|o| o.f64("time_s"));
    let eigen_its = eigen.as_ref().and_then(|o| o.usize("updates"));
    let eigen_per_it = match (eigen_s, eigen_its) {
        (Some(t), Some(i)) => Some(t / i.max(1) as f64),
        _ => None,
    };
    // The SpMV q = A p (its bytes count p and q once), then 7 vector passes moving 17 n f32:
    // dot p.q 2, x update 3, r update 3, Jacobi 3, dot r.z 2, norm r 1, p update 3.
    let bytes_it = spmv_bytes_a + 4 * 17 * n;
    let gbs = bytes_it as f64 / per_it / 1e9;
    let th = thesis::b4(g);
    CgRow {
        case: format!("g={g}"),
        grid: g,
        n,
        nnz,
        tolerance: CG_TOLERANCE as f64,
        gpumat_s: m.seconds,
        gpumat_iterations: its,
        gpumat_per_iteration_s: per_it,
        gpumat_residual: info.residual[0] as f64,
        gpumat_converged: converged,
        eigen_s,
        eigen_iterations: eigen_its,
        eigen_reported_iterations: eigen.as_ref().and_then(|o| o.usize("iterations")),
        eigen_per_iteration_s: eigen_per_it,
        eigen_residual: eigen.as_ref().and_then(|o| o.f64("error")),
        scipy_s,
        scipy_iterations: scipy_its,
        scipy_per_iteration_s: scipy_s.zip(scipy_its).map(|(t, i)| t / i.max(1) as f64),
        speedup_vs_eigen: ratio(eigen_s, Some(m.seconds)),
        speedup_vs_scipy: ratio(scipy_s, Some(m.seconds)),
        per_iteration_speedup_vs_eigen: ratio(eigen_per_it, Some(per_it)),
        bytes: bytes_it,
        eigen_bytes: spmv_bytes(n, nnz, 4) + 4 * 17 * n,
        gpumat_gbs: gbs,
        stream_triad_gbs: ctx.stream_gbs,
        fraction_of_stream: gbs / ctx.stream_gbs,
        same_rhs,
        thesis_cumat_ms: th.map(|t| t.0),
        thesis_eigen_ms: th.map(|t| t.1),
    }
}

impl CgRow {
    /// Recomputes the fraction of STREAM for the bandwidth `stream_gbs`.
    pub fn set_stream(&mut self, stream_gbs: f64) {
        self.stream_triad_gbs = stream_gbs;
        self.fraction_of_stream = self.gpumat_gbs / stream_gbs;
    }
}

/// The grid sizes of B.4 (quick: up to 300).
pub fn b4_grids(quick: bool) -> Vec<usize> {
    if quick {
        vec![10, 100, 300]
    } else {
        vec![10, 100, 1000]
    }
}

/// Table B.4.
pub fn table_b4(ctx: &mut Ctx) -> Vec<CgRow> {
    b4_grids(ctx.quick).into_iter().map(|g| cg_row(ctx, g)).collect()
}

/// Markdown columns of B.3.
pub fn b3_columns() -> Vec<Col> {
    vec![
        col("g", "grid", Fmt::Plain),
        col("nnz", "nnz", Fmt::Plain),
        col("gpumat ms", "gpumat_s", Fmt::SecondsAsMs),
        col("Eigen ms", "eigen_s", Fmt::SecondsAsMs),
        col("scipy ms", "scipy_s", Fmt::SecondsAsMs),
        col("gpumat GB/s", "gpumat_gbs", Fmt::Gbs),
        col("of STREAM", "fraction_of_stream", Fmt::Percent),
        col("Eigen GB/s", "eigen_gbs", Fmt::Gbs),
        col("Eigen of STREAM", "eigen_fraction_of_stream", Fmt::Percent),
        col("vs Eigen", "speedup_vs_eigen", Fmt::Ratio),
        col("vs scipy", "speedup_vs_scipy", Fmt::Ratio),
        col("faer ms", "faer_s", Fmt::SecondsAsMs),
        col("vs faer", "speedup_vs_faer", Fmt::Ratio),
        col("thesis cuSPARSE ms", "thesis_cusparse_ms", Fmt::Ms),
        col("thesis cuMat ms", "thesis_cumat_ms", Fmt::Ms),
        col("thesis Eigen ms", "thesis_eigen_ms", Fmt::Ms),
    ]
}

/// Markdown columns of B.4.
pub fn b4_columns() -> Vec<Col> {
    vec![
        col("g", "grid", Fmt::Plain),
        col("gpumat ms", "gpumat_s", Fmt::SecondsAsMs),
        col("gpumat its", "gpumat_iterations", Fmt::Plain),
        col("gpumat ms/it", "gpumat_per_iteration_s", Fmt::SecondsAsMs),
        col("Eigen ms", "eigen_s", Fmt::SecondsAsMs),
        col("Eigen its", "eigen_iterations", Fmt::Plain),
        col("Eigen ms/it", "eigen_per_iteration_s", Fmt::SecondsAsMs),
        col("per-it vs Eigen", "per_iteration_speedup_vs_eigen", Fmt::Ratio),
        col("scipy ms", "scipy_s", Fmt::SecondsAsMs),
        col("scipy its", "scipy_iterations", Fmt::Plain),
        col("scipy ms/it", "scipy_per_iteration_s", Fmt::SecondsAsMs),
        col("vs scipy", "speedup_vs_scipy", Fmt::Ratio),
        col("gpumat GB/s", "gpumat_gbs", Fmt::Gbs),
        col("of STREAM", "fraction_of_stream", Fmt::Percent),
        col("thesis cuMat ms", "thesis_cumat_ms", Fmt::Ms),
        col("thesis Eigen ms", "thesis_eigen_ms", Fmt::Ms),
    ]
}
