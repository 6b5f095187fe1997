//! The peer systems: Eigen (C++ programs in `crates/bench/eigen`, built by `eigen/build.sh`),
//! numpy (`crates/bench/python/lincomb.py`) and scikit-fem + scipy
//! (`crates/bench/python/step_peer.py`), installed by `crates/bench/peers/install.sh`. Each
//! peer program runs one case and prints one line of `key=value` pairs (`time_s=...
//! samples=... checksum=...`). A peer that is missing or fails yields `None` and a note, never
//! an estimate.
//!
//! Python: `$PYTHON` when set, else the virtual environment the install script makes
//! (`target/bench-venv`, or `$CARGO_TARGET_DIR/bench-venv`) when it exists, else `python3`.

use crate::timing::Policy;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

/// The `key=value` pairs a peer printed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PeerOutput(pub BTreeMap<String, String>);

impl PeerOutput {
    /// Parses the last line of `stdout` that holds `time_s=`.
    pub fn parse(stdout: &str) -> Option<Self> {
        let line = stdout.lines().rev().find(|l| l.contains("time_s="))?;
        let map = line
            .split_whitespace()
            .filter_map(|kv| kv.split_once('='))
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        Some(Self(map))
    }
    /// A numeric field.
    pub fn f64(&self, key: &str) -> Option<f64> {
        self.0.get(key)?.parse().ok()
    }
    /// The faster of two outputs (by `time_s`); a missing one loses.
    pub fn faster(a: Option<Self>, b: Option<Self>) -> Option<Self> {
        match (a, b) {
            (Some(a), Some(b)) => {
                let (ta, tb) = (a.f64("time_s"), b.f64("time_s"));
                if tb.is_some() && (ta.is_none() || tb < ta) {
                    Some(b)
                } else {
                    Some(a)
                }
            }
            (a, None) => a,
            (None, b) => b,
        }
    }
    /// An integer field.
    pub fn usize(&self, key: &str) -> Option<usize> {
        self.0.get(key)?.parse().ok()
    }
}

/// Runs `cmd` and parses its output; `Err` names what went wrong.
fn run_parsed(mut cmd: Command, what: &str) -> Result<PeerOutput, String> {
    let out = cmd.output().map_err(|e| format!("{what}: cannot start: {e}"))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let tail: String = err.lines().rev().take(3).collect::<Vec<_>>().join(" | ");
        return Err(format!("{what}: exit {}: {tail}", out.status));
    }
    PeerOutput::parse(&stdout).ok_or_else(|| format!("{what}: no `time_s=` line in its output"))
}

/// The crate's directory (sources of the peers).
fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Where the Eigen programs are built: `$CARGO_TARGET_DIR/bench-eigen`, else the workspace's
/// `target/bench-eigen`.
pub fn eigen_build_dir() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| crate_dir().join("../../target"));
    target.join("bench-eigen")
}

/// The python the python peers run with (module docs).
pub fn python() -> String {
    if let Ok(p) = std::env::var("PYTHON") {
        return p;
    }
    let venv = eigen_build_dir().with_file_name("bench-venv").join("bin/python");
    if venv.exists() {
        return venv.display().to_string();
    }
    "python3".to_string()
}

/// The version strings `import`ing `modules` in `python` prints, or why not.
fn python_versions(python: &str, modules: &[&str]) -> Result<Vec<String>, String> {
    let code = format!(
        "import {m}; print(' '.join(x.__version__ for x in ({m},)))",
        m = modules.join(", ")
    );
    let out = Command::new(python)
        .args(["-c", &code])
        .output()
        .map_err(|e| format!("cannot run {python}: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "{python} cannot import {} (crates/bench/peers/install.sh installs them)",
            modules.join(", ")
        ));
    }
    Ok(String::from_utf8_lossy(&out.stdout)
        .split_whitespace()
        .map(str::to_string)
        .collect())
}

/// The built Eigen programs.
#[derive(Clone, Debug)]
pub struct Eigen {
    dir: PathBuf,
    /// `compiler`, `flags`, `eigen` (version), `openmp_threads` from the build's `info.txt`
    pub info: BTreeMap<String, String>,
}

impl Eigen {
    /// Builds (or finds up to date) the Eigen programs with `eigen/build.sh`.
    pub fn build() -> Result<Self, String> {
        let script = crate_dir().join("eigen/build.sh");
        if !script.exists() {
            return Err(format!("{} not found", script.display()));
        }
        let dir = eigen_build_dir();
        let out = Command::new("bash")
            .arg(&script)
            .arg(&dir)
            .output()
            .map_err(|e| format!("cannot run bash {}: {e}", script.display()))?;
        if !out.status.success() {
            let err = String::from_utf8_lossy(&out.stderr);
            let first = err.lines().next().unwrap_or("").to_string();
            return Err(format!("eigen/build.sh failed ({}): {first}", out.status));
        }
        let info = std::fs::read_to_string(dir.join("info.txt"))
            .unwrap_or_default()
            .lines()
            .filter_map(|l| l.split_once('='))
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        Ok(Self { dir, info })
    }
    /// Runs program `prog` with the case arguments `case` followed by the policy.
    pub fn run(&self, prog: &str, case: &[String], policy: &Policy) -> Result<PeerOutput, String> {
        let mut cmd = Command::new(self.dir.join(prog));
        cmd.args(case).args(policy.peer_args());
        run_parsed(cmd, &format!("eigen/{prog} {}", case.join(" ")))
    }
}

