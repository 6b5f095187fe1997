//! `softbody`: the command-line face of the project.
//!
//! The subcommands of `../shared/docs/interface.md` (simulate, observe, fit, diagnose,
//! gradcheck, demo) arrive with the cutfem, adjoint and diagnosis issues. Until then this
//! binary only identifies itself.

fn main() {
    println!(
        "softbody {} — no subcommands yet (the simulation arrives with the cutfem issue).\n\
         Run `cargo run --release -p bench --bin tables` for the gpumat benchmark tables.",
        env!("CARGO_PKG_VERSION")
    );
}
