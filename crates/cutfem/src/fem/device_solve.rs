//! The step's linear solve on a device (`[numerics] backend = "cuda"`, issue 16): `A`'s block
//! pattern is uploaded once and kept while it stays the same, `A`'s values and `b`, `x` every
//! solve; block-Jacobi and the batched CG run there ([`gpumat::device::device_cg`], thesis Alg.
//! 4.1, reading the convergence state back every [`CHECK_EVERY`] iterations); `x` comes back.
//! Assembly, contact and the Newmark right-hand side stay on the host.
//!
//! On the device the preconditioner is block-Jacobi whatever `[numerics] preconditioner` says
//! (IC(0)'s and Cholesky's triangular solves are sequential and not on the device), and a
//! repeated matrix is not factored ([`super::solver`]'s `reuse_factor` is a host path). When CG
//! fails (no convergence, indefinite), the host's fallback (a sparse Cholesky solve) runs as
//! on the CPU; a failing device call is an error.
//!
//! Which device: [`cuda_device`] opens CUDA device 0 once per process (feature `cuda`); a
//! build without the feature, or a machine without CUDA, gets a one-line
//! [`gpumat::Error::CudaUnavailable`]. Tests pass any [`Device`] (the emulated one) with
//! [`crate::fem::Simulation::set_device`].

use gpumat::device::{
    device_cg_in, Device, DeviceBlockJacobi, DeviceBsr3, DeviceBuffer, DeviceCgParams, DeviceCgWork,
    DevicePattern,
};
use gpumat::{CgError, CgInfo, CgParams, Mat3, Matrix, SparseMatrix, Vec3};
use std::sync::Arc;

/// The device CG reads its per-batch state back every this many iterations.
pub const CHECK_EVERY: usize = 8;

/// Where a simulation's linear solves run (`[numerics] backend`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ComputeBackend {
    /// the host (gpumat's CPU backend)
    #[default]
    Cpu,
    /// a CUDA device (module docs)
    Cuda,
}

impl ComputeBackend {
    /// The scene name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Cpu => "cpu",
            Self::Cuda => "cuda",
        }
    }
}

/// CUDA device 0, opened once per process (module docs).
pub fn cuda_device() -> Result<Arc<dyn Device>, gpumat::Error> {
    #[cfg(feature = "cuda")]
    {
        static DEVICE: std::sync::OnceLock<Result<Arc<dyn Device>, gpumat::Error>> =
            std::sync::OnceLock::new();
        DEVICE.get_or_init(|| gpumat::device::CudaDevice::new(0)).clone()
    }
    #[cfg(not(feature = "cuda"))]
    {
        Err(gpumat::Error::CudaUnavailable(
            "this build has no CUDA support (build softbody with --features cuda)".into(),
        ))
    }
}

/// A device and what stays on it between solves.
#[derive(Debug)]
pub struct DeviceSolver {
    device: Arc<dyn Device>,
    pattern: Option<Arc<DevicePattern>>,
    a: Option<DeviceBsr3<f64>>,
    /// the CG's vectors, kept while the system's size stays
    work: Option<DeviceCgWork<f64>>,
}

impl DeviceSolver {
    /// Solves on `device`.
    pub fn new(device: Arc<dyn Device>) -> Self {
        Self {
            device,
            pattern: None,
            a: None,
            work: None,
        }
    }

    /// The device's name.
    pub fn name(&self) -> String {
        self.device.name()
    }

    /// Solves `a x = b` from `x` with block-Jacobi CG on the device. The outer error is a
    /// device or preconditioner failure; the inner one CG's own outcome.
    pub fn solve(
        &mut self,
        a: &SparseMatrix<Mat3<f64>>,
        b: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        cg: &CgParams<f64>,
    ) -> Result<Result<CgInfo<f64>, CgError<f64>>, gpumat::Error> {
        let same = self.pattern.as_ref().is_some_and(|p| p.is(a.pattern()));
        if !same {
            self.pattern = Some(Arc::new(DevicePattern::new(&self.device, a.pattern())?));
            self.a = None;
        }
        let pattern = self.pattern.as_ref().expect("uploaded above");
        let da = match self.a.take() {
            Some(mut m) if m.batches() == a.batches() => {
                m.upload_values(a)?;
                m
            }
            _ => DeviceBsr3::from_host(pattern, a)?,
        };
        let da = self.a.insert(da);
        let pre = DeviceBlockJacobi::new(da)?;
        let db = DeviceBuffer::from_slice(&self.device, b.as_slice())?;
        let mut dx = DeviceBuffer::from_slice(&self.device, x.as_slice())?;
        let params = DeviceCgParams {
            cg: *cg,
            check_every: CHECK_EVERY,
        };
        let work = match self.work.take() {
            Some(w) if w.fits(&self.device, da.rows(), da.batches()) => w,
            _ => DeviceCgWork::new(&self.device, da.rows(), da.batches())?,
        };
        let work = self.work.insert(work);
        let out = device_cg_in(work, da, &db, &mut dx, &pre, &params);
        if let Err(CgError::Device(e)) = out {
            return Err(e);
        }
        dx.download(x.as_mut_slice())?;
        Ok(out)
    }
}
