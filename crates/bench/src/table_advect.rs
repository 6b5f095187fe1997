//! Table 4.4 (thesis Fig. 4.3 / 4.4, sec. 4.4.5): what the level-set advection adds to a time
//! step of the cuboid, held at one end (case 1) and falling on the ground (case 2), per
//! resolution: the diffusion of the displacements into the empty band nodes (a batched CG,
//! [`cutfem::fem::advect::Diffusion`]) and the advection of the SDF (the bounding box of the
//! displaced band and the Direct Forward splat, [`cutfem::fem::advect::advect`]; the thesis
//! timed the bounding box apart, ours computes it inside the advection), beside the elasticity
//! step (the thesis' block-Jacobi CG, as in Table B.5).

use crate::progress;
use crate::report::{col, markdown_table, Col, Fmt};
use cutfem::fem::advect::{advect, Diffusion};
use cutfem::fem::{Grid, Preconditioner, Simulation};
use serde::Serialize;
use std::time::Instant;

/// One row: one case at one resolution.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// "held" or "ground"
    pub case: String,
    /// the thesis' resolution r (cells of size 1/(2r))
    pub resolution: u32,
    /// steps averaged
    pub steps: usize,
    /// active nodes, and the empty band nodes the diffusion fills
    pub nodes: usize,
    pub band_nodes: usize,
    /// seconds per step: the elasticity step, the diffusion, the advection (bounding box
    /// included)
    pub step_s: f64,
    pub diffusion_s: f64,
    pub advection_s: f64,
    /// diffusion CG iterations per step (the most of the three coordinates)
    pub diffusion_iterations: f64,
    /// (diffusion + advection) / elasticity step
    pub advection_share: f64,
}

/// The row of one case at resolution `r`.
fn row(ground: bool, r: u32, steps: usize) -> Result<Row, String> {
    let (shape, model) = cutfem::fem::model::thesis_cuboid(ground);
    let sdf = shape.to_sdf(2.0 * r as f64, 6).map_err(|e| e.to_string())?;
    let grid = Grid::new(sdf).map_err(|e| e.to_string())?;
    let band = Diffusion::new(&grid).map_err(|e| e.to_string())?;
    let mut sim = Simulation::new(grid, model).map_err(|e| e.to_string())?;
    sim.solver.preconditioner = Preconditioner::BlockJacobi;
    let (mut st, mut di, mut ad, mut its) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..steps {
        let t = Instant::now();
        sim.step().map_err(|e| e.to_string())?;
        let t1 = Instant::now();
        let (u_band, info) = band.diffuse_info(&sim.u).map_err(|e| e.to_string())?;
        let t2 = Instant::now();
        let moved = advect(&sim.grid, &band, &u_band).map_err(|e| e.to_string())?;
        std::hint::black_box(moved);
        let t3 = Instant::now();
        st += (t1 - t).as_secs_f64();
        di += (t2 - t1).as_secs_f64();
        ad += (t3 - t2).as_secs_f64();
        its += info.iterations.iter().copied().max().unwrap_or(0) as f64;
    }
    let n = steps as f64;
    Ok(Row {
        case: if ground { "ground" } else { "held" }.into(),
        resolution: r,
        steps,
        nodes: sim.grid.dofs(),
        band_nodes: band.empty_count(),
        step_s: st / n,
        diffusion_s: di / n,
        advection_s: ad / n,
        diffusion_iterations: its / n,
        advection_share: (di + ad) / st,
    })
}

/// The table: r = 5, 10, 15, 20 (`quick`: 5, 10), 10 steps each, both cases; a failing row
/// is left out with a note.
pub fn table(quick: bool, notes: &mut Vec<String>) -> Vec<Row> {
    let rs: &[u32] = if quick { &[5, 10] } else { &[5, 10, 15, 20] };
    let mut rows = Vec::new();
    for ground in [false, true] {
        for &r in rs {
            progress(&format!("4.4: {} r={r}", if ground { "ground" } else { "held" }));
            match row(ground, r, 10) {
                Ok(row) => rows.push(row),
                Err(e) => notes.push(format!("4.4 r={r} failed: {e}")),
            }
        }
    }
    rows
}

fn columns() -> Vec<Col> {
    vec![
        col("case", "case", Fmt::Plain),
        col("r", "resolution", Fmt::Plain),
        col("nodes", "nodes", Fmt::Plain),
        col("band nodes", "band_nodes", Fmt::Plain),
        col("step ms", "step_s", Fmt::SecondsAsMs),
        col("diffusion ms", "diffusion_s", Fmt::SecondsAsMs),
        col("diffusion its", "diffusion_iterations", Fmt::Ratio),
        col("advection ms", "advection_s", Fmt::SecondsAsMs),
        col("(diffusion + advection) / step", "advection_share", Fmt::Percent),
    ]
}

/// The table's markdown section.
pub fn markdown(rows: &[serde_json::Value]) -> String {
    markdown_table(
        "Table 4.4: the level-set advection's cost per step (thesis Fig. 4.3 / 4.4)",
        "The cuboid of Table B.5 (held) and B.6 (ground), corotation on, block-Jacobi CG 1e-6; per \
         step, averaged over 10 steps: the elasticity step, the diffusion of the displacements into \
         the empty band nodes (Jacobi CG, warm-started), the advection of the SDF (bounding box of \
         the displaced band and the Direct Forward splat). The thesis found the advection at high \
         resolution about 20% of the elasticity step (GTX 1060).",
        rows,
        &columns(),
    )
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_small_row_is_measured() {
        let r = super::row(false, 3, 2).unwrap();
        assert!(r.band_nodes > 0 && r.step_s > 0.0 && r.diffusion_s > 0.0 && r.advection_s > 0.0);
        assert!(r.diffusion_iterations >= 1.0);
    }
}
