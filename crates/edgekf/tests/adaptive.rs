//! Noise the filters learn online (`adaptive`, [`edgekf::estimate::adaptive`]) in the engine:
//! on the RKF's and JRKF's own model (the hexagon's closed loop, whose process noise is what the
//! filters model) the learnt scales converge to the truth from 10× too high and 10× too low and
//! the filters become consistent; every adaptive filter (the CA filters included) is
//! bit-identical for any thread count; at full availability the adaptive GA-RKF is the adaptive
//! RKF-CA. The CA model itself and a step in the intensity are tested on the filters' own model
//! outside the engine (`estimate::adaptive::own_model`).
//!
//! Tolerances: runs are independent, so a mean over R runs has standard error `s/√R`; a
//! z-score beyond 4.5 has probability 7·10⁻⁶. On the random-walk model σ̂_w shows no bias
//! beyond that (see `docs/issue25-notes.md`); the consistency is allowed [`BIAS_C`] more.

mod common;

use edgekf::scenario::Scenario;
use edgekf::sim::Results;

/// Per-run window means of `metric` of estimator `label` over the reports with time in
/// `[t0, t1]` (plain means: the reports are evenly spaced).
fn window(res: &Results, label: &str, metric: &str, t0: f64, t1: f64) -> Vec<f64> {
    let est = res
        .estimators
        .iter()
        .find(|e| e.label == label)
        .unwrap_or_else(|| panic!("estimator {label}"));
    let m = est
        .metrics
        .iter()
        .position(|m| m == metric)
        .unwrap_or_else(|| panic!("{label}: metric {metric} in {:?}", est.metrics));
    let runs = res.runs.len();
    let mut sums = vec![0.0; runs];
    let mut n = 0;
    for (k, &step) in res.steps.iter().enumerate() {
        let t = step as f64 * res.dt;
        if t >= t0 && t <= t1 {
            for (r, s) in sums.iter_mut().enumerate() {
                *s += est.values[m][k * runs + r];
            }
            n += 1;
        }
    }
    sums.iter().map(|s| s / n as f64).collect()
}

/// [`window`] over the finite values only (a quantity undefined at some steps).
fn window_finite(res: &Results, label: &str, metric: &str, t0: f64, t1: f64) -> Vec<f64> {
    let est = res.estimators.iter().find(|e| e.label == label).unwrap();
    let m = est.metrics.iter().position(|m| m == metric).unwrap();
    let runs = res.runs.len();
    (0..runs)
        .map(|r| {
            let v: Vec<f64> = res
                .steps
                .iter()
                .enumerate()
                .filter(|&(_, &k)| (t0..=t1).contains(&(k as f64 * res.dt)))
                .map(|(i, _)| est.values[m][i * runs + r])
                .filter(|x| x.is_finite())
                .collect();
            v.iter().sum::<f64>() / v.len() as f64
        })
        .collect()
}

fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// Paired ratio Σa/Σb with its delta-method standard error.
fn ratio_se(a: &[f64], b: &[f64]) -> (f64, f64) {
    let n = a.len() as f64;
    let rho = a.iter().sum::<f64>() / b.iter().sum::<f64>();
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - rho * y).collect();
    let (_, se_d) = mean_se(&d);
    let bbar = b.iter().sum::<f64>() / n;
    (rho, se_d / bbar)
}

fn scenario(text: &str) -> Scenario {
    let spec = edgekf_io::spec_from_toml(text).expect("TOML");
    Scenario::from_spec(&spec, None).expect("valid")
}

const Z: f64 = 4.5;
/// Allowance for the adaptive filter's excess error over its covariance (its gain follows the
/// noisy estimate): measured −0.7 to −1.6 % here (within one to two standard errors).
const BIAS_C: f64 = 0.02;

