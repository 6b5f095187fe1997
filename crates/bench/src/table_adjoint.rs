//! Table 5.2 (thesis sec. 5.9): the adjoint's performance on three bodies, the swinging
//! torus, the bunny falling on the ground and the dragon held at the head. Per time step:
//! forward time (the steps without the cost), cost time (cost and its gradient), backward
//! time, backward / forward, and the CG iterations of the forward and adjoint solves.
//!
//! Every case fits Young's modulus and Poisson's ratio to noise-free observations of its
//! own scene (4 virtual cameras of 32 x 32 pixels, seed 0, frames 1..=steps, surface cost),
//! and the gradient is taken at a perturbed start (E x 1.1, nu + 0.02; the thesis' torus
//! experiment started at k = 2200, nu = 0.32 from the truth 2000, 0.3). One warm-up
//! gradient, then the minimum of each time over the repetitions.
//!
//! The memory row runs a long dragon gradient (300 steps; `--quick`: 60) in a child process
//! (the `tables` binary re-invoked with a hidden flag) on observations written by the parent,
//! and reads the child's resident set: `VmRSS` once the problem is set up and `VmHWM` (the
//! peak) after the gradient.

use adjoint::cost::Robust;
use adjoint::fit::{scene_problem, CostKind};
use adjoint::observations::Observations;
use adjoint::observe::{rig_around, synthesize, RigParams};
use adjoint::params::ParamSet;
use adjoint::problem::Problem;
use cutfem::scene::Scene;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::progress;
use crate::report::{col, markdown_table, Col, Fmt};

/// Thesis Table 5.2 ("Timings of the benchmarks", sec. 5.9, NVIDIA GTX 1060, f32): the
/// columns we reproduce.
#[derive(Clone, Copy, Debug)]
struct Thesis {
    active_nodes: u32,
    active_cells: u32,
    steps: usize,
    /// forward time per time step, average, seconds
    forward_s: f64,
    /// cost evaluation per time step, average, seconds
    cost_s: f64,
    /// backward time per time step, average, seconds
    backward_s: f64,
}

/// One body of the table.
#[derive(Clone, Copy, Debug)]
struct Body {
    case: &'static str,
    /// scene file, relative to the workspace root
    scene: &'static str,
    /// distance of the cameras from the body's centre
    radius: f64,
    /// steps of the `--quick` run
    quick_steps: usize,
    thesis: Thesis,
}

/// The thesis' Table 5.2: "# active nodes" 9220 / 3495 / 13575, "# active cells"
/// 7180 / 2560 / 9968, "# timesteps" 30 / 65 / 30; per time step (avg, min, max in s):
/// forward 0.211, 0.168, 0.343 / 0.039, 0.027, 0.095 / 0.450, 0.188, 0.712; cost
/// 0.021, 0.186, 0.026 (sic: the torus' min exceeds its avg and max, a typo for 0.0186?) /
/// 0.0088, 0.0053, 0.065 / 0.027, 0.012, 0.044; backward 0.392, 0.211, 0.519 /
/// 0.077, 0.0039, 0.110 / 0.900, 0.368, 1.216. We take the averages. We run the thesis'
/// number of steps.
const BODIES: [Body; 3] = [
    Body {
        case: "torus",
        scene: "examples/scenes/swinging_torus.toml",
        radius: 3.0,
        quick_steps: 10,
        thesis: Thesis {
            active_nodes: 9220,
            active_cells: 7180,
            steps: 30,
            forward_s: 0.211,
            cost_s: 0.021,
            backward_s: 0.392,
        },
    },
    Body {
        case: "bunny",
        scene: "examples/scenes/bunny_ground.toml",
        radius: 12.0,
        quick_steps: 30,
        thesis: Thesis {
            active_nodes: 3495,
            active_cells: 2560,
            steps: 65,
            forward_s: 0.039,
            cost_s: 0.0088,
            backward_s: 0.077,
        },
    },
    Body {
        case: "dragon",
        scene: "examples/scenes/dragon_swing.toml",
        radius: 12.0,
        quick_steps: 10,
        thesis: Thesis {
            active_nodes: 13575,
            active_cells: 9968,
            steps: 30,
            forward_s: 0.450,
            cost_s: 0.027,
            backward_s: 0.900,
        },
    },
];

/// Thesis sec. 5.7: the dragon's 300-step adjoint needs "around 540 MB" (GPU) once the
/// matrices are recomputed in the backward pass instead of stored.
pub const THESIS_DRAGON_300_MB: f64 = 540.0;
/// Steps of the memory run (full / `--quick`).
const MEMORY_STEPS: [usize; 2] = [300, 60];

