//! Shared helpers for the benchmarks: the thesis' Appendix B cases (cuMat benchmarks B.1-B.4)
//! rebuilt on `gpumat`, the timing policy, the STREAM triad, the Eigen and numpy peers and the
//! report writers. The `tables` binary ties them together; the criterion suite
//! (`benches/gpumat.rs`) reuses the same kernels at small sizes.

pub mod figures;
pub mod lincomb;
pub mod machine;
pub mod peers;
pub mod problems;
pub mod report;
pub mod stream;
pub mod table_adjoint;
pub mod table_advect;
pub mod table_bsr;
pub mod table_diagnose;
pub mod table_hidden;
pub mod table_lincomb;
pub mod table_scaling;
pub mod table_sparse;
pub mod table_step_peer;
pub mod targets;
pub mod thesis;
pub mod timing;

use peers::Peers;
use timing::Policy;

/// What every table function needs: the timing policy, the peers, the STREAM bandwidth.
#[derive(Debug)]
pub struct Ctx {
    /// timing policy
    pub policy: Policy,
    /// Eigen and numpy, when available (and notes about them)
    pub peers: Peers,
    /// STREAM triad bandwidth, GB/s
    pub stream_gbs: f64,
    /// `--quick`
    pub quick: bool,
}

/// `a / b` as a ratio, or `None` when either side is missing.
pub fn ratio(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) if b > 0.0 => Some(a / b),
        _ => None,
    }
}

/// The rows `row(ctx, r)` of the thesis' resolutions `r = 10, 20` (`--quick`: 10); a row that
/// fails is left out and named in the notes (`table`: the table's id).
pub fn resolution_rows<R>(
    ctx: &mut Ctx,
    table: &str,
    mut row: impl FnMut(&mut Ctx, u32) -> Result<R, String>,
) -> Vec<R> {
    let rs: &[u32] = if ctx.quick { &[10] } else { &[10, 20] };
    let mut rows = Vec::new();
    for &r in rs {
        match row(ctx, r) {
            Ok(row) => rows.push(row),
            Err(e) => {
                let why = format!("{table} r={r} failed: {e}");
                eprintln!("warning: {why}");
                ctx.peers.notes.push(why);
            }
        }
    }
    rows
}

/// Progress line on stderr.
pub fn progress(msg: &str) {
    eprintln!("[tables] {msg}");
}
pub mod table_cuboid;
