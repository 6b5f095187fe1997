//! An emulated CUDA device for tests (feature `emulate`): gpumat's generated CUDA sources
//! compiled by the system C++ compiler (`$CXX`, else `g++`) against the host-emulation header
//! `cuda_emu.h`, loaded as a shared library and launched with `cuLaunchKernel`-style arguments
//! (an array of pointers to the argument values). Its memory is host memory.
//!
//! `cuda_emu.h`: a launch runs the grid's blocks one after another; a block's threads are OS
//! threads and `__syncthreads` is a barrier of the block; `__shared__` is a function-local
//! static (blocks do not overlap). Launches are serialised (one at a time per process).
//!
//! For every `extern "C" __global__ void NAME(PARAMS)` a thunk `NAME__emu(void** a)` calling
//! `NAME(*(T0*)a[0], ...)` is generated; `gpumat_emu_launch` runs it over the grid. Libraries
//! are cached in the given folder by a hash of their text.

use super::{Arg, Device};
use crate::cuda::launch::Grid;
use crate::cuda::{headers, KernelSource};
use crate::error::Error;
use std::collections::HashMap;
use std::ffi::c_void;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};

/// The host-emulation header.
pub const HEADER: &str = include_str!("cuda_emu.h");

type LaunchFn = unsafe extern "C" fn(unsafe extern "C" fn(*mut *mut c_void), *mut *mut c_void, u32, u32, u32);
type Thunk = unsafe extern "C" fn(*mut *mut c_void);

static LAUNCHES: Mutex<()> = Mutex::new(());

/// The parameter types of `extern "C" __global__ void NAME(PARAMS)`.
fn param_types(params: &str) -> Vec<String> {
    // drop comments (a constant's value is noted in one, with commas)
    let mut text = String::new();
    let mut rest = params;
    while let Some(i) = rest.find("/*") {
        text.push_str(&rest[..i]);
        rest = rest[i..].find("*/").map_or("", |j| &rest[i + j + 2..]);
    }
    text.push_str(rest);
    let mut out = Vec::new();
    let (mut depth, mut cur) = (0i32, String::new());
    for ch in text.chars().chain(std::iter::once(',')) {
        match ch {
            '<' | '(' => depth += 1,
            '>' | ')' => depth -= 1,
            _ => {}
        }
        if ch == ',' && depth == 0 {
            let p = cur.trim().to_string();
            if !p.is_empty() {
                let name_at = p
                    .rfind(|c: char| !(c.is_alphanumeric() || c == '_'))
                    .map_or(0, |i| i + 1);
                out.push(p[..name_at].trim().to_string());
            }
            cur.clear();
        } else {
            cur.push(ch);
        }
    }
    out
}

/// The thunks of all kernels in `src`.
fn thunks(src: &str) -> String {
    let mut out = String::new();
    let key = "extern \"C\" __global__ void ";
    for (i, _) in src.match_indices(key) {
        let rest = &src[i + key.len()..];
        let Some(open) = rest.find('(') else { continue };
        let name = &rest[..open];
        let mut depth = 0;
        let mut close = open;
        for (j, ch) in rest[open..].char_indices() {
            match ch {
                '(' => depth += 1,
                ')' => {
                    depth -= 1;
                    if depth == 0 {
                        close = open + j;
                        break;
                    }
                }
                _ => {}
            }
        }
        let args: Vec<String> = param_types(&rest[open + 1..close])
            .iter()
            .enumerate()
            .map(|(k, t)| format!("*({t}*)a[{k}]"))
            .collect();
        out.push_str(&format!(
            "extern \"C\" void {name}__emu(void** a) {{ {name}({}); }}\n",
            args.join(", ")
        ));
    }
    out
}

/// The C++ compiler: `$CXX`, else `g++`.
pub fn compiler() -> String {
    std::env::var("CXX").unwrap_or_else(|_| "g++".into())
}

