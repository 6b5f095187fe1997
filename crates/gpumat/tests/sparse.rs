//! Sparse matrices against naive loops: BSR (`Mat3`) and scalar CSR SpMV `A * x` against the
//! scalar expansion built by hand, with batched values and batch broadcasting on either side
//! and several right-hand-side columns; the library's own expansion (`expanded_pattern`,
//! `expanded_values_f64`, `to_faer_csr`, `to_faer`, `to_dense`) against the same; transposed
//! SpMV; the fused `b = A u + c v`; sparse views `(M.as_diagonal() a + K b)` on K's pattern
//! (with a vector of reals cast to `Mat3`) by entry and through a leaf with another pattern;
//! `from_triplets` and the validation of CSR arrays.

mod common;

use common::*;
use gpumat::{LinearOperator, Mat3, Matrix, SparseMatrix, SparsityPattern, Transposed, Vec3};
use proptest::prelude::*;
use std::sync::Arc;

/// A random block pattern of `rows x cols` blocks, each entry present with probability
/// `density`, and `batches` batches of random blocks; also returned as naive per-batch
/// triplet lists `(row, col, block)`.
#[allow(clippy::type_complexity)]
fn random_bsr(
    rng: &mut Rand,
    rows: usize,
    cols: usize,
    density: f64,
    batches: usize,
) -> (SparseMatrix<Mat3<f64>>, Vec<Vec<(usize, usize, [[f64; 3]; 3])>>) {
    let mut entries = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            if rng.unit() < density {
                entries.push((r, c));
            }
        }
    }
    let p = SparsityPattern::from_entries(rows, cols, entries.iter().copied());
    let mut trip = vec![Vec::new(); batches];
    let mut vals = Vec::new();
    for t in trip.iter_mut() {
        for &(r, c) in &entries {
            let m = rng.mat3(-1.0, 1.0);
            t.push((r, c, m));
            vals.push(Mat3::from_rows(m));
        }
    }
    (SparseMatrix::from_values(p, batches, vals), trip)
}

/// The dense scalar expansion of one batch of triplets.
fn expand(rows: usize, cols: usize, t: &[(usize, usize, [[f64; 3]; 3])]) -> Vec<Vec<f64>> {
    let mut d = vec![vec![0.0; 3 * cols]; 3 * rows];
    for &(r, c, m) in t {
        for i in 0..3 {
            for j in 0..3 {
                d[3 * r + i][3 * c + j] += m[i][j];
            }
        }
    }
    d
}

fn random_vec3s(rng: &mut Rand, s: (usize, usize, usize)) -> Matrix<Vec3<f64>> {
    Matrix::from_fn(s.0, s.1, s.2, |_, _, _| {
        Vec3::new(
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
        )
    })
}

/// `(A x)` (or `A^T x` when `transpose`) by naive loops on the expansions; `x` as lanes.
fn naive_spmv(d: &[Vec<f64>], x: &Matrix<Vec3<f64>>, c: usize, b: usize, transpose: bool) -> Vec<f64> {
    let xb = if x.batches() == 1 { 0 } else { b };
    let xs: Vec<f64> = (0..x.rows()).flat_map(|r| x.get(r, c, xb).to_array()).collect();
    let (n, m) = if transpose {
        (d[0].len(), d.len())
    } else {
        (d.len(), d[0].len())
    };
    (0..n)
        .map(|i| {
            (0..m)
                .map(|j| if transpose { d[j][i] } else { d[i][j] } * xs[j])
                .sum()
        })
        .collect()
}

