//! Statistics: how a claim's number is computed from a study's per-run results.
//!
//! Windows are in seconds of simulated time and include both ends (every reported step `k`
//! with `a ≤ k·Δt ≤ b`). A *unit* is one Monte Carlo run (runs of all seeds pooled: every run has
//! its own random stream); per-seed statistics use the seeds as units. See [`crate::stats`]
//! for the standard errors.

use edgekf::design::checks::{CheckReport, Trilateration};
use edgekf::design::{self, generators, Method};
use edgekf::scenario::Scenario;
use edgekf::sim::Results;
use edgekf_slam::linalg::observable_dimension;
use edgekf_slam::observer::printed_care;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Deserializer};

use crate::stats::{self, Estimate};
use crate::study::Data;

/// A time window `[from, to]` in seconds. A *window mean* is the time average over the window's
/// reported steps: each report weighted by the time since the previous report, so that the
/// log-spaced reports of a transient do not outweigh the evenly spaced ones after it.
pub type Window = (f64, f64);

/// The first reported step (k = 1); `"first"` in the claims files.
pub const FIRST: Window = (0.0, 0.001);

/// Steady state for the estimation error and the covariance, 15–30 s (the filters' floors are
/// reached within a second); `"steady"` in the claims files.
pub const STEADY: Window = (15.0, 30.0);

/// The floor of the Procrustes error, 25–30 s (the formation converges at ≈ 0.44 /s);
/// `"floor"` in the claims files.
pub const FLOOR: Window = (25.0, 30.0);

/// The transient, 0.5–4 s; `"early"` in the claims files.
pub const EARLY: Window = (0.5, 4.0);

/// A GA-RKF run of 60 s after its first reports (ψ is undefined before them); `"whole"` in the
/// claims files.
pub const WHOLE: Window = (0.5, 60.0);

/// The windows the claims files name.
pub const NAMED_WINDOWS: [(&str, Window); 5] = [
    ("first", FIRST),
    ("steady", STEADY),
    ("floor", FLOOR),
    ("early", EARLY),
    ("whole", WHOLE),
];

/// Reads a window of a claims file: `[from, to]` in seconds, or one of [`NAMED_WINDOWS`].
fn window<'de, D: Deserializer<'de>>(d: D) -> Result<Window, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Given {
        Named(String),
        Span(f64, f64),
    }
    match Given::deserialize(d)? {
        Given::Span(a, b) => Ok((a, b)),
        Given::Named(n) => NAMED_WINDOWS
            .iter()
            .find(|(name, _)| *name == n)
            .map(|(_, w)| *w)
            .ok_or_else(|| {
                serde::de::Error::custom(format!(
                    "unknown window `{n}`: [from, to] in seconds, or one of first, steady, floor, early, whole"
                ))
            }),
    }
}

