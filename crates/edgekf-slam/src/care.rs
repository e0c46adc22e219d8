//! Continuous algebraic Riccati equation of the filter type, eq. (20):
//!
//! `Ā P + P Āᵀ + W − P S P = 0`, with `W = Ḡ Q Ḡᵀ ⪰ 0` and `S = H̄ᵀ R⁻¹ H̄ ⪰ 0`.
//!
//! The stabilising solution (the one with `Ā − P S` Hurwitz) is the graph `P = U₂ U₁⁻¹` of the stable invariant
//! subspace `[U₁; U₂]` of the Hamiltonian
//!
//! `𝓗 = [[Āᵀ, −S], [−W, −Ā]]`.
//!
//! It exists iff `𝓗` has no eigenvalue on the imaginary axis (given stabilisability/detectability). The solver
//! (i) checks the Hamiltonian spectrum, (ii) computes the stable subspace with the matrix sign function (Newton
//! iteration with determinant scaling; Byers 1987, Gardiner & Laub 1986), (iii) refines the result with
//! Newton–Kleinman steps whose Lyapunov equations are solved by the sign function as well (Roberts 1980), and
//! (iv) verifies the residual, `P > 0` and the Hurwitz property of `Ā − P S`. Pure Rust, dense, `O(r³)` per step.
//!
//! # References
//! - R. Byers, "Solving the algebraic Riccati equation with the matrix sign function", LAA 85 (1987).
//! - J. D. Roberts, "Linear model reduction and solution of the algebraic Riccati equation by use of the sign
//!   function", Int. J. Control 32 (1980).
//! - D. L. Kleinman, "On an iterative technique for Riccati equation computations", IEEE TAC 13 (1968).

use crate::linalg::{eigenvalues, min_sym_eigenvalue, spectral_abscissa};
use nalgebra::{Complex, DMatrix};

/// Eigenvalues with `|Re λ| ≤ IMAG_AXIS_TOL · ‖𝓗‖_F` count as lying on the imaginary axis.
///
/// Eigenvalues of a Jordan block of size `k` at 0 are perturbed by roundoff to about `ε^{1/k}·‖𝓗‖`; a block of
/// size 2 gives ≈ 1.5e-8, so the threshold sits above that and far below every genuine stable mode of the models
/// here (≥ 1e-2 in magnitude).
pub const IMAG_AXIS_TOL: f64 = 1e-6;

/// A numerical failure of the CARE solver.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CareError {
    /// The Hamiltonian has an eigenvalue on the imaginary axis: no stabilising solution exists.
    #[error("the Hamiltonian has an eigenvalue {re:+e}{im:+e}i on the imaginary axis, so the CARE has no stabilising solution")]
    ImaginaryAxisEigenvalue {
        /// Real part of the offending eigenvalue.
        re: f64,
        /// Imaginary part.
        im: f64,
    },
    /// The eigenvalue or sign iteration did not converge, or a matrix to be inverted was singular.
    #[error("the {what} failed to converge")]
    NoConvergence {
        /// Which iteration.
        what: &'static str,
    },
    /// The computed solution is not positive definite.
    #[error("the solution is not positive definite (smallest eigenvalue {min_eig:e})")]
    NotPositiveDefinite {
        /// Its smallest eigenvalue.
        min_eig: f64,
    },
    /// The computed solution does not stabilise `Ā − P S`.
    #[error("the solution is not stabilising (spectral abscissa of Ā − P S = {abscissa:e})")]
    NotStabilising {
        /// `max Re λ(Ā − P S)`.
        abscissa: f64,
    },
}

/// The stabilising solution of eq. (20) and its verification.
#[derive(Debug, Clone)]
pub struct CareSolution {
    /// `P̄` (symmetric positive definite).
    pub p: DMatrix<f64>,
    /// `‖Ā P + P Āᵀ + W − P S P‖_F`.
    pub residual: f64,
    /// The residual divided by `2‖Ā P‖_F + ‖W‖_F + ‖P S P‖_F`.
    pub relative_residual: f64,
    /// Smallest eigenvalue of `P̄` (> 0).
    pub min_eig: f64,
    /// Spectral abscissa of `Ā − P̄ S` (< 0).
    pub closed_loop_abscissa: f64,
    /// Smallest `|Re λ|` over the Hamiltonian's eigenvalues.
    pub hamiltonian_min_abs_re: f64,
    /// Newton–Kleinman refinement steps taken.
    pub newton_steps: usize,
}