/// `|x − target| < Z·se + allowance`, printed.
fn within(what: &str, x: f64, se: f64, target: f64, allowance: f64) {
    eprintln!(
        "{what}: {x:.5} ± {se:.5} (target {target}, z {:.2})",
        (x - target) / se
    );
    assert!(
        (x - target).abs() < Z * se + allowance,
        "{what}: {x} ± {se} vs {target} (allowance {allowance})"
    );
}

fn hexagon(estimators: &str, steps: usize, runs: usize) -> Scenario {
    scenario(&format!(
        r#"
name = "adaptive"
estimators = [{estimators}]
[framework]
preset = "hexagon"
[sim]
steps = {steps}
runs = {runs}
every = 100
seed = 3
[noise]
sigma_w = 0.001
sigma_v = 0.1
"#
    ))
}

/// The hexagon's world has σ_w = 0.001, σ_v = 0.1 (Δt = 0.001, so a memory of 1 s with
/// `forgetting = 0.999`). `rkf` learns both scales from (10σ_w, 10σ_v) and (σ_w/10, σ_v/10),
/// `jrkf` the process scale from 10× and 1/10 of σ_w. Over 3–6 s (3 memories after the start)
/// every estimate is at the truth and every filter consistent.
#[test]
fn rkf_and_jrkf_learn_the_noise_from_ten_times_off() {
    let sc = hexagon(
        r#"
  { kind = "rkf", label = "high", sigma_w = 0.01, sigma_v = 1.0, adaptive = "both", forgetting = 0.999 },
  { kind = "rkf", label = "low", sigma_w = 0.0001, sigma_v = 0.01, adaptive = "both", forgetting = 0.999 },
  { kind = "jrkf", label = "jhigh", sigma_w = 0.01, adaptive = true, forgetting = 0.999 },
  { kind = "jrkf", label = "jlow", sigma_w = 0.0001, adaptive = true, forgetting = 0.999 },
"#,
        6000,
        12,
    );
    let res = common::run(&sc);
    for label in ["high", "low", "jhigh", "jlow"] {
        let ln_w: Vec<f64> = window(&res, label, "sigma_w_hat", 3.0, 6.0)
            .iter()
            .map(|s| (s / 0.001).ln())
            .collect();
        let (m, se) = mean_se(&ln_w);
        within(&format!("{label} ln(σ̂_w/σ_w)"), m, se, 0.0, 0.0);
        if !label.starts_with('j') {
            // From 10× too high σ̂_v is still +0.5 % high over 3–4.5 s (a transient; the data of 30
            // edges × 2 axes per step make that 15 standard errors): tested from 4.5 s on.
            let v = window(&res, label, "sigma_v_hat", 4.5, 6.0);
            let (m, se) = mean_se(&v);
            within(&format!("{label} σ̂_v"), m, se, 0.1, 0.0);
        }
        let e2 = window(&res, label, "est_error_sq", 3.0, 6.0);
        let ct = window(&res, label, "cov_trace", 3.0, 6.0);
        let (c, se) = ratio_se(&e2, &ct);
        within(&format!("{label} ε²/cov_trace"), c, se, 1.0, BIAS_C);
    }
}

/// Bitwise equality of every value (NaN equal to itself).
fn bits(r: &Results) -> Vec<Vec<u64>> {
    r.estimators
        .iter()
        .flat_map(|e| e.values.iter().chain([&e.paths]))
        .map(|v| v.iter().map(|x| x.to_bits()).collect())
        .collect()
}

fn with_threads(sc: &Scenario, t: usize) -> Results {
    rayon::ThreadPoolBuilder::new()
        .num_threads(t)
        .build()
        .unwrap()
        .install(|| common::run(sc))
}

/// The CA filters on Li & Rajan's maneuver with lost links and a departure.
fn maneuver(estimators: &str, steps: usize, runs: usize, faults: &str) -> Scenario {
    scenario(&format!(
        r#"
name = "adaptive-ca"
estimators = [{estimators}]
[framework]
preset = "hexagon"
[sim]
dt = 0.01
steps = {steps}
runs = {runs}
every = 10
seed = 11
samples_per_step = 1
[noise]
sigma_w = 0.001
sigma_v = 0.1
meas_corr = 0.3
[maneuver]
keyframes = "garkf-fig7b"
[control]
follower_gain = 5.0
[metrics]
edge = [5, 0]
{faults}
"#
    ))
}

