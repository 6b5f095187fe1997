//! The declared range of every numeric key of a scene file, checked in one place
//! ([`out_of_range`], called by [`super::Scene::parse`] before any section is read) with the key
//! and its line in the message.
//!
//! A value outside its range is refused even where a deeper layer would accept it: a
//! tolerance that makes a solver do nothing (`numerics.cg_tolerance = 1.0`: the first residual
//! already meets it, CG does no iteration and the motion is silently wrong) is out of range,
//! not a choice. [`crate::fem::Model::validate`] keeps guarding models built in code; this table
//! is the user-facing declaration (`tests/scene_ranges.rs`: every range refuses what lies just
//! outside it, and every numeric key a complete scene can hold is declared here).
//!
//! Keys are written as in the file with array indices dropped (`dirichlet[0].min[2]` is
//! `dirichlet.min`); a numeric key of an effect's own section is declared here too when the
//! effect is part of this crate (a third party's section checks its own keys).

/// One end of a range: the value and whether it belongs to the range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct End {
    /// the value (infinite: no limit on that side)
    pub value: f64,
    /// true when `value` itself is allowed
    pub closed: bool,
}

/// The range of one key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyRange {
    /// dotted key, array indices dropped
    pub key: &'static str,
    /// lower end
    pub min: End,
    /// upper end
    pub max: End,
    /// why the range is what it is (said with a refused value)
    pub why: &'static str,
}

const fn open(value: f64) -> End {
    End { value, closed: false }
}
const fn closed(value: f64) -> End {
    End { value, closed: true }
}
const INF: f64 = f64::INFINITY;

const fn r(key: &'static str, min: End, max: End, why: &'static str) -> KeyRange {
    KeyRange { key, min, max, why }
}

/// Any finite number.
const FINITE: (End, End) = (open(-INF), open(INF));
/// A positive finite number.
const POSITIVE: (End, End) = (open(0.0), open(INF));
/// A finite number >= 0.
const NON_NEGATIVE: (End, End) = (closed(0.0), open(INF));

const fn any(key: &'static str, (min, max): (End, End), why: &'static str) -> KeyRange {
    r(key, min, max, why)
}

/// The loosest relative CG tolerance a scene may ask for: a looser solve leaves each step's
/// displacement with errors of the order of the observations' noise (1.0 does no iteration).
pub const MAX_CG_TOLERANCE: f64 = 1e-3;
/// The tightest: below double precision's resolution of a residual norm CG cannot get.
pub const MIN_CG_TOLERANCE: f64 = 1e-16;
/// The most CG iterations per solve a scene may ask for.
pub const MAX_CG_ITERATIONS: f64 = 1e7;

