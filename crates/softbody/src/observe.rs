//! `softbody observe SCENE [--out OBS.csv] [--cameras N] [--pixels W] [--noise SIGMA]
//! [--seed S] ...`: virtual RGB-D cameras look at the simulated body and the points they see
//! are written as an observation CSV (`frame,x,y,z,camera`, interface.md).
//!
//! The scene is simulated as by `simulate` (every effect of its model); at each observed
//! frame the reference marching-cubes surface moved by the interpolated displacements
//! (`Grid::deformed`) is rendered by every camera of the rig (`adjoint::observe`: cameras
//! at distance `--radius` from the centre of the body's reference bounding box, polar angle
//! from +y uniform in [pi/6, pi/2], azimuth uniform in [0, 2 pi), drawn from `--seed`),
//! Gaussian noise of standard deviation `--noise` is added to every depth, and the pixels
//! are unprojected to world points. Frames 1..=steps are observed (the states after each
//! step); `--include-reference` adds frame 0, `--frames` picks a list instead.

use crate::progress;
use crate::simulate::default_out;
use adjoint::observe::{observe_run, render_depth, DepthCamera, ObservationRun, RigParams};
use cutfem::render::{viridis, Image};
use cutfem::scene::Scene;
use cutfem::TriMesh;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::Instant;

/// The most points `observe` may be asked to see (cameras x pixels^2 x frames): 2^27, about
/// 5 GiB of points in memory.
pub const MAX_POINTS: u64 = 1 << 27;

/// Arguments of `observe`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The scene file (TOML, see interface.md).
    pub scene: PathBuf,
    /// Output CSV file (default: `out/<scene name>-observe/observations.csv`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Number of cameras.
    #[arg(long, default_value_t = 4)]
    pub cameras: usize,
    /// Image side in pixels: every camera renders W x W depths.
    #[arg(long, default_value_t = 32)]
    pub pixels: usize,
    /// Standard deviation of the Gaussian depth noise, in world units.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub noise: f64,
    /// Seed of the camera placement and the noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Distance of the cameras from the centre of the body's reference bounding box.
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
    pub radius: f64,
    /// Field of view of the cameras in degrees.
    #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
    pub fov: f64,
    /// Override `[time].steps`.
    #[arg(long)]
    pub steps: Option<usize>,
    /// Frames to observe instead of 1..=steps, e.g. `0,5,10-20` (frame f = after f steps).
    #[arg(long)]
    pub frames: Option<String>,
    /// Also observe frame 0, the reference configuration.
    #[arg(long)]
    pub include_reference: bool,
    /// Also write a PNG of every camera's depth image at the last observed frame.
    #[arg(long)]
    pub preview: Option<PathBuf>,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Parses `0,5,10-20` into sorted, distinct frame numbers, each at most `steps`: every
/// number is checked before a range is expanded (so a range's size is bounded by the steps).
fn parse_frames(s: &str, steps: usize) -> Result<Vec<usize>, String> {
    let quoted = |part: &str| cutfem::scene::quote(part, 100);
    let bad = |part: &str| {
        format!(
            "--frames: {:?} is not a frame number or a range a-b",
            quoted(part)
        )
    };
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim) {
        let num = |t: &str| {
            let f = t.trim().parse::<usize>().map_err(|_| bad(part))?;
            if f > steps {
                return Err(format!(
                    "--frames: frame {f} is beyond the {steps} steps simulated (raise [time].steps or pass --steps)"
                ));
            }
            Ok(f)
        };
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b) = (num(a)?, num(b)?);
                if a > b {
                    return Err(format!("--frames: empty range {:?}", quoted(part)));
                }
                out.extend(a..=b);
            }
            None => out.push(num(part)?),
        }
        out.sort_unstable();
        out.dedup();
    }
    Ok(out)
}

