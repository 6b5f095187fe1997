//! The logic check (emulated CUDA): the generated CUDA sources, compiled by the system C++
//! compiler against the test-only header `tests/emu/cuda_emu.h` (blocks one after another, a
//! block's threads as OS threads, `__syncthreads` a barrier), launched with the launch geometry
//! of [`gpumat::cuda::launch`] and compared with the CPU backend on random inputs. This runs the
//! kernels' own index arithmetic, broadcasting, row loops, tree reductions and barriers.
//!
//! Here the build-time catalogue (tests/emulated_expr.rs checks the expression kernels):
//! reductions (and their bitwise repeatability), CSR/BSR SpMV and transposed SpMV, Jacobi and
//! block-Jacobi setup and apply, Newmark A and b, the CG vector updates and per-batch scalars.

mod emu;

use emu::{rnd, Args, Emu};
use gpumat::cuda::{self, launch};
use gpumat::{Axes, BlockJacobi, Jacobi, Mat3, Matrix, Preconditioner, SparseMatrix, Vec3};
use std::sync::OnceLock;

fn emu() -> &'static Emu {
    static E: OnceLock<Emu> = OnceLock::new();
    E.get_or_init(|| Emu::build(&cuda::catalogue()))
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

const N: usize = 700; // three blocks of 256: partial sums, ragged last block
const B: usize = 2;

