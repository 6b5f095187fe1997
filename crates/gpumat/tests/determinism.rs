//! Results do not depend on the number of threads: reductions over ~1e6 `f32` values of
//! widely varied magnitudes (sum, dot, norm, squared norm, min/max and `_over` every axis set),
//! large fused assignments with broadcasting, BSR SpMV and its transpose, and full batched CG
//! solves (Jacobi and BlockJacobi, `f32` and `f64`) are run inside rayon pools of 1, 2, 3 and 8
//! threads and must agree bit for bit (compared through `to_bits`). The reductions are also
//! checked against an `f64` reference, so a deterministic but wrong result fails too.

mod common;

use common::*;
use gpumat::backend::{Backend, Cpu};
use gpumat::{cg, Axes, BlockJacobi, CgParams, Jacobi, Matrix, Real, Vec3};

const THREADS: [usize; 4] = [1, 2, 3, 8];

/// Runs `f` in pools of every size in [`THREADS`] and asserts the bit patterns agree.
fn same_bits_for_all_thread_counts(what: &str, f: impl Fn() -> Vec<u64> + Send + Sync) {
    let mut first: Option<Vec<u64>> = None;
    for k in THREADS {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(k).build().unwrap();
        let bits = pool.install(|| {
            assert_eq!(Cpu.name(), format!("cpu ({k} threads)"), "the pool is in effect");
            f()
        });
        assert!(!bits.is_empty());
        match &first {
            None => first = Some(bits),
            Some(b0) => {
                let diff = b0.iter().zip(&bits).position(|(x, y)| x != y);
                assert_eq!(b0.len(), bits.len(), "{what}: length differs with {k} threads");
                assert!(
                    diff.is_none(),
                    "{what}: value {diff:?} differs between 1 and {k} threads"
                );
            }
        }
    }
}

fn bits<R: Real>(v: impl IntoIterator<Item = R>) -> Vec<u64> {
    v.into_iter().map(|x| x.as_f64().to_bits()).collect()
}

fn varied(n: usize, seed: u64) -> Matrix<f32> {
    let mut rng = Rand::new(seed);
    Matrix::from_fn(n, 1, 1, |_, _, _| {
        let mag = 10f64.powi(rng.below(9) as i32 - 4);
        (rng.uniform(-1.0, 1.0) * mag) as f32
    })
}

#[test]
fn reductions_are_deterministic_and_accurate() {
    let n = 1 << 20;
    let x = varied(n, 1);
    let y = varied(n, 2);
    let cube = x.clone().reshape(128, 2048, 4);
    let (fx, fy) = (lanes_f64(&x), lanes_f64(&y));
    // Accuracy against f64 with the rigorous bound n eps sum|.|.
    let e = f32::EPSILON as f64 * n as f64;
    let abs: f64 = fx.iter().map(|v| v.abs()).sum();
    assert_close(x.ex().sum() as f64, fx.iter().sum(), e * abs, "sum");
    let d: f64 = fx.iter().zip(&fy).map(|(a, b)| a * b).sum();
    let dabs: f64 = fx.iter().zip(&fy).map(|(a, b)| (a * b).abs()).sum();
    assert_close(x.ex().dot(y.ex()) as f64, d, e * dabs, "dot");
    let sq: f64 = fx.iter().map(|v| v * v).sum();
    assert_close(x.ex().norm() as f64, sq.sqrt(), e * sq.sqrt(), "norm");

    same_bits_for_all_thread_counts("reductions", || {
        let mut out = bits([
            x.ex().sum(),
            x.ex().dot(y.ex()),
            x.ex().norm(),
            x.ex().squared_norm(),
            (x.ex() - y.ex()).squared_norm(),
            x.ex().min(),
            x.ex().max(),
        ]);
        for m in 1..8u8 {
            let axes = Axes {
                rows: m & 1 != 0,
                cols: m & 2 != 0,
                batches: m & 4 != 0,
            };
            out.extend(bits(cube.ex().sum_over(axes).into_vec()));
            out.extend(bits(cube.ex().norm_over(axes).into_vec()));
        }
        let x64 = Matrix::<f64>::eval(x.ex().cast());
        out.extend(bits([x64.ex().sum(), x64.ex().dot(y.ex().cast::<f64>())]));
        out
    });
}

