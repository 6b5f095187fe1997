//! Dense batched products against the naive triple loop: `matmul` on rectangular shapes with
//! the batch dimension broadcast on either side, `matmul_into` with `alpha` and accumulation,
//! the parallel-over-batches and the parallel-GEMM paths, and the shape checks.

mod common;

use common::*;
use gpumat::{matmul, matmul_into, Matrix, Real, Shape};
use proptest::prelude::*;

/// `C(:,:,b) = alpha A(:,:,b) B(:,:,b) (+ C0)`, naive, with size-1 batches broadcast.
fn naive<R: Real>(a: &Matrix<R>, b: &Matrix<R>, c0: Option<&Matrix<R>>, alpha: f64) -> (Vec<f64>, Vec<f64>) {
    let nb = a.batches().max(b.batches());
    let (m, k, n) = (a.rows(), a.cols(), b.cols());
    let mut out = Vec::with_capacity(m * n * nb);
    let mut mag = Vec::with_capacity(m * n * nb);
    for bb in 0..nb {
        let (ab, bb2) = (
            if a.batches() == 1 { 0 } else { bb },
            if b.batches() == 1 { 0 } else { bb },
        );
        for j in 0..n {
            for i in 0..m {
                let mut s = 0.0;
                let mut s_abs = 0.0;
                for l in 0..k {
                    let p = a.get(i, l, ab).as_f64() * b.get(l, j, bb2).as_f64();
                    s += p;
                    s_abs += p.abs();
                }
                let c = c0.map_or(0.0, |c| c.get(i, j, bb).as_f64());
                out.push(alpha * s + c);
                mag.push((alpha * s_abs).abs() + c.abs());
            }
        }
    }
    (out, mag)
}

fn check<R: Real>(got: &Matrix<R>, want: &(Vec<f64>, Vec<f64>), k: usize, what: &str) {
    let g = lanes_f64(got);
    assert_eq!(g.len(), want.0.len(), "{what}: element count");
    for i in 0..g.len() {
        let tol = (k as f64 + 2.0) * eps::<R>() * want.1[i];
        assert_close(g[i], want.0[i], tol, &format!("{what}[{i}]"));
    }
}

fn check_products<R: Real>(seed: u64, m: usize, k: usize, n: usize, nb: usize, which: u8, alpha: f64) {
    let mut rng = Rand::new(seed);
    // which: 0 = both batched, 1 = left shared, 2 = right shared.
    let (ab, bb) = match which {
        0 => (nb, nb),
        1 => (1, nb),
        _ => (nb, 1),
    };
    let a = random_matrix::<R>(&mut rng, (m, k, ab), -1.0, 1.0);
    let b = random_matrix::<R>(&mut rng, (k, n, bb), -1.0, 1.0);
    let c = matmul(&a, &b);
    assert_eq!(c.shape(), Shape::new(m, n, nb));
    check(&c, &naive(&a, &b, None, 1.0), k, "matmul");
    let c0 = random_matrix::<R>(&mut rng, (m, n, nb), -1.0, 1.0);
    let mut acc = c0.clone();
    matmul_into(&mut acc, &a, &b, R::of(alpha), true);
    check(
        &acc,
        &naive(&a, &b, Some(&c0), R::of(alpha).as_f64()),
        k,
        "C += alpha A B",
    );
    let mut rep = c0.clone();
    matmul_into(&mut rep, &a, &b, R::of(alpha), false);
    check(
        &rep,
        &naive(&a, &b, None, R::of(alpha).as_f64()),
        k,
        "C = alpha A B",
    );
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn matmul_matches_triple_loop(
        seed in any::<u64>(),
        m in 1usize..7,
        k in 1usize..7,
        n in 1usize..7,
        nb in 1usize..4,
        which in 0u8..3,
        alpha in -2.0f64..2.0,
    ) {
        check_products::<f32>(seed, m, k, n, nb, which, alpha);
        check_products::<f64>(seed, m, k, n, nb, which, alpha);
    }
}

/// Many small batches (parallel over batches) and one product big enough for parallel GEMM.
#[test]
fn large_products() {
    check_products::<f64>(1, 9, 13, 5, 40, 0, 1.5);
    check_products::<f64>(2, 9, 13, 5, 40, 1, -0.5);
    check_products::<f64>(3, 70, 64, 66, 1, 0, 1.0); // 70*64*66 >= 2^18 flops
    check_products::<f32>(4, 80, 70, 60, 2, 2, 1.0);
}

#[test]
fn faer_views_round_trip() {
    let mut rng = Rand::new(9);
    let a = random_matrix::<f64>(&mut rng, (4, 3, 2), -1.0, 1.0);
    let f0 = a.to_faer(0);
    let f1 = a.faer_ref(1);
    let back = Matrix::from_faer(&[f0.as_ref(), f1]);
    assert_eq!(back, a);
}

#[test]
#[should_panic(expected = "inner dimensions")]
fn matmul_rejects_mismatched_inner_dimensions() {
    let _ = matmul(&Matrix::<f64>::zeros(2, 3, 1), &Matrix::<f64>::zeros(4, 2, 1));
}

#[test]
#[should_panic(expected = "batches")]
fn matmul_rejects_mismatched_batches() {
    let _ = matmul(&Matrix::<f64>::zeros(2, 3, 2), &Matrix::<f64>::zeros(3, 2, 3));
}
