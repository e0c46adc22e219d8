//! Claim 7b: CARE residuals tiny, P̄_i > 0, Ā¹¹ − K̄H̄ Hurwitz; the CARE as printed has Hamiltonian eigenvalues on
//! the imaginary axis and no stabilising solution.
mod common;

use edgekf_slam::care::CareError;
use edgekf_slam::observer::printed_care;

#[test]
fn care_solutions_are_verified() {
    let sc = common::scenario(common::FIG3);
    for (i, ob) in sc.observers().iter().enumerate() {
        let c = &ob.care;
        // A backward-stable solve gives a relative residual of a small multiple of r·ε (r ≤ 12 here, ε = 2.2e-16);
        // 1e-13 allows a condition-number factor of ~40.
        assert!(
            c.relative_residual < 1e-13,
            "robot {i}: {}",
            c.relative_residual
        );
        assert!(c.min_eig > 0.0, "robot {i}");
        assert!(c.closed_loop_abscissa < 0.0, "robot {i}");
        // Recompute the residual independently from the stored matrices.
        let s = ob.h_bar.transpose() * ob.r.clone().try_inverse().unwrap() * &ob.h_bar;
        let w = nalgebra::DMatrix::<f64>::identity(ob.a11.nrows(), ob.a11.nrows()) * sc.q();
        let res = &ob.a11 * &c.p + &c.p * ob.a11.transpose() + &w - &c.p * &s * &c.p;
        assert!(res.norm() < 1e-12, "robot {i}: {}", res.norm());
        // K_i = Z_i P̄ H̄ᵀ R⁻¹ lives in the observable subspace.
        assert!((ob.decomposition.w.transpose() * &ob.k).amax() < 1e-12);
    }
}

#[test]
fn printed_care_has_imaginary_axis_eigenvalues() {
    let sc = common::scenario(common::FIG3);
    for (i, ob) in sc.observers().iter().enumerate() {
        let pc = printed_care(sc.model(), ob, sc.q());
        // Each of the 2c_i landmark coordinates of Ā¹¹ is a zero mode without noise weight: a pair of Hamiltonian
        // eigenvalues at 0 each. The tolerance is care::IMAG_AXIS_TOL·‖𝓗‖ (see its justification).
        let c_i = sc.model().landmark_sets[i].len();
        assert_eq!(pc.on_axis, 2 * 2 * c_i, "robot {i}");
        assert!(
            pc.closest_eigenvalue.re.abs() < 1e-12 * pc.hamiltonian_norm,
            "robot {i}"
        );
        assert!(
            matches!(pc.result, Err(CareError::ImaginaryAxisEigenvalue { .. })),
            "robot {i}"
        );
    }
}
