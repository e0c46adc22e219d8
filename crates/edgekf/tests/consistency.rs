//! Filter consistency: each Kalman filter here is exact for its own model, so its mean squared
//! error equals the trace of its posterior covariance (issue 2, point 10), and covariances stay
//! symmetric positive semidefinite.

#![allow(clippy::needless_range_loop)]

mod common;

use common::{hexagon, names, run};
use edgekf::estimate::{Estimator, Faults, Step};

/// z-test of E[ε²] = tr Σ per filter.
///
/// For each run the squared error is averaged over the steady-state window (report steps from
/// 1000 on, every 50th step: 21 per run); the runs are independent, so the mean over R runs has
/// standard error s/√R with s the sample std of the per-run averages. Under the hypothesis
/// "mean squared error = covariance trace" the z-score is ~N(0, 1); |z| < 4.5 fails with
/// probability 7e-6 per check (three filters, two windows: < 5e-5 in all), while a filter whose
/// error is 10 % off its covariance gives |z| ≈ 0.1 / (s/√R / tr) ≫ 4.5 here (s/tr ≈ 0.1 for
/// R = 200, so a 10 % bias is z ≈ 14).
#[test]
fn mean_squared_error_equals_covariance_trace() {
    let runs = 200;
    let sc = hexagon(0.001, 0.1, 2000, runs, 50, names(&["rkf", "jrkf", "crkf"]));
    let res = run(&sc);
    let from = res.steps.iter().position(|&k| k >= 1000).unwrap();
    let nr = res.steps.len();
    for label in res.labels() {
        let per_run = res.values(label, "est_error_sq").unwrap();
        // Early window: the very first update (k = 1), where Σ is far from steady state.
        for window in [0..1, from..nr] {
            let avgs: Vec<f64> = (0..runs)
                .map(|r| {
                    window.clone().map(|k| per_run[k * runs + r]).sum::<f64>() / window.len() as f64
                })
                .collect();
            let mean = avgs.iter().sum::<f64>() / runs as f64;
            let sd =
                (avgs.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / (runs - 1) as f64).sqrt();
            let ct = res.series(label, "cov_trace").unwrap();
            let trace = window.clone().map(|k| ct.mean[k]).sum::<f64>() / window.len() as f64;
            let z = (mean - trace) / (sd / (runs as f64).sqrt());
            println!(
                "{label} window {window:?}: mse {mean:.5e} trace {trace:.5e} ratio {:.4} z {z:.2}",
                mean / trace
            );
            assert!(z.abs() < 4.5, "{label}: mean squared error {mean:.4e} vs covariance trace {trace:.4e} (z = {z:.2})");
        }
    }
}

/// Covariances stay symmetric PSD step after step, and the node-space CRKF has exactly the
/// covariance trace of the edge-space recursion (EUSIPCO eq. 9) it replaces.
#[test]
fn covariances_stay_psd_and_node_space_crkf_matches_edge_space() {
    let sc = hexagon(0.001, 0.1, 10, 1, 1, names(&["jrkf"]));
    let m = sc.model();
    let t = sc.samples();
    let mut jrkf = edgekf::estimate::jrkf::Jrkf::new(m, t, 1, None, true);
    let mut crkf = edgekf::estimate::crkf::Crkf::new(m, t, 1, true);
    let (ne, d, n) = (m.num_edges(), m.dim(), m.agents());
    let zeros_e = vec![0.0; ne * d];
    let zeros_n = vec![0.0; n * d];
    let faults = Faults::none(n, m.edges(), 1);
    let input = Step {
        k: 1,
        dt: sc.dt(),
        y: &zeros_e,
        means: edgekf::estimate::Means::formed(&zeros_e, d, 1),
        u_prev: &zeros_n,
        du: &zeros_e,
        faults: &faults,
        truth: &zeros_e,
        target: None,
    };
    let w_edges = m.mean_cov(t);
    // Edge-space CRKF (9d)–(9g) in the full M·D = 120 dimensions, Joseph form.
    let md = ne * d;
    let mut sigma = nalgebra::DMatrix::zeros(md, md);
    let mut qx = nalgebra::DMatrix::zeros(md, md);
    let mut w = nalgebra::DMatrix::zeros(md, md);
    for e in 0..ne {
        for f in 0..ne {
            sigma
                .view_mut((e * d, f * d), (d, d))
                .copy_from(&m.edge_p0(e, f));
            qx.view_mut((e * d, f * d), (d, d))
                .copy_from(&m.edge_q(e, f));
        }
        w.view_mut((e * d, e * d), (d, d)).copy_from(&w_edges[e]);
    }
    for step in 0..10 {
        jrkf.step(&input);
        crkf.step(&input);
        let prior = &sigma + &qx;
        let s = &prior + &w;
        let k = &prior * s.try_inverse().unwrap();
        let a = nalgebra::DMatrix::identity(md, md) - &k;
        sigma = &a * &prior * a.transpose() + &k * &w * k.transpose();
        let mut trace = [0.0];
        crkf.cov_trace(&input, &mut trace);
        let rel = (sigma.trace() - trace[0]).abs() / sigma.trace();
        assert!(
            rel < 1e-9,
            "step {step}: edge-space trace {} vs node-space {}",
            sigma.trace(),
            trace[0]
        );
        for i in 0..n {
            let c = jrkf.covariance(i, 0);
            assert!(
                (c - c.transpose()).amax() == 0.0,
                "JRKF covariance symmetric"
            );
            let ev = c.clone().symmetric_eigen().eigenvalues;
            assert!(ev.min() > -1e-15 * ev.max(), "JRKF covariance PSD");
        }
        let c = crkf.node_covariance(0);
        assert!((c - c.transpose()).amax() == 0.0);
        assert!(c.clone().symmetric_eigen().eigenvalues.min() > 0.0);
    }
}
