//! Batched preconditioned CG on a device (thesis Alg. 4.1, sec. 3.4): the one algorithm
//! [`run_cg`] (the host's [`crate::cg`] runs it too) over the device's operations, each a
//! kernel of the catalogue.
//!
//! Per iteration, for every batch `b` at once: `q = A p`; `pq_b = p_b . q_b` (two-phase
//! reduction, fixed tree); `alpha_b = (r_b . z_b) / pq_b` (zero once the batch has stopped);
//! `x += alpha p`, `r -= alpha q` (one kernel); `z = P^-1 r`; `(r . z, r . r)` in one
//! reduction; `beta_b = (r . z)_new / (r . z)_old`, and the batch stops when
//! `||r_b||^2 <= (tol ||b_b|| + abs_tol)^2`; `p = z + beta p`. The per-batch state (`active`,
//! iteration counts, `(r.z)_old`) stays on the device, so each batch stops on its own, as on the
//! CPU, without the host.
//!
//! **Read-back policy.** The thesis and cuMat copied the residual to the host every iteration.
//! Here the host reads the `active` flags (and `p.q`, `r.r` for the failure checks) only every
//! [`DeviceCgParams::check_every`] iterations (default 8) and at the iteration limit: a stopped
//! batch's updates are masked on the device, so iterations run past its stop change nothing,
//! and the result equals a check at every iteration; at most `check_every - 1` iterations of
//! time are spent after the last batch stops. The reads are small synchronous copies (a few
//! bytes per batch); everything else is queued without waiting.
//!
//! Failures: a non-finite `r.r` or `p.q` is [`CgError::NonFinite`], `p.q <= 0` in a running
//! batch is [`CgError::NotPositiveDefinite`] (both seen at the check iterations; a kernel
//! stops a batch whose `r.z` is not finite, so it cannot run on with NaN), the limit reached
//! is [`CgError::NoConvergence`], and a failing device call is [`CgError::Device`].

use super::{Arg, Device, DeviceBlockJacobi, DeviceBsr3, DeviceBuffer, DeviceReal};
use crate::cuda::launch;
use crate::error::Error;
use crate::scalar::Scalar;
use crate::solve::{run_cg, CgError, CgInfo, CgOps, CgParams, CgState};
use crate::{Mat3, Vec3};
use std::sync::Arc;

/// Parameters of [`device_cg`].
#[derive(Clone, Copy, Debug)]
pub struct DeviceCgParams<R> {
    /// iteration limit and tolerances, as on the CPU
    pub cg: CgParams<R>,
    /// read the per-batch state back every this many iterations (module docs); at least 1
    pub check_every: usize,
}

impl<R: DeviceReal> Default for DeviceCgParams<R> {
    fn default() -> Self {
        Self {
            cg: CgParams::default(),
            check_every: 8,
        }
    }
}

/// The vectors and per-batch scalars of a solve on `n x batches` vectors: allocated once by
/// [`DeviceCgWork::new`] and reused by every [`device_cg_in`] of that size (each solve resets
/// what it reads).
pub struct DeviceCgWork<R: DeviceReal> {
    n: usize,
    nb: usize,
    r: DeviceBuffer<Vec3<R>>,
    z: DeviceBuffer<Vec3<R>>,
    p: DeviceBuffer<Vec3<R>>,
    q: DeviceBuffer<Vec3<R>>,
    partials: DeviceBuffer<R>,
    pair_partials: DeviceBuffer<[R; 2]>,
    pq: DeviceBuffer<R>,
    rz_rr: DeviceBuffer<[R; 2]>,
    rz_old: DeviceBuffer<R>,
    alpha: DeviceBuffer<R>,
    beta: DeviceBuffer<R>,
    tol2: DeviceBuffer<R>,
    active: DeviceBuffer<u32>,
    iterations: DeviceBuffer<u32>,
    /// `|b|` per batch
    norms: DeviceBuffer<R>,
}

impl<R: DeviceReal> std::fmt::Debug for DeviceCgWork<R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DeviceCgWork")
            .field("n", &self.n)
            .field("batches", &self.nb)
            .finish()
    }
}

