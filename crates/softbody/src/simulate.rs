//! `softbody simulate SCENE [--out DIR] [--json]`: the forward run.

use crate::progress;
use cutfem::fem::forward::ForwardRun;
use cutfem::render::{render, Camera, Coloring, Ground, Image, RenderItem, RenderOptions};
use cutfem::scene::Scene;
use cutfem::sdf::NpyDtype;
use cutfem::surface::{extract_surface, write_ply};
use cutfem::TriMesh;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The most frames the picture shows (each is a 320 x 240 tile).
pub const MAX_PICTURE_FRAMES: usize = 64;

/// Arguments of `simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The scene file (TOML, see interface.md).
    pub scene: PathBuf,
    /// Output folder (default: `out/<scene name>`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
    /// Override `[time].steps`.
    #[arg(long)]
    pub steps: Option<usize>,
    /// Number of frames shown in the picture (1 to 64).
    #[arg(long, default_value_t = 4)]
    pub picture_frames: usize,
    /// Also run the scene at twice and half its resolution and report how far the surface
    /// moves differently (the discretisation error of the run, `adjoint::refine`).
    #[arg(long)]
    pub refine_check: bool,
}

/// The default output folder of a scene.
pub fn default_out(scene: &Path, command: &str) -> PathBuf {
    let stem = scene.file_stem().and_then(|s| s.to_str()).unwrap_or("scene");
    PathBuf::from("out").join(format!("{stem}-{command}"))
}

/// Renders frames side by side, with the ground plane when the model has one.
pub fn picture(frames: &[(usize, TriMesh)], ground: Option<f64>) -> Image {
    let all: Vec<&TriMesh> = frames.iter().map(|(_, m)| m).collect();
    let (mut lo, mut hi) = cutfem::render::bounds(&all).unwrap_or(([-1.0; 3], [1.0; 3]));
    if let Some(h) = ground {
        lo[1] = lo[1].min(h);
        hi[1] = hi[1].max(h);
    }
    let camera = Camera::framing(lo, hi, 0.6, 0.35);
    let options = RenderOptions {
        ground: ground.map(|height| Ground {
            height,
            cell: 0.25,
            extent: 6.0,
            ..Ground::default()
        }),
        supersample: 2,
        ..RenderOptions::default()
    };
    let images: Vec<Image> = frames
        .iter()
        .map(|(f, m)| {
            let item = RenderItem {
                mesh: m,
                coloring: Coloring::Uniform([90, 140, 200]),
            };
            let mut img = render(&[item], &camera, 320, 240, &options);
            img.label(&format!("frame {f}"));
            img
        })
        .collect();
    Image::tile(&images, images.len().min(4))
}

/// The frames the picture shows: `n` (at most `steps + 1`) spread evenly over `0..=steps`.
fn picked_frames(n: usize, steps: usize) -> Vec<usize> {
    let n = n.min(steps + 1);
    let mut v: Vec<usize> = (0..n)
        .map(|i| if n == 1 { steps } else { i * steps / (n - 1) })
        .collect();
    v.dedup();
    v
}

/// The height of the horizontal plane the pictures draw for the ground, at the body.
fn ground_line(model: &cutfem::fem::Model) -> Option<f64> {
    model.ground.map(|g| {
        if (g.normal.y - 1.0).abs() < 1e-9 {
            g.height
        } else {
            g.height / g.normal.y.max(1e-9)
        }
    })
}

/// Writes the advected level set of the last frame (`final_advected.npy`) and its picture;
/// returns their entry of the summary's `files`.
fn write_advected(
    out: &std::path::Path,
    adv: &cutfem::SdfGrid,
    steps: usize,
    ground: Option<f64>,
) -> Result<serde_json::Value, String> {
    let npy = out.join("final_advected.npy");
    adv.write_npy(&npy, NpyDtype::F32).map_err(|e| e.to_string())?;
    let adv_png = out.join("final_advected.png");
    let mesh = extract_surface(adv).mesh;
    picture(&[(steps, mesh)], ground)
        .save_png(&adv_png)
        .map_err(|e| e.to_string())?;
    Ok(json!({
        "sdf_npy": npy.display().to_string(), "origin": adv.origin, "spacing": adv.spacing,
        "dims": adv.dims, "picture": adv_png.display().to_string()
    }))
}

/// The warning for a body that starts in the ground ([`cutfem::fem::Simulation::initial_penetration`]).
pub fn penetration_warning(penetration: Option<(f64, f64)>) -> Option<String> {
    let (depth, share) = penetration?;
    Some(format!(
        "warning: the body starts {depth:.4} deep in the ground ({:.0}% of its surface below \
         the plane): the contact springs push it out from the first step; if that is not meant, \
         check [ground] height and normal (the ground is the half-space normal . x >= height)",
        100.0 * share
    ))
}

