//! Sections of effects defined outside this crate (extensions, e.g. the adjoint layer's
//! `wind`).
//!
//! The scene's core sections are typed ([`super::Scene`]); any other top-level *table* is kept
//! here, by name, with the line it starts on, for the layer that defines its effect. That layer
//! validates it: `adjoint::fit::scene_model`, through which every `softbody` command builds its
//! model, refuses a section or an effect name that no effect of its catalogue claims, naming
//! the line. A top-level key that is not a table is an error here.

use crate::error::Error;
use serde::de::DeserializeOwned;
use std::collections::BTreeMap;
use std::path::Path;

/// The top-level keys of the core scene.
pub const SECTIONS: [&str; 11] = [
    "body",
    "material",
    "damping",
    "gravity",
    "ground",
    "dirichlet",
    "initial",
    "time",
    "model",
    "fit",
    "numerics",
];

/// One extension section: its table and the line of its header (0: made in code).
#[derive(Clone, Debug, PartialEq)]
pub struct Extension {
    /// the section's keys
    pub table: toml::Table,
    /// 1-based line of `[name]` in the scene file (0 when not read from a file)
    pub line: usize,
}

impl Extension {
    /// `"line N: "` for an error about the section (nothing when made in code).
    pub fn location(&self) -> String {
        at(self.line)
    }
    /// The section as `T` (typically a `deny_unknown_fields` struct of the effect's file); the
    /// error names the file, the line and the section.
    pub fn parse<T: DeserializeOwned>(&self, name: &str, path: &Path) -> Result<T, Error> {
        toml::Value::Table(self.table.clone())
            .try_into()
            .map_err(|e: toml::de::Error| {
                Error::format(
                    path,
                    super::shorten_quotes(&format!(
                        "{}[{name}]: {}",
                        at(self.line),
                        e.message().replace('\n', " ")
                    )),
                )
            })
    }
}

/// `"line N: "`, or nothing for line 0.
fn at(line: usize) -> String {
    if line == 0 {
        String::new()
    } else {
        format!("line {line}: ")
    }
}

/// The extension sections of scene `text` (parsed as `table`): its top-level tables that are
/// not core sections. A non-table top-level key that is not a core section is an error naming
/// its line.
pub fn collect(text: &str, table: toml::Table, path: &Path) -> Result<BTreeMap<String, Extension>, Error> {
    let mut out = BTreeMap::new();
    for (key, value) in table {
        if SECTIONS.contains(&key.as_str()) {
            continue;
        }
        let line = line_of(text, &key);
        match value {
            toml::Value::Table(table) => {
                out.insert(key, Extension { table, line });
            }
            _ => {
                return Err(Error::format(
                    path,
                    format!(
                        "{}unknown key `{key}` (sections: {})",
                        at(line),
                        SECTIONS.join(", ")
                    ),
                ))
            }
        }
    }
    Ok(out)
}

/// The first line (1-based) that opens section `key` (`[key]`, `[key.`) or sets it at the top
/// level (`key =`, `key.`); 0 if none is found.
fn line_of(text: &str, key: &str) -> usize {
    let mut top = true;
    for (i, raw) in text.lines().enumerate() {
        let l = raw.trim_start();
        if let Some(h) = l.strip_prefix('[') {
            let h = h.trim_start_matches('[').trim_start();
            if h.strip_prefix(key)
                .is_some_and(|r| r.trim_start().starts_with(']') || r.starts_with('.'))
            {
                return i + 1;
            }
            top = false;
        } else if top {
            if let Some(r) = l.strip_prefix(key) {
                let r = r.trim_start();
                if r.starts_with('=') || r.starts_with('.') {
                    return i + 1;
                }
            }
        }
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_are_kept_with_their_line_and_other_keys_refused() {
        let text = "[body]\nresolution = 5\n\n[wind]\ntraction = [1.0, 2.0, 3.0]\n";
        let ext = collect(text, text.parse().unwrap(), Path::new("s.toml")).unwrap();
        assert_eq!(ext.len(), 1);
        assert_eq!(ext["wind"].line, 4);
        assert_eq!(ext["wind"].table["traction"].as_array().unwrap().len(), 3);
        let text = "youngs = 3.0\n[body]\nresolution = 5\n";
        let err = collect(text, text.parse().unwrap(), Path::new("s.toml")).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("s.toml") && msg.contains("line 1: unknown key `youngs`"),
            "{msg}"
        );
        assert_eq!(line_of("[a]\nx = 1\n[[b.c]]\n", "b"), 3);
    }

    #[test]
    fn a_section_parses_into_its_type_or_names_the_line() {
        #[derive(serde::Deserialize, Debug)]
        #[serde(deny_unknown_fields)]
        struct S {
            #[allow(dead_code)]
            traction: [f64; 3],
        }
        let text = "[body]\n[wind]\ntractio = [1.0, 2.0, 3.0]\n";
        let ext = collect(text, text.parse().unwrap(), Path::new("s.toml")).unwrap();
        let err = ext["wind"]
            .parse::<S>("wind", Path::new("s.toml"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("line 2: [wind]: unknown field `tractio`"), "{err}");
    }
}
