//! Helpers shared by the integration tests: a small deterministic RNG, conversion of matrices
//! to `f64` for naive reference loops, tolerance checks, and random symmetric positive
//! definite (SPD) block-sparse systems with a known Gershgorin lower bound on their spectrum.
#![allow(dead_code)]

use gpumat::{Mat3, Matrix, Real, Scalar, SparseMatrix, SparsityPattern};
use proptest::test_runner::Config;
use std::sync::Arc;

/// The proptest configuration of every property test: a fixed, modest number of cases (64;
/// `GPUMAT_PROPTEST_CASES` raises it for a local stress run).
pub fn config() -> Config {
    let cases = std::env::var("GPUMAT_PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64);
    Config {
        failure_persistence: None,
        ..Config::with_cases(cases)
    }
}

/// splitmix64: deterministic, seedable, good enough for test data.
#[derive(Debug, Clone)]
pub struct Rand(u64);

impl Rand {
    pub fn new(seed: u64) -> Self {
        Self(
            seed.wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(0x2545_F491_4F6C_DD1D),
        )
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// Uniform in `0..n`.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    pub fn mat3(&mut self, lo: f64, hi: f64) -> [[f64; 3]; 3] {
        std::array::from_fn(|_| std::array::from_fn(|_| self.uniform(lo, hi)))
    }
}

/// Every lane of every element of a matrix, as `f64`, in element order.
pub fn lanes_f64<T: Scalar>(m: &Matrix<T>) -> Vec<f64> {
    m.as_slice()
        .iter()
        .flat_map(|v| (0..T::LANES).map(move |l| v.lane(l).as_f64()))
        .collect()
}

/// A random real matrix with entries uniform in `[lo, hi)`.
pub fn random_matrix<R: Real>(rng: &mut Rand, shape: (usize, usize, usize), lo: f64, hi: f64) -> Matrix<R> {
    Matrix::from_fn(shape.0, shape.1, shape.2, |_, _, _| R::of(rng.uniform(lo, hi)))
}

/// The broadcast element `(r, c, b)` of a column-major `rows x cols x batches` array.
pub fn bget<T: Copy>(data: &[T], s: (usize, usize, usize), r: usize, c: usize, b: usize) -> T {
    let r = if s.0 == 1 { 0 } else { r };
    let c = if s.1 == 1 { 0 } else { c };
    let b = if s.2 == 1 { 0 } else { b };
    data[r + s.0 * (c + s.1 * b)]
}

/// Asserts `|got - want| <= tol`, with a message naming the quantity.
#[track_caller]
pub fn assert_close(got: f64, want: f64, tol: f64, what: &str) {
    assert!(
        (got - want).abs() <= tol || (got.is_nan() && want.is_nan()),
        "{what}: got {got:e}, want {want:e}, |diff| = {:e} > tol {tol:e}",
        (got - want).abs()
    );
}

/// Asserts element by element that `got` is within `rtol * |want| + atol` of `want`.
#[track_caller]
pub fn assert_all_close(got: &[f64], want: &[f64], rtol: f64, atol: f64, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: lengths differ");
    for (i, (&g, &w)) in got.iter().zip(want).enumerate() {
        assert_close(g, w, rtol * w.abs() + atol, &format!("{what}[{i}]"));
    }
}

/// The unit roundoff-ish epsilon of `R` as `f64`.
pub fn eps<R: Real>() -> f64 {
    R::epsilon().as_f64()
}

/// A random SPD block system: `n` 3x3 block rows, a symmetric random pattern (always with the
/// diagonal and the chain `i, i+1`), per-batch values. Off-diagonal blocks are uniform in
/// `[-1, 1]` with `A_ji = A_ij^T`; each diagonal lane is the absolute sum of the other entries of
/// its scalar row plus `margin` plus a per-batch random extra, so every batch is strictly
/// diagonally dominant and symmetric: by Gershgorin its smallest eigenvalue is at least
/// `margin`.
#[derive(Debug, Clone)]
pub struct SpdBlocks {
    pub n: usize,
    pub pattern: Arc<SparsityPattern>,
    /// `values[b][k]` is block `k` (pattern order) of batch `b`.
    pub values: Vec<Vec<[[f64; 3]; 3]>>,
    pub margin: f64,
}

pub fn random_spd_blocks(rng: &mut Rand, n: usize, batches: usize, density: f64, margin: f64) -> SpdBlocks {
    let mut pairs = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            if j == i + 1 || rng.unit() < density {
                pairs.push((i, j));
            }
        }
    }
    spd_from_pairs(rng, n, batches, &pairs, margin)
}

/// Like [`random_spd_blocks`] for large `n`: the chain plus `extra` random couplings per row.
pub fn random_spd_blocks_large(
    rng: &mut Rand,
    n: usize,
    batches: usize,
    extra: usize,
    margin: f64,
) -> SpdBlocks {
    let mut pairs: Vec<(usize, usize)> = (0..n.saturating_sub(1)).map(|i| (i, i + 1)).collect();
    for i in 0..n {
        for _ in 0..extra {
            let j = rng.below(n);
            if j != i {
                pairs.push((i.min(j), i.max(j)));
            }
        }
    }
    spd_from_pairs(rng, n, batches, &pairs, margin)
}