/// A statistic of one study. In a claims file (`claims/*.toml`) it is a table with one key, the
/// variant's name in snake case (`stat.ratio = { metric = "est_error", num = "crkf", den =
/// "jrkf", window = "steady" }`); windows are `[from, to]` or a name of [`NAMED_WINDOWS`].
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Statistic {
    /// Mean over runs of the per-run window mean of `metric` of `label`.
    Mean {
        /// Estimator label.
        label: &'static str,
        /// Metric name.
        metric: &'static str,
        /// Window.
        #[serde(deserialize_with = "window")]
        window: Window,
    },
    /// `num / den`: ratio of the window means of `metric` of two estimators, paired over runs.
    Ratio {
        /// Metric.
        metric: &'static str,
        /// Numerator estimator.
        num: &'static str,
        /// Denominator estimator.
        den: &'static str,
        /// Window.
        #[serde(deserialize_with = "window")]
        window: Window,
    },
    /// Ratio of the window means of two metrics of one estimator, paired over runs (e.g. the
    /// consistency ratio `est_error_sq / cov_trace`).
    MetricRatio {
        /// Estimator.
        label: &'static str,
        /// Numerator metric.
        num: &'static str,
        /// Denominator metric.
        den: &'static str,
        /// Window.
        #[serde(deserialize_with = "window")]
        window: Window,
    },
    /// Ratio of one estimator's window means of `metric` over two windows, paired over runs.
    WindowRatio {
        /// Estimator.
        label: &'static str,
        /// Metric.
        metric: &'static str,
        /// Numerator window.
        #[serde(deserialize_with = "window")]
        num: Window,
        /// Denominator window.
        #[serde(deserialize_with = "window")]
        den: Window,
    },
    /// The paired ratio `num/den` in window `first` over the same ratio in window `second`
    /// (jackknife over runs): 1 when the gap between two estimators is constant.
    GapRatio {
        /// Metric.
        metric: &'static str,
        /// Numerator estimator.
        num: &'static str,
        /// Denominator estimator.
        den: &'static str,
        /// First window.
        #[serde(deserialize_with = "window")]
        first: Window,
        /// Second window.
        #[serde(deserialize_with = "window")]
        second: Window,
    },
    /// Exponential decay rate `ln(v(a)/v(b)) / (b − a)` of each run's `metric`, mean over runs
    /// (values at the first reported steps at or after `a` and `b`).
    DecayRate {
        /// Estimator.
        label: &'static str,
        /// Metric.
        metric: &'static str,
        /// `(a, b)`.
        #[serde(deserialize_with = "window")]
        window: Window,
    },
    /// Ratio of the decay rates over two windows, paired over runs (1: a pure exponential).
    DecayRateRatio {
        /// Estimator.
        label: &'static str,
        /// Metric.
        metric: &'static str,
        /// Numerator window.
        #[serde(deserialize_with = "window")]
        first: Window,
        /// Denominator window.
        #[serde(deserialize_with = "window")]
        second: Window,
    },
    /// Ratio of the across-run standard deviations of `metric` (time average over the window's
    /// reported steps of the standard deviation at each), jackknife over runs.
    StdRatio {
        /// Metric.
        metric: &'static str,
        /// Numerator estimator.
        num: &'static str,
        /// Denominator estimator.
        den: &'static str,
        /// Window.
        #[serde(deserialize_with = "window")]
        window: Window,
    },
    /// The largest value of the mean curve of `metric` in `window` over its value at the first
    /// reported step (> 1: the mean error grows before it falls), jackknife over runs.
    PeakOverStart {
        /// Estimator.
        label: &'static str,
        /// Metric.
        metric: &'static str,
        /// Window.
        #[serde(deserialize_with = "window")]
        window: Window,
    },
    /// Largest over smallest window mean of `metric` among `labels`, jackknife over runs.
    Spread {
        /// Estimators.
        labels: Vec<&'static str>,
        /// Metric.
        metric: &'static str,
        /// Window.
        #[serde(deserialize_with = "window")]
        window: Window,
    },
    /// Per seed, the time at which the mean curve of `metric` first falls within `tol`
    /// (relative) of its floor (its mean over `floor`), for each of `labels`; the value is the
    /// last label's time minus the first's (seconds), with the standard error over seeds.
    TimeToFloor {
        /// Estimators (the first and last are compared; all are reported).
        labels: Vec<&'static str>,
        /// Metric.
        metric: &'static str,
        /// Floor window.
        #[serde(deserialize_with = "window")]
        floor: Window,
        /// Relative tolerance.
        tol: f64,
    },
    /// The AR(1) (Yule–Walker) coefficient `a₁ = r(1)/r(0)` of the inputs in the closed loop of
    /// `label`, pooled over agents, runs and steps, averaged over the coordinates (minus that of
    /// `minus`'s loop, if given); per seed, with the standard error over seeds.
    InputAr1 {
        /// Estimator.
        label: &'static str,
        /// Subtract this loop's coefficient (paired by seed).
        minus: Option<&'static str>,
    },
    /// The largest over `nums` of the inputs' step-to-step roughness `E|u_k − u_{k−1}|² =
    /// 2(r(0) − r(1))` relative to that of `den`; per seed, standard error over seeds.
    InputRoughness {
        /// Numerator estimators (the roughest counts).
        nums: Vec<&'static str>,
        /// Denominator estimator.
        den: &'static str,
    },
    /// The largest absolute difference of any per-run value of any metric at any reported step
    /// between two estimators (0: bit for bit the same).
    MaxAbsDifference {
        /// First estimator.
        a: &'static str,
        /// Second estimator.
        b: &'static str,
    },
    /// `(max − min) / mean` of the mean curve of `metric` over all reported steps.
    RelativeRange {
        /// Estimator.
        label: &'static str,
        /// Metric.
        metric: &'static str,
    },
    /// Li & Rajan's Theorem 1 on the agents' means: the largest, over the reported steps in
    /// `window`, of `E[ψ_k] / (c̄·E[δ_k] + b̄)` (means over runs of the `psi` and
    /// `tracking_error` metrics; `c̄`, `b̄` the agents' means of (20a–b) on the nominal graph,
    /// [`Scenario::theorem1_means`]). Below 1 where the bound holds; jackknife over runs.
    Theorem1 {
        /// Estimator (a `garkf`).
        label: &'static str,
        /// Window (start after the first ψ: ψ is undefined before it).
        #[serde(deserialize_with = "window")]
        window: Window,
    },
    /// The share of runs that stay stable (Li & Rajan Fig. 13; the rule of a sweep's `stable`,
    /// [`edgekf::sim::sweep::stable_runs`]): δ finite at every report and its mean over `last`
    /// at most `factor` times its mean over `reference`. Mean of the per-run 0/1 values.
    StableShare {
        /// Estimator.
        label: &'static str,
        /// The reference window (before the failures).
        #[serde(deserialize_with = "window")]
        reference: Window,
        /// The final window.
        #[serde(deserialize_with = "window")]
        last: Window,
        /// The allowed growth.
        factor: f64,
    },
    /// The largest of several statistics of the same study (conservative for a `Below` rule).
    Max(Vec<Statistic>),
    /// Structural numbers of a checked filter scenario (no simulation).
    Model(ModelStat),
    /// Numbers of the SLAM observer (deterministic).
    Slam(SlamStat),
}

/// Structural numbers of a filter scenario (`stat.model = "mean_degree"` in a claims file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelStat {
    /// The stress's smallest nonzero eigenvalue if the framework is universally rigid (PSD,
    /// rank `N − D − 1`) and its graph a D-trilateration graph, else 0.
    UniversallyRigid,
    /// The thesis SDP (3.5) (best-conditioned form) on the framework's links: `λ_min/λ_max`
    /// of the designed stress (> 0: a solution exists), 0 when it fails.
    SdpSolution,
    /// `Δt · c · λ_max(L_ff)` (the discrete loop is stable below 2).
    StepBound,
    /// Smallest eigenvalue of the agents' disturbance covariance `Q_A` (Mercer: ≥ 0).
    QaMinEigenvalue,
    /// Largest off-diagonal entry of `Q` over its diagonal entry σ_w² (EUSIPCO: in [0, 1]).
    QOffDiagonalMax,
    /// Mean degree of the graph, `2|E|/N`.
    MeanDegree,
}