/// Every numeric key of a scene, with its range.
pub const RANGES: &[KeyRange] = &[
    any("body.origin", FINITE, "a position"),
    any("body.spacing", POSITIVE, "a grid spacing"),
    any("body.resolution", POSITIVE, "grid cells per unit"),
    any("body.shape.center", FINITE, "a position"),
    any("body.shape.size", POSITIVE, "edge lengths"),
    any("body.shape.radius", POSITIVE, "a radius"),
    any("body.shape.axis", FINITE, "a direction"),
    any("body.shape.major", POSITIVE, "a radius"),
    any("body.shape.minor", POSITIVE, "a radius"),
    any("body.shape.a", FINITE, "a position"),
    any("body.shape.b", FINITE, "a position"),
    any("material.young", POSITIVE, "Young's modulus"),
    r(
        "material.poisson",
        open(0.0),
        open(0.5),
        "a Poisson ratio of an isotropic solid",
    ),
    any("material.density", POSITIVE, "a mass density"),
    any("damping.mass", NON_NEGATIVE, "a damping coefficient"),
    any("damping.stiffness", NON_NEGATIVE, "a damping coefficient"),
    any("gravity.acceleration", FINITE, "an acceleration"),
    any("ground.normal", FINITE, "a direction"),
    any("ground.height", FINITE, "a position along the normal"),
    any("ground.stiffness", POSITIVE, "a contact stiffness"),
    any("ground.softness", POSITIVE, "a contact softness"),
    any("dirichlet.min", FINITE, "a corner"),
    any("dirichlet.max", FINITE, "a corner"),
    any("initial.velocity", FINITE, "a velocity"),
    any("initial.angular_velocity", FINITE, "an angular velocity"),
    any("time.dt", POSITIVE, "a time step"),
    r(
        "time.steps",
        closed(0.0),
        closed(super::MAX_STEPS as f64),
        "every step's state is kept: lower it or raise time.dt",
    ),
    r(
        "time.theta",
        closed(0.5),
        open(1.0),
        "Newmark's theta: stable from 0.5",
    ),
    r(
        "time.substeps",
        closed(1.0),
        closed(crate::fem::model::MAX_SUBSTEPS as f64),
        "solver steps per observed step",
    ),
    r(
        "model.stiffness_field.cells",
        closed(1.0),
        closed(super::StiffnessFieldSection::MAX_CELLS as f64),
        "coarse cells per axis",
    ),
    r("fit.iterations", closed(0.0), closed(1e6), "optimizer iterations"),
    any("numerics.nitsche_eta", POSITIVE, "a penalty"),
    any("numerics.nitsche_gamma", POSITIVE, "a penalty factor"),
    r(
        "numerics.cg_tolerance",
        closed(MIN_CG_TOLERANCE),
        closed(MAX_CG_TOLERANCE),
        "1.0 does no iteration; looser leaves each step's motion wrong by about the noise",
    ),
    r(
        "numerics.cg_max_iterations",
        closed(1.0),
        closed(MAX_CG_ITERATIONS),
        "0 iterations solve nothing",
    ),
    any("numerics.reuse_factor_mb", NON_NEGATIVE, "a memory budget"),
    r(
        "numerics.surface_subdivision",
        closed(1.0),
        closed(super::MAX_SURFACE_SUBDIVISION as f64),
        "the observed surface's refinement of the grid",
    ),
    any("drag.coefficient", NON_NEGATIVE, "a drag coefficient"),
    any("clamp.stiffness", POSITIVE, "a support stiffness"),
    any("friction.coefficient", NON_NEGATIVE, "a friction coefficient"),
    any("wind.traction", FINITE, "a traction"),
];

impl KeyRange {
    /// True when `v` lies in the range.
    pub fn contains(&self, v: f64) -> bool {
        let above = if self.min.closed {
            v >= self.min.value
        } else {
            v > self.min.value
        };
        let below = if self.max.closed {
            v <= self.max.value
        } else {
            v < self.max.value
        };
        v.is_finite() && above && below
    }

    /// The range as written in maths: `(0, 0.5)`, `[1, 8]`, `> 0`, `>= 0`, `finite`.
    pub fn describe(&self) -> String {
        let (lo, hi) = (self.min, self.max);
        match (lo.value.is_finite(), hi.value.is_finite()) {
            (false, false) => "a finite number".into(),
            (true, false) => format!("{} {}", if lo.closed { ">=" } else { ">" }, short(lo.value)),
            (false, true) => format!("{} {}", if hi.closed { "<=" } else { "<" }, short(hi.value)),
            (true, true) => format!(
                "in {}{}, {}{}",
                if lo.closed { "[" } else { "(" },
                short(lo.value),
                short(hi.value),
                if hi.closed { "]" } else { ")" }
            ),
        }
    }
}

/// `v` as a reader writes it: `0.5`, `1000`, `1e-16`, `1e7`.
fn short(v: f64) -> String {
    if v == 0.0 || (1e-3..1e6).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// The range of `key` (dotted, array indices dropped), if declared.
pub fn range_of(key: &str) -> Option<&'static KeyRange> {
    RANGES.iter().find(|r| r.key == key)
}

/// Every numeric key of `text` (dotted, array indices dropped), once each, in file order.
pub fn numeric_keys(text: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    super::check::each_number(text, &mut |n| {
        if !out.iter().any(|k| k == n.declared) {
            out.push(n.declared.to_string());
        }
    });
    out
}

/// The first numeric value of scene `text` outside its declared range, as
/// `"line N: key: must be RANGE (why), got V"`; `None` when all lie in theirs (or the text does
/// not parse: the parser says why).
pub fn out_of_range(text: &str) -> Option<String> {
    let mut found = None;
    super::check::each_number(text, &mut |n| {
        let (Some(x), Some(range)) = (n.value, range_of(n.declared)) else {
            return;
        };
        // not finite: said by the finiteness check, with its own words
        if found.is_none() && x.is_finite() && !range.contains(x) {
            found = Some(format!(
                "line {}: {}: must be {} ({}), got {}",
                n.line,
                n.declared,
                range.describe(),
                range.why,
                short(x)
            ));
        }
    });
    found
}
