//! Table `step-peer`: a Newmark step of the thesis' cuboid held at one end (Table B.5's body,
//! cells of size 1/(2r)), ours against scikit-fem + scipy (`crates/bench/python/step_peer.py`),
//! the tools a user of Python FEM would pick, per phase.
//!
//! Both sides integrate the same scheme (thesis eq. 2.6.2, theta = 0.6, dt = 0.01, Rayleigh
//! damping 0.1 / 0.01, lumped mass, gravity) of linear elasticity (E = 2000, nu = 0.3) on
//! trilinear hexahedra of the same size from rest, to the same CG tolerance. The meshes differ
//! as each tool makes them: ours is the cut-cell grid of the box's SDF (the cells at the ends
//! are cut, the hold is Nitsche's weak box), the peer's a conforming hex mesh of the box with
//! strong Dirichlet conditions on the nodes in the hold box (the same cell count as the thesis'
//! grid at r = 10); the unknowns of both are columns of the table.
//!
//! - *linear step*: a linear model's step. The peer assembles `K` once (skfem's `asm`, its
//!   seconds a column of their own) and per step forms `A`, `b` and solves, with scipy's `cg`
//!   (Jacobi) or with the SuperLU factor made at the first step (the faster counts; its one-off
//!   factorization is a column). Ours runs its whole step (the assembly pass included: our
//!   step does not keep `K`), once per preconditioner with the factor reuse off, and once with
//!   the defaults (IC(0); a matrix that repeats is factored and solved directly,
//!   [`cutfem::fem::solver`]): its 5-step mean, and its steps after the factorization with
//!   the factor's one-off seconds a column of their own, as the peer's LU factor; and the same
//!   without the default size limit of that factor (its megabytes a column).
//! - *reassembling step*: a model whose `K` changes every step (ours: corotation, the defaults;
//!   the peer: its `asm` + the linear step with CG; skfem has no corotated element, so the peer
//!   is timed on the linear system, which favours it).
//!
//! `max_u` (largest nodal displacement at the end) is a sanity check that both ran the same
//! motion; the weak and the strong hold differ slightly.

use crate::peers::PeerOutput;
use crate::report::{col, Col, Fmt};
use crate::{progress, ratio, Ctx};
use cutfem::fem::{Grid, Model, Preconditioner, Simulation};
use serde::Serialize;
use std::time::Instant;

