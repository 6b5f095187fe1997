//! Scene files (TOML, `../shared/docs/interface.md`): the body, the physics the user believes
//! in, which effects the model includes, time stepping and fitting defaults.
//!
//! Unknown keys are errors (a typo must not silently fall back to a default). Relative paths
//! are relative to the scene file. Core effects ([`EFFECTS`]): `gravity`, `damping`, `ground`,
//! `corotation`, `stiffness_field`, `initial_velocity`; with `[model]` absent, every effect
//! whose section is present is on, plus corotation.
//!
//! Effects with their own section (e.g. the tutorial effect `wind`,
//! `docs/effects-tutorial.md`) own it: any top-level table that is not a core section is kept
//! in [`Scene::extensions`], and the effect ([`effects`]) validates its keys and builds its
//! physics. [`Scene::build_model`] (through which every `softbody` command builds its model)
//! refuses sections and effect names no effect claims and applies those that are on;
//! [`Scene::to_model`] alone leaves them out.

mod body;
mod build;
mod check;
mod derived;
pub mod effects;
mod extensions;
mod fit;
mod mesh_cache;
mod numerics;
pub mod ranges;
mod write;

pub use body::{extension_error, pad, DEFAULT_RESOLUTION, PADDING_CELLS};
pub use check::{check_steps, dedupe_prefixes, non_finite, quote, shorten_quotes, MAX_QUOTE, MAX_STEPS};
pub use extensions::{Extension, SECTIONS};
pub use fit::FitSection;
use mesh_cache::{mesh_cache_get, mesh_cache_put};
pub use numerics::{NumericsSection, DEFAULT_SURFACE_SUBDIVISION, MAX_SURFACE_SUBDIVISION};

use crate::error::Error;
use crate::fem::{Aabb, Ground, Model};
use gpumat::Vec3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The effect vocabulary.
pub const EFFECTS: [&str; 6] = [
    "gravity",
    "damping",
    "ground",
    "corotation",
    "stiffness_field",
    "initial_velocity",
];

/// `[body]`
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BodySection {
    /// thesis `.sdf` or `.npy` file
    pub sdf: Option<PathBuf>,
    /// triangle mesh file
    pub mesh: Option<PathBuf>,
    /// analytic shape
    pub shape: Option<crate::shapes::Shape>,
    /// origin of an `.npy` grid
    pub origin: Option<[f64; 3]>,
    /// spacing of an `.npy` grid
    pub spacing: Option<f64>,
    /// grid cells per world unit (mesh and shape)
    pub resolution: Option<f64>,
}

/// `[material]`
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MaterialSection {
    /// Young's modulus
    pub young: f64,
    /// Poisson ratio
    pub poisson: f64,
    /// density
    #[serde(default = "one")]
    pub density: f64,
}
fn one() -> f64 {
    1.0
}

/// `[damping]`
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DampingSection {
    /// Rayleigh mass coefficient
    #[serde(default)]
    pub mass: f64,
    /// Rayleigh stiffness coefficient
    #[serde(default)]
    pub stiffness: f64,
}

/// `[gravity]`
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GravitySection {
    /// acceleration vector
    pub acceleration: [f64; 3],
}

