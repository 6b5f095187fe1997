//! The checks of a parsed scene that do not fit a type: every float key finite (one place for
//! all of them, extensions' sections included, naming the key and its line), step counts
//! within what a run can hold ([`MAX_STEPS`]), the body given once, the model's effects backed
//! by their sections, the stiffness field's coarse cells
//! ([`super::StiffnessFieldSection::check`]), and the model's own ranges
//! ([`crate::fem::Model::validate`]).

use super::Scene;
use crate::error::Error;
use std::path::Path;
use toml::de::{DeTable, DeValue};

/// The most time steps a scene (or a `--steps` flag) may ask for. Every step's state is kept
/// by a fit (its adjoint runs backwards through them) and every step's surface is written by
/// `simulate`, so a count beyond this is a typo, not a run: a million steps of the smallest
/// body already take hours.
pub const MAX_STEPS: usize = 1_000_000;

/// Errors unless `steps` (given by `key`, e.g. `time.steps` or `--steps`) is at most
/// [`MAX_STEPS`].
pub fn check_steps(steps: usize, key: &str) -> Result<(), String> {
    if steps > MAX_STEPS {
        return Err(format!(
            "{key}: {steps} steps is more than the {MAX_STEPS} a run can hold (every step's state is kept); \
             lower it or raise time.dt"
        ));
    }
    Ok(())
}

/// Quotes at most `max` characters of `s` (an ellipsis marks the cut), for error messages
/// that repeat a user's value.
pub fn quote(s: &str, max: usize) -> String {
    match s.char_indices().nth(max) {
        Some((at, _)) => format!("{}…", &s[..at]),
        None => s.to_string(),
    }
}

/// The longest quoted value an error message repeats ([`shorten_quotes`]).
pub const MAX_QUOTE: usize = 100;

/// `msg` with every quoted part (between `"` or backticks; an unclosed quote runs to the end)
/// longer than [`MAX_QUOTE`] characters cut with an ellipsis: an error names the bad value,
/// it does not repeat a whole line of garbage.
pub fn shorten_quotes(msg: &str) -> String {
    let chars: Vec<char> = msg.chars().collect();
    let mut out = String::with_capacity(msg.len().min(4 * MAX_QUOTE));
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        out.push(c);
        i += 1;
        if c != '"' && c != '`' {
            continue;
        }
        // the quoted part: up to the same quote (a `\"` inside "..." is escaped)
        let start = i;
        while i < chars.len() && chars[i] != c {
            i += if c == '"' && chars[i] == '\\' { 2 } else { 1 };
        }
        let end = i.min(chars.len());
        let inner: String = chars[start..end].iter().collect();
        out.push_str(&quote(&inner, MAX_QUOTE));
        if i < chars.len() {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// `msg` without a prefix repeated in a row (`"s.toml: body.shape: body.shape: ..."` ->
/// `"s.toml: body.shape: ..."`), and without a file name or dotted key said again further on
/// (`"s/x.toml: drag: s/x.toml: [drag]: ..."` -> `"s/x.toml: drag: [drag]: ..."`): layers that
/// each name the file or key they checked may meet.
pub fn dedupe_prefixes(msg: &str) -> String {
    // a file name or dotted key: one word with a `.` or `/` and a letter
    let named = |p: &str| {
        !p.contains(char::is_whitespace) && p.contains(['.', '/']) && p.chars().any(char::is_alphabetic)
    };
    let mut parts: Vec<&str> = Vec::new();
    let all: Vec<&str> = msg.split(": ").collect();
    for (i, &part) in all.iter().enumerate() {
        let last = i + 1 == all.len();
        let again = parts.last() == Some(&part) || (named(part) && parts.contains(&part));
        if !again || part.is_empty() || last {
            parts.push(part);
        }
    }
    parts.join(": ")
}

/// The first float of scene `text` that is not finite (`nan`, `inf`), as
/// `"line N: key.path: not a finite number (nan)"`.
pub fn non_finite(text: &str) -> Option<String> {
    let mut found = None;
    each_number(text, &mut |n| {
        // the parser refuses literals that overflow; nan and inf are what is left
        if found.is_none() && n.float && !n.value.is_some_and(f64::is_finite) {
            found = Some(format!(
                "line {}: {}: not a finite number ({})",
                n.line,
                n.key,
                quote(n.raw, 20)
            ));
        }
    });
    found
}

/// One number of a scene's text, as [`each_number`] visits it.
pub(super) struct Number<'a> {
    /// its key as written, array indices included (`dirichlet[0].min[2]`)
    pub key: &'a str,
    /// the key of its declaration, array indices dropped (`dirichlet.min`,
    /// [`super::ranges`])
    pub declared: &'a str,
    /// the literal
    pub raw: &'a str,
    /// its value, when it parses
    pub value: Option<f64>,
    /// a float literal (else an integer)
    pub float: bool,
    /// 1-based line
    pub line: usize,
}

/// Visits every number of scene `text` in file order (nothing when it does not parse: the
/// parser says why): the one walk of the finiteness check, the declared ranges and their
/// tests.
pub(super) fn each_number(text: &str, visit: &mut dyn FnMut(&Number<'_>)) {
    let Ok(table) = DeTable::parse(text) else {
        return;
    };
    let mut walk = Walk { text, visit };
    walk.table(table.get_ref(), "", "");
}

struct Walk<'t, 'v> {
    text: &'t str,
    visit: &'v mut dyn FnMut(&Number<'_>),
}

impl Walk<'_, '_> {
    fn table(&mut self, t: &DeTable<'_>, prefix: &str, declared: &str) {
        for (k, v) in t {
            let join = |p: &str| {
                if p.is_empty() {
                    k.get_ref().to_string()
                } else {
                    format!("{p}.{}", k.get_ref())
                }
            };
            self.value(v.get_ref(), v.span(), &join(prefix), &join(declared));
        }
    }

    fn value(&mut self, v: &DeValue<'_>, span: std::ops::Range<usize>, key: &str, declared: &str) {
        let (raw, value, float) = match v {
            DeValue::Float(f) => (f.as_str(), f.as_str().parse::<f64>().ok(), true),
            DeValue::Integer(i) => (
                i.as_str(),
                i128::from_str_radix(i.as_str(), i.radix()).ok().map(|i| i as f64),
                false,
            ),
            DeValue::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    self.value(x.get_ref(), x.span(), &format!("{key}[{i}]"), declared);
                }
                return;
            }
            DeValue::Table(t) => return self.table(t, key, declared),
            _ => return,
        };
        let line = self.text[..span.start.min(self.text.len())].matches('\n').count() + 1;
        (self.visit)(&Number {
            key,
            declared,
            raw,
            value,
            float,
            line,
        });
    }
}

