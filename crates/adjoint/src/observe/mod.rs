//! Virtual RGB-D cameras: synthetic observations of a simulated surface (thesis sec. 5.8,
//! Fig. 5.8: simulated cameras whose depth images give the sparse point cloud of eq. 5.4.4).
//!
//! # Camera placement
//!
//! `N` cameras look at a target `c` (the centre of the body's reference bounding box) from
//! the sphere of radius `R` around it. Camera `k` draws, from a seeded [`SplitMix64`]
//! stream, a polar angle `theta_k` (from the up axis +y) uniform in `[pi/6, pi/2]` and an
//! azimuth `phi_k` uniform in `[0, 2 pi)`, and sits at
//!
//! `e_k = c + R (sin theta_k cos phi_k, cos theta_k, sin theta_k sin phi_k)`
//!
//! (between 30 degrees from straight above and the body's horizon), looking at `c` with +y
//! up, `W x W` pixels and a vertical field of view `fov_y` (45 degrees by default).
//!
//! # Depth images and points
//!
//! [`render_depth`] rasterizes the surface mesh into a z-buffer (pinhole projection
//! `u = c_x + f x / z`, `v = c_y - f y / z`, `f = (W / 2) / tan(fov_y / 2)` of the one
//! pinhole camera, see [`cutfem::render::camera`]; a [`DepthCamera`] is that camera plus its
//! image size); only the body's mesh is drawn, so a ground plane is never observed. Each
//! pixel `(i, j)` that sees the surface at depth `z` gets sensor noise
//! `z~ = z + sigma n`, `n ~ N(0, 1)` (Box-Muller on the camera's own stream, keyed by seed,
//! frame and camera index, pixels in row-major order), and is unprojected at its centre
//! `(u, v) = (i + 1/2, j + 1/2)`:
//!
//! `p = e + z~ (forward + (u - c_x) / f right - (v - c_y) / f up)`.
//!
//! Without noise `p` lies exactly on a triangle of the mesh; with noise it moves along the
//! pixel's ray and its depth has standard deviation `sigma`. A camera sees about
//! `A / a_pix` points, where `A` is the surface's projected area on the plane at depth `z`
//! and `a_pix = (z / f)^2` the pixel's footprint there.
//!
//! Everything is deterministic: the same mesh, cameras, noise and seed give bit-identical
//! points regardless of thread count or crate versions; a different seed gives different
//! cameras and noise.
//!
//! ```
//! use adjoint::observe::{observe_mesh, place_cameras, RigParams};
//! use cutfem::{shapes::Shape, surface::extract_surface};
//! let sdf = Shape::Sphere { center: [0.0, 1.0, 0.0], radius: 0.5 }.to_sdf(10.0, 2).unwrap();
//! let mesh = extract_surface(&sdf).mesh;
//! let rig = RigParams { cameras: 2, pixels: 16, ..RigParams::default() };
//! let cameras = place_cameras([0.0, 1.0, 0.0], &rig);
//! let points = observe_mesh(&mesh, &cameras, 0.0, rig.seed, 1);
//! assert_eq!(points.len(), 2);
//! assert!(points.iter().all(|p| !p.is_empty()));
//! ```

pub mod camera;
pub mod raster;
pub mod rng;
pub mod samples;

pub use camera::DepthCamera;
pub use raster::{render_depth, DepthImage};
pub use rng::SplitMix64;
pub use samples::sample_surface;

use crate::observations::{Observations, ObservedPoint};
use crate::Error;
use cutfem::render::Camera;
use cutfem::v3::{add, scale};
use cutfem::TriMesh;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_6, TAU};
use std::time::Instant;

/// Tags of the random streams (camera placement, depth noise).
const PLACEMENT: u64 = 1;
const NOISE: u64 = 2;

/// Settings of the camera rig (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct RigParams {
    /// number of cameras (default 4)
    pub cameras: usize,
    /// image side `W` in pixels: each camera is `W x W` (default 32)
    pub pixels: usize,
    /// distance of the eyes from the target (default 3)
    pub radius: f64,
    /// vertical (= horizontal) field of view in radians (default 45 degrees)
    pub fov_y: f64,
    /// range of the polar angle from +y in radians (default `[pi/6, pi/2]`)
    pub theta: [f64; 2],
    /// seed of the placement (and, in [`observe_mesh`], of the noise); default 0
    pub seed: u64,
}

