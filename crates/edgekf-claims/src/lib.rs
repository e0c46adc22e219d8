//! # edgekf-claims — the papers' claims as data, settled by the data
//!
//! Every quantitative or checkable qualitative claim of the papers this project reproduces —
//! van der Marel & Rajan (EUSIPCO 2022), van der Marel's thesis (2021, chapters 3–6), Guo et
//! al. (IFAC 2020) — and the README's own findings, each as a [`Claim`]: where the paper says
//! it, what it says, the paper's value, the [`study`] it is measured on (a shipped reproduction,
//! possibly edited), the [`Statistic`] and the [`Rule`] that turns the measurement into a
//! [`Verdict`]. [`evaluate`] runs each study once (claims share simulations) and judges every
//! claim; [`Outcome::record`] is the row the CLI prints and writes as `claims.json`.
//!
//! Standard errors come from independent Monte Carlo runs (or seeds), comparisons between
//! estimators are paired over the same runs, and deterministic quantities are compared exactly
//! (see [`stats`]).
//!
//! It is its own crate because it needs both libraries: the filter engine (`edgekf`) and the
//! distributed SLAM observer (`edgekf-slam`), which share no code and should not depend on each
//! other; like them it is pure computation (no files, no printing), so the CLI and the tests use
//! it alike.
//!
//! ```
//! let claims = edgekf_claims::registry::claims();
//! assert!(claims.len() >= 50);
//! let one: Vec<_> = claims.into_iter().filter(|c| c.id == "guo-6-omega-positive").collect();
//! let out = edgekf_claims::evaluate(&one, edgekf_claims::Options::default(), &edgekf_claims::Silent)
//!     .unwrap();
//! assert_eq!(out[0].verdict, edgekf_claims::Verdict::Agrees);
//! ```
#![warn(missing_docs)]

pub mod readme;
pub mod registry;
pub mod rule;
pub mod statistic;
pub mod stats;
pub mod study;

use std::collections::BTreeMap;

use edgekf::sim::{Observer, Quiet};
use serde::Serialize;

pub use rule::{Rule, Verdict};
pub use statistic::Statistic;
pub use stats::Estimate;
pub use study::{Data, Size, Study};

/// Why the claims could not be evaluated (a bad name, or a bug in the registry).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ClaimsError {
    /// No reproduction of that name.
    #[error("unknown reproduction `{0}`; `edgekf reproduce --list` prints the names")]
    UnknownReproduction(String),
    /// A claim names a study that does not exist.
    #[error("claim `{claim}` uses the unknown study `{study}`")]
    UnknownStudy {
        /// The claim.
        claim: String,
        /// The study.
        study: String,
    },
    /// A study's edited scenario does not check.
    #[error("study `{study}`: {message}")]
    Scenario {
        /// The study.
        study: String,
        /// What is wrong.
        message: String,
    },
    /// The observer asked to stop.
    #[error("the run was cancelled")]
    Cancelled,
}

/// The paper a claim comes from (`paper = "eusipco"` … in a claims file: the variant's name in
/// snake case).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Paper {
    /// van der Marel & Rajan, EUSIPCO 2022.
    Eusipco,
    /// van der Marel, MSc thesis, TU Delft 2021.
    Thesis,
    /// Guo, Jayawardhana, Lee & Shim, IFAC 2020.
    Guo,
    /// Li & Rajan, IEEE OJCSYS 2026 (GA-RKF; its claims join when GA-RKF is built).
    LiRajan,
    /// This project's README (its own measured statements).
    Project,
}

impl Paper {
    /// The name used in outputs.
    pub fn name(self) -> &'static str {
        match self {
            Paper::Eusipco => "EUSIPCO 2022",
            Paper::Thesis => "thesis 2021",
            Paper::Guo => "Guo et al. 2020",
            Paper::LiRajan => "Li & Rajan 2026",
            Paper::Project => "edgekf README",
        }
    }
}

/// How a claim's number is obtained.
#[derive(Debug, Clone, PartialEq)]
pub enum Measure {
    /// A statistic of one study.
    On {
        /// The study's id.
        study: &'static str,
        /// The statistic.
        stat: Statistic,
    },
    /// The quotient of two independent measurements (relative errors in quadrature).
    Quotient(Box<Measure>, Box<Measure>),
    /// Nothing to measure (the rule says why).
    Nothing,
}

