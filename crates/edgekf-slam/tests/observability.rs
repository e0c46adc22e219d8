//! Claim 7a: (A, H_i) is not observable for any §6 robot, but (Ā_i¹¹, H̄_i) is; the numerical decomposition
//! (eq. 18) has the structure the paper states.
mod common;

use edgekf_slam::linalg::{kalman_decomposition, observable_dimension};

#[test]
fn a_h_i_unobservable_and_reduced_pair_observable() {
    let sc = common::scenario(common::FIG3);
    let (n, m) = (sc.n(), sc.m());
    let dim = 2 * (n + m);
    for (i, ob) in sc.observers().iter().enumerate() {
        let c_i = sc.model().landmark_sets[i].len();
        // Observable dimension 2n + 2c_i < 2(n + m): robots and the landmarks of M_i (§4.1).
        let r = observable_dimension(&sc.model().a, &sc.model().h[i]);
        assert_eq!(r, 2 * n + 2 * c_i, "robot {i}");
        assert!(r < dim, "robot {i}: (A, H_i) must not be observable");
        // (Ā¹¹, H̄) is observable: its own unobservable subspace is {0}.
        assert_eq!(observable_dimension(&ob.a11, &ob.h_bar), r, "robot {i}");
        // Eq. (18): Zᵀ A W = 0 and H W = 0; T orthogonal. Entries are O(1) sums of products of orthonormal
        // bases, so 1e-12 leaves ~1e3 ε of room for the SVD roundoff.
        let kd = &ob.decomposition;
        assert!((kd.z.transpose() * &sc.model().a * &kd.w).amax() < 1e-12);
        assert!((&sc.model().h[i] * &kd.w).amax() < 1e-12);
        let t = nalgebra::DMatrix::from_columns(
            &kd.z
                .column_iter()
                .chain(kd.w.column_iter())
                .map(|c| c.into_owned())
                .collect::<Vec<_>>(),
        );
        assert!((t.transpose() * &t - nalgebra::DMatrix::<f64>::identity(dim, dim)).amax() < 1e-12);
        // The unobservable subspace is exactly the landmarks outside M_i (the §6 permutation form).
        let proj = &kd.w * kd.w.transpose();
        for k in 0..dim {
            let unseen = k >= 2 * n && !sc.model().landmark_sets[i].contains(&((k - 2 * n) / 2));
            let expect = if unseen { 1.0 } else { 0.0 };
            assert!(
                (proj[(k, k)] - expect).abs() < 1e-12,
                "robot {i}, coordinate {k}"
            );
        }
    }
}

#[test]
fn decomposition_works_for_a_non_permutation_model() {
    // A generic model: the observable subspace is not spanned by coordinate vectors.
    let a =
        nalgebra::DMatrix::from_row_slice(3, 3, &[-1.0, 1.0, 1.0, 0.0, -2.0, 0.0, 0.0, 0.0, -2.0]);
    let h = nalgebra::DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0]);
    // x2 and x3 enter x1' identically with the same dynamics, so only x2 + x3 is observable.
    let kd = kalman_decomposition(&a, &h);
    assert_eq!(kd.z.ncols(), 2);
    let w = kd.w.column(0);
    assert!(w[0].abs() < 1e-12 && (w[1] + w[2]).abs() < 1e-12);
}

/// The control law of eqs. (3)–(4) applied directly equals the compact closed loop of eq. (14),
/// `A x + B u + d` with `u = 1 ⊗ (ṗ_c* + k₁ p_c*) + k₂(𝓛_f ⊗ I)P*` (with the dot restored) and `d = −k₂[D E; 0]`.
#[test]
fn control_law_equals_compact_closed_loop() {
    let sc = common::scenario(common::FIG3);
    let (n, dim) = (sc.n(), sc.model().dim());
    let x = nalgebra::DVector::from_fn(dim, |k, _| ((k * 13 + 5) % 17) as f64 / 3.0 - 2.0);
    let xhat: Vec<nalgebra::DVector<f64>> = (0..n)
        .map(|i| {
            nalgebra::DVector::from_fn(dim, |k, _| ((k * 7 + 11 * i + 1) % 19) as f64 / 4.0 - 2.0)
        })
        .collect();
    let t = 1.37;
    let refs: Vec<&[f64]> = xhat.iter().map(|v| v.as_slice()).collect();
    let direct = sc.model().control(t, x.as_slice(), &refs);
    let e = nalgebra::DVector::from_fn(n * dim, |r, _| xhat[r / dim][r % dim] - x[r % dim]);
    let compact = &sc.model().a * &x + sc.model().input(t) - {
        let mut d = nalgebra::DVector::zeros(dim);
        d.rows_mut(0, 2 * n)
            .copy_from(&(&sc.model().d * &e * sc.model().k2));
        d
    };
    // Entries are O(10); the two forms sum the same terms in a different order: 1e-12 is roundoff room.
    assert!((direct - compact.rows(0, 2 * n)).amax() < 1e-12);
    assert!(compact.rows(2 * n, dim - 2 * n).amax() < 1e-15);
}
