//! The claims of the GA-RKF issue (Li & Rajan 2026) on `rkf-ca` and `garkf`, at reduced size:
//! equality at λ = 1, the Riccati fixed point, unbounded growth of a lost edge without geometry,
//! covariance ordering, the corrected PCRB, and bit-identical results for any thread count.

mod common;

use edgekf::scenario::Scenario;
use edgekf::sim::Results;
use nalgebra::{Matrix2, SMatrix};

/// A hexagon scenario at Δt = 0.01, σ_v = 0.1, ρ = 0.3, one sample per step (Li & Rajan §VI)
/// with `extra` TOML appended (faults, maneuver, …).
fn scenario(steps: usize, runs: usize, every: usize, extra: &str) -> Scenario {
    scenario_with(steps, runs, every, "", extra)
}

/// [`scenario`] with `sim` keys appended to `[sim]`.
fn scenario_with(steps: usize, runs: usize, every: usize, sim: &str, extra: &str) -> Scenario {
    let text = format!(
        r#"
name = "garkf-test"
estimators = [{{ kind = "rkf-ca", sigma_w = 1.0 }}, {{ kind = "garkf", sigma_w = 1.0, epsilon = 0.08 }}]
[framework]
preset = "hexagon"
[sim]
dt = 0.01
steps = {steps}
runs = {runs}
every = {every}
seed = 11
samples_per_step = 1
{sim}
[noise]
sigma_w = 0.001
sigma_v = 0.1
meas_corr = 0.3
{extra}
"#
    );
    let spec = edgekf_io::spec_from_toml(&text).expect("valid TOML");
    Scenario::from_spec(&spec, None).expect("valid scenario")
}

fn values<'a>(res: &'a Results, label: &str, metric: &str) -> &'a [f64] {
    res.values(label, metric)
        .unwrap_or_else(|| panic!("{label}: no metric {metric}"))
}

/// The steady position-block trace of the CA filter with one observation per step: the
/// Riccati recursion iterated to its fixed point (independent of the library's kernels).
fn riccati_position_trace(dt: f64, sigma_w: f64, sigma_v: f64, rho: f64) -> f64 {
    type M6 = SMatrix<f64, 6, 6>;
    let f1 = [[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]];
    let q1 = [0.5 * dt * dt, dt, 1.0];
    let f = M6::from_fn(|a, b| {
        if a % 2 == b % 2 {
            f1[a / 2][b / 2]
        } else {
            0.0
        }
    });
    let q = M6::from_fn(|a, b| {
        if a % 2 == b % 2 {
            sigma_w * sigma_w * q1[a / 2] * q1[b / 2]
        } else {
            0.0
        }
    });
    let r = Matrix2::new(1.0, rho, rho, 1.0) * sigma_v * sigma_v;
    let g = SMatrix::<f64, 2, 6>::from_fn(|a, b| if a == b { 1.0 } else { 0.0 });
    let mut p = M6::identity();
    for _ in 0..100_000 {
        let pm = f * p * f.transpose() + q;
        let s = g * pm * g.transpose() + r;
        let k = pm * g.transpose() * s.try_inverse().unwrap();
        let ikg = M6::identity() - k * g;
        p = ikg * pm * ikg.transpose() + k * r * k.transpose();
    }
    p[(0, 0)] + p[(1, 1)]
}

#[test]
fn at_full_availability_garkf_equals_rkf_ca_bit_for_bit() {
    let sc = scenario(
        600,
        3,
        10,
        "[maneuver]\nkeyframes = \"garkf-fig7b\"\n[control]\nfollower_gain = 5.0",
    );
    let res = common::run(&sc);
    for m in ["est_error_sq", "cov_trace", "tracking_error"] {
        let (a, b) = (values(&res, "rkf-ca", m), values(&res, "garkf", m));
        assert!(
            a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
            "{m} differs"
        );
    }
}