/// Numbers of the SLAM observer and its run (`stat.slam = "omega"` in a claims file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SlamStat {
    /// `λ_min Ω(∞)` of (24) with the corrected `−1/δ` (sup over δ).
    Omega,
    /// `sup_{δ,τ} ζ_min(γλ_min − 1/(2τ)) − γ²ξ²/4` of (25).
    Condition25,
    /// `λ_min` of `diag(W_iᵀ)(𝓛_c ⊗ I)diag(W_i)` (Lee & Shim: positive definite).
    LeeShim,
    /// Spectral abscissa of the error system (21).
    ErrorAbscissa,
    /// The same with eq. (10)'s consensus sign.
    ErrorAbscissaEq10,
    /// Unobservable directions of the reduced pairs `(Ā_i¹¹, H̄_i)`, summed over robots.
    ReducedUnobservable,
    /// Fewest unobservable directions of `(A, H_i)` over robots.
    RobotUnobservable,
    /// Unobservable directions of `(A, H)` with every robot's measurements.
    CollectiveUnobservable,
    /// Hamiltonian eigenvalues on the imaginary axis of the CARE (20) as printed
    /// (`Ḡ_i = Z_iᵀ G`), summed over robots (0 is needed for a stabilising solution).
    PrintedCareOnAxis,
    /// Smallest eigenvalue of `P̄_i` over robots, CARE with the design weight `Z_iᵀ Q Z_i`.
    CareMinEigenvalue,
    /// `V̇_ob − (−eᵀΩ(δ)e + δ‖w‖²)` with eq. (24)'s printed `+1/δ` at `w = δ⁻¹P̄⁻¹e` (δ = 0.7):
    /// > 0 means the bound (26) is violated.
    Eq26PrintedSign,
    /// `est_err_total` at the horizon \[m\].
    FinalEstimationError,
    /// `formation_err` at the horizon \[m\].
    FinalFormationError,
    /// `centroid_err` at the horizon \[m\].
    FinalCentroidError,
    /// The largest error of any robot's estimate of any landmark at the horizon \[m\].
    FinalLandmarkError,
    /// `est_err_total` at the horizon over its peak.
    FinalOverPeak,
}

/// A measured value with an optional note (sub-results), or why it could not be measured.
pub type Measured = Result<(Estimate, Option<String>), String>;

struct Filt<'a> {
    scenario: &'a Scenario,
    results: &'a [Results],
}

fn idx(res: &Results, w: Window) -> Vec<usize> {
    res.steps
        .iter()
        .enumerate()
        .filter(|(_, &k)| {
            let t = k as f64 * res.dt;
            t >= w.0 - 1e-9 && t <= w.1 + 1e-9
        })
        .map(|(i, _)| i)
        .collect()
}

impl Filt<'_> {
    fn values<'b>(res: &'b Results, label: &str, metric: &str) -> Result<&'b [f64], String> {
        res.values(label, metric)
            .ok_or_else(|| format!("no metric `{metric}` of estimator `{label}` in the study"))
    }

    /// Per-unit matrix `[unit][report in window]`, runs of all seeds pooled.
    fn matrix(&self, label: &str, metric: &str, w: Window) -> Result<Vec<Vec<f64>>, String> {
        let mut out = Vec::new();
        for res in self.results {
            let v = Self::values(res, label, metric)?;
            let runs = res.runs.len();
            let ks = idx(res, w);
            if ks.is_empty() {
                return Err(format!("no reported step in {w:?} s"));
            }
            for r in 0..runs {
                out.push(ks.iter().map(|&k| v[k * runs + r]).collect());
            }
        }
        Ok(out)
    }

    /// The time each report of `w` stands for (see [`report_weights`]), one seed's reports; the
    /// same reports for every seed of a study.
    fn weights(&self, w: Window) -> Result<Vec<f64>, String> {
        let res = self.results.first().ok_or("the study has no results")?;
        Ok(report_weights(res, &idx(res, w)))
    }

    /// Per-unit window means, each report weighted by the time it stands for, so that a window
    /// mean is a time average whatever the spacing of the reports (log-spaced early reports
    /// would otherwise dominate a transient window).
    fn units(&self, label: &str, metric: &str, w: Window) -> Result<Vec<f64>, String> {
        let wt = self.weights(w)?;
        let total: f64 = wt.iter().sum();
        Ok(self
            .matrix(label, metric, w)?
            .iter()
            .map(|row| row.iter().zip(&wt).map(|(x, a)| x * a).sum::<f64>() / total)
            .collect())
    }

    /// Per-unit value at the first reported step at or after `t`.
    fn at(&self, label: &str, metric: &str, t: f64) -> Result<Vec<f64>, String> {
        let mut out = Vec::new();
        for res in self.results {
            let v = Self::values(res, label, metric)?;
            let runs = res.runs.len();
            let k = res
                .steps
                .iter()
                .position(|&k| k as f64 * res.dt >= t - 1e-9)
                .ok_or_else(|| format!("no reported step at {t} s"))?;
            out.extend_from_slice(&v[k * runs..(k + 1) * runs]);
        }
        Ok(out)
    }

    /// The mean curve over runs of one seed.
    fn curve(res: &Results, label: &str, metric: &str) -> Result<Vec<f64>, String> {
        let v = Self::values(res, label, metric)?;
        let runs = res.runs.len();
        Ok((0..res.steps.len())
            .map(|k| v[k * runs..(k + 1) * runs].iter().sum::<f64>() / runs as f64)
            .collect())
    }

    fn acov(res: &Results, label: &str) -> Result<Vec<(f64, f64)>, String> {
        let e = res
            .estimators
            .iter()
            .position(|e| e.label == label)
            .ok_or_else(|| format!("no estimator `{label}` in the study"))?;
        let a = res
            .input_acov
            .get(e)
            .ok_or("the study did not record the inputs' autocovariance")?;
        Ok(a.iter().map(|r| (r[0], r[1])).collect())
    }

    fn per_seed(&self, f: impl Fn(&Results) -> Result<f64, String>) -> Result<Vec<f64>, String> {
        self.results.iter().map(f).collect()
    }
}

/// The time each report in `ks` (indices into `res.steps`) stands for: from the previous report
/// (or from t = 0 for the first) to its own time. Evenly spaced reports get equal weights, so a
/// window of them gives the plain mean.
fn report_weights(res: &Results, ks: &[usize]) -> Vec<f64> {
    ks.iter()
        .map(|&i| {
            let prev = if i == 0 { 0 } else { res.steps[i - 1] };
            (res.steps[i] - prev) as f64 * res.dt
        })
        .collect()
}

fn mean_of(rows: &[Vec<f64>], units: &[usize], k: usize) -> f64 {
    units.iter().map(|&u| rows[u][k]).sum::<f64>() / units.len() as f64
}