impl Measure {
    /// A statistic of one study.
    pub fn on(study: &'static str, stat: Statistic) -> Self {
        Measure::On { study, stat }
    }

    fn studies(&self, out: &mut Vec<&'static str>) {
        match self {
            Measure::On { study, .. } => {
                if !out.contains(study) {
                    out.push(study);
                }
            }
            Measure::Quotient(a, b) => {
                a.studies(out);
                b.studies(out);
            }
            Measure::Nothing => {}
        }
    }

    fn eval(&self, data: &BTreeMap<&'static str, Data>) -> statistic::Measured {
        match self {
            Measure::On { study, stat } => {
                let d = data.get(study).ok_or("its study did not run")?;
                stat.eval(d)
            }
            Measure::Quotient(a, b) => {
                let (x, nx) = a.eval(data)?;
                let (y, ny) = b.eval(data)?;
                let note = match (nx, ny) {
                    (None, None) => None,
                    (p, q) => Some(format!(
                        "{} / {}",
                        p.unwrap_or_default(),
                        q.unwrap_or_default()
                    )),
                };
                let note = note.or(Some(format!(
                    "{} ± {} over {} ± {}",
                    rule::num(x.value),
                    rule::num(x.se),
                    rule::num(y.value),
                    rule::num(y.se)
                )));
                Ok((stats::quotient(x, y), note))
            }
            Measure::Nothing => Err("nothing to measure".into()),
        }
    }

    /// The measurement in words.
    pub fn describe(&self) -> String {
        match self {
            Measure::On { study, stat } => format!("{} (study `{study}`)", stat.describe()),
            Measure::Quotient(a, b) => format!("[{}] / [{}]", a.describe(), b.describe()),
            Measure::Nothing => "—".into(),
        }
    }
}

/// One claim of a paper, as data.
#[derive(Debug, Clone, PartialEq)]
pub struct Claim {
    /// Stable id, `<source>-<section or figure>-<slug>` (the source followed by a digit).
    pub id: &'static str,
    /// The paper.
    pub paper: Paper,
    /// Where the paper says it ("thesis §4.5, Fig. 4.9").
    pub location: &'static str,
    /// What it says.
    pub statement: &'static str,
    /// The paper's value or ordering, in words.
    pub paper_value: &'static str,
    /// The reproduction it belongs to (`edgekf reproduce --list`).
    pub reproduction: &'static str,
    /// How it is measured.
    pub measure: Measure,
    /// When it agrees.
    pub rule: Rule,
    /// Whether its verdict is already settled at [`Size::Reduced`] (checked by `cargo test`).
    pub small: bool,
}

/// A judged claim.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The claim.
    pub claim: Claim,
    /// The measurement, if any.
    pub estimate: Option<Estimate>,
    /// The verdict.
    pub verdict: Verdict,
    /// Why it is not checkable.
    pub reason: Option<String>,
    /// Sub-results worth showing (e.g. each estimator's time to the floor).
    pub note: Option<String>,
}

/// The row of `claims.json`: exactly these keys.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Record {
    /// Claim id.
    pub id: String,
    /// The paper.
    pub paper: String,
    /// Where in the paper.
    #[serde(rename = "where")]
    pub location: String,
    /// The statement.
    pub claim: String,
    /// The paper's value or ordering.
    pub paper_value: String,
    /// Our value (null when not checkable).
    pub value: Option<f64>,
    /// Its standard error (0: exact; null: none).
    pub se: Option<f64>,
    /// `agrees`, `differs` or `not checkable`.
    pub verdict: Verdict,
}

impl Outcome {
    /// The `claims.json` row.
    pub fn record(&self) -> Record {
        let finite = |x: f64| x.is_finite().then_some(x);
        Record {
            id: self.claim.id.into(),
            paper: self.claim.paper.name().into(),
            location: self.claim.location.into(),
            claim: self.claim.statement.into(),
            paper_value: self.claim.paper_value.into(),
            value: self.estimate.and_then(|e| finite(e.value)),
            se: self.estimate.and_then(|e| finite(e.se)),
            verdict: self.verdict,
        }
    }
}

