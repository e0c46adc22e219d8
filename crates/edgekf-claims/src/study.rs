//! Studies: the simulations the claims are measured on — a shipped reproduction, possibly edited
//! (seeds, size, gains, kernel, estimators) — each run once and shared by every claim that needs
//! it.

use edgekf::noise::Kernel;
use edgekf::scenario::{EstimatorEntry, Scenario, ScenarioSpec};
use edgekf::sim::{self, Observer, Results};
use edgekf_io::reproductions::{self, Entry};

use crate::ClaimsError;

/// What a study computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Monte Carlo runs of a filter scenario (one study per seed), with the inputs'
    /// autocovariance at lag 0 and 1.
    Filters,
    /// The checked filter scenario only (its model and framework), no simulation.
    Model,
    /// The distributed SLAM observer (Guo et al.): its design and one deterministic run.
    Slam,
}

/// Edits of a shipped filter scenario.
#[derive(Debug, Clone, Default, PartialEq)]
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
    pub keep: Option<&'static [&'static str]>,
    /// Extra estimators, as JSON entries (`{"kind": "rkf", "label": "rkf"}`).
    pub add: &'static [&'static str],
    /// Run the scenario of the reproduction's companion `k` (e.g. the dense graph of
    /// `garkf-fig13`) instead of its own.
    pub companion: Option<usize>,
    /// Run value `k` of the scenario's `[sweep]` (the other edits apply first); without it a
    /// scenario with a sweep runs as written, without the sweep.
    pub point: Option<usize>,
}

