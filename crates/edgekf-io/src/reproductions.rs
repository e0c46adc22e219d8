//! The shipped scenarios and the paper figures they reproduce (`edgekf reproduce`).
//!
//! Several figures come from one simulation (e.g. thesis Figs 4.9–4.11); `reproduce` runs each
//! scenario file once and draws every figure of it, whichever of them was asked for. The scenario texts are embedded
//! at build time, so the reproductions work from any directory. The files live in this crate's
//! `scenarios/` directory (the repository's top-level `scenarios` links to it).

use edgekf::scenario::{FrameworkSpec, Scenario, ScenarioError, ScenarioSpec};

use crate::framework::{spec_from_json, FrameworkFileError};
use crate::FrameworkError;

/// Why a shipped scenario cannot be had (a bug of the shipped files: tests check every entry),
/// or why a reproduction is not a filter study.
#[derive(Debug, thiserror::Error)]
pub enum ShippedError {
    /// The TOML does not parse into a scenario spec.
    #[error("{file}: {source}")]
    Toml {
        /// The scenario file.
        file: String,
        /// The parser's error.
        source: toml::de::Error,
    },
    /// `framework.file` names a file that is not embedded.
    #[error("{file}: framework file `{path}` is not embedded")]
    NotEmbedded {
        /// The scenario file.
        file: String,
        /// The framework file it names.
        path: String,
    },
    /// The framework file does not parse.
    #[error("{file}: {source}")]
    Framework {
        /// The scenario file.
        file: String,
        /// Why.
        source: FrameworkFileError,
    },
    /// The scenario fails its checks.
    #[error("{file}: {source}")]
    Scenario {
        /// The scenario file.
        file: String,
        /// Which key, and why.
        source: ScenarioError,
    },
    /// A SLAM study has no filter scenario.
    #[error("{0} is a SLAM study")]
    Slam(&'static str),
}

/// One reproducible figure.
pub struct Entry {
    /// Reproduction name (`<source>-fig<number>`).
    pub name: &'static str,
    /// What it shows.
    pub description: &'static str,
    /// Scenario file name under `scenarios/`.
    pub file: &'static str,
    /// The scenario text (embedded at build time, so `reproduce` works from any directory).
    pub text: &'static str,
    /// Plot file stems of this figure (empty for SLAM studies, which draw their own).
    pub plots: &'static [&'static str],
    /// Further scenario files (name, text) whose results the figure draws as well (e.g. the
    /// dense graph of Li & Rajan Fig. 13 beside the sparse one); each is simulated as its own
    /// study.
    pub companions: &'static [(&'static str, &'static str)],
}

macro_rules! scenario {
    ($f:literal) => {
        ($f, include_str!(concat!("../scenarios/", $f)))
    };
}

const NOISELESS: (&str, &str) = scenario!("thesis-fig3.3.toml");
const FIG45: (&str, &str) = scenario!("thesis-fig4.5.toml");
const FIG46: (&str, &str) = scenario!("thesis-fig4.6.toml");
const FIG48: (&str, &str) = scenario!("thesis-fig4.8.toml");
const FIG49: (&str, &str) = scenario!("thesis-fig4.9.toml");
const FILTERS: (&str, &str) = scenario!("eusipco.toml");
const FIG61: (&str, &str) = scenario!("thesis-fig6.1.toml");
const FIG62: (&str, &str) = scenario!("thesis-fig6.2.toml");
const FIG63: (&str, &str) = scenario!("thesis-fig6.3.toml");
const SLAM: (&str, &str) = scenario!("slam-fig3.toml");
const SLAM_DIST: (&str, &str) = scenario!("slam-disturbed.toml");
const GA8: (&str, &str) = scenario!("garkf-fig8.toml");
const GA9: (&str, &str) = scenario!("garkf-fig9.toml");
const GA10: (&str, &str) = scenario!("garkf-fig10.toml");
const GA11: (&str, &str) = scenario!("garkf-fig11.toml");
const GA12: (&str, &str) = scenario!("garkf-fig12.toml");
const GA13: (&str, &str) = scenario!("garkf-fig13.toml");
const GA13_DENSE: (&str, &str) = scenario!("garkf-fig13-dense.toml");
const F3D: (&str, &str) = scenario!("formation-3d.toml");

macro_rules! entry {
    ($name:literal, $desc:literal, $sc:expr, [$($p:literal),*]) => {
        entry!($name, $desc, $sc, [$($p),*], [])
    };
    ($name:literal, $desc:literal, $sc:expr, [$($p:literal),*], [$($c:expr),*]) => {
        Entry {
            name: $name,
            description: $desc,
            file: $sc.0,
            text: $sc.1,
            plots: &[$($p),*],
            companions: &[$($c),*],
        }
    };
}

macro_rules! framework {
    ($f:literal) => {
        ($f, include_str!(concat!("../scenarios/", $f)))
    };
}