/// One row: one resolution.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// "res=10"
    pub case: String,
    /// the thesis' resolution r (cells of size 1/(2r))
    pub resolution: u32,
    /// steps run by each side (from rest)
    pub steps: usize,
    /// CG relative tolerance of both sides
    pub cg_tolerance: f64,
    /// ours: active cells, unknowns (3 per active node)
    pub cutfem_cells: usize,
    pub cutfem_unknowns: usize,
    /// ours, linear model: seconds per step in assembly (the pass over cells and rows)
    pub cutfem_assembly_s: f64,
    /// ours, linear model, factor reuse off: seconds per step (whole step) per preconditioner
    pub cutfem_block_jacobi_step_s: f64,
    pub cutfem_block_ic0_step_s: f64,
    pub cutfem_rest_cholesky_step_s: f64,
    /// ours, CG iterations per step per preconditioner
    pub cutfem_block_jacobi_iterations: f64,
    pub cutfem_block_ic0_iterations: f64,
    pub cutfem_rest_cholesky_iterations: f64,
    /// ours, linear model, default settings: seconds per step (whole step)
    pub cutfem_default_step_s: f64,
    /// ours, default settings: seconds per step once the repeated matrix is factored (the
    /// steps after the factorization: assembly pass + direct solve), and that one-off
    /// factorization's seconds (as the peer's LU factor, a column of its own); `None` where
    /// the factor exceeds the default size limit (`cutfem::fem::solver::MAX_REUSED_FACTOR`, 200 MB)
    pub cutfem_factored_step_s: Option<f64>,
    pub cutfem_factor_s: Option<f64>,
    /// the same without the size limit, and the factor's size in MB (8 bytes per entry)
    pub cutfem_unlimited_factored_step_s: Option<f64>,
    pub cutfem_unlimited_factor_s: Option<f64>,
    pub cutfem_unlimited_factor_mb: f64,
    /// ours: the fastest linear step and its configuration
    pub cutfem_linear_step_s: f64,
    pub cutfem_linear_best: String,
    /// ours, corotated (default settings): seconds per step
    pub cutfem_corotated_step_s: f64,
    /// ours: largest nodal displacement at the end (linear model)
    pub cutfem_max_u: f64,
    /// peer: cells, unknowns (free dofs)
    pub skfem_cells: Option<usize>,
    pub skfem_unknowns: Option<usize>,
    /// peer: `K` by skfem's `asm`, seconds (once)
    pub skfem_assembly_s: Option<f64>,
    /// peer: `A`, `b` and condensation, seconds per step
    pub skfem_system_s: Option<f64>,
    /// peer: scipy `cg` (Jacobi), seconds and iterations per step
    pub skfem_cg_s: Option<f64>,
    pub skfem_cg_iterations: Option<f64>,
    /// peer: SuperLU solve per step and its one-off factorization
    pub skfem_direct_s: Option<f64>,
    pub skfem_direct_factor_s: Option<f64>,
    /// peer: the linear step (system + the faster of cg and the direct solve)
    pub skfem_linear_step_s: Option<f64>,
    /// peer: the reassembling step (asm + system + cg)
    pub skfem_reassembling_step_s: Option<f64>,
    /// peer: largest nodal displacement at the end
    pub skfem_max_u: Option<f64>,
    /// peer linear step / ours (>1: ours faster)
    pub linear_speedup: Option<f64>,
    /// peer reassembling step / our corotated step (>1: ours faster)
    pub reassembling_speedup: Option<f64>,
}

/// Our run of `steps` steps.
struct Ours {
    /// seconds per step (whole step), assembly seconds per step, CG iterations per step
    step_s: f64,
    assembly_s: f64,
    iterations: f64,
    /// largest nodal displacement at the end
    max_u: f64,
    /// the steps after the last one that factored a matrix: (their mean seconds, the seconds
    /// of that last factorization); `None` when no step factored or none came after it
    factored: Option<(f64, f64)>,
    /// entries of the kept factor of the repeated matrix at the end (0 without one)
    factor_entries: usize,
}

fn ours(
    grid: &Grid,
    model: &Model,
    steps: usize,
    tolerance: f64,
    setup: impl Fn(&mut Simulation),
) -> Result<Ours, String> {
    let mut sim = Simulation::new(grid.clone(), model.clone()).map_err(|e| e.to_string())?;
    sim.solver.cg.tolerance = tolerance;
    setup(&mut sim);
    let (mut total, mut asm, mut its) = (0.0, 0.0, 0.0);
    // seconds of the steps since the last factorization, and that factorization's seconds
    let (mut after, mut factor_s) = (Vec::new(), None);
    for _ in 0..steps {
        let t = Instant::now();
        let info = sim.step().map_err(|e| e.to_string())?;
        let s = t.elapsed().as_secs_f64();
        total += s;
        asm += info.assembly_s;
        its += info.iterations as f64;
        if info.factorizations > 0 {
            after.clear();
            factor_s = Some(info.factor_s);
        } else if factor_s.is_some() {
            after.push(s);
        }
    }
    let max_u = sim.u.as_slice().iter().map(|u| u.norm()).fold(0.0, f64::max);
    let n = steps as f64;
    let factored = match (after.is_empty(), factor_s) {
        (false, Some(f)) => Some((after.iter().sum::<f64>() / after.len() as f64, f)),
        _ => None,
    };
    Ok(Ours {
        step_s: total / n,
        assembly_s: asm / n,
        iterations: its / n,
        max_u,
        factored,
        factor_entries: sim.reused_factor_entries(),
    })
}