#[test]
fn rkf_ca_reaches_the_riccati_fixed_point() {
    let p = riccati_position_trace(0.01, 1.0, 0.1, 0.3);
    // The issue quotes 3.6037e-3 (five figures: half a unit of the last is 5e-8).
    assert!((p - 3.6037e-3).abs() < 5e-8, "{p}");
    let sc = scenario(3000, 2, 3000, "[metrics]\nedge = [5, 0]");
    let res = common::run(&sc);
    let last = values(&res, "rkf-ca", "edge_cov_trace");
    let last = &last[last.len() - 2..];
    // Deterministic recursion: after 30 s (≫ the filter's settling time) the covariance equals
    // the fixed point up to rounding of the Joseph recursion.
    for v in last {
        assert!((v / p - 1.0).abs() < 1e-9, "{v} vs {p}");
    }
}

/// The estimators beside a loop they do not steer (Li & Rajan §VI-B, Fig. 10): on the hexagon a
/// loop closed on a permanently lost edge diverges whatever the estimator (see the user guide's GA-RKF chapter).
#[test]
fn a_lost_edge_grows_like_t5_without_geometry_and_stays_bounded_with_it() {
    let (steps, every) = (2000, 100);
    let sc = scenario(
        steps,
        2,
        every,
        "[faults]\nlost = [[5, 0]]\n[metrics]\nedge = [5, 0]\n[control]\nfeedback = \"truth\"",
    );
    let res = common::run(&sc);
    let runs = 2;
    let at = |k: usize| res.steps.iter().position(|&s| s == k).unwrap();
    let rkf = values(&res, "rkf-ca", "edge_cov_trace");
    let ga = values(&res, "garkf", "edge_cov_trace");
    let (k1, k2) = (at(1000), at(2000));
    for r in 0..runs {
        // Unobserved CA model: the position variance is a polynomial in t whose leading term
        // is σ_w² t⁵/20 per coordinate; between 10 s and 20 s the lower-order terms (from the
        // initial covariance, ≤ t⁴) still lower the log-log slope a little below 5.
        let slope = (rkf[k2 * runs + r] / rkf[k1 * runs + r]).ln() / 2f64.ln();
        assert!((4.5..=5.0 + 1e-9).contains(&slope), "slope {slope}");
        // GA-RKF: the same edge is corrected geometrically every step; its covariance stays at
        // the level of R^geo + ψ, far below a metre² and not growing.
        assert!(ga[k2 * runs + r] < 1e-2, "{}", ga[k2 * runs + r]);
        assert!(
            ga[k2 * runs + r] <= 1.5 * ga[k1 * runs + r],
            "{} vs {}",
            ga[k2 * runs + r],
            ga[k1 * runs + r]
        );
    }
}

#[test]
fn garkf_covariance_is_below_rkf_ca_and_equals_its_pcrb() {
    let sc = scenario(
        800,
        3,
        1,
        "[faults]\navailability = 0.4\n[metrics]\nedge = [5, 0]",
    );
    let res = common::run(&sc);
    let rkf = values(&res, "rkf-ca", "edge_cov_trace");
    let ga = values(&res, "garkf", "edge_cov_trace");
    let pcrb = values(&res, "garkf", "pcrb_trace");
    let pcrb_rkf = values(&res, "rkf-ca", "pcrb_trace");
    let (rkf_all, ga_all) = (
        values(&res, "rkf-ca", "cov_trace"),
        values(&res, "garkf", "cov_trace"),
    );
    for n in 0..rkf.len() {
        // Same direct observations plus extra corrections: the Riccati map is monotone, so
        // Λ_ga ⪯ Λ_rkf, hence the traces are ordered (a relative 1e-12 allows for rounding).
        assert!(
            ga[n] <= rkf[n] * (1.0 + 1e-12),
            "{n}: {} > {}",
            ga[n],
            rkf[n]
        );
        assert!(ga_all[n] <= rkf_all[n] * (1.0 + 1e-12), "{n}");
        // A linear-Gaussian filter attains its PCRB: the same recursion in information form;
        // the two differ by rounding only.
        assert!(
            (pcrb[n] / ga[n] - 1.0).abs() < 1e-6,
            "{n}: {} vs {}",
            pcrb[n],
            ga[n]
        );
        assert!((pcrb_rkf[n] / rkf[n] - 1.0).abs() < 1e-6, "{n}");
    }
}

