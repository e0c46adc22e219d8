//! The scenario file (spec) and its validation into the checked [`Scenario`].
//!
//! A [`ScenarioSpec`] is what a TOML scenario (top-level `kind = "slam"`) or a resolved `scenario.json`
//! (`"schema": "edgekf.slam/1"`) holds. [`ScenarioSpec::validate`] checks it once — graphs, landmark sets, gains,
//! time grid — designs every robot's observer (eqs. 18–20) and returns a [`Scenario`]; every failure is a
//! [`ScenarioError`] that names the key and the condition.

use crate::care::CareError;
use crate::disturbance::Disturbance;
use crate::graph::{
    check_laplacian, is_connected, is_strongly_connected, matrix_from_rows, LaplacianDefect,
};
use crate::model::Model;
use crate::observer::{design_robot, RobotObserver};
use crate::theorem::Theorem1Report;
use nalgebra::{DMatrix, DVector, Vector2};
use serde::{Deserialize, Serialize};

/// The schema tag of a resolved scenario.
pub const SCHEMA: &str = "edgekf.slam/1";
/// The `kind` tag of a TOML scenario.
pub const KIND: &str = "slam";

/// The graphs as Laplacian matrices (rows; `l_ij < 0` is an edge "i receives from / measures j").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphsSpec {
    /// `𝓛_c`, undirected and connected (Assumption 4).
    pub communication: Vec<Vec<f64>>,
    /// `𝓛⁺`, directed and strongly connected (Assumption 1).
    pub measurement: Vec<Vec<f64>>,
    /// `𝓛_f`, undirected and connected (Assumption 1); `𝓛⁻ = 𝓛_f − 𝓛⁺` must be a Laplacian.
    pub formation: Vec<Vec<f64>>,
}

/// Control and coupling gains (eqs. 3, 4, 19).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GainsSpec {
    /// `k₁` (manoeuvre, eq. 3), > 0.
    pub k1: f64,
    /// `k₂` (formation, eq. 4), > 0.
    pub k2: f64,
    /// `γ` (consensus coupling, eq. 19), > 0.
    pub gamma: f64,
}

/// `R_i = r_i I`: one scalar for all robots or one per robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum RSpec {
    /// Same `r` for every robot.
    Scalar(f64),
    /// `r_i` per robot.
    PerRobot(Vec<f64>),
}

/// Observer design weights (eq. 20).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObserverSpec {
    /// `Q = q I_N` (design weight `Ḡ_i Q Ḡ_iᵀ = Z_iᵀ Q Z_i`), > 0.
    pub q: f64,
    /// `R_i = r_i I`, > 0.
    pub r: RSpec,
}

/// Centroid reference `p_c*(t) = start + velocity · t` (eq. 3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CentroidSpec {
    /// `p_c*(0)` (m).
    pub start: [f64; 2],
    /// `ṗ_c*` (m/s).
    pub velocity: [f64; 2],
}

/// Named initial estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InitialEstimateKind {
    /// Every estimate at the origin.
    Origin,
    /// Every estimate equal to the true initial state.
    Exact,
}

/// Initial estimates `x̂_i(0)`: `"origin"`, `"exact"`, or one vector of length `N = 2(n+m)` per robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum InitialEstimatesSpec {
    /// A named choice.
    Named(InitialEstimateKind),
    /// Explicit vectors.
    Explicit(Vec<Vec<f64>>),
}

/// Time grid: classical RK4 with step `step` over `[0, horizon]`, output every `output_every`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Horizon (s), a whole number of steps.
    pub horizon: f64,
    /// RK4 step `h` (s).
    pub step: f64,
    /// Output interval (s), a whole number of steps.
    pub output_every: f64,
}