impl<R: DeviceReal> DeviceCgWork<R>
where
    Vec3<R>: Scalar + bytemuck::Pod,
{
    /// Buffers for solves of `n` block rows and `batches` batches on `dev`.
    pub fn new(dev: &Arc<dyn Device>, n: usize, batches: usize) -> Result<Self, Error> {
        let nb = batches;
        let vec = || DeviceBuffer::<Vec3<R>>::zeros(dev, n * nb);
        let parts = launch::reduction_parts(n) as usize;
        Ok(Self {
            n,
            nb,
            r: vec()?,
            z: vec()?,
            p: vec()?,
            q: vec()?,
            partials: DeviceBuffer::zeros(dev, parts * nb)?,
            pair_partials: DeviceBuffer::zeros(dev, parts * nb)?,
            pq: DeviceBuffer::zeros(dev, nb)?,
            rz_rr: DeviceBuffer::zeros(dev, nb)?,
            rz_old: DeviceBuffer::zeros(dev, nb)?,
            alpha: DeviceBuffer::zeros(dev, nb)?,
            beta: DeviceBuffer::zeros(dev, nb)?,
            tol2: DeviceBuffer::zeros(dev, nb)?,
            active: DeviceBuffer::zeros(dev, nb)?,
            iterations: DeviceBuffer::zeros(dev, nb)?,
            norms: DeviceBuffer::zeros(dev, nb)?,
        })
    }

    /// Whether these buffers fit solves of `n` block rows and `batches` batches on `dev`.
    pub fn fits(&self, dev: &Arc<dyn Device>, n: usize, batches: usize) -> bool {
        self.n == n && self.nb == batches && Arc::ptr_eq(self.r.device(), dev)
    }
}

/// Launch helper: kernel `name` with the real type's suffix.
fn run<R: DeviceReal>(
    dev: &Arc<dyn Device>,
    name: &str,
    grid: launch::Grid,
    args: &[Arg],
) -> Result<(), Error> {
    // SAFETY: every call below passes the kernel's parameters in order (build.rs `cg`), on
    // buffers of this solve sized n x batches (vectors), parts x batches (partials) or
    // batches (scalars), as the grid assumes.
    unsafe { dev.launch(&format!("{name}_{}", R::SUFFIX), grid, args) }
}

/// `out_b = x_b . y_b` (vectors of `n` per batch).
fn dot<R: DeviceReal>(
    dev: &Arc<dyn Device>,
    w: &DeviceCgWork<R>,
    x: &DeviceBuffer<Vec3<R>>,
    y: &DeviceBuffer<Vec3<R>>,
    out: &DeviceBuffer<R>,
    n: usize,
    nb: usize,
) -> Result<(), Error>
where
    Vec3<R>: Scalar + bytemuck::Pod,
{
    let parts = launch::reduction_parts(n) as u64;
    let partial = [x.arg(), y.arg(), Arg::Index(n as u64), w.partials.arg()];
    run::<R>(
        dev,
        "gpumat_cg_dot_partial_vec3",
        launch::reduction(n, nb),
        &partial,
    )?;
    let finish = [w.partials.arg(), Arg::Index(parts), out.arg()];
    run::<R>(
        dev,
        "gpumat_reduce_sum_finish",
        launch::reduction_finish(nb),
        &finish,
    )
}

/// The device's [`CgOps`]: every vector and per-batch scalar on the device.
struct DeviceCg<'a, R: DeviceReal> {
    dev: Arc<dyn Device>,
    a: &'a DeviceBsr3<R>,
    b: &'a DeviceBuffer<Vec3<R>>,
    x: &'a mut DeviceBuffer<Vec3<R>>,
    precond: &'a DeviceBlockJacobi<R>,
    w: &'a mut DeviceCgWork<R>,
    n: usize,
    nb: usize,
}

