//! Batched preconditioned CG and the sparse Cholesky against faer's dense LU solve, on random
//! SPD block-sparse systems (symmetric random patterns, strictly diagonally dominant, with a
//! Gershgorin bound `lambda_min >= margin` so that `|x - x*| <= |b - A x| / margin` is a
//! rigorous check). Each batch has its own values and right-hand side and converges on its
//! own (iteration counts per batch equal those of solving that batch alone). Covers Jacobi,
//! BlockJacobi, SparseCholesky and identity preconditioners, BSR and scalar CSR, `f32` and
//! `f64`, warm starts (the exact solution needs 0 iterations), and the failure values:
//! NotPositiveDefinite, NonFinite, NoConvergence, and the preconditioners' own errors.

mod common;

use common::*;
use gpumat::{
    cg, BlockJacobi, CgError, CgParams, Error, IdentityPreconditioner, Jacobi, Mat3, Matrix, Preconditioner,
    SparseCholesky, SparseMatrix, Vec3,
};
use proptest::prelude::*;

const TOL: f64 = 1e-10;

fn params(tol: f64) -> CgParams<f64> {
    CgParams {
        max_iterations: 1000,
        tolerance: tol,
        absolute_tolerance: 0.0,
    }
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

fn lanes_of<T: gpumat::Scalar>(x: &Matrix<T>, b: usize) -> Vec<f64> {
    lanes_f64(&Matrix::from_slice(x.rows(), 1, 1, x.batch(b)))
}

/// The residual of `x` in batch `b` is within the tolerance, and `x` is within the
/// Gershgorin bound of faer's direct solution.
#[track_caller]
fn check_solution<T: gpumat::Scalar>(sys: &SpdBlocks, rhs: &Matrix<T>, x: &Matrix<T>, tol: f64, what: &str) {
    for b in 0..rhs.batches() {
        let a = sys.dense(b);
        let (bv, xv) = (lanes_of(rhs, b), lanes_of(x, b));
        let direct = dense_solve(&a, &bv);
        let ax = dense_mul(&a, &xv);
        let res = diff_norm(&bv, &ax);
        assert!(
            res <= 2.0 * tol * norm(&bv),
            "{what}, batch {b}: residual {res:e} vs |b| {:e}",
            norm(&bv)
        );
        let err = diff_norm(&xv, &direct);
        let bound = res / sys.margin * 1.01 + 1e-12 * norm(&direct);
        assert!(err <= bound, "{what}, batch {b}: |x - x*| = {err:e} > {bound:e}");
    }
}

proptest! {
    #![proptest_config(config())]

    /// BSR systems with every block preconditioner; the exact (Cholesky) preconditioner
    /// converges in one or two iterations.
    #[test]
    fn bsr_cg_matches_direct_solve(seed in any::<u64>(), n in 1usize..20, nb in 1usize..4, density in 0.0f64..0.4) {
        let mut rng = Rand::new(seed);
        let sys = random_spd_blocks(&mut rng, n, nb, density, 1.0);
        let a = sys.bsr::<f64>();
        let rhs = random_rhs(&mut rng, n, nb);
        let jacobi = Jacobi::new(&a).unwrap();
        let block = BlockJacobi::new(&a).unwrap();
        let chol = SparseCholesky::new(&a).unwrap();
        let pre: [(&str, &dyn Preconditioner<Vec3<f64>>); 4] =
            [("identity", &IdentityPreconditioner), ("jacobi", &jacobi), ("block jacobi", &block), ("cholesky", &chol)];
        for (name, p) in pre {
            let mut x = Matrix::zeros(n, 1, nb);
            let info = cg(&a, &rhs, &mut x, p, &params(TOL)).unwrap_or_else(|e| panic!("{name}: {e}"));
            prop_assert!(info.converged.iter().all(|&c| c));
            prop_assert!(info.max_residual() <= TOL);
            prop_assert_eq!(info.iterations.len(), nb);
            check_solution(&sys, &rhs, &x, TOL, name);
            if name == "cholesky" {
                prop_assert!(info.max_iterations() <= 2, "exact preconditioner took {:?}", info.iterations);
            }
        }
        // The direct solver alone.
        let x = chol.solve(&rhs);
        check_solution(&sys, &rhs, &x, 1e-13, "SparseCholesky::solve");
    }

    /// The same systems expanded to scalar CSR (f64), and as f32 BSR with a looser tolerance.
    #[test]
    fn scalar_and_f32_cg(seed in any::<u64>(), n in 1usize..12, nb in 1usize..3) {
        let mut rng = Rand::new(seed);
        let sys = random_spd_blocks(&mut rng, n, nb, 0.3, 1.0);
        let a = sys.scalar::<f64>();
        let rhs = random_matrix::<f64>(&mut rng, (3 * n, 1, nb), -1.0, 1.0);
        let mut x = Matrix::zeros(3 * n, 1, nb);
        cg(&a, &rhs, &mut x, &Jacobi::new(&a).unwrap(), &params(TOL)).unwrap();
        check_solution(&sys, &rhs, &x, TOL, "scalar jacobi");
        let chol = SparseCholesky::new(&a).unwrap();
        check_solution(&sys, &rhs, &chol.solve(&rhs), 1e-13, "scalar cholesky");
        let mut x = Matrix::zeros(3 * n, 1, nb);
        let info = cg(&a, &rhs, &mut x, &chol, &params(TOL)).unwrap();
        prop_assert!(info.max_iterations() <= 2);
        // f32: the system rounded to f32; residuals measured in f64 against the f64 values.
        let a32 = sys.bsr::<f32>();
        let rhs32 = Matrix::from_fn(n, 1, nb, |r, _, b| Vec3::new(rhs.get(3 * r, 0, b) as f32, rhs.get(3 * r + 1, 0, b) as f32, rhs.get(3 * r + 2, 0, b) as f32));
        let mut x32 = Matrix::zeros(n, 1, nb);
        let p32 = CgParams { max_iterations: 1000, tolerance: 1e-4f32, absolute_tolerance: 0.0 };
        cg(&a32, &rhs32, &mut x32, &BlockJacobi::new(&a32).unwrap(), &p32).unwrap();
        check_solution(&sys, &rhs32, &x32, 1e-4, "f32 block jacobi");
        let x32c = SparseCholesky::new(&a32).unwrap().solve(&rhs32);
        // x rounded to f32 and A rounded to f32: relative residual ~ |A| eps_f32 <= 1e-5.
        check_solution(&sys, &rhs32, &x32c, 1e-5, "f32 cholesky");
    }

    /// Per-batch convergence: batch 0 is a multiple of the identity (one iteration), the
    /// others random; every batch takes exactly the iterations it takes alone and ends at
    /// exactly the same solution.
    #[test]
    fn batches_converge_independently(seed in any::<u64>(), n in 3usize..15) {
        let mut rng = Rand::new(seed);
        let nb = 3;
        let mut sys = random_spd_blocks(&mut rng, n, nb, 0.3, 1.0);
        for (k, v) in sys.values[0].iter_mut().enumerate() {
            let diag = sys.pattern.entry_rows()[k] == sys.pattern.col_idx()[k] as usize;
            *v = if diag { [[5.0, 0.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, 5.0]] } else { [[0.0; 3]; 3] };
        }
        let a = sys.bsr::<f64>();
        let rhs = random_rhs(&mut rng, n, nb);
        let mut x = Matrix::zeros(n, 1, nb);
        let info = cg(&a, &rhs, &mut x, &IdentityPreconditioner, &params(TOL)).unwrap();
        check_solution(&sys, &rhs, &x, TOL, "batched");
        prop_assert_eq!(info.iterations[0], 1);
        prop_assert!(info.iterations[1] > 1 && info.iterations[2] > 1, "{:?}", info.iterations);
        for b in 0..nb {
            let one = SpdBlocks { values: vec![sys.values[b].clone()], ..sys.clone() };
            let a1 = one.bsr::<f64>();
            let r1 = Matrix::from_slice(n, 1, 1, rhs.batch(b));
            let mut x1 = Matrix::zeros(n, 1, 1);
            let i1 = cg(&a1, &r1, &mut x1, &IdentityPreconditioner, &params(TOL)).unwrap();
            prop_assert_eq!(i1.iterations[0], info.iterations[b], "batch {}", b);
            prop_assert_eq!(x1.batch(0), x.batch(b), "batch {} solution", b);
        }
    }

    /// Warm start from the exact solution converges in 0 iterations and leaves x unchanged;
    /// a warm start from a nearby point needs fewer iterations than a cold start.
    #[test]
    fn warm_start(seed in any::<u64>(), n in 2usize..15, nb in 1usize..3) {
        let mut rng = Rand::new(seed);
        let sys = random_spd_blocks(&mut rng, n, nb, 0.3, 1.0);
        let a = sys.bsr::<f64>();
        let rhs = random_rhs(&mut rng, n, nb);
        let jacobi = Jacobi::new(&a).unwrap();
        let exact = Matrix::from_fn(n, 1, nb, |r, _, b| {
            let d = dense_solve(&sys.dense(b), &lanes_of(&rhs, b));
            Vec3::new(d[3 * r], d[3 * r + 1], d[3 * r + 2])
        });
        let mut x = exact.clone();
        let info = cg(&a, &rhs, &mut x, &jacobi, &params(1e-8)).unwrap();
        prop_assert_eq!(&info.iterations, &vec![0; nb]);
        prop_assert!(info.converged.iter().all(|&c| c));
        prop_assert_eq!(&x, &exact);
        let mut cold = Matrix::zeros(n, 1, nb);
        let ci = cg(&a, &rhs, &mut cold, &jacobi, &params(TOL)).unwrap();
        // Restarting from a converged solution (at a tolerance with room for the drift
        // between the recursive and the true residual) needs no iteration.
        let mut again = cold.clone();
        let wi = cg(&a, &rhs, &mut again, &jacobi, &params(10.0 * TOL)).unwrap();
        prop_assert_eq!(&wi.iterations, &vec![0; nb]);
        prop_assert!(ci.max_iterations() >= 1);
    }
}

/// Each preconditioner applies the inverse it claims: the inverse lane diagonal, the inverse
/// diagonal blocks, and the inverse of the whole matrix, per batch.
#[test]
fn preconditioners_apply_their_inverse() {
    let mut rng = Rand::new(12);
    let (n, nb) = (7, 2);
    let sys = random_spd_blocks(&mut rng, n, nb, 0.3, 1.0);
    let a = sys.bsr::<f64>();
    let r = random_rhs(&mut rng, n, nb);
    let mut z = Matrix::zeros(n, 1, nb);
    let jacobi = Jacobi::new(&a).unwrap();
    jacobi.apply(&r, &mut z);
    for b in 0..nb {
        let d = sys.dense(b);
        let (rv, zv) = (lanes_of(&r, b), lanes_of(&z, b));
        for i in 0..3 * n {
            assert_close(
                zv[i],
                rv[i] / d[(i, i)],
                2.0 * f64::EPSILON * zv[i].abs(),
                "jacobi",
            );
            let inv = jacobi.inverse_diagonal().get(i / 3, 0, b).to_array()[i % 3];
            assert_close(inv, 1.0 / d[(i, i)], f64::EPSILON * inv.abs(), "inverse diagonal");
        }
    }
    BlockJacobi::new(&a).unwrap().apply(&r, &mut z);
    for b in 0..nb {
        let d = sys.dense(b);
        let (rv, zv) = (lanes_of(&r, b), lanes_of(&z, b));
        for blk in 0..n {
            let db = faer::Mat::from_fn(3, 3, |i, j| d[(3 * blk + i, 3 * blk + j)]);
            let want = dense_solve(&db, &rv[3 * blk..3 * blk + 3]);
            assert_all_close(&zv[3 * blk..3 * blk + 3], &want, 1e-13, 1e-15, "block jacobi");
        }
    }
    SparseCholesky::new(&a).unwrap().apply(&r, &mut z);
    for b in 0..nb {
        let want = dense_solve(&sys.dense(b), &lanes_of(&r, b));
        assert_all_close(&lanes_of(&z, b), &want, 1e-12, 1e-14, "cholesky");
    }
}

fn two_batch_system(seed: u64, n: usize, negate_second: bool) -> (SpdBlocks, SparseMatrix<Mat3<f64>>) {
    let mut rng = Rand::new(seed);
    let mut sys = random_spd_blocks(&mut rng, n, 2, 0.3, 1.0);
    if negate_second {
        for v in sys.values[1].iter_mut() {
            *v = v.map(|r| r.map(|x| -x));
        }
    }
    let a = sys.bsr::<f64>();
    (sys, a)
}

#[test]
fn negative_definite_batch_is_reported() {
    let (_, a) = two_batch_system(1, 6, true);
    let rhs = random_rhs(&mut Rand::new(2), 6, 2);
    let mut x = Matrix::zeros(6, 1, 2);
    match cg(&a, &rhs, &mut x, &IdentityPreconditioner, &params(TOL)) {
        Err(CgError::NotPositiveDefinite {
            batch,
            iteration,
            curvature,
        }) => {
            assert_eq!((batch, iteration), (1, 0));
            assert!(curvature < 0.0);
        }
        other => panic!("expected NotPositiveDefinite, got {other:?}"),
    }
    // The direct solver refuses it too, naming the batch.
    match SparseCholesky::new(&a) {
        Err(Error::NotPositiveDefinite { batch, .. }) => assert_eq!(batch, 1),
        other => panic!("expected NotPositiveDefinite, got {other:?}"),
    }
    // And on refactoring a valid factorization with indefinite values.
    let (_, good) = two_batch_system(1, 6, false);
    let mut chol = SparseCholesky::new(&good).unwrap();
    assert!(matches!(
        chol.refactor(&a),
        Err(Error::NotPositiveDefinite { batch: 1, .. })
    ));
}

#[test]
fn indefinite_scalar_matrix() {
    // diag(2, -1, 3) with a coupling: indefinite. b = e_1 gives p.Ap < 0 at once.
    let a = SparseMatrix::<f64>::from_triplets(
        3,
        3,
        &[(0, 0, 2.0), (1, 1, -1.0), (2, 2, 3.0), (0, 2, 0.5), (2, 0, 0.5)],
    );
    let b = Matrix::column(&[0.0, 1.0, 0.0]);
    let mut x = Matrix::zeros(3, 1, 1);
    let r = cg(&a, &b, &mut x, &IdentityPreconditioner, &params(TOL));
    assert!(
        matches!(
            r,
            Err(CgError::NotPositiveDefinite {
                batch: 0,
                iteration: 0,
                ..
            })
        ),
        "{r:?}"
    );
    assert!(matches!(
        SparseCholesky::new(&a),
        Err(Error::NotPositiveDefinite { batch: 0, .. })
    ));
    assert!(matches!(
        SparseCholesky::new(&SparseMatrix::<f64>::from_triplets(2, 3, &[(0, 0, 1.0)])),
        Err(Error::NotSquare { rows: 2, cols: 3 })
    ));
}

#[test]
fn non_finite_right_hand_side() {
    let (_, a) = two_batch_system(3, 5, false);
    for bad in [f64::NAN, f64::INFINITY] {
        let mut rhs = random_rhs(&mut Rand::new(4), 5, 2);
        rhs.set(2, 0, 1, Vec3::new(1.0, bad, 0.0));
        let mut x = Matrix::zeros(5, 1, 2);
        let r = cg(&a, &rhs, &mut x, &Jacobi::new(&a).unwrap(), &params(TOL));
        assert!(
            matches!(
                r,
                Err(CgError::NonFinite {
                    batch: 1,
                    iteration: 0
                })
            ),
            "{bad}: {r:?}"
        );
    }
}

#[test]
fn iteration_limit_gives_no_convergence() {
    let (_, a) = two_batch_system(5, 12, false);
    let rhs = random_rhs(&mut Rand::new(6), 12, 2);
    let mut x = Matrix::zeros(12, 1, 2);
    let p = CgParams {
        max_iterations: 1,
        ..params(TOL)
    };
    match cg(&a, &rhs, &mut x, &Jacobi::new(&a).unwrap(), &p) {
        Err(CgError::NoConvergence { info }) => {
            assert_eq!(info.iterations, vec![1, 1]);
            assert_eq!(info.converged, vec![false, false]);
            assert!(info.max_residual() > TOL && info.max_residual().is_finite());
        }
        other => panic!("expected NoConvergence, got {other:?}"),
    }
    // Converges given room, from where it stopped.
    let info = cg(&a, &rhs, &mut x, &Jacobi::new(&a).unwrap(), &params(TOL)).unwrap();
    assert!(info.converged.iter().all(|&c| c));
}

#[test]
fn preconditioner_errors() {
    let no_diag = SparseMatrix::<f64>::from_triplets(2, 2, &[(0, 0, 1.0), (0, 1, 1.0), (1, 0, 1.0)]);
    assert_eq!(
        Jacobi::new(&no_diag).unwrap_err(),
        Error::MissingDiagonal { row: 1 }
    );
    let zero = SparseMatrix::<f64>::from_triplets(2, 2, &[(0, 0, 1.0), (1, 1, 0.0)]);
    assert_eq!(
        Jacobi::new(&zero).unwrap_err(),
        Error::SingularDiagonal { row: 1, batch: 0 }
    );
    let rect = SparseMatrix::<f64>::from_triplets(2, 3, &[(0, 0, 1.0), (1, 1, 1.0)]);
    assert_eq!(
        Jacobi::new(&rect).unwrap_err(),
        Error::NotSquare { rows: 2, cols: 3 }
    );
    // A singular diagonal block in the second batch: lanes non-zero, block singular.
    let p = gpumat::SparsityPattern::from_entries(2, 2, [(0, 0), (1, 1)]);
    let ones = Mat3::from_rows([[1.0; 3]; 3]);
    let vals = vec![Mat3::identity(), Mat3::identity(), Mat3::identity(), ones];
    let a = SparseMatrix::<Mat3<f64>>::from_values(p, 2, vals);
    assert!(Jacobi::new(&a).is_ok());
    assert_eq!(
        BlockJacobi::new(&a).unwrap_err(),
        Error::SingularDiagonal { row: 1, batch: 1 }
    );
}

/// One factorization serves several right-hand sides; refactor takes new values.
#[test]
fn cholesky_refactor_and_shared_factor() {
    let mut rng = Rand::new(8);
    let sys = random_spd_blocks(&mut rng, 10, 2, 0.3, 1.0);
    let first = SpdBlocks {
        values: vec![sys.values[0].clone()],
        ..sys.clone()
    };
    let second = SpdBlocks {
        values: vec![sys.values[1].clone()],
        ..sys.clone()
    };
    let mut chol = SparseCholesky::new(&first.bsr::<f64>()).unwrap();
    assert_eq!(chol.batches(), 1);
    let rhs = random_rhs(&mut rng, 10, 3);
    let x = chol.solve(&rhs);
    let three = SpdBlocks {
        values: vec![sys.values[0].clone(); 3],
        ..sys.clone()
    };
    check_solution(&three, &rhs, &x, 1e-13, "shared factor");
    chol.refactor(&second.bsr::<f64>()).unwrap();
    let three = SpdBlocks {
        values: vec![sys.values[1].clone(); 3],
        ..sys.clone()
    };
    check_solution(&three, &rhs, &chol.solve(&rhs), 1e-13, "refactored");
}