proptest! {
    #![proptest_config(config())]

    /// The operator's transpose: `<A x, y> = <x, A^T y>` per batch on a random non-symmetric
    /// square BSR matrix, and [`Transposed`] swaps `apply` and `transpose_apply`.
    #[test]
    fn linear_operator_transpose_is_the_adjoint(seed in any::<u64>(), n in 1usize..9, nb in 1usize..3) {
        let mut rng = Rand::new(seed);
        let (a, _) = random_bsr(&mut rng, n, n, 0.6, nb);
        let (x, y) = (random_vec3s(&mut rng, (n, 1, nb)), random_vec3s(&mut rng, (n, 1, nb)));
        let (mut ax, mut aty) = (Matrix::zeros(n, 1, nb), Matrix::zeros(n, 1, nb));
        a.apply(&x, &mut ax);
        a.transpose_apply(&y, &mut aty);
        let dot = |u: &Matrix<Vec3<f64>>, v: &Matrix<Vec3<f64>>, b: usize| -> f64 {
            u.batch(b).iter().zip(v.batch(b)).map(|(p, q)| p.dot(*q)).sum()
        };
        for b in 0..nb {
            let (l, r) = (dot(&ax, &y, b), dot(&x, &aty, b));
            prop_assert!((l - r).abs() <= 1e-12 * (1.0 + l.abs()), "batch {}: {} vs {}", b, l, r);
        }
        let (mut t1, mut t2) = (Matrix::zeros(n, 1, nb), Matrix::zeros(n, 1, nb));
        Transposed(&a).apply(&y, &mut t1);
        Transposed(&a).transpose_apply(&x, &mut t2);
        prop_assert_eq!(t1.as_slice(), aty.as_slice());
        prop_assert_eq!(t2.as_slice(), ax.as_slice());
        prop_assert_eq!(LinearOperator::<Vec3<f64>>::dim(&Transposed(&a)), n);
    }

    #[test]
    fn bsr_spmv_matches_expanded_csr(
        seed in any::<u64>(),
        rows in 1usize..8,
        cols in 1usize..8,
        k in 1usize..3,
        nb in 1usize..4,
        which in 0u8..3,
        density in 0.0f64..1.0,
    ) {
        let mut rng = Rand::new(seed);
        // which: 0 = both batched, 1 = A shared by every batch of x, 2 = x shared.
        let (ab, xb) = match which { 0 => (nb, nb), 1 => (1, nb), _ => (nb, 1) };
        let (a, trip) = random_bsr(&mut rng, rows, cols, density, ab);
        let x = random_vec3s(&mut rng, (cols, k, xb));
        let xt = random_vec3s(&mut rng, (rows, k, xb));
        let y = Matrix::eval(&a * &x);
        let yt = Matrix::eval(a.transpose_mul(xt.ex()));
        prop_assert_eq!(y.shape(), gpumat::Shape::new(rows, k, nb));
        prop_assert_eq!(yt.shape(), gpumat::Shape::new(cols, k, nb));
        for b in 0..nb {
            let d = expand(rows, cols, &trip[if ab == 1 { 0 } else { b }]);
            for c in 0..k {
                let want = naive_spmv(&d, &x, c, b, false);
                let got: Vec<f64> = (0..rows).flat_map(|r| y.get(r, c, b).to_array()).collect();
                assert_all_close(&got, &want, 0.0, f64::EPSILON * (3.0 * cols as f64).powi(2), "A x");
                let want = naive_spmv(&d, &xt, c, b, true);
                let got: Vec<f64> = (0..cols).flat_map(|r| yt.get(r, c, b).to_array()).collect();
                assert_all_close(&got, &want, 0.0, f64::EPSILON * (3.0 * rows as f64).powi(2), "A^T x");
            }
        }
        // Padding lanes stay zero.
        prop_assert!(y.as_slice().iter().chain(yt.as_slice()).all(|v| v.w == 0.0));
    }

    #[test]
    fn library_expansion_matches_naive(seed in any::<u64>(), rows in 1usize..7, cols in 1usize..7, nb in 1usize..3) {
        let mut rng = Rand::new(seed);
        let (a, trip) = random_bsr(&mut rng, rows, cols, 0.5, nb);
        let (row_ptr, col_idx) = a.expanded_pattern();
        prop_assert_eq!(row_ptr.len(), 3 * rows + 1);
        for b in 0..nb {
            let d = expand(rows, cols, &trip[b]);
            let vals = a.expanded_values_f64(b);
            let csr = a.to_faer_csr(b);
            let csc = a.to_faer(b);
            let dense = a.to_dense(b);
            let mut seen = vec![vec![0.0; 3 * cols]; 3 * rows];
            for i in 0..3 * rows {
                for k in row_ptr[i]..row_ptr[i + 1] {
                    seen[i][col_idx[k]] = vals[k];
                }
            }
            prop_assert_eq!(&seen, &d);
            let cd = csr.to_dense();
            let sd = csc.to_dense();
            for i in 0..3 * rows {
                for j in 0..3 * cols {
                    prop_assert_eq!(cd[(i, j)], d[i][j]);
                    prop_assert_eq!(sd[(i, j)], d[i][j]);
                    prop_assert_eq!(dense.get(i / 3, j / 3, 0).m[i % 3][j % 3], d[i][j]);
                    prop_assert_eq!(a.get(i / 3, j / 3, b).m[i % 3][j % 3], d[i][j]);
                }
            }
        }
    }

    #[test]
    fn scalar_csr_spmv(seed in any::<u64>(), n in 1usize..20, m in 1usize..20, nb in 1usize..4) {
        let mut rng = Rand::new(seed);
        let mut trip = Vec::new();
        for r in 0..n {
            for c in 0..m {
                if rng.unit() < 0.3 {
                    trip.push((r, c, rng.uniform(-1.0, 1.0)));
                }
            }
        }
        // Duplicates are summed by from_triplets.
        if let Some(&(r, c, v)) = trip.first() {
            trip.push((r, c, 0.25 * v));
        }
        let a = SparseMatrix::from_triplets(n, m, &trip);
        let x = random_matrix::<f64>(&mut rng, (m, 2, nb), -1.0, 1.0);
        let y = Matrix::eval(&a * &x);
        let a32 = SparseMatrix::from_values(a.pattern().clone(), 1, a.values().iter().map(|&v| v as f32).collect());
        let x32 = Matrix::<f32>::eval(x.ex().cast());
        let y32 = Matrix::eval(&a32 * &x32);
        for b in 0..nb {
            for c in 0..2 {
                for r in 0..n {
                    let mut want = 0.0;
                    let mut want32 = 0.0;
                    let mut mag = 0.0;
                    for &(tr, tc, v) in &trip {
                        if tr == r {
                            want += v * x.get(tc, c, b);
                            mag += (v * x.get(tc, c, b)).abs();
                        }
                    }
                    for cc in 0..m {
                        want32 += a32.get(r, cc, 0) as f64 * x32.get(cc, c, b) as f64;
                    }
                    assert_close(y.get(r, c, b), want, 4.0 * f64::EPSILON * mag, "scalar A x");
                    assert_close(y32.get(r, c, b) as f64, want32, 2.0 * f32::EPSILON as f64 * (m as f64) * mag + 1e-30, "f32 A x");
                }
            }
        }
    }

    /// `b = A u + c v` in one fused assignment, batched, against naive loops.
    #[test]
    fn fused_spmv_axpy(seed in any::<u64>(), n in 1usize..10, nb in 1usize..4, c in -2.0f64..2.0) {
        let mut rng = Rand::new(seed);
        let (a, trip) = random_bsr(&mut rng, n, n, 0.4, nb);
        let u = random_vec3s(&mut rng, (n, 1, nb));
        let v = random_vec3s(&mut rng, (n, 1, 1)); // broadcast over batches
        let mut out = Matrix::<Vec3<f64>>::zeros(n, 1, nb);
        gpumat::stats::reset();
        out.assign(&a * u.ex() + v.ex() * c);
        prop_assert_eq!(gpumat::stats::passes(), 1);
        prop_assert_eq!(gpumat::stats::allocations(), 0);
        for b in 0..nb {
            let au = naive_spmv(&expand(n, n, &trip[b]), &u, 0, b, false);
            for r in 0..n {
                let want: [f64; 3] = std::array::from_fn(|i| au[3 * r + i] + c * v.get(r, 0, 0).to_array()[i]);
                let got = out.get(r, 0, b).to_array();
                for i in 0..3 {
                    assert_close(got[i], want[i], f64::EPSILON * (3.0 * n as f64 + 2.0).powi(2), "A u + c v");
                }
            }
        }
    }

    /// The Newmark matrix `a M + b K` with a lumped mass vector `M` (reals cast to `Mat3`)
    /// on K's pattern, one pass; also with a leaf on another (larger) pattern, which is read
    /// by coordinates rather than by entry.
    #[test]
    fn sparse_view_newmark(seed in any::<u64>(), n in 1usize..10, nb in 1usize..4, alpha in -2.0f64..2.0, beta in -2.0f64..2.0) {
        let mut rng = Rand::new(seed);
        let mut entries: Vec<(usize, usize)> = (0..n).map(|i| (i, i)).collect();
        for i in 0..n {
            for j in 0..n {
                if i != j && rng.unit() < 0.3 {
                    entries.push((i, j));
                }
            }
        }
        let p = SparsityPattern::from_entries(n, n, entries.iter().copied());
        let kv: Vec<Mat3<f64>> = (0..p.nnz() * nb).map(|_| Mat3::from_rows(rng.mat3(-1.0, 1.0))).collect();
        let k = SparseMatrix::from_values(p.clone(), nb, kv);
        let m = random_matrix::<f64>(&mut rng, (n, 1, nb), 0.5, 2.0);
        let mut a = SparseMatrix::<Mat3<f64>>::zeros(p.clone(), nb);
        gpumat::stats::reset();
        a.assign((m.ex().cast::<Mat3<f64>>().as_diagonal() * alpha + k.ex() * beta).sparse_view(k.pattern()));
        prop_assert_eq!(gpumat::stats::passes(), 1);
        prop_assert_eq!(gpumat::stats::allocations(), 0);
        // A leaf with a different pattern (all of K's entries plus more, single batch).
        let full = SparsityPattern::from_entries(n, n, (0..n).flat_map(|i| (0..n).map(move |j| (i, j))));
        let g = SparseMatrix::from_values(full.clone(), 1, (0..full.nnz()).map(|_| Mat3::from_rows(rng.mat3(-1.0, 1.0))).collect());
        let mut a2 = SparseMatrix::<Mat3<f64>>::zeros(p.clone(), nb);
        a2.assign((k.ex() - g.ex()).sparse_view(&p));
        for b in 0..nb {
            for r in 0..n {
                for kk in p.row_range(r) {
                    let c = p.col_idx()[kk] as usize;
                    let kb = k.batch_values(b)[kk].m;
                    let want: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| {
                        beta * kb[i][j] + if r == c && i == j { alpha * m.get(r, 0, b) } else { 0.0 }
                    }));
                    let got = a.batch_values(b)[kk].m;
                    let got2 = a2.batch_values(b)[kk].m;
                    let gv = g.get(r, c, 0).m;
                    for i in 0..3 {
                        for j in 0..3 {
                            assert_close(got[i][j], want[i][j], 4.0 * f64::EPSILON * 4.0, "a M + b K");
                            prop_assert_eq!(got2[i][j], kb[i][j] - gv[i][j]);
                        }
                    }
                }
            }
        }
    }
}