/// The Hamiltonian `[[Āᵀ, −S], [−W, −Ā]]` of the filter CARE `Ā P + P Āᵀ + W − P S P = 0`.
pub fn hamiltonian(a: &DMatrix<f64>, s: &DMatrix<f64>, w: &DMatrix<f64>) -> DMatrix<f64> {
    let r = a.nrows();
    let mut h = DMatrix::zeros(2 * r, 2 * r);
    h.view_mut((0, 0), (r, r)).copy_from(&a.transpose());
    h.view_mut((0, r), (r, r)).copy_from(&(-s));
    h.view_mut((r, 0), (r, r)).copy_from(&(-w));
    h.view_mut((r, r), (r, r)).copy_from(&(-a));
    h
}

/// The Hamiltonian eigenvalue closest to the imaginary axis.
///
/// # Errors
/// [`CareError::NoConvergence`] when the Schur iteration fails.
pub fn closest_to_imaginary_axis(h: &DMatrix<f64>) -> Result<Complex<f64>, CareError> {
    let ev = eigenvalues(h).ok_or(CareError::NoConvergence {
        what: "Hamiltonian Schur iteration",
    })?;
    Ok(ev
        .into_iter()
        .fold(Complex::new(f64::INFINITY, 0.0), |best, z| {
            if z.re.abs() < best.re.abs() {
                z
            } else {
                best
            }
        }))
}

/// The residual `Ā P + P Āᵀ + W − P S P`.
pub fn residual(
    a: &DMatrix<f64>,
    s: &DMatrix<f64>,
    w: &DMatrix<f64>,
    p: &DMatrix<f64>,
) -> DMatrix<f64> {
    let ap = a * p;
    &ap + ap.transpose() + w - p * s * p
}

/// `log |det m|` and invertibility via LU.
fn log_abs_det(m: &DMatrix<f64>) -> Option<f64> {
    let lu = m.clone().lu();
    let u = lu.u();
    let mut acc = 0.0;
    for k in 0..u.nrows() {
        let d = u[(k, k)].abs();
        if d == 0.0 || !d.is_finite() {
            return None;
        }
        acc += d.ln();
    }
    Some(acc)
}

/// Matrix sign function by the scaled Newton iteration `Z ← (c Z + (c Z)⁻¹)/2`, `c = |det Z|^{−1/n}`.
fn sign_function(m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = m.nrows();
    let mut z = m.clone();
    let mut scaling = true;
    for _ in 0..200 {
        let c = if scaling {
            (-log_abs_det(&z)? / n as f64).exp()
        } else {
            1.0
        };
        let zc = &z * c;
        let inv = zc.clone().try_inverse()?;
        let next = (zc + inv) * 0.5;
        let change = (&next - &z).norm();
        let size = next.norm();
        z = next;
        if !size.is_finite() {
            return None;
        }
        if change <= 1e-3 * size {
            scaling = false; // quadratic convergence phase: scaling no longer helps
        }
        if change <= 1e-13 * size {
            return Some(z);
        }
    }
    None
}

/// Solves the Lyapunov equation `F X + X Fᵀ + C = 0` for Hurwitz `F` with the sign-function iteration on
/// `[[F, C], [0, −Fᵀ]]`: `X = ½ lim C_k` with `C_{k+1} = ½ c (C_k + c⁻² F_k⁻¹ C_k F_k⁻ᵀ)`.
pub fn lyapunov(f: &DMatrix<f64>, c: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = f.nrows();
    let mut fk = f.clone();
    let mut ck = c.clone();
    let mut scaling = true;
    for _ in 0..200 {
        let s = if scaling {
            (-log_abs_det(&fk)? / n as f64).exp()
        } else {
            1.0
        };
        let fs = &fk * s;
        let cs = &ck * s;
        let inv = fs.clone().try_inverse()?;
        let next_f = (&fs + &inv) * 0.5;
        let next_c = (&cs + &inv * &cs * inv.transpose()) * 0.5;
        let change = (&next_f - &fk).norm();
        let size = next_f.norm();
        fk = next_f;
        ck = next_c;
        if !size.is_finite() {
            return None;
        }
        if change <= 1e-3 * size {
            scaling = false;
        }
        if change <= 1e-13 * size {
            let x = ck * 0.5;
            return Some((&x + x.transpose()) * 0.5);
        }
    }
    None
}

