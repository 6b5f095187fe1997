//! Table `scaling`: how the cost of a time step grows with the body's size. The thesis' cuboid
//! held at one end (`examples/scenes/cuboid_dirichlet.toml`, a shape sampled at each
//! resolution) and a scan body (the thesis' bunny, `bunny_small.sdf`, resampled from its
//! trilinear interpolant to each resolution, falling on the ground of
//! `examples/scenes/bunny_ground.toml`), from about 1e3 to 1e5 active nodes, with the
//! scene's own model and the default solver settings (IC(0), corotation), and again with the
//! `multigrid` preconditioner (geometric multigrid V-cycle, `cutfem::fem::solver`). Per body and
//! preconditioner the exponent `p` of `time ~ nodes^p` is the least-squares slope of `ln time`
//! against `ln nodes`, and likewise for the CG iterations per step.
//!
//! For the cuboid also a gradient (forward + cost + backward, Table 5.2's problem: Young's
//! modulus and Poisson ratio, the surface cost of 4 cameras of 32 x 32 pixels, 3 steps) per
//! step, with each preconditioner (the backward solves use the forward's). The bunny's gradient
//! is not timed: its scene reads an SDF file, whose own spacing sets the grid of a fit (the step
//! rows resample the file).

use crate::progress;
use crate::report::{col, markdown_table, Col, Fmt};
use cutfem::fem::{Grid, Preconditioner, Simulation};
use cutfem::scene::Scene;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// One row: one body at one resolution.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// "cuboid" or "bunny"
    pub body: String,
    /// the CG preconditioner's scene name (`block_ic0`: the default)
    pub preconditioner: String,
    /// grid cells per world unit
    pub resolution: f64,
    /// active nodes (degrees of freedom / 3)
    pub nodes: usize,
    /// active cells
    pub cells: usize,
    /// steps timed (after one untimed step)
    pub steps: usize,
    /// seconds per step (whole step), and its assembly and solve shares
    pub step_s: f64,
    pub assembly_s: f64,
    pub solve_s: f64,
    /// seconds per step in the preconditioner's set-up (IC(0) factorization, multigrid
    /// refresh), part of `solve_s`
    pub setup_s: f64,
    /// CG iterations per step
    pub cg_iterations: f64,
    /// seconds per step of a gradient (forward + cost + backward; the cuboid only)
    pub gradient_s: Option<f64>,
    /// the body's fitted exponent of step time against nodes (same in every row of the body)
    pub step_exponent: Option<f64>,
    /// the body's fitted exponent of gradient time against nodes
    pub gradient_exponent: Option<f64>,
    /// the body's fitted exponent of CG iterations against nodes
    pub iteration_exponent: Option<f64>,
}

/// Least-squares slope of `ln y` against `ln x` (`None` with fewer than two points).
pub fn log_slope(points: &[(f64, f64)]) -> Option<f64> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Times `steps` steps (after one untimed) of `scene`'s model on `grid` with preconditioner
/// `pre` (`None`: the scene's).
fn time_steps(
    body: &str,
    scene: &Scene,
    grid: Grid,
    resolution: f64,
    steps: usize,
    pre: Option<Preconditioner>,
) -> Result<Row, String> {
    let model = scene.build_model(&grid).map_err(|e| e.to_string())?;
    let mut sim = Simulation::new(grid, model).map_err(|e| e.to_string())?;
    sim.solver = scene.solver_settings(sim.solver);
    if let Some(p) = pre {
        sim.solver.preconditioner = p;
    }
    sim.step().map_err(|e| e.to_string())?;
    let (mut total, mut asm, mut solve, mut its, mut setup) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for _ in 0..steps {
        let t = Instant::now();
        let info = sim.step().map_err(|e| e.to_string())?;
        total += t.elapsed().as_secs_f64();
        asm += info.assembly_s;
        solve += info.solve_s;
        setup += info.factor_s;
        its += info.iterations as f64;
    }
    let n = steps as f64;
    Ok(Row {
        body: body.to_string(),
        preconditioner: sim.solver.preconditioner.name().to_string(),
        resolution,
        nodes: sim.grid.dofs(),
        cells: sim.grid.cells.len(),
        steps,
        step_s: total / n,
        assembly_s: asm / n,
        solve_s: solve / n,
        setup_s: setup / n,
        cg_iterations: its / n,
        gradient_s: None,
        step_exponent: None,
        gradient_exponent: None,
        iteration_exponent: None,
    })
}

