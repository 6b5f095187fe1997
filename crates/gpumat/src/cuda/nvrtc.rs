//! Compiling gpumat's CUDA sources with NVRTC (feature `cuda`; no GPU needed).
//!
//! [`load`] finds `libnvrtc` (by name through `LD_LIBRARY_PATH`, or from a folder such as the
//! one `crates/gpumat/tools/nvrtc.sh` installs the PyPI wheel into, which it loads first by
//! absolute path, so that cudarc's lookup by name finds the already loaded library). A missing
//! library is [`Error::CudaUnavailable`], never a panic. [`compile`] turns one
//! [`KernelSource`] into PTX (`compute_XX`) or a CUBIN (`sm_XX`, with `ptxas -v`), passing
//! gpumat's [`headers`] in memory; [`resources`] reads registers, stack, spills and shared
//! memory per kernel from the `ptxas` log.

use super::{headers, KernelSource, NVRTC_OPTIONS};
use crate::error::Error;
use cudarc::nvrtc::sys;
use std::ffi::{c_char, CString};
use std::path::Path;
use std::sync::OnceLock;

/// What NVRTC produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// PTX for a virtual architecture, `compute_{0}`
    Ptx(u32),
    /// machine code for a real architecture, `sm_{0}`
    Cubin(u32),
}

/// One compiled source.
#[derive(Clone, Debug)]
pub struct Compiled {
    /// PTX text or CUBIN bytes
    pub image: Vec<u8>,
    /// NVRTC's log (with `ptxas info` lines for CUBIN targets)
    pub log: String,
}

/// Resource use of one kernel as `ptxas -v` reports it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Resources {
    /// the entry point
    pub kernel: String,
    /// registers per thread
    pub registers: u32,
    /// bytes of stack frame per thread
    pub stack: u64,
    /// bytes of register spill stores
    pub spill_stores: u64,
    /// bytes of register spill loads
    pub spill_loads: u64,
    /// bytes of static shared memory
    pub shared: u64,
}

static LOADED: OnceLock<Result<(i32, i32), Error>> = OnceLock::new();
static PRELOADED: OnceLock<Vec<libloading::Library>> = OnceLock::new();

/// Loads NVRTC (once per process) and returns its version `(major, minor)`. With `dir`, the
/// `libnvrtc*.so*` files in it are loaded first by path.
pub fn load(dir: Option<&Path>) -> Result<(i32, i32), Error> {
    LOADED.get_or_init(|| load_now(dir)).clone()
}

fn load_now(dir: Option<&Path>) -> Result<(i32, i32), Error> {
    if let Some(dir) = dir {
        let mut libs: Vec<_> = std::fs::read_dir(dir)
            .map_err(|e| Error::CudaUnavailable(format!("NVRTC folder {}: {e}", dir.display())))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                let n = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
                n.starts_with("libnvrtc") && n.contains(".so") && !n.contains(".alt.")
            })
            .collect();
        // the builtins first: libnvrtc opens them when it compiles
        libs.sort_by_key(|p| !p.to_string_lossy().contains("builtins"));
        let mut kept = Vec::new();
        for lib in libs {
            // SAFETY: loads NVIDIA's NVRTC shared libraries, whose initialisers only set up
            // the library itself; the handles are kept for the life of the process.
            match unsafe { libloading::Library::new(&lib) } {
                Ok(l) => kept.push(l),
                Err(e) => {
                    return Err(Error::CudaUnavailable(format!(
                        "cannot load {}: {e}",
                        lib.display()
                    )))
                }
            }
        }
        let _ = PRELOADED.set(kept);
    }
    // SAFETY: only tries to open the NVRTC library by its usual names (cudarc would panic
    // later if it were missing; this is the check that prevents it).
    if !unsafe { sys::is_culib_present() } {
        return Err(Error::CudaUnavailable(match dir {
            Some(d) => format!("no loadable libnvrtc.so in {}", d.display()),
            None => "libnvrtc.so not found (set GPUMAT_NVRTC_DIR or LD_LIBRARY_PATH; \
                     crates/gpumat/tools/nvrtc.sh installs it)"
                .into(),
        }));
    }
    let (mut major, mut minor) = (0, 0);
    // SAFETY: NVRTC is loaded (checked above); the out-pointers are valid locals.
    let rc = unsafe { sys::nvrtcVersion(&mut major, &mut minor) };
    if rc != sys::nvrtcResult::NVRTC_SUCCESS {
        return Err(Error::CudaUnavailable(format!("nvrtcVersion failed: {rc:?}")));
    }
    Ok((major, minor))
}