/// numpy through `python3`.
#[derive(Clone, Debug)]
pub struct Numpy {
    python: String,
    script: PathBuf,
    /// numpy's version
    pub version: String,
}

impl Numpy {
    /// Finds `python3` with numpy importable.
    pub fn detect() -> Result<Self, String> {
        let python = python();
        let script = crate_dir().join("python/lincomb.py");
        if !script.exists() {
            return Err(format!("{} not found", script.display()));
        }
        let version = python_versions(&python, &["numpy"])?.join(" ");
        Ok(Self {
            python,
            script,
            version,
        })
    }
    /// Times the linear combination of `k` vectors of length `n` in `dtype` (`f32`, `f64`).
    pub fn lincomb(&self, n: usize, k: usize, dtype: &str, policy: &Policy) -> Result<PeerOutput, String> {
        let mut cmd = Command::new(&self.python);
        cmd.arg(&self.script)
            .arg(n.to_string())
            .arg(k.to_string())
            .args(policy.peer_args())
            .arg(dtype);
        run_parsed(cmd, &format!("python/lincomb.py {n} {k} {dtype}"))
    }
}

/// scikit-fem and scipy through python ([`python`]).
#[derive(Clone, Debug)]
pub struct Skfem {
    python: String,
    script: PathBuf,
    /// `scikit-fem X scipy Y`
    pub version: String,
}

impl Skfem {
    /// Finds a python with scikit-fem and scipy importable.
    pub fn detect() -> Result<Self, String> {
        let python = python();
        let script = crate_dir().join("python/step_peer.py");
        if !script.exists() {
            return Err(format!("{} not found", script.display()));
        }
        let v = python_versions(&python, &["skfem", "scipy"])?;
        let version = format!(
            "scikit-fem {} scipy {}",
            v.first().map_or("?", String::as_str),
            v.get(1).map_or("?", String::as_str)
        );
        Ok(Self {
            python,
            script,
            version,
        })
    }
    /// Times scipy on the `g x g` Poisson matrix: `mode` `spmv` (Table B.3) or `cg` (B.4)
    /// (`sparse2d.py`).
    pub fn sparse2d(&self, mode: &str, g: usize, policy: &Policy) -> Result<PeerOutput, String> {
        let mut cmd = Command::new(&self.python);
        cmd.arg(self.script.with_file_name("sparse2d.py"))
            .arg(mode)
            .arg(g.to_string())
            .args(policy.peer_args());
        run_parsed(cmd, &format!("python/sparse2d.py {mode} {g}"))
    }
    /// Times scipy's BSR and CSR products with the matrix in `file` (`bsr_spmv.py`).
    pub fn bsr_spmv(&self, file: &str, policy: &Policy) -> Result<PeerOutput, String> {
        let mut cmd = Command::new(&self.python);
        cmd.arg(self.script.with_file_name("bsr_spmv.py"))
            .arg(file)
            .args(policy.peer_args());
        run_parsed(cmd, "python/bsr_spmv.py")
    }
    /// Runs `steps` Newmark steps of the held cuboid at resolution `r` (`step_peer.py`).
    pub fn step(&self, r: u32, steps: usize, tolerance: f64) -> Result<PeerOutput, String> {
        let mut cmd = Command::new(&self.python);
        cmd.arg(&self.script)
            .arg(r.to_string())
            .arg(steps.to_string())
            .arg(format!("{tolerance:e}"));
        run_parsed(cmd, &format!("python/step_peer.py {r} {steps}"))
    }
}

/// The peers available in this run, and why the others are not.
#[derive(Debug, Default)]
pub struct Peers {
    /// Eigen, when it built
    pub eigen: Option<Eigen>,
    /// numpy, when importable
    pub numpy: Option<Numpy>,
    /// scikit-fem and scipy, when importable
    pub skfem: Option<Skfem>,
    /// notes for `machine.notes` (why a peer is missing, failures during the run)
    pub notes: Vec<String>,
}

impl Peers {
    /// Builds/detects the peers (`use_peers = false` skips them all).
    pub fn detect(use_peers: bool) -> Self {
        let mut p = Peers::default();
        if !use_peers {
            p.notes
                .push("peers disabled (--no-peers): the Eigen, numpy and scikit-fem columns are null".into());
            return p;
        }
        match Eigen::build() {
            Ok(e) => p.eigen = Some(e),
            Err(why) => p
                .notes
                .push(format!("Eigen not available, its columns are null: {why}")),
        }
        match Numpy::detect() {
            Ok(n) => p.numpy = Some(n),
            Err(why) => p
                .notes
                .push(format!("numpy not available, its columns are null: {why}")),
        }
        match Skfem::detect() {
            Ok(n) => p.skfem = Some(n),
            Err(why) => p
                .notes
                .push(format!("scikit-fem not available, its columns are null: {why}")),
        }
        p
    }
    /// Unwraps a peer result, recording a failure as a note.
    pub fn take(&mut self, r: Result<PeerOutput, String>) -> Option<PeerOutput> {
        match r {
            Ok(o) => Some(o),
            Err(why) => {
                eprintln!("warning: {why}");
                self.notes.push(why);
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_last_timing_line() {
        let o = PeerOutput::parse("hello\ntime_s=1e-3 samples=4 iterations=12\n").unwrap();
        assert_eq!(o.f64("time_s"), Some(1e-3));
        assert_eq!(o.usize("iterations"), Some(12));
        assert!(PeerOutput::parse("nothing").is_none());
    }
}
