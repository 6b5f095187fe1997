//! The CUDA device (feature `cuda`): a context and one stream on a GPU through cudarc's driver
//! API, the build-time catalogue ([`crate::cuda::catalogue`]) compiled by NVRTC for the device's
//! architecture and loaded as one module per source, its kernels launched by name.
//!
//! - [`CudaDevice::new`] checks the libraries first ([`crate::cuda::check_libraries`]: cudarc
//!   panics on a missing library), so a machine without CUDA gets
//!   [`Error::CudaUnavailable`] with one line. It compiles every catalogue source to a CUBIN for
//!   `sm_XX` of the device (PTX for the newest architecture NVRTC knows when NVRTC is older than
//!   the device), through a [`KernelCache`] on disk ([`cache_dir`]), so later runs load the
//!   images without compiling.
//! - Memory: `cuMemAllocAsync` / `cuMemFreeAsync` on the device's stream when the device has
//!   memory pools, else `cuMemAlloc` / `cuMemFree` (after the stream's work); zeroed with
//!   `cuMemsetD8Async`. The 16-byte alignment of the [`Device`] contract is checked (`cuMemAlloc`
//!   aligns to 256 bytes).
//! - Copies are queued on the stream and waited for: [`Device::upload`] returns once the host
//!   slice has been read, [`Device::download`] once the data is there (after the stream's
//!   earlier work).
//! - [`Device::launch`]: `cuLaunchKernel` on the stream, grid `(blocks.0, blocks.1, 1)`, block
//!   `(threads, 1, 1)`, no dynamic shared memory; each argument's value in an 8-byte slot.
//!
//! Every driver call first makes the context current on the calling thread, so the device can
//! be used from any thread. Driver failures are [`Error::Device`].

use super::{Arg, Device};
use crate::cuda::cache::KernelCache;
use crate::cuda::launch::Grid;
use crate::cuda::nvrtc::{self, Target};
use crate::cuda::KernelSource;
use crate::error::Error;
use cudarc::driver::{result, CudaContext, CudaFunction, CudaModule, CudaStream, DriverError};
use cudarc::nvrtc::Ptx;
use rayon::prelude::*;
use std::collections::HashMap;
use std::ffi::c_void;
use std::path::PathBuf;
use std::sync::Arc;

/// A CUDA GPU with the catalogue loaded (module docs).
pub struct CudaDevice {
    ctx: Arc<CudaContext>,
    stream: Arc<CudaStream>,
    name: String,
    arch: u32,
    target: Target,
    /// kept for the life of the device (the functions also hold them)
    modules: Vec<Arc<CudaModule>>,
    kernels: HashMap<String, CudaFunction>,
}

impl std::fmt::Debug for CudaDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CudaDevice")
            .field("ordinal", &self.ctx.ordinal())
            .field("name", &self.name)
            .field("arch", &self.arch)
            .field("target", &self.target)
            .field("modules", &self.modules.len())
            .field("kernels", &self.kernels.len())
            .finish()
    }
}

/// The kernel cache folder: `$GPUMAT_KERNEL_CACHE` when set, else `$XDG_CACHE_HOME/gpumat`,
/// else `$HOME/.cache/gpumat`; `None` (memory only) when none of them is set.
pub fn cache_dir() -> Option<PathBuf> {
    let var = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty()).map(PathBuf::from);
    var("GPUMAT_KERNEL_CACHE")
        .or_else(|| var("XDG_CACHE_HOME").map(|d| d.join("gpumat")))
        .or_else(|| var("HOME").map(|d| d.join(".cache").join("gpumat")))
}

/// A driver error as a gpumat error, with what was being done.
fn device_err(what: impl std::fmt::Display) -> impl Fn(DriverError) -> Error {
    move |e| Error::Device(format!("{what}: {e}"))
}

/// The image to build for a device of architecture `arch`, given NVRTC's real architectures:
/// a CUBIN for `sm_{arch}` when NVRTC knows it (or cannot say), else PTX for the newest
/// architecture below it, which the driver compiles for the device at load time.
fn target_for(arch: u32, supported: Option<&[u32]>) -> Target {
    match supported {
        Some(archs) if !archs.is_empty() && !archs.contains(&arch) => {
            let below = archs.iter().copied().filter(|&a| a <= arch).max();
            Target::Ptx(below.unwrap_or(arch))
        }
        _ => Target::Cubin(arch),
    }
}

/// Compiles `src` for `target`; a CUBIN that NVRTC refuses is retried as PTX for the same
/// architecture (the first error is reported when both fail).
fn compile(cache: &KernelCache, src: &KernelSource, target: Target) -> Result<(Target, Vec<u8>), Error> {
    match cache.get_or_compile(src, target) {
        Ok(c) => Ok((target, c.image.clone())),
        Err(first) => match target {
            Target::Cubin(a) => cache
                .get_or_compile(src, Target::Ptx(a))
                .map(|c| (Target::Ptx(a), c.image.clone()))
                .map_err(|_| first),
            Target::Ptx(_) => Err(first),
        },
    }
}

