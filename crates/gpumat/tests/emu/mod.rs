//! Builds gpumat's generated CUDA sources with the system C++ compiler against the test-only
//! emulation header `cuda_emu.h`, loads the library and launches kernels with
//! cuLaunchKernel-style arguments (an array of pointers to the argument values).
//!
//! For every `extern "C" __global__ void NAME(PARAMS)` in the sources a thunk
//! `NAME__emu(void** a)` is generated that calls `NAME(*(T0*)a[0], ...)`; `gpumat_emu_launch`
//! runs it over the grid (see `cuda_emu.h`).

use gpumat::cuda::launch::Grid;
use gpumat::cuda::{headers, KernelSource};
use std::ffi::c_void;
use std::path::PathBuf;
use std::process::Command;
use std::sync::Mutex;

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

type Launch = unsafe extern "C" fn(unsafe extern "C" fn(*mut *mut c_void), *mut *mut c_void, u32, u32, u32);

/// A built emulation library.
pub struct Emu {
    lib: libloading::Library,
}

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
        let name = &rest[..rest.find('(').unwrap()];
        let open = rest.find('(').unwrap();
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

/// True when the C++ compiler (`$CXX`, else `g++`) runs. Without it the logic checks skip and
/// say so, except with `CI=true`, where they fail.
pub fn compiler_available() -> bool {
    let cxx = std::env::var("CXX").unwrap_or_else(|_| "g++".into());
    let ok = Command::new(&cxx)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true"),
            "CI=true and the C++ compiler {cxx} is missing (needed by the emulated-CUDA check)"
        );
        eprintln!("SKIPPED emulated-CUDA check: no C++ compiler {cxx}");
    }
    ok
}

impl Emu {
    /// Compiles `sources` (each with its thunks) into one shared library named `name`.
    pub fn build(name: &str, sources: &[KernelSource]) -> Emu {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("gpumat_emu");
        std::fs::create_dir_all(&dir).unwrap();
        let inc = dir.join("include");
        std::fs::create_dir_all(&inc).unwrap();
        for (h, text) in headers() {
            std::fs::write(inc.join(h), text).unwrap();
        }
        let emu_h = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/emu/cuda_emu.h");
        let mut text = String::new();
        for s in sources {
            text.push_str(&s.source);
            text.push('\n');
            text.push_str(&thunks(&s.source));
        }
        let cpp = dir.join(format!("{name}.cpp"));
        let so = dir.join(format!("{name}.so"));
        std::fs::write(&cpp, text).unwrap();
        let cxx = std::env::var("CXX").unwrap_or_else(|_| "g++".into());
        let out = Command::new(&cxx)
            .args([
                "-std=c++20",
                "-O1",
                "-shared",
                "-fPIC",
                "-pthread",
                "-w",
                "-include",
                emu_h,
            ])
            .arg("-I")
            .arg(&inc)
            .arg(&cpp)
            .arg("-o")
            .arg(&so)
            .output()
            .unwrap_or_else(|e| panic!("cannot run {cxx}: {e}"));
        assert!(
            out.status.success(),
            "{cxx} failed on {}:\n{}",
            cpp.display(),
            String::from_utf8_lossy(&out.stderr)
                .lines()
                .take(30)
                .collect::<Vec<_>>()
                .join("\n")
        );
        // SAFETY: the library was just built from gpumat's sources and the emulation header;
        // its initialisers only set up the C++ runtime.
        let lib = unsafe { libloading::Library::new(&so) }.unwrap();
        Emu { lib }
    }

    /// Launches kernel `name` on `grid` with `args` (one launch at a time per process).
    pub fn launch(&self, name: &str, grid: Grid, args: Args) {
        let _guard = LAUNCHES.lock().unwrap_or_else(|e| e.into_inner());
        let mut ptrs: Vec<*mut c_void> = args.slots.iter().map(|s| s.0.as_ptr() as *mut c_void).collect();
        // SAFETY: both symbols exist in the library built above with these signatures (the thunk
        // is generated from the kernel's parameter list, which `args` must match: the caller
        // passes one correctly typed value per parameter; buffers outlive the launch).
        unsafe {
            let launch: libloading::Symbol<Launch> = self.lib.get(b"gpumat_emu_launch").unwrap();
            let thunk: libloading::Symbol<unsafe extern "C" fn(*mut *mut c_void)> = self
                .lib
                .get(format!("{name}__emu").as_bytes())
                .unwrap_or_else(|_| panic!("no kernel {name}"));
            launch(
                *thunk,
                ptrs.as_mut_ptr(),
                grid.blocks.0,
                grid.blocks.1,
                grid.threads,
            );
        }
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
