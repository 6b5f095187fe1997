//! What the commands print, written fallibly: a write that fails must neither panic (as
//! `println!` does) nor pass silently.
//!
//! - [`print_json`] writes the one `--json` object to stdout. A closed stdout (EPIPE, e.g.
//!   `softbody ... --json | head -c 100`) is not an error of the run: the command ends quietly
//!   with exit code [`EXIT_STDOUT_CLOSED`] (141, what a shell reports for a process ended by
//!   SIGPIPE), its files already written. Any other failure (a full disk, `> /dev/full`) is a
//!   one-line error naming stdout, exit code 1.
//! - [`note!`](crate::note) writes a line of human output to stderr and ignores failure (when
//!   stderr itself is closed there is nobody left to tell).

use serde_json::Value;
use std::io::{ErrorKind, Write};

/// The exit code of a command whose stdout was closed before its output was written.
pub const EXIT_STDOUT_CLOSED: u8 = 141;

/// The error [`print_json`] returns for a closed stdout; `main` turns it into
/// [`EXIT_STDOUT_CLOSED`] without a message.
pub const STDOUT_CLOSED: &str = "\u{0}stdout closed";

/// Writes `text` and a newline to stdout and flushes it (module docs for the errors).
pub fn print_line(text: &str) -> Result<(), String> {
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{text}").and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == ErrorKind::BrokenPipe => Err(STDOUT_CLOSED.into()),
        Err(e) => Err(format!("stdout: {e}")),
    }
}

/// Writes the one JSON object of `--json` to stdout (module docs).
pub fn print_json(value: &Value) -> Result<(), String> {
    print_line(&value.to_string())
}

/// A failure's message as the one line `error: ...` shows: each prefix once, a quoted bad
/// value repeated up to 100 characters.
pub fn error_line(e: &str) -> String {
    let line = crate::out_dir::public_message(e).replace(['\n', '\r'], " ");
    cutfem::scene::shorten_quotes(&cutfem::scene::dedupe_prefixes(&line))
}

/// Set on the MPI ranks other than 0 (`crate::ensemble`): their notes would repeat rank 0's.
pub static SILENT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// `eprintln!` that ignores a failing stderr instead of panicking (and says nothing on a
/// [`SILENT`] rank).
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if !$crate::output::SILENT.load(std::sync::atomic::Ordering::Relaxed) {
            let _ = writeln!(std::io::stderr(), $($arg)*);
        }
    }};
}

/// Says each of `warnings` on stderr as `warning: ...` (one line each).
pub fn warn_all(warnings: &[String]) {
    for w in warnings {
        crate::note!("warning: {}", error_line(w));
    }
}
