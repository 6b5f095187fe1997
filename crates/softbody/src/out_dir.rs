//! Transactional outputs: a run's files appear complete and together, or not at all.
//!
//! Every command that writes an `--out` goes through this module (docs/cli.md, "Outputs"):
//!
//! - [`OutDir`] (a report folder: `simulate`, `fit`, `diagnose`, `demo`) is written as
//!   `DIR.tmp-<pid>` beside `DIR` and renamed into place by [`OutDir::commit`] at the end of a
//!   successful run; the earlier `DIR` is replaced as a whole (no frame or plot of an earlier
//!   run survives) only then. A run that fails (or is dropped) removes its temporary folder and
//!   leaves the earlier `DIR` byte for byte as it was.
//! - [`OutFiles`] (single files: `observe`'s CSV, its camera file and preview) writes each as
//!   `FILE.tmp-<pid>`; [`OutFiles::commit`] renames them all into place, restoring the earlier
//!   files when one rename fails.
//! - Both hold an advisory lock (`flock` through `std::fs::File::try_lock`, std since 1.89) on a lock file beside the
//!   target (`DIR.lock`, `FILE.lock`) from the start to the end of the run: a second run into
//!   the same target fails at once with `DIR is in use by process N`. The lock file holds the
//!   pid and is removed at the end; a lock left by a killed run is not held and is taken over.
//! - A folder is only replaced when it is empty or was written by softbody (it holds
//!   [`MARKER`] or a report file of a command): `--out .` or a folder of other files is refused
//!   rather than deleted.
//! - No output replaces the run's own inputs ([`refuse_inputs`]): a target that is an input
//!   file (through any link), or a folder that holds one, is refused before anything is written.
//!
//! A run that is killed leaves its `DIR.tmp-<pid>` behind; the next run into `DIR` that
//! succeeds removes it, and `fit --resume` reads its `fit.log` ([`OutDir::resume_file`]), so an
//! interrupted fit loses nothing.

use serde_json::Value;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

/// The file that marks a folder as written by softbody.
pub const MARKER: &str = ".softbody-out";

/// Report files whose presence marks a folder written by softbody before [`MARKER`] existed.
const REPORT_FILES: [&str; 5] = [
    "summary.json",
    "fit.json",
    "fit.log",
    "diagnosis.json",
    "demo.json",
];

/// `PATH` + `suffix` (`out/x` + `.lock` is `out/x.lock`).
fn beside(path: &Path, suffix: &str) -> PathBuf {
    let mut s = normalise(path).into_os_string();
    s.push(suffix);
    PathBuf::from(s)
}

/// `path` said once, the way every output path is compared and staged: trailing separators
/// and `.` components dropped (`out/` and `./out/.` are `out`), `..` kept (lexically resolving
/// it would be wrong through a link). A report folder's temporary twin is then always staged
/// beside it (`out.tmp-PID`), never inside it (`out/.tmp-PID`).
pub fn normalise(path: &Path) -> PathBuf {
    let mut out: PathBuf = path.components().collect();
    if out.as_os_str().is_empty() && !path.as_os_str().is_empty() {
        // `./` alone
        out.push(".");
    }
    out
}

fn err(path: &Path, e: impl std::fmt::Display) -> String {
    format!("{}: {e}", path.display())
}

/// An error message with the temporary names of this process's outputs (`X.tmp-<pid>`) said
/// as the names they stand for (`X`): a user knows the target, not our scratch name.
pub fn public_message(message: &str) -> String {
    message.replace(&format!(".tmp-{}", std::process::id()), "")
}

/// An advisory lock on `TARGET.lock`, released and removed on drop.
#[derive(Debug)]
struct Lock {
    path: PathBuf,
    file: File,
}

// `File::try_lock` is std since 1.89: the toolchain is 1.95 and the dependencies already need
// 1.85 (clap 4.6, indicatif 0.18); the workspace's declared rust-version (1.80) is not raised
// here because that turns on MSRV-gated lints in every crate
#[allow(clippy::incompatible_msrv)]
impl Lock {
    /// Takes the lock of `target` or fails at once naming the holder.
    fn take(target: &Path) -> Result<Lock, String> {
        let path = beside(target, ".lock");
        // a lock file removed by its holder between our open and our lock is a stale inode:
        // take the lock again on the file now at the path
        for _ in 0..16 {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(|e| err(target, e))?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    let mut text = String::new();
                    let _ = file.read_to_string(&mut text);
                    let who = match text.trim().parse::<u32>() {
                        Ok(pid) => format!("process {pid}"),
                        Err(_) => "another process".to_string(),
                    };
                    return Err(format!(
                        "{} is in use by {who} (lock file {}); wait for it or choose another --out",
                        target.display(),
                        path.display()
                    ));
                }
                Err(TryLockError::Error(e)) => return Err(err(&path, e)),
            }
            if !same_file(&file, &path) {
                continue;
            }
            file.set_len(0).map_err(|e| err(&path, e))?;
            file.rewind().map_err(|e| err(&path, e))?;
            write!(file, "{}", std::process::id())
                .and_then(|()| file.flush())
                .map_err(|e| err(&path, e))?;
            return Ok(Lock { path, file });
        }
        Err(err(
            &path,
            "could not take the lock (the lock file keeps changing)",
        ))
    }
}

