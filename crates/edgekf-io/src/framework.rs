//! Framework files (schema `edgekf.framework/1`, DESIGN.md): written by `edgekf design`, read by
//! `edgekf design` and by scenarios (`framework.file`).

use edgekf::design::Candidate;
use edgekf::framework::Framework;
use edgekf::scenario::FrameworkSpec;
use serde::{Deserialize, Serialize};

/// Schema tag of framework files.
pub const FRAMEWORK_SCHEMA: &str = "edgekf.framework/1";

/// Why a text is not a framework file.
#[derive(Debug, thiserror::Error)]
pub enum FrameworkFileError {
    /// Not JSON of the right shape (unknown keys are refused, naming them).
    #[error("not a framework file: {0}")]
    Parse(#[from] serde_json::Error),
    /// Another schema.
    #[error("key `schema`: expected `{FRAMEWORK_SCHEMA}`, got `{0}`")]
    Schema(String),
}

/// A framework file (`edgekf.framework/1`).
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FrameworkFile {
    /// Must be [`FRAMEWORK_SCHEMA`].
    pub schema: String,
    /// Name.
    pub name: String,
    /// D.
    pub dim: usize,
    /// Nominal configuration, one point per agent.
    pub config: Vec<Vec<f64>>,
    /// Undirected links `[i, j]`, `i < j`, sorted (as input: the candidate links).
    pub edges: Vec<[usize; 2]>,
    /// One weight per link (absent in an input: to be designed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights: Option<Vec<f64>>,
    /// Leaders.
    #[serde(default)]
    pub leaders: Vec<usize>,
}

impl FrameworkFile {
    /// Parses a framework file's text.
    ///
    /// # Errors
    /// [`FrameworkFileError`] when the text is not such a file.
    pub fn parse(text: &str) -> Result<Self, FrameworkFileError> {
        let f: FrameworkFile = serde_json::from_str(text)?;
        if f.schema != FRAMEWORK_SCHEMA {
            return Err(FrameworkFileError::Schema(f.schema));
        }
        Ok(f)
    }

    /// The file of a designed framework.
    pub fn from_framework(f: &Framework) -> Self {
        Self {
            schema: FRAMEWORK_SCHEMA.into(),
            name: f.name().into(),
            dim: f.dim(),
            config: (0..f.agents()).map(|i| f.point(i).to_vec()).collect(),
            edges: f.graph().links().iter().map(|&(i, j)| [i, j]).collect(),
            weights: Some(f.weights().to_vec()),
            leaders: f.leaders().to_vec(),
        }
    }

    /// The design input it describes.
    pub fn candidate(&self) -> Candidate {
        Candidate {
            name: self.name.clone(),
            dim: self.dim,
            config: self.config.clone(),
            links: self.edges.iter().map(|e| (e[0], e[1])).collect(),
            leaders: self.leaders.clone(),
        }
    }

    /// The inline framework of a scenario it describes.
    pub fn to_spec(&self) -> FrameworkSpec {
        FrameworkSpec {
            preset: None,
            file: None,
            dim: Some(self.dim),
            config: Some(self.config.clone()),
            edges: Some(self.edges.clone()),
            weights: self.weights.clone(),
            leaders: Some(self.leaders.clone()),
            name: Some(self.name.clone()),
        }
    }
}

/// The inline framework a framework file's text describes.
///
/// # Errors
/// [`FrameworkFileError`] when the text is not such a file.
pub fn spec_from_json(text: &str) -> Result<FrameworkSpec, FrameworkFileError> {
    FrameworkFile::parse(text).map(|f| f.to_spec())
}
