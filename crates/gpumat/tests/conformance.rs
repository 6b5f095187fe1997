//! One conformance suite, written once and stamped per backend (cubecl's `testgen_*!` macros
//! are the model): the block-sparse SpMV, the Newmark-1 matrix, block-Jacobi and the batched
//! CG, each checked against an independent dense reference (plain loops over the triplets, not
//! gpumat's sparse code) and, for the device backends, against the CPU backend.
//!
//! Backends: `cpu` (gpumat's host types), `emulated` (the catalogue's CUDA kernels run by the
//! host emulation of CUDA through [`gpumat::device`]; skipped without a C++ compiler, except with
//! `CI=true`) and `cuda` (a real GPU through the same code; skipped, with a line saying so, when
//! none is present). The expression kernels are checked one by one in `tests/emulated_expr.rs`.

mod emu;

use emu::rnd;
use gpumat::device::{
    device_cg, device_cg_in, Device, DeviceBlockJacobi, DeviceBsr3, DeviceBuffer, DeviceCgParams,
    DeviceCgWork, DevicePattern,
};
use gpumat::{cg, BlockJacobi, CgError, CgInfo, CgParams, Error, Mat3, Matrix, SparseMatrix, Vec3};
use std::sync::{Arc, OnceLock};

/// What the suite asks of a backend (host data in, host data out).
trait Backend {
    fn spmv(&self, a: &SparseMatrix<Mat3<f64>>, x: &Matrix<Vec3<f64>>) -> Matrix<Vec3<f64>>;
    fn newmark(
        &self,
        m: &SparseMatrix<Mat3<f64>>,
        k: &SparseMatrix<Mat3<f64>>,
        cm: f64,
        ck: f64,
    ) -> SparseMatrix<Mat3<f64>>;
    fn block_jacobi(
        &self,
        a: &SparseMatrix<Mat3<f64>>,
        r: &Matrix<Vec3<f64>>,
    ) -> Result<Matrix<Vec3<f64>>, Error>;
    #[allow(clippy::type_complexity)]
    fn cg(
        &self,
        a: &SparseMatrix<Mat3<f64>>,
        b: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        params: &CgParams<f64>,
    ) -> Result<CgInfo<f64>, CgError<f64>>;
    /// True when a device runs the kernels (then the CPU is a second reference).
    fn is_device(&self) -> bool;
}

struct Cpu;

impl Backend for Cpu {
    fn spmv(&self, a: &SparseMatrix<Mat3<f64>>, x: &Matrix<Vec3<f64>>) -> Matrix<Vec3<f64>> {
        Matrix::eval(a * x)
    }
    fn newmark(
        &self,
        m: &SparseMatrix<Mat3<f64>>,
        k: &SparseMatrix<Mat3<f64>>,
        cm: f64,
        ck: f64,
    ) -> SparseMatrix<Mat3<f64>> {
        let vals = m
            .values()
            .iter()
            .zip(k.values())
            .map(|(&m, &k)| m * cm + k * ck)
            .collect();
        SparseMatrix::from_values(m.pattern().clone(), m.batches(), vals)
    }
    fn block_jacobi(
        &self,
        a: &SparseMatrix<Mat3<f64>>,
        r: &Matrix<Vec3<f64>>,
    ) -> Result<Matrix<Vec3<f64>>, Error> {
        use gpumat::Preconditioner;
        let p = BlockJacobi::new(a)?;
        let mut z = Matrix::zeros_shape(r.shape());
        p.apply(r, &mut z);
        Ok(z)
    }
    fn cg(
        &self,
        a: &SparseMatrix<Mat3<f64>>,
        b: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        params: &CgParams<f64>,
    ) -> Result<CgInfo<f64>, CgError<f64>> {
        let p = BlockJacobi::new(a).expect("block-Jacobi");
        cg(a, b, x, &p, params)
    }
    fn is_device(&self) -> bool {
        false
    }
}

/// Any [`Device`]: the data goes up, the kernels run there, the result comes back.
struct OnDevice(Arc<dyn Device>);

