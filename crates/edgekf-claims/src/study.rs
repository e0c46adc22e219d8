//! Studies: the simulations the claims are measured on — a shipped reproduction, possibly edited
//! (seeds, size, gains, kernel, estimators) — each run once and shared by every claim that needs
//! it.

use std::sync::OnceLock;

use edgekf::noise::Kernel;
use edgekf::scenario::{EstimatorEntry, Scenario};
use edgekf::sim::{self, Observer, Results};
use edgekf_io::reproductions::{self, Entry};
use serde::Deserialize;

use crate::ClaimsError;

/// What a study computes (`kind = "model"` … in `claims/studies.toml`; default `"filters"`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// Monte Carlo runs of a filter scenario (one study per seed), with the inputs'
    /// autocovariance at lag 0 and 1.
    #[default]
    Filters,
    /// The checked filter scenario only (its model and framework), no simulation.
    Model,
    /// The distributed SLAM observer (Guo et al.): its design and one deterministic run.
    Slam,
}

/// Edits of a shipped filter scenario (`edit = { … }` in `claims/studies.toml`, these keys).
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Edit {
    /// Monte Carlo runs per seed.
    pub runs: Option<usize>,
    /// Steps.
    pub steps: Option<usize>,
    /// Report interval (1: one-step resolution).
    pub every: Option<usize>,
    /// Follower and leader gain.
    pub gain: Option<f64>,
    /// σ_w.
    pub sigma_w: Option<f64>,
    /// The spatial kernel of `Q_A`.
    pub kernel: Option<Kernel>,
    /// Keep only these estimator labels (in the file's order).
    #[serde(borrow)]
    pub keep: Option<Vec<&'static str>>,
    /// Extra estimators, as JSON entries (`{"kind": "rkf", "label": "rkf"}`).
    #[serde(borrow)]
    pub add: Vec<&'static str>,
    /// Run the scenario of the reproduction's companion `k` (e.g. the dense graph of
    /// `garkf-fig13`) instead of its own.
    pub companion: Option<usize>,
    /// Run value `k` of the scenario's `[sweep]` (the other edits apply first); without it a
    /// scenario with a sweep runs as written, without the sweep.
    pub point: Option<usize>,
}

/// A simulation the claims are measured on (a `[[study]]` of `claims/studies.toml`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Study {
    /// Stable name.
    pub id: &'static str,
    /// The reproduction whose scenario it runs (`edgekf reproduce --list`).
    pub reproduction: &'static str,
    /// What it changes, in words (empty: the shipped scenario).
    #[serde(default)]
    pub about: &'static str,
    /// What it computes.
    #[serde(default)]
    pub kind: Kind,
    /// Edits of the shipped scenario.
    #[serde(default)]
    pub edit: Edit,
    /// Seeds (the file's seed, then the next ones) at full size.
    pub seeds: usize,
    /// Runs per seed at reduced size (tests; default 4).
    #[serde(default = "four")]
    pub small_runs: usize,
}

fn four() -> usize {
    4
}

/// How large to run the studies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Size {
    /// The papers' size (50 runs, 30 s) with each study's seeds.
    Full,
    /// One seed and a few runs per study (tests: only claims settled at this size are judged).
    Reduced,
}

/// A study's results.
#[derive(Debug)]
pub enum Data {
    /// Filter runs: one [`Results`] per seed (the same scenario otherwise).
    Filters {
        /// The scenario (of the first seed).
        scenario: Box<Scenario>,
        /// The seeds.
        seeds: Vec<u64>,
        /// Per seed.
        results: Vec<Results>,
    },
    /// A checked filter scenario.
    Model {
        /// The scenario.
        scenario: Box<Scenario>,
    },
    /// The SLAM observer.
    Slam {
        /// The validated scenario (design, Theorem 1).
        scenario: Box<edgekf_slam::Scenario>,
        /// Its RK4 run.
        trajectory: edgekf_slam::Trajectory,
    },
}

fn entry(name: &str) -> Result<&'static Entry, ClaimsError> {
    reproductions::find(name).ok_or_else(|| ClaimsError::UnknownReproduction(name.to_string()))
}

fn label_of(e: &EstimatorEntry) -> String {
    e.0.get("label")
        .or_else(|| e.0.get("kind"))
        .and_then(|v| v.as_str())
        .unwrap_or_default()
        .to_string()
}