/// `[ground]`
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GroundSection {
    /// normal (normalized on load)
    #[serde(default = "up")]
    pub normal: [f64; 3],
    /// the ground is `normal . x >= height`
    #[serde(default)]
    pub height: f64,
    /// contact stiffness: a pressure per unit penetration with the per-area laws ("penalty",
    /// "softmin"), a spring per grid crossing with "implicit" and "thesis"; absent: the
    /// scheme's default ([`GroundSection::stiffness`])
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// the law's sharpness `alpha` (the penalty's smoothing length is `1 / alpha`); absent:
    /// the scheme's default ([`GroundSection::softness`])
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub softness: Option<f64>,
    /// the contact law and its time discretization: "penalty" (default; per unit area, no push
    /// before contact), "softmin" (per unit area), "implicit" or "thesis" (the thesis' softmin
    /// springs per grid crossing)
    #[serde(default)]
    pub scheme: crate::fem::collision::ContactScheme,
}
fn up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}
/// Default `[ground] stiffness` of the per-area laws ("penalty", "softmin"): a pressure per
/// unit penetration (a body of density 1000 resting 1 m deep under g = 10 sinks 2.5 mm).
pub const DEFAULT_GROUND_STIFFNESS: f64 = 4.0e6;
/// Default `[ground] softness` of the per-area laws: the penalty's smoothing length 1e-5.
pub const DEFAULT_GROUND_SOFTNESS: f64 = 1.0e5;
/// Default `[ground] stiffness` of the per-crossing laws ("implicit", "thesis"): the spring per
/// grid crossing of the thesis' scenes.
pub const DEFAULT_CROSSING_STIFFNESS: f64 = 1.0e4;
/// Default `[ground] softness` of the per-crossing laws (the softmin's `alpha`).
pub const DEFAULT_CROSSING_SOFTNESS: f64 = 100.0;

impl GroundSection {
    /// The stated stiffness, else the scheme's default (per unit area or per crossing).
    pub fn stiffness(&self) -> f64 {
        self.stiffness.unwrap_or(if self.scheme.per_area() {
            DEFAULT_GROUND_STIFFNESS
        } else {
            DEFAULT_CROSSING_STIFFNESS
        })
    }
    /// The stated softness, else the scheme's default.
    pub fn softness(&self) -> f64 {
        self.softness.unwrap_or(if self.scheme.per_area() {
            DEFAULT_GROUND_SOFTNESS
        } else {
            DEFAULT_CROSSING_SOFTNESS
        })
    }
}

/// `[[dirichlet]]`
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DirichletSection {
    /// lower corner
    pub min: [f64; 3],
    /// upper corner
    pub max: [f64; 3],
}

/// `[initial]`
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct InitialSection {
    /// linear velocity
    #[serde(default)]
    pub velocity: [f64; 3],
    /// angular velocity about the center of mass
    #[serde(default)]
    pub angular_velocity: [f64; 3],
}

/// `[time]`
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TimeSection {
    /// time between frames (the time step when `substeps` is 1)
    #[serde(default = "dt")]
    pub dt: f64,
    /// number of frames simulated (steps of `dt`)
    #[serde(default = "steps")]
    pub steps: usize,
    /// Newmark theta
    #[serde(default = "theta")]
    pub theta: f64,
    /// integrator steps per frame: the body is integrated with `dt / substeps`, frames stay
    /// `dt` apart (observations keep their frame numbers)
    #[serde(default = "substeps")]
    pub substeps: usize,
}
fn dt() -> f64 {
    0.01
}
fn steps() -> usize {
    30
}
fn theta() -> f64 {
    0.6
}
fn substeps() -> usize {
    1
}
impl Default for TimeSection {
    fn default() -> Self {
        Self {
            dt: dt(),
            steps: steps(),
            theta: theta(),
            substeps: substeps(),
        }
    }
}

/// `[model]`
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ModelSection {
    /// the effects the model includes
    pub effects: Vec<String>,
    /// resolution of a heterogeneous Young's modulus
    pub stiffness_field: Option<StiffnessFieldSection>,
}

/// `[model].stiffness_field`
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StiffnessFieldSection {
    /// coarse cells per axis, each in `1..=`[`StiffnessFieldSection::MAX_CELLS`]
    pub cells: [usize; 3],
}

impl StiffnessFieldSection {
    /// The most coarse cells per axis: 65^3 = 274 625 coefficients, more than any grid's cells
    /// at the resolutions that run.
    pub const MAX_CELLS: usize = 64;