impl Default for RigParams {
    fn default() -> Self {
        RigParams {
            cameras: 4,
            pixels: 32,
            radius: 3.0,
            fov_y: 45f64.to_radians(),
            theta: [FRAC_PI_6, FRAC_PI_2],
            seed: 0,
        }
    }
}

impl RigParams {
    /// Checks the settings; the message names the offending field.
    pub fn validate(&self) -> Result<(), Error> {
        if self.cameras == 0 {
            return Err(Error::invalid("cameras must be at least 1"));
        }
        if self.pixels == 0 {
            return Err(Error::invalid("pixels must be at least 1"));
        }
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(Error::Invalid(format!(
                "radius must be positive and finite, found {}",
                self.radius
            )));
        }
        if !Camera::is_valid_fov_y(self.fov_y) {
            return Err(Error::Invalid(format!(
                "fov_y must be in (0, 180) degrees, found {}",
                self.fov_y.to_degrees()
            )));
        }
        let [a, b] = self.theta;
        if !(a.is_finite() && b.is_finite() && 0.0 <= a && a <= b && b <= std::f64::consts::PI) {
            return Err(Error::Invalid(format!(
                "theta must satisfy 0 <= min <= max <= pi, found [{a}, {b}]"
            )));
        }
        Ok(())
    }

    /// The angles `[theta_k, phi_k]` of the cameras, drawn from the seed.
    pub fn angles(&self) -> Vec<[f64; 2]> {
        let mut rng = SplitMix64::stream(self.seed, &[PLACEMENT]);
        let [t0, t1] = self.theta;
        (0..self.cameras)
            .map(|_| {
                let theta = t0 + (t1 - t0) * rng.uniform();
                let phi = TAU * rng.uniform();
                [theta, phi]
            })
            .collect()
    }
}

/// The cameras of the rig around `target` (see the module docs). Panics when `params` is
/// invalid (see [`RigParams::validate`]).
#[track_caller]
pub fn place_cameras(target: [f64; 3], params: &RigParams) -> Vec<DepthCamera> {
    if let Err(e) = params.validate() {
        panic!("place_cameras: {e}");
    }
    params
        .angles()
        .into_iter()
        .map(|[theta, phi]| {
            let dir = [theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()];
            let eye = add(target, scale(dir, params.radius));
            DepthCamera::look_at(eye, target, params.fov_y, params.pixels, params.pixels)
        })
        .collect()
}

/// The world points seen through the hit pixels of `image` (row-major order), with
/// Gaussian depth noise of standard deviation `sigma` drawn from `rng` (none when
/// `sigma == 0`).
pub fn unproject_depth(
    camera: &DepthCamera,
    image: &DepthImage,
    sigma: f64,
    rng: &mut SplitMix64,
) -> Vec<[f64; 3]> {
    let frame = camera.frame();
    let mut out = Vec::with_capacity(image.hits());
    for j in 0..image.height {
        for i in 0..image.width {
            let z = image.depth[j * image.width + i];
            if !z.is_finite() {
                continue;
            }
            let z = if sigma > 0.0 {
                z + sigma * rng.gaussian()
            } else {
                z
            };
            out.push(frame.unproject(i as f64 + 0.5, j as f64 + 0.5, z));
        }
    }
    out
}

/// What every camera sees of `mesh` at `frame`: one point list per camera (row-major pixel
/// order), with depth noise `sigma` from the stream keyed by `(seed, frame, camera)`.
/// Panics when `sigma` is negative or not finite.
#[track_caller]
pub fn observe_mesh(
    mesh: &TriMesh,
    cameras: &[DepthCamera],
    sigma: f64,
    seed: u64,
    frame: usize,
) -> Vec<Vec<[f64; 3]>> {
    assert!(
        sigma.is_finite() && sigma >= 0.0,
        "observe_mesh: noise must be non-negative and finite, found {sigma}"
    );
    cameras
        .iter()
        .enumerate()
        .map(|(k, cam)| {
            let image = render_depth(mesh, cam);
            let mut rng = SplitMix64::stream(seed, &[NOISE, frame as u64, k as u64]);
            unproject_depth(cam, &image, sigma, &mut rng)
        })
        .collect()
}

/// Adds per-camera point lists (as from [`observe_mesh`]) to `obs` at `frame`, with the
/// camera index and weight 1.
pub fn record(obs: &mut Observations, frame: usize, per_camera: &[Vec<[f64; 3]>]) {
    for (k, points) in per_camera.iter().enumerate() {
        for &p in points {
            obs.push(
                frame,
                ObservedPoint {
                    position: p,
                    camera: Some(k as u32),
                    weight: 1.0,
                },
            );
        }
    }
}