impl Scene {
    /// The checks of the module docs on the values as read (the finiteness and the ranges of
    /// the numbers are checked on the text before, [`Scene::parse`]).
    pub(super) fn check(&self, path: &Path) -> Result<(), Error> {
        check_steps(self.time.steps, "time.steps").map_err(|e| Error::format(path, e))?;
        check_steps(
            self.time.steps.saturating_mul(self.time.substeps),
            "time.steps x time.substeps",
        )
        .map_err(|e| Error::format(path, e))?;
        let b = &self.body;
        let given = [b.sdf.is_some(), b.mesh.is_some(), b.shape.is_some()]
            .iter()
            .filter(|&&x| x)
            .count();
        if given != 1 {
            return Err(Error::format(
                path,
                "body: give exactly one of `sdf`, `mesh`, `shape`",
            ));
        }
        if let Some(m) = &self.model {
            // a repeat usually hides a typo of another name (repeated `--params` are refused too)
            if let Some((i, e)) = m
                .effects
                .iter()
                .enumerate()
                .find(|(i, e)| m.effects[..*i].contains(e))
            {
                return Err(Error::format(
                    path,
                    format!(
                        "model.effects: `{}` is listed twice (entry {}); list each effect once",
                        quote(e, 100),
                        i + 1
                    ),
                ));
            }
            for e in &m.effects {
                // a name that is not a core effect is an extension's, checked by its layer
                let section = match e.as_str() {
                    "gravity" => self.gravity.is_some(),
                    "damping" => self.damping.is_some(),
                    "ground" => self.ground.is_some(),
                    "initial_velocity" => self.initial.is_some(),
                    "stiffness_field" => m.stiffness_field.is_some(),
                    _ => true,
                };
                if !section {
                    let name = match e.as_str() {
                        "initial_velocity" => "initial",
                        "stiffness_field" => "model.stiffness_field",
                        other => other,
                    };
                    return Err(Error::format(
                        path,
                        format!(
                            "model.effects: `{}` is listed but the scene has no [{name}] section",
                            quote(e, 100)
                        ),
                    ));
                }
            }
        }
        if let Some(f) = self.model.as_ref().and_then(|m| m.stiffness_field.as_ref()) {
            super::StiffnessFieldSection::check(f.cells).map_err(|e| Error::format(path, e))?;
        }
        self.numerics
            .nitsche_penalty()
            .map_err(|e| Error::format(path, e))?;
        let mb = self.numerics.reuse_factor_mb;
        if !(mb.is_finite() && mb >= 0.0) {
            return Err(Error::format(
                path,
                format!("numerics.reuse_factor_mb: {mb} is not a finite number >= 0"),
            ));
        }
        let s = self.numerics.surface_subdivision;
        if !(1..=super::numerics::MAX_SURFACE_SUBDIVISION).contains(&s) {
            return Err(Error::format(
                path,
                format!(
                    "numerics.surface_subdivision: {s} is not in 1..={}",
                    super::numerics::MAX_SURFACE_SUBDIVISION
                ),
            ));
        }
        self.to_model()
            .validate()
            .map_err(|e| Error::format(path, e.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_the_first_non_finite_key_and_its_line() {
        let text = "[body]\nx = 1.0\n[ground]\nnormal = [0.0, nan, 0.0]\n[time]\ndt = inf\n";
        assert_eq!(
            non_finite(text).unwrap(),
            "line 4: ground.normal[1]: not a finite number (nan)"
        );
        let text = "[[dirichlet]]\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, -inf, 1.0]\n";
        assert_eq!(
            non_finite(text).unwrap(),
            "line 3: dirichlet[0].max[1]: not a finite number (-inf)"
        );
        assert!(non_finite("[a]\nb = 1e300\nc = [1, 2.5]\n").is_none());
    }

    #[test]
    fn quotes_are_cut_with_an_ellipsis() {
        assert_eq!(quote("abc", 100), "abc");
        let long = "é".repeat(150);
        let q = quote(&long, 100);
        assert_eq!(q.chars().count(), 101);
        assert!(q.ends_with('…'));
    }

    #[test]
    fn long_quoted_values_are_shortened() {
        let long = "x".repeat(300);
        let msg = format!("a.csv: line 2: y is not a number: \"{long}\" and `{long}`, `ok`");
        let short = shorten_quotes(&msg);
        let cut = format!("{}…", "x".repeat(MAX_QUOTE));
        assert_eq!(
            short,
            format!("a.csv: line 2: y is not a number: \"{cut}\" and `{cut}`, `ok`")
        );
        assert_eq!(shorten_quotes(&format!("open \"{long}")), format!("open \"{cut}"));
        assert_eq!(shorten_quotes("esc \"a\\\"b\" c"), "esc \"a\\\"b\" c");
        assert_eq!(shorten_quotes("plain"), "plain");
    }

    #[test]
    fn repeated_prefixes_are_said_once() {
        assert_eq!(
            dedupe_prefixes("s.toml: body.shape: body.shape: sphere needs a radius"),
            "s.toml: body.shape: sphere needs a radius"
        );
        assert_eq!(dedupe_prefixes("a: b: a: c"), "a: b: a: c");
        assert_eq!(
            dedupe_prefixes("s/x.toml: drag: s/x.toml: line 22: [drag]: bad"),
            "s/x.toml: drag: line 22: [drag]: bad"
        );
        // the last part is what is wrong: it stays, whatever it repeats
        assert_eq!(dedupe_prefixes("a.csv: b: a.csv"), "a.csv: b: a.csv");
        assert_eq!(dedupe_prefixes("plain"), "plain");
    }

    #[test]
    fn steps_beyond_the_cap_are_refused_naming_the_key() {
        assert!(check_steps(MAX_STEPS, "time.steps").is_ok());
        let e = check_steps(100_000_000_000, "--steps").unwrap_err();
        assert!(e.starts_with("--steps: 100000000000 steps"), "{e}");
    }

    #[test]
    fn substeps_are_checked_naming_the_key() {
        let scene = |time: &str| {
            let text = format!(
                "[body]\nshape = {{ kind = \"sphere\", center = [0.0, 0.0, 0.0], radius = 0.3 }}\n[material]\nyoung = 1000.0\npoisson = 0.3\ndensity = 1.0\n[time]\n{time}\n"
            );
            Scene::parse(&text, Path::new("s.toml"))
        };
        let ok = scene("dt = 0.02\nsubsteps = 4").unwrap();
        let m = ok.to_model();
        assert_eq!((m.dt, m.substeps), (0.005, 4));
        for (time, says) in [
            (
                "substeps = 0",
                // the declared range of the key, on the text (`super::ranges`)
                "s.toml: line 8: time.substeps: must be in [1, 1000] (solver steps per observed step), got 0",
            ),
            (
                "substeps = 1001",
                "s.toml: line 8: time.substeps: must be in [1, 1000] (solver steps per observed step), got 1001",
            ),
            (
                "steps = 1000000\nsubsteps = 2",
                "s.toml: time.steps x time.substeps: 2000000 steps",
            ),
        ] {
            let e = scene(time).unwrap_err().to_string();
            assert!(e.starts_with(says), "{time}: {e}");
        }
    }

    /// Every command refuses a stiffness field without coarse cells on some axis, or with
    /// more than it can hold, naming the file and the key (`simulate` ran such a scene before).
    #[test]
    fn stiffness_field_cells_are_checked_on_load() {
        let scene = |cells: &str| {
            let text = format!(
                "[body]\nshape = {{ kind = \"sphere\", center = [0.0, 0.0, 0.0], radius = 0.3 }}\n[material]\nyoung = 1000.0\npoisson = 0.3\n[model]\neffects = [\"stiffness_field\"]\nstiffness_field = {{ cells = {cells} }}\n"
            );
            Scene::parse(&text, Path::new("s.toml"))
        };
        assert!(scene("[1, 4, 64]").is_ok());
        for cells in ["[0, 4, 4]", "[4, 65, 4]", "[100000, 100000, 100000]"] {
            let e = scene(cells).unwrap_err().to_string();
            assert!(
                e.starts_with("s.toml: line 8: model.stiffness_field.cells: must be in [1, 64]"),
                "{cells}: {e}"
            );
        }
    }
}
