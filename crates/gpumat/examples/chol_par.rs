//! Sequential against parallel (faer's rayon) numeric Cholesky factorization of 3D 27-point
//! 3x3-block matrices (a grid's elasticity pattern) of growing size: the measurement behind
//! `gpumat::solve::PARALLEL_FACTOR_ENTRIES`, and whether the two give the same solution bits
//! (they did at every size measured: the threshold changes no result). Run with
//! `cargo run --release -p gpumat --example chol_par`.

use gpumat::{solve::SparseCholesky, Mat3, SparseMatrix};
use std::time::Instant;
fn main() {
    for n in [8usize, 12, 16, 20, 26] {
        let idx = |i: usize, j: usize, k: usize| i + n * (j + n * k);
        let mut t = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let r = idx(i, j, k);
                    for dk in -1i64..=1 {
                        for dj in -1i64..=1 {
                            for di in -1i64..=1 {
                                let (a, b, c) = (i as i64 + di, j as i64 + dj, k as i64 + dk);
                                if a < 0 || b < 0 || c < 0 || a >= n as i64 || b >= n as i64 || c >= n as i64
                                {
                                    continue;
                                }
                                let col = idx(a as usize, b as usize, c as usize);
                                let m = if col == r {
                                    Mat3::from_scalar(30.0)
                                        + Mat3::from_rows([[1.0, 0.1, 0.0], [0.1, 1.0, 0.0], [0.0, 0.0, 1.0]])
                                } else {
                                    Mat3::from_scalar(-1.0)
                                };
                                t.push((r, col, m));
                            }
                        }
                    }
                }
            }
        }
        let rows = n * n * n;
        let a = SparseMatrix::from_triplets(rows, rows, &t);
        let mut c = SparseCholesky::analyse(&a, None).unwrap();
        let (mut res, mut sols) = (Vec::new(), Vec::new());
        for parallel in [false, true] {
            c.refactor_on(&a, parallel).unwrap();
            let mut best = f64::INFINITY;
            for _ in 0..5 {
                let s = Instant::now();
                c.refactor_on(&a, parallel).unwrap();
                best = best.min(s.elapsed().as_secs_f64());
            }
            res.push(best);
            let mut x = gpumat::Matrix::from_fn(rows, 1, 1, |r, _, _| {
                gpumat::Vec3::new((r as f64).sin(), 1.0, (0.3 * r as f64).cos())
            });
            c.solve_in_place(&mut x);
            sols.push(x);
        }
        println!(
            "nodes {rows} factor entries {} seq {:.3} ms rayon {:.3} ms, same solution bits: {}",
            c.factor_nnz(),
            res[0] * 1e3,
            res[1] * 1e3,
            sols[0].as_slice() == sols[1].as_slice()
        );
    }
}