impl<R: DeviceReal> DeviceCg<'_, R>
where
    Mat3<R>: Scalar + bytemuck::Pod,
    Vec3<R>: Scalar + bytemuck::Pod,
{
    fn nn(&self) -> Arg {
        Arg::Index(self.n as u64)
    }
    fn nbi(&self) -> Arg {
        Arg::Index(self.nb as u64)
    }
    /// `z = P^-1 r`, `(r.z, r.r)`, `beta` with each batch's stop test, `p = z + beta p`.
    fn precondition_and_turn(&mut self) -> Result<(), Error> {
        let (n, nb, nn, nbi) = (self.n, self.nb, self.nn(), self.nbi());
        let (dev, w) = (&self.dev, &mut *self.w);
        self.precond.apply(&w.r, &mut w.z)?;
        let parts = Arg::Index(launch::reduction_parts(n) as u64);
        let partial = [w.r.arg(), w.z.arg(), nn, w.pair_partials.arg()];
        run::<R>(
            dev,
            "gpumat_cg_dot2_partial_vec3",
            launch::reduction(n, nb),
            &partial,
        )?;
        let finish = [w.pair_partials.arg(), parts, w.rz_rr.arg()];
        run::<R>(
            dev,
            "gpumat_reduce_sum_finish_pair",
            launch::reduction_finish(nb),
            &finish,
        )?;
        let beta = [
            w.rz_rr.arg(),
            w.rz_old.arg(),
            w.tol2.arg(),
            w.active.arg(),
            w.iterations.arg(),
            w.beta.arg(),
            nbi,
        ];
        run::<R>(dev, "gpumat_cg_beta", launch::elementwise(nb), &beta)?;
        let update = [w.p.arg(), w.z.arg(), w.beta.arg(), w.active.arg(), nn, nbi];
        run::<R>(
            dev,
            "gpumat_cg_update_p_vec3",
            launch::elementwise(n * nb),
            &update,
        )
    }
}

impl<R: DeviceReal> CgOps<Vec3<R>> for DeviceCg<'_, R>
where
    Mat3<R>: Scalar + bytemuck::Pod,
    Vec3<R>: Scalar<Real = R> + bytemuck::Pod,
{
    fn b_norms(&mut self) -> Result<Vec<R>, CgError<R>> {
        let w = &*self.w;
        dot(&self.dev, w, self.b, self.b, &w.norms, self.n, self.nb).map_err(CgError::Device)?;
        Ok(w.norms
            .to_vec()
            .map_err(CgError::Device)?
            .iter()
            .map(|&v| v.sqrt())
            .collect())
    }
    fn start(&mut self, target: &[R]) -> Result<(), CgError<R>> {
        let tol2: Vec<R> = target.iter().map(|&t| t * t).collect();
        let e = CgError::Device;
        self.w.tol2.upload(&tol2).map_err(e)?;
        // every batch active, (r.z)_old = 1, no iterations yet (the buffers may hold a
        // previous solve's state)
        self.w.rz_old.upload(&vec![R::ONE; self.nb]).map_err(e)?;
        self.w.active.upload(&vec![1u32; self.nb]).map_err(e)?;
        self.w.iterations.upload(&vec![0u32; self.nb]).map_err(e)?;
        // r = b - A x; z, (r.z, r.r), p = z (beta from (r.z)_old = 1 on p = 0; the first beta
        // launch counts one iteration, taken off in `state`)
        self.a.spmv(self.x, &mut self.w.q).map_err(e)?;
        let args = [
            self.w.r.arg(),
            self.b.arg(),
            self.w.q.arg(),
            self.nn(),
            self.nbi(),
        ];
        run::<R>(
            &self.dev,
            "gpumat_cg_residual_vec3",
            launch::elementwise(self.n * self.nb),
            &args,
        )
        .map_err(e)?;
        self.precondition_and_turn().map_err(e)
    }
    fn iterate(&mut self, _it: usize) -> Result<(), CgError<R>> {
        let e = CgError::Device;
        let (n, nb, nn, nbi) = (self.n, self.nb, self.nn(), self.nbi());
        self.a.spmv(&self.w.p, &mut self.w.q).map_err(e)?;
        let w = &*self.w;
        dot(&self.dev, w, &w.p, &w.q, &w.pq, n, nb).map_err(e)?;
        let alpha = [w.rz_rr.arg(), w.pq.arg(), w.active.arg(), w.alpha.arg(), nbi];
        run::<R>(&self.dev, "gpumat_cg_alpha", launch::elementwise(nb), &alpha).map_err(e)?;
        let xr = [
            self.x.arg(),
            w.r.arg(),
            w.p.arg(),
            w.q.arg(),
            w.alpha.arg(),
            w.active.arg(),
            nn,
            nbi,
        ];
        run::<R>(
            &self.dev,
            "gpumat_cg_update_xr_vec3",
            launch::elementwise(n * nb),
            &xr,
        )
        .map_err(e)?;
        self.precondition_and_turn().map_err(e)
    }
    fn state(&mut self) -> Result<CgState<R>, CgError<R>> {
        let e = CgError::Device;
        let rz_rr = self.w.rz_rr.to_vec().map_err(e)?;
        Ok(CgState {
            active: self
                .w
                .active
                .to_vec()
                .map_err(e)?
                .iter()
                .map(|&f| f != 0)
                .collect(),
            rz: rz_rr.iter().map(|p| p[0]).collect(),
            rr: rz_rr.iter().map(|p| p[1]).collect(),
            pq: self.w.pq.to_vec().map_err(e)?,
            iterations: self
                .w
                .iterations
                .to_vec()
                .map_err(e)?
                .iter()
                .map(|&k| k.saturating_sub(1) as usize)
                .collect(),
        })
    }
}

