//! Data on a device and the kernels that work on it: the seam between gpumat's host types and a
//! CUDA-like device (architecture principle 2: the algorithms are written once, over
//! [`Device`]).
//!
//! A [`Device`] is the driver-level contract: zeroed allocations addressed by a 64-bit device
//! pointer, copies to and from the host, and launches of the build-time catalogue's kernels
//! ([`crate::cuda::catalogue`]) by name on a [`Grid`] from [`crate::cuda::launch`], with
//! `cuLaunchKernel`-style arguments ([`Arg`]). Two devices implement it:
//!
//! - `CudaDevice` (feature `cuda`, `device/cuda.rs`): a CUDA context and stream through cudarc's
//!   driver API; the catalogue is compiled by NVRTC for the device's `sm_XX` when the device is
//!   opened (cached on disk by [`crate::cuda::cache::KernelCache`] under `cache_dir()`), loaded
//!   as one module per source, and launched with `cuLaunchKernel`. Without CUDA on the machine
//!   `CudaDevice::new` is [`Error::CudaUnavailable`] with one line, never a panic.
//! - [`emulated::EmulatedDevice`] (feature `emulate`, for tests): the same catalogue compiled by
//!   the system C++ compiler against a host emulation of CUDA (blocks one after another, a
//!   block's threads as OS threads, `__syncthreads` a barrier), its memory host memory. It runs
//!   the kernels' real index arithmetic and synchronisation through the same host code as a GPU.
//!
//! On top, written once for both: [`DeviceBuffer`] (typed, owned, freed on drop), the 3x3
//! block-sparse matrix [`DeviceBsr3`] (pattern uploaded once, values every step), its SpMV, the
//! Newmark-1 matrix `A = cm M + ck K` (thesis eq. 4.3), block-Jacobi, and the batched CG
//! [`device_cg`] with its read-back policy ([`DeviceCgParams::check_every`]).
//!
//! Element types cross the seam bit for bit: [`crate::Vec3`] is a 16-byte-aligned
//! `float4`/`double4` (w = 0) and [`crate::Mat3`] nine reals, row by row, as in
//! `kernels/block3.cuh` (`tests/emulated.rs` checks the arithmetic of both against Rust's).

mod bsr;
mod cg;
#[cfg(feature = "cuda")]
mod cuda;
#[cfg(feature = "emulate")]
pub mod emulated;

pub use bsr::{DeviceBlockJacobi, DeviceBsr3, DevicePattern};
pub use cg::{device_cg, device_cg_in, DeviceCgParams, DeviceCgWork};
#[cfg(feature = "cuda")]
pub use cuda::{cache_dir, CudaDevice};

use crate::cuda::launch::Grid;
use crate::error::Error;
use crate::scalar::Real;
use std::sync::Arc;

/// One kernel argument, passed by value (`cuLaunchKernel` receives a pointer to each).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Arg {
    /// a device pointer (`T*`)
    Ptr(u64),
    /// `gpumat_index` (unsigned long long)
    Index(u64),
    /// `unsigned int`
    U32(u32),
    /// `float`
    F32(f32),
    /// `double`
    F64(f64),
}

impl Arg {
    /// The 8-byte slot `cuLaunchKernel` reads the value from: the value's own bytes (native
    /// endianness) at its start, zeros after a 4-byte value.
    pub fn slot(&self) -> u64 {
        let mut out = [0u8; 8];
        match *self {
            Arg::Ptr(v) | Arg::Index(v) => out.copy_from_slice(&v.to_ne_bytes()),
            Arg::U32(v) => out[..4].copy_from_slice(&v.to_ne_bytes()),
            Arg::F32(v) => out[..4].copy_from_slice(&v.to_ne_bytes()),
            Arg::F64(v) => out.copy_from_slice(&v.to_ne_bytes()),
        }
        u64::from_ne_bytes(out)
    }
}