/// Solves eq. (20), `Ā P + P Āᵀ + W − P S P = 0`, for the stabilising `P > 0`.
///
/// # Errors
/// [`CareError::ImaginaryAxisEigenvalue`] when no stabilising solution exists; the other variants when the
/// computed solution fails verification.
pub fn solve(
    a: &DMatrix<f64>,
    s: &DMatrix<f64>,
    w: &DMatrix<f64>,
) -> Result<CareSolution, CareError> {
    let r = a.nrows();
    let ham = hamiltonian(a, s, w);
    let closest = closest_to_imaginary_axis(&ham)?;
    let scale = ham.norm().max(f64::MIN_POSITIVE);
    if closest.re.abs() <= IMAG_AXIS_TOL * scale {
        return Err(CareError::ImaginaryAxisEigenvalue {
            re: closest.re,
            im: closest.im,
        });
    }
    let sgn = sign_function(&ham).ok_or(CareError::NoConvergence {
        what: "Hamiltonian sign iteration",
    })?;
    // [W12; W22 + I] P = −[W11 + I; W21]  (Byers' least-squares form).
    let mut lhs = DMatrix::zeros(2 * r, r);
    lhs.view_mut((0, 0), (r, r))
        .copy_from(&sgn.view((0, r), (r, r)));
    lhs.view_mut((r, 0), (r, r))
        .copy_from(&(sgn.view((r, r), (r, r)) + DMatrix::identity(r, r)));
    let mut rhs = DMatrix::zeros(2 * r, r);
    rhs.view_mut((0, 0), (r, r))
        .copy_from(&(-(sgn.view((0, 0), (r, r)) + DMatrix::identity(r, r))));
    rhs.view_mut((r, 0), (r, r))
        .copy_from(&(-sgn.view((r, 0), (r, r))));
    let p = lhs
        .svd(true, true)
        .solve(&rhs, 1e-14)
        .map_err(|_| CareError::NoConvergence {
            what: "sign-function subspace solve",
        })?;
    let mut p = (&p + p.transpose()) * 0.5;
    let mut res = residual(a, s, w, &p).norm();
    // Newton–Kleinman refinement: (Ā − P S) X + X (Ā − P S)ᵀ + W + P S P = 0.
    let mut newton_steps = 0;
    for _ in 0..4 {
        let f = a - &p * s;
        if spectral_abscissa(&f) >= 0.0 {
            break;
        }
        let c = w + &p * s * &p;
        let Some(next) = lyapunov(&f, &c) else { break };
        let next_res = residual(a, s, w, &next).norm();
        if next_res < res {
            p = next;
            res = next_res;
            newton_steps += 1;
        } else {
            break;
        }
    }
    let ap = a * &p;
    let denom = 2.0 * ap.norm() + w.norm() + (&p * s * &p).norm();
    let min_eig = min_sym_eigenvalue(&p);
    if min_eig.is_nan() || min_eig <= 0.0 {
        return Err(CareError::NotPositiveDefinite { min_eig });
    }
    let closed_loop_abscissa = spectral_abscissa(&(a - &p * s));
    if closed_loop_abscissa.is_nan() || closed_loop_abscissa >= 0.0 {
        return Err(CareError::NotStabilising {
            abscissa: closed_loop_abscissa,
        });
    }
    Ok(CareSolution {
        p,
        residual: res,
        relative_residual: res / denom.max(f64::MIN_POSITIVE),
        min_eig,
        closed_loop_abscissa,
        hamiltonian_min_abs_re: closest.re.abs(),
        newton_steps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_care_matches_closed_form() {
        // a p + p a + w − s p² = 0  →  p = (a + sqrt(a² + s w)) / s.
        let (a, s, w) = (0.7, 2.0, 3.0);
        let sol = solve(
            &DMatrix::from_element(1, 1, a),
            &DMatrix::from_element(1, 1, s),
            &DMatrix::from_element(1, 1, w),
        )
        .unwrap();
        let exact = (a + (a * a + s * w).sqrt()) / s;
        assert!(
            (sol.p[(0, 0)] - exact).abs() < 1e-13,
            "{} vs {exact}",
            sol.p[(0, 0)]
        );
        assert!(sol.closed_loop_abscissa < 0.0);
    }

    #[test]
    fn lyapunov_solution_satisfies_the_equation() {
        let f = DMatrix::from_row_slice(3, 3, &[-1.0, 2.0, 0.0, 0.0, -3.0, 1.0, 0.5, 0.0, -2.0]);
        let c = DMatrix::from_row_slice(3, 3, &[2.0, 0.5, 0.0, 0.5, 1.0, 0.1, 0.0, 0.1, 3.0]);
        let x = lyapunov(&f, &c).unwrap();
        let r = &f * &x + &x * f.transpose() + &c;
        assert!(r.norm() < 1e-12 * c.norm(), "{}", r.norm());
    }

    #[test]
    fn unweighted_marginal_mode_has_no_stabilising_solution() {
        // ẋ = 0 with no process noise and no measurement: eigenvalue 0 of the Hamiltonian.
        let z = DMatrix::zeros(1, 1);
        let e = solve(&z, &z, &z).unwrap_err();
        assert!(
            matches!(e, CareError::ImaginaryAxisEigenvalue { .. }),
            "{e}"
        );
        assert!(e.to_string().contains("no stabilising solution"));
    }
}
