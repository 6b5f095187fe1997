//! Tables B.5 and B.6 (thesis sec. 4.6): the cuboid (center (0,1,0), size (1.29, 0.4, 0.8)),
//! cells of size 1/(2r), corotation on, held at one end by a Dirichlet box (B.5) or falling on
//! the ground (B.6), simulated on the cut-cell grid and on the 6-tets-per-cell baseline.
//! Per-step times are averages over the run; the thesis' figures (GTX 1060) sit beside ours.
//!
//! The grid's linear solve is measured with each preconditioner of
//! [`cutfem::fem::solver`]: block-Jacobi (the thesis', in the full grid run with advection),
//! then two more runs of the same steps with the modified block IC(0) (`ic0_*`) and with the
//! reused rest-state Cholesky factor (`rc_*`). Their CG seconds leave out the factorizations,
//! which are counted and timed apart (seconds per step = all factorization seconds / steps).

use cutfem::fem::advect::Diffusion;
use cutfem::fem::element::Element;
use cutfem::fem::tet::TetSimulation;
use cutfem::fem::{Grid, Model, Preconditioner, Simulation};
use gpumat::Vec3;
use serde::Serialize;
use std::time::Instant;

/// One row of Table B.5 or B.6.
#[derive(Clone, Debug, Serialize)]
pub struct CuboidRow {
    /// "res=10"
    pub case: String,
    /// the thesis' resolution r (cells of size 1/(2r))
    pub resolution: u32,
    /// time steps run
    pub steps: usize,
    /// active grid nodes (the grid's degrees of freedom)
    pub grid_free_nodes: usize,
    /// empty nodes filled by the diffusion before advection
    pub grid_empty_nodes: usize,
    /// active cells
    pub grid_elements: usize,
    /// cut cells
    pub grid_cut_cells: usize,
    /// free tet nodes
    pub tet_free_nodes: usize,
    /// fixed tet nodes (hard Dirichlet)
    pub tet_fixed_nodes: usize,
    /// tetrahedra
    pub tet_elements: usize,
    /// average 3x3 blocks per row of the grid's stiffness matrix
    pub grid_entries_per_row: f64,
    /// average 3x3 blocks per row of the tets' stiffness matrix
    pub tet_entries_per_row: f64,
    /// grid: seconds per step in assembly (rotations, stiffness values, forces, A, b)
    pub grid_assembly_s: f64,
    /// tets: seconds per step in assembly
    pub tet_assembly_s: f64,
    /// grid: seconds per step in rotations + stiffness values (the thesis' "assembly"): the pass
    /// over cells and rows, which also computes `K u`, the corotation and body forces, all
    /// blocks of A and most of b (a step's stiffness values go into A, K is not stored)
    pub grid_stiffness_s: f64,
    /// tets: seconds per step in rotations + stiffness values
    pub tet_stiffness_s: f64,
    /// tet stiffness / grid stiffness time (target: at least 2; thesis 2-3)
    pub grid_vs_tet_stiffness_speedup: f64,
    /// grid: seconds per step in collision forces
    pub grid_collision_s: f64,
    /// tets: seconds per step in collision forces
    pub tet_collision_s: f64,
    /// grid: CG iterations per step (mean)
    pub grid_cg_iterations: f64,
    /// tets: CG iterations per step (mean)
    pub tet_cg_iterations: f64,
    /// grid: seconds per step in the CG solve
    pub grid_cg_s: f64,
    /// grid, modified block IC(0): CG iterations per step (mean)
    pub ic0_cg_iterations: f64,
    /// grid, modified block IC(0): seconds per step in CG (factorization left out)
    pub ic0_cg_s: f64,
    /// grid, modified block IC(0): factorization seconds per step (over the run)
    pub ic0_factor_s: f64,
    /// grid, modified block IC(0): factorizations in the run
    pub ic0_factorizations: usize,
    /// grid, modified block IC(0): |u - u_block_jacobi| / |u| at the end of the run
    pub ic0_u_difference: f64,
    /// grid, rest-state Cholesky: CG iterations per step (mean)
    pub rc_cg_iterations: f64,
    /// grid, rest-state Cholesky: seconds per step in CG (factorizations left out)
    pub rc_cg_s: f64,
    /// grid, rest-state Cholesky: factorization seconds per step (over the run)
    pub rc_factor_s: f64,
    /// grid, rest-state Cholesky: factorizations in the run
    pub rc_factorizations: usize,
    /// grid, rest-state Cholesky: |u - u_block_jacobi| / |u| at the end of the run
    pub rc_u_difference: f64,
    /// tets: seconds per step in the CG solve
    pub tet_cg_s: f64,
    /// grid: seconds per step in diffusion + advection
    pub grid_advection_s: f64,
    /// grid: seconds per step, all stages
    pub grid_step_s: f64,
    /// grid assembly / grid step (target: at most 0.05)
    pub assembly_fraction: f64,
    /// grid: seconds per step (`Simulation::step`, no advection) with the incompatible element
    /// ([`Element::Incompatible`]), measured alternately with the thesis' element (faster of
    /// two runs each)
    pub incompatible_step_s: f64,
    /// grid: the same with the thesis' element ([`Element::Trilinear`])
    pub trilinear_step_s: f64,
    /// `incompatible_step_s / trilinear_step_s` (issue 12 target: at most 1.3)
    pub incompatible_cost_ratio: f64,
    /// tet assembly / grid assembly (target: at least 2; thesis 2-3)
    pub grid_vs_tet_assembly_speedup: f64,
    /// thesis (GTX 1060): grid nodes
    pub thesis_grid_free_nodes: Option<u32>,
    /// thesis: tetrahedra
    pub thesis_tet_elements: Option<u32>,
    /// thesis: grid cells
    pub thesis_grid_elements: Option<u32>,
    /// thesis (GTX 1060): grid assembly seconds per step
    pub thesis_grid_assembly_s: Option<f64>,
    /// thesis (GTX 1060): tet assembly seconds per step
    pub thesis_tet_assembly_s: Option<f64>,
    /// thesis (GTX 1060, f32): grid CG iterations
    pub thesis_grid_cg_iterations: Option<u32>,
    /// thesis (GTX 1060, f32): tet CG iterations
    pub thesis_tet_cg_iterations: Option<u32>,
    /// thesis (GTX 1060): grid CG seconds per step
    pub thesis_grid_cg_s: Option<f64>,
}

