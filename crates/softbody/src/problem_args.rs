//! What `fit` and `gradcheck` share: the scene, the observations, the fitted parameters, the
//! cost and the camera file, read and checked the same way.

use adjoint::camera_file::CameraFile;
use adjoint::fit::{cameras_path, check_frames, CostKind};
use adjoint::observations::Observations;
use adjoint::params::ParamSet;
use cutfem::scene::Scene;
use std::path::PathBuf;

/// The arguments naming a reconstruction problem.
#[derive(clap::Args, Debug)]
pub struct ProblemArgs {
    /// The scene file (TOML): the model to fit and its starting values (`fit` also takes a
    /// study file of several recordings, docs/study.md).
    pub scene: PathBuf,
    /// Observed surface points (CSV: frame,x,y,z[,camera][,weight]); required with a scene.
    #[arg(long)]
    pub observations: Option<PathBuf>,
    /// Parameters, comma separated (default: [fit].parameters, else young,poisson).
    #[arg(long)]
    pub params: Option<String>,
    /// Override `[time].steps`.
    #[arg(long)]
    pub steps: Option<usize>,
    /// surface (distance to the simulated surface mesh, along the viewing rays when the cameras
    /// are known) | levelset (the thesis' phi(t)(x), eq. 5.4.4).
    #[arg(long, default_value = "surface")]
    pub cost: String,
    /// Camera eyes (JSON written by `observe` beside the CSV; default: OBS.cameras.json if it
    /// exists). Residuals are then measured along each point's viewing ray.
    #[arg(long)]
    pub cameras: Option<PathBuf>,
}

/// A loaded problem description.
#[derive(Debug)]
pub struct Loaded {
    /// the scene
    pub scene: Scene,
    /// its `[fit]` section
    pub section: cutfem::scene::FitSection,
    /// the fitted parameters
    pub params: ParamSet,
    /// the residual
    pub kind: CostKind,
    /// the observations (frames checked against the simulated steps)
    pub observations: Observations,
    /// the camera eyes (empty when unknown)
    pub eyes: Vec<[f64; 3]>,
    /// the camera file (`--cameras`, else OBS.cameras.json when it exists), checked against
    /// the observations
    pub cameras: Option<CameraFile>,
    /// the files read (scene, body file, observations, camera file): no output may replace
    /// them (`crate::out_dir::refuse_inputs`)
    pub inputs: Vec<std::path::PathBuf>,
}

impl ProblemArgs {
    /// Reads the scene, its `[fit]` section, the parameters, the cost, the observations and the
    /// cameras; every failure is one line naming the file, line, key or flag. The observations
    /// must be able to inform a fit ([`Observations::check_informative`]) and the camera file
    /// must name every camera they use ([`CameraFile::check_used`]).
    pub fn load(&self) -> Result<Loaded, String> {
        if crate::study_fit::is_study_file(&self.scene) {
            return Err(format!(
                "{}: a study file (several recordings) where one scene is expected; `softbody fit` and `softbody diagnose` take studies, other commands and a study's recordings take scenes",
                self.scene.display()
            ));
        }
        // the scene first: a file that is not what it should be says so before a flag is missed
        let scene = Scene::load(&self.scene).map_err(|e| e.to_string())?;
        let obs_path = self.observations()?;
        let n_steps = steps(self.steps, &scene)?;
        let section = scene.fit.clone().unwrap_or_default();
        let params = self.params(&section)?;
        let kind: CostKind = self.cost.parse().map_err(|e| format!("--cost: {e}"))?;
        let observations = Observations::read_csv(obs_path).map_err(|e| e.to_string())?;
        check_frames(&observations, obs_path, n_steps)?;
        // data that cannot inform a fit are refused here, for every command
        observations.check_informative(obs_path, n_steps)?;
        let path = match &self.cameras {
            Some(p) => Some(p.clone()),
            None => Some(cameras_path(obs_path)).filter(|p| p.exists()),
        };
        let camera_path = path.clone();
        let cameras = match path {
            Some(p) => {
                let file = CameraFile::read(&p)?;
                file.check_used(&observations, obs_path)?;
                Some(file)
            }
            None => None,
        };
        let eyes = cameras.as_ref().map_or_else(Vec::new, CameraFile::eyes);
        let mut inputs = scene.input_files();
        inputs.push(obs_path.to_path_buf());
        inputs.extend(camera_path);
        Ok(Loaded {
            inputs,
            scene,
            section,
            params,
            kind,
            observations,
            eyes,
            cameras,
        })
    }
}