/// The row of resolution `r`.
pub fn row(ctx: &mut Ctx, r: u32, steps: usize, tolerance: f64) -> Result<Row, String> {
    let (shape, corotated) = cutfem::fem::model::thesis_cuboid(false);
    let linear = Model {
        corotation: false,
        ..corotated.clone()
    };
    let sdf = shape.to_sdf(2.0 * r as f64, 6).map_err(|e| e.to_string())?;
    let grid = Grid::new(sdf).map_err(|e| e.to_string())?;
    let mut per = Vec::new();
    for p in Preconditioner::ALL {
        progress(&format!("step-peer r={r}: ours, {}", p.name()));
        per.push(ours(&grid, &linear, steps, tolerance, |s| {
            s.solver.preconditioner = p;
            s.solver.reuse_factor = false;
        })?);
    }
    progress(&format!("step-peer r={r}: ours, defaults"));
    let default = ours(&grid, &linear, steps, tolerance, |_| {})?;
    progress(&format!("step-peer r={r}: ours, factor without size limit"));
    let unlimited = ours(&grid, &linear, steps, tolerance, |s| {
        s.solver.max_reused_factor = usize::MAX;
    })?;
    let corot = ours(&grid, &corotated, steps, tolerance, |_| {})?;
    // the peer's linear step leaves its one-off LU factor out; so does ours once factored
    let mut best = ("defaults".to_string(), default.step_s);
    if let Some((s, _)) = default.factored.filter(|(s, _)| *s < best.1) {
        best = ("defaults, factored (factor once)".to_string(), s);
    }
    if let Some((s, _)) = unlimited.factored.filter(|(s, _)| *s < best.1) {
        best = ("factored without size limit (factor once)".to_string(), s);
    }
    for (p, o) in Preconditioner::ALL.iter().zip(&per) {
        if o.step_s < best.1 {
            best = (format!("{}, no reuse", p.name()), o.step_s);
        }
    }
    progress(&format!("step-peer r={r}: scikit-fem + scipy"));
    let peer: Option<PeerOutput> = match ctx.peers.skfem.clone() {
        Some(s) => ctx.peers.take(s.step(r, steps, tolerance)),
        None => None,
    };
    let get = |k: &str| peer.as_ref().and_then(|o| o.f64(k));
    let geti = |k: &str| peer.as_ref().and_then(|o| o.usize(k));
    let solve = match (get("cg_s"), get("direct_s")) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    let skfem_linear = get("system_s").zip(solve).map(|(a, b)| a + b);
    let skfem_reassembling = match (get("assembly_s"), get("system_s"), get("cg_s")) {
        (Some(a), Some(b), Some(c)) => Some(a + b + c),
        _ => None,
    };
    Ok(Row {
        case: format!("res={r}"),
        resolution: r,
        steps,
        cg_tolerance: tolerance,
        cutfem_cells: grid.cells.len(),
        cutfem_unknowns: 3 * grid.dofs(),
        cutfem_assembly_s: default.assembly_s,
        cutfem_block_jacobi_step_s: per[0].step_s,
        cutfem_block_ic0_step_s: per[1].step_s,
        cutfem_rest_cholesky_step_s: per[2].step_s,
        cutfem_block_jacobi_iterations: per[0].iterations,
        cutfem_block_ic0_iterations: per[1].iterations,
        cutfem_rest_cholesky_iterations: per[2].iterations,
        cutfem_default_step_s: default.step_s,
        cutfem_factored_step_s: default.factored.map(|f| f.0),
        cutfem_factor_s: default.factored.map(|f| f.1),
        cutfem_unlimited_factored_step_s: unlimited.factored.map(|f| f.0),
        cutfem_unlimited_factor_s: unlimited.factored.map(|f| f.1),
        cutfem_unlimited_factor_mb: unlimited.factor_entries as f64 * 8.0 / 1e6,
        cutfem_linear_step_s: best.1,
        cutfem_linear_best: best.0,
        cutfem_corotated_step_s: corot.step_s,
        cutfem_max_u: default.max_u,
        skfem_cells: geti("cells"),
        skfem_unknowns: geti("dofs"),
        skfem_assembly_s: get("assembly_s"),
        skfem_system_s: get("system_s"),
        skfem_cg_s: get("cg_s"),
        skfem_cg_iterations: get("cg_iterations"),
        skfem_direct_s: get("direct_s"),
        skfem_direct_factor_s: get("direct_factor_s"),
        skfem_linear_step_s: skfem_linear,
        skfem_reassembling_step_s: skfem_reassembling,
        skfem_max_u: get("max_u"),
        linear_speedup: ratio(skfem_linear, Some(best.1)),
        reassembling_speedup: ratio(skfem_reassembling, Some(corot.step_s)),
    })
}