/// The SPD system on the symmetric pattern of the diagonal and the `(i, j)`/`(j, i)` pairs.
fn spd_from_pairs(
    rng: &mut Rand,
    n: usize,
    batches: usize,
    pairs: &[(usize, usize)],
    margin: f64,
) -> SpdBlocks {
    let entries = (0..n)
        .map(|i| (i, i))
        .chain(pairs.iter().flat_map(|&(i, j)| [(i, j), (j, i)]));
    let pattern = SparsityPattern::from_entries(n, n, entries);
    let nnz = pattern.nnz();
    let mut values = Vec::with_capacity(batches);
    for _ in 0..batches {
        let mut v = vec![[[0.0; 3]; 3]; nnz];
        for r in 0..n {
            for k in pattern.row_range(r) {
                let c = pattern.col_idx()[k] as usize;
                if c > r {
                    let blk = rng.mat3(-1.0, 1.0);
                    v[k] = blk;
                    let kt = pattern.find(c, r).expect("pattern is symmetric");
                    v[kt] = std::array::from_fn(|i| std::array::from_fn(|j| blk[j][i]));
                } else if c == r {
                    let s = rng.mat3(-1.0, 1.0);
                    v[k] = std::array::from_fn(|i| std::array::from_fn(|j| 0.5 * (s[i][j] + s[j][i])));
                }
            }
        }
        // Diagonal lanes: absolute off-diagonal row sum + margin + extra.
        for r in 0..n {
            let kd = pattern.find(r, r).expect("diagonal stored");
            for i in 0..3 {
                let mut off = 0.0;
                for k in pattern.row_range(r) {
                    for j in 0..3 {
                        if !(k == kd && j == i) {
                            off += v[k][i][j].abs();
                        }
                    }
                }
                v[kd][i][i] = off + margin + rng.uniform(0.0, 2.0);
            }
        }
        values.push(v);
    }
    SpdBlocks {
        n,
        pattern,
        values,
        margin,
    }
}

impl SpdBlocks {
    /// As a BSR matrix with every batch.
    pub fn bsr<R: Real>(&self) -> SparseMatrix<Mat3<R>>
    where
        Mat3<R>: Scalar,
    {
        let vals = self
            .values
            .iter()
            .flatten()
            .map(|m| Mat3::from_rows(m.map(|row| row.map(R::of))))
            .collect();
        SparseMatrix::from_values(self.pattern.clone(), self.values.len(), vals)
    }
    /// As a scalar CSR matrix (`3n x 3n`, the blocks expanded by hand) with every batch.
    pub fn scalar<R: Real>(&self) -> SparseMatrix<R> {
        let p = &self.pattern;
        let mut entries = Vec::new();
        for r in 0..self.n {
            for k in p.row_range(r) {
                let c = p.col_idx()[k] as usize;
                for i in 0..3 {
                    for j in 0..3 {
                        entries.push((3 * r + i, 3 * c + j));
                    }
                }
            }
        }
        let sp = SparsityPattern::from_entries(3 * self.n, 3 * self.n, entries);
        let mut vals = vec![R::ZERO; sp.nnz() * self.values.len()];
        for (b, bv) in self.values.iter().enumerate() {
            for r in 0..self.n {
                for k in p.row_range(r) {
                    let c = p.col_idx()[k] as usize;
                    for i in 0..3 {
                        for j in 0..3 {
                            let ks = sp.find(3 * r + i, 3 * c + j).expect("expanded entry");
                            vals[b * sp.nnz() + ks] = R::of(bv[k][i][j]);
                        }
                    }
                }
            }
        }
        SparseMatrix::from_values(sp, self.values.len(), vals)
    }
    /// Batch `b` as a dense `3n x 3n` faer matrix (naive expansion).
    pub fn dense(&self, b: usize) -> faer::Mat<f64> {
        let mut d = faer::Mat::<f64>::zeros(3 * self.n, 3 * self.n);
        for r in 0..self.n {
            for k in self.pattern.row_range(r) {
                let c = self.pattern.col_idx()[k] as usize;
                for i in 0..3 {
                    for j in 0..3 {
                        d[(3 * r + i, 3 * c + j)] = self.values[b][k][i][j];
                    }
                }
            }
        }
        d
    }
}

/// `A x` for a dense faer matrix and a plain vector, naive loops.
pub fn dense_mul(a: &faer::Mat<f64>, x: &[f64]) -> Vec<f64> {
    (0..a.nrows())
        .map(|i| (0..a.ncols()).map(|j| a[(i, j)] * x[j]).sum())
        .collect()
}

/// Solves `A x = b` with faer's dense partial-pivoting LU (the direct reference).
pub fn dense_solve(a: &faer::Mat<f64>, b: &[f64]) -> Vec<f64> {
    use faer::linalg::solvers::Solve;
    let rhs = faer::Mat::from_fn(b.len(), 1, |i, _| b[i]);
    let x = a.partial_piv_lu().solve(&rhs);
    (0..b.len()).map(|i| x[(i, 0)]).collect()
}

pub fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

pub fn diff_norm(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}