/// One timing row of Table 5.2 (`null`: the case could not run; see the notes).
#[derive(Clone, Debug, Default, Serialize)]
pub struct AdjointRow {
    /// "torus", "bunny", "dragon"
    pub case: String,
    /// time steps simulated (all observed)
    pub steps: usize,
    /// active grid nodes (3 unknowns each)
    pub dofs: Option<usize>,
    /// active grid cells
    pub active_cells: Option<usize>,
    /// observed points over all frames
    pub observed_points: Option<usize>,
    /// seconds per step of the forward pass (cost left out)
    pub forward_s: Option<f64>,
    /// seconds per step of the cost and its gradient
    pub cost_s: Option<f64>,
    /// seconds per step of the backward pass
    pub backward_s: Option<f64>,
    /// backward_s / forward_s (target: at most 1.5)
    pub backward_over_forward: Option<f64>,
    /// CG iterations per step of the forward solves (mean)
    pub forward_iterations: Option<f64>,
    /// CG iterations per step of the adjoint solves (mean)
    pub backward_iterations: Option<f64>,
    /// thesis (GTX 1060): active nodes
    pub thesis_active_nodes: u32,
    /// thesis: active cells
    pub thesis_active_cells: u32,
    /// thesis: time steps
    pub thesis_steps: usize,
    /// thesis (GTX 1060): forward seconds per step (average)
    pub thesis_forward_s: f64,
    /// thesis (GTX 1060): cost seconds per step (average)
    pub thesis_cost_s: f64,
    /// thesis (GTX 1060): backward seconds per step (average)
    pub thesis_backward_s: f64,
    /// thesis: backward / forward
    pub thesis_backward_over_forward: f64,
}

/// The memory row of Table 5.2: a long dragon gradient in a child process.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MemoryRow {
    /// "dragon memory"
    pub case: String,
    /// time steps of the gradient (all observed)
    pub steps: usize,
    /// active grid nodes
    pub dofs: Option<usize>,
    /// resident set once the problem is set up, before the gradient, MB (1e6 bytes)
    pub rss_before_mb: Option<f64>,
    /// peak resident set of the child (`VmHWM`) at the end of the gradient, MB (target:
    /// at most 600 for 300 steps)
    pub peak_rss_mb: Option<f64>,
    /// peak_rss_mb - rss_before_mb: what the gradient itself added, MB
    pub gradient_mb: Option<f64>,
    /// what the stored trajectory takes by count: u and v of every frame, 3 f64 per node
    /// each (as `adjoint::problem` keeps them; the cost gradients are recomputed), MB
    pub trajectory_mb: Option<f64>,
    /// seconds of the gradient (forward + cost + backward)
    pub gradient_s: Option<f64>,
    /// whether the peak was reset before the gradient (`/proc/self/clear_refs`), so that it
    /// counts the gradient only
    pub peak_reset: Option<bool>,
    /// the same gradient over the first half of the steps (a second child): its peak, MB
    pub half_peak_rss_mb: Option<f64>,
    /// peak memory per stored step: the peaks' difference over the steps' difference
    /// (`(peak(steps) - peak(steps / 2)) / (steps - steps / 2)`), MB
    pub peak_mb_per_step: Option<f64>,
    /// the stored trajectory per step by count (`trajectory_mb / (steps + 1)`), MB
    pub trajectory_mb_per_step: Option<f64>,
    /// thesis (sec. 5.7, GTX 1060): memory of the 300-step dragon adjoint, MB
    pub thesis_peak_mb: f64,
}

/// A row of Table 5.2: a body's timings or the memory run.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum Row {
    /// per-step timings of one body
    Timing(AdjointRow),
    /// the long dragon gradient's memory
    Memory(MemoryRow),
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The rig of 4 cameras of 32 x 32 pixels (seed 0) at `radius` from the centre of the body's
/// reference surface.
fn rig(radius: f64) -> RigParams {
    RigParams {
        cameras: 4,
        pixels: 32,
        radius,
        seed: 0,
        ..RigParams::default()
    }
}

/// Noise-free observations of the scene's own simulation, frames 1..=steps, and the eyes of
/// the cameras.
pub(crate) fn observe(
    scene: &Scene,
    steps: usize,
    radius: f64,
) -> Result<(Observations, Vec<[f64; 3]>), String> {
    let (obs, cameras) = synthesize(scene, &rig(radius), 0.0, steps, |_, _| {})?;
    Ok((obs, cameras.iter().map(|c| c.camera.eye).collect()))
}