/// The depth images of all cameras side by side (viridis, near = dark), each at least
/// 128 pixels wide.
fn preview(mesh: &TriMesh, cameras: &[DepthCamera], frame: usize) -> Image {
    let tiles: Vec<Image> = cameras
        .iter()
        .enumerate()
        .map(|(k, cam)| {
            let d = render_depth(mesh, cam);
            let hit = d.depth.iter().copied().filter(|z| z.is_finite());
            let lo = hit.clone().fold(f64::INFINITY, f64::min);
            let hi = hit.fold(f64::NEG_INFINITY, f64::max);
            let s = 128usize.div_ceil(d.width.max(1)).max(1);
            let mut img = Image::new(d.width * s, d.height * s, [40, 40, 40]);
            for j in 0..d.height {
                for i in 0..d.width {
                    let z = d.depth[j * d.width + i];
                    if z.is_finite() {
                        let t = if hi > lo { (z - lo) / (hi - lo) } else { 0.5 };
                        img.fill_rect(i * s, j * s, s, s, viridis(t));
                    }
                }
            }
            img.label(&format!("cam {k} f {frame}"));
            img
        })
        .collect();
    Image::tile(&tiles, tiles.len().min(4))
}

/// The camera rig of the flags, checked (sizes a machine can hold; errors name the flag).
fn rig(a: &Args) -> Result<RigParams, String> {
    if !(a.noise.is_finite() && a.noise >= 0.0) {
        return Err(format!(
            "--noise must be a non-negative number, found {}",
            a.noise
        ));
    }
    let rig = RigParams {
        cameras: a.cameras,
        pixels: a.pixels,
        radius: a.radius,
        fov_y: a.fov.to_radians(),
        seed: a.seed,
        ..RigParams::default()
    };
    // sizes a machine can hold (a W x W depth image is 8 W^2 bytes per camera)
    if a.pixels > 8192 {
        return Err(format!("--pixels must be at most 8192, found {}", a.pixels));
    }
    if a.cameras > 10_000 {
        return Err(format!("--cameras must be at most 10000, found {}", a.cameras));
    }
    // the messages start with the field's name; name the flag instead
    rig.validate()
        .map_err(|e| format!("--{}", e.to_string().replacen("fov_y", "fov", 1)))?;
    Ok(rig)
}

/// The observed frames (`--frames`, else every step; frame 0 first with
/// `--include-reference`), checked against what an observation file holds.
fn frames(a: &Args, steps: usize) -> Result<Vec<usize>, String> {
    let mut frames = match &a.frames {
        Some(s) => parse_frames(s, steps)?,
        None => (1..=steps).collect(),
    };
    if a.include_reference && frames.first() != Some(&0) {
        frames.insert(0, 0);
    }
    if frames.is_empty() {
        return Err("no frame to observe (steps is 0; add --include-reference for frame 0)".into());
    }
    // what the points can take: every camera sees at most W x W points per frame
    let rays = (a.cameras as u128) * (a.pixels as u128).pow(2) * frames.len() as u128;
    if rays > MAX_POINTS as u128 {
        return Err(format!(
            "--cameras {} x --pixels {}^2 x {} frames could see {rays} points, more than the {MAX_POINTS} \
             an observation file holds; lower --pixels, --cameras or the frames",
            a.cameras,
            a.pixels,
            frames.len()
        ));
    }
    Ok(frames)
}

/// The observation file: `--out`, else `out/<scene>-observe/observations.csv`.
fn out_path(a: &Args) -> PathBuf {
    a.out
        .clone()
        .unwrap_or_else(|| default_out(&a.scene, "observe").join("observations.csv"))
}

/// `observe`'s JSON summary (`seconds.total` is set by the caller).
fn summary(
    a: &Args,
    rig: &RigParams,
    run: &ObservationRun,
    frames: &[usize],
    [out, camera_file]: [&std::path::Path; 2],
    preview_path: Option<String>,
) -> Value {
    let (obs, cameras, target) = (&run.observations, &run.cameras, run.target);
    let last = frames[frames.len() - 1];
    let (out, camera_file) = (out.display().to_string(), camera_file.display().to_string());
    let per_frame: Vec<usize> = frames.iter().map(|&f| obs.frame(f).len()).collect();
    let mut per_camera = vec![0usize; cameras.len()];
    for (_, pts) in obs.frames() {
        for p in pts {
            per_camera[p.camera.unwrap_or(0) as usize] += 1;
        }
    }
    let poses: Vec<_> = cameras
        .iter()
        .zip(rig.angles())
        .map(|(c, [theta, phi])| json!({"eye": c.camera.eye, "target": c.camera.target, "theta": theta, "phi": phi}))
        .collect();
    let min = per_frame.iter().copied().min().unwrap_or(0);
    let max = per_frame.iter().copied().max().unwrap_or(0);
    let mean = obs.len() as f64 / frames.len() as f64;
    json!({
        "scene": a.scene.display().to_string(),
        "out": out,
        "points": obs.len(),
        "frames": frames.len(),
        "first_frame": frames[0],
        "last_frame": last,
        "cameras": cameras.len(),
        "camera_poses": poses,
        "target": target,
        "pixels": a.pixels,
        "fov_degrees": a.fov,
        "radius": a.radius,
        "noise": a.noise,
        "seed": a.seed,
        "steps": last,
        "points_per_frame": {"min": min, "max": max, "mean": mean},
        "points_per_camera": per_camera,
        "preview": preview_path,
        "camera_file": camera_file,
        "seconds": {
            "simulation": run.simulation_s,
            "observation": run.observation_s,
            "total": 0.0
        },
    })
}