/// A real sparse matrix times a vector of `Vec3` scales each vector (a scalar mass matrix).
#[test]
fn real_matrix_times_vec3() {
    let a = SparseMatrix::<f64>::from_triplets(2, 3, &[(0, 0, 2.0), (0, 2, -1.0), (1, 1, 0.5)]);
    let x = Matrix::column(&[
        Vec3::new(1.0, 2.0, 3.0),
        Vec3::new(4.0, 4.0, 4.0),
        Vec3::new(1.0, 0.0, -1.0),
    ]);
    let y = Matrix::eval(&a * &x);
    assert_eq!(y.get(0, 0, 0), Vec3::new(1.0, 4.0, 7.0));
    assert_eq!(y.get(1, 0, 0), Vec3::splat(2.0));
    let yt = Matrix::eval(a.transpose_mul(y.ex()));
    assert_eq!(yt.get(0, 0, 0), Vec3::new(2.0, 8.0, 14.0));
    assert_eq!(yt.get(1, 0, 0), Vec3::splat(1.0));
    assert_eq!(yt.get(2, 0, 0), Vec3::new(-1.0, -4.0, -7.0));
}

/// Large SpMV over the parallel assignment path against the naive loop.
#[test]
fn large_bsr_spmv() {
    let mut rng = Rand::new(5);
    let n = 12_000;
    let entries = (0..n).flat_map(|i| [(i, i), (i, (i + 1) % n), (i, (i * 7 + 3) % n)]);
    let p = SparsityPattern::from_entries(n, n, entries);
    let vals = (0..p.nnz() * 3)
        .map(|_| Mat3::from_rows(rng.mat3(-1.0, 1.0)))
        .collect();
    let a = SparseMatrix::from_values(p.clone(), 3, vals);
    let x = random_vec3s(&mut rng, (n, 1, 3));
    let y = Matrix::eval(&a * &x);
    let yt = Matrix::eval(a.transpose_mul(x.ex()));
    let mut yt_want = vec![[0.0f64; 3]; n * 3];
    for b in 0..3 {
        for r in 0..n {
            let mut acc = [0.0; 3];
            for k in p.row_range(r) {
                let c = p.col_idx()[k] as usize;
                let m = a.batch_values(b)[k].m;
                let xv = x.get(c, 0, b).to_array();
                let xr = x.get(r, 0, b).to_array();
                for i in 0..3 {
                    for j in 0..3 {
                        acc[i] += m[i][j] * xv[j];
                        yt_want[b * n + c][j] += m[i][j] * xr[i];
                    }
                }
            }
            let got = y.get(r, 0, b).to_array();
            for i in 0..3 {
                assert_close(got[i], acc[i], 1e-14 * 9.0, "large A x");
            }
        }
        for c in 0..n {
            let got = yt.get(c, 0, b).to_array();
            for j in 0..3 {
                assert_close(got[j], yt_want[b * n + c][j], 1e-14 * 9.0, "large A^T x");
            }
        }
    }
}