/// How to evaluate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Options {
    /// Full (the papers' size) or reduced (tests).
    pub size: Size,
    /// Seeds per filter study at full size (default: each study's own).
    pub seeds: Option<usize>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            size: Size::Full,
            seeds: None,
        }
    }
}

/// Progress hooks (the library never prints).
pub trait Hooks: Sync {
    /// The engine's observer (progress, cancellation).
    fn observer(&self) -> &dyn Observer;
    /// A study starts.
    fn study_start(&self, _study: &Study) {}
    /// A study is done.
    fn study_done(&self, _study: &Study) {}
}

/// Hooks that ignore everything.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Hooks for Silent {
    fn observer(&self) -> &dyn Observer {
        &Quiet
    }
}

/// The studies `claims` need, in run order.
///
/// # Errors
/// [`ClaimsError::UnknownStudy`] when a claim names a study that does not exist.
pub fn needed_studies(claims: &[Claim]) -> Result<Vec<Study>, ClaimsError> {
    let mut ids = Vec::new();
    for c in claims {
        c.measure.studies(&mut ids);
    }
    let all = study::studies();
    for c in claims {
        let mut mine = Vec::new();
        c.measure.studies(&mut mine);
        for s in mine {
            if !all.iter().any(|x| x.id == s) {
                return Err(ClaimsError::UnknownStudy {
                    claim: c.id.into(),
                    study: s.into(),
                });
            }
        }
    }
    Ok(all.into_iter().filter(|s| ids.contains(&s.id)).collect())
}

/// Runs every study the claims need once and judges each claim.
///
/// # Errors
/// [`ClaimsError`] for a registry bug (unknown study, a scenario that does not check) or a
/// cancelled run.
pub fn evaluate(
    claims: &[Claim],
    opt: Options,
    hooks: &dyn Hooks,
) -> Result<Vec<Outcome>, ClaimsError> {
    let mut data = BTreeMap::new();
    for s in needed_studies(claims)? {
        hooks.study_start(&s);
        let d = s.run(opt.size, opt.seeds, hooks.observer())?;
        hooks.study_done(&s);
        data.insert(s.id, d);
    }
    Ok(claims.iter().map(|c| judge(c, &data)).collect())
}

/// Judges one claim on the studies' data.
pub fn judge(c: &Claim, data: &BTreeMap<&'static str, Data>) -> Outcome {
    let (estimate, note, failure) = match (&c.rule, &c.measure) {
        (Rule::NotCheckable(_), _) | (_, Measure::Nothing) => (None, None, None),
        _ => match c.measure.eval(data) {
            Ok((e, n)) => (Some(e), n, None),
            Err(why) => (None, None, Some(why)),
        },
    };
    let (verdict, reason) = match failure {
        Some(why) => (Verdict::NotCheckable, Some(why)),
        None => c.rule.judge(estimate),
    };
    Outcome {
        claim: c.clone(),
        estimate,
        verdict,
        reason,
        note,
    }
}

/// The claims of the named reproductions (`all`, or none: every claim), in registry order.
///
/// # Errors
/// [`ClaimsError::UnknownReproduction`] for a name that is no reproduction.
pub fn select(names: &[String]) -> Result<Vec<Claim>, ClaimsError> {
    let all = registry::claims();
    if names.is_empty() || names.iter().any(|n| n == "all") {
        return Ok(all);
    }
    for n in names {
        if edgekf_io::reproductions::find(n).is_none() {
            return Err(ClaimsError::UnknownReproduction(n.clone()));
        }
    }
    Ok(all
        .into_iter()
        .filter(|c| names.iter().any(|n| n == c.reproduction))
        .collect())
}

/// The simulation directory a claim's results belong in (`reproduce --out DIR` writes each
/// simulation to `DIR/<simulation>`).
pub fn simulation_of(c: &Claim) -> &'static str {
    edgekf_io::reproductions::find(c.reproduction).map_or("claims", |e| e.simulation())
}