/// The table: r = 10 and 20 (`--quick`: 10), 5 steps each, tolerance 1e-6.
pub fn table(ctx: &mut Ctx) -> Vec<Row> {
    crate::resolution_rows(ctx, "step-peer", |ctx, r| row(ctx, r, 5, 1e-6))
}

/// The markdown columns.
pub fn columns() -> Vec<Col> {
    vec![
        col("r", "resolution", Fmt::Plain),
        col("ours unknowns", "cutfem_unknowns", Fmt::Plain),
        col("peer unknowns", "skfem_unknowns", Fmt::Plain),
        col("ours asm ms", "cutfem_assembly_s", Fmt::SecondsAsMs),
        col("ours BJ ms", "cutfem_block_jacobi_step_s", Fmt::SecondsAsMs),
        col("BJ its", "cutfem_block_jacobi_iterations", Fmt::Ratio),
        col("ours IC0 ms", "cutfem_block_ic0_step_s", Fmt::SecondsAsMs),
        col("IC0 its", "cutfem_block_ic0_iterations", Fmt::Ratio),
        col("ours RC ms", "cutfem_rest_cholesky_step_s", Fmt::SecondsAsMs),
        col("ours default ms", "cutfem_default_step_s", Fmt::SecondsAsMs),
        col("ours factored ms", "cutfem_factored_step_s", Fmt::SecondsAsMs),
        col("ours factor ms (once)", "cutfem_factor_s", Fmt::SecondsAsMs),
        col(
            "ours unlimited factored ms",
            "cutfem_unlimited_factored_step_s",
            Fmt::SecondsAsMs,
        ),
        col(
            "its factor ms (once)",
            "cutfem_unlimited_factor_s",
            Fmt::SecondsAsMs,
        ),
        col("its factor MB", "cutfem_unlimited_factor_mb", Fmt::Ratio),
        col("ours best", "cutfem_linear_best", Fmt::Plain),
        col("peer asm ms (once)", "skfem_assembly_s", Fmt::SecondsAsMs),
        col("peer A,b ms", "skfem_system_s", Fmt::SecondsAsMs),
        col("peer cg ms", "skfem_cg_s", Fmt::SecondsAsMs),
        col("peer cg its", "skfem_cg_iterations", Fmt::Ratio),
        col("peer LU solve ms", "skfem_direct_s", Fmt::SecondsAsMs),
        col(
            "peer LU factor ms (once)",
            "skfem_direct_factor_s",
            Fmt::SecondsAsMs,
        ),
        col("linear: peer / ours", "linear_speedup", Fmt::Ratio),
        col("ours corot. ms", "cutfem_corotated_step_s", Fmt::SecondsAsMs),
        col("reassembling: peer / ours", "reassembling_speedup", Fmt::Ratio),
        col("ours max u", "cutfem_max_u", Fmt::Sci),
        col("peer max u", "skfem_max_u", Fmt::Sci),
    ]
}