/// A scenario file: everything needed to recompute a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    /// `"slam"` in a TOML scenario (absent in a resolved one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<String>,
    /// `"edgekf.slam/1"` in a resolved scenario.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub schema: Option<String>,
    /// Scenario name.
    pub name: String,
    /// Free text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Initial robot positions `p_i(0)` (m).
    pub robots: Vec<[f64; 2]>,
    /// Landmark positions `m_l` (m).
    pub landmarks: Vec<[f64; 2]>,
    /// Desired positions `p_i*` (only differences matter, eq. 4).
    pub desired: Vec<[f64; 2]>,
    /// `M_i`: the landmarks robot `i` measures (0-based).
    pub landmark_sets: Vec<Vec<usize>>,
    /// The graphs.
    pub graphs: GraphsSpec,
    /// The gains.
    pub gains: GainsSpec,
    /// Observer weights.
    pub observer: ObserverSpec,
    /// Centroid reference.
    pub centroid: CentroidSpec,
    /// Initial estimates.
    pub initial_estimates: InitialEstimatesSpec,
    /// Time grid.
    pub time: TimeSpec,
    /// Optional disturbances (none when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disturbance: Option<Disturbance>,
}

/// A scenario that fails validation. Every message names the key and the condition.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScenarioError {
    /// A tag has the wrong value.
    #[error("key `{key}` must be \"{expected}\", found \"{found}\"")]
    WrongTag {
        /// The key.
        key: &'static str,
        /// Expected value.
        expected: &'static str,
        /// Found value.
        found: String,
    },
    /// A list has the wrong length.
    #[error("key `{key}` has {found} entries, expected {expected} ({why})")]
    Dimension {
        /// The key.
        key: String,
        /// Expected length.
        expected: usize,
        /// Found length.
        found: usize,
        /// Where the expected length comes from.
        why: &'static str,
    },
    /// There are no robots.
    #[error("key `robots` is empty: at least one robot is needed")]
    NoRobots,
    /// A number is NaN or infinite.
    #[error("key `{key}` is not finite")]
    NotFinite {
        /// The key.
        key: String,
    },
    /// A number too large to simulate in f64 (its square, or a product of two, overflows).
    #[error("key `{key}` = {value:e} is too large to simulate in f64 (|value| ≤ {MAX_MAGNITUDE:e}); rescale the units")]
    TooLarge {
        /// The key.
        key: String,
        /// The value.
        value: f64,
    },
    /// The time grid has more steps or stored samples than a run can hold.
    #[error("key `{key}`: {what}")]
    TooLong {
        /// The key.
        key: &'static str,
        /// What is too large, with the numbers.
        what: String,
    },
    /// RK4 is unstable at this step for these dynamics.
    #[error("key `time.step`: h·ρ = {h_rho:.3e} ≥ {RK4_BOUND} ({what} ρ = {rho:.3e} /s): RK4 is unstable at this step and the run would overflow; lower `time.step` below {bound:.3e} s")]
    Unstable {
        /// `h ρ`.
        h_rho: f64,
        /// `ρ`.
        rho: f64,
        /// Which dynamics.
        what: &'static str,
        /// The largest stable step.
        bound: f64,
    },
    /// A number that must be positive is not.
    #[error("key `{key}` must be > 0, found {value}")]
    NotPositive {
        /// The key.
        key: String,
        /// The value.
        value: f64,
    },
    /// A matrix is not a graph Laplacian.
    #[error("key `{key}` is not a graph Laplacian: {defect}")]
    NotLaplacian {
        /// The key.
        key: &'static str,
        /// What is wrong.
        defect: LaplacianDefect,
    },
    /// `𝓛⁻ = 𝓛_f − 𝓛⁺` has a negative edge weight (G⁺ is not a subgraph of G_f).
    #[error("keys `graphs.formation` − `graphs.measurement`: the estimation graph L⁻ = L_f − L⁺ has negative weight {weight} on edge ({i}, {j}) (G⁺ must be contained in G_f)")]
    NegativeEstimationWeight {
        /// Row.
        i: usize,
        /// Column.
        j: usize,
        /// The weight `−l⁻_ij`.
        weight: f64,
    },
    /// G⁺ is not strongly connected.
    #[error("key `graphs.measurement`: the measurement graph G⁺ is not strongly connected (Assumption 1)")]
    NotStronglyConnected,
    /// An undirected graph is not connected.
    #[error("key `{key}`: the {what} is not connected (Assumption {assumption})")]
    NotConnected {
        /// The key.
        key: &'static str,
        /// Which graph.
        what: &'static str,
        /// Which assumption of the paper.
        assumption: u8,
    },
    /// A landmark index is out of range.
    #[error("key `landmark_sets[{robot}]`: landmark {index} does not exist (there are {m} landmarks, 0-based)")]
    LandmarkOutOfRange {
        /// Robot.
        robot: usize,
        /// Bad index.
        index: usize,
        /// Number of landmarks.
        m: usize,
    },
    /// A landmark appears twice in one set.
    #[error("key `landmark_sets[{robot}]`: landmark {index} is listed twice")]
    DuplicateLandmark {
        /// Robot.
        robot: usize,
        /// Repeated index.
        index: usize,
    },
    /// Some landmark is seen by no robot.
    #[error("key `landmark_sets`: landmark {landmark} is in no robot's set (∪ M_i must contain every landmark)")]
    LandmarkUnobserved {
        /// The landmark.
        landmark: usize,
    },
    /// A time value is not a whole number of steps.
    #[error("key `{key}` = {value} is not a whole number of steps of `time.step` = {step}")]
    NotMultipleOfStep {
        /// The key.
        key: &'static str,
        /// The value.
        value: f64,
        /// The step.
        step: f64,
    },
    /// A robot's CARE (eq. 20) failed.
    #[error("keys `observer.q`, `observer.r`: the CARE (eq. 20) of robot {robot} has no usable solution: {source}")]
    Care {
        /// Robot.
        robot: usize,
        /// The solver's diagnosis.
        source: CareError,
    },
    /// The robots' observable subspaces do not jointly cover the state.
    #[error("keys `landmark_sets`, `graphs`: the unobservable subspaces of the robots intersect (λ_min of Wᵀ(L_c⊗I)W = {lambda_min:e}), so the distributed observer cannot converge")]
    JointlyUnobservable {
        /// `λ_min` of the proof of Theorem 1.
        lambda_min: f64,
    },
}

