//! Claim: the Theorem 1 report for the §6 gains — (24) holds (with −1/δ), (25) fails, yet the error system is
//! Hurwitz; eq. (10)'s consensus sign destabilises; the printed +1/δ breaks the Lyapunov bound (26).
mod common;

use edgekf_slam::linalg::min_sym_eigenvalue;
use nalgebra::DVector;

#[test]
fn section6_gains_fail_25_but_errors_converge() {
    let sc = common::scenario(common::FIG3);
    let r = sc.theorem1();
    assert!(r.condition24 && r.zeta_sup > 0.5, "{r:?}");
    // λ_min and ξ are exact here: Wᵀ(L_c⊗I)W restricted to one unseen landmark per robot pair gives 1, ξ = √2
    // (measured 1 − 8e-16 and 1.41421356237309(6)); 1e-12 is roundoff room.
    assert!((r.lambda_min - 1.0).abs() < 1e-12);
    assert!((r.xi - 2f64.sqrt()).abs() < 1e-12);
    assert!(!r.condition25 && r.condition25_sup < 0.0 && r.witness.is_none());
    assert!(r.error_abscissa < -0.5, "{}", r.error_abscissa);
    assert!(r.error_abscissa_eq10 > 1.0, "{}", r.error_abscissa_eq10);
}

#[test]
fn small_q_satisfies_both_conditions_with_a_witness() {
    let mut spec = common::spec(common::FIG3);
    spec.observer.q = 0.01;
    let sc = spec.validate().unwrap();
    let r = sc.theorem1();
    let (delta, tau) = r.witness.expect("(24)-(25) hold for q = 0.01");
    assert!(min_sym_eigenvalue(&r.omega(delta, false)) > 0.0);
    assert!(r.m_matrix.symmetric_eigenvalues().min() > 0.0);
    assert!(tau > 0.0 && r.error_abscissa < 0.0);
}

/// `V̇_ob` of the proof along `ė_o = (Ā − K̄H̄) e_o + k₂ diag(Zᵀ) D̄ diag(Z) e_o + w` equals
/// `eᵀ(P̄⁻¹F + FᵀP̄⁻¹)e + 2 eᵀΨe + 2 eᵀP̄⁻¹w`. The bound (26) `V̇ ≤ −eᵀΩ(δ)e + δ‖w‖²` holds for all e, w with
/// −1/δ; with the printed +1/δ it fails for `w = δ⁻¹ P̄⁻¹ e` (the equality case of Young's inequality).
#[test]
fn plus_one_over_delta_breaks_the_lyapunov_bound() {
    let sc = common::scenario(common::FIG3);
    let r = sc.theorem1();
    let blocks: Vec<_> = sc
        .observers()
        .iter()
        .map(|o| &o.a11 - &o.k_bar * &o.h_bar)
        .collect();
    let total: usize = blocks.iter().map(|b| b.nrows()).sum();
    let mut f = nalgebra::DMatrix::zeros(total, total);
    let mut off = 0;
    for b in &blocks {
        f.view_mut((off, off), b.shape()).copy_from(b);
        off += b.nrows();
    }
    let vdot = |e: &DVector<f64>, w: &DVector<f64>| -> f64 {
        let pf = &r.p_inv * &f;
        (e.transpose() * (&pf + pf.transpose()) * e)[0]
            + 2.0 * (e.transpose() * &r.psi * e)[0]
            + 2.0 * (e.transpose() * &r.p_inv * w)[0]
    };
    let delta = 0.7;
    let e = DVector::from_fn(total, |k, _| ((k * 7 + 3) % 11) as f64 / 11.0 - 0.4);
    let w = &r.p_inv * &e / delta;
    let bound =
        |plus: bool| -(e.transpose() * r.omega(delta, plus) * &e)[0] + delta * w.norm_squared();
    let v = vdot(&e, &w);
    // Young's inequality is tight at this w: with −1/δ the bound holds with equality (up to roundoff, 1e-9 of
    // the terms' size ~10²), with +1/δ it is exceeded by 2δ⁻¹‖P̄⁻¹e‖².
    assert!(
        v <= bound(false) + 1e-9 * v.abs().max(1.0),
        "{v} vs {}",
        bound(false)
    );
    let gap = v - bound(true);
    assert!(
        gap > 0.0 && (gap - 2.0 / delta * (&r.p_inv * &e).norm_squared()).abs() < 1e-9 * gap,
        "{gap}"
    );
    // For arbitrary (e, w) the corrected bound holds.
    for s in 0..20 {
        let e = DVector::from_fn(total, |k, _| {
            (((k + 1) * (s + 3) * 37) % 101) as f64 / 50.0 - 1.0
        });
        let w = DVector::from_fn(total, |k, _| {
            (((k + 5) * (s + 1) * 53) % 97) as f64 / 48.0 - 1.0
        });
        let b = -(e.transpose() * r.omega(delta, false) * &e)[0] + delta * w.norm_squared();
        assert!(vdot(&e, &w) <= b + 1e-9 * b.abs().max(1.0));
    }
}