/// Solves `A x = b` for every batch from the given `x` (warm start), with block-Jacobi:
/// [`run_cg`] over the device's operations, reading the state back every
/// [`DeviceCgParams::check_every`] iterations.
///
/// `b` and `x` hold `n x batches` vectors, `n = A.rows()`. The result is within rounding of
/// the CPU's [`crate::cg`] with [`crate::BlockJacobi`] (the dots are summed in another order).
pub fn device_cg<R: DeviceReal>(
    a: &DeviceBsr3<R>,
    b: &DeviceBuffer<Vec3<R>>,
    x: &mut DeviceBuffer<Vec3<R>>,
    precond: &DeviceBlockJacobi<R>,
    params: &DeviceCgParams<R>,
) -> Result<CgInfo<R>, CgError<R>>
where
    Mat3<R>: Scalar + bytemuck::Pod,
    Vec3<R>: Scalar<Real = R> + bytemuck::Pod,
{
    let mut work = DeviceCgWork::new(b.device(), a.rows(), a.batches()).map_err(CgError::Device)?;
    device_cg_in(&mut work, a, b, x, precond, params)
}

/// [`device_cg`] in buffers the caller keeps between solves ([`DeviceCgWork`]; made anew when
/// they do not fit this system).
pub fn device_cg_in<R: DeviceReal>(
    work: &mut DeviceCgWork<R>,
    a: &DeviceBsr3<R>,
    b: &DeviceBuffer<Vec3<R>>,
    x: &mut DeviceBuffer<Vec3<R>>,
    precond: &DeviceBlockJacobi<R>,
    params: &DeviceCgParams<R>,
) -> Result<CgInfo<R>, CgError<R>>
where
    Mat3<R>: Scalar + bytemuck::Pod,
    Vec3<R>: Scalar<Real = R> + bytemuck::Pod,
{
    let (n, nb) = (a.rows(), a.batches());
    assert!(
        a.cols() == n && b.len() == n * nb && x.len() == n * nb,
        "device_cg: A is {} x {n} x {nb}, b has {} and x {} vectors",
        a.cols(),
        b.len(),
        x.len()
    );
    let dev = b.device().clone();
    if !work.fits(&dev, n, nb) {
        *work = DeviceCgWork::new(&dev, n, nb).map_err(CgError::Device)?;
    }
    let w = work;
    let mut ops = DeviceCg {
        dev,
        a,
        b,
        x,
        precond,
        w,
        n,
        nb,
    };
    run_cg(&mut ops, &params.cg, params.check_every)
}