/// The real architectures (`sm_XX` as `XX`) this NVRTC can compile CUBINs for, ascending.
/// Call [`load`] first.
pub fn supported_archs() -> Result<Vec<u32>, Error> {
    load(None)?;
    let mut n = 0i32;
    // SAFETY: NVRTC is loaded (checked above); `n` is a valid out-pointer.
    let rc = unsafe { sys::nvrtcGetNumSupportedArchs(&mut n) };
    if rc != sys::nvrtcResult::NVRTC_SUCCESS {
        return Err(Error::CudaUnavailable(format!(
            "nvrtcGetNumSupportedArchs failed: {rc:?}"
        )));
    }
    let mut archs = vec![0i32; n.max(0) as usize];
    // SAFETY: `archs` has the `n` entries NVRTC reported.
    let rc = unsafe { sys::nvrtcGetSupportedArchs(archs.as_mut_ptr()) };
    if rc != sys::nvrtcResult::NVRTC_SUCCESS {
        return Err(Error::CudaUnavailable(format!(
            "nvrtcGetSupportedArchs failed: {rc:?}"
        )));
    }
    let mut out: Vec<u32> = archs.into_iter().filter(|&a| a > 0).map(|a| a as u32).collect();
    out.sort_unstable();
    Ok(out)
}

fn cstring(s: &str, what: &str) -> Result<CString, Error> {
    CString::new(s).map_err(|_| Error::Compile(format!("{what} contains a NUL byte")))
}

/// Compiles `src` for `target` with [`NVRTC_OPTIONS`] and `extra` options. A CUBIN target adds
/// `--ptxas-options=-v`, so the log carries the resource lines [`resources`] reads. Call
/// [`load`] first.
pub fn compile(src: &KernelSource, target: Target, extra: &[&str]) -> Result<Compiled, Error> {
    load(None)?;
    let code = cstring(&src.source, &src.name)?;
    let name = cstring(&src.name, "source name")?;
    let hs = headers();
    let h_text: Vec<CString> = hs.iter().map(|h| cstring(h.1, h.0)).collect::<Result<_, _>>()?;
    let h_name: Vec<CString> = hs.iter().map(|h| cstring(h.0, h.0)).collect::<Result<_, _>>()?;
    let h_text_p: Vec<*const c_char> = h_text.iter().map(|c| c.as_ptr()).collect();
    let h_name_p: Vec<*const c_char> = h_name.iter().map(|c| c.as_ptr()).collect();
    let arch = match target {
        Target::Ptx(a) => format!("--gpu-architecture=compute_{a}"),
        Target::Cubin(a) => format!("--gpu-architecture=sm_{a}"),
    };
    let mut opts = vec![arch];
    opts.extend(NVRTC_OPTIONS.iter().map(|s| s.to_string()));
    if matches!(target, Target::Cubin(_)) {
        opts.push("--ptxas-options=-v".into());
    }
    opts.extend(extra.iter().map(|s| s.to_string()));
    let opts: Vec<CString> = opts
        .iter()
        .map(|o| cstring(o, "option"))
        .collect::<Result<_, _>>()?;
    let opts_p: Vec<*const c_char> = opts.iter().map(|c| c.as_ptr()).collect();

    let mut prog: sys::nvrtcProgram = std::ptr::null_mut();
    // SAFETY: NVRTC is loaded; every pointer is a NUL-terminated string alive for the call, the
    // header arrays have `hs.len()` entries each, and `prog` is a valid out-pointer.
    let rc = unsafe {
        sys::nvrtcCreateProgram(
            &mut prog,
            code.as_ptr(),
            name.as_ptr(),
            hs.len() as i32,
            h_text_p.as_ptr(),
            h_name_p.as_ptr(),
        )
    };
    if rc != sys::nvrtcResult::NVRTC_SUCCESS {
        return Err(Error::Compile(format!(
            "{}: nvrtcCreateProgram: {rc:?}",
            src.name
        )));
    }
    // SAFETY: `prog` was created above; the options outlive the call.
    let rc = unsafe { sys::nvrtcCompileProgram(prog, opts_p.len() as i32, opts_p.as_ptr()) };
    let log = program_log(prog);
    let out = if rc != sys::nvrtcResult::NVRTC_SUCCESS {
        let first = log
            .lines()
            .find(|l| l.contains("error"))
            .unwrap_or("no error line in the log")
            .trim();
        let errors = log.lines().filter(|l| l.contains("error")).count();
        Err(Error::Compile(format!(
            "{}: {first} ({errors} error lines)",
            src.name
        )))
    } else {
        image(prog, target).map(|image| Compiled { image, log })
    };
    // SAFETY: `prog` was created above and is destroyed once.
    unsafe { sys::nvrtcDestroyProgram(&mut prog) };
    out
}