/// The framework files the shipped scenarios name (`framework.file`, relative to `scenarios/`),
/// embedded like the scenarios.
pub const FRAMEWORKS: &[(&str, &str)] = &[
    framework!("frameworks/random50-sparse.json"),
    framework!("frameworks/random50-dense.json"),
    framework!("frameworks/hexagon3d.json"),
];

/// The embedded text of a shipped framework file.
pub fn framework_text(path: &str) -> Option<&'static str> {
    let path = path.trim_start_matches("./");
    FRAMEWORKS.iter().find(|(p, _)| *p == path).map(|(_, t)| *t)
}

/// The embedded framework file `path` (as a shipped scenario names it), parsed: how the
/// reproductions resolve `framework.file` ([`crate::load_scenario_with`]).
///
/// # Errors
/// [`FrameworkError::NotShipped`] when it is not embedded, [`FrameworkError::Parse`] when it does
/// not parse.
pub fn embedded_framework(path: &str) -> Result<FrameworkSpec, FrameworkError> {
    let text = framework_text(path).ok_or_else(|| FrameworkError::NotShipped {
        path: path.to_string(),
    })?;
    spec_from_json(text).map_err(|error| FrameworkError::Parse {
        path: path.into(),
        error,
    })
}

/// Every reproducible figure, in paper order.
pub const ENTRIES: &[Entry] = &[
    entry!(
        "eusipco-fig3",
        "EUSIPCO 2022 Fig. 3: agent paths for MLE, RKF, JRKF, CRKF",
        FILTERS,
        ["eusipco-fig3"]
    ),
    entry!(
        "eusipco-fig4a",
        "EUSIPCO 2022 Fig. 4a: trace of the posterior covariance",
        FILTERS,
        ["eusipco-fig4a"]
    ),
    entry!(
        "eusipco-fig4b",
        "EUSIPCO 2022 Fig. 4b: estimation error, mean ± 1σ over 50 runs",
        FILTERS,
        ["eusipco-fig4b"]
    ),
    entry!(
        "thesis-fig3.3",
        "thesis Fig. 3.3: noiseless convergence to a rigid formation (Procrustes)",
        NOISELESS,
        ["thesis-fig3.3"]
    ),
    entry!(
        "thesis-fig3.4",
        "thesis Fig. 3.4: noiseless agent paths",
        NOISELESS,
        ["thesis-fig3.4"]
    ),
    entry!(
        "thesis-fig4.5",
        "thesis Fig. 4.5: no estimator vs MLE for T = 10, 100 (observation noise)",
        FIG45,
        ["thesis-fig4.5"]
    ),
    entry!(
        "thesis-fig4.6",
        "thesis Fig. 4.6: MMSE filter for three prior variances vs MLE",
        FIG46,
        ["thesis-fig4.6"]
    ),
    entry!(
        "thesis-fig4.8",
        "thesis Fig. 4.8: none, MLE, MMSE, RKF with observation noise only",
        FIG48,
        ["thesis-fig4.8"]
    ),
    entry!(
        "thesis-fig4.9",
        "thesis Fig. 4.9: Procrustes error with observation and process noise",
        FIG49,
        ["thesis-fig4.9"]
    ),
    entry!(
        "thesis-fig4.10",
        "thesis Fig. 4.10: estimation error with observation and process noise",
        FIG49,
        ["thesis-fig4.10"]
    ),
    entry!(
        "thesis-fig4.11",
        "thesis Fig. 4.11: agent paths, σ_v = 0.1, σ_w = 0.001",
        FIG49,
        ["thesis-fig4.11"]
    ),
    entry!(
        "thesis-fig5.1",
        "thesis Fig. 5.1: trace of the posterior covariance",
        FILTERS,
        ["thesis-fig5.1"]
    ),
    entry!(
        "thesis-fig5.2",
        "thesis Fig. 5.2: estimation error ε_k",
        FILTERS,
        ["thesis-fig5.2"]
    ),
    entry!(
        "thesis-fig5.3",
        "thesis Fig. 5.3: Procrustes error",
        FILTERS,
        ["thesis-fig5.3", "thesis-fig5.3-ratio"]
    ),
    entry!(
        "thesis-fig6.1",
        "thesis Fig. 6.1: one realization of an agent's control input (RKF loop)",
        FIG61,
        ["thesis-fig6.1"]
    ),
    entry!(
        "thesis-fig6.2",
        "thesis Fig. 6.2: random link failures, AR(1) prediction, P_fail in {0, .25, .5, .75, 1}, u = 0 baseline",
        FIG62,
        ["thesis-fig6.2"]
    ),
    entry!(
        "thesis-fig6.3",
        "thesis Fig. 6.3: no communication (Wiener prediction) vs u = 0 baseline vs clairvoyant",
        FIG63,
        ["thesis-fig6.3"]
    ),
    entry!(
        "garkf-fig8",
        "Li & Rajan Fig. 8: tr Θ̂ from RAL and from consensus, λ = 1 and 0.2",
        GA8,
        ["garkf-fig8"]
    ),
    entry!(
        "garkf-fig9",
        "Li & Rajan Fig. 9: convergence indicator ψ against tracking error δ with Theorem 1's bound",
        GA9,
        ["garkf-fig9"]
    ),
    entry!(
        "garkf-fig10",
        "Li & Rajan Fig. 10: one edge's covariance, RKF vs GA-RKF (edge lost, λ = 1, λ = 0.2)",
        GA10,
        ["garkf-fig10"]
    ),
    entry!(
        "garkf-fig11",
        "Li & Rajan Fig. 11: tracking error at λ = 0.4 and time-averaged over λ",
        GA11,
        ["garkf-fig11-time", "garkf-fig11-sweep"]
    ),
    entry!(
        "garkf-fig12",
        "Li & Rajan Fig. 12: one agent departing at t0 = 0, 1.5, 3, 10 s",
        GA12,
        ["garkf-fig12"]
    ),
    entry!(
        "garkf-fig13",
        "Li & Rajan Fig. 13: 50 agents, sparse vs dense graph, share of stable runs as agents depart",
        GA13,
        ["garkf-fig13"],
        [GA13_DENSE]
    ),
    entry!(
        "formation-3d",
        "a 3-D formation (11 agents, designed by edgekf design): every estimator, paths in three orthographic views",
        F3D,
        [
            "formation-3d-paths",
            "formation-3d-error",
            "formation-3d-cov",
            "formation-3d-procrustes"
        ]
    ),
    entry!(
        "slam-fig3",
        "Guo et al. IFAC 2020 Fig. 3: distributed localization, mapping and formation (§6)",
        SLAM,
        []
    ),
    entry!(
        "slam-disturbed",
        "Guo et al. §6 with bounded L² disturbances on [1, 3] s",
        SLAM_DIST,
        []
    ),
];