/// True when the C++ compiler runs.
pub fn compiler_available() -> bool {
    Command::new(compiler())
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// A built emulation library.
#[derive(Debug)]
pub struct EmulatedLibrary {
    lib: libloading::Library,
}

impl EmulatedLibrary {
    /// Compiles `sources` (each with its thunks) into one shared library in `dir` (reused when
    /// a library of the same text is there).
    pub fn build(dir: &Path, sources: &[KernelSource]) -> Result<Self, Error> {
        let fail = |what: String| Error::CudaUnavailable(format!("emulated CUDA: {what}"));
        let inc = dir.join("include");
        std::fs::create_dir_all(&inc).map_err(|e| fail(format!("{}: {e}", inc.display())))?;
        let mut text = String::new();
        for s in sources {
            text.push_str(&s.source);
            text.push('\n');
            text.push_str(&thunks(&s.source));
        }
        let mut key = 0xCBF2_9CE4_8422_2325u64;
        crate::cuda::fnv1a(&mut key, text.as_bytes());
        crate::cuda::fnv1a(&mut key, HEADER.as_bytes());
        for (h, t) in headers() {
            crate::cuda::fnv1a(&mut key, h.as_bytes());
            crate::cuda::fnv1a(&mut key, t.as_bytes());
        }
        let so = dir.join(format!("gpumat_emu_{key:016x}.so"));
        if !so.exists() {
            for (h, t) in headers() {
                write_if_changed(&inc.join(h), t).map_err(&fail)?;
            }
            let emu_h = dir.join("cuda_emu.h");
            write_if_changed(&emu_h, HEADER).map_err(&fail)?;
            let unique = format!("{key:016x}_{}", std::process::id());
            let cpp = dir.join(format!("gpumat_emu_{unique}.cpp"));
            let tmp = dir.join(format!("gpumat_emu_{unique}.so.tmp"));
            std::fs::write(&cpp, &text).map_err(|e| fail(format!("{}: {e}", cpp.display())))?;
            let cxx = compiler();
            let out = Command::new(&cxx)
                .args([
                    "-std=c++20",
                    "-O1",
                    "-shared",
                    "-fPIC",
                    "-pthread",
                    "-w",
                    "-include",
                ])
                .arg(&emu_h)
                .arg("-I")
                .arg(&inc)
                .arg(&cpp)
                .arg("-o")
                .arg(&tmp)
                .output()
                .map_err(|e| fail(format!("cannot run {cxx}: {e}")))?;
            let _ = std::fs::remove_file(&cpp);
            if !out.status.success() {
                let first = String::from_utf8_lossy(&out.stderr)
                    .lines()
                    .find(|l| l.contains("error"))
                    .unwrap_or("")
                    .to_string();
                return Err(Error::Compile(format!("{cxx} on the emulated sources: {first}")));
            }
            std::fs::rename(&tmp, &so).map_err(|e| fail(format!("{}: {e}", so.display())))?;
        }
        // SAFETY: the library was built from gpumat's sources and the emulation header; its
        // initialisers only set up the C++ runtime.
        let lib =
            unsafe { libloading::Library::new(&so) }.map_err(|e| fail(format!("{}: {e}", so.display())))?;
        Ok(Self { lib })
    }

    /// Runs kernel `name` on `grid`; `args[i]` points at the i-th argument's value.
    ///
    /// # Safety
    /// The values behind `args` match the kernel's parameters, and its pointers address memory
    /// large enough for what the kernel reads and writes.
    pub unsafe fn launch_raw(&self, name: &str, grid: Grid, args: &mut [*mut c_void]) -> Result<(), Error> {
        let _guard = LAUNCHES.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: both symbols exist in the library built above with these signatures (thunks
        // are generated from the kernels' parameter lists); the caller vouches for the values.
        unsafe {
            let launch: libloading::Symbol<LaunchFn> = self
                .lib
                .get(b"gpumat_emu_launch")
                .map_err(|e| Error::CudaUnavailable(format!("emulated CUDA: {e}")))?;
            let thunk: libloading::Symbol<Thunk> = self
                .lib
                .get(format!("{name}__emu").as_bytes())
                .map_err(|_| Error::CudaUnavailable(format!("emulated CUDA: no kernel {name}")))?;
            launch(
                *thunk,
                args.as_mut_ptr(),
                grid.blocks.0,
                grid.blocks.1,
                grid.threads,
            );
        }
        Ok(())
    }
}

fn write_if_changed(path: &PathBuf, text: &str) -> Result<(), String> {
    if std::fs::read_to_string(path).is_ok_and(|t| t == text) {
        return Ok(());
    }
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    std::fs::write(&tmp, text)
        .and_then(|_| std::fs::rename(&tmp, path))
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// The emulated device: the catalogue's kernels on the host, its memory host memory.
#[derive(Debug)]
pub struct EmulatedDevice {
    lib: EmulatedLibrary,
    allocs: Mutex<HashMap<u64, Box<[u128]>>>,
}

impl EmulatedDevice {
    /// Builds (or reuses from `dir`) the catalogue's emulation library.
    pub fn open(dir: &Path) -> Result<Arc<dyn Device>, Error> {
        let lib = EmulatedLibrary::build(dir, &crate::cuda::catalogue())?;
        Ok(Arc::new(Self {
            lib,
            allocs: Mutex::new(HashMap::new()),
        }))
    }
    /// An error unless `ptr .. ptr + len` lies in one live allocation.
    fn check(&self, ptr: u64, len: usize) -> Result<(), Error> {
        let allocs = self.allocs.lock().unwrap_or_else(|e| e.into_inner());
        let inside = allocs.iter().any(|(&base, mem)| {
            let size = (mem.len() * 16) as u64;
            ptr >= base && ptr + len as u64 <= base + size
        });
        if inside {
            Ok(())
        } else {
            Err(Error::CudaUnavailable(format!(
                "emulated CUDA: {len} bytes at {ptr:#x} are outside every allocation"
            )))
        }
    }
}

impl Device for EmulatedDevice {
    fn name(&self) -> String {
        "emulated CUDA (host threads)".into()
    }
    fn alloc_zeroed(&self, bytes: usize) -> Result<u64, Error> {
        let mem = vec![0u128; bytes.div_ceil(16).max(1)].into_boxed_slice();
        let ptr = mem.as_ptr() as u64;
        self.allocs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(ptr, mem);
        Ok(ptr)
    }
    unsafe fn free(&self, ptr: u64) {
        self.allocs.lock().unwrap_or_else(|e| e.into_inner()).remove(&ptr);
    }
    unsafe fn upload(&self, dst: u64, src: &[u8]) -> Result<(), Error> {
        self.check(dst, src.len())?;
        // SAFETY: dst .. dst + len lies in a live allocation (checked above).
        unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), dst as *mut u8, src.len()) };
        Ok(())
    }
    unsafe fn download(&self, src: u64, dst: &mut [u8]) -> Result<(), Error> {
        self.check(src, dst.len())?;
        // SAFETY: src .. src + len lies in a live allocation (checked above).
        unsafe { std::ptr::copy_nonoverlapping(src as *const u8, dst.as_mut_ptr(), dst.len()) };
        Ok(())
    }
    unsafe fn launch(&self, kernel: &str, grid: Grid, args: &[Arg]) -> Result<(), Error> {
        let mut slots: Vec<u64> = args.iter().map(Arg::slot).collect();
        let mut ptrs: Vec<*mut c_void> = slots.iter_mut().map(|s| (s as *mut u64).cast()).collect();
        // SAFETY: the caller's contract (Device::launch); each value sits in an 8-byte slot
        // whose first bytes are the value (little or big endian alike: `slot` writes the
        // value's own representation at the start).
        unsafe { self.lib.launch_raw(kernel, grid, &mut ptrs) }
    }
    fn synchronize(&self) -> Result<(), Error> {
        Ok(())
    }
}