fn std_of(rows: &[Vec<f64>], units: &[usize], k: usize) -> f64 {
    let m = mean_of(rows, units, k);
    (units.iter().map(|&u| (rows[u][k] - m).powi(2)).sum::<f64>() / (units.len() as f64 - 1.0))
        .sqrt()
}

fn ms(x: f64) -> String {
    format!("{:.0} ms", x * 1e3)
}

impl Statistic {
    /// Evaluates the statistic on a study's data.
    pub fn eval(&self, data: &Data) -> Measured {
        match (self, data) {
            (Statistic::Model(m), Data::Model { scenario }) => model(*m, scenario),
            (
                Statistic::Slam(s),
                Data::Slam {
                    scenario,
                    trajectory,
                },
            ) => Ok((Estimate::exact(slam(*s, scenario, trajectory)), None)),
            (Statistic::Max(list), _) => {
                let mut best: Option<(Estimate, Option<String>)> = None;
                let mut notes = Vec::new();
                for s in list {
                    let (e, _) = s.eval(data)?;
                    notes.push(crate::rule::num(e.value));
                    if best.as_ref().is_none_or(|(b, _)| e.value > b.value) {
                        best = Some((e, None));
                    }
                }
                let (e, _) = best.ok_or("an empty maximum")?;
                Ok((e, Some(format!("each: {}", notes.join(", ")))))
            }
            (
                s,
                Data::Filters {
                    scenario, results, ..
                },
            ) => s.eval_filters(&Filt { scenario, results }),
            _ => Err("the statistic does not apply to this study's kind".into()),
        }
    }

    /// A statistic of filter runs: each variant is one method of [`Filt`].
    fn eval_filters(&self, f: &Filt<'_>) -> Measured {
        let plain = |e: Estimate| Ok((e, None));
        match *self {
            Statistic::Mean {
                label,
                metric,
                window,
            } => plain(stats::mean(&f.units(label, metric, window)?)),
            Statistic::Ratio {
                metric,
                num,
                den,
                window,
            } => plain(f.paired(num, metric, window, den, metric, window)?),
            Statistic::MetricRatio {
                label,
                num,
                den,
                window,
            } => plain(f.paired(label, num, window, label, den, window)?),
            Statistic::WindowRatio {
                label,
                metric,
                num,
                den,
            } => plain(f.paired(label, metric, num, label, metric, den)?),
            Statistic::GapRatio {
                metric,
                num,
                den,
                first,
                second,
            } => f.gap_ratio(metric, (num, den), first, second),
            Statistic::DecayRate {
                label,
                metric,
                window,
            } => plain(stats::mean(&f.decay_rates(label, metric, window)?)),
            Statistic::DecayRateRatio {
                label,
                metric,
                first,
                second,
            } => f.decay_rate_ratio(label, metric, first, second),
            Statistic::StdRatio {
                metric,
                num,
                den,
                window,
            } => plain(f.std_ratio(metric, num, den, window)?),
            Statistic::PeakOverStart {
                label,
                metric,
                window,
            } => plain(f.peak_over_start(label, metric, window)?),
            _ => self.eval_filters_rest(f),
        }
    }

    /// [`Statistic::eval_filters`] for the statistics that are not window means.
    fn eval_filters_rest(&self, f: &Filt<'_>) -> Measured {
        let plain = |e: Estimate| Ok((e, None));
        match self {
            Statistic::Spread {
                labels,
                metric,
                window,
            } => f.spread(labels, metric, *window),
            Statistic::TimeToFloor {
                labels,
                metric,
                floor,
                tol,
            } => f.time_to_floor(labels, metric, *floor, *tol),
            Statistic::InputAr1 { label, minus } => f.input_ar1(label, *minus),
            Statistic::InputRoughness { nums, den } => plain(f.input_roughness(nums, den)?),
            Statistic::MaxAbsDifference { a, b } => f.max_abs_difference(a, b),
            Statistic::RelativeRange { label, metric } => plain(f.relative_range(label, metric)?),
            Statistic::Theorem1 { label, window } => f.theorem1(label, *window),
            Statistic::StableShare {
                label,
                reference,
                last,
                factor,
            } => plain(f.stable_share(label, *reference, *last, *factor)?),
            _ => Err("the statistic does not apply to a filter study".into()),
        }
    }

    /// The statistic in words.
    pub fn describe(&self) -> String {
        match self {
            Statistic::DecayRate {
                label,
                metric,
                window,
            } => format!(
                "decay rate of `{metric}` of {label} between {} and {} s [1/s], mean over runs",
                window.0, window.1
            ),
            Statistic::InputAr1 { label, minus } => match minus {
                None => format!("AR(1) coefficient a₁ of the inputs in the {label} loop, per seed"),
                Some(m) => format!(
                    "AR(1) coefficient a₁ of the inputs, {label} loop minus {m} loop, per seed"
                ),
            },
            Statistic::InputRoughness { nums, den } => format!(
                "input roughness E|u_k − u_(k−1)|² of {} over {den}'s (largest), per seed",
                nums.join(", ")
            ),
            Statistic::MaxAbsDifference { a, b } => {
                format!("largest |difference| of any per-run value, {a} vs {b}")
            }
            Statistic::RelativeRange { label, metric } => {
                format!("(max − min)/mean of the mean `{metric}` of {label} over time")
            }
            Statistic::Max(list) => format!(
                "largest of: {}",
                list.iter()
                    .map(Statistic::describe)
                    .collect::<Vec<_>>()
                    .join("; ")
            ),
            Statistic::StableShare {
                label,
                reference,
                last,
                factor,
            } => format!(
                "share of runs of {label} whose δ stays finite and ends (mean over {}–{} s) at most {factor}× its mean over {}–{} s",
                last.0, last.1, reference.0, reference.1
            ),
            Statistic::Model(m) => m.describe().into(),
            Statistic::Slam(s) => s.describe().into(),
            _ => self.describe_windowed(),
        }
    }

