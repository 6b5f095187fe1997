//! Block incomplete Cholesky (`BlockIc0`, plain, shifted and relaxed-modified) against a naive
//! dense f64 reference of the same algorithm written the other way round (right-looking over
//! dense 3x3 blocks, restricted to the block pattern), the exact case of a full pattern
//! against faer's dense LU, CG with it on a 3D grid block Laplacian (fewer iterations than
//! block-Jacobi), f32, batches and the errors. Also the nested-dissection ordering of the
//! sparse Cholesky factor (a valid permutation, the same solution, less fill than the natural
//! order on a grid).

mod common;

use common::*;
use gpumat::{
    cg, nested_dissection, BlockIc0, BlockJacobi, CgParams, Error, Ic0Params, Mat3, Matrix, Preconditioner,
    SparseCholesky, SparseMatrix, SparsityPattern, Vec3,
};
use proptest::prelude::*;

type B = [[f64; 3]; 3];

fn mul(a: &B, b: &B) -> B {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}
fn tr(a: &B) -> B {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}
fn sub(a: &B, b: &B) -> B {
    std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] - b[i][j]))
}
fn inv(a: &B) -> B {
    let m = faer::Mat::from_fn(3, 3, |i, j| a[i][j]);
    let x = dense_inverse(&m);
    std::array::from_fn(|i| std::array::from_fn(|j| x[(i, j)]))
}
fn dense_inverse(m: &faer::Mat<f64>) -> faer::Mat<f64> {
    use faer::linalg::solvers::Solve;
    m.partial_piv_lu()
        .solve(faer::Mat::<f64>::identity(m.nrows(), m.nrows()))
}

/// The preconditioner matrix `M = (D + U^T) D^-1 (D + U)` of the incomplete factorization of
/// batch `b`, dense, by the right-looking algorithm: eliminating row `k` updates every pair
/// `(i, j)`, `k < i <= j`, coupled to `k`; an update outside the pattern is dropped, or, scaled
/// by `relaxation` and symmetrized, moved onto the pivots of `i` and `j`.
fn reference_m(sys: &SpdBlocks, b: usize, params: Ic0Params) -> faer::Mat<f64> {
    let n = sys.n;
    let p = &sys.pattern;
    let mut mask = vec![vec![false; n]; n];
    let mut w = vec![vec![[[0.0; 3]; 3]; n]; n];
    for i in 0..n {
        for k in p.row_range(i) {
            let j = p.col_idx()[k] as usize;
            mask[i][j] = true;
            w[i][j] = sys.values[b][k];
        }
        for l in 0..3 {
            w[i][i][l][l] *= 1.0 + params.shift;
        }
    }
    for k in 0..n {
        let dk = inv(&w[k][k]);
        for i in k + 1..n {
            if !mask[k][i] {
                continue;
            }
            let left = mul(&tr(&w[k][i]), &dk);
            for j in i..n {
                if !mask[k][j] {
                    continue;
                }
                let f = mul(&left, &w[k][j]);
                if mask[i][j] {
                    w[i][j] = sub(&w[i][j], &f);
                } else {
                    let g: B = std::array::from_fn(|r| {
                        std::array::from_fn(|c| 0.5 * params.relaxation * (f[r][c] + f[c][r]))
                    });
                    w[i][i] = sub(&w[i][i], &g);
                    w[j][j] = sub(&w[j][j], &g);
                }
            }
        }
    }
    // M = (D + U^T) D^-1 (D + U)
    let mut lower = faer::Mat::<f64>::zeros(3 * n, 3 * n);
    let mut upper = faer::Mat::<f64>::zeros(3 * n, 3 * n);
    let mut dinv = faer::Mat::<f64>::zeros(3 * n, 3 * n);
    for i in 0..n {
        let di = inv(&w[i][i]);
        for j in i..n {
            if !mask[i][j] {
                continue;
            }
            for r in 0..3 {
                for c in 0..3 {
                    upper[(3 * i + r, 3 * j + c)] = w[i][j][r][c];
                    lower[(3 * j + c, 3 * i + r)] = w[i][j][r][c];
                    if i == j {
                        dinv[(3 * i + r, 3 * i + c)] = di[r][c];
                    }
                }
            }
        }
    }
    &lower * &dinv * &upper
}

fn random_rhs(rng: &mut Rand, n: usize, nb: usize) -> Matrix<Vec3<f64>> {
    Matrix::from_fn(n, 1, nb, |_, _, _| {
        Vec3::new(
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
        )
    })
}

fn batch_lanes(x: &Matrix<Vec3<f64>>, b: usize) -> Vec<f64> {
    lanes_f64(&Matrix::from_slice(x.rows(), 1, 1, x.batch(b)))
}