/// The problem of a scene for `steps` steps with its observations, and the perturbed start.
pub(crate) fn problem(
    scene: &Scene,
    obs: &Observations,
    eyes: &[[f64; 3]],
    steps: usize,
) -> Result<(Problem, Vec<f64>), String> {
    let params = ParamSet::parse(&["young,poisson"])?;
    let p = scene_problem(
        scene,
        obs,
        params,
        Robust::Squared,
        Some(steps),
        CostKind::Surface,
        eyes,
    )?;
    let mut start = p.base.clone();
    start.young *= 1.1;
    start.poisson += 0.02;
    let x = p.params.to_x(&start);
    Ok((p, x))
}

fn load(body: &Body) -> Result<Scene, String> {
    let path = root().join(body.scene);
    Scene::load(&path).map_err(|e| format!("{}: {e}", body.scene))
}

fn time_body(body: &Body, steps: usize, reps: usize, row: &mut AdjointRow) -> Result<(), String> {
    let scene = load(body)?;
    let (obs, eyes) = observe(&scene, steps, body.radius)?;
    row.observed_points = Some(obs.len());
    let (mut p, x) = problem(&scene, &obs, &eyes, steps)?;
    row.dofs = Some(p.sim.grid.dofs());
    row.active_cells = Some(p.sim.grid.cells.len());
    p.gradient(&x).map_err(|e| format!("warm-up gradient: {e}"))?;
    let (mut fwd, mut cost, mut bwd) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let n = steps as f64;
    for _ in 0..reps {
        let (ev, _, _) = p.gradient(&x).map_err(|e| e.to_string())?;
        fwd = fwd.min(ev.forward_s);
        cost = cost.min(ev.cost_s);
        bwd = bwd.min(ev.backward_s);
        row.forward_iterations = Some(ev.forward_iterations as f64 / n);
        row.backward_iterations = Some(ev.backward_iterations as f64 / n);
    }
    row.forward_s = Some(fwd / n);
    row.cost_s = Some(cost / n);
    row.backward_s = Some(bwd / n);
    row.backward_over_forward = Some(bwd / fwd);
    Ok(())
}

/// Measures Table 5.2; returns its rows and notes for the machine object.
pub fn table(quick: bool) -> (Vec<Row>, Vec<String>) {
    let reps = if quick { 1 } else { 3 };
    let mut rows = Vec::new();
    let mut notes = vec![format!(
        "5.2: fit of young and poisson to noise-free observations of the scene's own run (4 cameras, \
         32 x 32 pixels, seed 0, frames 1..=steps, surface cost), gradient at E x 1.1, nu + 0.02; \
         per step = seconds of one gradient / steps; minimum of each time over {reps} gradient(s) \
         after one warm-up; iterations are CG iterations per step (mean). Thesis columns: Table 5.2 \
         averages (GTX 1060, f32){}",
        if quick {
            "; quick mode: fewer steps than the thesis (torus 10, bunny 30, dragon 10)"
        } else {
            ""
        }
    )];
    for body in &BODIES {
        let steps = if quick {
            body.quick_steps
        } else {
            body.thesis.steps
        };
        progress(&format!("5.2 {} ({steps} steps)", body.case));
        let th = body.thesis;
        let mut row = AdjointRow {
            case: body.case.into(),
            steps,
            thesis_active_nodes: th.active_nodes,
            thesis_active_cells: th.active_cells,
            thesis_steps: th.steps,
            thesis_forward_s: th.forward_s,
            thesis_cost_s: th.cost_s,
            thesis_backward_s: th.backward_s,
            thesis_backward_over_forward: th.backward_s / th.forward_s,
            ..AdjointRow::default()
        };
        if let Err(e) = time_body(body, steps, reps, &mut row) {
            notes.push(format!("5.2 {}: could not run: {e}", body.case));
        }
        rows.push(Row::Timing(row));
    }
    let steps = MEMORY_STEPS[usize::from(quick)];
    progress(&format!("5.2 dragon memory ({steps} steps, child process)"));
    let (mem, note) = memory(steps);
    notes.push(note);
    rows.push(Row::Memory(mem));
    (rows, notes)
}

