//! Helpers shared by the CLI tests: run the `softbody` binary, scratch folders, and the checks
//! of its two kinds of answer (one JSON object, or a one-line error with exit code 1).

#![allow(dead_code)] // each test file uses its own subset

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `softbody` binary of this build.
pub fn softbody() -> Command {
    Command::new(env!("CARGO_BIN_EXE_softbody"))
}

/// A fresh, empty scratch folder for test `name` of suite `suite` (per process).
pub fn tmp(suite: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("softbody-{suite}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes `text` to `dir/name`.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `softbody args...`.
pub fn run(args: &[&str]) -> Output {
    softbody().args(args).output().unwrap()
}

/// Asserts success.
pub fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Asserts success and reads the one JSON object on stdout.
pub fn json(o: &Output) -> Value {
    ok(o);
    serde_json::from_slice(&o.stdout).expect("one JSON object on stdout")
}

/// Asserts a one-line error containing `needle`, exit code 1, no panic.
pub fn one_line_error(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "exit code for `{needle}`: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    assert_eq!(err.trim().lines().count(), 1, "one line expected: {err}");
    assert!(err.contains(needle), "`{needle}` not in: {err}");
}
