//! The papers' claims, at reduced size (issue 2, point 10).

mod common;

use common::{build, hexagon, names, run, spec, table, tail_mean};
use edgekf::scenario::{EstimatorEntry, Scenario};

fn with_gain(
    gain: f64,
    sigma_v: f64,
    steps: usize,
    runs: usize,
    every: usize,
    est: Vec<EstimatorEntry>,
) -> Scenario {
    let mut s = spec(0.0, sigma_v, steps, runs, every, est);
    s.control.follower_gain = gain;
    s.control.leader_gain = gain;
    build(&s)
}

/// Thesis Fig. 3.3: without noise the loop converges exponentially to a rigid formation.
#[test]
fn noiseless_loop_converges_to_a_rigid_formation() {
    let sc = hexagon(0.0, 0.0, 10_000, 4, 100, names(&["none"]));
    let res = run(&sc);
    let p = &res.series("none", "procrustes").unwrap().mean;
    let at = |t: f64| {
        p[res
            .steps
            .iter()
            .position(|&k| k as f64 * sc.dt() >= t)
            .unwrap()]
    };
    // Exponential decay: the log-slope between 5 s and 10 s is the slowest closed-loop rate; the
    // hexagon's measured rate is ≈ 0.44 /s, so 0.3 /s leaves room for run-to-run spread of 4 runs.
    let rate = (at(5.0) / at(10.0)).ln() / 5.0;
    println!(
        "procrustes: t=0 {:.3e}, 5 s {:.3e}, 10 s {:.3e}, rate {rate:.3}/s",
        p[0],
        at(5.0),
        at(10.0)
    );
    assert!(rate > 0.3, "rate {rate}");
    assert!(at(10.0) < 2e-2 * p[0]);
}

/// Thesis Fig. 4.5: the MLE's Procrustes floor is ≈ √T below the floor without estimator.
///
/// In steady state the position error is a linear response to the measurement noise (small-noise
/// regime), and both loops see the same normals (common random numbers), scaled by 1/√T for the
/// MLE: the ratio of floors is √T up to the leaders' nonlinearity and the finite window. Follower
/// and leader gains 10 make the floor reached within 3 s; 10 % covers the measured deviation
/// (0.6 % at 20 runs, 7 % with gain 1 where the larger noise of `none` bends the leaders' law).
#[test]
fn mle_floor_is_sqrt_t_below_no_estimator() {
    let sc = with_gain(10.0, 0.1, 10_000, 8, 50, names(&["none", "mle"]));
    let res = run(&sc);
    let half = res.steps.len() / 2;
    let none = tail_mean(&res.series("none", "procrustes").unwrap().mean, half);
    let mle = tail_mean(&res.series("mle", "procrustes").unwrap().mean, half);
    let ratio = none / mle;
    println!(
        "none {none:.3e} mle {mle:.3e} ratio {ratio:.3} (√10 = {:.3})",
        10f64.sqrt()
    );
    assert!((ratio / 10f64.sqrt() - 1.0).abs() < 0.1, "ratio {ratio}");
}

/// Thesis Fig. 4.8: with observation noise only the RKF's Procrustes floor is far below the
/// MLE's. The size of the gap depends on the loop bandwidth: the MLE's white errors are averaged
/// by the loop over ≈ 1/λ, while the RKF (no process noise) averages all k·T samples so far. At
/// 30 s we measured 3.1× with the hexagon's gains 1 and 9.6× (the thesis's "≈ 10×") with gains 10
/// (20 runs). The bounds 2× and 6× sit well inside those (the floors' run-to-run spread is
/// ≈ 30 %, over 6 runs ≈ 12 %).
#[test]
fn rkf_floor_far_below_mle_with_observation_noise_only() {
    for (gain, bound) in [(1.0, 2.0), (10.0, 6.0)] {
        let sc = with_gain(gain, 0.1, 30_000, 6, 100, names(&["mle", "rkf"]));
        let res = run(&sc);
        let from = res.steps.iter().position(|&k| k >= 25_000).unwrap();
        let mle = tail_mean(&res.series("mle", "procrustes").unwrap().mean, from);
        let rkf = tail_mean(&res.series("rkf", "procrustes").unwrap().mean, from);
        println!(
            "gain {gain}: mle {mle:.3e} rkf {rkf:.3e} ratio {:.2}",
            mle / rkf
        );
        assert!(mle / rkf > bound, "gain {gain}: ratio {}", mle / rkf);
    }
}

/// MMSE (thesis §4.4): with a very wide prior it is the MLE; a tight prior converges more slowly
/// (Fig. 4.6).
#[test]
fn mmse_interpolates_between_mle_and_a_slow_filter() {
    let sc = hexagon(
        0.0,
        0.1,
        3000,
        4,
        100,
        vec![
            table("mle", "mle", None, None),
            table("mmse", "wide", None, Some(1e3)),
            table("mmse", "tight", None, Some(1e-5)),
        ],
    );
    let res = run(&sc);
    let mle = &res.series("mle", "est_error").unwrap().mean;
    let wide = &res.series("wide", "est_error").unwrap().mean;
    let tight = &res.series("tight", "est_error").unwrap().mean;
    for k in 0..mle.len() {
        assert!(
            (mle[k] - wide[k]).abs() < 1e-3 * mle[k],
            "a 1e3 prior is the MLE to 1e-6 relative gain"
        );
    }
    // Early on (agents moving fast) the tight prior lags far behind the truth.
    assert!(tight[5] > 3.0 * mle[5], "tight {} mle {}", tight[5], mle[5]);
    let ct = res.series("tight", "cov_trace").unwrap().mean[0];
    assert!(
        ct < res.series("mle", "cov_trace").unwrap().mean[0],
        "(Σ⁻¹ + T R⁻¹)⁻¹ < R/T"
    );
}