#[test]
fn new_estimators_are_bit_identical_for_any_thread_count() {
    let sc = scenario(
        300,
        5,
        10,
        "[faults]\navailability = 0.5\ndepartures = [{ agent = 6, at = 1.0, rejoin = 2.0 }]\n[maneuver]\nkeyframes = \"garkf-fig7b\"\n[control]\nfollower_gain = 5.0\n[metrics]\nedge = [5, 0]",
    );
    let with = |t: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap()
            .install(|| common::run(&sc))
    };
    // Bitwise: NaN (an undefined ψ, say) is equal to itself here, unlike with `==`.
    let bits = |r: &Results| -> Vec<Vec<Vec<u64>>> {
        r.estimators
            .iter()
            .map(|e| {
                e.values
                    .iter()
                    .chain([&e.paths])
                    .map(|v| v.iter().map(|x| x.to_bits()).collect())
                    .collect()
            })
            .collect()
    };
    let one = with(1);
    assert!(one.labels().contains(&"garkf") && one.labels().contains(&"rkf-ca"));
    for t in [2, 3] {
        let other = with(t);
        assert_eq!(one.steps, other.steps);
        assert_eq!(bits(&one), bits(&other), "{t} threads");
    }
}

/// Theorem 1 (Li & Rajan (19)–(20)): `E[ψ_i] ≤ c_i E[δ] + b_i`. Averaging over the agents (ψ is
/// reported as the mean over agents), `E[ψ] ≤ c̄ E[δ] + b̄` with c̄, b̄ the agents' means — checked
/// at every reported step of 40 runs of the maneuver at λ = 1. Monte Carlo error: in the 100-run
/// study (`garkf-fig9`) E[ψ] − b̄ is about a tenth of c̄ E[δ] at every step, far more than the
/// runs' spread, so the test allows no slack.
#[test]
fn convergence_indicator_obeys_theorem_1_on_average() {
    use edgekf::estimate::ral::{theorem1_coefficients, LocalGeometry, RalOptions};
    use nalgebra::Vector2;
    let sc = scenario(
        1500,
        40,
        10,
        "[maneuver]\nkeyframes = \"garkf-fig7b\"\n[control]\nfollower_gain = 1.0",
    );
    let fw = sc.framework();
    let g = fw.graph();
    let n = fw.agents();
    let cfg: Vec<Vector2<f64>> = (0..n)
        .map(|i| Vector2::new(fw.point(i)[0], fw.point(i)[1]))
        .collect();
    let trace_r = sc.model().mean_cov(1)[0].trace();
    let opts = RalOptions::default();
    let geo: Vec<LocalGeometry<2>> = (0..n)
        .map(|i| {
            let nb: Vec<usize> = g.neighbours(i).collect();
            LocalGeometry::new(&cfg, i, &nb, &opts).expect("every hexagon agent is feasible")
        })
        .collect();
    let (mut c, mut b) = (0.0, 0.0);
    for i in 0..n {
        let nbs: Vec<&LocalGeometry<2>> = g.neighbours(i).map(|j| &geo[j]).collect();
        let (ci, bi) = theorem1_coefficients(n, &geo[i], &nbs, trace_r).expect("coefficients");
        c += ci / n as f64;
        b += bi / n as f64;
    }
    let res = common::run(&sc);
    let runs = 40;
    let psi = values(&res, "garkf", "psi");
    let delta = values(&res, "garkf", "tracking_error");
    let mean = |v: &[f64], k: usize| v[k * runs..(k + 1) * runs].iter().sum::<f64>() / runs as f64;
    for k in 0..res.steps.len() {
        let (p, d) = (mean(psi, k), mean(delta, k));
        assert!(
            p <= c * d + b,
            "step {}: E[ψ] = {p} > {c}·{d} + {b}",
            res.steps[k]
        );
    }
}