/// A validated scenario with its model and observer design: sealed — its fields are private and
/// read through accessors, and the only way to have one is [`ScenarioSpec::validate`], so the
/// simulation and the design checks rely on its invariants without checking again.
#[derive(Debug, Clone)]
pub struct Scenario {
    name: String,
    resolved: ScenarioSpec,
    model: Model,
    gamma: f64,
    q: f64,
    r: Vec<f64>,
    x0: DVector<f64>,
    xhat0: Vec<DVector<f64>>,
    step: f64,
    steps: usize,
    output_stride: usize,
    disturbance: Option<Disturbance>,
    observers: Vec<RobotObserver>,
}

fn finite(key: &str, v: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ScenarioError::NotFinite {
            key: key.to_string(),
        })
    }
}

fn positive(key: &str, v: f64) -> Result<f64, ScenarioError> {
    finite(key, v)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(ScenarioError::NotPositive {
            key: key.to_string(),
            value: v,
        })
    }
}

/// The largest magnitude of a position, estimate, velocity or amplitude: errors are Euclidean
/// norms over the state, so squares of the values must stay far from overflow.
pub const MAX_MAGNITUDE: f64 = 1e75;

/// RK4's stability bound on the negative real axis, `h ρ < 2.78`.
pub const RK4_BOUND: f64 = 2.78;

/// The largest number of RK4 steps of a run (about an hour at a microsecond a step).
pub const MAX_STEPS: f64 = 1e9;

/// The largest number of stored values (samples × robots × state size): 2 GB of f64.
pub const MAX_VALUES: f64 = 2.5e8;

fn representable(key: &str, v: f64) -> Result<f64, ScenarioError> {
    finite(key, v)?;
    if v.abs() > MAX_MAGNITUDE {
        return Err(ScenarioError::TooLarge {
            key: key.to_string(),
            value: v,
        });
    }
    Ok(v)
}

fn points(key: &str, pts: &[[f64; 2]]) -> Result<(), ScenarioError> {
    for (k, p) in pts.iter().enumerate() {
        for (c, v) in p.iter().enumerate() {
            representable(&format!("{key}[{k}][{c}]"), *v)?;
        }
    }
    Ok(())
}