/// Writes the observations, runs the child and reads its report.
fn memory(steps: usize) -> (MemoryRow, String) {
    let mut row = MemoryRow {
        case: "dragon memory".into(),
        steps,
        thesis_peak_mb: THESIS_DRAGON_300_MB,
        ..MemoryRow::default()
    };
    let csv =
        |steps: usize| std::env::temp_dir().join(format!("tables-5.2-{}-{steps}.csv", std::process::id()));
    // one child per step count, each on observations of its own length
    let child = |steps: usize| -> Result<serde_json::Value, String> {
        let scene = load(&BODIES[2])?;
        observe(&scene, steps, BODIES[2].radius)?
            .0
            .write_csv(csv(steps))
            .map_err(|e| e.to_string())?;
        let exe = std::env::current_exe().map_err(|e| e.to_string())?;
        let out = std::process::Command::new(exe)
            .arg("--adjoint-memory-child")
            .arg(csv(steps))
            .arg("--adjoint-memory-steps")
            .arg(steps.to_string())
            .stderr(std::process::Stdio::inherit())
            .output()
            .map_err(|e| format!("cannot start the child: {e}"))?;
        if !out.status.success() {
            return Err(format!("the child failed ({})", out.status));
        }
        serde_json::from_slice(&out.stdout).map_err(|e| format!("the child's report: {e}"))
    };
    let run = || -> Result<(serde_json::Value, serde_json::Value), String> {
        Ok((child(steps)?, child(steps / 2)?))
    };
    let result = run();
    let _ = std::fs::remove_file(csv(steps));
    let _ = std::fs::remove_file(csv(steps / 2));
    let note = match result {
        Ok((v, half)) => {
            let f = |k: &str| v.get(k).and_then(serde_json::Value::as_f64);
            row.dofs = v
                .get("dofs")
                .and_then(serde_json::Value::as_u64)
                .map(|d| d as usize);
            row.rss_before_mb = f("rss_before_mb");
            row.peak_rss_mb = f("peak_rss_mb");
            row.gradient_mb = row.peak_rss_mb.zip(row.rss_before_mb).map(|(p, b)| p - b);
            row.trajectory_mb = f("trajectory_mb");
            row.gradient_s = f("gradient_s");
            row.peak_reset = v.get("peak_reset").and_then(serde_json::Value::as_bool);
            row.half_peak_rss_mb = half.get("peak_rss_mb").and_then(serde_json::Value::as_f64);
            row.peak_mb_per_step = row
                .peak_rss_mb
                .zip(row.half_peak_rss_mb)
                .map(|(p, h)| (p - h) / (steps - steps / 2) as f64);
            row.trajectory_mb_per_step = row.trajectory_mb.map(|t| t / (steps + 1) as f64);
            format!(
                "5.2 memory: a {steps}-step dragon gradient in a child process (this binary with a hidden \
                 flag) on observations written by the parent; rss_before = VmRSS after the problem is set \
                 up, peak = VmHWM at the end of the gradient{}; per stored step = the difference of the \
                 peaks of a {steps}-step and a {}-step gradient (two children) over the steps' difference; \
                 MB = 1e6 bytes{}",
                if row.peak_reset == Some(true) {
                    " (the peak was reset just before the gradient)"
                } else {
                    " (the peak could not be reset: it includes the set-up)"
                },
                steps / 2,
                if steps < 300 {
                    "; quick mode: fewer steps than the target's 300"
                } else {
                    ""
                }
            )
        }
        Err(e) => format!("5.2 memory: could not run: {e}"),
    };
    (row, note)
}

/// `VmRSS` and `VmHWM` of this process, in bytes.
fn rss() -> Option<(f64, f64)> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb = |key: &str| -> Option<f64> {
        let line = s.lines().find(|l| l.starts_with(key))?;
        Some(line.split_whitespace().nth(1)?.parse::<f64>().ok()? * 1024.0)
    };
    Some((kb("VmRSS:")?, kb("VmHWM:")?))
}

