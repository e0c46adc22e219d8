//! Steady-state covariance ordering with spatially correlated disturbances (EUSIPCO §4, thesis
//! §5.4): crkf < jrkf < rkf < mle < none; without process noise the joint and single-edge
//! filters coincide (EUSIPCO §4, last paragraph). `cov_trace` is deterministic (the gains do not
//! depend on the data), so these are exact comparisons, not statistical ones.

mod common;

use common::{hexagon, names, run};

#[test]
fn steady_state_ordering_with_correlated_disturbances() {
    let sc = hexagon(
        0.001,
        0.1,
        3000,
        1,
        100,
        names(&["none", "mle", "rkf", "jrkf", "crkf"]),
    );
    let res = run(&sc);
    let last = |l: &str| *res.series(l, "cov_trace").unwrap().mean.last().unwrap();
    let (none, mle, rkf, jrkf, crkf) = (
        last("none"),
        last("mle"),
        last("rkf"),
        last("jrkf"),
        last("crkf"),
    );
    println!("none {none:.4e} mle {mle:.4e} rkf {rkf:.4e} jrkf {jrkf:.4e} crkf {crkf:.4e}");
    assert!(crkf < jrkf && jrkf < rkf && rkf < mle && mle < none);
    // The model's own numbers: none = Σ tr R = 60 · 2 σ_v², mle = none / T.
    assert!((none - 60.0 * 2.0 * 0.01).abs() < 1e-12);
    assert!((mle - none / 10.0).abs() < 1e-12);
    // The joint filter gains from the correlation: more than 5 % below the RKF here.
    assert!(jrkf < 0.95 * rkf);
}

#[test]
fn without_process_noise_joint_and_single_edge_filters_coincide() {
    let sc = hexagon(0.0, 0.1, 3000, 1, 100, names(&["rkf", "jrkf"]));
    let res = run(&sc);
    let rkf = &res.series("rkf", "cov_trace").unwrap().mean;
    let jrkf = &res.series("jrkf", "cov_trace").unwrap().mean;
    let k = rkf.len() - 1;
    // Both decay like tr(R/T)/k; the joint filter's only extra information is the initial
    // correlation B_iᵀB_i ⊗ P, whose effect is O(1/k²): relative O(tr(R/T)/(k tr P)) ≈ 1e-7.
    let rel = (jrkf[k] - rkf[k]).abs() / rkf[k];
    println!(
        "k = 3000: rkf {:.6e} jrkf {:.6e} rel {rel:.2e}",
        rkf[k], jrkf[k]
    );
    assert!(rel < 1e-4, "relative difference {rel}");
    assert!(
        rkf[k] < 1e-3 * rkf[0],
        "both keep decreasing without process noise"
    );
}