/// Number of steps in `value` (must be a whole number, tolerance 1e-9 relative).
fn whole_steps(key: &'static str, value: f64, step: f64) -> Result<usize, ScenarioError> {
    let k = (value / step).round();
    if k < 1.0 || ((value / step) - k).abs() > 1e-9 * k.max(1.0) {
        return Err(ScenarioError::NotMultipleOfStep { key, value, step });
    }
    if k > MAX_STEPS {
        return Err(ScenarioError::TooLong {
            key,
            what: format!(
                "{value} s is {k:.3e} steps of `time.step` = {step}; a run takes at most {MAX_STEPS:e}"
            ),
        });
    }
    Ok(k as usize)
}

/// The checked graphs (Laplacians) of a scenario.
struct Graphs {
    l_c: DMatrix<f64>,
    l_plus: DMatrix<f64>,
    l_f: DMatrix<f64>,
}

/// The checked time grid.
struct Grid {
    step: f64,
    steps: usize,
    output_stride: usize,
}

impl ScenarioSpec {
    /// Parses a SLAM scenario file's text (TOML), refusing unknown keys by name; nothing is
    /// checked beyond the keys and their types ([`ScenarioSpec::validate`] does that).
    ///
    /// The same as `toml::from_str::<ScenarioSpec>`, compiled once here instead of in every
    /// caller and test binary (serde's deserialiser is generic; docs/build-times.md).
    ///
    /// # Errors
    /// TOML syntax, an unknown key or a value of the wrong type, with its line and column.
    pub fn from_toml(text: &str) -> Result<Self, toml::de::Error> {
        toml::from_str(text)
    }

