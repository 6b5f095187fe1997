//! Table B.3-bsr: the SpMV a simulation runs, `y = K x` with the held cuboid's stiffness matrix
//! (Table B.5's body at the thesis' resolution r, f64), as 3x3 blocks (BSR) and as the same
//! matrix in scalar CSR, ours against scipy's `bsr_matrix` and `csr_matrix` and Eigen's
//! row-major `SparseMatrix` (Eigen has no block format) and faer's CSR product (in-process).
//! This shows what blocking buys.
//!
//! The matrix goes to the peers through a file (`target/bench-data/cuboid_k_r{r}.bin`,
//! little-endian: `u64` block rows `n`, `u64` blocks `nnz`, `u64` row pointers `[n + 1]`, `u32`
//! block columns `[nnz]`, `f64` row-major 3x3 blocks `[9 nnz]`); `x_j` is
//! `2 u(SPMV_X_SEED, j) - 1` of `crate::problems` (an f32 value, widened) on every side, and each
//! side reports `sum(y)`.

use crate::peers::PeerOutput;
use crate::problems::{random_vector, SPMV_X_SEED};
use crate::report::{col, Col, Fmt};
use crate::timing::{best_of, measure, Policy};
use crate::{progress, ratio, Ctx};
use gpumat::{Mat3, Matrix, SparseMatrix, SparsityPattern, Vec3};
use serde::Serialize;
use std::hint::black_box;
use std::path::{Path, PathBuf};

/// One row: one resolution.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// "res=20"
    pub case: String,
    /// the thesis' resolution r
    pub resolution: u32,
    /// block rows (nodes) and 3x3 blocks
    pub block_rows: usize,
    pub blocks: usize,
    /// scalar rows and entries of the same matrix in CSR
    pub rows: usize,
    pub nnz: usize,
    /// seconds per product: ours BSR, ours scalar CSR
    pub gpumat_s: f64,
    pub gpumat_csr_s: f64,
    /// scipy `bsr_matrix` (blocksize 3) and `csr_matrix` of the same matrix
    pub scipy_bsr_s: Option<f64>,
    pub scipy_csr_s: Option<f64>,
    /// Eigen `SparseMatrix<double, RowMajor>` (OpenMP)
    pub eigen_s: Option<f64>,
    /// faer `sparse_dense_matmul` with the scalar CSR (`Par::rayon(0)`, in-process)
    pub faer_s: f64,
    /// bytes a BSR product moves (values, u32 block columns, row pointers, x, y) and a CSR one
    pub bsr_bytes: usize,
    pub csr_bytes: usize,
    /// GB/s of ours
    pub gpumat_gbs: f64,
    pub gpumat_csr_gbs: f64,
    /// ratios (>1: our BSR faster)
    pub bsr_vs_scipy_csr: Option<f64>,
    pub bsr_vs_scipy_bsr: Option<f64>,
    pub bsr_vs_eigen: Option<f64>,
    pub bsr_vs_faer: f64,
    /// what blocking buys us: ours CSR / ours BSR
    pub bsr_vs_own_csr: f64,
    /// every side's `sum(y)` agrees with ours to 1e-9 relative
    pub results_agree: bool,
}

/// The cuboid's stiffness matrix at resolution `r`.
fn stiffness(r: u32) -> Result<SparseMatrix<Mat3<f64>>, String> {
    let (shape, model) = cutfem::fem::model::thesis_cuboid(false);
    let sdf = shape.to_sdf(2.0 * r as f64, 6).map_err(|e| e.to_string())?;
    let grid = cutfem::fem::Grid::new(sdf).map_err(|e| e.to_string())?;
    let sim = cutfem::fem::Simulation::new(grid, model).map_err(|e| e.to_string())?;
    Ok(sim.stiffness().clone())
}

/// The same matrix with scalar entries (each block's 9 entries, zeros included).
fn scalar(k: &SparseMatrix<Mat3<f64>>) -> SparseMatrix<f64> {
    let p = k.pattern();
    let n = p.rows();
    let mut row_ptr = vec![0usize; 3 * n + 1];
    let mut cols = Vec::with_capacity(9 * p.nnz());
    let mut vals = Vec::with_capacity(9 * p.nnz());
    for br in 0..n {
        for a in 0..3 {
            for e in p.row_range(br) {
                let c = p.col_idx()[e] as usize;
                for b in 0..3 {
                    cols.push(3 * c + b);
                    vals.push(k.values()[e].m[a][b]);
                }
            }
            row_ptr[3 * br + a + 1] = cols.len();
        }
    }
    let pattern = SparsityPattern::new(3 * n, 3 * n, row_ptr, cols).expect("block columns are sorted");
    SparseMatrix::from_values(pattern, 1, vals)
}