/// Seconds per step of the best of two gradients of Table 5.2's problem on `scene` at
/// `resolution` with preconditioner `pre` (`None`: the scene's), after a warm-up gradient.
fn gradient(
    scene: &Scene,
    resolution: f64,
    steps: usize,
    pre: Option<Preconditioner>,
) -> Result<f64, String> {
    let mut scene = scene.clone();
    scene.body.resolution = Some(resolution);
    if let Some(p) = pre {
        scene.numerics.preconditioner = p;
    }
    let (obs, eyes) = crate::table_adjoint::observe(&scene, steps, 3.0)?;
    let (mut p, x) = crate::table_adjoint::problem(&scene, &obs, &eyes, steps)?;
    p.gradient(&x).map_err(|e| format!("warm-up gradient: {e}"))?;
    let mut best = f64::INFINITY;
    for _ in 0..2 {
        let (ev, _, _) = p.gradient(&x).map_err(|e| e.to_string())?;
        best = best.min(ev.forward_s + ev.cost_s + ev.backward_s);
    }
    Ok(best / steps as f64)
}

/// The rows of one body at `resolutions` with preconditioner `pre` (`None`: the scene's), with
/// their exponents.
fn body_rows(
    body: &str,
    scene_file: &str,
    resolutions: &[f64],
    steps: usize,
    gradients: bool,
    pre: Option<Preconditioner>,
) -> Result<Vec<Row>, String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(scene_file);
    let scene = Scene::load(&path).map_err(|e| format!("{scene_file}: {e}"))?;
    let mut rows = Vec::new();
    for &r in resolutions {
        let with = pre.map_or(String::new(), |p| format!(", {}", p.name()));
        progress(&format!("scaling: {body} at {r} cells per unit{with}"));
        let sdf = scene.body_sdf_at(Some(r)).map_err(|e| e.to_string())?;
        let grid = Grid::new(sdf).map_err(|e| e.to_string())?;
        let mut row = time_steps(body, &scene, grid, r, steps, pre)?;
        if gradients {
            progress(&format!("scaling: {body} at {r} cells per unit, gradient"));
            row.gradient_s = Some(gradient(&scene, r, steps, pre)?);
        }
        rows.push(row);
    }
    let slope =
        |f: fn(&Row) -> f64| log_slope(&rows.iter().map(|r| (r.nodes as f64, f(r))).collect::<Vec<_>>());
    let (p, q) = (slope(|r| r.step_s), slope(|r| r.cg_iterations));
    let g = gradients
        .then(|| slope(|r| r.gradient_s.unwrap_or(0.0)))
        .flatten();
    for r in &mut rows {
        r.step_exponent = p;
        r.iteration_exponent = q;
        r.gradient_exponent = g;
    }
    Ok(rows)
}

/// The table (`quick`: up to about 1e4 nodes); a body that fails is left out with a note.
pub fn table(quick: bool, notes: &mut Vec<String>) -> Vec<Row> {
    // cuboid: 2r cells per unit, r = 5 .. 30 (about 700 .. 1e5 nodes); the bunny (3495 nodes
    // at its file's 5 cells per unit, the thesis' 5.2) from 3 to 15 cells per unit
    let (cuboid, bunny): (&[f64], &[f64]) = if quick {
        (&[10.0, 16.0, 24.0], &[3.0, 4.0, 5.0])
    } else {
        (
            &[10.0, 16.0, 24.0, 36.0, 48.0, 60.0],
            &[3.0, 4.0, 5.0, 7.0, 10.0, 15.0],
        )
    };
    let mut rows = Vec::new();
    for (body, scene, res, gradients, pre) in [
        (
            "cuboid",
            "examples/scenes/cuboid_dirichlet.toml",
            cuboid,
            true,
            None,
        ),
        (
            "cuboid",
            "examples/scenes/cuboid_dirichlet.toml",
            cuboid,
            true,
            Some(Preconditioner::Multigrid),
        ),
        ("bunny", "examples/scenes/bunny_ground.toml", bunny, false, None),
        (
            "bunny",
            "examples/scenes/bunny_ground.toml",
            bunny,
            false,
            Some(Preconditioner::Multigrid),
        ),
    ] {
        match body_rows(body, scene, res, 3, gradients, pre) {
            Ok(mut r) => rows.append(&mut r),
            Err(e) => {
                let with = pre.map_or(String::new(), |p| format!(" with {}", p.name()));
                let why = format!("scaling: {body}{with} failed: {e}");
                eprintln!("warning: {why}");
                notes.push(why);
            }
        }
    }
    rows
}