#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_: &File, path: &Path) -> bool {
    path.exists()
}

#[allow(clippy::incompatible_msrv)] // File::unlock (see `impl Lock`)
impl Drop for Lock {
    fn drop(&mut self) {
        // removed while held: a run waiting on this inode sees it gone and takes a fresh one
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.unlock();
    }
}

/// A report folder written transactionally (module docs).
#[derive(Debug)]
pub struct OutDir {
    target: PathBuf,
    tmp: PathBuf,
    /// temporary folders of killed runs, newest first
    stale: Vec<PathBuf>,
    committed: bool,
    /// held to the end of the run; `None` for a folder inside another run's temporary folder
    /// ([`OutDir::nested`]), which is made in place
    lock: Option<Lock>,
}

impl OutDir {
    /// Locks `target` and creates its temporary folder; fails when `target` is in use, is not
    /// a folder, is a folder of files softbody did not write, or holds one of the run's
    /// `inputs`.
    pub fn begin(target: &Path, inputs: &[PathBuf]) -> Result<OutDir, String> {
        let target = &normalise(target);
        if target.as_os_str().is_empty() || target.file_name().is_none() {
            return Err(format!(
                "--out {}: name a folder (not `.`, `..` or `/`)",
                target.display()
            ));
        }
        refuse_inputs(target, inputs)?;
        if let Some(parent) = target.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| err(parent, e))?;
        }
        let lock = Lock::take(target)?;
        check_replaceable(target)?;
        let stale = stale_dirs(target);
        let pid = std::process::id();
        let mut tmp = beside(target, &format!(".tmp-{pid}"));
        let mut k = 0;
        while tmp.exists() {
            // a killed run of an earlier process with our pid: keep it for resume_file
            k += 1;
            tmp = beside(target, &format!(".tmp-{pid}-{k}"));
        }
        std::fs::create_dir(&tmp).map_err(|e| err(&tmp, e))?;
        Ok(OutDir {
            target: target.to_path_buf(),
            tmp,
            stale,
            committed: false,
            lock: Some(lock),
        })
    }

    /// A report folder `name` inside this one's temporary folder (a study's recording): it is
    /// created directly (the outer folder is this run's own, so it needs no lock and no
    /// temporary name), gets the marker on [`OutDir::commit`] and moves into place with the
    /// outer folder. `name` must be one plain file name that is not there yet.
    pub fn nested(&self, name: &str) -> Result<OutDir, String> {
        let path = self.tmp.join(name);
        let plain = Path::new(name).file_name().is_some_and(|f| f == name);
        if !plain {
            return Err(format!(
                "{}: `{name}` is not a plain folder name",
                self.target.display()
            ));
        }
        std::fs::create_dir(&path).map_err(|e| err(&self.target.join(name), e))?;
        Ok(OutDir {
            target: path.clone(),
            tmp: path,
            stale: Vec::new(),
            committed: false,
            lock: None,
        })
    }

    /// The folder to write into (the temporary one).
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Rewrites every string of `v` that names a path under the temporary folder to the path it
    /// will have after the commit (the JSON a command writes and prints).
    pub fn publish(&self, v: &mut Value) {
        let tmp = self.tmp.display().to_string();
        let target = self.target.display().to_string();
        fn walk(v: &mut Value, tmp: &str, target: &str) {
            match v {
                Value::String(s) => {
                    if let Some(rest) = s.strip_prefix(tmp) {
                        if rest.is_empty() || rest.starts_with(std::path::MAIN_SEPARATOR) {
                            *s = format!("{target}{rest}");
                        }
                    }
                }
                Value::Array(a) => a.iter_mut().for_each(|x| walk(x, tmp, target)),
                Value::Object(m) => m.values_mut().for_each(|x| walk(x, tmp, target)),
                _ => {}
            }
        }
        walk(v, &tmp, &target);
    }

    /// Finishes a report: rewrites the paths of `summary` to their final place ([`publish`]),
    /// writes it as `file` (pretty JSON) into the folder and moves the folder into place
    /// ([`commit`]).
    ///
    /// [`publish`]: OutDir::publish
    /// [`commit`]: OutDir::commit
    pub fn finish(self, summary: &mut Value, file: &str) -> Result<(), String> {
        self.publish(summary);
        let path = self.tmp.join(file);
        std::fs::write(&path, serde_json::to_string_pretty(summary).expect("json"))
            .map_err(|e| format!("{}: {e}", self.target.join(file).display()))?;
        self.commit()
    }

    /// The earlier run's file `name` to continue from: in the temporary folder of the newest
    /// run that was killed (it has the latest state), else in the target; `None` when neither
    /// has it.
    pub fn resume_file(&self, name: &str) -> Option<PathBuf> {
        self.stale
            .iter()
            .map(|d| d.join(name))
            .chain(std::iter::once(self.target.join(name)))
            .find(|p| p.is_file())
    }

    /// Moves the finished folder into place: the earlier one (if any) is replaced, temporary
    /// folders of killed runs are removed.
    pub fn commit(mut self) -> Result<(), String> {
        let marker = self.tmp.join(MARKER);
        std::fs::write(&marker, format!("{}\n", std::process::id())).map_err(|e| err(&marker, e))?;
        if self.lock.is_none() {
            // nested: already in place inside the outer temporary folder
            self.committed = true;
            return Ok(());
        }
        let old = beside(&self.target, &format!(".old-{}", std::process::id()));
        let had_old = self.target.exists();
        if had_old {
            let _ = std::fs::remove_dir_all(&old);
            std::fs::rename(&self.target, &old).map_err(|e| err(&self.target, e))?;
        }
        if let Err(e) = std::fs::rename(&self.tmp, &self.target) {
            if had_old {
                let _ = std::fs::rename(&old, &self.target);
            }
            return Err(err(&self.target, e));
        }
        self.committed = true;
        if had_old {
            let _ = std::fs::remove_dir_all(&old);
        }
        for d in &self.stale {
            let _ = std::fs::remove_dir_all(d);
        }
        Ok(())
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
    }
}

