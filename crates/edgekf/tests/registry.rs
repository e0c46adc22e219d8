//! Adding an estimator is one new type plus one registry line: a tiny estimator defined here —
//! an exponential smoother of the measurement means, `x̂ ← x̂ + α (ȳ − x̂)` — runs through the
//! whole engine, with its option checked, its metrics reported and an injected breakdown turned
//! into a typed outcome.

mod common;

use std::sync::Arc;

use edgekf::estimate::{
    options_of, parse_options, Breakdown, Configured, Cost, Estimator, EstimatorKind, Model,
    Options, Registry, Step,
};
use edgekf::scenario::{EstimatorEntry, Scenario};
use edgekf::sim::Outcome;
use serde::{Deserialize, Serialize};

struct SmootherKind;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SmootherOptions {
    alpha: f64,
    /// Step at which to report a breakdown (to test the typed outcome).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fail_at: Option<usize>,
}

impl EstimatorKind for SmootherKind {
    fn name(&self) -> &'static str {
        "smoother"
    }
    fn about(&self) -> &'static str {
        "exponential smoother of the measurement means"
    }
    fn configure(&self, o: &Options, _m: &Model) -> Result<Arc<dyn Configured>, String> {
        let opt: SmootherOptions = parse_options(o)?;
        if !(opt.alpha > 0.0 && opt.alpha <= 1.0) {
            return Err(format!(
                "option `alpha` must lie in (0, 1], got {}",
                opt.alpha
            ));
        }
        Ok(Arc::new(Config(opt)))
    }
}

#[derive(Debug)]
struct Config(SmootherOptions);

impl Configured for Config {
    fn options(&self) -> Options {
        options_of(&self.0)
    }
    fn build(&self, m: &Model, _samples: usize, runs: usize) -> Box<dyn Estimator> {
        Box::new(Smoother {
            alpha: self.0.alpha,
            fail_at: self.0.fail_at,
            x: vec![0.0; m.num_edges() * m.dim() * runs],
            broken: None,
        })
    }
    fn cost(&self, _m: &Model) -> Cost {
        Cost::default()
    }
}

struct Smoother {
    alpha: f64,
    fail_at: Option<usize>,
    x: Vec<f64>,
    broken: Option<Breakdown>,
}

impl Estimator for Smoother {
    fn step(&mut self, s: &Step<'_>) {
        for (x, y) in self.x.iter_mut().zip(s.y) {
            *x += self.alpha * (y - *x);
        }
        if self.fail_at == Some(s.k) {
            self.broken = Some(Breakdown {
                what: "injected breakdown".into(),
            });
        }
    }
    fn estimates(&self) -> &[f64] {
        &self.x
    }
    fn cov_trace(&self, _s: &Step<'_>, out: &mut [f64]) {
        out.fill(0.0);
    }
    fn breakdown(&self) -> Option<&Breakdown> {
        self.broken.as_ref()
    }
}

fn scenario(entries: Vec<EstimatorEntry>) -> Result<Scenario, edgekf::scenario::ScenarioError> {
    let registry = Registry::default().with(SmootherKind);
    let spec = common::spec(0.001, 0.1, 400, 3, 20, entries);
    Scenario::from_spec_in(&spec, None, &registry)
}

#[test]
fn a_new_estimator_runs_through_the_engine() {
    let sc = scenario(vec![
        EstimatorEntry::kind("mle"),
        EstimatorEntry::kind("smoother").with("alpha", 1.0),
        EstimatorEntry::kind("smoother")
            .with("alpha", 0.5)
            .with("label", "half"),
    ])
    .unwrap();
    let res = common::run(&sc);
    // α = 1 is the MLE, bit for bit.
    for m in ["est_error", "procrustes"] {
        assert_eq!(res.values("mle", m), res.values("smoother", m), "{m}");
    }
    assert!(res.series("half", "est_error").is_some());
    // Its options go to the resolved scenario and come back.
    let r = sc.to_resolved();
    assert_eq!(
        r.estimator_specs.as_ref().unwrap()[2]["alpha"],
        serde_json::json!(0.5)
    );
    let registry = Registry::default().with(SmootherKind);
    let back = Scenario::from_resolved_in(&r, &registry).unwrap();
    assert_eq!(common::run(&back), res);
    // Without the registration the kind is unknown, and the message lists the known ones.
    let e = Scenario::from_resolved(&r).unwrap_err();
    assert_eq!(e.key, "estimator_specs[1].kind");
    assert!(e.message.contains("unknown estimator `smoother`"), "{e}");
}

#[test]
fn its_options_are_checked_by_its_own_rules() {
    let e = scenario(vec![EstimatorEntry::kind("smoother")]).unwrap_err();
    assert_eq!(e.key, "estimators[0]");
    assert!(e.message.contains("missing field `alpha`"), "{e}");
    let e = scenario(vec![EstimatorEntry::kind("smoother")
        .with("alpha", 0.5)
        .with("prior_var", 1e-3)])
    .unwrap_err();
    assert!(e.message.contains("unknown field `prior_var`"), "{e}");
    assert!(
        e.message
            .contains("every estimator also takes `kind`, `label` and `samples`"),
        "{e}"
    );
    let e = scenario(vec![EstimatorEntry::kind("smoother").with("alpha", 2.0)]).unwrap_err();
    assert!(e.message.contains("`alpha` must lie in (0, 1]"), "{e}");
    // A value of the wrong type: serde names no option; the message does.
    let e = scenario(vec![EstimatorEntry::kind("smoother").with("alpha", "big")]).unwrap_err();
    assert!(e.message.contains("option `alpha`: invalid type"), "{e}");
    let e = scenario(vec![EstimatorEntry::kind("mmse").with("prior_var", "big")]).unwrap_err();
    assert!(
        e.message.contains("mmse: option `prior_var`: invalid type"),
        "{e}"
    );
    // An option whose own message names it is not named twice.
    let e = scenario(vec![
        EstimatorEntry::kind("rkf").with("adaptive", "sometimes")
    ])
    .unwrap_err();
    assert_eq!(e.message.matches("option `adaptive`").count(), 1, "{e}");
    let e = scenario(vec![EstimatorEntry::kind("mmse")]).unwrap_err();
    assert!(
        e.message
            .contains("add it to its table, `{ kind = \"mmse\", prior_var = … }`"),
        "{e}"
    );
}

#[test]
fn a_breakdown_is_a_typed_outcome_not_a_panic() {
    let sc = scenario(vec![
        EstimatorEntry::kind("mle"),
        EstimatorEntry::kind("smoother")
            .with("alpha", 0.5)
            .with("fail_at", 101),
    ])
    .unwrap();
    let res = common::run(&sc);
    let e = res.estimator("smoother").unwrap();
    match &e.outcome {
        Outcome::Diverged { step, cause, .. } => {
            assert_eq!(*step, 101);
            assert!(cause.starts_with("injected breakdown"), "{cause}");
        }
        Outcome::Completed => panic!("the breakdown was not reported"),
    }
    // Its series stop before the breakdown: reports 1, 20, …, 100 are valid.
    assert_eq!(e.valid, 6);
    assert_eq!(res.series("smoother", "est_error").unwrap().mean.len(), 6);
    // The other estimator of the study is unaffected.
    assert_eq!(res.estimator("mle").unwrap().outcome, Outcome::Completed);
}