/// Thesis rows (Tables B.5 / B.6, GTX 1060, the columns we reproduce): r, grid nodes, tets,
/// grid cells, tet free nodes, tet assembly s, grid assembly s, tet CG iterations, grid CG
/// iterations, grid CG s.
type ThesisRow = (u32, u32, u32, u32, u32, f64, f64, u32, u32, f64);
const THESIS_B5: [ThesisRow; 4] = [
    (5, 675, 2496, 448, 605, 0.000176, 0.000123, 67, 42, 0.009479),
    (10, 4131, 19968, 3328, 3951, 0.001054, 0.000449, 136, 84, 0.029373),
    (
        15, 13325, 67392, 11520, 12415, 0.003004, 0.001333, 170, 126, 0.105245,
    ),
    (
        20, 29733, 159744, 26624, 28373, 0.007200, 0.002984, 176, 167, 0.288962,
    ),
];
const THESIS_B6: [ThesisRow; 4] = [
    (5, 675, 2496, 448, 630, 0.000152, 0.000110, 51, 40, 0.008629),
    (10, 4131, 19968, 3328, 4131, 0.001065, 0.000449, 84, 61, 0.021316),
    (
        15, 13325, 67392, 11520, 13000, 0.003135, 0.001289, 93, 86, 0.072414,
    ),
    (
        20, 29733, 159744, 26624, 29733, 0.007484, 0.002937, 99, 82, 0.143439,
    ),
];

/// The cuboid's model: B.5 (`ground = false`) or B.6 (`ground = true`)
/// ([`cutfem::fem::model::thesis_cuboid`]).
pub fn cuboid_model(ground: bool) -> Model {
    cutfem::fem::model::thesis_cuboid(ground).1
}

