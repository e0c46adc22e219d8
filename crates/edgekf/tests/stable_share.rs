//! A sweep that counts stable runs (Li & Rajan Fig. 13) judges divergence run by run: a run
//! whose error passes the divergence bound is one unstable run, not the end of every run's
//! loop. Until 2026-12-04 the first such run stopped the estimator and every share of the
//! sparse graph with departures read 0 (the 100-run shares are 0.78 / 0.65 / 0.10 / 0.10 at
//! 6 / 10 / 30 / 50 % departing, σ_w = 1, and 0.77 / 0.65 / 0.12 / 0.08 at the shipped 0.03).

use edgekf::scenario::{Scenario, StableSpec};
use edgekf::sim::{self, sweep, Options, Outcome, Quiet};
use edgekf_io::reproductions::{framework_of, ENTRIES};

/// The shipped sparse Fig. 13 at `runs` runs and one value of its sweep (10 % departing).
fn fig13_sparse(runs: usize) -> (Scenario, StableSpec) {
    let e = ENTRIES
        .iter()
        .find(|e| e.file == "garkf-fig13.toml")
        .expect("shipped");
    // The scenario as written at the swept value, so that the sweep runs it once.
    let text = e.text.replace("share = 0.5, at", "share = 0.1, at");
    assert_ne!(text, e.text, "the shipped share");
    let mut spec = edgekf_io::spec_from_toml(&text).expect("valid TOML");
    let fw = framework_of(e.file, &spec).expect("framework");
    spec.plots.clear();
    spec.sim.runs = runs;
    let sw = spec.sweep.as_mut().expect("a sweep");
    sw.values.retain(|v| v.as_f64() == Some(0.1));
    assert_eq!(sw.values.len(), 1, "the shipped sweep has 10 %");
    let rule = sw.stable.expect("a stable rule");
    (
        Scenario::from_spec(&spec, fw.as_ref()).expect("valid"),
        rule,
    )
}

/// The sweep's stable runs are those a study of each run alone finds stable (a run alone stops
/// at its divergence, the old policy, so each verdict is that run's own), and some runs
/// diverge while others stay stable.
#[test]
fn a_diverged_run_is_one_unstable_run_not_the_end_of_the_study() {
    let runs = 8;
    let (sc, rule) = fig13_sparse(runs);
    let point = sc.sweep_points().expect("points").swap_remove(0).scenario;
    let together = sim::run_range(
        &point,
        0..runs,
        &Quiet,
        Options {
            per_run_divergence: true,
            ..Options::default()
        },
    )
    .expect("runs");
    let e = &together.estimators[0];
    let joint = sweep::stable_runs(&together, &e.label, &rule).expect("judged");
    let alone: Vec<f64> = (0..runs)
        .map(|r| {
            let one = sim::run_range(&point, r..r + 1, &Quiet, Options::default()).expect("run");
            sweep::stable_runs(&one, &e.label, &rule).expect("judged")[0]
        })
        .collect();
    assert_eq!(joint, alone, "per run: together vs alone");
    let stable = joint.iter().sum::<f64>();
    assert!(
        stable > 0.0 && stable < runs as f64,
        "some runs stable, some not: {joint:?}"
    );
    // The loop went on, so the study completed; the diverged runs read +∞ from their
    // divergence on.
    assert_eq!(e.outcome, Outcome::Completed);
    // A diverged run is unstable (an unstable one may only have grown past the factor).
    assert!(e.diverged_runs(runs) <= runs - stable as usize);
    let delta = together.values(&e.label, "tracking_error").expect("δ");
    let last = &delta[(together.steps.len() - 1) * runs..];
    for (r, (&s, &d)) in joint.iter().zip(last).enumerate() {
        assert!(
            s == 1.0 || d == f64::INFINITY || d.is_finite(),
            "run {r}: {d}"
        );
    }
    // The sweep reports the same share.
    let res = sweep::run(&sc, &Quiet).expect("sweep");
    let share = res
        .summary
        .iter()
        .find(|r| r.metric == "stable_share")
        .expect("a share");
    assert_eq!(share.mean, stable / runs as f64);
}

/// `sweep::run_with` records the frames of the scenario as written (the sweep's `base`, here
/// also its one point) and changes no summary and no point's metrics.
#[test]
fn a_sweep_records_frames_of_the_scenario_as_written_and_nothing_else() {
    let (sc, _) = fig13_sparse(4);
    let plain = sweep::run(&sc, &Quiet).expect("sweep");
    let extra = Options {
        frame_runs: 2,
        frame_limit: 10,
        ..Options::default()
    };
    let framed = sweep::run_with(&sc, &Quiet, extra).expect("sweep");
    // Compared as printed: NaN (a std of one value) is not equal to itself.
    let same =
        |a: &dyn std::fmt::Debug, b: &dyn std::fmt::Debug| format!("{a:?}") == format!("{b:?}");
    assert!(same(&plain.summary, &framed.summary), "summaries differ");
    for (a, b) in plain.points.iter().zip(&framed.points) {
        for (x, y) in a.results.estimators.iter().zip(&b.results.estimators) {
            assert!(same(&x.values, &y.values), "{}: values differ", x.label);
        }
    }
    assert_eq!(framed.base.frame_steps.len(), 10);
    for e in &framed.base.estimators {
        let runs: Vec<usize> = e.frames.iter().map(|f| f.run).collect();
        assert_eq!(runs, vec![0, 1], "{}", e.label);
    }
    assert!(plain.base.estimators.iter().all(|e| e.frames.is_empty()));
}
