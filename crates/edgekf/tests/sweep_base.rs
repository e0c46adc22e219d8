//! A sweep keeps the results of its scenario as written (the base) for the figures; when one of
//! its values is that scenario, the value's results are the base's and it is simulated once.
//! Until 2026-12-06 the values (which carry no figures) never compared equal to a scenario with
//! figures, and every shipped sweep with figures (Li & Rajan Figs. 8, 10–13) simulated its base
//! value twice. The cost estimate counts what is simulated.
//!
//! A sweep over the share of followers that depart at random (Li & Rajan Fig. 13) steps its
//! values together until the departures and each value on its own from there (`sim::fork`):
//! every value's results must be, bit for bit, those of simulating it alone — metrics, the
//! recorded paths, the frames of the scenario as written — at any thread count; and the steps
//! before the departures must be stepped once, not once per value.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

use edgekf::estimate::Estimator;
use edgekf::scenario::Scenario;
use edgekf::sim::{self, sweep, Observer, Options, Quiet};
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

// ---- values that share their first steps (`sim::fork`) ----

const FORK_RUNS: usize = 5;
const FORK_STEPS: usize = 120;
/// The departures at 0.6 s: step 60.
const AT: usize = 60;

/// The shipped Fig. 13 (sparse graph), small, with `rkf-ca` and `none` beside GA-RKF.
fn fig13() -> Scenario {
    let e = ENTRIES
        .iter()
        .find(|e| e.file == "garkf-fig13.toml")
        .expect("shipped");
    let text = e
        .text
        .replace(
            "estimators = [{",
            "estimators = [{ kind = \"rkf-ca\", label = \"RKF-CA\", sigma_w = 0.03 }, { kind = \"none\" }, {",
        )
        .replace("at = 8.0 }", "at = 0.6 }")
        .replace(
            "stable = { reference = [7.0, 8.0], final = [14.0, 15.0], factor = 10.0 }",
            "stable = { reference = [0.5, 0.6], final = [1.1, 1.2], factor = 10.0 }",
        )
        .replace("every = 10", "every = 5");
    let mut spec = edgekf_io::spec_from_toml(&text).expect("valid TOML");
    spec.sim.runs = FORK_RUNS;
    spec.sim.steps = FORK_STEPS;
    let fw = framework_of(e.file, &spec).expect("framework");
    Scenario::from_spec(&spec, fw.as_ref()).expect("valid")
}

/// Counts the estimators' reports before the departures.
#[derive(Default)]
struct Before(AtomicUsize);