proptest! {
    #![proptest_config(config())]

    /// `M z = r` for `z = BlockIc0::apply(r)`, with `M` from the dense reference, for plain,
    /// relaxed-modified and shifted factorizations; every batch has its own factor.
    #[test]
    fn ic0_matches_dense_reference(seed in any::<u64>(), n in 1usize..14, nb in 1usize..3, density in 0.0f64..0.5) {
        let mut rng = Rand::new(seed);
        let sys = random_spd_blocks(&mut rng, n, nb, density, 1.0);
        let a = sys.bsr::<f64>();
        let r = random_rhs(&mut rng, n, nb);
        for params in [
            Ic0Params::default(),
            Ic0Params { shift: 0.0, relaxation: 0.95 },
            Ic0Params { shift: 0.1, relaxation: 1.0 },
        ] {
            let ic = BlockIc0::with_params(&a, params).unwrap();
            prop_assert_eq!(ic.batches(), nb);
            let mut z = Matrix::zeros(n, 1, nb);
            ic.apply(&r, &mut z);
            for b in 0..nb {
                let m = reference_m(&sys, b, params);
                let (zb, rb) = (batch_lanes(&z, b), batch_lanes(&r, b));
                let res = diff_norm(&dense_mul(&m, &zb), &rb);
                prop_assert!(res <= 1e-12 * norm(&rb).max(1.0), "{params:?} batch {b}: |M z - r| = {res:e}");
            }
        }
    }

    /// With every block stored (no dropped fill), IC(0) is the exact block Cholesky: the
    /// preconditioner is `A^-1`, whatever the relaxation.
    #[test]
    fn ic0_on_full_pattern_is_exact(seed in any::<u64>(), n in 1usize..10) {
        let mut rng = Rand::new(seed);
        let sys = random_spd_blocks(&mut rng, n, 1, 1.0, 1.0);
        let a = sys.bsr::<f64>();
        let r = random_rhs(&mut rng, n, 1);
        let ic = BlockIc0::with_params(&a, Ic0Params { shift: 0.0, relaxation: 1.0 }).unwrap();
        let mut z = Matrix::zeros(n, 1, 1);
        ic.apply(&r, &mut z);
        let want = dense_solve(&sys.dense(0), &batch_lanes(&r, 0));
        let err = diff_norm(&batch_lanes(&z, 0), &want);
        prop_assert!(err <= 1e-10 * norm(&want), "|z - A^-1 r| = {err:e}");
    }
}

/// The block Laplacian of a `g^3` grid with the 27-point stencil (coupling `-C` between
/// neighbours, the neighbour count plus `shift` times the coupling on the diagonal: a
/// Neumann Laplacian made definite by the shift), node coordinates.
fn grid_laplacian(g: usize, shift: f64) -> (SparseMatrix<Mat3<f64>>, Vec<[f64; 3]>) {
    let idx = |i: usize, j: usize, k: usize| i + g * (j + g * k);
    let mut trip = Vec::new();
    let mut coords = Vec::new();
    let couple = Mat3::from_rows([[1.0, 0.2, 0.0], [0.2, 1.0, 0.1], [0.0, 0.1, 1.0]]);
    for k in 0..g {
        for j in 0..g {
            for i in 0..g {
                coords.push([i as f64, j as f64, k as f64]);
                let me = idx(i, j, k);
                let mut deg = 0.0;
                for dk in -1i64..=1 {
                    for dj in -1i64..=1 {
                        for di in -1i64..=1 {
                            let (ni, nj, nk) = (i as i64 + di, j as i64 + dj, k as i64 + dk);
                            if (di, dj, dk) == (0, 0, 0) || ni < 0 || nj < 0 || nk < 0 {
                                continue;
                            }
                            let (ni, nj, nk) = (ni as usize, nj as usize, nk as usize);
                            if ni >= g || nj >= g || nk >= g {
                                continue;
                            }
                            trip.push((me, idx(ni, nj, nk), couple * -1.0));
                            deg += 1.0;
                        }
                    }
                }
                trip.push((me, me, couple * (deg + shift)));
            }
        }
    }
    (SparseMatrix::from_triplets(g * g * g, g * g * g, &trip), coords)
}

