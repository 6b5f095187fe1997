//! `[fit]`: the defaults of a fit of this scene (`softbody fit`, `diagnose`, `gradcheck`):
//! which parameters, which optimizer, how many iterations. The command-line flags override
//! them; the adjoint layer reads them. Checked on load like every section, with errors naming
//! the key (`[fit].iteration: unknown key (known: ...)`).

use serde::{Deserialize, Serialize};

/// `[fit]`
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FitSection {
    /// the fitted parameters (names as `--params` takes them)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parameters: Option<Vec<String>>,
    /// the optimizer (`lbfgs`, `gd`, `gauss-newton`)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub optimizer: Option<String>,
    /// the most iterations
    #[serde(skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
}

/// Checks the raw `[fit]` table of a scene before it is read as a [`FitSection`], so that a
/// wrong key or type is an error naming it (serde's would name neither the section nor the
/// key's expected form).
pub(super) fn check(v: Option<&toml::Value>) -> Result<(), String> {
    let Some(v) = v else { return Ok(()) };
    let table = v.as_table().ok_or("[fit] must be a table")?;
    for (k, v) in table {
        let ok = match k.as_str() {
            "parameters" => v
                .as_array()
                .is_some_and(|a| a.iter().all(|s| s.as_str().is_some())),
            "optimizer" => v.as_str().is_some(),
            "iterations" => v.as_integer().is_some_and(|n| n >= 0),
            other => {
                return Err(format!(
                    "[fit].{other}: unknown key (known: parameters, optimizer, iterations)"
                ))
            }
        };
        if !ok {
            return Err(match k.as_str() {
                "parameters" => "[fit].parameters must be a list of names",
                "optimizer" => "[fit].optimizer must be a string",
                _ => "[fit].iterations must be a non-negative integer",
            }
            .into());
        }
    }
    Ok(())
}