impl CudaDevice {
    /// Opens CUDA device `ordinal` and loads the catalogue (compiling it on first use), as the
    /// shared [`Device`] the device types take ([`CudaDevice::open`] for the concrete type).
    ///
    /// [`Error::CudaUnavailable`] (one line, never a panic) when the driver library, NVRTC or
    /// the device is missing; [`Error::Compile`] when NVRTC rejects a source;
    /// [`Error::Device`] when the driver cannot load a module or find an entry point.
    #[allow(clippy::new_ret_no_self)] // the seam's constructor: a shared Device
    pub fn new(ordinal: usize) -> Result<Arc<dyn Device>, Error> {
        Ok(Arc::new(Self::open(ordinal)?))
    }

    /// [`CudaDevice::new`] as the concrete type (for [`CudaDevice::arch`] and the like).
    pub fn open(ordinal: usize) -> Result<Self, Error> {
        // before any cudarc call: cudarc panics on a missing library
        crate::cuda::check_libraries()?;
        let unavailable = |e: DriverError| Error::CudaUnavailable(format!("device {ordinal}: {e}"));
        let ctx = CudaContext::new(ordinal).map_err(unavailable)?;
        let (major, minor) = ctx.compute_capability().map_err(unavailable)?;
        let arch = (major * 10 + minor) as u32;
        let device_name = ctx.name().unwrap_or_else(|_| "unknown device".into());
        let stream = ctx.new_stream().map_err(device_err("cuStreamCreate"))?;

        let supported = nvrtc::supported_archs().ok();
        let target = target_for(arch, supported.as_deref());
        let cache = KernelCache::new(cache_dir());
        let sources = crate::cuda::catalogue();
        let images: Vec<(Target, Vec<u8>)> = sources
            .par_iter()
            .map(|s| compile(&cache, s, target))
            .collect::<Result<_, _>>()?;
        // what was built (a CUBIN that NVRTC refused falls back to PTX)
        let target = images.first().map_or(target, |i| i.0);

        let mut modules = Vec::with_capacity(sources.len());
        let mut kernels = HashMap::new();
        for (src, (built, mut image)) in sources.iter().zip(images) {
            if matches!(built, Target::Ptx(_)) && image.last() != Some(&0) {
                // cuModuleLoadData reads PTX as NUL-terminated text
                image.push(0);
            }
            let module = ctx
                .load_module(Ptx::from_binary(image))
                .map_err(device_err(format!("loading {} ({built:?})", src.name)))?;
            for entry in &src.entries {
                let f = module
                    .load_function(entry)
                    .map_err(device_err(format!("{} in {}", entry, src.name)))?;
                kernels.insert(entry.clone(), f);
            }
            modules.push(module);
        }
        let name = format!("{device_name} (sm_{arch}, device {ordinal})");
        Ok(Self {
            ctx,
            stream,
            name,
            arch,
            target,
            modules,
            kernels,
        })
    }

    /// The device's architecture, `major * 10 + minor` of its compute capability.
    pub fn arch(&self) -> u32 {
        self.arch
    }

    /// What the catalogue was compiled to (a CUBIN for the device, or PTX the driver compiles).
    pub fn target(&self) -> Target {
        self.target
    }

    /// True when the catalogue defines kernel `name`.
    pub fn has_kernel(&self, name: &str) -> bool {
        self.kernels.contains_key(name)
    }

    fn bind(&self) -> Result<(), Error> {
        self.ctx
            .bind_to_thread()
            .map_err(device_err("binding the context"))
    }
}

impl Drop for CudaDevice {
    fn drop(&mut self) {
        // the modules are unloaded next: let queued kernels finish first (errors cannot be
        // reported from here)
        let _ = self.stream.synchronize();
    }
}

impl Device for CudaDevice {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn alloc_zeroed(&self, bytes: usize) -> Result<u64, Error> {
        self.bind()?;
        let bytes = bytes.max(1);
        let stream = self.stream.cu_stream();
        let ptr = if self.ctx.has_async_alloc() {
            // SAFETY: the stream belongs to this device's context, which is current; the memory
            // is only used on this stream (every copy and launch of this device is queued on it).
            unsafe { result::malloc_async(stream, bytes) }
        } else {
            // SAFETY: the context is current; the memory is zeroed below before any use.
            unsafe { result::malloc_sync(bytes) }
        }
        .map_err(device_err(format!("allocating {bytes} bytes")))?;
        if ptr % 16 != 0 {
            // SAFETY: `ptr` was allocated above and is not handed out.
            unsafe { self.free(ptr) };
            return Err(Error::Device(format!(
                "allocation at {ptr:#x} is not 16-byte aligned"
            )));
        }
        // SAFETY: `ptr .. ptr + bytes` was just allocated in this context; the memset is queued
        // on the stream, before any later use of the memory.
        let zeroed = unsafe { result::memset_d8_async(ptr, 0, bytes, stream) };
        if let Err(e) = zeroed {
            // SAFETY: `ptr` was allocated above and is not handed out.
            unsafe { self.free(ptr) };
            return Err(device_err("zeroing an allocation")(e));
        }
        Ok(ptr)
    }

