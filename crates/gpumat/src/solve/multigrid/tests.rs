//! The multigrid's maths: iterations that do not grow with the lattice, a symmetric cycle,
//! Galerkin products equal to dense ones, results independent of the thread count.

use super::*;
use crate::solve::{cg, BlockJacobi, CgParams};

/// A coupling block, symmetric positive definite.
fn coupling() -> Mat3<f64> {
    Mat3::from_rows([[2.0, 0.5, 0.0], [0.5, 1.5, 0.3], [0.0, 0.3, 1.0]])
}

/// `L (x) C` with `L` the 27-point trilinear (Q1) finite-element Laplacian of an `n^3` lattice
/// of nodes held at zero outside, plus `shift C` on the diagonal.
fn laplacian(n: usize, shift: f64) -> SparseMatrix<Mat3<f64>> {
    let c = coupling();
    let idx = |i: usize, j: usize, k: usize| i + n * (j + n * k);
    let mut t = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                for dk in -1i64..=1 {
                    for dj in -1i64..=1 {
                        for di in -1i64..=1 {
                            let (a, b, q) = (i as i64 + di, j as i64 + dj, k as i64 + dk);
                            if [a, b, q].iter().any(|&v| v < 0 || v >= n as i64) {
                                continue;
                            }
                            let far = di.abs() + dj.abs() + dk.abs();
                            let w = match far {
                                0 => 8.0 / 3.0 + shift,
                                1 => 0.0,
                                2 => -1.0 / 6.0,
                                _ => -1.0 / 12.0,
                            };
                            if w != 0.0 {
                                t.push((idx(i, j, k), idx(a as usize, b as usize, q as usize), c * w));
                            }
                        }
                    }
                }
            }
        }
    }
    SparseMatrix::from_triplets(n * n * n, n * n * n, &t)
}

/// Reproducible values in [-1, 1).
fn noise(len: usize, seed: u64) -> Matrix<Vec3<f64>> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    };
    Matrix::from_fn(len, 1, 1, |_, _, _| Vec3::new(next(), next(), next()))
}

fn hierarchy(n: usize, a: &SparseMatrix<Mat3<f64>>, params: MultigridParams) -> Multigrid {
    let nodes: Vec<usize> = (0..n * n * n).collect();
    Multigrid::new(a, lattice_prolongations([n, n, n], &nodes, &params), params).unwrap()
}

fn dot(x: &Matrix<Vec3<f64>>, y: &Matrix<Vec3<f64>>) -> f64 {
    x.as_slice()
        .iter()
        .zip(y.as_slice())
        .map(|(a, b)| a.dot(*b))
        .sum()
}