#[test]
fn adaptive_filters_are_bit_identical_for_any_thread_count() {
    let ca = maneuver(
        r#"{ kind = "rkf-ca", sigma_w = 0.5, adaptive = true },
  { kind = "garkf", sigma_w = 0.5, adaptive = "both", label = "garkf-both" }"#,
        300,
        5,
        "[faults]\navailability = 0.5\ndepartures = [{ agent = 6, at = 1.0, rejoin = 2.0 }]",
    );
    let rw = hexagon(
        r#"{ kind = "rkf", adaptive = "both", sigma_w = 0.01 }, { kind = "jrkf", adaptive = true }"#,
        300,
        5,
    );
    for sc in [ca, rw] {
        let one = with_threads(&sc, 1);
        for e in &one.estimators {
            assert!(e.metrics.iter().any(|m| m == "sigma_w_hat"), "{}", e.label);
        }
        for t in [2, 3] {
            let other = with_threads(&sc, t);
            assert_eq!(one.steps, other.steps);
            assert_eq!(bits(&one), bits(&other), "{t} threads");
        }
    }
}

/// Without lost links GA-RKF never uses its geometric observation, so the adaptive GA-RKF is
/// the adaptive RKF-CA bit for bit (as the fixed ones are), and its learnt σ_w stays finite and
/// positive on the maneuver.
#[test]
fn at_full_availability_adaptive_garkf_equals_adaptive_rkf_ca() {
    let sc = maneuver(
        r#"{ kind = "rkf-ca", sigma_w = 0.5, adaptive = "both" },
  { kind = "garkf", sigma_w = 0.5, adaptive = "both" }"#,
        600,
        3,
        "",
    );
    let res = common::run(&sc);
    for m in ["est_error_sq", "cov_trace", "sigma_w_hat", "sigma_v_hat"] {
        let (a, b) = (
            res.values("rkf-ca", m).unwrap(),
            res.values("garkf", m).unwrap(),
        );
        assert_eq!(a.len(), b.len());
        assert!(
            a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
            "{m} differs"
        );
        assert!(a.iter().all(|x| x.is_finite() && *x >= 0.0), "{m}");
    }
}

/// `adaptive = false` and no `sigma_w`/`sigma_v` is the filter as before, bit for bit.
#[test]
fn adaptive_off_is_the_fixed_filter() {
    let sc = hexagon(
        r#""rkf", "jrkf", { kind = "rkf", label = "rkf-off", adaptive = false },
  { kind = "jrkf", label = "jrkf-off", adaptive = "off" }"#,
        300,
        3,
    );
    let res = common::run(&sc);
    for (a, b) in [("rkf", "rkf-off"), ("jrkf", "jrkf-off")] {
        for m in ["est_error_sq", "cov_trace"] {
            let (x, y) = (res.values(a, m).unwrap(), res.values(b, m).unwrap());
            assert!(
                x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()),
                "{b} {m}"
            );
        }
    }
}