    /// Errors (naming the key) unless every axis has `1..=MAX_CELLS` cells.
    pub fn check(cells: [usize; 3]) -> Result<(), String> {
        if cells.iter().any(|&c| c == 0 || c > Self::MAX_CELLS) {
            return Err(format!(
                "model.stiffness_field.cells: each must lie in 1..={}, got {cells:?}",
                Self::MAX_CELLS
            ));
        }
        Ok(())
    }
}

/// A parsed scene file. Its top-level keys are checked by [`Scene::parse`]: the core sections
/// ([`SECTIONS`]) and extension tables ([`Scene::extensions`]).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
pub struct Scene {
    /// the body
    pub body: BodySection,
    /// the material
    pub material: MaterialSection,
    /// Rayleigh damping
    pub damping: Option<DampingSection>,
    /// gravity
    pub gravity: Option<GravitySection>,
    /// ground
    pub ground: Option<GroundSection>,
    /// Dirichlet boxes
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub dirichlet: Vec<DirichletSection>,
    /// initial motion
    pub initial: Option<InitialSection>,
    /// time stepping
    #[serde(default)]
    pub time: TimeSection,
    /// effects of the model
    pub model: Option<ModelSection>,
    /// fitting defaults (read by the adjoint layer)
    pub fit: Option<FitSection>,
    /// numerics (written only when not the defaults)
    #[serde(default, skip_serializing_if = "NumericsSection::is_default")]
    pub numerics: NumericsSection,
    /// the scene file's folder (set on load)
    #[serde(skip)]
    pub dir: PathBuf,
    /// the scene file (set on load)
    #[serde(skip)]
    pub path: PathBuf,
    /// the sections of effects defined outside this crate, by name (module docs)
    #[serde(skip)]
    pub extensions: std::collections::BTreeMap<String, Extension>,
}

impl Scene {
    /// Reads and checks a scene file.
    pub fn load(path: &Path) -> Result<Scene, Error> {
        let text = crate::input::read_string(path, crate::input::MAX_CONFIG_BYTES)
            .map_err(|e| Error::io(path, e))?;
        Self::parse(&text, path)
    }