    /// [`Statistic::describe`] for the statistics over windows of reports.
    fn describe_windowed(&self) -> String {
        match self {
            Statistic::Mean {
                label,
                metric,
                window,
            } => format!("mean of `{metric}` of {label} {}", over(window)),
            Statistic::Ratio {
                metric,
                num,
                den,
                window,
            } => format!(
                "{num}/{den} of `{metric}` {}, paired over runs",
                over(window)
            ),
            Statistic::MetricRatio {
                label,
                num,
                den,
                window,
            } => format!(
                "`{num}`/`{den}` of {label} {}, paired over runs",
                over(window)
            ),
            Statistic::WindowRatio {
                label,
                metric,
                num,
                den,
            } => format!(
                "`{metric}` of {label} {} over {}, paired over runs",
                over(num),
                over(den)
            ),
            Statistic::GapRatio {
                metric,
                num,
                den,
                first,
                second,
            } => format!(
                "{num}/{den} of `{metric}` {} over the same {}, jackknife over runs",
                over(first),
                over(second)
            ),
            Statistic::DecayRateRatio {
                label,
                metric,
                first,
                second,
            } => format!(
                "decay rate of `{metric}` of {label} {} over that {}, paired over runs",
                over(first),
                over(second)
            ),
            _ => self.describe_windowed_rest(),
        }
    }

    /// [`Statistic::describe_windowed`], continued.
    fn describe_windowed_rest(&self) -> String {
        match self {
            Statistic::StdRatio {
                metric,
                num,
                den,
                window,
            } => format!(
                "{num}/{den} of the across-run std of `{metric}` {}, jackknife over runs",
                over(window)
            ),
            Statistic::PeakOverStart {
                label,
                metric,
                window,
            } => format!(
                "peak of the mean `{metric}` of {label} {} over its start, jackknife over runs",
                over(window)
            ),
            Statistic::Spread {
                labels,
                metric,
                window,
            } => format!(
                "largest/smallest mean `{metric}` among {} {}, jackknife over runs",
                labels.join(", "),
                over(window)
            ),
            Statistic::TimeToFloor {
                labels,
                metric,
                floor,
                tol,
            } => format!(
                "time for the mean `{metric}` to come within {:.0} % of its floor ({}), {} minus {} [s], per seed",
                tol * 100.0,
                over(floor),
                labels[labels.len() - 1],
                labels[0]
            ),
            Statistic::Theorem1 { label, window } => format!(
                "largest E[ψ]/(c̄·E[δ] + b̄) of {label} {} (Theorem 1 holds below 1)",
                over(window)
            ),
            _ => unreachable!("describe handles the other statistics"),
        }
    }
}

/// A window in words: `at the first step` or `over a–b s`.
fn over(w: &Window) -> String {
    if *w == FIRST {
        "at the first step".to_string()
    } else {
        format!("over {}–{} s", w.0, w.1)
    }
}