impl OnDevice {
    fn matrix(&self, a: &SparseMatrix<Mat3<f64>>) -> DeviceBsr3<f64> {
        let p = Arc::new(DevicePattern::new(&self.0, a.pattern()).unwrap());
        DeviceBsr3::from_host(&p, a).unwrap()
    }
    fn vector(&self, x: &Matrix<Vec3<f64>>) -> DeviceBuffer<Vec3<f64>> {
        DeviceBuffer::from_slice(&self.0, x.as_slice()).unwrap()
    }
    fn back(&self, x: &DeviceBuffer<Vec3<f64>>, like: &Matrix<Vec3<f64>>) -> Matrix<Vec3<f64>> {
        let s = like.shape();
        Matrix::from_vec(s.rows, s.cols, s.batches, x.to_vec().unwrap())
    }
}

impl Backend for OnDevice {
    fn spmv(&self, a: &SparseMatrix<Mat3<f64>>, x: &Matrix<Vec3<f64>>) -> Matrix<Vec3<f64>> {
        let da = self.matrix(a);
        let dx = self.vector(x);
        let mut dy = DeviceBuffer::zeros(&self.0, a.rows() * a.batches()).unwrap();
        da.spmv(&dx, &mut dy).unwrap();
        let like = Matrix::<Vec3<f64>>::zeros(a.rows(), 1, a.batches());
        self.back(&dy, &like)
    }
    fn newmark(
        &self,
        m: &SparseMatrix<Mat3<f64>>,
        k: &SparseMatrix<Mat3<f64>>,
        cm: f64,
        ck: f64,
    ) -> SparseMatrix<Mat3<f64>> {
        let p = Arc::new(DevicePattern::new(&self.0, m.pattern()).unwrap());
        let dm = DeviceBsr3::from_host(&p, m).unwrap();
        let dk = DeviceBsr3::from_host(&p, k).unwrap();
        let mut da = DeviceBsr3::zeros(&p, m.batches()).unwrap();
        da.assign_newmark(&dm, &dk, cm, ck).unwrap();
        da.to_host().unwrap()
    }
    fn block_jacobi(
        &self,
        a: &SparseMatrix<Mat3<f64>>,
        r: &Matrix<Vec3<f64>>,
    ) -> Result<Matrix<Vec3<f64>>, Error> {
        let da = self.matrix(a);
        let p = DeviceBlockJacobi::new(&da)?;
        let dr = self.vector(r);
        let mut dz = DeviceBuffer::zeros(&self.0, r.as_slice().len()).unwrap();
        p.apply(&dr, &mut dz).unwrap();
        Ok(self.back(&dz, r))
    }
    fn cg(
        &self,
        a: &SparseMatrix<Mat3<f64>>,
        b: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        params: &CgParams<f64>,
    ) -> Result<CgInfo<f64>, CgError<f64>> {
        let da = self.matrix(a);
        let p = DeviceBlockJacobi::new(&da).expect("block-Jacobi");
        let db = self.vector(b);
        let mut dx = self.vector(x);
        let params = DeviceCgParams {
            cg: *params,
            check_every: 5,
        };
        let out = device_cg(&da, &db, &mut dx, &p, &params);
        *x = self.back(&dx, x);
        out
    }
    fn is_device(&self) -> bool {
        true
    }
}

fn emulated() -> Option<OnDevice> {
    static D: OnceLock<Option<Arc<dyn Device>>> = OnceLock::new();
    D.get_or_init(|| {
        emu::compiler_available()
            .then(|| gpumat::device::emulated::EmulatedDevice::open(&emu::dir()).unwrap())
    })
    .clone()
    .map(OnDevice)
}

// ---- references ------------------------------------------------------------------------------

/// A random SPD-like block matrix on a banded pattern: `n` block rows, `batches` value sets.
fn spd(n: usize, batches: usize, seed: u64) -> SparseMatrix<Mat3<f64>> {
    let mut t: Vec<(usize, usize, Mat3<f64>)> = Vec::new();
    let block = |r: usize, c: usize| Mat3 {
        m: std::array::from_fn(|i| {
            std::array::from_fn(|j| 0.5 * rnd(seed, 9 * (r.min(c) * n + r.max(c)) + 3 * i.min(j) + i.max(j)))
        }),
    };
    for r in 0..n {
        for c in [
            r.saturating_sub(3),
            r.saturating_sub(1),
            r,
            (r + 1).min(n - 1),
            (r + 3).min(n - 1),
        ] {
            if t.iter().any(|&(a, b, _)| a == r && b == c) {
                continue;
            }
            let m = if r == c {
                block(r, r) + Mat3::from_scalar(6.0)
            } else {
                block(r, c)
            };
            t.push((r, c, m));
        }
    }
    let one = SparseMatrix::from_triplets(n, n, &t);
    let vals = (0..batches)
        .flat_map(|b| one.values().iter().map(move |m| *m * (1.0 + 0.5 * b as f64)))
        .collect();
    SparseMatrix::from_values(one.pattern().clone(), batches, vals)
}