    /// Parses scene text; `path` names the file in errors and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Scene, Error> {
        let bad = |e: toml::de::Error| {
            let msg = e.message().replace('\n', " ");
            let at = e
                .span()
                .map(|s| {
                    let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
                    format!("line {line}: ")
                })
                .unwrap_or_default();
            Error::format(path, shorten_quotes(&format!("{at}{msg}")))
        };
        let table: toml::Table = text.parse().map_err(bad)?;
        // every number finite and in its declared range, before any section is read
        if let Some(msg) = non_finite(text).or_else(|| ranges::out_of_range(text)) {
            return Err(Error::format(path, msg));
        }
        fit::check(table.get("fit")).map_err(|msg| Error::format(path, msg))?;
        let extensions = extensions::collect(text, table, path)?;
        let mut scene: Scene = toml::from_str(text).map_err(bad)?;
        scene.path = path.to_path_buf();
        scene.dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        scene.extensions = extensions;
        scene.check(path)?;
        Ok(scene)
    }

    /// True when the model includes `effect`.
    pub fn effect_on(&self, effect: &str) -> bool {
        match &self.model {
            Some(m) => m.effects.iter().any(|e| e == effect),
            None => match effect {
                "corotation" => true,
                "gravity" => self.gravity.is_some(),
                "damping" => self.damping.is_some(),
                "ground" => self.ground.is_some(),
                "initial_velocity" => self.initial.is_some(),
                "stiffness_field" => false,
                other => self.extensions.contains_key(other),
            },
        }
    }

    /// The effects the model includes: the core ones in [`EFFECTS`] order, then the
    /// extensions' (in `[model].effects` order, or by name when `[model]` is absent).
    pub fn effects(&self) -> Vec<String> {
        let mut out: Vec<String> = EFFECTS
            .iter()
            .filter(|e| self.effect_on(e))
            .map(|e| e.to_string())
            .collect();
        let ext: Vec<String> = match &self.model {
            Some(m) => m.effects.clone(),
            None => self.extensions.keys().cloned().collect(),
        };
        for e in ext {
            if !EFFECTS.contains(&e.as_str()) && !out.contains(&e) {
                out.push(e);
            }
        }
        out
    }

    /// The section of extension effect `name` as `T` (`None`: the scene has none); errors
    /// name the file, the line and the section.
    pub fn extension<T: serde::de::DeserializeOwned>(&self, name: &str) -> Result<Option<T>, Error> {
        self.extensions
            .get(name)
            .map(|x| x.parse(name, &self.path))
            .transpose()
    }

    /// Sets the section of extension effect `name` (e.g. when a diagnosis switches it on).
    pub fn set_extension(&mut self, name: &str, table: toml::Table) {
        let line = self.extensions.get(name).map_or(0, |x| x.line);
        self.extensions
            .insert(name.to_string(), Extension { table, line });
    }

    /// Writes an effect's section struct as the extension section `[name]` (the write twin of
    /// [`Scene::extension`]).
    pub fn set_section<T: serde::Serialize>(&mut self, name: &str, section: &T) {
        let toml::Value::Table(t) = toml::Value::try_from(section).expect("a section serializes") else {
            unreachable!("a struct serializes to a table")
        };
        self.set_extension(name, t);
    }

    /// The files the scene reads: the scene file itself and its body file (`sdf` or `mesh`,
    /// resolved). A command's outputs must not replace them.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let body = [&self.body.sdf, &self.body.mesh];
        std::iter::once(self.path.clone())
            .chain(body.into_iter().flatten().map(|p| self.resolve(p)))
            .collect()
    }

    /// Resolves a path given in the scene.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.dir.join(p)
        }
    }

    /// The forward model with exactly the effects the scene switches on.
    pub fn to_model(&self) -> Model {
        let v3 = |a: [f64; 3]| Vec3::new(a[0], a[1], a[2]);
        let mut m = Model {
            young: self.material.young,
            poisson: self.material.poisson,
            density: self.material.density,
            corotation: self.effect_on("corotation"),
            // a zero substep count is refused by `Model::validate` (naming `time.substeps`)
            dt: self.time.dt / self.time.substeps.max(1) as f64,
            substeps: self.time.substeps,
            theta: self.time.theta,
            // both keys given is refused by `check`
            nitsche_quadrature: self.numerics.nitsche,
            nitsche: self
                .numerics
                .nitsche_penalty()
                .unwrap_or(self.numerics.nitsche.default_penalty()),
            element: self.numerics.element,
            mass: self.numerics.mass,
            dirichlet: self
                .dirichlet
                .iter()
                .map(|d| Aabb {
                    min: d.min,
                    max: d.max,
                })
                .collect(),
            ..Model::default()
        };
        if let (true, Some(d)) = (self.effect_on("damping"), &self.damping) {
            m.damping_mass = d.mass;
            m.damping_stiffness = d.stiffness;
        }
        if let (true, Some(g)) = (self.effect_on("gravity"), &self.gravity) {
            m.gravity = v3(g.acceleration);
        }
        if let (true, Some(g)) = (self.effect_on("ground"), &self.ground) {
            let n = v3(g.normal);
            let len = n.norm();
            m.ground = Some(Ground {
                normal: if len > 0.0 { n * (1.0 / len) } else { n },
                height: if len > 0.0 { g.height / len } else { g.height },
                stiffness: g.stiffness(),
                softness: g.softness(),
                scheme: g.scheme,
            });
        }
        if let (true, Some(i)) = (self.effect_on("initial_velocity"), &self.initial) {
            m.initial_velocity = v3(i.velocity);
            m.initial_angular_velocity = v3(i.angular_velocity);
        }
        m
    }
}