/// The statistics of filter runs, one method per [`Statistic`] that is not a plain window mean.
impl Filt<'_> {
    /// The ratio of the window means of (`a`, `ma`, `wa`) and (`b`, `mb`, `wb`), paired over
    /// units.
    fn paired(
        &self,
        a: &str,
        ma: &str,
        wa: Window,
        b: &str,
        mb: &str,
        wb: Window,
    ) -> Result<Estimate, String> {
        Ok(stats::ratio(
            &self.units(a, ma, wa)?,
            &self.units(b, mb, wb)?,
        ))
    }

    fn gap_ratio(
        &self,
        metric: &str,
        (num, den): (&str, &str),
        first: Window,
        second: Window,
    ) -> Measured {
        let (a1, b1) = (
            self.units(num, metric, first)?,
            self.units(den, metric, first)?,
        );
        let (a2, b2) = (
            self.units(num, metric, second)?,
            self.units(den, metric, second)?,
        );
        let sum = |v: &[f64], u: &[usize]| u.iter().map(|&i| v[i]).sum::<f64>();
        let e = stats::jackknife(a1.len(), |u| {
            (sum(&a1, u) / sum(&b1, u)) / (sum(&a2, u) / sum(&b2, u))
        });
        let r1 = stats::ratio(&a1, &b1);
        let r2 = stats::ratio(&a2, &b2);
        Ok((
            e,
            Some(format!(
                "{num}/{den}: {} ± {} over {first:?} s, {} ± {} over {second:?} s",
                crate::rule::num(r1.value),
                crate::rule::num(r1.se),
                crate::rule::num(r2.value),
                crate::rule::num(r2.se)
            )),
        ))
    }

    /// Per-unit decay rates `ln(v(a)/v(b)) / (b − a)` over `w = (a, b)`.
    fn decay_rates(&self, label: &str, metric: &str, w: Window) -> Result<Vec<f64>, String> {
        let (a, b) = (self.at(label, metric, w.0)?, self.at(label, metric, w.1)?);
        Ok(a.iter()
            .zip(&b)
            .map(|(x, y)| (x / y).ln() / (w.1 - w.0))
            .collect())
    }

    fn decay_rate_ratio(
        &self,
        label: &str,
        metric: &str,
        first: Window,
        second: Window,
    ) -> Measured {
        let (r1, r2) = (
            self.decay_rates(label, metric, first)?,
            self.decay_rates(label, metric, second)?,
        );
        let note = format!(
            "rates {} /s over {first:?} s and {} /s over {second:?} s",
            crate::rule::num(stats::mean(&r1).value),
            crate::rule::num(stats::mean(&r2).value)
        );
        Ok((stats::ratio(&r1, &r2), Some(note)))
    }

    fn std_ratio(
        &self,
        metric: &str,
        num: &str,
        den: &str,
        window: Window,
    ) -> Result<Estimate, String> {
        let (a, b) = (
            self.matrix(num, metric, window)?,
            self.matrix(den, metric, window)?,
        );
        let wt = self.weights(window)?;
        let nk = a[0].len();
        Ok(stats::jackknife(a.len(), |u| {
            let sa: f64 = (0..nk).map(|k| wt[k] * std_of(&a, u, k)).sum();
            let sb: f64 = (0..nk).map(|k| wt[k] * std_of(&b, u, k)).sum();
            sa / sb
        }))
    }

    fn peak_over_start(
        &self,
        label: &str,
        metric: &str,
        window: Window,
    ) -> Result<Estimate, String> {
        let m = self.matrix(label, metric, window)?;
        let s = self.matrix(label, metric, FIRST)?;
        let nk = m[0].len();
        Ok(stats::jackknife(m.len(), |u| {
            let peak = (0..nk)
                .map(|k| mean_of(&m, u, k))
                .fold(f64::NEG_INFINITY, f64::max);
            peak / mean_of(&s, u, 0)
        }))
    }

    fn spread(&self, labels: &[&str], metric: &str, window: Window) -> Measured {
        let u: Vec<Vec<f64>> = labels
            .iter()
            .map(|l| self.units(l, metric, window))
            .collect::<Result<_, _>>()?;
        let means = |idx: &[usize]| -> Vec<f64> {
            u.iter()
                .map(|v| idx.iter().map(|&i| v[i]).sum::<f64>() / idx.len() as f64)
                .collect()
        };
        let e = stats::jackknife(u[0].len(), |idx| {
            let m = means(idx);
            m.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
                / m.iter().cloned().fold(f64::INFINITY, f64::min)
        });
        let all: Vec<usize> = (0..u[0].len()).collect();
        let note = labels
            .iter()
            .zip(means(&all))
            .map(|(l, m)| format!("{l} {}", crate::rule::num(m)))
            .collect::<Vec<_>>()
            .join(", ");
        Ok((e, Some(note)))
    }

    fn time_to_floor(&self, labels: &[&str], metric: &str, floor: Window, tol: f64) -> Measured {
        let time = |res: &Results, l: &str| -> Result<f64, String> {
            let c = Filt::curve(res, l, metric)?;
            let ks = idx(res, floor);
            let fl = ks.iter().map(|&k| c[k]).sum::<f64>() / ks.len() as f64;
            let k = c
                .iter()
                .position(|&v| v <= (1.0 + tol) * fl)
                .ok_or_else(|| format!("`{l}` never reaches its floor"))?;
            Ok(res.steps[k] as f64 * res.dt)
        };
        let mut per_label = Vec::new();
        for l in labels {
            per_label.push(self.per_seed(|r| time(r, l))?);
        }
        let first = &per_label[0];
        let last = &per_label[labels.len() - 1];
        let diff: Vec<f64> = last.iter().zip(first).map(|(a, b)| a - b).collect();
        let note = labels
            .iter()
            .zip(&per_label)
            .map(|(l, t)| format!("{l} {}", ms(stats::mean(t).value)))
            .collect::<Vec<_>>()
            .join(", ");
        Ok((stats::mean(&diff), Some(note)))
    }

    fn input_ar1(&self, label: &str, minus: Option<&str>) -> Measured {
        let a1 = |r: &Results, l: &str, d: Option<usize>| -> Result<f64, String> {
            let a = Filt::acov(r, l)?;
            Ok(match d {
                Some(d) => a[d].1 / a[d].0,
                None => a.iter().map(|(r0, r1)| r1 / r0).sum::<f64>() / a.len() as f64,
            })
        };
        let v = self.per_seed(|r| {
            let x = a1(r, label, None)?;
            Ok(match minus {
                Some(m) => x - a1(r, m, None)?,
                None => x,
            })
        })?;
        let mut notes = Vec::new();
        for l in std::iter::once(label).chain(minus) {
            let (x, y) = (
                stats::mean(&self.per_seed(|r| a1(r, l, Some(0)))?),
                stats::mean(&self.per_seed(|r| a1(r, l, Some(1)))?),
            );
            notes.push(format!(
                "{l} loop: a₁ = {:.3} ± {:.3} (x) / {:.3} ± {:.3} (y)",
                x.value, x.se, y.value, y.se
            ));
        }
        Ok((stats::mean(&v), Some(notes.join("; "))))
    }

    fn input_roughness(&self, nums: &[&str], den: &str) -> Result<Estimate, String> {
        let rough = |r: &Results, l: &str| -> Result<f64, String> {
            let a = Filt::acov(r, l)?;
            Ok(a.iter().map(|(r0, r1)| 2.0 * (r0 - r1)).sum::<f64>())
        };
        let v = self.per_seed(|r| {
            let d = rough(r, den)?;
            let mut m = f64::NEG_INFINITY;
            for n in nums {
                m = m.max(rough(r, n)? / d);
            }
            Ok(m)
        })?;
        Ok(stats::mean(&v))
    }

    fn max_abs_difference(&self, a: &str, b: &str) -> Measured {
        let mut m: f64 = 0.0;
        let (mut count, mut total, mut reduced) = (0usize, 0usize, 0usize);
        let differ = |x: &f64, y: &f64| x.to_bits() != y.to_bits();
        for res in self.results {
            let ea = res.estimator(a).ok_or(format!("no estimator `{a}`"))?;
            let runs = res.runs.len();
            for (name, va) in ea.metrics.iter().zip(&ea.values) {
                let vb = Filt::values(res, b, name)?;
                for (x, y) in va.iter().zip(vb) {
                    total += 1;
                    if differ(x, y) {
                        count += 1;
                        m = m.max((x - y).abs());
                    }
                }
                // The engine's reduction (mean, std over runs) of identical values.
                let (sa, sb) = (
                    edgekf::sim::Series::of(va, runs, res.steps.len()),
                    edgekf::sim::Series::of(vb, runs, res.steps.len()),
                );
                reduced += sa
                    .mean
                    .iter()
                    .zip(&sb.mean)
                    .filter(|(x, y)| differ(x, y))
                    .count()
                    + sa.std
                        .iter()
                        .zip(&sb.std)
                        .filter(|(x, y)| differ(x, y))
                        .count();
            }
        }
        Ok((
            Estimate::exact(m),
            Some(format!(
                "{count} of {total} per-run values differ; {reduced} reduced means and stds differ"
            )),
        ))
    }

    fn relative_range(&self, label: &str, metric: &str) -> Result<Estimate, String> {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        let mut sum = 0.0;
        let mut n = 0.0;
        for res in self.results {
            for v in Filt::curve(res, label, metric)? {
                lo = lo.min(v);
                hi = hi.max(v);
                sum += v;
                n += 1.0;
            }
        }
        Ok(Estimate::exact((hi - lo) / (sum / n)))
    }

    fn theorem1(&self, label: &str, window: Window) -> Measured {
        let def = self
            .scenario
            .estimators()
            .iter()
            .find(|d| d.label() == label)
            .ok_or_else(|| format!("no estimator `{label}` in the study"))?;
        let (c, b) = self
            .scenario
            .theorem1_means(def.samples())
            .ok_or("no agent has a feasible RAL on the nominal graph")?;
        let psi = self.matrix(label, "psi", window)?;
        let delta = self.matrix(label, "tracking_error", window)?;
        let nk = psi[0].len();
        // The worst step; steps where ψ is undefined in some run are left out.
        let e = stats::jackknife(psi.len(), |u| {
            (0..nk)
                .map(|k| mean_of(&psi, u, k) / (c * mean_of(&delta, u, k) + b))
                .filter(|x| x.is_finite())
                .fold(f64::NEG_INFINITY, f64::max)
        });
        Ok((
            e,
            Some(format!(
                "c̄ = {}, b̄ = {} (means over the agents)",
                crate::rule::num(c),
                crate::rule::num(b)
            )),
        ))
    }

    fn stable_share(
        &self,
        label: &str,
        reference: Window,
        last: Window,
        factor: f64,
    ) -> Result<Estimate, String> {
        let rule = edgekf::scenario::StableSpec {
            reference: [reference.0, reference.1],
            final_window: [last.0, last.1],
            factor,
        };
        let mut v = Vec::new();
        for res in self.results {
            v.extend(
                edgekf::sim::sweep::stable_runs(res, label, &rule).ok_or_else(|| {
                    format!("no `tracking_error` of estimator `{label}` in the study")
                })?,
            );
        }
        Ok(stats::mean(&v))
    }
}