/// The child of the memory run: one gradient of `steps` steps on the dragon with the
/// observations in `csv`; prints one JSON object on stdout.
pub fn memory_child(csv: &Path, steps: usize) -> Result<(), String> {
    let scene = load(&BODIES[2])?;
    let obs = Observations::read_csv(csv).map_err(|e| e.to_string())?;
    // the same rig as the parent's (deterministic)
    let surface = scene
        .grid()
        .and_then(|g| g.surface())
        .map_err(|e| e.to_string())?;
    let (_, cameras) = rig_around(&surface.mesh, &rig(BODIES[2].radius))?;
    let eyes: Vec<[f64; 3]> = cameras.iter().map(|c| c.camera.eye).collect();
    let (mut p, x) = problem(&scene, &obs, &eyes, steps)?;
    drop(obs);
    let dofs = p.sim.grid.dofs();
    let (before, _) = rss().ok_or("cannot read /proc/self/status")?;
    // "5" resets the peak resident set size (Linux >= 4.0)
    let peak_reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
    let t = Instant::now();
    p.gradient(&x).map_err(|e| e.to_string())?;
    let gradient_s = t.elapsed().as_secs_f64();
    let (_, peak) = rss().ok_or("cannot read /proc/self/status")?;
    let vector = 3.0 * 8.0 * dofs as f64;
    let trajectory = vector * 2.0 * (steps + 1) as f64;
    let report = serde_json::json!({
        "steps": steps,
        "dofs": dofs,
        "rss_before_mb": before / 1e6,
        "peak_rss_mb": peak / 1e6,
        "trajectory_mb": trajectory / 1e6,
        "gradient_s": gradient_s,
        "peak_reset": peak_reset,
    });
    println!("{report}");
    Ok(())
}

/// The columns of the timing table.
fn timing_columns() -> Vec<Col> {
    vec![
        col("case", "case", Fmt::Plain),
        col("steps", "steps", Fmt::Plain),
        col("nodes", "dofs", Fmt::Plain),
        col("cells", "active_cells", Fmt::Plain),
        col("fwd ms", "forward_s", Fmt::SecondsAsMs),
        col("cost ms", "cost_s", Fmt::SecondsAsMs),
        col("bwd ms", "backward_s", Fmt::SecondsAsMs),
        col("bwd/fwd", "backward_over_forward", Fmt::Ratio),
        col("fwd its", "forward_iterations", Fmt::Ratio),
        col("bwd its", "backward_iterations", Fmt::Ratio),
        col("thesis steps", "thesis_steps", Fmt::Plain),
        col("thesis nodes", "thesis_active_nodes", Fmt::Plain),
        col("thesis fwd ms", "thesis_forward_s", Fmt::SecondsAsMs),
        col("thesis cost ms", "thesis_cost_s", Fmt::SecondsAsMs),
        col("thesis bwd ms", "thesis_backward_s", Fmt::SecondsAsMs),
        col("thesis bwd/fwd", "thesis_backward_over_forward", Fmt::Ratio),
    ]
}

/// The columns of the memory table.
fn memory_columns() -> Vec<Col> {
    vec![
        col("case", "case", Fmt::Plain),
        col("steps", "steps", Fmt::Plain),
        col("nodes", "dofs", Fmt::Plain),
        col("RSS before MB", "rss_before_mb", Fmt::Gbs),
        col("peak RSS MB", "peak_rss_mb", Fmt::Gbs),
        col("gradient MB", "gradient_mb", Fmt::Gbs),
        col("trajectory MB", "trajectory_mb", Fmt::Gbs),
        col("peak MB per step", "peak_mb_per_step", Fmt::Ratio),
        col("trajectory MB per step", "trajectory_mb_per_step", Fmt::Ratio),
        col("gradient s", "gradient_s", Fmt::Ratio),
        col("peak reset", "peak_reset", Fmt::Plain),
        col("thesis MB", "thesis_peak_mb", Fmt::Gbs),
    ]
}

/// The markdown of Table 5.2 from its JSON rows.
pub fn markdown(rows: &[serde_json::Value]) -> String {
    let (mem, timing): (Vec<_>, Vec<_>) = rows.iter().cloned().partition(|r| r.get("peak_rss_mb").is_some());
    let mut s = markdown_table(
        "Table 5.2: adjoint gradient per time step (forward, cost, backward), fit of E and nu",
        "Times per step = one gradient's seconds / steps (minimum over the repetitions); its = CG \
         iterations per step. Thesis columns: Table 5.2 averages, thesis, GTX 1060 (f32).",
        &timing,
        &timing_columns(),
    );
    s.push_str(&markdown_table(
        "Table 5.2 (memory): peak resident set of a long dragon gradient (child process)",
        "RSS before = after setting up the problem; peak = VmHWM after the gradient; gradient = \
         peak - before; trajectory = the stored u and v (3 f64 per node, every frame) by count; \
         peak per step = (peak of this gradient - peak of the same gradient over half the steps) / \
         the steps' difference, the measured growth of the peak per stored step; \
         MB = 1e6 bytes. Thesis: 540 MB for 300 steps after recomputation (sec. 5.7, thesis, GTX 1060).",
        &mem,
        &memory_columns(),
    ));
    s
}
