//! Dense linear-algebra helpers: the orthogonal Kalman observability decomposition (eq. 18), eigenvalues and the
//! spectral abscissa.

use nalgebra::{Complex, DMatrix, Schur};

/// Relative rank tolerance used by the subspace computations (singular values below `RANK_TOL · scale` are zero).
pub const RANK_TOL: f64 = 1e-9;

/// The orthogonal Kalman decomposition `T_i = [Z_i W_i]` of eq. (18).
///
/// `W` is an orthonormal basis of the unobservable subspace of `(A, H)` (the largest `A`-invariant subspace in
/// `ker H`), `Z` an orthonormal basis of its orthogonal complement. Then `Zᵀ A W = 0` and `H W = 0`, so
/// `Tᵀ A T = [[Ā¹¹, 0], [Ā²¹, Ā²²]]` and `H T = [H̄, 0]` with `(Ā¹¹, H̄)` observable.
#[derive(Debug, Clone)]
pub struct KalmanDecomposition {
    /// Observable part `Z` (`N × r`), orthonormal columns.
    pub z: DMatrix<f64>,
    /// Unobservable part `W` (`N × (N − r)`), orthonormal columns.
    pub w: DMatrix<f64>,
}

/// Orthonormal basis of the null space of `m` (`rows × cols`), by SVD of `m` padded to at least `cols` rows.
pub fn null_space(m: &DMatrix<f64>, tol: f64) -> DMatrix<f64> {
    let cols = m.ncols();
    if cols == 0 {
        return DMatrix::zeros(0, 0);
    }
    let rows = m.nrows().max(cols);
    let mut padded = DMatrix::zeros(rows, cols);
    padded.view_mut((0, 0), (m.nrows(), cols)).copy_from(m);
    let svd = padded.svd(false, true);
    let vt = svd.v_t.expect("SVD was asked for V");
    let keep: Vec<usize> = (0..cols)
        .filter(|&k| svd.singular_values[k] <= tol)
        .collect();
    DMatrix::from_fn(cols, keep.len(), |r, c| vt[(keep[c], r)])
}

/// Orthonormal basis of the orthogonal complement of the span of the orthonormal columns `w` in `ℝᴺ`.
pub fn orthogonal_complement(w: &DMatrix<f64>, n: usize) -> DMatrix<f64> {
    if w.ncols() == 0 {
        return DMatrix::identity(n, n);
    }
    // Null space of wᵀ.
    null_space(&w.transpose(), 0.5)
}

/// Computes the orthogonal Kalman decomposition (eq. 18) of `(A, H)` numerically, for any model.
///
/// The unobservable subspace is found by the deflation `V₀ = ker H`, `V_{k+1} = {v ∈ V_k : A v ∈ V_k}`, which
/// avoids the badly scaled powers `H Aᵏ` of the observability matrix.
pub fn kalman_decomposition(a: &DMatrix<f64>, h: &DMatrix<f64>) -> KalmanDecomposition {
    let n = a.nrows();
    let scale = a.norm().max(h.norm()).max(1.0);
    let tol = RANK_TOL * scale;
    let mut v = null_space(h, tol);
    loop {
        let d = v.ncols();
        if d == 0 {
            break;
        }
        let av = a * &v;
        let proj = &av - &v * (v.transpose() * &av);
        let c = null_space(&proj, tol);
        if c.ncols() == d {
            break;
        }
        v = &v * c;
    }
    let z = orthogonal_complement(&v, n);
    KalmanDecomposition { z, w: v }
}

/// Eigenvalues of a real square matrix (real Schur form), or `None` when the QR iteration does not converge.
///
/// nalgebra's Schur deflation test with `ε = f64::EPSILON` can stall on the error-system matrices here (many
/// structurally zero subdiagonals); the deflation threshold is relaxed step by step to `1e-14`, `1e-12`, which
/// perturbs eigenvalues by at most about that times `‖m‖`.
pub fn eigenvalues(m: &DMatrix<f64>) -> Option<Vec<Complex<f64>>> {
    if m.nrows() == 0 {
        return Some(Vec::new());
    }
    for eps in [4.0 * f64::EPSILON, 1e-14, 1e-12] {
        if let Some(schur) = Schur::try_new(m.clone(), eps, 20_000) {
            return Some(schur.complex_eigenvalues().iter().copied().collect());
        }
    }
    None
}

/// Spectral abscissa `max Re λ(m)` (`NaN` when the eigenvalue iteration fails).
pub fn spectral_abscissa(m: &DMatrix<f64>) -> f64 {
    eigenvalues(m).map_or(f64::NAN, |ev| {
        ev.iter().map(|z| z.re).fold(f64::NEG_INFINITY, f64::max)
    })
}

/// Spectral radius `max |λ(m)|` (`NaN` when the eigenvalue iteration fails).
pub fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    eigenvalues(m).map_or(f64::NAN, |ev| {
        ev.iter().map(|z| z.norm()).fold(0.0, f64::max)
    })
}

/// Smallest eigenvalue of the symmetric part of `m`.
pub fn min_sym_eigenvalue(m: &DMatrix<f64>) -> f64 {
    let s = (m + m.transpose()) * 0.5;
    s.symmetric_eigenvalues()
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
}

/// Rank of the matrix `[m; m a; …; m a^{N−1}]` computed by the same deflation: `N − dim` of the unobservable
/// subspace. Returns the dimension `r` of the observable subspace of `(a, m)`.
pub fn observable_dimension(a: &DMatrix<f64>, h: &DMatrix<f64>) -> usize {
    kalman_decomposition(a, h).z.ncols()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decomposition_of_a_double_integrator_with_a_hidden_state() {
        // x1' = x2, x2' = 0, x3' = 0, y = x1: x3 unobservable.
        let a = DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let h = DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0]);
        let kd = kalman_decomposition(&a, &h);
        assert_eq!(kd.z.ncols(), 2);
        assert_eq!(kd.w.ncols(), 1);
        assert!((kd.w[(2, 0)].abs() - 1.0).abs() < 1e-12);
        assert!((kd.z.transpose() * &a * &kd.w).norm() < 1e-12);
        assert!((&h * &kd.w).norm() < 1e-12);
    }

    #[test]
    fn abscissa_of_a_rotation_plus_damping() {
        let m = DMatrix::from_row_slice(2, 2, &[-0.5, 2.0, -2.0, -0.5]);
        assert!((spectral_abscissa(&m) + 0.5).abs() < 1e-12);
        assert!((spectral_radius(&m) - (4.25_f64).sqrt()).abs() < 1e-12);
    }
}