/// Refuses an output `target` that would replace one of the run's `inputs` (the scene, its
/// body file, the observations, a camera file): the same file (by path after links, or by
/// inode: a hard link), or a folder that holds one (a report folder is replaced as a whole).
/// A target that does not exist yet holds nothing.
pub fn refuse_inputs(target: &Path, inputs: &[PathBuf]) -> Result<(), String> {
    let Ok(t) = std::fs::canonicalize(target) else {
        return Ok(());
    };
    for input in inputs {
        let Ok(i) = std::fs::canonicalize(input) else {
            continue;
        };
        if i == t || same_inode(&i, &t) {
            return Err(format!(
                "{}: is an input of this run ({}); choose another output",
                target.display(),
                input.display()
            ));
        }
        if t.is_dir() && i.starts_with(&t) {
            return Err(format!(
                "{}: the folder holds an input of this run ({}) and a run replaces the whole \
                 folder; choose another --out",
                target.display(),
                input.display()
            ));
        }
    }
    Ok(())
}

#[cfg(unix)]
fn same_inode(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => a.is_file() && a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_inode(_: &Path, _: &Path) -> bool {
    false
}

/// Refuses a target that is not a folder or is a non-empty folder softbody did not write.
fn check_replaceable(target: &Path) -> Result<(), String> {
    let Ok(meta) = std::fs::symlink_metadata(target) else {
        return Ok(());
    };
    if !meta.is_dir() {
        return Err(format!(
            "{}: exists and is not a folder; choose another --out",
            target.display()
        ));
    }
    let mut entries = std::fs::read_dir(target).map_err(|e| err(target, e))?;
    let empty = entries.next().is_none();
    let ours = std::iter::once(MARKER)
        .chain(REPORT_FILES)
        .any(|f| target.join(f).is_file());
    if empty || ours {
        Ok(())
    } else {
        Err(format!(
            "{}: the folder holds files that softbody did not write and a run replaces the whole \
             folder; choose a new or empty --out",
            target.display()
        ))
    }
}

/// Temporary folders `TARGET.tmp-*` of killed runs (we hold the lock, so none is live), newest
/// first.
fn stale_dirs(target: &Path) -> Vec<PathBuf> {
    let (Some(parent), Some(name)) = (target.parent(), target.file_name()) else {
        return Vec::new();
    };
    let parent = if parent.as_os_str().is_empty() {
        Path::new(".")
    } else {
        parent
    };
    let prefix = format!("{}.tmp-", name.to_string_lossy());
    let mut found: Vec<(std::time::SystemTime, PathBuf)> = std::fs::read_dir(parent)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
        .filter(|e| e.file_type().is_ok_and(|t| t.is_dir()))
        .map(|e| {
            let t = e
                .metadata()
                .and_then(|m| m.modified())
                .unwrap_or(std::time::UNIX_EPOCH);
            (t, beside(target, &e.file_name().to_string_lossy()[name.len()..]))
        })
        .collect();
    found.sort_by_key(|f| std::cmp::Reverse(f.0));
    found.into_iter().map(|(_, p)| p).collect()
}

/// Single output files written transactionally (module docs); the lock is on the first.
#[derive(Debug)]
pub struct OutFiles {
    /// (temporary, target)
    files: Vec<(PathBuf, PathBuf)>,
    committed: bool,
    _lock: Lock,
}

impl OutFiles {
    /// Locks `targets[0]` and checks that every target can be replaced by a file (it is not a
    /// folder or one of the run's `inputs`, its folder exists or can be made, a file can be
    /// created there).
    pub fn begin(targets: &[PathBuf], inputs: &[PathBuf]) -> Result<OutFiles, String> {
        let targets: Vec<PathBuf> = targets.iter().map(|t| normalise(t)).collect();
        let targets = &targets[..];
        let first = targets.first().ok_or("no output file")?;
        for t in targets {
            refuse_inputs(t, inputs)?;
        }
        for t in targets {
            if let Some(dir) = t.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).map_err(|e| err(dir, e))?;
            }
        }
        let lock = Lock::take(first)?;
        if let Some(t) = targets.iter().find(|t| t.is_dir()) {
            return Err(format!("{}: is a folder, not a file", t.display()));
        }
        let pid = std::process::id();
        // dropped on an error: the temporary files made so far are removed
        let mut out = OutFiles {
            files: Vec::new(),
            committed: false,
            _lock: lock,
        };
        for t in targets {
            let tmp = beside(t, &format!(".tmp-{pid}"));
            // fail on an unwritable output before the work
            File::create(&tmp).map_err(|e| err(t, e))?;
            out.files.push((tmp, t.clone()));
        }
        Ok(out)
    }

    /// The temporary file to write instead of `target` (`target` itself when it is not one of
    /// the files).
    pub fn path(&self, target: &Path) -> PathBuf {
        self.files
            .iter()
            .find(|(_, t)| t == target)
            .map_or_else(|| target.to_path_buf(), |(tmp, _)| tmp.clone())
    }

    /// Renames every file into place; when one fails, the files already renamed are removed
    /// and the earlier ones restored.
    pub fn commit(mut self) -> Result<(), String> {
        let pid = std::process::id();
        let mut done: Vec<(PathBuf, Option<PathBuf>)> = Vec::new();
        let mut failure = None;
        for (tmp, target) in &self.files {
            let backup = beside(target, &format!(".old-{pid}"));
            let had = std::fs::symlink_metadata(target).is_ok();
            if had {
                if target.is_dir() {
                    failure = Some(format!("{}: is a folder, not a file", target.display()));
                    break;
                }
                if let Err(e) = std::fs::rename(target, &backup) {
                    failure = Some(err(target, e));
                    break;
                }
            }
            if let Err(e) = std::fs::rename(tmp, target) {
                if had {
                    let _ = std::fs::rename(&backup, target);
                }
                failure = Some(err(target, e));
                break;
            }
            done.push((target.clone(), had.then_some(backup)));
        }
        if let Some(e) = failure {
            for (target, backup) in done.into_iter().rev() {
                let _ = std::fs::remove_file(&target);
                if let Some(b) = backup {
                    let _ = std::fs::rename(&b, &target);
                }
            }
            return Err(e);
        }
        self.committed = true;
        for (_, backup) in done {
            if let Some(b) = backup {
                let _ = std::fs::remove_file(b);
            }
        }
        Ok(())
    }
}

impl Drop for OutFiles {
    fn drop(&mut self) {
        if !self.committed {
            for (tmp, _) in &self.files {
                let _ = std::fs::remove_file(tmp);
            }
        }
    }
}

#[cfg(test)]
mod tests;
