//! A sweep keeps the results of its scenario as written (the base) for the figures; when one of
//! its values is that scenario, the value's results are the base's and it is simulated once.
//! Until 2026-12-06 the values (which carry no figures) never compared equal to a scenario with
//! figures, and every shipped sweep with figures (Li & Rajan Figs. 8, 10–13) simulated its base
//! value twice. The cost estimate counts what is simulated.

use std::sync::atomic::{AtomicU64, Ordering};

use edgekf::scenario::Scenario;
use edgekf::sim::{self, sweep, Observer};
use edgekf_io::reproductions::{framework_of, ENTRIES};

/// Counts the run-steps simulated.
#[derive(Default)]
struct Steps(AtomicU64);

impl Observer for Steps {
    fn on_progress(&self, n: u64) {
        self.0.fetch_add(n, Ordering::Relaxed);
    }
}

const RUNS: usize = 2;
const STEPS: usize = 60;

/// The shipped Fig. 12 (a sweep of the departure time over 0, 1.5, 3 and 10 s, with a figure),
/// small, its own departure at `at` s.
fn fig12(at: &str) -> Scenario {
    let e = ENTRIES
        .iter()
        .find(|e| e.file == "garkf-fig12.toml")
        .expect("shipped");
    let text = e
        .text
        .replace("agent = 6, at = 10.0", &format!("agent = 6, at = {at}"));
    let mut spec = edgekf_io::spec_from_toml(&text).expect("valid TOML");
    assert!(!spec.plots.is_empty(), "the shipped sweep has its figure");
    spec.sim.runs = RUNS;
    spec.sim.steps = STEPS;
    let fw = framework_of(e.file, &spec).expect("framework");
    Scenario::from_spec(&spec, fw.as_ref()).expect("valid")
}

#[test]
fn a_value_that_is_the_scenario_is_simulated_once_and_is_its_base() {
    let per_study = (RUNS * STEPS) as u64;
    // 10 s is one of the values: four simulations.
    let sc = fig12("10.0");
    let steps = Steps::default();
    let res = sweep::run(&sc, &steps).expect("sweep");
    assert_eq!(steps.0.load(Ordering::Relaxed), 4 * per_study);
    let last = &res.points[3];
    assert_eq!(last.value, Some(10.0));
    for e in &res.base.estimators {
        let base = res.base.values(&e.label, "tracking_error").expect("δ");
        let point = last.results.values(&e.label, "tracking_error").expect("δ");
        assert_eq!(
            base.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            point.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            "{}",
            e.label
        );
    }
    // 5 s is not: the four values and the base.
    let other = fig12("5.0");
    let steps = Steps::default();
    sweep::run(&other, &steps).expect("sweep");
    assert_eq!(steps.0.load(Ordering::Relaxed), 5 * per_study);
}

#[test]
fn the_cost_estimate_counts_the_base_only_when_it_is_simulated() {
    let points = |sc: &Scenario| -> f64 {
        sc.sweep_points()
            .expect("points")
            .iter()
            .fold(0.0, |s, p| s + sim::cost(&p.scenario, RUNS, 1).seconds)
    };
    let sc = fig12("10.0");
    assert_eq!(sim::cost(&sc, RUNS, 1).seconds, points(&sc));
    let other = fig12("5.0");
    let base = sim::cost(&other.without_sweep(), RUNS, 1).seconds;
    let total = sim::cost(&other, RUNS, 1).seconds;
    assert!(
        (total - (base + points(&other))).abs() <= 1e-12 * total,
        "{total} vs {base} + {}",
        points(&other)
    );
}
