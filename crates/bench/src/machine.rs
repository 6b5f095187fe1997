//! What the tables were measured on: CPU, cores, date, build, STREAM bandwidth, peers.

use serde::Serialize;
use std::collections::BTreeMap;

/// The `machine` object of the JSON report.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// CPU model name (`/proc/cpuinfo`)
    pub cpu: String,
    /// logical CPUs available to this process
    pub cores: usize,
    /// rayon worker threads gpumat ran on
    pub rayon_threads: usize,
    /// last-level cache, as reported by the OS
    pub llc: Option<String>,
    /// UTC date and time of the run (ISO 8601)
    pub date: String,
    /// `quick` or `full`
    pub mode: String,
    /// STREAM triad bandwidth on all cores, GB/s (1e9 bytes/s): the best sample
    pub stream_triad_gbs: f64,
    /// the STREAM triad samples taken before, between and after the tables, GB/s
    pub stream_triad_runs_gbs: Vec<f64>,
    /// STREAM triad array length (f32 elements per array)
    pub stream_triad_len: usize,
    /// how times were taken
    pub timing: String,
    /// how `bytes` and GB/s are counted
    pub bytes: String,
    /// the Rust build (profile, target features)
    pub gpumat_build: String,
    /// the Eigen build (`null` when Eigen is not available)
    pub eigen: Option<BTreeMap<String, String>>,
    /// numpy's version (`null` when not available)
    pub numpy: Option<String>,
    /// scikit-fem and scipy versions, when available
    pub skfem: Option<String>,
    /// where the `thesis_*` fields come from
    pub thesis_hardware: String,
    /// `/proc/loadavg` (1, 5, 15 min) when the run started and ended: other processes
    /// competing for the cores disturb the times
    pub load_average: [Option<String>; 2],
    /// caveats, missing peers, failures
    pub notes: Vec<String>,
}

/// The 1, 5 and 15 minute load averages, if the OS says.
pub fn load_average() -> Option<String> {
    let s = std::fs::read_to_string("/proc/loadavg").ok()?;
    Some(s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
}

/// The CPU model name, if the OS says.
pub fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
}

/// The last-level cache size from sysfs (e.g. `"32768K"`), if available.
pub fn llc() -> Option<String> {
    let base = "/sys/devices/system/cpu/cpu0/cache";
    let mut best: Option<(u32, String)> = None;
    for e in std::fs::read_dir(base).ok()?.flatten() {
        let p = e.path();
        let level: u32 = std::fs::read_to_string(p.join("level"))
            .ok()?
            .trim()
            .parse()
            .ok()?;
        let size = std::fs::read_to_string(p.join("size")).ok()?.trim().to_string();
        if best.as_ref().map_or(true, |(l, _)| level > *l) {
            best = Some((level, format!("L{level} {size}")));
        }
    }
    best.map(|b| b.1)
}

/// Logical CPUs available.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The current UTC time as `YYYY-MM-DDTHH:MM:SSZ` (the history files' clock).
pub fn utc_now() -> String {
    adjoint::diagnosis::history::utc_now()
}

/// The Rust build: profile and the SIMD level the code was compiled for.
pub fn gpumat_build() -> String {
    let simd = if cfg!(target_feature = "avx512f") {
        "avx512f"
    } else if cfg!(target_feature = "avx2") {
        "avx2"
    } else if cfg!(target_feature = "avx") {
        "avx"
    } else if cfg!(target_feature = "sse2") {
        "sse2 (x86-64 baseline; set RUSTFLAGS=\"-C target-cpu=native\" for wider SIMD)"
    } else {
        "target default"
    };
    let profile = if cfg!(debug_assertions) {
        "debug"
    } else {
        "release"
    };
    format!(
        "rustc {profile} build for {}, SIMD: {simd}; gpumat CPU backend on rayon",
        std::env::consts::ARCH
    )
}

#[cfg(test)]
mod tests {
    #[test]
    fn date_is_iso() {
        let d = super::utc_now();
        assert_eq!(d.len(), 20);
        assert!(d.starts_with("20") && d.ends_with('Z'));
    }
}