/// A simulation the claims are measured on.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    /// Stable name.
    pub id: &'static str,
    /// The reproduction whose scenario it runs (`edgekf reproduce --list`).
    pub reproduction: &'static str,
    /// What it changes, in words (empty: the shipped scenario).
    pub about: &'static str,
    /// What it computes.
    pub kind: Kind,
    /// Edits of the shipped scenario.
    pub edit: Edit,
    /// Seeds (the file's seed, then the next ones) at full size.
    pub seeds: usize,
    /// Runs per seed at reduced size (tests).
    pub small_runs: usize,
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
        let mut spec: ScenarioSpec = toml::from_str(text).map_err(|x| bad(x.to_string()))?;
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
        if let Some(keep) = ed.keep {
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
        for a in ed.add {
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
                let spec: edgekf_slam::ScenarioSpec =
                    toml::from_str(e.text).map_err(|x| ClaimsError::Scenario {
                        study: self.id.to_string(),
                        message: x.to_string(),
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

/// Every study, in the order they run.
pub fn studies() -> Vec<Study> {
    let full = |id, reproduction, seeds| Study {
        id,
        reproduction,
        about: "",
        kind: Kind::Filters,
        edit: Edit::default(),
        seeds,
        small_runs: 4,
    };
    vec![
        Study {
            about: "the shipped scenario; 4 seeds for the per-seed input statistics",
            ..full("eusipco", "eusipco-fig4a", 4)
        },
        Study {
            about: "σ_w = 0 (no disturbances), 3 s, rkf and jrkf, 2 runs (covariances are exact)",
            edit: Edit {
                sigma_w: Some(0.0),
                steps: Some(3000),
                runs: Some(2),
                keep: Some(&["rkf", "jrkf"]),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("eusipco-calm", "eusipco-fig4a", 1)
        },
        Study {
            about: "a white kernel (Q_A = I: uncorrelated disturbances), rkf and jrkf",
            edit: Edit {
                kernel: Some(Kernel::White),
                keep: Some(&["rkf", "jrkf"]),
                ..Edit::default()
            },
            ..full("eusipco-white", "eusipco-fig4a", 1)
        },
        Study {
            about: "the shipped scenario, 2 seeds",
            ..full("fig4.9", "thesis-fig4.9", 2)
        },
        full("fig4.8", "thesis-fig4.8", 1),
        Study {
            about: "follower and leader gains 10 (a ten times faster loop), mle and rkf, 3 seeds",
            edit: Edit {
                gain: Some(10.0),
                keep: Some(&["mle", "rkf"]),
                ..Edit::default()
            },
            ..full("fig4.8-gain10", "thesis-fig4.8", 3)
        },
        full("fig4.5", "thesis-fig4.5", 1),
        Study {
            about: "plus an MMSE filter with a very wide prior (σ²_prior = 1e3), 2 seeds",
            edit: Edit {
                add: &[r#"{"kind": "mmse", "prior_var": 1000.0, "label": "mmse-1e3"}"#],
                ..Edit::default()
            },
            ..full("fig4.6", "thesis-fig4.6", 2)
        },
        full("fig3.3", "thesis-fig3.3", 1),
        full("fig6.2", "thesis-fig6.2", 1),
        Study {
            about:
                "the first second at one-step resolution (every = 1), the rkf-ar lanes plus the plain rkf, 6 seeds",
            edit: Edit {
                steps: Some(1000),
                every: Some(1),
                keep: Some(&["P_fail=0", "P_fail=0.25", "P_fail=0.5", "P_fail=0.75", "P_fail=1"]),
                add: &[r#"{"kind": "rkf", "label": "rkf"}"#],
                ..Edit::default()
            },
            ..full("fig6.2-onset", "thesis-fig6.2", 6)
        },
        Study {
            about: "the shipped scenario, 2 seeds",
            ..full("fig6.3", "thesis-fig6.3", 2)
        },
        Study {
            about: "the hexagon scenario, checked (no simulation)",
            kind: Kind::Model,
            ..full("hexagon", "thesis-fig3.3", 1)
        },
        Study {
            about: "the EUSIPCO noise model, checked (no simulation)",
            kind: Kind::Model,
            ..full("eusipco-model", "eusipco-fig4a", 1)
        },
        Study {
            about: "λ = 1 (the sweep's first value), 10 runs, 60 s",
            edit: Edit {
                point: Some(0),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig8", "garkf-fig8", 1)
        },
        Study {
            about: "λ = 0.2 (the sweep's second value), 10 runs, 60 s",
            edit: Edit {
                point: Some(1),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig8-low", "garkf-fig8", 1)
        },
        Study {
            about: "the shipped scenario at 40 runs",
            edit: Edit {
                runs: Some(40),
                ..Edit::default()
            },
            ..full("garkf-fig9", "garkf-fig9", 1)
        },
        Study {
            about: "edge 5→0 lost for good (sweep value 0), 10 runs, 60 s",
            edit: Edit {
                runs: Some(10),
                point: Some(0),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig10-lost", "garkf-fig10", 1)
        },
        Study {
            about: "λ = 1 (sweep value 1), 10 runs, 60 s",
            edit: Edit {
                runs: Some(10),
                point: Some(1),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig10", "garkf-fig10", 1)
        },
        Study {
            about: "λ = 0.2 (sweep value 2), 10 runs, 60 s",
            edit: Edit {
                runs: Some(10),
                point: Some(2),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig10-low", "garkf-fig10", 1)
        },
        Study {
            about: "λ = 0.4 (the shipped scenario without its sweep), 10 runs, 60 s",
            small_runs: 2,
            ..full("garkf-fig11", "garkf-fig11", 1)
        },
        Study {
            about: "λ = 0.2 (sweep value 1), 10 runs, 30 s",
            edit: Edit {
                steps: Some(3000),
                point: Some(1),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig11-low", "garkf-fig11", 1)
        },
        Study {
            about: "λ = 0.2 (sweep value 1), 10 runs, 60 s, plus RKF and GA-RKF with σ_w = 0.1",
            edit: Edit {
                point: Some(1),
                keep: Some(&["no estimator"]),
                add: &[
                    r#"{"kind": "rkf-ca", "label": "RKF σw=0.1", "sigma_w": 0.1}"#,
                    r#"{"kind": "garkf", "label": "GA-RKF σw=0.1", "sigma_w": 0.1, "epsilon": 0.08}"#,
                ],
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig11-low-matched", "garkf-fig11", 1)
        },
        Study {
            about: "λ = 0.8 (sweep value 4), 10 runs, 60 s",
            edit: Edit {
                point: Some(4),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig11-high", "garkf-fig11", 1)
        },
        Study {
            about: "λ = 1 (sweep value 5), 10 runs, 60 s",
            edit: Edit {
                point: Some(5),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig11-full", "garkf-fig11", 1)
        },
        Study {
            about: "agent 6 departs at t₀ = 10 s (the shipped scenario without its sweep), 20 runs, 30 s",
            small_runs: 2,
            ..full("garkf-fig12", "garkf-fig12", 1)
        },
        Study {
            about: "agent 6 departs at t₀ = 10 s, 20 runs, 90 s (30 s past the maneuver's end)",
            edit: Edit {
                steps: Some(9000),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig12-long", "garkf-fig12", 1)
        },
        Study {
            about: "agent 6 departs at t₀ = 0 (sweep value 0), 20 runs, 30 s",
            edit: Edit {
                point: Some(0),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig12-early", "garkf-fig12", 1)
        },
        Study {
            about: "sparse graph, half the agents depart at 8 s (sweep value 4), 100 runs, 15 s",
            edit: Edit {
                runs: Some(100),
                point: Some(4),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig13-sparse", "garkf-fig13", 1)
        },
        Study {
            about: "sparse graph, 6 % of the agents depart at 8 s (sweep value 1), 20 runs, 15 s",
            edit: Edit {
                runs: Some(20),
                point: Some(1),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig13-sparse-few", "garkf-fig13", 1)
        },
        Study {
            about: "dense graph, half the agents depart at 8 s (sweep value 4), 10 runs, 15 s",
            edit: Edit {
                runs: Some(10),
                companion: Some(0),
                point: Some(4),
                ..Edit::default()
            },
            small_runs: 2,
            ..full("garkf-fig13-dense", "garkf-fig13", 1)
        },
        Study {
            about: "the sparse 50-agent graph, checked (no simulation)",
            kind: Kind::Model,
            ..full("garkf-fig13-sparse-model", "garkf-fig13", 1)
        },
        Study {
            about: "the dense 50-agent graph, checked (no simulation)",
            kind: Kind::Model,
            edit: Edit {
                companion: Some(0),
                ..Edit::default()
            },
            ..full("garkf-fig13-dense-model", "garkf-fig13", 1)
        },
        Study {
            kind: Kind::Slam,
            ..full("slam-fig3", "slam-fig3", 1)
        },
        Study {
            kind: Kind::Slam,
            ..full("slam-disturbed", "slam-disturbed", 1)
        },
    ]
}

/// Looks a study up.
pub fn study(id: &str) -> Option<Study> {
    studies().into_iter().find(|s| s.id == id)
}