/// The markdown columns.
fn columns() -> Vec<Col> {
    vec![
        col("body", "body", Fmt::Plain),
        col("preconditioner", "preconditioner", Fmt::Plain),
        col("cells/unit", "resolution", Fmt::Plain),
        col("nodes", "nodes", Fmt::Plain),
        col("cells", "cells", Fmt::Plain),
        col("step ms", "step_s", Fmt::SecondsAsMs),
        col("assembly ms", "assembly_s", Fmt::SecondsAsMs),
        col("solve ms", "solve_s", Fmt::SecondsAsMs),
        col("set-up ms", "setup_s", Fmt::SecondsAsMs),
        col("CG its", "cg_iterations", Fmt::Ratio),
        col("gradient ms/step", "gradient_s", Fmt::SecondsAsMs),
        col("p (step ~ nodes^p)", "step_exponent", Fmt::Ratio),
        col("p (gradient)", "gradient_exponent", Fmt::Ratio),
        col("p (its ~ nodes^p)", "iteration_exponent", Fmt::Ratio),
    ]
}

/// The table's markdown section.
pub fn markdown(rows: &[serde_json::Value]) -> String {
    markdown_table(
        "Table scaling: step time against the number of active nodes",
        "The scenes' models and default solver settings (block IC(0) CG, relative tolerance 1e-6, \
         corotation; the bunny also meets the ground), then the same with the multigrid \
         preconditioner (V(3,3) cycle, Chebyshev smoothing, Galerkin coarse levels); seconds per \
         step averaged over 3 steps after one untimed step; set-up: the preconditioner's \
         factorization or refresh, within the solve; gradient: forward + cost + backward per step \
         of Table 5.2's problem (E and nu, 4 cameras of 32 x 32 pixels, 3 steps; the cuboid only, with \
         each preconditioner). p: least-squares slope of ln(time) (and ln(CG \
         iterations)) against ln(nodes) over the rows of one body and preconditioner.",
        rows,
        &columns(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_slope_recovers_a_power_law() {
        let pts: Vec<(f64, f64)> = [1e3_f64, 1e4, 1e5]
            .iter()
            .map(|&n| (n, 3e-6 * n.powf(1.2)))
            .collect();
        assert!((log_slope(&pts).unwrap() - 1.2).abs() < 1e-12);
        assert_eq!(log_slope(&pts[..1]), None);
    }

    /// Two small resolutions of the cuboid, with each preconditioner: more cells, more nodes, a
    /// positive time, an exponent, a gradient with that preconditioner.
    #[test]
    fn rows_grow_with_the_resolution() {
        for pre in [None, Some(Preconditioner::Multigrid)] {
            let rows = body_rows(
                "cuboid",
                "examples/scenes/cuboid_dirichlet.toml",
                &[6.0, 10.0],
                1,
                true,
                pre,
            )
            .unwrap();
            let name = pre.unwrap_or_default().name();
            assert!(rows.iter().all(|r| r.preconditioner == name), "{pre:?}");
            assert!(rows[1].nodes > rows[0].nodes && rows[1].cells > rows[0].cells);
            assert!(rows.iter().all(|r| r.step_s > 0.0 && r.cg_iterations > 0.0));
            assert!(rows.iter().all(|r| r.gradient_s.is_some_and(|g| g > 0.0)));
            assert!(rows[0].step_exponent.is_some() && rows[0].gradient_exponent.is_some());
        }
    }
}
