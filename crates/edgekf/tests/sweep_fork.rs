//! A sweep over the share of followers that depart at random (Li & Rajan Fig. 13) steps its
//! values together until the departures and each value on its own from there (`sim::fork`):
//! every value's results must be, bit for bit, those of simulating it alone — metrics, the
//! recorded paths, the frames of the scenario as written — at any thread count; and the steps
//! before the departures must be stepped once, not once per value.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};

use edgekf::estimate::Estimator;
use edgekf::scenario::Scenario;
use edgekf::sim::{self, sweep, Observer, Options, Quiet};
use edgekf_io::reproductions::{framework_of, ENTRIES};

const RUNS: usize = 5;
const STEPS: usize = 120;
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
    spec.sim.runs = RUNS;
    spec.sim.steps = STEPS;
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
        // The four values with departures (0.06 … 0.5) are stepped once before them; the
        // share 0, which has no faults, on its own: 2 reports per value-chunk-estimator.
        let reports = sc.report_steps().iter().filter(|&&k| k < AT).count();
        let chunks = threads.min(RUNS);
        assert_eq!(
            before.0.load(Ordering::Relaxed),
            2 * reports * chunks * sc.estimators().len(),
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
        v[..last * RUNS].iter().map(|x| x.to_bits()).collect()
    };
    for label in ["GA-RKF", "RKF-CA", "none"] {
        for k in 2..5 {
            assert_eq!(bits(1, label), bits(k, label), "{label}, value {k}");
        }
        // ... and not after them (more agents leave).
        let after = |k: usize| {
            res.points[k]
                .results
                .values(label, "tracking_error")
                .expect("δ")[(last + 2) * RUNS..]
                .to_vec()
        };
        assert_ne!(
            format!("{:?}", after(1)),
            format!("{:?}", after(4)),
            "{label}"
        );
    }
}
