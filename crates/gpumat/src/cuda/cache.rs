//! The NVRTC cache: a kernel is compiled at first use and kept by the hash of what decides its
//! code, in memory and (optionally) on disk.
//!
//! The key is the 64-bit FNV-1a hash of the source text (which [`crate::cuda_codegen`] derives
//! from the expression's structure, element types and shapes, so equal trees give equal text),
//! gpumat's headers, the NVRTC options, the target and NVRTC's version. On disk an image is
//! `dir/<key>-<target>.ptx|cubin`, written to a temporary name and renamed, so a reader never
//! sees half a file; a corrupt or unreadable file is compiled again.

use super::nvrtc::{self, Compiled, Target};
use super::{fnv1a, headers, KernelSource, NVRTC_OPTIONS};
use crate::error::Error;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// Compiled images by content hash (see the module docs).
#[derive(Debug, Default)]
pub struct KernelCache {
    dir: Option<PathBuf>,
    mem: Mutex<HashMap<(u64, Target), Arc<Compiled>>>,
    compiles: AtomicUsize,
    disk_hits: AtomicUsize,
}

fn target_name(t: Target) -> String {
    match t {
        Target::Ptx(a) => format!("compute_{a}.ptx"),
        Target::Cubin(a) => format!("sm_{a}.cubin"),
    }
}

impl KernelCache {
    /// A cache in memory only (`dir = None`) or also under `dir` (created when first written).
    pub fn new(dir: Option<PathBuf>) -> Self {
        Self {
            dir,
            ..Self::default()
        }
    }

    /// The cache key of `src` for `target` (stable across runs and machines).
    pub fn key(src: &KernelSource, target: Target) -> u64 {
        let mut h = 0xCBF2_9CE4_8422_2325u64;
        fnv1a(&mut h, src.source.as_bytes());
        for (name, text) in headers() {
            fnv1a(&mut h, name.as_bytes());
            fnv1a(&mut h, text.as_bytes());
        }
        for o in NVRTC_OPTIONS {
            fnv1a(&mut h, o.as_bytes());
        }
        fnv1a(&mut h, target_name(target).as_bytes());
        if let Ok((major, minor)) = nvrtc::load(None) {
            fnv1a(&mut h, format!("nvrtc {major}.{minor}").as_bytes());
        }
        h
    }

    /// The image of `src` for `target`: from memory, else from disk, else compiled by NVRTC
    /// (and stored in both).
    pub fn get_or_compile(&self, src: &KernelSource, target: Target) -> Result<Arc<Compiled>, Error> {
        let key = Self::key(src, target);
        if let Some(c) = self.lock().get(&(key, target)) {
            return Ok(c.clone());
        }
        let file = self
            .dir
            .as_ref()
            .map(|d| d.join(format!("{key:016x}-{}", target_name(target))));
        if let Some(image) = file.as_ref().and_then(|f| std::fs::read(f).ok()) {
            if !image.is_empty() {
                self.disk_hits.fetch_add(1, Ordering::Relaxed);
                let c = Arc::new(Compiled {
                    image,
                    log: String::new(),
                });
                self.lock().insert((key, target), c.clone());
                return Ok(c);
            }
        }
        let c = Arc::new(nvrtc::compile(src, target, &[])?);
        self.compiles.fetch_add(1, Ordering::Relaxed);
        if let Some(file) = file {
            // best effort: a cache that cannot be written only costs a recompile next time
            let _ = write_atomically(&file, &c.image);
        }
        self.lock().insert((key, target), c.clone());
        Ok(c)
    }

    /// How many images this cache compiled (not found in memory or on disk).
    pub fn compiles(&self) -> usize {
        self.compiles.load(Ordering::Relaxed)
    }

    /// How many images this cache read from disk.
    pub fn disk_hits(&self) -> usize {
        self.disk_hits.load(Ordering::Relaxed)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<(u64, Target), Arc<Compiled>>> {
        // a panic while holding the lock cannot leave the map half-updated (one insert)
        self.mem.lock().unwrap_or_else(|e| e.into_inner())
    }
}

fn write_atomically(file: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Some(dir) = file.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let tmp = file.with_extension(format!("tmp{}", std::process::id()));
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, file)
}