/// The grid's linear solve over a run with one preconditioner.
struct SolveStats {
    iterations: f64,
    cg_s: f64,
    factor_s: f64,
    factorizations: usize,
    u_difference: f64,
}

/// Runs `steps` grid steps with preconditioner `p` (no advection); the final displacement is
/// compared with `reference`.
fn solve_stats(
    grid: &Grid,
    model: &Model,
    p: Preconditioner,
    steps: usize,
    cg_tolerance: f64,
    reference: &gpumat::Matrix<Vec3<f64>>,
) -> Result<SolveStats, String> {
    let mut sim = Simulation::new(grid.clone(), model.clone()).map_err(|e| e.to_string())?;
    sim.solver.cg.tolerance = cg_tolerance;
    sim.solver.preconditioner = p;
    let (mut its, mut solve, mut factor) = (0.0, 0.0, 0.0);
    for _ in 0..steps {
        let info = sim.step().map_err(|e| format!("{}: {e}", p.name()))?;
        its += info.iterations as f64;
        solve += info.solve_s;
        factor += info.factor_s;
    }
    let n = steps as f64;
    let d = gpumat::Matrix::eval(sim.u.ex() - reference.ex());
    Ok(SolveStats {
        iterations: its / n,
        cg_s: (solve - factor) / n,
        factor_s: factor / n,
        factorizations: sim.factorizations(),
        u_difference: d.ex().norm() / reference.ex().norm().max(f64::MIN_POSITIVE),
    })
}

/// Seconds per grid step (`Simulation::step` alone) of the incompatible element and of the
/// thesis' element on the same grid and model, run alternately (two runs each, the faster kept) so the
/// machine's load hits both alike.
fn element_costs(grid: &Grid, model: &Model, steps: usize, cg_tolerance: f64) -> Result<(f64, f64), String> {
    let mut best = [f64::INFINITY; 2];
    for _ in 0..2 {
        for (k, element) in [Element::Incompatible, Element::Trilinear]
            .into_iter()
            .enumerate()
        {
            let m = Model {
                element,
                ..model.clone()
            };
            let mut sim = Simulation::new(grid.clone(), m).map_err(|e| e.to_string())?;
            sim.solver.cg.tolerance = cg_tolerance;
            sim.solver.preconditioner = Preconditioner::BlockJacobi;
            let t = Instant::now();
            for _ in 0..steps {
                sim.step().map_err(|e| format!("{}: {e}", element.name()))?;
            }
            best[k] = best[k].min(t.elapsed().as_secs_f64() / steps as f64);
        }
    }
    Ok((best[0], best[1]))
}

