//! The benchmark inputs, built identically here, in the Eigen programs (`eigen/common.hpp`) and
//! in the numpy script (`python/lincomb.py`): a counter-based splitmix64 generator, random
//! vectors, the 5-point 2D Poisson matrix and the CG right-hand side.

use gpumat::{Matrix, SparseMatrix, SparsityPattern};

/// Seed of the CG right-hand side (thesis / cuMat: `srand(42)`).
pub const RHS_SEED: u64 = 42;
/// Seed of the SpMV input vector.
pub const SPMV_X_SEED: u64 = 3;
/// Seed of the linear-combination factors.
pub const FACTOR_SEED: u64 = 7;
/// Seed of linear-combination vector `i` is `VECTOR_SEED + i`.
pub const VECTOR_SEED: u64 = 1000;

/// Counter-based splitmix64: the `i`-th output of the splitmix64 sequence started at `seed`
/// (`state_i = seed + (i + 1) * golden`, then the splitmix finaliser). Counter-based, so the
/// same numbers come out of a sequential loop, a parallel loop or numpy's vector arithmetic.
#[inline]
pub fn splitmix64(seed: u64, i: u64) -> u64 {
    let mut z = seed.wrapping_add(i.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A float in `[0, 1)` from the top 24 bits of `splitmix64(seed, i)` (exact in f32).
#[inline]
pub fn uniform01(seed: u64, i: u64) -> f32 {
    (splitmix64(seed, i) >> 40) as f32 * (1.0 / 16_777_216.0)
}

/// A float in `[-1, 1)`.
#[inline]
pub fn uniform_pm1(seed: u64, i: u64) -> f32 {
    2.0 * uniform01(seed, i) - 1.0
}

/// The `n x 1` vector of [`uniform_pm1`] values.
pub fn random_vector(seed: u64, n: usize) -> Matrix<f32> {
    Matrix::from_fn(n, 1, 1, |r, _, _| uniform_pm1(seed, r as u64))
}

/// Linear-combination operands: vectors `v_i` (seed `VECTOR_SEED + i`) and factors `alpha_i`
/// in `[0, 1)` (seed `FACTOR_SEED`, index `i`), as in cuMat's benchmark.
pub fn lincomb_inputs(n: usize, k: usize) -> (Vec<Matrix<f32>>, Vec<f32>) {
    let vs = (0..k).map(|i| random_vector(VECTOR_SEED + i as u64, n)).collect();
    let alphas = (0..k).map(|i| uniform01(FACTOR_SEED, i as u64)).collect();
    (vs, alphas)
}

/// CSR arrays of the 5-point Laplacian on a `g x g` grid with Dirichlet boundary (neighbours
/// outside the grid are dropped): 4 on the diagonal, -1 for each neighbour. Node `(x, y)` is
/// row `y + x g` (cuMat's `IDX`); columns are sorted.
pub fn poisson_csr(g: usize) -> (Vec<usize>, Vec<usize>, Vec<f32>) {
    let n = g * g;
    let mut row_ptr = Vec::with_capacity(n + 1);
    let mut col_idx = Vec::with_capacity(5 * n);
    let mut values = Vec::with_capacity(5 * n);
    row_ptr.push(0);
    for x in 0..g {
        for y in 0..g {
            let row = y + x * g;
            let mut push = |c: usize, v: f32| {
                col_idx.push(c);
                values.push(v);
            };
            if x > 0 {
                push(row - g, -1.0);
            }
            if y > 0 {
                push(row - 1, -1.0);
            }
            push(row, 4.0);
            if y + 1 < g {
                push(row + 1, -1.0);
            }
            if x + 1 < g {
                push(row + g, -1.0);
            }
            row_ptr.push(col_idx.len());
        }
    }
    (row_ptr, col_idx, values)
}

/// The Poisson matrix of [`poisson_csr`] as a gpumat sparse matrix (one batch).
pub fn poisson_matrix(g: usize) -> SparseMatrix<f32> {
    let (row_ptr, col_idx, values) = poisson_csr(g);
    let n = g * g;
    let pattern = SparsityPattern::new(n, n, row_ptr, col_idx).expect("the Poisson pattern is valid CSR");
    SparseMatrix::from_values(pattern, 1, values)
}

/// Stored entries of the `g x g` Poisson matrix: `5 g^2 - 4 g`.
pub fn poisson_nnz(g: usize) -> usize {
    5 * g * g - 4 * g
}

/// The CG right-hand side: `uniform01(RHS_SEED, node)` on boundary nodes, zero inside.
pub fn boundary_rhs(g: usize) -> Matrix<f32> {
    Matrix::from_fn(g * g, 1, 1, |row, _, _| {
        let (x, y) = (row / g, row % g);
        if x == 0 || y == 0 || x + 1 == g || y + 1 == g {
            uniform01(RHS_SEED, row as u64)
        } else {
            0.0
        }
    })
}

/// Sum of the elements in f64 (the checksum the peers print too).
pub fn checksum(v: &[f32]) -> f64 {
    v.iter().map(|&x| x as f64).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix_matches_the_reference_sequence() {
        // splitmix64 seeded with 0: first output 0xE220A8397B1DCDAF (Vigna's reference).
        assert_eq!(splitmix64(0, 0), 0xE220_A839_7B1D_CDAF);
        assert!((0..1000).all(|i| (0.0..1.0).contains(&uniform01(42, i))));
    }

    #[test]
    fn poisson_is_symmetric_with_expected_nnz() {
        for g in [1, 2, 5] {
            let a = poisson_matrix(g);
            assert_eq!(a.nnz(), poisson_nnz(g));
            let d = a.to_dense(0);
            for r in 0..g * g {
                for c in 0..g * g {
                    assert_eq!(d.get(r, c, 0), d.get(c, r, 0));
                }
            }
        }
    }
}