#[test]
fn assignments_are_deterministic() {
    let n = 1 << 20;
    let a = varied(n, 3).reshape(256, 1024, 4);
    let row = varied(1024, 4).reshape(1, 1024, 1);
    let col = varied(256 * 4, 5).reshape(256, 1, 4);
    same_bits_for_all_thread_counts("assignments", || {
        let mut d = Matrix::<f32>::zeros(256, 1024, 4);
        d.assign(a.ex() + row.ex() * 2.0 - col.ex().abs().sqrt());
        d += a.ex().cwise_mul(row.ex());
        d.assign_with(|d| d.cwise_max(col.ex()) * 0.5);
        bits(d.into_vec())
    });
}

#[test]
fn spmv_is_deterministic() {
    let mut rng = Rand::new(6);
    let sys = random_spd_blocks_large(&mut rng, 30_000, 2, 2, 1.0);
    let a = sys.bsr::<f32>();
    let x = Matrix::from_fn(30_000, 1, 2, |_, _, _| {
        Vec3::new(
            rng.uniform(-1.0, 1.0) as f32,
            rng.uniform(-1e3, 1e3) as f32,
            rng.uniform(-1e-3, 1e-3) as f32,
        )
    });
    same_bits_for_all_thread_counts("spmv", || {
        let y = Matrix::eval(&a * &x);
        let yt = Matrix::eval(a.transpose_mul(x.ex()) - y.ex());
        y.as_slice()
            .iter()
            .chain(yt.as_slice())
            .flat_map(|v| bits(v.to_array()))
            .collect()
    });
}

#[test]
fn batched_cg_is_deterministic() {
    let mut rng = Rand::new(7);
    let n = 12_000;
    let sys = random_spd_blocks_large(&mut rng, n, 3, 2, 0.5);
    let a64 = sys.bsr::<f64>();
    let a32 = sys.bsr::<f32>();
    let rhs = Matrix::from_fn(n, 1, 3, |_, _, _| {
        Vec3::new(
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
        )
    });
    let rhs32 = Matrix::<Vec3<f32>>::eval(rhs.ex().cast());
    same_bits_for_all_thread_counts("batched CG", || {
        let mut x = Matrix::zeros(n, 1, 3);
        let p = CgParams {
            max_iterations: 500,
            tolerance: 1e-9,
            absolute_tolerance: 0.0,
        };
        let info = cg(&a64, &rhs, &mut x, &BlockJacobi::new(&a64).unwrap(), &p).unwrap();
        let mut x32 = Matrix::zeros(n, 1, 3);
        let p32 = CgParams {
            max_iterations: 500,
            tolerance: 1e-5f32,
            absolute_tolerance: 0.0,
        };
        let i32_ = cg(&a32, &rhs32, &mut x32, &Jacobi::new(&a32).unwrap(), &p32).unwrap();
        let mut out: Vec<u64> = info
            .iterations
            .iter()
            .chain(&i32_.iterations)
            .map(|&i| i as u64)
            .collect();
        out.extend(bits(info.residual));
        out.extend(x.as_slice().iter().flat_map(|v| bits(v.to_array())));
        out.extend(x32.as_slice().iter().flat_map(|v| bits(v.to_array())));
        out
    });
}

#[test]
fn cholesky_preconditioned_cg_is_deterministic() {
    let mut rng = Rand::new(8);
    let n = 12_000;
    let sys = random_spd_blocks_large(&mut rng, n, 2, 0, 1.0);
    let a = sys.bsr::<f64>();
    let rhs = Matrix::from_fn(n, 1, 2, |_, _, _| Vec3::new(rng.unit(), rng.unit(), rng.unit()));
    same_bits_for_all_thread_counts("cholesky CG", || {
        let chol = gpumat::SparseCholesky::new(&a).unwrap();
        let mut x = Matrix::zeros(n, 1, 2);
        let p = CgParams {
            max_iterations: 10,
            tolerance: 1e-12,
            absolute_tolerance: 0.0,
        };
        let info = cg(&a, &rhs, &mut x, &chol, &p).unwrap();
        let mut out: Vec<u64> = info.iterations.iter().map(|&i| i as u64).collect();
        out.extend(x.as_slice().iter().flat_map(|v| bits(v.to_array())));
        out
    });
}
