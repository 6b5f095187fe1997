//! `softbody`: the command-line face of the project (`../shared/docs/interface.md`).
//!
//! Thin by design: parse, call the library, print, draw. Every error becomes one line on
//! stderr and a non-zero exit code; `--json` prints exactly one JSON object on stdout. The
//! report charts (`plot`) are drawn once and written as PNG and as SVG.

mod demo;
mod diagnose;
mod diagnose_report;
mod ensemble;
mod fit;
mod fit_report;
mod gradcheck;
mod observe;
mod out_dir;
mod output;
mod problem_args;
mod progress;
mod refine_check;
mod simulate;
mod study_design;
mod study_diagnose;
mod study_fit;

use clap::{Parser, Subcommand};
use softbody::plot;
use std::process::ExitCode;

/// Physically based reconstruction of elastic soft bodies.
#[derive(Parser, Debug)]
#[command(name = "softbody", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Forward simulation: per-frame surface meshes (DIR/frames/NNNN.ply), a picture and a
    /// JSON summary.
    Simulate(simulate::Args),
    /// Virtual RGB-D cameras look at the simulated body; writes the points they see as an
    /// observation CSV (frame,x,y,z,camera).
    Observe(observe::Args),
    /// Reconstructs parameters from observed points with adjoint gradients; writes a report
    /// (fit.json, fit.log, plots) to DIR.
    Fit(fit::Args),
    /// Adjoint gradient against central finite differences for every fitted parameter.
    Gradcheck(gradcheck::Args),
    /// Fits the model as given, shows where it fails (residuals per frame, camera, surface
    /// region, direction; pictures) and which physical effect is missing.
    Diagnose(diagnose::Args),
    /// The whole story on a built-in case with a hidden effect: observe, fit, diagnose, add
    /// the missing effect, refit, watch the error fall.
    Demo(demo::Args),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    let result = match cli.command {
        // several processes writing the same report: only `fit` shares its work over ranks
        _ if ensemble::launched() && !matches!(cli.command, Command::Fit(_)) => Err(
            "started by mpirun with several processes: only `softbody fit` runs across MPI ranks; run this command as one process".to_string(),
        ),
        Command::Simulate(a) => simulate::run(a),
        Command::Observe(a) => observe::run(a),
        Command::Fit(a) => fit::run(a),
        Command::Gradcheck(a) => gradcheck::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Demo(a) => demo::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // the output's reader went away: end quietly (interface.md)
        Err(e) if e == output::STDOUT_CLOSED => ExitCode::from(output::EXIT_STDOUT_CLOSED),
        // an MPI rank other than 0: rank 0 says why
        Err(e) if e == ensemble::QUIET_FAILURE => ExitCode::FAILURE,
        Err(e) => {
            // one line, each prefix once, a quoted bad value repeated up to 100 characters
            crate::note!("error: {}", output::error_line(&e));
            ExitCode::FAILURE
        }
    }
}