/// The table's markdown section.
pub fn markdown(rows: &[serde_json::Value]) -> String {
    crate::report::markdown_table(
        "Table step-peer: a Newmark step of the held cuboid, ours against scikit-fem + scipy",
        "Linear elasticity on trilinear hexahedra of size 1/(2r), f64, CG relative tolerance 1e-6 \
         from u + dt v, 5 steps from rest, times per step. Ours: the cut-cell grid with the Nitsche \
         hold, the whole step (assembly pass + solve) with each preconditioner (BJ block-Jacobi, \
         IC0 block IC(0), RC rest-state Cholesky; factor reuse off) and with the defaults (IC(0), a \
         repeated matrix factored and solved directly: the 5-step mean, and the steps after the \
         factorization with the factor's one-off seconds apart, as the peer's LU; a factor above \
         200 MB is not made by default, so also without that limit, with the factor's size). Peer (`crates/bench/python/step_peer.py`): \
         a conforming hex mesh of the box, strong Dirichlet, K by skfem's `asm` once, per step A, b, \
         condensation and scipy `cg` (Jacobi) or a SuperLU solve with the factor of the first step. \
         linear: peer (A,b + the faster solve) / our fastest step (either side's one-off factor \
         left out); reassembling: peer (asm + A,b + \
         cg) / our corotated step (defaults; the peer has no corotation and solves the linear \
         system, which favours it). Peer python is single-threaded; ours uses every core.",
        rows,
        &columns(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::peers::{Peers, Skfem};
    use crate::timing::Policy;

    fn ctx(peers: Peers) -> Ctx {
        Ctx {
            policy: Policy::quick(),
            peers,
            stream_gbs: 0.0,
            quick: true,
        }
    }

    /// Without the peer its columns are null, never estimated; ours are measured.
    #[test]
    fn a_missing_peer_leaves_its_columns_null() {
        let mut c = ctx(Peers::default());
        let r = row(&mut c, 3, 4, 1e-6).unwrap();
        assert!(r.cutfem_unknowns > 0 && r.cutfem_linear_step_s > 0.0 && r.cutfem_corotated_step_s > 0.0);
        // the linear model's matrix repeats: factored at the second step, solved after it
        assert!(r.cutfem_factored_step_s.is_some_and(|s| s > 0.0));
        assert!(r.cutfem_factor_s.is_some_and(|s| s > 0.0));
        assert!(r.cutfem_max_u > 0.0, "gravity moves the body");
        assert!(r.skfem_unknowns.is_none() && r.skfem_linear_step_s.is_none() && r.skfem_max_u.is_none());
        assert!(r.linear_speedup.is_none() && r.reassembling_speedup.is_none());
    }

    /// The peer integrates the same motion: after a few steps the largest displacement of the
    /// conforming mesh with the strong hold and of our cut-cell grid with the weak hold agree
    /// closely. `.ci/run` installs the peer (`crates/bench/peers/install.sh --python-only`),
    /// so under `CI` a missing peer fails this test; elsewhere it says so and passes.
    #[test]
    fn the_peer_integrates_the_same_motion() {
        let skfem = match Skfem::detect() {
            Ok(s) => s,
            Err(why) if std::env::var_os("CI").is_none() => {
                eprintln!("not run: {why}");
                return;
            }
            Err(why) => panic!("CI installs the python peers (crates/bench/peers/install.sh): {why}"),
        };
        let mut c = ctx(Peers {
            skfem: Some(skfem),
            ..Peers::default()
        });
        let r = row(&mut c, 5, 4, 1e-8).unwrap();
        let peer = r.skfem_max_u.expect("the peer ran");
        eprintln!("max u: ours {:.6e}, peer {peer:.6e}", r.cutfem_max_u);
        assert!(
            (peer / r.cutfem_max_u - 1.0).abs() < 0.05,
            "ours {} peer {peer}",
            r.cutfem_max_u
        );
        assert!(r.skfem_cg_iterations.is_some_and(|i| i > 1.0));
        assert!(r.linear_speedup.is_some_and(|s| s > 0.0));
    }
}