impl Study {
    /// The checked scenario of this study at `size` (seed: the file's).
    ///
    /// # Errors
    /// [`ClaimsError::Scenario`] when the edited scenario does not check (a bug in the
    /// registry: tests build every study).
    pub fn scenario(&self, size: Size) -> Result<Scenario, ClaimsError> {
        let e = entry(self.reproduction)?;
        let bad = |m: String| ClaimsError::Scenario {
            study: self.id.to_string(),
            message: m,
        };
        let ed = &self.edit;
        let text = match ed.companion {
            Some(k) => {
                e.companions
                    .get(k)
                    .ok_or_else(|| bad(format!("{} has no companion {k}", e.name)))?
                    .1
            }
            None => e.text,
        };
        let mut spec = edgekf_io::spec_from_toml(text).map_err(|x| bad(x.to_string()))?;
        spec.plots.clear();
        if let Some(g) = ed.gain {
            spec.control.follower_gain = g;
            spec.control.leader_gain = g;
        }
        if let Some(s) = ed.sigma_w {
            spec.noise.sigma_w = s;
        }
        if let Some(k) = ed.kernel {
            spec.noise.kernel = k;
        }
        if let Some(keep) = &ed.keep {
            let have: Vec<String> = spec.estimators.iter().map(label_of).collect();
            if let Some(missing) = keep.iter().find(|k| !have.iter().any(|h| h == *k)) {
                return Err(bad(format!(
                    "`{missing}` is not an estimator label of {} ({have:?})",
                    e.file
                )));
            }
            spec.estimators
                .retain(|x| keep.contains(&label_of(x).as_str()));
        }
        for a in &ed.add {
            let x: EstimatorEntry =
                serde_json::from_str(a).map_err(|x| bad(format!("estimator {a}: {x}")))?;
            spec.estimators.push(x);
        }
        if let Some(s) = ed.steps {
            spec.sim.steps = s;
        }
        if let Some(v) = ed.every {
            spec.sim.every = v;
        }
        if let Some(r) = ed.runs {
            spec.sim.runs = r;
        }
        if size == Size::Reduced {
            spec.sim.runs = spec.sim.runs.min(self.small_runs);
        }
        let fw = reproductions::framework_of(e.file, &spec).map_err(|x| bad(x.to_string()))?;
        let sc = Scenario::from_spec(&spec, fw.as_ref()).map_err(|x| bad(x.to_string()))?;
        match ed.point {
            Some(k) => {
                let mut points = sc.sweep_points().map_err(|x| bad(x.to_string()))?;
                if k >= points.len() {
                    return Err(bad(format!(
                        "the sweep has {} values, not {}",
                        points.len(),
                        k + 1
                    )));
                }
                Ok(points.swap_remove(k).scenario)
            }
            None => Ok(sc.without_sweep()),
        }
    }

    /// Whether the study's reproduction counts stable runs (its sweep has a `stable` rule):
    /// then divergence is judged run by run, as the reproduction's sweep does.
    pub fn counts_stable_runs(&self) -> bool {
        let Ok(e) = entry(self.reproduction) else {
            return false;
        };
        let text = match self.edit.companion {
            Some(k) => e.companions.get(k).map_or(e.text, |c| c.1),
            None => e.text,
        };
        edgekf_io::spec_from_toml(text)
            .ok()
            .and_then(|s| s.sweep)
            .is_some_and(|s| s.stable.is_some())
    }

    /// The seeds run at `size` (`seeds` overrides the study's own number at full size).
    pub fn seed_list(&self, base: u64, size: Size, seeds: Option<usize>) -> Vec<u64> {
        let n = match size {
            Size::Reduced => 1,
            Size::Full => seeds.unwrap_or(self.seeds).max(1),
        };
        (0..n as u64).map(|s| base.wrapping_add(s)).collect()
    }

    /// Runs the study.
    ///
    /// # Errors
    /// [`ClaimsError`] for an unknown reproduction, a scenario that does not check, or a
    /// cancelled run.
    pub fn run(
        &self,
        size: Size,
        seeds: Option<usize>,
        obs: &dyn Observer,
    ) -> Result<Data, ClaimsError> {
        match self.kind {
            Kind::Slam => {
                let e = entry(self.reproduction)?;
                let spec = edgekf_slam::ScenarioSpec::from_toml(e.text).map_err(|x| {
                    ClaimsError::Scenario {
                        study: self.id.to_string(),
                        message: x.to_string(),
                    }
                })?;
                let sc = spec.validate().map_err(|x| ClaimsError::Scenario {
                    study: self.id.to_string(),
                    message: x.to_string(),
                })?;
                let trajectory = edgekf_slam::simulate(&sc);
                Ok(Data::Slam {
                    scenario: Box::new(sc),
                    trajectory,
                })
            }
            Kind::Model => Ok(Data::Model {
                scenario: Box::new(self.scenario(size)?),
            }),
            Kind::Filters => {
                let sc = self.scenario(size)?;
                let list = self.seed_list(sc.seed(), size, seeds);
                let opt = sim::Options {
                    input_lags: 1,
                    input_from: 1,
                    per_run_divergence: self.counts_stable_runs(),
                    ..sim::Options::default()
                };
                let mut results = Vec::with_capacity(list.len());
                for &s in &list {
                    let scs = sc.clone().with_seed(s);
                    results
                        .push(sim::run_with(&scs, obs, opt).map_err(|_| ClaimsError::Cancelled)?);
                }
                Ok(Data::Filters {
                    scenario: Box::new(sc),
                    seeds: list,
                    results,
                })
            }
        }
    }

    /// Run-steps this study simulates at `size` (for progress bars).
    pub fn work(&self, size: Size, seeds: Option<usize>) -> u64 {
        match (self.kind, self.scenario(size)) {
            (Kind::Filters, Ok(sc)) => {
                let n = self.seed_list(sc.seed(), size, seeds).len();
                (n * sc.runs() * sc.steps()) as u64
            }
            _ => 0,
        }
    }
}

/// The studies file (`claims/studies.toml`).
const STUDIES: &str = include_str!("../claims/studies.toml");

#[derive(Deserialize)]
#[serde(deny_unknown_fields, bound(deserialize = "'de: 'static"))]
struct File {
    study: Vec<Study>,
}

/// Every study of the shipped file, in the order they run.
///
/// # Errors
/// The parser's error when the file does not read.
pub fn load() -> Result<Vec<Study>, toml::de::Error> {
    toml::from_str::<File>(STUDIES).map(|f| f.study)
}

/// Every study, in the order they run.
///
/// # Panics
/// If the shipped studies file does not read ([`load`]; a bug the tests catch).
pub fn studies() -> Vec<Study> {
    static ALL: OnceLock<Vec<Study>> = OnceLock::new();
    ALL.get_or_init(|| load().unwrap_or_else(|e| panic!("claims/studies.toml: {e}")))
        .clone()
}

/// Looks a study up.
pub fn study(id: &str) -> Option<Study> {
    studies().into_iter().find(|s| s.id == id)
}