/// Issue 25 point 3 (numbers for `docs/issue25-notes.md`): GA-RKF against RKF-CA at λ = 0.2 on
/// Li & Rajan's maneuver, with σ_w = 1 (shipped), 0.05 (the maneuver's jerk) and learnt, in
/// open loop (feedback on the true edges, Fig. 10) and closed loop (Fig. 11): the paired error
/// ratio, each filter's consistency ε²/cov_trace, and the tracking error δ.
#[test]
#[ignore = "study: cargo test -p edgekf --test adaptive -- --ignored --nocapture"]
fn study_garkf_at_low_availability() {
    let est = r#"
  { kind = "none", label = "none" },
  { kind = "rkf-ca", label = "rkf-1", sigma_w = 1.0 },
  { kind = "garkf", label = "ga-1", sigma_w = 1.0 },
  { kind = "rkf-ca", label = "rkf-0.05", sigma_w = 0.05 },
  { kind = "garkf", label = "ga-0.05", sigma_w = 0.05 },
  { kind = "rkf-ca", label = "rkf-ad", sigma_w = 0.05, adaptive = true },
  { kind = "garkf", label = "ga-ad", sigma_w = 0.05, adaptive = true },
"#;
    let lam: f64 = std::env::var("LAMBDA")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.2);
    for feedback in ["truth", "estimates"] {
        let sc = scenario(&format!(
            r#"
name = "study"
estimators = [{est}]
[framework]
preset = "hexagon"
[sim]
dt = 0.01
steps = 6000
runs = 20
every = 10
seed = 1101
samples_per_step = 1
allow_divergence = true
[noise]
sigma_w = 0.001
sigma_v = 0.1
meas_corr = 0.3
[faults]
availability = {lam}
[maneuver]
keyframes = "garkf-fig7b"
[control]
follower_gain = 1.0
leaders = "target"
feedback = "{feedback}"
"#
        ));
        let res = common::run(&sc);
        eprintln!("== λ = {lam}, feedback = {feedback} (window 10–60 s, 20 runs)");
        let (t0, t1) = (10.0, 60.0);
        for label in [
            "none", "rkf-1", "ga-1", "rkf-0.05", "ga-0.05", "rkf-ad", "ga-ad",
        ] {
            let e2 = window(&res, label, "est_error_sq", t0, t1);
            let ct = window(&res, label, "cov_trace", t0, t1);
            let (c, cse) = ratio_se(&e2, &ct);
            let (e, ese) = mean_se(&e2);
            let (d, dse) = mean_se(&window(&res, label, "tracking_error", t0, t1));
            let sw = if label.ends_with("ad") {
                let (m, se) = mean_se(&window(&res, label, "sigma_w_hat", t0, t1));
                format!(" σ̂_w {m:.4} ± {se:.4}")
            } else {
                String::new()
            };
            eprintln!(
                "{label:9} ε² {e:.4e} ± {ese:.1e}  ε²/cov {c:.3} ± {cse:.3}  δ {d:.4e} ± {dse:.1e}{sw}"
            );
        }
        for (ga, rkf) in [
            ("ga-1", "rkf-1"),
            ("ga-0.05", "rkf-0.05"),
            ("ga-ad", "rkf-ad"),
        ] {
            let (a, b) = (
                window(&res, ga, "est_error_sq", t0, t1),
                window(&res, rkf, "est_error_sq", t0, t1),
            );
            let (r, se) = ratio_se(&a, &b);
            let (ca, cb) = (
                window(&res, ga, "cov_trace", t0, t1),
                window(&res, rkf, "cov_trace", t0, t1),
            );
            let (rc, sec) = ratio_se(&ca, &cb);
            eprintln!("{ga}/{rkf}: ε² ratio {r:.3} ± {se:.3}, cov ratio {rc:.3} ± {sec:.3}");
            // R̃ = R^ral/N + ψI takes the consensus to divide the RAL's error by N = 10: the
            // consensus Θ̂'s error against the local RAL's (both against the target's Θ*).
            let (a, b) = (
                window_finite(&res, ga, "theta_error", t0, t1),
                window_finite(&res, ga, "theta_ral_error", t0, t1),
            );
            let ((ea, sa), (eb, sb)) = (mean_se(&a), mean_se(&b));
            let (q, qse) = ratio_se(&a, &b);
            eprintln!("  {ga}: ‖Θ̂−Θ*‖² consensus {ea:.3e} ± {sa:.1e}, RAL {eb:.3e} ± {sb:.1e}: ratio {q:.3} ± {qse:.3}");
        }
    }
}
