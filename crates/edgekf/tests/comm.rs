//! Filtering without reliable communication (thesis chapter 6; issue 3, point 6).

mod common;

use common::{ar, names, run, tail_mean};
use edgekf::scenario::{CommSpec, EstimatorEntry, Scenario};

fn entry(kind: &str, label: &str, p_fail: Option<f64>) -> EstimatorEntry {
    let e = EstimatorEntry::kind(kind).with("label", label);
    match p_fail {
        Some(p) => e.with("p_fail", p),
        None => e,
    }
}

fn scenario(steps: usize, runs: usize, every: usize, estimators: Vec<EstimatorEntry>) -> Scenario {
    let mut s = common::spec(0.001, 0.1, steps, runs, every, estimators);
    s.comm = CommSpec {
        p_fail: 0.0,
        ar: Some(ar()),
    };
    common::build(&s)
}

#[test]
fn rkf_ar_without_failures_is_the_rkf_bit_for_bit() {
    let sc = scenario(
        3000,
        3,
        10,
        vec![
            entry("rkf", "rkf", None),
            entry("rkf-ar", "ar0", Some(0.0)),
            entry("jrkf", "jrkf", None),
            entry("jrkf-ar", "jar0", Some(0.0)),
        ],
    );
    let res = run(&sc);
    for (a, b) in [("rkf", "ar0"), ("jrkf", "jar0")] {
        for m in ["est_error", "est_error_sq", "cov_trace", "procrustes"] {
            let (x, y) = (res.values(a, m).unwrap(), res.values(b, m).unwrap());
            assert!(
                x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()),
                "{a} vs {b}: {m}"
            );
        }
    }
}

/// With failures the AR-predicted filter stays at the clairvoyant floor and consistent, while
/// ignoring the neighbour's input (û = 0) is biased: in the transient its mean squared error is
/// far above its own covariance trace.
///
/// Tolerances: 20 runs; the steady-state errors are averaged over 3–6 s (150 reports), where the
/// run-to-run spread of ε is ≈ 10 %, so ±5 % on the ratio to the paired clairvoyant filter (same
/// noise) is several standard errors. In the transient (0.1–1 s) the û = 0 filter's MSE exceeds
/// its covariance by a factor > 10 (measured ≈ 70); the AR filter's ratio stays below 1.5
/// (measured ≈ 1.0; it is not exact because the AR model is approximate).
#[test]
fn ar_prediction_keeps_the_floor_and_zero_input_is_biased() {
    let sc = scenario(
        6000,
        20,
        20,
        vec![
            entry("rkf", "rkf", None),
            entry("rkf-ar", "ar50", Some(0.5)),
            entry("rkf-ar", "ar100", Some(1.0)),
            entry("rkf-zero", "zero", None),
        ],
    );
    let res = run(&sc);
    let at = |t: f64| {
        res.steps
            .iter()
            .position(|&k| k as f64 * sc.dt() >= t)
            .unwrap()
    };
    let window = |l: &str, m: &str, a: f64, b: f64| {
        let v = &res.series(l, m).unwrap().mean;
        v[at(a)..at(b)].iter().sum::<f64>() / (at(b) - at(a)) as f64
    };
    let floor = window("rkf", "est_error", 3.0, 6.0);
    for l in ["ar50", "ar100"] {
        let e = window(l, "est_error", 3.0, 6.0);
        println!("{l}: steady est_error {e:.4e} vs clairvoyant {floor:.4e}");
        assert!((e / floor - 1.0).abs() < 0.05, "{l}: {e} vs {floor}");
    }
    for l in ["ar50", "ar100", "zero"] {
        let ratio = window(l, "est_error_sq", 0.1, 1.0) / window(l, "cov_trace", 0.1, 1.0);
        println!("{l}: transient mse / cov_trace = {ratio:.2}");
        if l == "zero" {
            assert!(ratio > 10.0, "û = 0 is biased: {ratio}");
        } else {
            assert!(ratio < 1.5, "{l} stays consistent: {ratio}");
        }
    }
}

/// The joint filter with predicted inputs keeps the joint filter's floor (same tolerance argument
/// as above, 8 paired runs over 2–4 s).
#[test]
fn jrkf_ar_keeps_the_joint_floor() {
    let sc = scenario(
        4000,
        8,
        20,
        vec![
            entry("jrkf", "jrkf", None),
            entry("jrkf-ar", "jar50", Some(0.5)),
        ],
    );
    let res = run(&sc);
    let from = res.steps.iter().position(|&k| k >= 2000).unwrap();
    let j = tail_mean(&res.series("jrkf", "est_error").unwrap().mean, from);
    let a = tail_mean(&res.series("jar50", "est_error").unwrap().mean, from);
    println!("jrkf {j:.4e} jrkf-ar(0.5) {a:.4e}");
    assert!((a / j - 1.0).abs() < 0.05);
}

/// Without any communication the Wiener predictor converges faster than ignoring the input
/// (thesis Fig. 6.3): over 0.5–4 s its mean error is below the û = 0 baseline's (paired runs;
/// measured 7.7 % lower at 50 runs and 7 % at these 12, so a 3 % margin), and both end at the
/// clairvoyant floor within 10 %.
#[test]
fn commless_converges_faster_than_zero_input() {
    let sc = scenario(
        8000,
        12,
        20,
        vec![
            entry("rkf", "rkf", None),
            entry("rkf-zero", "zero", None),
            entry("rkf-commless", "commless", None),
        ],
    );
    let res = run(&sc);
    let at = |t: f64| {
        res.steps
            .iter()
            .position(|&k| k as f64 * sc.dt() >= t)
            .unwrap()
    };
    let mean = |l: &str, a: f64, b: f64| {
        let v = &res.series(l, "est_error").unwrap().mean;
        v[at(a)..at(b)].iter().sum::<f64>() / (at(b) - at(a)) as f64
    };
    let (c, z) = (mean("commless", 0.5, 4.0), mean("zero", 0.5, 4.0));
    println!("0.5–4 s: commless {c:.4e}, zero {z:.4e}");
    assert!(c < 0.97 * z);
    let floor = mean("rkf", 6.0, 8.0);
    for l in ["commless", "zero"] {
        let e = mean(l, 6.0, 8.0);
        assert!((e / floor - 1.0).abs() < 0.1, "{l}: {e} vs {floor}");
    }
}

#[test]
fn missing_ar_model_is_named() {
    let mut r = common::hexagon(0.001, 0.1, 10, 1, 1, names(&["rkf"])).to_resolved();
    r.estimators = vec!["rkf-ar".into()];
    r.estimator_specs = None;
    let e = Scenario::from_resolved(&r).unwrap_err();
    assert_eq!(e.key, "estimators[0]");
    assert!(e.message.contains("[comm.ar]"), "{e}");
    r.comm = Some(CommSpec {
        p_fail: 1.5,
        ar: Some(ar()),
    });
    assert_eq!(Scenario::from_resolved(&r).unwrap_err().key, "comm.p_fail");
}