fn program_log(prog: sys::nvrtcProgram) -> String {
    let mut n = 0usize;
    // SAFETY: `prog` is a live program; `n` is a valid out-pointer.
    if unsafe { sys::nvrtcGetProgramLogSize(prog, &mut n) } != sys::nvrtcResult::NVRTC_SUCCESS {
        return String::new();
    }
    let mut buf = vec![0u8; n.max(1)];
    // SAFETY: `buf` has the size NVRTC reported for the log.
    unsafe { sys::nvrtcGetProgramLog(prog, buf.as_mut_ptr().cast()) };
    String::from_utf8_lossy(&buf).trim_end_matches('\0').to_string()
}

fn image(prog: sys::nvrtcProgram, target: Target) -> Result<Vec<u8>, Error> {
    let mut n = 0usize;
    let fail = |what: &str, rc| Error::Compile(format!("{what}: {rc:?}"));
    match target {
        Target::Ptx(_) => {
            // SAFETY: `prog` compiled successfully; `n` is a valid out-pointer.
            let rc = unsafe { sys::nvrtcGetPTXSize(prog, &mut n) };
            if rc != sys::nvrtcResult::NVRTC_SUCCESS {
                return Err(fail("nvrtcGetPTXSize", rc));
            }
            let mut buf = vec![0u8; n];
            // SAFETY: `buf` has the size NVRTC reported.
            let rc = unsafe { sys::nvrtcGetPTX(prog, buf.as_mut_ptr().cast()) };
            if rc != sys::nvrtcResult::NVRTC_SUCCESS {
                return Err(fail("nvrtcGetPTX", rc));
            }
            Ok(buf)
        }
        Target::Cubin(_) => {
            // SAFETY: as above.
            let rc = unsafe { sys::nvrtcGetCUBINSize(prog, &mut n) };
            if rc != sys::nvrtcResult::NVRTC_SUCCESS {
                return Err(fail("nvrtcGetCUBINSize", rc));
            }
            let mut buf = vec![0u8; n];
            // SAFETY: `buf` has the size NVRTC reported.
            let rc = unsafe { sys::nvrtcGetCUBIN(prog, buf.as_mut_ptr().cast()) };
            if rc != sys::nvrtcResult::NVRTC_SUCCESS {
                return Err(fail("nvrtcGetCUBIN", rc));
            }
            Ok(buf)
        }
    }
}

/// The per-kernel resources in a `ptxas -v` log (empty for PTX targets).
pub fn resources(log: &str) -> Vec<Resources> {
    let mut out: Vec<Resources> = Vec::new();
    let num = |s: &str, before: &str| -> Option<u64> {
        let head = &s[..s.find(before)?];
        head.split_whitespace().last()?.parse().ok()
    };
    for line in log.lines() {
        if let Some(rest) = line.split("Compiling entry function '").nth(1) {
            let kernel = rest.split('\'').next().unwrap_or("").to_string();
            out.push(Resources {
                kernel,
                ..Resources::default()
            });
        } else if let Some(r) = out.last_mut() {
            if line.contains("bytes stack frame") {
                r.stack = num(line, "bytes stack frame").unwrap_or(0);
                r.spill_stores = num(line, "bytes spill stores").unwrap_or(0);
                r.spill_loads = num(line, "bytes spill loads").unwrap_or(0);
            } else if line.contains("Used") && line.contains("registers") {
                r.registers = num(line, "registers").unwrap_or(0) as u32;
                r.shared = num(line, "bytes smem").unwrap_or(0);
            }
        }
    }
    out
}