impl Observer for Before {
    fn on_estimator(&self, k: usize, _i: usize, _runs: Range<usize>, _est: &dyn Estimator) {
        if k < AT {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
    }
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool")
}

#[test]
fn every_value_is_the_study_of_it_alone() {
    let sc = fig13();
    let frames = Options {
        frame_runs: 2,
        frame_limit: 8,
        ..Options::default()
    };
    let points = sc.sweep_points().expect("points");
    assert_eq!(points.len(), 5);
    for threads in [1, 2] {
        let before = Before::default();
        let res = pool(threads)
            .install(|| sweep::run_with(&sc, &before, frames))
            .expect("sweep");
        // The five values (0 … 0.5) are stepped once before the departures.
        let reports = sc.report_steps().iter().filter(|&&k| k < AT).count();
        let chunks = threads.min(FORK_RUNS);
        assert_eq!(
            before.0.load(Ordering::Relaxed),
            reports * chunks * sc.estimators().len(),
            "{threads} thread(s)"
        );
        for (k, p) in points.iter().enumerate() {
            // The scenario as written (share 0.5) keeps its frames.
            let is_base = k == 4;
            let opt = Options {
                per_run_divergence: true,
                frame_runs: if is_base { frames.frame_runs } else { 0 },
                frame_limit: if is_base { frames.frame_limit } else { 0 },
                ..Options::default()
            };
            let alone = pool(threads)
                .install(|| sim::run_with(&p.scenario, &Quiet, opt))
                .expect("run");
            // Debug text compares every number bit for bit (NaN included).
            assert_eq!(
                format!("{:?}", res.points[k].results),
                format!("{alone:?}"),
                "value {} at {threads} thread(s)",
                p.label
            );
            if is_base {
                assert!(!alone.estimators[0].frames.is_empty(), "frames recorded");
                assert_eq!(format!("{:?}", res.base), format!("{alone:?}"));
            }
        }
    }
}

#[test]
fn the_values_are_the_same_runs_until_the_departures() {
    let sc = fig13();
    let res = sweep::run(&sc, &Quiet).expect("sweep");
    let last = sc.report_steps().iter().filter(|&&k| k < AT).count();
    let bits = |k: usize, label: &str| -> Vec<u64> {
        let v = res.points[k]
            .results
            .values(label, "tracking_error")
            .expect("δ");
        v[..last * FORK_RUNS].iter().map(|x| x.to_bits()).collect()
    };
    for label in ["GA-RKF", "RKF-CA", "none"] {
        for k in 1..5 {
            assert_eq!(bits(0, label), bits(k, label), "{label}, value {k}");
        }
        // ... and not after them (more agents leave).
        let after = |k: usize| {
            res.points[k]
                .results
                .values(label, "tracking_error")
                .expect("δ")[(last + 2) * FORK_RUNS..]
                .to_vec()
        };
        assert_ne!(
            format!("{:?}", after(1)),
            format!("{:?}", after(4)),
            "{label}"
        );
    }
}

#[test]
fn a_departure_of_nobody_is_no_departure() {
    // The share 0 tracks presence from the first step (so that it shares the other values'
    // loops); every agent stays, and its results are those of no departure at all.
    let points = fig13().sweep_points().expect("points");
    let nobody = &points[0].scenario;
    assert_eq!(nobody.faults().random_departures.map(|d| d.0), Some(0));
    let mut spec = edgekf_io::spec_from_toml(
        &ENTRIES
            .iter()
            .find(|e| e.file == "garkf-fig13.toml")
            .expect("shipped")
            .text
            .replace(
                "estimators = [{",
                "estimators = [{ kind = \"rkf-ca\", label = \"RKF-CA\", sigma_w = 0.03 }, { kind = \"none\" }, {",
            )
            .replace("every = 10", "every = 5"),
    )
    .expect("valid TOML");
    spec.sim.runs = FORK_RUNS;
    spec.sim.steps = FORK_STEPS;
    spec.faults = Default::default();
    spec.sweep = None;
    spec.plots.clear();
    let fw = framework_of("garkf-fig13.toml", &spec).expect("framework");
    let plain = Scenario::from_spec(&spec, fw.as_ref()).expect("valid");
    assert!(!plain.faults().any());
    let a = sim::run(nobody, &Quiet).expect("run");
    let b = sim::run(&plain, &Quiet).expect("run");
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
}

#[test]
fn the_cost_estimate_counts_shared_first_steps_once() {
    let sc = fig13();
    let points = sc.sweep_points().expect("points");
    let cost = |s: &Scenario| sim::cost(s, FORK_RUNS, 1).seconds;
    // The base is the last value; the first value simulates every step, the others from the
    // departures on.
    let after = 1.0 - (AT - 1) as f64 / FORK_STEPS as f64;
    let expected = cost(&points[0].scenario)
        + points[1..]
            .iter()
            .map(|p| after * cost(&p.scenario))
            .sum::<f64>();
    let total = cost(&sc);
    assert!(
        (total - expected).abs() <= 1e-12 * expected,
        "{total} vs {expected}"
    );
}

/// Every built-in estimator (the adaptive ones and the chapter 6 input predictors included) on
/// the thesis hexagon, the departures at 0.4 s, swept over the share departing.
fn every_estimator(values: &str) -> Scenario {
    let text = format!(
        r#"
name = "fork-all"
estimators = ["none", "mle", "rkf", "rkf-zero", "jrkf", "crkf", "oracle", "rkf-ca", "garkf",
  {{ kind = "mmse", prior_var = 1e-3 }}, {{ kind = "rkf-ar", p_fail = 0.25 }},
  {{ kind = "jrkf-ar", p_fail = 0.25 }}, {{ kind = "rkf-commless", label = "commless" }},
  {{ kind = "rkf", label = "rkf-adaptive", adaptive = "both" }},
  {{ kind = "jrkf", label = "jrkf-adaptive", adaptive = "process" }},
  {{ kind = "rkf-ca", label = "rkf-ca-adaptive", adaptive = "both" }},
  {{ kind = "garkf", label = "garkf-adaptive", adaptive = true }}]
[framework]
preset = "hexagon"
[sim]
dt = 0.01
steps = 80
runs = 4
every = 5
seed = 10
[noise]
sigma_w = 0.001
sigma_v = 0.1
[comm.ar]
coeffs = [[0.97, 0.98]]
noise_var = [0.0115, 0.0119]
[faults]
random_departures = {{ share = 0.3, at = 0.4 }}
[sweep]
parameter = "faults.random_departures.share"
values = {values}
"#
    );
    let spec = edgekf_io::spec_from_toml(&text).expect("valid TOML");
    Scenario::from_spec(&spec, None).expect("valid")
}

#[test]
fn every_estimator_forks_to_the_bits_of_its_study_alone() {
    let sc = every_estimator("[0.0, 0.15, 0.3]");
    let points = sc.sweep_points().expect("points");
    for threads in [1, 2] {
        let res = pool(threads)
            .install(|| sweep::run(&sc, &Quiet))
            .expect("sweep");
        for (k, p) in points.iter().enumerate() {
            let alone = pool(threads)
                .install(|| sim::run(&p.scenario, &Quiet))
                .expect("run");
            for (a, b) in res.points[k]
                .results
                .estimators
                .iter()
                .zip(&alone.estimators)
            {
                assert_eq!(
                    format!("{a:?}"),
                    format!("{b:?}"),
                    "{} at share {}, {threads} thread(s)",
                    a.label,
                    p.label
                );
            }
        }
    }
}

/// Every estimator but the CRKF gives the bits of no departure at all.
#[test]
fn a_departure_of_nobody_is_no_departure_for_every_estimator() {
    let sc = every_estimator("[0.0]");
    let nobody = &sc.sweep_points().expect("points")[0].scenario;
    let mut plain = every_estimator("[0.0]").without_sweep().to_resolved();
    plain.faults = None;
    let plain = Scenario::from_resolved(&plain).expect("valid");
    assert!(nobody.faults().any() && !plain.faults().any());
    let (a, b) = (
        sim::run(nobody, &Quiet).expect("run"),
        sim::run(&plain, &Quiet).expect("run"),
    );
    for (x, y) in a.estimators.iter().zip(&b.estimators) {
        if x.kind != "crkf" {
            assert_eq!(format!("{x:?}"), format!("{y:?}"), "{}", x.label);
            continue;
        }
        // The CRKF's path with faults forms its information from the edges observed (all of
        // them here) rather than from its precomputed sum: the same numbers added in another
        // order, 4.4e-13 relative at most over these 80 steps (1e-9 leaves room for rounding
        // to grow with the steps, and fails at any real difference).
        assert_eq!(x.outcome, y.outcome);
        for (p, q) in x.values.iter().flatten().zip(y.values.iter().flatten()) {
            assert!(
                (p - q).abs() <= 1e-9 * p.abs().max(q.abs()),
                "crkf: {p} vs {q}"
            );
        }
    }
}