    unsafe fn free(&self, ptr: u64) {
        // Errors cannot be returned from here: they are recorded in the context, whose next
        // checked call reports them.
        self.ctx.record_err(self.ctx.bind_to_thread());
        if self.ctx.has_async_alloc() {
            // SAFETY: the caller's contract: `ptr` came from alloc_zeroed (cuMemAllocAsync on
            // this stream) and is not used afterwards; the free is ordered after the stream's
            // queued work, which may still use it.
            self.ctx
                .record_err(unsafe { result::free_async(ptr, self.stream.cu_stream()) });
        } else {
            // the queued work may still use the memory: wait for it first
            self.ctx.record_err(self.stream.synchronize());
            // SAFETY: the caller's contract: `ptr` came from alloc_zeroed (cuMemAlloc) and is
            // not used afterwards; no queued work uses it any more (synchronised above).
            self.ctx.record_err(unsafe { result::free_sync(ptr) });
        }
    }

    unsafe fn upload(&self, dst: u64, src: &[u8]) -> Result<(), Error> {
        if src.is_empty() {
            return Ok(());
        }
        self.bind()?;
        // SAFETY: the caller's contract: `dst .. dst + src.len()` lies in a live allocation of
        // this device; `src` stays borrowed until the copy has completed (synchronised below).
        unsafe { result::memcpy_htod_async(dst, src, self.stream.cu_stream()) }
            .map_err(device_err(format!("copying {} bytes to the device", src.len())))?;
        // `src` is only borrowed for this call: wait until the driver has read it
        self.stream
            .synchronize()
            .map_err(device_err("synchronising after an upload"))
    }

    unsafe fn download(&self, src: u64, dst: &mut [u8]) -> Result<(), Error> {
        if dst.is_empty() {
            return Ok(());
        }
        self.bind()?;
        // SAFETY: the caller's contract: `src .. src + dst.len()` lies in a live allocation of
        // this device; the copy is ordered after the stream's queued work, and `dst` stays
        // borrowed until it has completed (synchronised below).
        unsafe { result::memcpy_dtoh_async(dst, src, self.stream.cu_stream()) }
            .map_err(device_err(format!("copying {} bytes from the device", dst.len())))?;
        self.stream
            .synchronize()
            .map_err(device_err("synchronising after a download"))
    }

    unsafe fn launch(&self, kernel: &str, grid: Grid, args: &[Arg]) -> Result<(), Error> {
        let f = self
            .kernels
            .get(kernel)
            .ok_or_else(|| Error::Device(format!("no kernel {kernel} in the catalogue")))?;
        self.bind()?;
        // each value at the start of an 8-byte slot (Arg::slot), aligned for every argument type
        let mut slots: Vec<u64> = args.iter().map(Arg::slot).collect();
        let mut params: Vec<*mut c_void> = slots.iter_mut().map(|s| (s as *mut u64).cast()).collect();
        // SAFETY: `f` is an entry point of a module this device keeps loaded; the caller's
        // contract (Device::launch) makes `args` match its parameters and its pointers valid;
        // `params` points at the slots, which outlive the call (cuLaunchKernel copies the
        // values before it returns).
        unsafe {
            result::launch_kernel(
                f.cu_function(),
                (grid.blocks.0, grid.blocks.1, 1),
                (grid.threads, 1, 1),
                0,
                self.stream.cu_stream(),
                &mut params,
            )
        }
        .map_err(device_err(format!(
            "launching {kernel} on {:?} blocks of {}",
            grid.blocks, grid.threads
        )))
    }

    fn synchronize(&self) -> Result<(), Error> {
        self.stream
            .synchronize()
            .map_err(device_err("cuStreamSynchronize"))?;
        // an error recorded by `free` surfaces here
        self.ctx.check_err().map_err(device_err("an earlier free"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_prefers_a_cubin_for_the_device() {
        assert_eq!(target_for(90, Some(&[75, 80, 86, 89, 90])), Target::Cubin(90));
        assert_eq!(target_for(90, None), Target::Cubin(90));
        assert_eq!(target_for(120, Some(&[75, 80, 90])), Target::Ptx(90));
        assert_eq!(target_for(50, Some(&[75, 80])), Target::Ptx(50));
    }

    #[test]
    fn cache_dir_follows_the_environment_order() {
        // only reads the environment: the test does not set variables (tests run in parallel)
        let dir = cache_dir();
        if let Some(d) = std::env::var_os("GPUMAT_KERNEL_CACHE").filter(|v| !v.is_empty()) {
            assert_eq!(dir, Some(PathBuf::from(d)));
        } else if let Some(d) = std::env::var_os("XDG_CACHE_HOME").filter(|v| !v.is_empty()) {
            assert_eq!(dir, Some(PathBuf::from(d).join("gpumat")));
        } else if let Some(h) = std::env::var_os("HOME").filter(|v| !v.is_empty()) {
            assert_eq!(dir, Some(PathBuf::from(h).join(".cache/gpumat")));
        } else {
            assert_eq!(dir, None);
        }
    }
}
