//! GA-RKF's `geo_noise = "matched"` (issue 25, point 3): the geometric observation's noise
//! matched online to the agent's consensus-vs-RAL discrepancy. On Li & Rajan's hexagon and
//! maneuver at λ = 0.2 with the estimators beside the loop (Fig. 10's setting, σ_w = 0.03), the
//! paper's R̃ leaves GA-RKF overconfident (mean ε² / cov_trace 5.03 ± 0.04 over 20 runs of
//! 10–60 s); matched brings it to 1.24 ± 0.02 and the error from 1.90× to 1.13× the RKF's
//! (`docs/issue25-notes.md`). Here at reduced size: 6 runs, 30 s, window 10–30 s.

mod common;

use edgekf::scenario::Scenario;
use edgekf::sim::{self, Quiet};

fn scenario(runs: usize, extra_garkf: &str, steps: usize) -> Scenario {
    let text = format!(
        r#"
name = "matched"
estimators = [
  {{ kind = "garkf", label = "paper", sigma_w = 0.03, epsilon = 0.08 }},
  {{ kind = "garkf", label = "matched", sigma_w = 0.03, epsilon = 0.08, geo_noise = "matched"{extra_garkf} }},
]
[framework]
preset = "hexagon"
[sim]
dt = 0.01
steps = {steps}
runs = {runs}
every = 10
seed = 25
samples_per_step = 1
[noise]
sigma_w = 0.001
sigma_v = 0.1
meas_corr = 0.3
[faults]
availability = 0.2
[maneuver]
keyframes = "garkf-fig7b"
[control]
follower_gain = 1.0
leaders = "target"
feedback = "truth"
"#
    );
    let spec = edgekf_io::spec_from_toml(&text).expect("valid TOML");
    Scenario::from_spec(&spec, None).expect("valid scenario")
}

/// Per run, mean ε² over mean cov_trace in 10–30 s; then mean and standard error over runs.
fn consistency(res: &sim::Results, label: &str) -> (f64, f64) {
    let runs = res.runs.len();
    let win: Vec<usize> = (0..res.steps.len())
        .filter(|&k| {
            let t = res.steps[k] as f64 * res.dt;
            (10.0..=30.0).contains(&t)
        })
        .collect();
    let (e2, cov) = (
        res.values(label, "est_error_sq").unwrap(),
        res.values(label, "cov_trace").unwrap(),
    );
    let per: Vec<f64> = (0..runs)
        .map(|r| {
            let a: f64 = win.iter().map(|&k| e2[k * runs + r]).sum();
            let b: f64 = win.iter().map(|&k| cov[k * runs + r]).sum();
            a / b
        })
        .collect();
    let m = per.iter().sum::<f64>() / runs as f64;
    let sd = (per.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (runs - 1) as f64).sqrt();
    (m, sd / (runs as f64).sqrt())
}

/// Matched is far nearer to consistent than the paper's R̃, and not overcautious: the paper's
/// ratio is ≈ 5 and matched ≈ 1.24 at paper scale; 6 runs give SEs of ≈ 0.1, so "below 2 and
/// above 0.8 by 3 SE, and at least 2 below the paper's" cannot pass by chance.
#[test]
fn matched_geometric_noise_is_nearly_consistent_where_the_paper_s_is_not() {
    let res = sim::run(&scenario(6, "", 3000), &Quiet).expect("runs");
    let (p, p_se) = consistency(&res, "paper");
    let (m, m_se) = consistency(&res, "matched");
    eprintln!("ε²/cov: paper {p:.3} ± {p_se:.3}, matched {m:.3} ± {m_se:.3}");
    assert!(
        p - 3.0 * p_se > 3.0,
        "the paper's R̃ is overconfident: {p} ± {p_se}"
    );
    assert!(m + 3.0 * m_se < 2.0 && m - 3.0 * m_se > 0.8, "{m} ± {m_se}");
    assert!(p - m > 2.0);
}

/// The option's errors name the key.
#[test]
fn geo_options_are_checked() {
    let bad = |extra: &str, estimators: &str| {
        let text = format!(
            "name = \"x\"\nestimators = [{estimators}]\n[framework]\npreset = \"hexagon\"\n[sim]\ndt = 0.01\nsteps = 10\n{extra}"
        );
        let spec = edgekf_io::spec_from_toml(&text).expect("TOML");
        Scenario::from_spec(&spec, None).unwrap_err().to_string()
    };
    let e = bad("", "{ kind = \"garkf\", geo_memory = 3.0 }");
    assert!(e.contains("geo_memory") && e.contains("matched"), "{e}");
    let e = bad(
        "",
        "{ kind = \"garkf\", geo_noise = \"matched\", geo_memory = 0.001 }",
    );
    assert!(e.contains("geo_memory") && e.contains("one step"), "{e}");
    let e = bad("", "{ kind = \"garkf\", geo_noise = \"exact\" }");
    assert!(e.contains("geo_noise") || e.contains("exact"), "{e}");
}

/// Like every estimator, bit-identical for any thread count.
#[test]
fn matched_is_bit_identical_for_any_thread_count() {
    let sc = scenario(5, ", geo_memory = 2.0", 400);
    let with = |t: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap()
            .install(|| common::run(&sc))
    };
    let bits = |r: &sim::Results| -> Vec<u64> {
        r.estimators
            .iter()
            .flat_map(|e| e.values.iter().flatten().map(|x| x.to_bits()))
            .collect()
    };
    let one = bits(&with(1));
    for t in [2, 3] {
        assert_eq!(one, bits(&with(t)), "{t} threads");
    }
}
