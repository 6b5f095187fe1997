//! Backends. The CPU backend is the default and the one that runs everything today.
//!
//! With feature `cuda`, [`Cuda::new`] checks that the CUDA driver library (`libcuda`) and
//! NVRTC (`libnvrtc`) can be loaded before touching cudarc (which panics on a missing library),
//! then opens a context on the device: on a machine without CUDA it returns
//! [`Error::CudaUnavailable`] with one line (the checks are [`crate::cuda`]'s
//! `check_libraries`, shared with the device). This type only opens the context; device memory,
//! kernel launches and the device CG are [`crate::device`]'s (`CudaDevice`, feature `cuda`).
//! Without the feature [`Cuda::new`] is a stub returning the same typed error, so code written
//! against the backend choice compiles and reports clearly (architecture principle 2; candle's
//! `dummy_cuda_backend`).

use crate::error::Error;

/// Where the data of a computation lives and where its loops run.
pub trait Backend: Send + Sync + std::fmt::Debug {
    /// Human-readable name.
    fn name(&self) -> String;
    /// Waits until all queued work is done.
    fn synchronize(&self) -> Result<(), Error>;
}

/// The CPU backend: host memory, loops on rayon's thread pool.
#[derive(Clone, Copy, Debug, Default)]
pub struct Cpu;

impl Backend for Cpu {
    fn name(&self) -> String {
        format!("cpu ({} threads)", rayon::current_num_threads())
    }
    fn synchronize(&self) -> Result<(), Error> {
        Ok(())
    }
}

/// The CUDA backend: a context on one device (see the module docs for what it can do).
#[derive(Debug)]
pub struct Cuda {
    #[cfg(feature = "cuda")]
    ctx: std::sync::Arc<cudarc::driver::CudaContext>,
    #[cfg(not(feature = "cuda"))]
    _private: (),
}

impl Cuda {
    /// Opens CUDA device `ordinal`; [`Error::CudaUnavailable`] when the driver, NVRTC or the
    /// device is missing.
    #[cfg(feature = "cuda")]
    pub fn new(ordinal: usize) -> Result<Self, Error> {
        crate::cuda::check_libraries()?;
        let ctx = cudarc::driver::CudaContext::new(ordinal)
            .map_err(|e| Error::CudaUnavailable(format!("device {ordinal}: {e:?}")))?;
        Ok(Self { ctx })
    }
    /// Opens CUDA device `ordinal`: always an error in a build without feature `cuda`.
    #[cfg(not(feature = "cuda"))]
    pub fn new(ordinal: usize) -> Result<Self, Error> {
        Err(Error::CudaUnavailable(format!(
            "device {ordinal} requested, but gpumat was built without feature `cuda`"
        )))
    }
}

impl Backend for Cuda {
    fn name(&self) -> String {
        #[cfg(feature = "cuda")]
        {
            let name = self.ctx.name().unwrap_or_else(|_| "unknown device".into());
            format!("cuda ({name}, device {})", self.ctx.ordinal())
        }
        #[cfg(not(feature = "cuda"))]
        {
            "cuda".into()
        }
    }
    fn synchronize(&self) -> Result<(), Error> {
        #[cfg(feature = "cuda")]
        {
            self.ctx
                .synchronize()
                .map_err(|e| Error::CudaUnavailable(format!("synchronize: {e:?}")))
        }
        #[cfg(not(feature = "cuda"))]
        {
            Err(Error::CudaUnavailable(
                "gpumat was built without feature `cuda`".into(),
            ))
        }
    }
}