/// A shipped scenario text, checked, its `framework.file` taken from [`FRAMEWORKS`].
fn scenario_of(file: &str, text: &str) -> Result<Scenario, ShippedError> {
    let spec = crate::spec_from_toml(text).map_err(|source| ShippedError::Toml {
        file: file.into(),
        source,
    })?;
    let fw = framework_of(file, &spec)?;
    Scenario::from_spec(&spec, fw.as_ref()).map_err(|source| ShippedError::Scenario {
        file: file.into(),
        source,
    })
}

/// The embedded framework file that shipped scenario `file` names (`framework.file`), parsed;
/// `None` when it names none.
///
/// # Errors
/// [`ShippedError`] when the file is not embedded or does not parse.
pub fn framework_of(
    file: &str,
    spec: &ScenarioSpec,
) -> Result<Option<FrameworkSpec>, ShippedError> {
    let Some(p) = &spec.framework.file else {
        return Ok(None);
    };
    let text = framework_text(p).ok_or_else(|| ShippedError::NotEmbedded {
        file: file.into(),
        path: p.clone(),
    })?;
    spec_from_json(text)
        .map(Some)
        .map_err(|source| ShippedError::Framework {
            file: file.into(),
            source,
        })
}

/// Looks a name up.
pub fn find(name: &str) -> Option<&'static Entry> {
    ENTRIES.iter().find(|e| e.name == name)
}

impl Entry {
    /// Whether it is a study of the distributed SLAM observer (`kind = "slam"`, its own crate).
    pub fn is_slam(&self) -> bool {
        self.file.starts_with("slam-")
    }

    /// The simulation's name: the scenario file without `.toml` (figures that share a
    /// simulation share it).
    pub fn simulation(&self) -> &'static str {
        self.file.strip_suffix(".toml").unwrap_or(self.file)
    }

    /// The checked scenario of a filter study.
    ///
    /// # Errors
    /// [`ShippedError`] if the shipped text does not parse or check (a bug: tests check every
    /// entry), or for a SLAM study.
    pub fn scenario(&self) -> Result<Scenario, ShippedError> {
        if self.is_slam() {
            return Err(ShippedError::Slam(self.name));
        }
        scenario_of(self.file, self.text)
    }

    /// The checked scenarios of its companions.
    ///
    /// # Errors
    /// As [`Entry::scenario`].
    pub fn companion_scenarios(&self) -> Result<Vec<Scenario>, ShippedError> {
        self.companions
            .iter()
            .map(|(f, t)| scenario_of(f, t))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_filter_reproduction_checks_and_names_follow_the_contract() {
        for e in ENTRIES {
            // `<source>-fig<number>`, or a plain descriptive name for a study that is no
            // paper's figure (DESIGN.md).
            if let Some((source, _)) = e.name.split_once("-fig") {
                assert!(
                    ["eusipco", "thesis", "garkf", "slam"].contains(&source),
                    "{}",
                    e.name
                );
            }
            if !e.is_slam() {
                let sc = e.scenario().unwrap();
                for p in e.plots {
                    assert!(sc.plots().iter().any(|q| q.file() == *p), "{}: {p}", e.name);
                }
                e.companion_scenarios().unwrap();
            }
        }
    }
}