/// What [`observe_run`] gives.
#[derive(Debug)]
pub struct ObservationRun {
    /// the points seen, per frame
    pub observations: Observations,
    /// the rig, placed around the body's reference bounding-box centre
    pub cameras: Vec<DepthCamera>,
    /// the point the cameras look at
    pub target: [f64; 3],
    /// the surface at the last frame observed
    pub last_mesh: Option<TriMesh>,
    /// seconds spent stepping the simulation
    pub simulation_s: f64,
    /// seconds spent observing: the deformed surface, the cameras' depth images, the points
    pub observation_s: f64,
}

/// The rig of `rig` cameras around the centre of `mesh`'s bounding box (a body's reference
/// surface): the target and the cameras. Errors when the mesh is empty.
pub fn rig_around(mesh: &TriMesh, rig: &RigParams) -> Result<([f64; 3], Vec<DepthCamera>), Error> {
    let (lo, hi) = mesh
        .bounding_box()
        .ok_or_else(|| Error::invalid("the body has no surface to observe"))?;
    let target = [0, 1, 2].map(|d| 0.5 * (lo[d] + hi[d]));
    Ok((target, place_cameras(target, rig)))
}

/// Runs `sim` from its current state up to the last of `frames` (sorted ascending, each once:
/// a frame out of order is not observed; frame 0
/// is the state before the first step) and observes each of `frames` with a rig of `rig`
/// cameras around the reference surface's bounding-box centre, depth noise `sigma` (seeded
/// per frame by `rig.seed`). `on_step` is called after each step (progress). The one home of
/// `softbody observe`, the demo's and the tests' synthetic data.
pub fn observe_run(
    sim: &mut cutfem::fem::Simulation,
    rig: &RigParams,
    sigma: f64,
    frames: &[usize],
    mut on_step: impl FnMut(usize),
) -> Result<ObservationRun, Error> {
    rig.validate()?;
    if !(sigma.is_finite() && sigma >= 0.0) {
        return Err(Error::Invalid(format!("noise must be non-negative, got {sigma}")));
    }
    let surface = sim.grid.surface()?;
    let (target, cameras) = rig_around(&surface.mesh, rig)?;
    let mut run = ObservationRun {
        observations: Observations::new(),
        cameras,
        target,
        last_mesh: None,
        simulation_s: 0.0,
        observation_s: 0.0,
    };
    let last = frames.last().copied().unwrap_or(0);
    for f in 0..=last {
        if f > 0 {
            let t = Instant::now();
            sim.step().map_err(|e| Error::step(format!("step {f}"), e))?;
            sim.check_finite()
                .map_err(|e| Error::step(format!("step {f}"), e))?;
            run.simulation_s += t.elapsed().as_secs_f64();
            on_step(f);
        }
        if frames.binary_search(&f).is_ok() {
            let t = Instant::now();
            let mesh = sim.grid.deformed(&surface, &sim.u);
            let seen = observe_mesh(&mesh, &run.cameras, sigma, rig.seed, f);
            record(&mut run.observations, f, &seen);
            run.observation_s += t.elapsed().as_secs_f64();
            if f == last {
                run.last_mesh = Some(mesh);
            }
        }
    }
    Ok(run)
}

/// Simulates `scene` (its model, `steps` steps) and observes frames `1..=steps` with a rig of
/// `rig` cameras around the body's reference bounding-box center and depth noise `sigma`:
/// the observations and the cameras (as `softbody observe` writes them). `edit` may change the
/// model before the run (e.g. a stiffness field a scene file cannot express).
pub fn synthesize(
    scene: &cutfem::scene::Scene,
    rig: &RigParams,
    sigma: f64,
    steps: usize,
    edit: impl FnOnce(&cutfem::fem::Grid, &mut cutfem::fem::Model),
) -> Result<(Observations, Vec<DepthCamera>), Error> {
    let mut sim = scene.build_simulation()?;
    let mut model = sim.model.clone();
    edit(&sim.grid, &mut model);
    sim.reset(model)?;
    let frames: Vec<usize> = (1..=steps).collect();
    let run = observe_run(&mut sim, rig, sigma, &frames, |_| {})?;
    Ok((run.observations, run.cameras))
}