#[test]
fn reductions_match_the_cpu_and_repeat_bitwise() {
    if !emu::compiler_available() {
        return;
    }
    let x = Matrix::<f64>::from_fn(N, 1, B, |r, _, b| rnd(1, r + N * b));
    let y = Matrix::<f64>::from_fn(N, 1, B, |r, _, b| rnd(2, r + N * b));
    let parts = launch::reduction_parts(N) as usize;
    assert_eq!(parts, 3);
    let run = |kernel: &str, args: Args| -> Vec<f64> {
        let mut partials = vec![0.0f64; parts * B];
        let mut out = vec![0.0f64; B];
        emu().launch(kernel, launch::reduction(N, B), args.n(N).out(&mut partials));
        let fin = kernel
            .replace("_partial_", "_finish_")
            .replace("squared_norm_finish", "sum_finish")
            .replace("max_abs_finish", "max_finish");
        let fin = fin.replace("cg_dot_finish", "reduce_sum_finish");
        emu().launch(
            &fin,
            launch::reduction_finish(B),
            Args::default().buf(&partials).n(parts).out(&mut out),
        );
        out
    };
    let sum = run("gpumat_reduce_sum_partial_f64", Args::default().buf(x.as_slice()));
    let dot = run(
        "gpumat_cg_dot_partial_f64",
        Args::default().buf(x.as_slice()).buf(y.as_slice()),
    );
    let sq = run(
        "gpumat_reduce_squared_norm_partial_f64",
        Args::default().buf(x.as_slice()),
    );
    let min = run("gpumat_reduce_min_partial_f64", Args::default().buf(x.as_slice()));
    let max = run("gpumat_reduce_max_partial_f64", Args::default().buf(x.as_slice()));
    let maxabs = run(
        "gpumat_reduce_max_abs_partial_f64",
        Args::default().buf(x.as_slice()),
    );
    let cpu_sum = x.ex().sum_over(Axes::ROWS);
    let cpu_dot = x.ex().dot_over(y.ex(), Axes::ROWS);
    let cpu_sq = x.ex().squared_norm_over(Axes::ROWS);
    let cpu_min = x.ex().min_over(Axes::ROWS);
    let cpu_max = x.ex().max_over(Axes::ROWS);
    let cpu_maxabs = x.ex().abs().max_over(Axes::ROWS);
    for b in 0..B {
        assert!(
            close(sum[b], cpu_sum.get(0, 0, b), 1e-12),
            "sum {} {}",
            sum[b],
            cpu_sum.get(0, 0, b)
        );
        assert!(close(dot[b], cpu_dot.get(0, 0, b), 1e-12), "dot");
        assert!(close(sq[b], cpu_sq.get(0, 0, b), 1e-12), "squared norm");
        assert_eq!(min[b], cpu_min.get(0, 0, b), "min");
        assert_eq!(max[b], cpu_max.get(0, 0, b), "max");
        assert_eq!(maxabs[b], cpu_maxabs.get(0, 0, b), "max abs");
    }
    // the same input gives the same bits
    let again = run("gpumat_reduce_sum_partial_f64", Args::default().buf(x.as_slice()));
    assert_eq!(
        sum.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        again.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
    // Vec3 f32: sum of vectors
    let v = Matrix::<Vec3<f32>>::from_fn(N, 1, B, |r, _, b| {
        Vec3::new(rnd(3, r) as f32, rnd(4, r + b) as f32, rnd(5, r * b) as f32)
    });
    let mut partials = vec![Vec3::<f32>::default(); parts * B];
    let mut out = vec![Vec3::<f32>::default(); B];
    emu().launch(
        "gpumat_reduce_sum_partial_vec3_f32",
        launch::reduction(N, B),
        Args::default().buf(v.as_slice()).n(N).out(&mut partials),
    );
    emu().launch(
        "gpumat_reduce_sum_finish_vec3_f32",
        launch::reduction_finish(B),
        Args::default().buf(&partials).n(parts).out(&mut out),
    );
    let cpu = v.ex().sum_over(Axes::ROWS);
    for b in 0..B {
        let (g, c) = (out[b], cpu.get(0, 0, b));
        for (gl, cl) in [(g.x, c.x), (g.y, c.y), (g.z, c.z)] {
            assert!(close(gl as f64, cl as f64, 1e-4), "{g:?} {c:?}");
        }
        assert_eq!(g.w, 0.0, "w stays 0");
    }
}

/// A random BSR matrix on a banded pattern (`n` block rows, full diagonal), `batches` value sets,
/// diagonally dominant (SPD-like) blocks.
fn bsr(n: usize, batches: usize, seed: u64) -> SparseMatrix<Mat3<f64>> {
    let mut t = Vec::new();
    for r in 0..n {
        for c in [r.saturating_sub(2), r, (r + 3).min(n - 1)] {
            if t.iter().any(|&(a, b, _)| a == r && b == c) {
                continue;
            }
            let m = Mat3 {
                m: std::array::from_fn(|i| std::array::from_fn(|j| rnd(seed, 9 * (r * n + c) + 3 * i + j))),
            };
            let m = if r == c { m + Mat3::from_scalar(8.0) } else { m };
            t.push((r, c, m));
        }
    }
    let one = SparseMatrix::from_triplets(n, n, &t);
    let vals = (0..batches)
        .flat_map(|b| one.values().iter().map(move |m| *m * (1.0 + 0.25 * b as f64)))
        .collect();
    SparseMatrix::from_values(one.pattern().clone(), batches, vals)
}

fn vec3s(n: usize, batches: usize, seed: u64) -> Matrix<Vec3<f64>> {
    Matrix::from_fn(n, 1, batches, |r, _, b| {
        Vec3::new(
            rnd(seed, 3 * (r + n * b)),
            rnd(seed, 3 * (r + n * b) + 1),
            rnd(seed, 3 * (r + n * b) + 2),
        )
    })
}

fn assert_vec3s_close(gpu: &[Vec3<f64>], cpu: &Matrix<Vec3<f64>>, what: &str) {
    for (i, (g, c)) in gpu.iter().zip(cpu.as_slice()).enumerate() {
        let ok = close(g.x, c.x, 1e-12) && close(g.y, c.y, 1e-12) && close(g.z, c.z, 1e-12) && g.w == 0.0;
        assert!(ok, "{what}: element {i}: emulated {g:?}, cpu {c:?}");
    }
}

#[test]
fn spmv_preconditioners_and_newmark_match_the_cpu() {
    if !emu::compiler_available() {
        return;
    }
    let n = 300;
    let a = bsr(n, B, 7);
    let x = vec3s(n, B, 8);
    let p = a.pattern();
    let row_ptr: Vec<u64> = p.row_ptr().iter().map(|&v| v as u64).collect();
    let nnz = a.nnz();
    let rows_grid = launch::elementwise(n * B);
    let mut y = vec![Vec3::<f64>::default(); n * B];
    emu().launch(
        "gpumat_bsr3_spmv_f64",
        rows_grid,
        Args::default()
            .buf(&row_ptr)
            .buf(p.col_idx())
            .buf(a.values())
            .n(nnz)
            .buf(x.as_slice())
            .out(&mut y)
            .n(n)
            .n(n)
            .n(B),
    );
    assert_vec3s_close(&y, &Matrix::eval(&a * x.ex()), "bsr3 spmv");
    let t = p.transpose_map();
    let (cp, ri, en): (Vec<u64>, Vec<u64>, Vec<u64>) = (
        t.col_ptr.iter().map(|&v| v as u64).collect(),
        t.row_idx.iter().map(|&v| v as u64).collect(),
        t.entry.iter().map(|&v| v as u64).collect(),
    );
    emu().launch(
        "gpumat_bsr3_spmv_transposed_f64",
        rows_grid,
        Args::default()
            .buf(&cp)
            .buf(&ri)
            .buf(&en)
            .buf(a.values())
            .n(nnz)
            .buf(x.as_slice())
            .out(&mut y)
            .n(n)
            .n(n)
            .n(B),
    );
    assert_vec3s_close(&y, &Matrix::eval(a.transpose_mul(x.ex())), "bsr3 spmv transposed");
    // shared values (vals_stride 0) with batched x
    let a1 = bsr(n, 1, 9);
    emu().launch(
        "gpumat_bsr3_spmv_f64",
        rows_grid,
        Args::default()
            .buf(&row_ptr)
            .buf(a1.pattern().col_idx())
            .buf(a1.values())
            .n(0)
            .buf(x.as_slice())
            .out(&mut y)
            .n(n)
            .n(n)
            .n(B),
    );
    assert_vec3s_close(&y, &Matrix::eval(&a1 * x.ex()), "bsr3 spmv, shared values");

    // Jacobi (inverse diagonal lanes) and block-Jacobi (inverse diagonal blocks)
    let diag: Vec<u64> = p.diagonal_entries().iter().map(|d| d.unwrap() as u64).collect();
    let mut bad = vec![7u32; n * B];
    let mut inv = vec![Vec3::<f64>::default(); n * B];
    emu().launch(
        "gpumat_jacobi_setup_bsr3_f64",
        rows_grid,
        Args::default()
            .buf(a.values())
            .out(&mut inv)
            .buf(&diag)
            .n(nnz)
            .out(&mut bad)
            .n(n)
            .n(B),
    );
    assert!(bad.iter().all(|&b| b == 0));
    let mut z = vec![Vec3::<f64>::default(); n * B];
    emu().launch(
        "gpumat_jacobi_apply_vec3_f64",
        rows_grid,
        Args::default().buf(&inv).buf(x.as_slice()).out(&mut z).n(n * B),
    );
    let mut cpu = Matrix::zeros(n, 1, B);
    Jacobi::new(&a).unwrap().apply(&x, &mut cpu);
    assert_vec3s_close(&z, &cpu, "jacobi");
    let mut binv = vec![Mat3::<f64>::default(); n * B];
    emu().launch(
        "gpumat_block_jacobi_setup_f64",
        rows_grid,
        Args::default()
            .buf(a.values())
            .out(&mut binv)
            .buf(&diag)
            .n(nnz)
            .out(&mut bad)
            .n(n)
            .n(B),
    );
    assert!(bad.iter().all(|&b| b == 0));
    emu().launch(
        "gpumat_block_jacobi_apply_f64",
        rows_grid,
        Args::default().buf(&binv).buf(x.as_slice()).out(&mut z).n(n * B),
    );
    BlockJacobi::new(&a).unwrap().apply(&x, &mut cpu);
    assert_vec3s_close(&z, &cpu, "block jacobi");
    // a singular diagonal block is flagged, as the CPU's Error::SingularDiagonal
    let mut sing = a.clone();
    sing.values_mut()[diag[5] as usize] = Mat3::default();
    emu().launch(
        "gpumat_block_jacobi_setup_f64",
        rows_grid,
        Args::default()
            .buf(sing.values())
            .out(&mut binv)
            .buf(&diag)
            .n(nnz)
            .out(&mut bad)
            .n(n)
            .n(B),
    );
    assert_eq!(bad.iter().filter(|&&b| b != 0).count(), 1);
    assert_eq!(bad[5], 1);

    // Newmark: A = cm M + ck K and b = (cm M + cb K) u + cv M v + dt f on one pattern
    let (m, k) = (bsr(n, B, 11), bsr(n, B, 11));
    let k = SparseMatrix::from_values(
        m.pattern().clone(),
        B,
        k.values()
            .iter()
            .map(|v| *v * 3.0 + Mat3::from_scalar(0.5))
            .collect(),
    );
    let (cm, ck, cb, cv, dt) = (2.5f64, 0.75, -0.125, 1.0 / 0.6, 0.01);
    let mut av = vec![Mat3::<f64>::default(); nnz * B];
    emu().launch(
        "gpumat_newmark_a_bsr3_f64",
        launch::elementwise(nnz * B),
        Args::default()
            .buf(m.values())
            .buf(k.values())
            .out(&mut av)
            .val(cm)
            .val(ck)
            .n(nnz * B),
    );
    for (i, g) in av.iter().enumerate() {
        let c = m.values()[i] * cm + k.values()[i] * ck;
        for (gr, cr) in g.m.iter().flatten().zip(c.m.iter().flatten()) {
            assert!(close(*gr, *cr, 1e-12), "newmark A entry {i}");
        }
    }
    let (u, v, f) = (vec3s(n, B, 12), vec3s(n, B, 13), vec3s(n, B, 14));
    let mut rhs = vec![Vec3::<f64>::default(); n * B];
    emu().launch(
        "gpumat_newmark_b_bsr3_f64",
        rows_grid,
        Args::default()
            .buf(&row_ptr)
            .buf(p.col_idx())
            .buf(m.values())
            .buf(k.values())
            .n(nnz)
            .buf(u.as_slice())
            .buf(v.as_slice())
            .buf(f.as_slice())
            .out(&mut rhs)
            .val(cm)
            .val(cb)
            .val(cv)
            .val(dt)
            .n(n)
            .n(B),
    );
    let mu = Matrix::eval(&m * u.ex());
    let ku = Matrix::eval(&k * u.ex());
    let mv = Matrix::eval(&m * v.ex());
    let cpu_b = Matrix::eval(mu.ex().scale(cm) + ku.ex().scale(cb) + mv.ex().scale(cv) + f.ex().scale(dt));
    for (i, (g, c)) in rhs.iter().zip(cpu_b.as_slice()).enumerate() {
        assert!(
            close(g.x, c.x, 1e-10) && close(g.y, c.y, 1e-10) && close(g.z, c.z, 1e-10),
            "newmark b {i}: {g:?} {c:?}"
        );
    }
}

#[test]
fn cg_updates_and_scalars_follow_each_batch() {
    if !emu::compiler_available() {
        return;
    }
    let n = 300;
    let (x0, r0, p0, ap) = (vec3s(n, B, 21), vec3s(n, B, 22), vec3s(n, B, 23), vec3s(n, B, 24));
    let (mut x, mut r) = (x0.as_slice().to_vec(), r0.as_slice().to_vec());
    let alpha = [0.5f64, -2.0];
    let active = [1u32, 0]; // batch 1 has converged: untouched
    emu().launch(
        "gpumat_cg_update_xr_vec3_f64",
        launch::elementwise(n * B),
        Args::default()
            .out(&mut x)
            .out(&mut r)
            .buf(p0.as_slice())
            .buf(ap.as_slice())
            .buf(&alpha)
            .buf(&active)
            .n(n)
            .n(B),
    );
    let a = Matrix::<f64>::from_fn(1, 1, B, |_, _, b| alpha[b] * active[b] as f64);
    let cpu_x = Matrix::eval(x0.ex() + a.ex().cwise_mul(p0.ex()));
    let cpu_r = Matrix::eval(r0.ex() - a.ex().cwise_mul(ap.ex()));
    assert_vec3s_close(&x, &cpu_x, "x += alpha p");
    assert_vec3s_close(&r, &cpu_r, "r -= alpha Ap");
    // p = z + beta p
    let z = vec3s(n, B, 25);
    let mut p = p0.as_slice().to_vec();
    let beta = [0.25f64, 3.0];
    emu().launch(
        "gpumat_cg_update_p_vec3_f64",
        launch::elementwise(n * B),
        Args::default()
            .out(&mut p)
            .buf(z.as_slice())
            .buf(&beta)
            .buf(&[1u32, 1])
            .n(n)
            .n(B),
    );
    let bm = Matrix::<f64>::from_fn(1, 1, B, |_, _, b| beta[b]);
    assert_vec3s_close(
        &p,
        &Matrix::eval(z.ex() + bm.ex().cwise_mul(p0.ex())),
        "p = z + beta p",
    );
    // the fused (r.z, r.r) reduction and the per-batch scalars
    let parts = launch::reduction_parts(n) as usize;
    let mut partials = vec![[0.0f64; 2]; parts * B];
    let mut rz_rr = vec![[0.0f64; 2]; B];
    emu().launch(
        "gpumat_cg_dot2_partial_vec3_f64",
        launch::reduction(n, B),
        Args::default()
            .buf(r0.as_slice())
            .buf(z.as_slice())
            .n(n)
            .out(&mut partials),
    );
    emu().launch(
        "gpumat_reduce_sum_finish_pair_f64",
        launch::reduction_finish(B),
        Args::default().buf(&partials).n(parts).out(&mut rz_rr),
    );
    let rz = r0.ex().dot_over(z.ex(), Axes::ROWS);
    let rr = r0.ex().squared_norm_over(Axes::ROWS);
    for b in 0..B {
        assert!(close(rz_rr[b][0], rz.get(0, 0, b), 1e-12) && close(rz_rr[b][1], rr.get(0, 0, b), 1e-12));
    }
    let pap = [2.0f64, 4.0];
    let mut al = [9.0f64; 2];
    emu().launch(
        "gpumat_cg_alpha_f64",
        launch::elementwise(B),
        Args::default()
            .buf(&rz_rr)
            .buf(&pap)
            .buf(&[1u32, 0])
            .out(&mut al)
            .n(B),
    );
    assert!(close(al[0], rz_rr[0][0] / 2.0, 1e-15) && al[1] == 0.0, "{al:?}");
    // batch 0 converges (|r|^2 <= tol2), batch 1 goes on: beta = rz_new / rz_old
    let mut rz_old = [1.0f64, 2.0];
    let tol2 = [rz_rr[0][1] * 2.0, rz_rr[1][1] * 0.5];
    let (mut act, mut its, mut be) = ([1u32, 1], [4u32, 4], [9.0f64; 2]);
    emu().launch(
        "gpumat_cg_beta_f64",
        launch::elementwise(B),
        Args::default()
            .buf(&rz_rr)
            .out(&mut rz_old)
            .buf(&tol2)
            .out(&mut act)
            .out(&mut its)
            .out(&mut be)
            .n(B),
    );
    assert_eq!(act, [0, 1]);
    assert_eq!(its, [5, 5]);
    assert!(be[0] == 0.0 && close(be[1], rz_rr[1][0] / 2.0, 1e-15), "{be:?}");
}