impl ModelStat {
    /// In words.
    pub fn describe(self) -> &'static str {
        match self {
            ModelStat::UniversallyRigid => {
                "smallest nonzero stress eigenvalue if universally rigid and 2-trilateration, else 0"
            }
            ModelStat::SdpSolution => "λ_min/λ_max of the stress designed by the SDP (3.5), 0 if none",
            ModelStat::StepBound => "Δt·c·λ_max(L_ff)",
            ModelStat::QaMinEigenvalue => "smallest eigenvalue of Q / σ_w²",
            ModelStat::QOffDiagonalMax => "largest off-diagonal entry of Q over σ_w²",
            ModelStat::MeanDegree => "mean degree 2|E|/N of the graph",
        }
    }
}

impl SlamStat {
    /// In words.
    pub fn describe(self) -> &'static str {
        match self {
            SlamStat::Omega => "λ_min Ω(∞) of (24) with −1/δ",
            SlamStat::Condition25 => "sup over δ, τ of ζ_min(γλ_min − 1/(2τ)) − γ²ξ²/4 (25)",
            SlamStat::LeeShim => "λ_min of diag(W_iᵀ)(𝓛_c ⊗ I)diag(W_i)",
            SlamStat::ErrorAbscissa => "spectral abscissa of the error system (21)",
            SlamStat::ErrorAbscissaEq10 => "spectral abscissa of (21) with eq. (10)'s consensus sign",
            SlamStat::ReducedUnobservable => "unobservable directions of (Ā_i¹¹, H̄_i), summed over robots",
            SlamStat::RobotUnobservable => "fewest unobservable directions of (A, H_i) over robots",
            SlamStat::CollectiveUnobservable => "unobservable directions of (A, [H_1; …; H_n])",
            SlamStat::PrintedCareOnAxis => {
                "imaginary-axis Hamiltonian eigenvalues of the printed CARE (20), summed over robots"
            }
            SlamStat::CareMinEigenvalue => "smallest eigenvalue of P̄_i over robots (design weight Z_iᵀQZ_i)",
            SlamStat::Eq26PrintedSign => {
                "V̇_ob minus the bound (26) with the printed +1/δ at w = δ⁻¹P̄⁻¹e, δ = 0.7"
            }
            SlamStat::FinalEstimationError => "est_err_total at the horizon [m]",
            SlamStat::FinalFormationError => "formation_err at the horizon [m]",
            SlamStat::FinalCentroidError => "centroid_err at the horizon [m]",
            SlamStat::FinalLandmarkError => "largest landmark estimation error at the horizon [m]",
            SlamStat::FinalOverPeak => "est_err_total at the horizon over its peak",
        }
    }
}

