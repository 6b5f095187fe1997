#![allow(dead_code)] // shared by several test binaries, each using a part
//! The emulated-CUDA test helpers: kernels built by [`gpumat::device::emulated`] (the system C++
//! compiler against the host emulation of CUDA) and launched with `cuLaunchKernel`-style
//! arguments built by [`Args`].

use gpumat::cuda::launch::Grid;
use gpumat::cuda::KernelSource;
use gpumat::device::emulated::{self, EmulatedLibrary};
use std::ffi::c_void;
use std::path::PathBuf;

/// One argument value, aligned for any element type (`double4` needs 16, `Mat3d` is 72 bytes).
#[repr(C, align(16))]
struct Slot([u8; 96]);

/// The arguments of one launch.
#[derive(Default)]
pub struct Args {
    slots: Vec<Slot>,
}

impl Args {
    /// An argument passed by value.
    pub fn val<V: Copy>(mut self, v: V) -> Self {
        assert!(std::mem::size_of::<V>() <= 96 && std::mem::align_of::<V>() <= 16);
        let mut s = Slot([0; 96]);
        // SAFETY: the slot is 96 bytes, 16-aligned, and V fits (asserted above).
        unsafe { std::ptr::write(s.0.as_mut_ptr().cast::<V>(), v) };
        self.slots.push(s);
        self
    }
    /// A read-only buffer.
    pub fn buf<T>(self, s: &[T]) -> Self {
        self.val(s.as_ptr())
    }
    /// A written buffer.
    pub fn out<T>(self, s: &mut [T]) -> Self {
        self.val(s.as_mut_ptr())
    }
    /// An index (`gpumat_index`, unsigned long long).
    #[allow(dead_code)] // used by tests/emulated.rs, not by tests/emulated_expr.rs
    pub fn n(self, v: usize) -> Self {
        self.val(v as u64)
    }
}

/// A built emulation library ([`gpumat::device::emulated::EmulatedLibrary`]).
pub struct Emu {
    lib: EmulatedLibrary,
}

/// The folder the emulation libraries are built in (and reused from).
pub fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("gpumat_emu")
}

/// True when the C++ compiler (`$CXX`, else `g++`) runs. Without it the logic checks skip and
/// say so, except with `CI=true`, where they fail.
pub fn compiler_available() -> bool {
    let ok = emulated::compiler_available();
    if !ok {
        let cxx = emulated::compiler();
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true"),
            "CI=true and the C++ compiler {cxx} is missing (needed by the emulated-CUDA check)"
        );
        eprintln!("SKIPPED emulated-CUDA check: no C++ compiler {cxx}");
    }
    ok
}

impl Emu {
    /// Compiles `sources` (each with its thunks) into one shared library.
    #[allow(dead_code)] // not every test binary builds its own
    pub fn build(sources: &[KernelSource]) -> Emu {
        let lib = EmulatedLibrary::build(&dir(), sources).unwrap_or_else(|e| panic!("{e}"));
        Emu { lib }
    }

    /// Launches kernel `name` on `grid` with `args` (one launch at a time per process).
    #[allow(dead_code)]
    pub fn launch(&self, name: &str, grid: Grid, args: Args) {
        let mut ptrs: Vec<*mut c_void> = args.slots.iter().map(|s| s.0.as_ptr() as *mut c_void).collect();
        // SAFETY: the caller passes one correctly typed value per kernel parameter, and the
        // buffers behind the pointers outlive the launch and are large enough.
        unsafe { self.lib.launch_raw(name, grid, &mut ptrs) }.unwrap_or_else(|e| panic!("{e}"));
    }
}

/// A deterministic pseudo-random value in [-1, 1) from a seed and an index.
pub fn rnd(seed: u64, i: usize) -> f64 {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (i as u64).wrapping_mul(0xD1B5_4A32_D192_ED03);
    x ^= x >> 31;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 29;
    (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}