/// Runs the command.
pub fn run(a: Args) -> Result<(), String> {
    let t_total = Instant::now();
    let scene = Scene::load(&a.scene).map_err(|e| e.to_string())?;
    let steps = crate::problem_args::steps(a.steps, &scene)?;
    if !(1..=MAX_PICTURE_FRAMES).contains(&a.picture_frames) {
        return Err(format!(
            "--picture-frames must lie in 1..={MAX_PICTURE_FRAMES}, found {}",
            a.picture_frames
        ));
    }
    let target = a.out.clone().unwrap_or_else(|| default_out(&a.scene, "simulate"));
    let dir = crate::out_dir::OutDir::begin(&target, &scene.input_files())?;
    let out = dir.path().to_path_buf();
    let frames_dir = out.join("frames");
    std::fs::create_dir_all(&frames_dir).map_err(|e| format!("{}: {e}", frames_dir.display()))?;

    // the scene's model with its model-level effects (e.g. `wind`)
    let mut sim = scene.build_simulation().map_err(|e| e.to_string())?;
    let penetration = sim.initial_penetration();
    if !a.json {
        if let Some(w) = penetration_warning(penetration) {
            crate::note!("{w}");
        }
    }
    let surface = sim
        .grid
        .surface()
        .map_err(|e| format!("{}: {e}", a.scene.display()))?;
    let mut run = ForwardRun::new(&sim, scene.numerics.diffusion).map_err(|e| e.to_string())?;
    let picks = picked_frames(a.picture_frames, steps);
    let mut shown = Vec::new();
    let write_frame = |f: usize, mesh: &TriMesh| -> Result<(), String> {
        let p = frames_dir.join(format!("{f:04}.ply"));
        write_ply(mesh, &p).map_err(|e| e.to_string())
    };
    let m0 = sim.grid.deformed(&surface, &sim.u);
    write_frame(0, &m0)?;
    if picks.contains(&0) {
        shown.push((0, m0));
    }

    let pb = progress::bar(steps as u64, "simulate", a.json);
    let mut push = cutfem::fem::collision::GroundPush::default();
    sim.add_ground_push(&mut push);
    for f in 1..=steps {
        run.frame(&mut sim, f).map_err(|e| e.to_string())?;
        sim.add_ground_push(&mut push);
        let mesh = sim.grid.deformed(&surface, &sim.u);
        write_frame(f, &mesh)?;
        if picks.contains(&f) {
            shown.push((f, mesh));
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    let ForwardRun {
        band,
        advected,
        totals,
    } = run;
    let iterations = &totals.iterations;

    let ground = ground_line(&sim.model);
    let pic_path = out.join("picture.png");
    picture(&shown, ground)
        .save_png(&pic_path)
        .map_err(|e| e.to_string())?;
    // the advected level set of the last frame, as data and as a picture
    let advected_files = match &advected {
        Some(adv) => write_advected(&out, adv, steps, ground)?,
        None => serde_json::Value::Null,
    };

    let refine = a.refine_check.then(|| {
        let params = adjoint::refine::RefineParams {
            steps: Some(steps),
            ..Default::default()
        };
        crate::refine_check::run(&scene, &sim.grid, &sim.model, &params, None, a.json)
    });
    let g = &sim.grid;
    let mut summary = json!({
        "scene": a.scene.display().to_string(),
        "out": out.display().to_string(),
        "nodes": {"active": g.dofs(), "free": g.dofs(), "empty": band.empty_count(), "grid": g.sdf.values.len()},
        "cells": {"active": g.cells.len(), "cut": g.cut_cells()},
        "cell_size": g.h(),
        "volume": g.volume(),
        "mass": sim.total_mass(),
        "steps": steps,
        "seconds": {
            "assembly": totals.info.assembly_s, "solve": totals.info.solve_s,
            "collision": totals.info.collision_s, "advection": totals.advection_s,
            "total": t_total.elapsed().as_secs_f64()
        },
        "solver": {
            "iterations": iterations, "max_residual": totals.info.residual, "fallbacks": totals.fallbacks,
            "preconditioner_substituted": totals.substituted,
            "preconditioner": if sim.device_name().is_some() { "block_jacobi" } else { sim.solver.preconditioner.name() },
            "factorizations": sim.factorizations(),
            "backend": sim.device_name().unwrap_or_else(|| "cpu".into()),
            "contact_newton_iterations": totals.info.newton
        },
        "final": {"max_displacement": sim.max_displacement()},
        "initial_penetration": penetration.map(|(depth, share)| json!({"depth": depth, "share": share})),
        "files": {
            "frames": frames_dir.display().to_string(),
            "picture": pic_path.display().to_string(),
            "advected": advected_files
        },
    });
    if let Some(r) = refine {
        summary["refine_check"] = r;
    }
    let hovers = sim.hovers(&push);
    if sim.model.ground.is_some() {
        summary["ground_push"] = crate::diagnose::ground_push_json(&push, hovers);
    }
    if hovers && !a.json {
        crate::note!("{}", crate::diagnose::hover_note(&push));
    }
    if totals.substituted > 0 && !a.json {
        crate::note!(
            "warning: the {} preconditioner could not be made in {} of {steps} steps; block-Jacobi preconditioned them",
            sim.solver.preconditioner.name(),
            totals.substituted
        );
    }
    if totals.fallbacks > 0 && !a.json {
        crate::note!(
            "warning: CG did not reach its tolerance within {} iterations in {} of {steps} steps; \
             a direct factorization solved them (the step matrix is ill-conditioned: a Poisson \
             ratio near 0.5, a very stiff ground or a very large time step)",
            sim.solver.cg.max_iterations,
            totals.fallbacks
        );
    }
    dir.finish(&mut summary, "summary.json")?;
    if a.json {
        crate::output::print_json(&summary)?;
    } else {
        crate::note!(
            "simulated {steps} steps of {} nodes / {} cells ({} cut) in {:.2} s; max displacement {:.4}; \
             CG iterations {}..{}; frames in {}, picture {}",
            g.dofs(),
            g.cells.len(),
            g.cut_cells(),
            t_total.elapsed().as_secs_f64(),
            sim.max_displacement(),
            iterations.iter().min().unwrap_or(&0),
            iterations.iter().max().unwrap_or(&0),
            target.join("frames").display(),
            target.join("picture.png").display()
        );
    }
    Ok(())
}
