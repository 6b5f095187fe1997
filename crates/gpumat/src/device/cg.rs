//! Batched preconditioned CG on a device (thesis Alg. 4.1, sec. 3.4), the CPU's [`crate::cg`]
//! in the catalogue's kernels.
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
use crate::solve::{CgError, CgInfo, CgParams};
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

/// The vectors and per-batch scalars of one solve.
struct Work<R: DeviceReal> {
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
    w: &Work<R>,
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

/// Solves `A x = b` for every batch from the given `x` (warm start), with block-Jacobi.
///
/// `b` and `x` hold `n x batches` vectors, `n = A.rows()`. The result is within rounding of
/// the CPU's [`crate::cg`] with [`crate::BlockJacobi`] (the dots are summed in another order),
/// with the same per-batch iteration counts up to a tie at the tolerance.
pub fn device_cg<R: DeviceReal>(
    a: &DeviceBsr3<R>,
    b: &DeviceBuffer<Vec3<R>>,
    x: &mut DeviceBuffer<Vec3<R>>,
    precond: &DeviceBlockJacobi<R>,
    params: &DeviceCgParams<R>,
) -> Result<CgInfo<R>, CgError<R>>
where
    Mat3<R>: Scalar + bytemuck::Pod,
    Vec3<R>: Scalar + bytemuck::Pod,
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
    let e = CgError::Device;
    let vec = || DeviceBuffer::<Vec3<R>>::zeros(&dev, n * nb);
    let parts = launch::reduction_parts(n) as usize;
    let w = Work {
        r: vec().map_err(e)?,
        z: vec().map_err(e)?,
        p: vec().map_err(e)?,
        q: vec().map_err(e)?,
        partials: DeviceBuffer::zeros(&dev, parts * nb).map_err(e)?,
        pair_partials: DeviceBuffer::zeros(&dev, parts * nb).map_err(e)?,
        pq: DeviceBuffer::zeros(&dev, nb).map_err(e)?,
        rz_rr: DeviceBuffer::zeros(&dev, nb).map_err(e)?,
        rz_old: DeviceBuffer::from_slice(&dev, &vec![R::ONE; nb]).map_err(e)?,
        alpha: DeviceBuffer::zeros(&dev, nb).map_err(e)?,
        beta: DeviceBuffer::zeros(&dev, nb).map_err(e)?,
        tol2: DeviceBuffer::zeros(&dev, nb).map_err(e)?,
        active: DeviceBuffer::from_slice(&dev, &vec![1u32; nb]).map_err(e)?,
        iterations: DeviceBuffer::zeros(&dev, nb).map_err(e)?,
    };
    let mut w = w;
    // tolerances from ||b|| (one read-back)
    let bb = {
        let out = DeviceBuffer::<R>::zeros(&dev, nb).map_err(e)?;
        dot(&dev, &w, b, b, &out, n, nb).map_err(e)?;
        out.to_vec().map_err(e)?
    };
    let bnorm: Vec<R> = bb.iter().map(|&v| v.sqrt()).collect();
    let cg = &params.cg;
    let tol2: Vec<R> = bnorm
        .iter()
        .map(|&bn| {
            let t = cg.tolerance * bn + cg.absolute_tolerance;
            t * t
        })
        .collect();
    w.tol2.upload(&tol2).map_err(e)?;
    let (nn, nbi) = (Arg::Index(n as u64), Arg::Index(nb as u64));
    let vgrid = launch::elementwise(n * nb);
    let sgrid = launch::elementwise(nb);
    let pair_parts = Arg::Index(parts as u64);

    // r = b - A x, z = P^-1 r, (r.z, r.r), p = z (beta from (r.z)_old = 1 on p = 0)
    a.spmv(x, &mut w.q).map_err(e)?;
    run::<R>(
        &dev,
        "gpumat_cg_residual_vec3",
        vgrid,
        &[w.r.arg(), b.arg(), w.q.arg(), nn, nbi],
    )
    .map_err(e)?;
    let rz_rr_and_beta = |w: &mut Work<R>| -> Result<(), Error> {
        precond.apply(&w.r, &mut w.z)?;
        let partial = [w.r.arg(), w.z.arg(), nn, w.pair_partials.arg()];
        run::<R>(
            &dev,
            "gpumat_cg_dot2_partial_vec3",
            launch::reduction(n, nb),
            &partial,
        )?;
        let finish = [w.pair_partials.arg(), pair_parts, w.rz_rr.arg()];
        run::<R>(
            &dev,
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
        run::<R>(&dev, "gpumat_cg_beta", sgrid, &beta)?;
        let update = [w.p.arg(), w.z.arg(), w.beta.arg(), w.active.arg(), nn, nbi];
        run::<R>(&dev, "gpumat_cg_update_p_vec3", vgrid, &update)
    };
    rz_rr_and_beta(&mut w).map_err(e)?;

    let check_every = params.check_every.max(1);
    let mut it = 0;
    loop {
        // the check (module docs): every `check_every` iterations and at the limit
        if it % check_every == 0 || it == cg.max_iterations {
            let active = w.active.to_vec().map_err(e)?;
            let rz_rr = w.rz_rr.to_vec().map_err(e)?;
            let pq = w.pq.to_vec().map_err(e)?;
            for bi in 0..nb {
                if !rz_rr[bi][1].is_finite() || !rz_rr[bi][0].is_finite() || !pq[bi].is_finite() {
                    return Err(CgError::NonFinite {
                        batch: bi,
                        iteration: it,
                    });
                }
                if it > 0 && active[bi] != 0 && pq[bi] <= R::ZERO {
                    return Err(CgError::NotPositiveDefinite {
                        batch: bi,
                        iteration: it,
                        curvature: pq[bi],
                    });
                }
            }
            if active.iter().all(|&f| f == 0) || it == cg.max_iterations {
                break;
            }
        }
        a.spmv(&w.p, &mut w.q).map_err(e)?;
        dot(&dev, &w, &w.p, &w.q, &w.pq, n, nb).map_err(e)?;
        let alpha = [w.rz_rr.arg(), w.pq.arg(), w.active.arg(), w.alpha.arg(), nbi];
        run::<R>(&dev, "gpumat_cg_alpha", sgrid, &alpha).map_err(e)?;
        let xr = [
            x.arg(),
            w.r.arg(),
            w.p.arg(),
            w.q.arg(),
            w.alpha.arg(),
            w.active.arg(),
            nn,
            nbi,
        ];
        run::<R>(&dev, "gpumat_cg_update_xr_vec3", vgrid, &xr).map_err(e)?;
        rz_rr_and_beta(&mut w).map_err(e)?;
        it += 1;
    }
    let rz_rr = w.rz_rr.to_vec().map_err(e)?;
    let iterations = w.iterations.to_vec().map_err(e)?;
    let mut info = CgInfo {
        iterations: iterations.iter().map(|&k| k.saturating_sub(1) as usize).collect(),
        residual: vec![R::ZERO; nb],
        converged: vec![false; nb],
    };
    for bi in 0..nb {
        let scale = if bnorm[bi] > R::ZERO { bnorm[bi] } else { R::ONE };
        info.residual[bi] = rz_rr[bi][1].sqrt() / scale;
        info.converged[bi] = rz_rr[bi][1] <= tol2[bi];
    }
    if info.converged.iter().all(|&c| c) {
        Ok(info)
    } else {
        Err(CgError::NoConvergence { info })
    }
}