fn model(m: ModelStat, sc: &Scenario) -> Measured {
    let fw = sc.framework();
    match m {
        ModelStat::UniversallyRigid => {
            let r = CheckReport::from_framework(fw);
            let tri = matches!(r.trilateration, Trilateration::Yes { .. });
            let v = if r.universally_rigid() && tri {
                r.stress_gap()
            } else {
                0.0
            };
            Ok((
                Estimate::exact(v),
                Some(format!(
                    "rank {} of N − D − 1 = {}, PSD {}, trilateration {}",
                    r.rank,
                    r.expected_rank,
                    r.psd(),
                    tri
                )),
            ))
        }
        ModelStat::SdpSolution => {
            let c = generators::Candidate {
                name: "claims".into(),
                dim: fw.dim(),
                config: (0..fw.agents()).map(|i| fw.point(i).to_vec()).collect(),
                links: fw.graph().links().to_vec(),
                leaders: fw.leaders().to_vec(),
            };
            let v = match design::design(&c, Method::Sdp) {
                Ok(d) => {
                    let ev = d.framework.eigenvalues();
                    d.framework.stress_gap() / ev[ev.len() - 1]
                }
                Err(_) => 0.0,
            };
            Ok((Estimate::exact(v), None))
        }
        ModelStat::StepBound => Ok((Estimate::exact(sc.step_bound()), None)),
        ModelStat::QaMinEigenvalue => {
            let q = sc.model().q();
            let ev = q.clone().symmetric_eigenvalues();
            Ok((Estimate::exact(ev.min() / q[(0, 0)]), None))
        }
        ModelStat::MeanDegree => {
            let links = fw.graph().links().len();
            Ok((
                Estimate::exact(2.0 * links as f64 / fw.agents() as f64),
                Some(format!("{links} links, {} agents", fw.agents())),
            ))
        }
        ModelStat::QOffDiagonalMax => {
            let q = sc.model().q();
            let d = fw.dim();
            let n = fw.agents();
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..n {
                for j in 0..n {
                    if i != j {
                        let v = q[(i * d, j * d)] / q[(i * d, i * d)];
                        lo = lo.min(v);
                        hi = hi.max(v);
                    }
                }
            }
            Ok((
                Estimate::exact(hi),
                Some(format!(
                    "off-diagonal/σ_w² between {} and {}",
                    crate::rule::num(lo),
                    crate::rule::num(hi)
                )),
            ))
        }
    }
}

fn slam(s: SlamStat, sc: &edgekf_slam::Scenario, tr: &edgekf_slam::Trajectory) -> f64 {
    let last = tr.times.len() - 1;
    let model = sc.model();
    match s {
        SlamStat::Omega => sc.theorem1().zeta_sup,
        SlamStat::Condition25 => sc.theorem1().condition25_sup,
        SlamStat::LeeShim => sc.theorem1().lambda_min,
        SlamStat::ErrorAbscissa => sc.theorem1().error_abscissa,
        SlamStat::ErrorAbscissaEq10 => sc.theorem1().error_abscissa_eq10,
        SlamStat::ReducedUnobservable => sc
            .observers()
            .iter()
            .map(|o| (o.a11.nrows() - observable_dimension(&o.a11, &o.h_bar)) as f64)
            .sum(),
        SlamStat::RobotUnobservable => (0..sc.n())
            .map(|i| (model.a.nrows() - observable_dimension(&model.a, &model.h[i])) as f64)
            .fold(f64::INFINITY, f64::min),
        SlamStat::CollectiveUnobservable => {
            let cols = model.a.ncols();
            let rows: usize = model.h.iter().map(|h| h.nrows()).sum();
            let mut h = DMatrix::zeros(rows, cols);
            let mut off = 0;
            for hi in &model.h {
                h.view_mut((off, 0), hi.shape()).copy_from(hi);
                off += hi.nrows();
            }
            (cols - observable_dimension(&model.a, &h)) as f64
        }
        SlamStat::PrintedCareOnAxis => sc
            .observers()
            .iter()
            .map(|o| printed_care(model, o, sc.q()).on_axis as f64)
            .sum(),
        SlamStat::CareMinEigenvalue => sc
            .observers()
            .iter()
            .map(|o| o.care.min_eig)
            .fold(f64::INFINITY, f64::min),
        SlamStat::Eq26PrintedSign => eq26_printed_sign(sc),
        SlamStat::FinalEstimationError => tr.total_error(last),
        SlamStat::FinalFormationError => sc.formation_error(&tr.x[last]),
        SlamStat::FinalCentroidError => sc.centroid_error(tr.times[last], &tr.x[last]),
        SlamStat::FinalLandmarkError => {
            let (n, m) = (sc.n(), sc.m());
            let mut worst: f64 = 0.0;
            for i in 0..n {
                let e = tr.error(last, i);
                for l in 0..m {
                    let k = 2 * (n + l);
                    worst = worst.max((e[k].powi(2) + e[k + 1].powi(2)).sqrt());
                }
            }
            worst
        }
        SlamStat::FinalOverPeak => {
            let peak = (0..=last).map(|k| tr.total_error(k)).fold(0.0, f64::max);
            tr.total_error(last) / peak
        }
    }
}

/// The Lyapunov bound (26) at the equality case of Young's inequality, `w = δ⁻¹P̄⁻¹e`, with
/// (24)'s printed `+1/δ`: `V̇_ob − (−eᵀΩ(δ)e + δ‖w‖²)`, which is `2δ⁻¹‖P̄⁻¹e‖² > 0` (the bound
/// fails) for every `e ≠ 0`; with `−1/δ` it is 0.
fn eq26_printed_sign(sc: &edgekf_slam::Scenario) -> f64 {
    let r = sc.theorem1();
    let blocks: Vec<DMatrix<f64>> = sc
        .observers()
        .iter()
        .map(|o| &o.a11 - &o.k_bar * &o.h_bar)
        .collect();
    let total: usize = blocks.iter().map(|b| b.nrows()).sum();
    let mut f = DMatrix::zeros(total, total);
    let mut off = 0;
    for b in &blocks {
        f.view_mut((off, off), b.shape()).copy_from(b);
        off += b.nrows();
    }
    let delta = 0.7;
    let e = DVector::from_fn(total, |k, _| ((k * 7 + 3) % 11) as f64 / 11.0 - 0.4);
    let w = &r.p_inv * &e / delta;
    let pf = &r.p_inv * &f;
    let vdot = (e.transpose() * (&pf + pf.transpose()) * &e)[0]
        + 2.0 * (e.transpose() * &r.psi * &e)[0]
        + 2.0 * (e.transpose() * &r.p_inv * &w)[0];
    let bound = -(e.transpose() * r.omega(delta, true) * &e)[0] + delta * w.norm_squared();
    vdot - bound
}