/// A device: memory and launches of the catalogue's kernels (module docs).
///
/// The memory methods and [`Device::launch`] are `unsafe`: they take raw device addresses.
/// [`DeviceBuffer`] and the types built on it are the safe interface.
pub trait Device: Send + Sync + std::fmt::Debug {
    /// A human-readable name (device, architecture).
    fn name(&self) -> String;
    /// Allocates `bytes` zeroed bytes, aligned to 16 (`bytes > 0`).
    fn alloc_zeroed(&self, bytes: usize) -> Result<u64, Error>;
    /// Frees an allocation of this device.
    ///
    /// # Safety
    /// `ptr` came from [`Device::alloc_zeroed`] of this device and is not used afterwards.
    unsafe fn free(&self, ptr: u64);
    /// Copies `src` to device address `dst`.
    ///
    /// # Safety
    /// `dst .. dst + src.len()` lies in one live allocation of this device.
    unsafe fn upload(&self, dst: u64, src: &[u8]) -> Result<(), Error>;
    /// Copies from device address `src` into `dst` (waits for queued work).
    ///
    /// # Safety
    /// `src .. src + dst.len()` lies in one live allocation of this device.
    unsafe fn download(&self, src: u64, dst: &mut [u8]) -> Result<(), Error>;
    /// Queues kernel `kernel` of the catalogue on `grid`.
    ///
    /// # Safety
    /// `args` match the kernel's parameter list in number and type, and every pointer addresses
    /// live allocations of this device large enough for what the kernel reads and writes.
    unsafe fn launch(&self, kernel: &str, grid: Grid, args: &[Arg]) -> Result<(), Error>;
    /// Waits until all queued work is done.
    fn synchronize(&self) -> Result<(), Error>;
}

/// A real type the catalogue has kernels for: its kernel-name suffix and argument.
pub trait DeviceReal: Real + bytemuck::Pod {
    /// `f32` or `f64` (the catalogue's suffix)
    const SUFFIX: &'static str;
    /// The value as a kernel argument.
    fn arg(self) -> Arg;
}

impl DeviceReal for f32 {
    const SUFFIX: &'static str = "f32";
    fn arg(self) -> Arg {
        Arg::F32(self)
    }
}

impl DeviceReal for f64 {
    const SUFFIX: &'static str = "f64";
    fn arg(self) -> Arg {
        Arg::F64(self)
    }
}

/// A typed allocation on a device, freed on drop.
#[derive(Debug)]
pub struct DeviceBuffer<T> {
    device: Arc<dyn Device>,
    ptr: u64,
    len: usize,
    _t: std::marker::PhantomData<T>,
}

impl<T: bytemuck::Pod> DeviceBuffer<T> {
    /// `len` zeroed elements.
    pub fn zeros(device: &Arc<dyn Device>, len: usize) -> Result<Self, Error> {
        let bytes = (len * std::mem::size_of::<T>()).max(16);
        Ok(Self {
            device: device.clone(),
            ptr: device.alloc_zeroed(bytes)?,
            len,
            _t: std::marker::PhantomData,
        })
    }
    /// A copy of `data`.
    pub fn from_slice(device: &Arc<dyn Device>, data: &[T]) -> Result<Self, Error> {
        let mut b = Self::zeros(device, data.len())?;
        b.upload(data)?;
        Ok(b)
    }
    /// Overwrites the buffer with `data` (same length).
    pub fn upload(&mut self, data: &[T]) -> Result<(), Error> {
        assert_eq!(data.len(), self.len, "DeviceBuffer::upload: length differs");
        if data.is_empty() {
            return Ok(());
        }
        // SAFETY: the buffer holds `len` elements of T, exactly `data`'s bytes.
        unsafe { self.device.upload(self.ptr, bytemuck::cast_slice(data)) }
    }
    /// Copies the buffer into `out` (same length).
    pub fn download(&self, out: &mut [T]) -> Result<(), Error> {
        assert_eq!(out.len(), self.len, "DeviceBuffer::download: length differs");
        if out.is_empty() {
            return Ok(());
        }
        // SAFETY: the buffer holds `len` elements of T, exactly `out`'s bytes.
        unsafe { self.device.download(self.ptr, bytemuck::cast_slice_mut(out)) }
    }
    /// The buffer as a new vector.
    pub fn to_vec(&self) -> Result<Vec<T>, Error> {
        let mut v = vec![T::zeroed(); self.len];
        self.download(&mut v)?;
        Ok(v)
    }
    /// Elements.
    pub fn len(&self) -> usize {
        self.len
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The device address as a kernel argument.
    pub fn arg(&self) -> Arg {
        Arg::Ptr(self.ptr)
    }
    /// The device holding the buffer.
    pub fn device(&self) -> &Arc<dyn Device> {
        &self.device
    }
}

impl<T> Drop for DeviceBuffer<T> {
    fn drop(&mut self) {
        // SAFETY: `ptr` came from this device's alloc_zeroed and the buffer is its only owner.
        unsafe { self.device.free(self.ptr) }
    }
}