fn vec3s(n: usize, batches: usize, seed: u64) -> Matrix<Vec3<f64>> {
    Matrix::from_fn(n, 1, batches, |r, _, b| {
        let i = 3 * (r + n * b);
        Vec3::new(rnd(seed, i), rnd(seed, i + 1), rnd(seed, i + 2))
    })
}

/// `y = A x` by plain loops over the stored blocks (the dense reference).
fn dense_mul(a: &SparseMatrix<Mat3<f64>>, x: &Matrix<Vec3<f64>>) -> Vec<[f64; 3]> {
    let (n, nb) = (a.rows(), a.batches());
    let p = a.pattern();
    let mut y = vec![[0.0; 3]; n * nb];
    for b in 0..nb {
        for r in 0..n {
            for j in p.row_range(r) {
                let c = p.col_idx()[j] as usize;
                let m = a.batch_values(b)[j];
                let v = x.get(c, 0, b);
                for (i, yi) in y[r + n * b].iter_mut().enumerate() {
                    *yi += m.m[i][0] * v.x + m.m[i][1] * v.y + m.m[i][2] * v.z;
                }
            }
        }
    }
    y
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

fn assert_close(got: &Matrix<Vec3<f64>>, want: &[[f64; 3]], tol: f64, what: &str) {
    for (i, (g, w)) in got.as_slice().iter().zip(want).enumerate() {
        let ok = close(g.x, w[0], tol) && close(g.y, w[1], tol) && close(g.z, w[2], tol) && g.w == 0.0;
        assert!(ok, "{what}: element {i}: {g:?}, reference {w:?}");
    }
}

// ---- the suite -------------------------------------------------------------------------------

fn spmv_matches_dense(be: &dyn Backend) {
    // 700 rows: three blocks of 256 threads with a ragged last one; 3 batches
    let a = spd(700, 3, 11);
    let x = vec3s(700, 3, 12);
    let y = be.spmv(&a, &x);
    assert_close(&y, &dense_mul(&a, &x), 1e-12, "spmv");
}

fn newmark_matrix_is_the_combination(be: &dyn Backend) {
    let m = spd(300, 2, 21);
    let k = spd(300, 2, 22);
    let k = SparseMatrix::from_values(m.pattern().clone(), 2, k.values().to_vec());
    let (cm, ck) = (1.0 / (0.5 * 0.01) + 0.3, 0.02 + 0.5 * 0.01);
    let a = be.newmark(&m, &k, cm, ck);
    for (i, ((g, mm), kk)) in a.values().iter().zip(m.values()).zip(k.values()).enumerate() {
        for r in 0..3 {
            for c in 0..3 {
                let want = cm * mm.m[r][c] + ck * kk.m[r][c];
                assert!(
                    close(g.m[r][c], want, 1e-14),
                    "A entry {i} ({r},{c}): {} vs {want}",
                    g.m[r][c]
                );
            }
        }
    }
}

fn block_jacobi_inverts_the_diagonal(be: &dyn Backend) {
    let a = spd(300, 2, 31);
    let r = vec3s(300, 2, 32);
    let z = be.block_jacobi(&a, &r).unwrap();
    // D z = r, block row by block row
    for b in 0..2 {
        for i in 0..300 {
            let d = a.get(i, i, b);
            let zi = z.get(i, 0, b);
            let ri = r.get(i, 0, b);
            for (l, rl) in [ri.x, ri.y, ri.z].into_iter().enumerate() {
                let dz = d.m[l][0] * zi.x + d.m[l][1] * zi.y + d.m[l][2] * zi.z;
                assert!(close(dz, rl, 1e-12), "D z = r at row {i} lane {l}: {dz} vs {rl}");
            }
        }
    }
    // a singular diagonal block is an error naming the row and batch, as on the CPU
    let mut s = a.clone();
    let pos = s.pattern().find(5, 5).unwrap();
    s.batch_values_mut(1)[pos] = Mat3::default();
    match be.block_jacobi(&s, &r) {
        Err(Error::SingularDiagonal { row: 5, batch: 1 }) => {}
        other => panic!("singular block: {other:?}"),
    }
}

fn cg_solves_each_batch_to_its_tolerance(be: &dyn Backend) {
    let n = 400;
    let a = spd(n, 3, 41);
    let b = vec3s(n, 3, 42);
    let mut x = Matrix::zeros(n, 1, 3);
    let params = CgParams {
        max_iterations: 500,
        tolerance: 1e-10,
        absolute_tolerance: 0.0,
    };
    let info = be.cg(&a, &b, &mut x, &params).unwrap();
    // the true residual against the dense product
    let ax = dense_mul(&a, &x);
    for bi in 0..3 {
        let (mut rr, mut bb) = (0.0, 0.0);
        for i in 0..n {
            let bv = b.get(i, 0, bi);
            for (l, bl) in [bv.x, bv.y, bv.z].into_iter().enumerate() {
                rr += (bl - ax[i + n * bi][l]).powi(2);
                bb += bl * bl;
            }
        }
        let rel = (rr / bb).sqrt();
        assert!(rel <= 2e-10, "batch {bi}: true relative residual {rel:e}");
        assert!(info.converged[bi] && info.residual[bi] <= 1e-10, "{info:?}");
    }
    if be.is_device() {
        // the same iterations as the CPU, batch by batch, and the same solution to rounding
        let mut xc = Matrix::zeros(n, 1, 3);
        let cpu = Cpu.cg(&a, &b, &mut xc, &params).unwrap();
        for bi in 0..3 {
            assert!(
                cpu.iterations[bi].abs_diff(info.iterations[bi]) <= 1,
                "batch {bi}: device {} iterations, cpu {}",
                info.iterations[bi],
                cpu.iterations[bi]
            );
        }
        let want: Vec<[f64; 3]> = xc.as_slice().iter().map(|v| [v.x, v.y, v.z]).collect();
        assert_close(&x, &want, 1e-8, "cg solution vs cpu");
    }
    // each batch stops on its own: batch 2 starts at its solution, batch 0 and 1 do not
    let mut x2 = x.clone();
    for i in 0..n {
        x2.set(i, 0, 0, Vec3::default());
    }
    let again = be.cg(&a, &b, &mut x2, &params).unwrap();
    assert_eq!(
        again.iterations[2], 0,
        "a batch that starts converged takes no step: {again:?}"
    );
    assert!(again.iterations[0] > 0);
    for i in 0..n {
        assert_eq!(
            x2.get(i, 0, 2),
            x.get(i, 0, 2),
            "the converged batch's x stays put"
        );
    }
}

fn cg_reports_failures(be: &dyn Backend) {
    let n = 100;
    // a negative definite matrix (with its own block-Jacobi: both negated): the curvature
    // p.Ap < 0 is NotPositiveDefinite (the device sees it at its first check)
    let a = spd(n, 1, 51);
    let vals: Vec<Mat3<f64>> = a.values().iter().map(|&m| m * -1.0).collect();
    let neg = SparseMatrix::from_values(a.pattern().clone(), 1, vals);
    let b = vec3s(n, 1, 52);
    let mut x = Matrix::zeros(n, 1, 1);
    let params = CgParams {
        max_iterations: 50,
        tolerance: 1e-10,
        absolute_tolerance: 0.0,
    };
    match be.cg(&neg, &b, &mut x, &params) {
        Err(CgError::NotPositiveDefinite {
            batch: 0, curvature, ..
        }) => assert!(curvature < 0.0),
        other => panic!("negative definite: {other:?}"),
    }
    // a non-finite right-hand side is an error, not a silent stop
    let mut bad = b.clone();
    bad.set(3, 0, 0, Vec3::new(f64::NAN, 0.0, 0.0));
    let mut x = Matrix::zeros(n, 1, 1);
    match be.cg(&a, &bad, &mut x, &params) {
        Err(CgError::NonFinite { batch: 0, .. }) => {}
        other => panic!("NaN in b: {other:?}"),
    }
    // too few iterations: NoConvergence with the info
    let mut x = Matrix::zeros(n, 1, 1);
    let few = CgParams {
        max_iterations: 3,
        ..params
    };
    match be.cg(&a, &b, &mut x, &few) {
        Err(CgError::NoConvergence { info }) => assert_eq!(info.iterations[0], 3, "{info:?}"),
        other => panic!("3 iterations: {other:?}"),
    }
}

/// A device CG's buffers kept between solves ([`DeviceCgWork`]) give each solve the bits of a
/// solve in fresh buffers: solves of two systems (another size, then the first again) in one
/// set of buffers against each in its own.
fn reused_work_gives_fresh_bits(be: &OnDevice) {
    let params = DeviceCgParams {
        cg: CgParams::default(),
        check_every: 3,
    };
    let systems = [(40, 3, 11), (25, 2, 12), (40, 3, 13)];
    let solve = |(n, nb, seed): (usize, usize, u64), work: Option<&mut DeviceCgWork<f64>>| {
        let a = spd(n, nb, seed);
        let da = be.matrix(&a);
        let p = DeviceBlockJacobi::new(&da).expect("block-Jacobi");
        let db = be.vector(&vec3s(n, nb, seed + 100));
        let mut dx = be.vector(&Matrix::zeros(n, 1, nb));
        let info = match work {
            Some(w) => device_cg_in(w, &da, &db, &mut dx, &p, &params),
            None => device_cg(&da, &db, &mut dx, &p, &params),
        }
        .expect("converges");
        (dx.to_vec().unwrap(), info.iterations)
    };
    let mut work = DeviceCgWork::new(&be.0, 40, 3).unwrap();
    for sys in systems {
        let fresh = solve(sys, None);
        let kept = solve(sys, Some(&mut work));
        assert!(fresh.1.iter().all(|&k| k > 3), "{:?}", fresh.1);
        assert_eq!(fresh.1, kept.1, "iterations, system {sys:?}");
        let bits =
            |v: &[Vec3<f64>]| -> Vec<u64> { v.iter().flat_map(|x| x.to_array()).map(f64::to_bits).collect() };
        assert_eq!(bits(&fresh.0), bits(&kept.0), "solution, system {sys:?}");
    }
}

#[test]
fn emulated_reused_work() {
    match emulated() {
        Some(be) => reused_work_gives_fresh_bits(&be),
        None => eprintln!("SKIPPED emulated reused work: no C++ compiler"),
    }
}

#[test]
fn cuda_reused_work() {
    match gpu() {
        Some(be) => reused_work_gives_fresh_bits(&be),
        None => eprintln!("SKIPPED cuda reused work: no GPU"),
    }
}

/// Stamps the suite for one backend: `$make` gives `Option<impl Backend>` (None: skipped).
macro_rules! conformance {
    ($name:ident, $make:expr) => {
        mod $name {
            use super::*;
            fn with(f: fn(&dyn Backend)) {
                match $make {
                    Some(be) => f(&be),
                    None => eprintln!(
                        "SKIPPED {} conformance: backend not available",
                        stringify!($name)
                    ),
                }
            }
            #[test]
            fn spmv() {
                with(spmv_matches_dense)
            }
            #[test]
            fn newmark() {
                with(newmark_matrix_is_the_combination)
            }
            #[test]
            fn block_jacobi() {
                with(block_jacobi_inverts_the_diagonal)
            }
            #[test]
            fn cg_converges() {
                with(cg_solves_each_batch_to_its_tolerance)
            }
            #[test]
            fn cg_failures() {
                with(cg_reports_failures)
            }
        }
    };
}

/// CUDA device 0 (the tests' gpumat has feature `cuda`), or None with the reason printed.
fn gpu() -> Option<OnDevice> {
    static D: OnceLock<Option<Arc<dyn Device>>> = OnceLock::new();
    D.get_or_init(|| match gpumat::device::CudaDevice::new(0) {
        Ok(d) => Some(d),
        Err(e) => {
            eprintln!("no GPU: {e}");
            None
        }
    })
    .clone()
    .map(OnDevice)
}

conformance!(cpu, Some(Cpu));
conformance!(emulated, emulated());
conformance!(cuda, gpu());