/// Runs the command.
pub fn run(a: Args) -> Result<(), String> {
    let t_total = Instant::now();
    let rig = rig(&a)?;
    let scene = Scene::load(&a.scene).map_err(|e| e.to_string())?;
    let steps = crate::problem_args::steps(a.steps, &scene)?;
    let frames = frames(&a, steps)?;
    let last = frames[frames.len() - 1];
    let out = out_path(&a);
    // the CSV, its camera file and the preview appear together at the end, or not at all
    // (`crate::out_dir`); an unwritable output fails here, before simulating
    let cams_path = adjoint::fit::cameras_path(&out);
    let mut targets = vec![out.clone(), cams_path.clone()];
    targets.extend(a.preview.clone());
    let files = crate::out_dir::OutFiles::begin(&targets, &scene.input_files())?;

    // the scene's model with its model-level effects (e.g. `wind`)
    let mut sim = scene.build_simulation().map_err(|e| e.to_string())?;
    if !a.json {
        if let Some(w) = crate::simulate::penetration_warning(sim.initial_penetration()) {
            crate::note!("{w}");
        }
    }
    let pb = progress::bar(last as u64, "observe", a.json);
    let run = observe_run(&mut sim, &rig, a.noise, &frames, |_| pb.inc(1))
        .map_err(|e| format!("{}: {e}", a.scene.display()))?;
    pb.finish_and_clear();
    let (obs, cameras) = (&run.observations, &run.cameras);
    if obs.is_empty() {
        return Err(format!(
            "{}: the {} cameras saw no point of the body in the {} frames observed (radius {}, fov {} degrees, \
             {}x{} pixels); move them closer (--radius), widen --fov or raise --pixels",
            a.scene.display(),
            cameras.len(),
            frames.len(),
            a.radius,
            a.fov,
            a.pixels,
            a.pixels
        ));
    }
    obs.write_csv(files.path(&out)).map_err(|e| e.to_string())?;
    // the cameras beside the CSV: `fit` measures residuals along their viewing rays
    let cams_text = adjoint::camera_file::CameraFile::text(cameras, a.noise, a.seed);
    std::fs::write(files.path(&cams_path), cams_text).map_err(|e| format!("{}: {e}", cams_path.display()))?;

    let preview_path = match (&a.preview, &run.last_mesh) {
        (Some(p), Some(mesh)) => {
            preview(mesh, cameras, last)
                .save_png(&files.path(p))
                .map_err(|e| e.to_string())?;
            Some(p.display().to_string())
        }
        _ => None,
    };
    let mut summary = summary(&a, &rig, &run, &frames, [&out, &cams_path], preview_path);
    summary["seconds"]["total"] = json!(t_total.elapsed().as_secs_f64());
    files.commit()?;
    if a.json {
        crate::output::print_json(&summary)?;
    } else {
        let ppf = &summary["points_per_frame"];
        crate::note!(
            "observed {} points in {} frames ({}..{} per frame) with {} cameras of {}x{} pixels, \
             noise {}, seed {}; written to {}",
            obs.len(),
            frames.len(),
            ppf["min"],
            ppf["max"],
            cameras.len(),
            a.pixels,
            a.pixels,
            a.noise,
            a.seed,
            out.display()
        );
    }
    Ok(())
}