impl Loaded {
    /// The fingerprint of the problem these inputs pose: a digest
    /// ([`cutfem::input::digest`]) of the input files' bytes (scene, body file, camera file),
    /// the observations' points ([`Observations::fingerprint`]), the fitted parameters, the
    /// simulated steps and the cost. A run's log
    /// carries it, and a resume from a log of another problem is refused
    /// ([`adjoint::fit::FitLog::begin`]).
    pub fn fingerprint(&self, steps: usize) -> String {
        // the observations as read (not their file again: it may be gigabytes), the other
        // inputs by their bytes
        let files = self
            .scene
            .input_files()
            .into_iter()
            .chain(self.cameras.as_ref().map(|c| c.path.clone()));
        let mut text = String::new();
        for f in files {
            let d = cutfem::input::file_digest(&f).unwrap_or(0);
            text.push_str(&format!("{d:016x}\n"));
        }
        text.push_str(&format!(
            "{}\n{}\n{steps}\n{:?}\n",
            self.observations.fingerprint(),
            self.params.labels().join(","),
            self.kind
        ));
        format!("{:016x}", cutfem::input::digest(text.as_bytes()))
    }

    /// The checks that need the simulation, run before any work by a command that builds its
    /// problem later (`diagnose`, each recording of a study): the scene's simulation builds (a
    /// grid too large, an effect without what it needs), and the observations are within
    /// reach of the simulated body at the starting parameters
    /// ([`adjoint::fit::check_observations`], the check `fit` and `gradcheck` run on their own
    /// problem). Costs one forward run.
    pub fn check_start(&self, obs_path: &std::path::Path, steps: Option<usize>) -> Result<(), String> {
        let mut problem = adjoint::fit::scene_problem(
            &self.scene,
            &self.observations,
            self.params.clone(),
            adjoint::cost::Robust::Squared,
            steps,
            self.kind,
            &self.eyes,
        )
        .map_err(|e| e.to_string())?;
        adjoint::fit::check_observations(&mut problem, &self.observations, obs_path)
            .map(|_| ())
            .map_err(|e| e.to_string())
    }
}

impl ProblemArgs {
    /// The fitted parameters: `--params`, else the scene's `[fit].parameters`, else Young's
    /// modulus and the Poisson ratio.
    pub fn params(&self, section: &cutfem::scene::FitSection) -> Result<ParamSet, String> {
        let names: Vec<String> = match (&self.params, &section.parameters) {
            (Some(p), _) => vec![p.clone()],
            (None, Some(p)) => p.clone(),
            (None, None) => vec!["young,poisson".into()],
        };
        ParamSet::parse(&names).map_err(|e| format!("--params: {e}"))
    }

    /// The observations' path: `--observations`, required with a scene.
    pub fn observations(&self) -> Result<&std::path::Path, String> {
        self.observations.as_deref().ok_or_else(|| {
            format!(
                "--observations: required with the scene {} (the observed points, CSV: frame,x,y,z[,camera][,weight])",
                self.scene.display()
            )
        })
    }
}

/// The steps to simulate: `--steps` when given (checked against
/// [`cutfem::scene::MAX_STEPS`], naming the flag), else the scene's `[time].steps` (checked on
/// load).
pub fn steps(flag: Option<usize>, scene: &Scene) -> Result<usize, String> {
    match flag {
        Some(n) => cutfem::scene::check_steps(n, "--steps").map(|()| n),
        None => Ok(scene.time.steps),
    }
}