/// Li & Rajan Fig. 12 / the issue's claim: after one follower departs, GA-RKF keeps δ (over the
/// agents present) near its no-failure value while the RKF's predictions go stale and its loop
/// diverges. "Near" is read as within a factor 2 of the same runs without the departure,
/// "diverges" as at least 100× that value; the two regimes are decades apart (`garkf-fig12`:
/// 0.135 vs ≥ 4.6e4 at 20–30 s), so the factors only separate them.
#[test]
fn after_a_departure_garkf_keeps_tracking_and_rkf_ca_diverges() {
    let common_toml = "[maneuver]\nkeyframes = \"garkf-fig7b\"\n[control]\nfollower_gain = 1.0";
    let (steps, runs) = (1400, 6);
    let base = scenario(steps, runs, 10, common_toml);
    // The RKF's loop is expected to diverge: allowed, so the run goes on to the end.
    let departed = scenario_with(
        steps,
        runs,
        10,
        "allow_divergence = true",
        &format!("[faults]\ndepartures = [{{ agent = 6, at = 4.0 }}]\n{common_toml}"),
    );
    let (a, b) = (common::run(&base), common::run(&departed));
    let from = common::at(&a, 12.0);
    let tail =
        |r: &Results, l: &str| common::tail_mean(values(r, l, "tracking_error"), from * runs);
    let nominal = tail(&a, "garkf");
    let (ga, rkf) = (tail(&b, "garkf"), tail(&b, "rkf-ca"));
    eprintln!("δ over 12–14 s: no failure {nominal}, garkf {ga}, rkf-ca {rkf}");
    assert!(nominal.is_finite() && nominal > 0.0);
    assert!(ga <= 2.0 * nominal, "garkf {ga} vs no failure {nominal}");
    assert!(
        rkf.is_nan() || rkf >= 100.0 * nominal,
        "rkf-ca {rkf} vs no failure {nominal}"
    );
}

/// ε of the consensus (16) is checked against 2/λ_max(L + diag|J_i|) of the nominal graph:
/// ε = 0.08 is below the hexagon's bound 0.1012 and accepted; 0.2 is refused naming the bound,
/// or scaled with `epsilon_policy = "scale"`. On the dense 50-agent graph of Fig. 13 (every pair
/// linked) the paper's 0.08 is above the bound and refused.
#[test]
fn consensus_step_is_checked_against_its_stability_bound() {
    let with = |est: &str, fw: &str| -> Result<Scenario, String> {
        let text = format!(
            "name = \"eps\"\nestimators = [{est}]\n{fw}\n[sim]\ndt = 0.01\nsteps = 10\nruns = 1\n"
        );
        let spec = edgekf_io::spec_from_toml(&text).map_err(|e| e.to_string())?;
        let file = spec.framework.file.as_ref().map(|_| {
            edgekf_io::framework::spec_from_json(include_str!(
                "../../../scenarios/frameworks/random50-dense.json"
            ))
            .unwrap()
        });
        Scenario::from_spec(&spec, file.as_ref()).map_err(|e| e.to_string())
    };
    let hex = "[framework]\npreset = \"hexagon\"";
    with("{ kind = \"garkf\", epsilon = 0.08 }", hex).expect("0.08 < 0.1012");
    let e = with("{ kind = \"garkf\", epsilon = 0.2 }", hex).unwrap_err();
    assert!(e.contains("stability bound") && e.contains("0.1012"), "{e}");
    with(
        "{ kind = \"garkf\", epsilon = 0.2, epsilon_policy = \"scale\" }",
        hex,
    )
    .expect("scaled");
    let dense = "[framework]\nfile = \"frameworks/random50-dense.json\"";
    let e = with("{ kind = \"garkf\", epsilon = 0.08 }", dense).unwrap_err();
    assert!(e.contains("stability bound"), "{e}");
}