/// On a grid, CG with IC(0) and with the relaxed modified IC(0) needs at least a third fewer
/// iterations than with block-Jacobi; all reach the same solution; f32 works too.
#[test]
fn ic0_cg_on_grid_laplacian() {
    let (a, _) = grid_laplacian(10, 0.01);
    let n = a.rows();
    let mut rng = Rand::new(3);
    let rhs = random_rhs(&mut rng, n, 1);
    let params = CgParams {
        max_iterations: 2000,
        tolerance: 1e-10,
        absolute_tolerance: 0.0,
    };
    let solve = |p: &dyn Preconditioner<Vec3<f64>>| {
        let mut x = Matrix::zeros(n, 1, 1);
        let info = cg(&a, &rhs, &mut x, p, &params).unwrap();
        (info.iterations[0], x)
    };
    let (bj, x_bj) = solve(&BlockJacobi::new(&a).unwrap());
    let (ic, x_ic) = solve(&BlockIc0::new(&a).unwrap());
    let mic = BlockIc0::with_params(
        &a,
        Ic0Params {
            shift: 0.0,
            relaxation: 0.95,
        },
    )
    .unwrap();
    let (mi, x_mi) = solve(&mic);
    assert!(
        3 * ic < 2 * bj && 3 * mi < 2 * bj,
        "iterations: block-Jacobi {bj}, IC(0) {ic}, MIC(0.95) {mi}"
    );
    for x in [&x_ic, &x_mi] {
        let d = Matrix::eval(x.ex() - x_bj.ex()).ex().norm();
        assert!(d <= 1e-7 * x_bj.ex().norm(), "solutions differ by {d:e}");
    }
    // f32
    let a32 = SparseMatrix::from_values(
        a.pattern().clone(),
        1,
        a.values()
            .iter()
            .map(|m| Mat3::from_rows(m.m.map(|r| r.map(|x| x as f32))))
            .collect(),
    );
    let rhs32 = Matrix::from_fn(n, 1, 1, |r, _, _| {
        let v = rhs.get(r, 0, 0);
        Vec3::new(v.x as f32, v.y as f32, v.z as f32)
    });
    let mut x32 = Matrix::zeros(n, 1, 1);
    let p32 = CgParams {
        max_iterations: 2000,
        tolerance: 1e-5f32,
        absolute_tolerance: 0.0,
    };
    let info = cg(&a32, &rhs32, &mut x32, &BlockIc0::new(&a32).unwrap(), &p32).unwrap();
    assert!(
        info.iterations[0] <= ic + 5,
        "f32 IC(0) took {:?}",
        info.iterations
    );
}

/// A single factor serves every batch of the right-hand side.
#[test]
fn ic0_single_factor_serves_batches() {
    let mut rng = Rand::new(5);
    let sys = random_spd_blocks(&mut rng, 9, 1, 0.3, 1.0);
    let a = sys.bsr::<f64>();
    let ic = BlockIc0::new(&a).unwrap();
    let r = random_rhs(&mut rng, 9, 3);
    let mut z = Matrix::zeros(9, 1, 3);
    ic.apply(&r, &mut z);
    for b in 0..3 {
        let one = Matrix::from_slice(9, 1, 1, r.batch(b));
        let mut zb = Matrix::zeros(9, 1, 1);
        ic.apply(&one, &mut zb);
        assert_eq!(zb.batch(0), z.batch(b));
    }
}

#[test]
fn ic0_errors() {
    let p = SparsityPattern::from_entries(2, 2, [(0, 0), (0, 1), (1, 0)]);
    let a = SparseMatrix::<Mat3<f64>>::from_values(p, 1, vec![Mat3::identity(); 3]);
    assert_eq!(BlockIc0::new(&a).unwrap_err(), Error::MissingDiagonal { row: 1 });
    let rect = SparseMatrix::<Mat3<f64>>::from_triplets(1, 2, &[(0, 0, Mat3::identity())]);
    assert!(matches!(BlockIc0::new(&rect), Err(Error::NotSquare { .. })));
    // indefinite: the second pivot block has a negative leading lane
    let a = SparseMatrix::from_triplets(
        2,
        2,
        &[
            (0, 0, Mat3::identity()),
            (1, 1, Mat3::from_diagonal(Vec3::new(1.0, -1.0, 1.0))),
        ],
    );
    assert_eq!(
        BlockIc0::new(&a).unwrap_err(),
        Error::NotPositiveDefinite { batch: 0, pivot: 4 }
    );
}

/// Nested dissection: a permutation, the same solution as AMD, less fill than the natural
/// order on a grid; bad orders are errors.
#[test]
fn nested_dissection_ordering() {
    let (a, coords) = grid_laplacian(9, 1.0);
    let n = a.rows();
    let order = nested_dissection(a.pattern(), &coords);
    let mut seen = vec![false; n];
    for &o in &order {
        assert!(!seen[o], "row {o} twice");
        seen[o] = true;
    }
    assert!(seen.iter().all(|&s| s));
    let natural: Vec<usize> = (0..n).collect();
    let nd = SparseCholesky::with_ordering(&a, Some(&order)).unwrap();
    let nat = SparseCholesky::with_ordering(&a, Some(&natural)).unwrap();
    let amd = SparseCholesky::new(&a).unwrap();
    assert!(
        nd.factor_nnz() < nat.factor_nnz(),
        "fill: nested dissection {}, natural {}",
        nd.factor_nnz(),
        nat.factor_nnz()
    );
    let mut rng = Rand::new(9);
    let rhs = random_rhs(&mut rng, n, 1);
    let (x_nd, x_amd) = (nd.solve(&rhs), amd.solve(&rhs));
    let d = Matrix::eval(x_nd.ex() - x_amd.ex()).ex().norm();
    assert!(d <= 1e-12 * x_amd.ex().norm(), "orders disagree by {d:e}");
    let r = Matrix::eval(&rhs - &a * &x_nd).ex().norm();
    assert!(r <= 1e-12 * rhs.ex().norm());
    assert!(matches!(
        SparseCholesky::with_ordering(&a, Some(&natural[1..])),
        Err(Error::Factorization(_))
    ));
    let mut twice = natural.clone();
    twice[1] = 0;
    assert!(matches!(
        SparseCholesky::with_ordering(&a, Some(&twice)),
        Err(Error::Factorization(_))
    ));
}