    /// Validates the spec and designs the observers.
    ///
    /// The sections are checked in the order of the file — tags, robots and landmarks, landmark
    /// sets, graphs, gains, observer weights, centroid, time grid, disturbance, initial
    /// estimates — then every robot's observer is designed and the whole checked (Theorem 1's
    /// joint observability, RK4 stability of the closed loop).
    ///
    /// # Errors
    /// A [`ScenarioError`] naming the first failing key and condition.
    pub fn validate(&self) -> Result<Scenario, ScenarioError> {
        self.check_tags()?;
        let n = self.check_positions()?;
        let m = self.landmarks.len();
        let dim = 2 * (n + m);
        let sets = self.check_landmark_sets(n)?;
        let graphs = self.graphs.check(n)?;
        let (k1, k2, gamma) = self.gains.check()?;
        let (q, r) = self.observer.check(n)?;
        self.centroid.check()?;
        let grid = self.time.check(n, dim)?;
        self.centroid.check_drift(self.time.horizon)?;
        check_formation_step(k1, k2, &graphs.l_f, grid.step)?;
        if let Some(d) = &self.disturbance {
            check_disturbance(d)?;
        }
        let x0 = self.initial_state(n, m);
        let xhat0 = self.check_initial_estimates(n, dim, &x0)?;
        let p_star =
            DVector::from_iterator(2 * n, self.desired.iter().flat_map(|p| p.iter().copied()));
        let model = Model::new(
            k1,
            k2,
            graphs.l_c,
            graphs.l_plus,
            graphs.l_f,
            m,
            sets,
            p_star,
            Vector2::new(self.centroid.start[0], self.centroid.start[1]),
            Vector2::new(self.centroid.velocity[0], self.centroid.velocity[1]),
        );
        let observers = (0..n)
            .map(|i| {
                design_robot(&model, i, q, r[i])
                    .map_err(|source| ScenarioError::Care { robot: i, source })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let scenario = Scenario {
            name: self.name.clone(),
            resolved: self.resolved(&r, &xhat0),
            model,
            gamma,
            q,
            r,
            x0,
            xhat0,
            step: grid.step,
            steps: grid.steps,
            output_stride: grid.output_stride,
            disturbance: self.disturbance.clone(),
            observers,
        };
        scenario.check_design()?;
        Ok(scenario)
    }

    /// `kind` and `schema`, when given, name this format.
    fn check_tags(&self) -> Result<(), ScenarioError> {
        if let Some(kind) = &self.kind {
            if kind != KIND {
                return Err(ScenarioError::WrongTag {
                    key: "kind",
                    expected: KIND,
                    found: kind.clone(),
                });
            }
        }
        if let Some(schema) = &self.schema {
            if schema != SCHEMA {
                return Err(ScenarioError::WrongTag {
                    key: "schema",
                    expected: SCHEMA,
                    found: schema.clone(),
                });
            }
        }
        Ok(())
    }

    /// `robots`, `landmarks` and `desired`: at least one robot, representable positions, one
    /// desired position per robot. Returns the number of robots.
    fn check_positions(&self) -> Result<usize, ScenarioError> {
        let n = self.robots.len();
        if n == 0 {
            return Err(ScenarioError::NoRobots);
        }
        points("robots", &self.robots)?;
        points("landmarks", &self.landmarks)?;
        points("desired", &self.desired)?;
        if self.desired.len() != n {
            return Err(ScenarioError::Dimension {
                key: "desired".into(),
                expected: n,
                found: self.desired.len(),
                why: "one per robot",
            });
        }
        Ok(n)
    }

    /// `landmark_sets`: one set per robot, indices in range and not repeated, every landmark in
    /// some set. Returns the sets sorted.
    fn check_landmark_sets(&self, n: usize) -> Result<Vec<Vec<usize>>, ScenarioError> {
        let m = self.landmarks.len();
        if self.landmark_sets.len() != n {
            return Err(ScenarioError::Dimension {
                key: "landmark_sets".into(),
                expected: n,
                found: self.landmark_sets.len(),
                why: "one set per robot",
            });
        }
        let mut sets = Vec::with_capacity(n);
        let mut seen = vec![false; m];
        for (i, set) in self.landmark_sets.iter().enumerate() {
            let mut s = set.clone();
            for &l in &s {
                if l >= m {
                    return Err(ScenarioError::LandmarkOutOfRange {
                        robot: i,
                        index: l,
                        m,
                    });
                }
                seen[l] = true;
            }
            s.sort_unstable();
            if let Some(w) = s.windows(2).find(|w| w[0] == w[1]) {
                return Err(ScenarioError::DuplicateLandmark {
                    robot: i,
                    index: w[0],
                });
            }
            sets.push(s);
        }
        if let Some(l) = seen.iter().position(|s| !s) {
            return Err(ScenarioError::LandmarkUnobserved { landmark: l });
        }
        Ok(sets)
    }

    /// The true initial state `x(0) = [p_1; …; p_n; m_1; …; m_m]`.
    fn initial_state(&self, n: usize, m: usize) -> DVector<f64> {
        let mut x0 = DVector::zeros(2 * (n + m));
        for (i, p) in self.robots.iter().enumerate() {
            x0[2 * i] = p[0];
            x0[2 * i + 1] = p[1];
        }
        for (l, p) in self.landmarks.iter().enumerate() {
            x0[2 * (n + l)] = p[0];
            x0[2 * (n + l) + 1] = p[1];
        }
        x0
    }

    /// `initial_estimates`: named, or one representable vector of the state dimension per robot.
    fn check_initial_estimates(
        &self,
        n: usize,
        dim: usize,
        x0: &DVector<f64>,
    ) -> Result<Vec<DVector<f64>>, ScenarioError> {
        let v = match &self.initial_estimates {
            InitialEstimatesSpec::Named(InitialEstimateKind::Origin) => {
                return Ok(vec![DVector::zeros(dim); n]);
            }
            InitialEstimatesSpec::Named(InitialEstimateKind::Exact) => {
                return Ok(vec![x0.clone(); n]);
            }
            InitialEstimatesSpec::Explicit(v) => v,
        };
        if v.len() != n {
            return Err(ScenarioError::Dimension {
                key: "initial_estimates".into(),
                expected: n,
                found: v.len(),
                why: "one vector per robot",
            });
        }
        let mut out = Vec::with_capacity(n);
        for (i, e) in v.iter().enumerate() {
            if e.len() != dim {
                return Err(ScenarioError::Dimension {
                    key: format!("initial_estimates[{i}]"),
                    expected: dim,
                    found: e.len(),
                    why: "the state dimension 2(n + m)",
                });
            }
            for (k, x) in e.iter().enumerate() {
                representable(&format!("initial_estimates[{i}][{k}]"), *x)?;
            }
            out.push(DVector::from_column_slice(e));
        }
        Ok(out)
    }

    /// The resolved spec: `schema` set, `r` per robot and the initial estimates explicit.
    fn resolved(&self, r: &[f64], xhat0: &[DVector<f64>]) -> ScenarioSpec {
        let mut resolved = self.clone();
        resolved.kind = None;
        resolved.schema = Some(SCHEMA.to_string());
        resolved.observer.r = RSpec::PerRobot(r.to_vec());
        resolved.initial_estimates = InitialEstimatesSpec::Explicit(
            xhat0.iter().map(|v| v.iter().copied().collect()).collect(),
        );
        resolved
    }
}

impl GraphsSpec {
    /// Each matrix is an `n × n` Laplacian (the undirected ones symmetric); G⁺ is strongly
    /// connected, G_f and G_c connected, and G⁺ contained in G_f (`𝓛⁻ = 𝓛_f − 𝓛⁺` has no
    /// negative edge weight).
    fn check(&self, n: usize) -> Result<Graphs, ScenarioError> {
        let lap = |key: &'static str,
                   rows: &[Vec<f64>],
                   undirected: bool|
         -> Result<DMatrix<f64>, ScenarioError> {
            let l = matrix_from_rows(rows, n)
                .map_err(|defect| ScenarioError::NotLaplacian { key, defect })?;
            check_laplacian(&l, undirected)
                .map_err(|defect| ScenarioError::NotLaplacian { key, defect })?;
            Ok(l)
        };
        let l_c = lap("graphs.communication", &self.communication, true)?;
        let l_plus = lap("graphs.measurement", &self.measurement, false)?;
        let l_f = lap("graphs.formation", &self.formation, true)?;
        if !is_strongly_connected(&l_plus) {
            return Err(ScenarioError::NotStronglyConnected);
        }
        if !is_connected(&l_f) {
            return Err(ScenarioError::NotConnected {
                key: "graphs.formation",
                what: "formation graph G_f",
                assumption: 1,
            });
        }
        if !is_connected(&l_c) {
            return Err(ScenarioError::NotConnected {
                key: "graphs.communication",
                what: "communication graph G_c",
                assumption: 4,
            });
        }
        let l_minus = &l_f - &l_plus;
        let scale = l_f
            .iter()
            .chain(l_plus.iter())
            .fold(1.0_f64, |a, v| a.max(v.abs()));
        for i in 0..n {
            for j in 0..n {
                if i != j && l_minus[(i, j)] > 1e-12 * scale {
                    return Err(ScenarioError::NegativeEstimationWeight {
                        i,
                        j,
                        weight: -l_minus[(i, j)],
                    });
                }
            }
        }
        Ok(Graphs { l_c, l_plus, l_f })
    }
}

impl GainsSpec {
    /// `k₁`, `k₂`, `γ`, each positive.
    fn check(&self) -> Result<(f64, f64, f64), ScenarioError> {
        let k1 = positive("gains.k1", self.k1)?;
        let k2 = positive("gains.k2", self.k2)?;
        let gamma = positive("gains.gamma", self.gamma)?;
        Ok((k1, k2, gamma))
    }
}

impl ObserverSpec {
    /// `q` positive; `r` one positive value, or one per robot. Returns `q` and `r_i` per robot.
    fn check(&self, n: usize) -> Result<(f64, Vec<f64>), ScenarioError> {
        let q = positive("observer.q", self.q)?;
        let r = match &self.r {
            RSpec::Scalar(v) => vec![positive("observer.r", *v)?; n],
            RSpec::PerRobot(v) => {
                if v.len() != n {
                    return Err(ScenarioError::Dimension {
                        key: "observer.r".into(),
                        expected: n,
                        found: v.len(),
                        why: "one r_i per robot",
                    });
                }
                v.iter()
                    .enumerate()
                    .map(|(i, x)| positive(&format!("observer.r[{i}]"), *x))
                    .collect::<Result<Vec<_>, _>>()?
            }
        };
        Ok((q, r))
    }
}

impl CentroidSpec {
    /// Start and velocity representable.
    fn check(&self) -> Result<(), ScenarioError> {
        for c in 0..2 {
            representable(&format!("centroid.start[{c}]"), self.start[c])?;
            representable(&format!("centroid.velocity[{c}]"), self.velocity[c])?;
        }
        Ok(())
    }

    /// The distance travelled over the horizon representable.
    fn check_drift(&self, horizon: f64) -> Result<(), ScenarioError> {
        for c in 0..2 {
            representable(
                "time.horizon × centroid.velocity",
                self.velocity[c] * horizon,
            )?;
        }
        Ok(())
    }
}

impl TimeSpec {
    /// Step, horizon and output interval positive; horizon and output interval whole numbers of
    /// steps, the horizon a whole number of output intervals; not more steps or stored values
    /// than a run can hold (`n` robots, state dimension `dim`).
    fn check(&self, n: usize, dim: usize) -> Result<Grid, ScenarioError> {
        let step = positive("time.step", self.step)?;
        positive("time.horizon", self.horizon)?;
        positive("time.output_every", self.output_every)?;
        let steps = whole_steps("time.horizon", self.horizon, step)?;
        let output_stride = whole_steps("time.output_every", self.output_every, step)?;
        if steps % output_stride != 0 {
            return Err(ScenarioError::NotMultipleOfStep {
                key: "time.horizon",
                value: self.horizon,
                step: self.output_every,
            });
        }
        let stored = (steps / output_stride + 1) as f64 * ((n + 1) * dim) as f64;
        if stored > MAX_VALUES {
            return Err(ScenarioError::TooLong {
                key: "time.output_every",
                what: format!(
                    "{} samples of {} values each ({stored:.3e} in all) are more than a run keeps ({MAX_VALUES:e}); raise `time.output_every`",
                    steps / output_stride + 1,
                    (n + 1) * dim
                ),
            });
        }
        Ok(Grid {
            step,
            steps,
            output_stride,
        })
    }
}

/// RK4 at `step` is stable on the formation dynamics `A = −(k₁/n) 11ᵀ − k₂ L_f` (⊗ I₂), whose
/// eigenvalues are −k₁ and −k₂ λ(L_f) (and the observer design is meaningless past it).
fn check_formation_step(
    k1: f64,
    k2: f64,
    l_f: &DMatrix<f64>,
    step: f64,
) -> Result<(), ScenarioError> {
    let rho_a = k1.max(k2 * l_f.symmetric_eigenvalues().amax());
    if step * rho_a >= RK4_BOUND {
        return Err(ScenarioError::Unstable {
            h_rho: step * rho_a,
            rho: rho_a,
            what: "the formation dynamics (gains.k1, gains.k2)",
            bound: RK4_BOUND / rho_a,
        });
    }
    Ok(())
}

/// `disturbance`: every number representable and a window of positive length.
fn check_disturbance(d: &Disturbance) -> Result<(), ScenarioError> {
    for (key, v) in [
        ("disturbance.start", d.start),
        ("disturbance.end", d.end),
        ("disturbance.omega_amplitude", d.omega_amplitude),
        ("disturbance.omega_frequency", d.omega_frequency),
        (
            "disturbance.omega_phase_per_coordinate",
            d.omega_phase_per_coordinate,
        ),
        ("disturbance.nu_amplitude", d.nu_amplitude),
        ("disturbance.nu_frequency", d.nu_frequency),
        ("disturbance.nu_phase_per_row", d.nu_phase_per_row),
        ("disturbance.nu_phase_per_robot", d.nu_phase_per_robot),
    ] {
        representable(key, v)?;
    }
    positive("disturbance.end − disturbance.start", d.end - d.start)?;
    Ok(())
}

impl Scenario {
    /// The designed whole: the robots' unobservable subspaces do not intersect (Theorem 1's
    /// `λ_min > 0`), and RK4 at the scenario's step is stable on the closed loop with the
    /// observers.
    fn check_design(&self) -> Result<(), ScenarioError> {
        let report = self.theorem1();
        if report.lambda_min.is_nan() || report.lambda_min <= 1e-9 {
            return Err(ScenarioError::JointlyUnobservable {
                lambda_min: report.lambda_min,
            });
        }
        let rho = self.closed_loop_spectral_radius();
        if rho.is_nan() || self.step * rho >= RK4_BOUND {
            return Err(ScenarioError::Unstable {
                h_rho: self.step * rho,
                rho,
                what: "the closed loop with the observers (gains.gamma, observer.q, observer.r)",
                bound: RK4_BOUND / rho,
            });
        }
        Ok(())
    }

    /// Name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The resolved spec (explicit initial estimates and per-robot `r`; `schema` set): what
    /// `scenario.json` holds, and validates to the same scenario.
    pub fn resolved(&self) -> &ScenarioSpec {
        &self.resolved
    }

    /// The model (eqs. 12–17).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Coupling gain `γ`.
    pub fn gamma(&self) -> f64 {
        self.gamma
    }

    /// `Q = q I`.
    pub fn q(&self) -> f64 {
        self.q
    }

    /// `R_i = r_i I`, one `r_i` per robot.
    pub fn r(&self) -> &[f64] {
        &self.r
    }

    /// True initial state `x(0)`.
    pub fn x0(&self) -> &DVector<f64> {
        &self.x0
    }

    /// Initial estimates `x̂_i(0)`, one per robot.
    pub fn xhat0(&self) -> &[DVector<f64>] {
        &self.xhat0
    }

    /// RK4 step `h` (s).
    pub fn step(&self) -> f64 {
        self.step
    }

    /// Number of RK4 steps.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Steps between outputs.
    pub fn output_stride(&self) -> usize {
        self.output_stride
    }

    /// Disturbances, if any.
    pub fn disturbance(&self) -> Option<&Disturbance> {
        self.disturbance.as_ref()
    }

    /// Per-robot observers (eqs. 18–20).
    pub fn observers(&self) -> &[RobotObserver] {
        &self.observers
    }

    /// Number of robots.
    pub fn n(&self) -> usize {
        self.model.n
    }

    /// Number of landmarks.
    pub fn m(&self) -> usize {
        self.model.m
    }

    /// The Theorem 1 condition report (eqs. 24–25) and the error system's spectral abscissa.
    pub fn theorem1(&self) -> Theorem1Report {
        Theorem1Report::compute(&self.model, &self.observers, self.q, self.gamma)
    }

    /// Spectral radius of the linear closed loop: in the coordinates `(x, E)` it is block triangular,
    /// `[[A, −k₂ [D; 0]], [0, 𝒜]]`, so its eigenvalues are those of `A` and of the error system `𝒜` (eq. 21).
    /// RK4 is stable for `h ρ ≲ 2.78` on the negative real axis; its local error scales as `(h ρ)⁵`.
    pub fn closed_loop_spectral_radius(&self) -> f64 {
        let err = crate::observer::error_system_matrix(
            &self.model,
            &self.observers,
            self.gamma,
            crate::observer::ConsensusSign::Eq19,
        );
        crate::linalg::spectral_radius(&self.model.a).max(crate::linalg::spectral_radius(&err))
    }

    /// Time of RK4 step `k` with step `h`: `k / (1/h)` when `1/h` is an integer (so that grid times print
    /// exactly, e.g. `0.3`), `k h` otherwise.
    pub fn time_of_step(k: usize, h: f64) -> f64 {
        let inv = 1.0 / h;
        let r = inv.round();
        if r >= 1.0 && (inv - r).abs() <= 1e-9 * r {
            k as f64 / r
        } else {
            k as f64 * h
        }
    }

    /// Centroid error `‖p_c − p_c*(t)‖` of a true state.
    pub fn centroid_error(&self, t: f64, x: &DVector<f64>) -> f64 {
        let pc = self.centroid(x);
        (pc - self.model.centroid_reference(t)).norm()
    }

    /// Centroid `p_c` of a true state.
    pub fn centroid(&self, x: &DVector<f64>) -> Vector2<f64> {
        let n = self.n();
        let mut pc = Vector2::zeros();
        for i in 0..n {
            pc += Vector2::new(x[2 * i], x[2 * i + 1]);
        }
        pc / n as f64
    }

    /// Formation error `sqrt(Σ_{i<j, (𝓛_f)_ij ≠ 0} ‖p_i − p_j − (p_i* − p_j*)‖²)`.
    pub fn formation_error(&self, x: &DVector<f64>) -> f64 {
        let n = self.n();
        let ps = &self.model.p_star;
        let mut acc = 0.0;
        for i in 0..n {
            for j in (i + 1)..n {
                if self.model.l_f[(i, j)] < 0.0 {
                    for c in 0..2 {
                        let e = x[2 * i + c] - x[2 * j + c] - (ps[2 * i + c] - ps[2 * j + c]);
                        acc += e * e;
                    }
                }
            }
        }
        acc.sqrt()
    }
}