/// Measures one row.
pub fn row(r: u32, ground: bool, steps: usize, cg_tolerance: f64) -> Result<CuboidRow, String> {
    let (shape, model) = cutfem::fem::model::thesis_cuboid(ground);
    let sdf = shape.to_sdf(2.0 * r as f64, 6).map_err(|e| e.to_string())?;
    let grid = Grid::new(sdf).map_err(|e| e.to_string())?;
    let band = Diffusion::new(&grid).map_err(|e| e.to_string())?;
    let mut tet = TetSimulation::from_grid(&grid, model.clone()).map_err(|e| e.to_string())?;
    let mut sim = Simulation::new(grid.clone(), model.clone()).map_err(|e| e.to_string())?;
    sim.solver.cg.tolerance = cg_tolerance;
    tet.solver.cg.tolerance = cg_tolerance;
    // the thesis' preconditioner for the columns compared with its tables
    sim.solver.preconditioner = Preconditioner::BlockJacobi;
    tet.solver.preconditioner = Preconditioner::BlockJacobi;
    let (mut ga, mut gk, mut gc, mut gs, mut gi, mut gadv, mut gstep) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for _ in 0..steps {
        let t = Instant::now();
        let info = sim.step().map_err(|e| e.to_string())?;
        let t_adv = Instant::now();
        let u_band = band.diffuse(&sim.u).map_err(|e| e.to_string())?;
        let _advected = cutfem::fem::advect::advect(&sim.grid, &band, &u_band).map_err(|e| e.to_string())?;
        gadv += t_adv.elapsed().as_secs_f64();
        gstep += t.elapsed().as_secs_f64();
        ga += info.assembly_s;
        gk += info.stiffness_s;
        gc += info.collision_s;
        gs += info.solve_s;
        gi += info.iterations as f64;
    }
    let ic0 = solve_stats(
        &grid,
        &model,
        Preconditioner::BlockIc0,
        steps,
        cg_tolerance,
        &sim.u,
    )?;
    let rc = solve_stats(
        &grid,
        &model,
        Preconditioner::RestCholesky,
        steps,
        cg_tolerance,
        &sim.u,
    )?;
    let (mut ta, mut tk, mut tc, mut ts, mut ti) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for _ in 0..steps {
        let info = tet.step().map_err(|e| e.to_string())?;
        ta += info.assembly_s;
        tk += info.stiffness_s;
        tc += info.collision_s;
        ts += info.solve_s;
        ti += info.iterations as f64;
    }
    let (incompatible_step_s, trilinear_step_s) = element_costs(&grid, &model, steps, cg_tolerance)?;
    let n = steps as f64;
    let table = if ground { &THESIS_B6 } else { &THESIS_B5 };
    let th = table.iter().find(|t| t.0 == r);
    let gp = sim.assembler.pattern();
    let tp = tet.assembler.pattern();
    Ok(CuboidRow {
        case: format!("res={r}"),
        resolution: r,
        steps,
        grid_free_nodes: sim.grid.dofs(),
        grid_empty_nodes: band.empty_count(),
        grid_elements: sim.grid.cells.len(),
        grid_cut_cells: sim.grid.cut_cells(),
        tet_free_nodes: tet.mesh.dofs(),
        tet_fixed_nodes: tet.mesh.fixed_nodes(),
        tet_elements: tet.mesh.tets.len(),
        grid_entries_per_row: gp.nnz() as f64 / gp.rows() as f64,
        tet_entries_per_row: tp.nnz() as f64 / tp.rows() as f64,
        grid_assembly_s: ga / n,
        tet_assembly_s: ta / n,
        grid_stiffness_s: gk / n,
        tet_stiffness_s: tk / n,
        grid_vs_tet_stiffness_speedup: tk / gk,
        grid_collision_s: gc / n,
        tet_collision_s: tc / n,
        grid_cg_iterations: gi / n,
        tet_cg_iterations: ti / n,
        grid_cg_s: gs / n,
        ic0_cg_iterations: ic0.iterations,
        ic0_cg_s: ic0.cg_s,
        ic0_factor_s: ic0.factor_s,
        ic0_factorizations: ic0.factorizations,
        ic0_u_difference: ic0.u_difference,
        rc_cg_iterations: rc.iterations,
        rc_cg_s: rc.cg_s,
        rc_factor_s: rc.factor_s,
        rc_factorizations: rc.factorizations,
        rc_u_difference: rc.u_difference,
        tet_cg_s: ts / n,
        grid_advection_s: gadv / n,
        grid_step_s: gstep / n,
        assembly_fraction: ga / gstep,
        incompatible_step_s,
        trilinear_step_s,
        incompatible_cost_ratio: incompatible_step_s / trilinear_step_s,
        grid_vs_tet_assembly_speedup: ta / ga,
        thesis_grid_free_nodes: th.map(|t| t.1),
        thesis_tet_elements: th.map(|t| t.2),
        thesis_grid_elements: th.map(|t| t.3),
        thesis_tet_assembly_s: th.map(|t| t.5),
        thesis_grid_assembly_s: th.map(|t| t.6),
        thesis_tet_cg_iterations: th.map(|t| t.7),
        thesis_grid_cg_iterations: th.map(|t| t.8),
        thesis_grid_cg_s: th.map(|t| t.9),
    })
}

/// The resolutions and steps of a run: full mode r = 5, 10, 15, 20 with 30 steps (as the
/// thesis), quick mode r = 5, 10 with 10 steps.
pub fn plan(quick: bool) -> (Vec<u32>, usize) {
    if quick {
        (vec![5, 10], 10)
    } else {
        (vec![5, 10, 15, 20], 30)
    }
}