/// (a) PCG iterations to 1e-8 with the default V(3,3) cycle stay flat from 8^3 to 32^3 nodes, while
/// block-Jacobi's grow like `n`.
#[test]
fn multigrid_iterations_do_not_grow_with_the_lattice() {
    let params = MultigridParams {
        max_coarse: 100,
        ..Default::default()
    };
    let cgp = CgParams {
        max_iterations: 2000,
        tolerance: 1e-8,
        absolute_tolerance: 0.0,
    };
    let mut mg_its = Vec::new();
    let mut bj_its = Vec::new();
    for n in [8, 16, 32] {
        let a = laplacian(n, 0.0);
        let mg = hierarchy(n, &a, params);
        let b = noise(a.rows(), n as u64);
        let mut x = Matrix::zeros(a.rows(), 1, 1);
        let info = cg(&a, &b, &mut x, &mg.preconditioner(&a), &cgp).unwrap();
        let jacobi = MultigridParams {
            smoother: Smoother::Jacobi,
            ..params
        };
        let mut xj = Matrix::zeros(a.rows(), 1, 1);
        let mgj = hierarchy(n, &a, jacobi);
        let ij = cg(&a, &b, &mut xj, &mgj.preconditioner(&a), &cgp).unwrap();
        println!(
            "n = {n}: lambda_max(D^-1 A) per level {:.3?}; block-Jacobi-smoothed (omega {}) multigrid {} iterations",
            mg.lambda_max(),
            jacobi.omega,
            ij.iterations[0]
        );
        let mut y = Matrix::zeros(a.rows(), 1, 1);
        let bj = cg(&a, &b, &mut y, &BlockJacobi::new(&a).unwrap(), &cgp).unwrap();
        println!(
            "n = {n}: levels {:?}, Chebyshev multigrid {} iterations, block-Jacobi {}",
            mg.level_rows(),
            info.iterations[0],
            bj.iterations[0]
        );
        mg_its.push(info.iterations[0] as f64);
        bj_its.push(bj.iterations[0] as f64);
    }
    let (lo, hi) = mg_its
        .iter()
        .fold((f64::MAX, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    assert!(hi / lo <= 1.5, "multigrid iterations {mg_its:?}");
    assert!(hi <= 20.0, "multigrid iterations {mg_its:?}");
    assert!(
        bj_its[2] >= 4.0 * hi,
        "block-Jacobi {bj_its:?}, multigrid {mg_its:?}"
    );
}

/// (b) `x . M y = y . M x` to 1e-12 relative.
#[test]
fn multigrid_cycle_is_symmetric() {
    let n = 12;
    let a = laplacian(n, 0.01);
    let params = MultigridParams {
        max_coarse: 30,
        sweeps: 3,
        ..Default::default()
    };
    let mg = hierarchy(n, &a, params);
    assert!(mg.levels() >= 3, "{:?}", mg.level_rows());
    let m = mg.preconditioner(&a);
    for seed in 1..4 {
        let (x, y) = (noise(a.rows(), seed), noise(a.rows(), 100 + seed));
        let (mut mx, mut my) = (Matrix::zeros(a.rows(), 1, 1), Matrix::zeros(a.rows(), 1, 1));
        m.apply(&x, &mut mx);
        m.apply(&y, &mut my);
        let (xmy, ymx) = (dot(&x, &my), dot(&y, &mx));
        let rel = (xmy - ymx).abs() / xmy.abs().max(ymx.abs());
        println!("x.My = {xmy:.15e}, y.Mx = {ymx:.15e}, relative difference {rel:.2e}");
        assert!(rel <= 1e-12, "{xmy} vs {ymx}");
        assert!(dot(&x, &mx) > 0.0);
    }
}

/// (c) The Galerkin operators equal dense `P^T A P`, level by level.
#[test]
fn galerkin_products_equal_dense_triple_products() {
    let n = 7;
    let mut a = laplacian(n, 0.3);
    // unequal values: each block scaled by its position
    let pat = a.pattern().clone();
    let rows = pat.entry_rows();
    for (e, v) in a.values_mut().iter_mut().enumerate() {
        let (r, c) = (rows[e], pat.col_idx()[e] as usize);
        *v = *v * (1.0 + 0.01 * ((r * c) % 7) as f64 + 0.02 * (r + c) as f64 / n as f64);
    }
    let params = MultigridParams {
        max_coarse: 5,
        ..Default::default()
    };
    let mg = hierarchy(n, &a, params);
    assert!(mg.levels() >= 3, "{:?}", mg.level_rows());
    let mut fine = a.to_dense(0);
    for (l, level) in mg.levels.iter().enumerate() {
        let p = level.p.to_dense(0);
        let (nf, nc) = (p.rows(), p.cols());
        let want = |i: usize, j: usize| {
            let mut s = Mat3::default();
            for k in 0..nf {
                for m in 0..nf {
                    let w = p.get(k, i, 0) * p.get(m, j, 0);
                    if w != 0.0 {
                        s = s + fine.get(k, m, 0) * w;
                    }
                }
            }
            s
        };
        let got = mg.coarse[l].to_dense(0);
        let mut worst = 0.0f64;
        let mut scale = 0.0f64;
        let mut dense = Matrix::zeros(nc, nc, 1);
        for i in 0..nc {
            for j in 0..nc {
                let w = want(i, j);
                dense.set(i, j, 0, w);
                let d = got.get(i, j, 0) - w;
                worst = worst.max(d.m.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs())));
                scale = scale.max(w.m.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs())));
            }
        }
        println!(
            "level {}: {nc} coarse rows, max |RAP - dense| = {worst:.2e} (scale {scale:.2e})",
            l + 1
        );
        assert!(worst <= 1e-13 * scale, "level {}: {worst}", l + 1);
        fine = dense;
    }
}

/// The cycle gives the same bits on 1 and 3 threads, and `refresh` with new values gives the
/// hierarchy built from them.
#[test]
fn multigrid_is_thread_independent_and_refreshes() {
    let n = 14;
    let a = laplacian(n, 0.0);
    let params = MultigridParams {
        max_coarse: 40,
        ..Default::default()
    };
    let r = noise(a.rows(), 7);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mg = hierarchy(n, &a, params);
            let mut z = Matrix::zeros(a.rows(), 1, 1);
            mg.preconditioner(&a).apply(&r, &mut z);
            z
        })
    };
    let (one, three) = (run(1), run(3));
    assert!(one.as_slice().iter().zip(three.as_slice()).all(|(p, q)| p == q));
    // refresh from other values = a fresh hierarchy of them
    let b = laplacian(n, 0.5);
    let mut mg = hierarchy(n, &a, params);
    mg.refresh(&b).unwrap();
    let fresh = hierarchy(n, &b, params);
    let (mut z1, mut z2) = (Matrix::zeros(a.rows(), 1, 1), Matrix::zeros(a.rows(), 1, 1));
    mg.preconditioner(&b).apply(&r, &mut z1);
    fresh.preconditioner(&b).apply(&r, &mut z2);
    assert_eq!(z1.as_slice(), z2.as_slice());
}
