//! Framework files (schema `edgekf.framework/1`, DESIGN.md), parsed from text: the caller reads
//! the file (the library does no I/O), or a reproduction embeds it.

use serde::Deserialize;

use super::FrameworkSpec;

/// Schema tag of framework files.
pub const FRAMEWORK_SCHEMA: &str = "edgekf.framework/1";

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FrameworkFile {
    schema: String,
    #[serde(default)]
    name: Option<String>,
    dim: usize,
    config: Vec<Vec<f64>>,
    edges: Vec<[usize; 2]>,
    #[serde(default)]
    weights: Option<Vec<f64>>,
    #[serde(default)]
    leaders: Option<Vec<usize>>,
}

impl FrameworkSpec {
    /// The inline framework a framework file (`edgekf.framework/1`, JSON) describes.
    ///
    /// # Errors
    /// A message when the text is not such a file (unknown keys are refused, naming them).
    pub fn from_framework_json(text: &str) -> Result<Self, String> {
        let f: FrameworkFile =
            serde_json::from_str(text).map_err(|e| format!("not a framework file: {e}"))?;
        if f.schema != FRAMEWORK_SCHEMA {
            return Err(format!(
                "key `schema`: expected `{FRAMEWORK_SCHEMA}`, got `{}`",
                f.schema
            ));
        }
        Ok(FrameworkSpec {
            preset: None,
            file: None,
            dim: Some(f.dim),
            config: Some(f.config),
            edges: Some(f.edges),
            weights: f.weights,
            leaders: f.leaders,
            name: f.name,
        })
    }
}
