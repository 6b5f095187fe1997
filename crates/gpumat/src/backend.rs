//! Backends. The CPU backend is the default and the only one built today; the CUDA backend
//! arrives with its own issue. Until then [`Cuda::new`] is a stub returning a typed error, so
//! code written against the backend choice already compiles and reports clearly
//! (architecture principle 2; candle's `dummy_cuda_backend`).

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

/// The CUDA backend (not built yet: see the module docs).
#[derive(Debug)]
pub struct Cuda {
    _private: (),
}

impl Cuda {
    /// Opens CUDA device `ordinal`. Always an error in this build.
    pub fn new(ordinal: usize) -> Result<Self, Error> {
        Err(Error::CudaUnavailable(format!(
            "device {ordinal} requested, but this build of gpumat has no CUDA backend"
        )))
    }
}

impl Backend for Cuda {
    fn name(&self) -> String {
        "cuda".into()
    }
    fn synchronize(&self) -> Result<(), Error> {
        Err(Error::CudaUnavailable("no CUDA backend in this build".into()))
    }
}