/// Writes `k` in the peers' format (module docs).
fn write(k: &SparseMatrix<Mat3<f64>>, path: &Path) -> Result<(), String> {
    let p = k.pattern();
    let mut out = Vec::with_capacity(16 + 8 * (p.rows() + 1) + 76 * p.nnz());
    out.extend((p.rows() as u64).to_le_bytes());
    out.extend((p.nnz() as u64).to_le_bytes());
    p.row_ptr()
        .iter()
        .for_each(|&v| out.extend((v as u64).to_le_bytes()));
    p.col_idx().iter().for_each(|&v| out.extend(v.to_le_bytes()));
    for m in k.values() {
        m.m.iter().flatten().for_each(|v| out.extend(v.to_le_bytes()));
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    std::fs::write(path, out).map_err(|e| format!("{}: {e}", path.display()))
}

/// Where the matrix file of resolution `r` goes.
fn matrix_file(r: u32) -> PathBuf {
    crate::peers::eigen_build_dir()
        .with_file_name("bench-data")
        .join(format!("cuboid_k_r{r}.bin"))
}

/// The row of resolution `r`.
pub fn row(ctx: &mut Ctx, r: u32) -> Result<Row, String> {
    progress(&format!("B.3-bsr r={r}"));
    let k = stiffness(r)?;
    let csr = scalar(&k);
    let n = k.rows();
    let xs: Vec<f64> = random_vector(SPMV_X_SEED, 3 * n)
        .as_slice()
        .iter()
        .map(|&v| v as f64)
        .collect();
    let xb = Matrix::from_fn(n, 1, 1, |i, _, _| {
        Vec3::new(xs[3 * i], xs[3 * i + 1], xs[3 * i + 2])
    });
    let xc = Matrix::from_fn(3 * n, 1, 1, |i, _, _| xs[i]);
    let mut yb = Matrix::<Vec3<f64>>::zeros(n, 1, 1);
    let mut yc = Matrix::<f64>::zeros(3 * n, 1, 1);
    let path = matrix_file(r);
    write(&k, &path)?;
    let p = ctx.policy;
    let one = Policy { rounds: 1, ..p };
    let cf = csr.to_faer_csr(0);
    let mut yf = faer::Mat::<f64>::zeros(3 * n, 1);
    let (mut mb, mut mc, mut mf) = (None, None, None);
    let (mut scipy, mut eigen): (Option<PeerOutput>, Option<PeerOutput>) = (None, None);
    let file = path.display().to_string();
    for _ in 0..p.rounds.max(1) {
        mb = Some(best_of(
            mb,
            measure(&one, || black_box(&mut yb).assign(black_box(&k) * &xb)),
        ));
        mc = Some(best_of(
            mc,
            measure(&one, || black_box(&mut yc).assign(black_box(&csr) * &xc)),
        ));
        let m = measure(&one, || {
            crate::table_sparse::faer_spmv(yf.as_mut(), cf.as_ref(), xc.faer_ref(0), 1.0)
        });
        mf = Some(best_of(mf, m));
        if let Some(s) = ctx.peers.skfem.clone() {
            let o = ctx.peers.take(s.bsr_spmv(&file, &one));
            scipy = PeerOutput::faster(scipy, o);
        }
        if let Some(e) = ctx.peers.eigen.clone() {
            let o = ctx
                .peers
                .take(e.run("bsr_spmv", std::slice::from_ref(&file), &one));
            eigen = PeerOutput::faster(eigen, o);
        }
    }
    let (tb, tc) = (mb.expect("a round").seconds, mc.expect("a round").seconds);
    let sum: f64 = yb.as_slice().iter().map(|v| v.x + v.y + v.z).sum();
    let scale: f64 = yb
        .as_slice()
        .iter()
        .map(|v| v.x.abs() + v.y.abs() + v.z.abs())
        .sum::<f64>()
        .max(1e-300);
    let own_csr: f64 = yc.as_slice().iter().sum();
    let agrees = |s: Option<f64>| s.is_some_and(|s| (s - sum).abs() <= 1e-9 * scale);
    let faer_sum: f64 = (0..3 * n).map(|i| yf[(i, 0)]).sum();
    let mut ok = agrees(Some(own_csr)) && agrees(Some(faer_sum));
    let tf = mf.expect("a round").seconds;
    for (who, o) in [("scipy", &scipy), ("Eigen", &eigen)] {
        if let Some(o) = o {
            if !agrees(o.f64("checksum")) {
                ok = false;
                ctx.peers.notes.push(format!(
                    "B.3-bsr r={r}: {who}'s sum(y) differs from ours ({:?})",
                    o.0
                ));
            }
        }
    }
    let nnzb = k.nnz();
    let bsr_bytes = nnzb * (72 + 4) + (n + 1) * std::mem::size_of::<usize>() + 2 * 24 * n;
    let csr_bytes = 9 * nnzb * (8 + 4) + (3 * n + 1) * std::mem::size_of::<usize>() + 2 * 24 * n;
    let scipy_bsr_s = scipy.as_ref().and_then(|o| o.f64("time_s"));
    let scipy_csr_s = scipy.as_ref().and_then(|o| o.f64("csr_s"));
    let eigen_s = eigen.as_ref().and_then(|o| o.f64("time_s"));
    Ok(Row {
        case: format!("res={r}"),
        resolution: r,
        block_rows: n,
        blocks: nnzb,
        rows: 3 * n,
        nnz: 9 * nnzb,
        gpumat_s: tb,
        gpumat_csr_s: tc,
        scipy_bsr_s,
        scipy_csr_s,
        eigen_s,
        faer_s: tf,
        bsr_bytes,
        csr_bytes,
        gpumat_gbs: bsr_bytes as f64 / tb / 1e9,
        gpumat_csr_gbs: csr_bytes as f64 / tc / 1e9,
        bsr_vs_scipy_csr: ratio(scipy_csr_s, Some(tb)),
        bsr_vs_scipy_bsr: ratio(scipy_bsr_s, Some(tb)),
        bsr_vs_eigen: ratio(eigen_s, Some(tb)),
        bsr_vs_faer: tf / tb,
        bsr_vs_own_csr: tc / tb,
        results_agree: ok,
    })
}

/// The table: r = 10 and 20 (`--quick`: 10).
pub fn table(ctx: &mut Ctx) -> Vec<Row> {
    crate::resolution_rows(ctx, "B.3-bsr", row)
}

/// The markdown columns.
pub fn columns() -> Vec<Col> {
    vec![
        col("r", "resolution", Fmt::Plain),
        col("block rows", "block_rows", Fmt::Plain),
        col("blocks", "blocks", Fmt::Plain),
        col("ours BSR ms", "gpumat_s", Fmt::SecondsAsMs),
        col("ours BSR GB/s", "gpumat_gbs", Fmt::Gbs),
        col("ours CSR ms", "gpumat_csr_s", Fmt::SecondsAsMs),
        col("ours CSR GB/s", "gpumat_csr_gbs", Fmt::Gbs),
        col("scipy BSR ms", "scipy_bsr_s", Fmt::SecondsAsMs),
        col("scipy CSR ms", "scipy_csr_s", Fmt::SecondsAsMs),
        col("Eigen CSR ms", "eigen_s", Fmt::SecondsAsMs),
        col("faer CSR ms", "faer_s", Fmt::SecondsAsMs),
        col("BSR: own CSR / ours", "bsr_vs_own_csr", Fmt::Ratio),
        col("scipy CSR / ours", "bsr_vs_scipy_csr", Fmt::Ratio),
        col("scipy BSR / ours", "bsr_vs_scipy_bsr", Fmt::Ratio),
        col("Eigen / ours", "bsr_vs_eigen", Fmt::Ratio),
        col("faer / ours", "bsr_vs_faer", Fmt::Ratio),
        col("agree", "results_agree", Fmt::Plain),
    ]
}

/// The table's markdown section.
pub fn markdown(rows: &[serde_json::Value]) -> String {
    crate::report::markdown_table(
        "Table B.3-bsr: SpMV with the held cuboid's stiffness matrix (f64), 3x3 blocks against scalar CSR",
        "The matrix of Table B.5's body (cells of size 1/(2r), Nitsche hold) as 3x3 blocks (ours: \
         `SparseMatrix<Mat3<f64>>`; scipy: `bsr_matrix`, blocksize 3) and as the same matrix in scalar \
         CSR with every block's 9 entries (ours `SparseMatrix<f64>`, scipy `csr_matrix`, Eigen \
         `SparseMatrix<double, RowMajor>` with OpenMP; faer `sparse_dense_matmul` on all threads). Times per product, the tables' timing policy on \
         every side; bytes: values + column indices + row pointers + x + y as stored (CSR: 8-byte values, \
         4-byte columns). scipy runs on one thread.",
        rows,
        &columns(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scalar CSR holds the blocks' entries: both products agree.
    #[test]
    fn scalar_csr_is_the_same_matrix() {
        let k = stiffness(3).unwrap();
        let c = scalar(&k);
        assert_eq!(c.nnz(), 9 * k.nnz());
        let n = k.rows();
        let x = Matrix::from_fn(n, 1, 1, |i, _, _| {
            let t = i as f64;
            Vec3::new(t.sin(), (0.7 * t).cos(), 0.5)
        });
        let xs = Matrix::from_fn(3 * n, 1, 1, |i, _, _| x.as_slice()[i / 3].to_array()[i % 3]);
        let yb = Matrix::eval(&k * &x);
        let ys = Matrix::eval(&c * &xs);
        // the same products in another summation order: equal to rounding of the largest terms
        let big = ys.as_slice().iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        for i in 0..3 * n {
            let (a, b) = (yb.as_slice()[i / 3].to_array()[i % 3], ys.as_slice()[i]);
            assert!((a - b).abs() <= 1e-12 * big, "row {i}: {a} vs {b}");
        }
    }
}
