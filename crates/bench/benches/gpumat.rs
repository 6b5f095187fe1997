//! Criterion benchmarks of the thesis' four cuMat cases (Appendix B) at small sizes, so that
//! `cargo bench --no-run` builds quickly and a run is short, and of the two kernels a
//! simulation spends its time in: the 3x3 block-sparse SpMV on the held cuboid's stiffness
//! matrix and one whole time step of that cuboid (Table B.5's body). The `tables` binary
//! measures the full size ranges with the peers.

use bench::lincomb::{fused, unfused};
use bench::problems::{boundary_rhs, lincomb_inputs, poisson_matrix, random_vector};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use gpumat::{cg, CgParams, Jacobi, Matrix};
use std::hint::black_box;
use std::time::Duration;

/// B.1: k = 2, n varies.
fn b1_lincomb_k2(c: &mut Criterion) {
    let mut g = c.benchmark_group("B.1 lincomb k=2");
    for n in [1_000usize, 100_000] {
        let (vs, a) = lincomb_inputs(n, 2);
        let mut d = Matrix::<f32>::zeros(n, 1, 1);
        g.throughput(Throughput::Bytes((12 * n) as u64));
        g.bench_with_input(BenchmarkId::new("fused", n), &n, |b, _| {
            b.iter(|| fused(black_box(&mut d), black_box(&vs), black_box(&a)))
        });
    }
    g.finish();
}

/// B.2: n fixed, k = 1..10, fused vs one pass per term.
fn b2_lincomb_k(c: &mut Criterion) {
    let n = 100_000;
    let mut g = c.benchmark_group("B.2 lincomb n=1e5");
    for k in [1usize, 4, 10] {
        let (vs, a) = lincomb_inputs(n, k);
        let mut d = Matrix::<f32>::zeros(n, 1, 1);
        g.throughput(Throughput::Bytes((4 * (k + 1) * n) as u64));
        g.bench_with_input(BenchmarkId::new("fused", k), &k, |b, _| {
            b.iter(|| fused(black_box(&mut d), black_box(&vs), black_box(&a)))
        });
        g.bench_with_input(BenchmarkId::new("unfused", k), &k, |b, _| {
            b.iter(|| unfused(black_box(&mut d), black_box(&vs), black_box(&a)))
        });
    }
    g.finish();
}

/// B.3: CSR SpMV on the 2D Poisson matrix.
fn b3_spmv(c: &mut Criterion) {
    let mut g = c.benchmark_group("B.3 spmv poisson");
    for grid in [10usize, 100, 300] {
        let a = poisson_matrix(grid);
        let x = random_vector(3, grid * grid);
        let mut y = Matrix::<f32>::zeros(grid * grid, 1, 1);
        g.throughput(Throughput::Elements(a.nnz() as u64));
        g.bench_with_input(BenchmarkId::from_parameter(grid), &grid, |b, _| {
            b.iter(|| black_box(&mut y).assign(black_box(&a) * black_box(&x)))
        });
    }
    g.finish();
}

/// B.4: Jacobi-preconditioned CG on 2D diffusion, tolerance 1e-4.
fn b4_cg(c: &mut Criterion) {
    let mut g = c.benchmark_group("B.4 cg diffusion");
    g.sample_size(10).measurement_time(Duration::from_secs(2));
    for grid in [10usize, 30] {
        let a = poisson_matrix(grid);
        let rhs = boundary_rhs(grid);
        let params = CgParams {
            max_iterations: 2 * grid * grid,
            tolerance: 1e-4f32,
            absolute_tolerance: 0.0,
        };
        let mut x = Matrix::<f32>::zeros(grid * grid, 1, 1);
        g.bench_with_input(BenchmarkId::from_parameter(grid), &grid, |b, _| {
            b.iter(|| {
                let pre = Jacobi::new(&a).expect("positive diagonal");
                x.as_mut_slice().fill(0.0);
                cg(&a, black_box(&rhs), &mut x, &pre, &params).expect("CG converges")
            })
        });
    }
    g.finish();
}

/// The held cuboid of Table B.5 at the thesis' resolution `r` (cells of size 1/(2r)).
fn cuboid(r: u32) -> cutfem::fem::Simulation {
    let (shape, model) = cutfem::fem::model::thesis_cuboid(false);
    let sdf = shape.to_sdf(2.0 * r as f64, 6).expect("cuboid SDF");
    let grid = cutfem::fem::Grid::new(sdf).expect("cuboid grid");
    cutfem::fem::Simulation::new(grid, model).expect("cuboid simulation")
}

/// BSR 3x3 SpMV `y = K x` on the cuboid's stiffness matrix (f64).
fn bsr_spmv(c: &mut Criterion) {
    let mut g = c.benchmark_group("BSR spmv cuboid");
    for r in [5u32, 10] {
        let sim = cuboid(r);
        let k = sim.stiffness().clone();
        let n = k.rows();
        let x = Matrix::<gpumat::Vec3<f64>>::from_fn(n, 1, 1, |i, _, _| {
            gpumat::Vec3::new(i as f64 * 1e-3, 1.0, -(i as f64) * 2e-3)
        });
        let mut y = Matrix::<gpumat::Vec3<f64>>::zeros(n, 1, 1);
        // values + column indices + row pointers + x + y
        let bytes = k.nnz() * (72 + 4) + (n + 1) * 4 + 2 * n * 24;
        g.throughput(Throughput::Bytes(bytes as u64));
        g.bench_with_input(BenchmarkId::from_parameter(r), &r, |b, _| {
            b.iter(|| black_box(&mut y).assign(black_box(&k) * black_box(&x)))
        });
    }
    g.finish();
}

/// One time step of the held cuboid (corotation, default solver settings).
fn cutfem_step(c: &mut Criterion) {
    let mut g = c.benchmark_group("cutfem step cuboid");
    g.sample_size(10).measurement_time(Duration::from_secs(2));
    let r = 5u32;
    let mut sim = cuboid(r);
    g.bench_with_input(BenchmarkId::from_parameter(r), &r, |b, _| {
        b.iter(|| sim.step().expect("step"))
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    targets = b1_lincomb_k2, b2_lincomb_k, b3_spmv, b4_cg, bsr_spmv, cutfem_step
}
criterion_main!(benches);