#[test]
fn pattern_validation() {
    let ok = SparsityPattern::new(2, 3, vec![0, 2, 3], vec![0, 2, 1]).expect("valid");
    assert_eq!(ok.nnz(), 3);
    assert_eq!(ok.find(0, 2), Some(1));
    assert_eq!(ok.find(1, 0), None);
    assert_eq!(ok.entry_rows(), vec![0, 0, 1]);
    let bad: Vec<(usize, usize, Vec<usize>, Vec<usize>)> = vec![
        (2, 2, vec![0, 1], vec![0]),          // row_ptr too short
        (2, 2, vec![1, 1, 1], vec![0]),       // does not start at 0
        (2, 2, vec![0, 1, 3], vec![0, 1]),    // does not end at nnz
        (2, 2, vec![0, 5, 3], vec![0, 1, 1]), // decreasing, interior pointer past nnz
        (2, 2, vec![0, 2, 1], vec![0, 1]),    // decreasing
        (2, 2, vec![0, 1, 2], vec![0, 2]),    // column out of range
        (2, 2, vec![0, 2, 2], vec![1, 0]),    // unsorted
        (2, 2, vec![0, 2, 2], vec![1, 1]),    // duplicate
    ];
    for (r, c, rp, ci) in bad {
        let what = format!("{rp:?} {ci:?}");
        let res = std::panic::catch_unwind(|| SparsityPattern::new(r, c, rp, ci));
        match res {
            Ok(Err(gpumat::Error::InvalidPattern(_))) => {}
            Ok(other) => panic!("{what}: expected InvalidPattern, got {other:?}"),
            Err(_) => panic!("{what}: SparsityPattern::new panicked instead of returning an error"),
        }
    }
    // from_entries merges duplicates and sorts.
    let p = SparsityPattern::from_entries(2, 2, [(1, 1), (0, 1), (1, 1), (0, 0)]);
    assert_eq!(p.row_ptr(), &[0, 2, 3]);
    assert_eq!(p.col_idx(), &[0, 1, 1]);
    let t = p.transpose_map();
    assert_eq!(t.col_ptr, vec![0, 1, 3]);
    assert_eq!(t.row_idx, vec![0, 0, 1]);
    assert_eq!(t.entry, vec![0, 1, 2]);
    let q: Arc<SparsityPattern> = SparsityPattern::new(2, 2, vec![0, 2, 3], vec![0, 1, 1]).unwrap();
    assert!(p.same_as(&q));
}