/// CG tolerance of the tables: relative residual 1e-6, the thesis' "error below 1e-6".
pub const CG_TOLERANCE: f64 = 1e-6;

/// Table B.5 (`ground = false`) or B.6 (`ground = true`).
pub fn table(ground: bool, quick: bool) -> Vec<CuboidRow> {
    let (rs, steps) = plan(quick);
    let mut rows = Vec::new();
    for r in rs {
        crate::progress(&format!(
            "{} r = {r} ({steps} steps, grid and tets)",
            if ground { "B.6" } else { "B.5" }
        ));
        match row(r, ground, steps, CG_TOLERANCE) {
            Ok(x) => rows.push(x),
            Err(e) => eprintln!("error: B.{} r = {r}: {e}", if ground { 6 } else { 5 }),
        }
    }
    rows
}

/// Markdown columns of Tables B.5/B.6.
pub fn columns() -> Vec<crate::report::Col> {
    use crate::report::{col, Fmt};
    vec![
        col("r", "resolution", Fmt::Plain),
        col("grid nodes", "grid_free_nodes", Fmt::Plain),
        col("thesis", "thesis_grid_free_nodes", Fmt::Plain),
        col("empty", "grid_empty_nodes", Fmt::Plain),
        col("cells", "grid_elements", Fmt::Plain),
        col("cut", "grid_cut_cells", Fmt::Plain),
        col("tets", "tet_elements", Fmt::Plain),
        col("thesis tets", "thesis_tet_elements", Fmt::Plain),
        col("tet free/fixed", "tet_free_nodes", Fmt::Plain),
        col("blocks/row grid", "grid_entries_per_row", Fmt::Ratio),
        col("blocks/row tet", "tet_entries_per_row", Fmt::Ratio),
        col("grid K ms", "grid_stiffness_s", Fmt::SecondsAsMs),
        col("tet K ms", "tet_stiffness_s", Fmt::SecondsAsMs),
        col("K speedup", "grid_vs_tet_stiffness_speedup", Fmt::Ratio),
        col("grid asm ms", "grid_assembly_s", Fmt::SecondsAsMs),
        col("tet asm ms", "tet_assembly_s", Fmt::SecondsAsMs),
        col("thesis grid asm ms", "thesis_grid_assembly_s", Fmt::SecondsAsMs),
        col("grid coll ms", "grid_collision_s", Fmt::SecondsAsMs),
        col("grid CG its", "grid_cg_iterations", Fmt::Ratio),
        col("thesis grid its", "thesis_grid_cg_iterations", Fmt::Plain),
        col("tet CG its", "tet_cg_iterations", Fmt::Ratio),
        col("grid CG ms", "grid_cg_s", Fmt::SecondsAsMs),
        col("thesis grid CG ms", "thesis_grid_cg_s", Fmt::SecondsAsMs),
        col("tet CG ms", "tet_cg_s", Fmt::SecondsAsMs),
        col("IC0 its", "ic0_cg_iterations", Fmt::Ratio),
        col("IC0 CG ms", "ic0_cg_s", Fmt::SecondsAsMs),
        col("IC0 factor ms", "ic0_factor_s", Fmt::SecondsAsMs),
        col("IC0 facts", "ic0_factorizations", Fmt::Plain),
        col("RC its", "rc_cg_iterations", Fmt::Ratio),
        col("RC CG ms", "rc_cg_s", Fmt::SecondsAsMs),
        col("RC factor ms", "rc_factor_s", Fmt::SecondsAsMs),
        col("RC facts", "rc_factorizations", Fmt::Plain),
        col("advect ms", "grid_advection_s", Fmt::SecondsAsMs),
        col("grid step ms", "grid_step_s", Fmt::SecondsAsMs),
        col("asm / step", "assembly_fraction", Fmt::Percent),
        col("step ms incompatible", "incompatible_step_s", Fmt::SecondsAsMs),
        col("step ms trilinear", "trilinear_step_s", Fmt::SecondsAsMs),
        col("incompatible / trilinear", "incompatible_cost_ratio", Fmt::Ratio),
    ]
}
