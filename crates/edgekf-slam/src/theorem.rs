//! The sufficient conditions of Theorem 1, eqs. (24)–(25), and the quantities of its proof.
//!
//! With `e_o = Zᵀe` and the Lyapunov function `V_ob = Σ e_oiᵀ P̄_i⁻¹ e_oi`, the CARE (eq. 20) and Young's
//! inequality `2 eᵀP̄⁻¹w ≤ δ⁻¹ eᵀP̄⁻²e + δ‖w‖²` give `V̇_ob ≤ −E_oᵀ Ω E_o + δ‖…‖²` with
//!
//! `Ω(δ) = diag(P̄_i⁻¹ (Ḡ_i Q Ḡ_iᵀ − δ⁻¹ I) P̄_i⁻¹ + H̄_iᵀ R_i⁻¹ H̄_i) − (Ψ + Ψᵀ)`,
//! `Ψ = k₂ diag(P̄_i⁻¹) diag(Z_iᵀ) D̄ diag(Z_i)`, `D̄ = 1_n ⊗ [D; 0]`.
//!
//! The paper prints `+δ⁻¹ I` in (24): with it `Ω` is positive definite for every gain once `δ` is small enough,
//! so the condition says nothing. With the correct `−δ⁻¹`, `Ω(δ)` increases with `δ`; (24) holds for some `δ > 0`
//! iff `Ω(∞) > 0`. Condition (25), `ζ_min (γ λ_min − 1/(2τ)) − γ²ξ²/4 > 0`, with
//! `λ_min = λ_min(diag(W_iᵀ)(𝓛_c ⊗ I_N) diag(W_i))`, `ξ = ‖diag(W_iᵀ)(𝓛_c ⊗ I_N) diag(Z_i)‖` (the paper writes
//! `I_{2(n+2m)}` there; the state dimension is `N = 2(n+m)`) and `ζ_min = λ_min(Ω(δ))`, makes the 2×2 matrix
//! `𝕄 = [[ζ_min, −γξ/2], [−γξ/2, γλ_min − 1/(2τ)]]` of the proof positive definite. Its supremum over `δ, τ` is
//! `ζ(∞) γ λ_min − γ²ξ²/4`. Both conditions are only sufficient: the error system's spectral abscissa decides.

use crate::linalg::{min_sym_eigenvalue, spectral_abscissa};
use crate::model::Model;
use crate::observer::{error_system_matrix, ConsensusSign, RobotObserver};
use nalgebra::{DMatrix, Matrix2};

/// The condition report of Theorem 1 (see the module documentation).
#[derive(Debug, Clone)]
pub struct Theorem1Report {
    /// `λ_min(Ω(∞))`: the supremum of `ζ_min` over `δ` (with `−1/δ`).
    pub zeta_sup: f64,
    /// `λ_min` of `diag(W_iᵀ)(𝓛_c ⊗ I_N) diag(W_i)`.
    pub lambda_min: f64,
    /// `ξ = ‖diag(W_iᵀ)(𝓛_c ⊗ I_N) diag(Z_i)‖₂`.
    pub xi: f64,
    /// Coupling gain `γ`.
    pub gamma: f64,
    /// Whether (24) (with `−1/δ`) holds for some `δ > 0`.
    pub condition24: bool,
    /// `ζ(∞) γ λ_min − γ²ξ²/4`, the supremum over `δ, τ` of the left side of (25).
    pub condition25_sup: f64,
    /// Whether (24) and (25) hold together for some `δ, τ > 0`.
    pub condition25: bool,
    /// `(δ, τ)` found by doubling from 1 for which (24) and (25) hold, if any.
    pub witness: Option<(f64, f64)>,
    /// `𝕄` at the witness, or its limit `δ, τ → ∞` when there is none.
    pub m_matrix: Matrix2<f64>,
    /// `Ω(∞) = diag(P̄_i⁻¹ Ḡ_i Q Ḡ_iᵀ P̄_i⁻¹ + H̄_iᵀ R_i⁻¹ H̄_i) − (Ψ + Ψᵀ)`; `Ω(δ) = Ω(∞) − δ⁻¹ diag(P̄_i⁻²)`.
    pub omega_inf: DMatrix<f64>,
    /// `diag(P̄_i⁻²)`, the direction of the `δ⁻¹` term.
    pub p_inv_sq: DMatrix<f64>,
    /// `diag(P̄_i⁻¹)`.
    pub p_inv: DMatrix<f64>,
    /// `Ψ = k₂ diag(P̄_i⁻¹) diag(Z_iᵀ) D̄ diag(Z_i)`.
    pub psi: DMatrix<f64>,
    /// Spectral abscissa of the error system (eq. 21) with eq. (19)'s consensus sign.
    pub error_abscissa: f64,
    /// Spectral abscissa with eq. (10)'s sign.
    pub error_abscissa_eq10: f64,
}

fn block_diag(blocks: &[DMatrix<f64>]) -> DMatrix<f64> {
    let rows: usize = blocks.iter().map(DMatrix::nrows).sum();
    let cols: usize = blocks.iter().map(DMatrix::ncols).sum();
    let mut out = DMatrix::zeros(rows, cols);
    let (mut r, mut c) = (0, 0);
    for b in blocks {
        out.view_mut((r, c), b.shape()).copy_from(b);
        r += b.nrows();
        c += b.ncols();
    }
    out
}

impl Theorem1Report {
    /// `Ω(δ)` of eq. (24) with the corrected `−δ⁻¹` (`plus = false`) or as printed, `+δ⁻¹` (`plus = true`).
    pub fn omega(&self, delta: f64, plus: bool) -> DMatrix<f64> {
        if plus {
            &self.omega_inf + &self.p_inv_sq / delta
        } else {
            &self.omega_inf - &self.p_inv_sq / delta
        }
    }

    /// Computes the report for designed observers with `Q = q I` and coupling gain `gamma`.
    pub fn compute(model: &Model, observers: &[RobotObserver], q: f64, gamma: f64) -> Self {
        let omega = Omega::of(model, observers, q);
        let zeta_sup = min_sym_eigenvalue(&omega.inf);
        let (lambda_min, xi) = consensus_terms(model, observers);
        let lam = if lambda_min.is_finite() {
            lambda_min
        } else {
            1.0
        };
        let condition24 = zeta_sup > 0.0;
        let condition25_sup = zeta_sup * gamma * lam - gamma * gamma * xi * xi / 4.0;
        let condition25 = condition24 && condition25_sup > 0.0;
        let m_of = |zeta: f64, tau_term: f64| {
            Matrix2::new(
                zeta,
                -gamma * xi / 2.0,
                -gamma * xi / 2.0,
                gamma * lam - tau_term,
            )
        };
        let mut witness = None;
        let mut m_matrix = m_of(zeta_sup, 0.0);
        if condition25 {
            // δ = τ = v, doubled from 1: ζ_min(δ) increases with δ and 1/(2τ) decreases.
            let mut v = 1.0_f64;
            for _ in 0..200 {
                let zeta = min_sym_eigenvalue(&(&omega.inf - &omega.delta_dir / v));
                let mm = m_of(zeta, 1.0 / (2.0 * v));
                if zeta > 0.0 && mm.determinant() > 0.0 && mm[(1, 1)] > 0.0 {
                    witness = Some((v, v));
                    m_matrix = mm;
                    break;
                }
                v *= 2.0;
            }
        }
        let abscissa =
            |sign| spectral_abscissa(&error_system_matrix(model, observers, gamma, sign));
        Self {
            zeta_sup,
            lambda_min,
            xi,
            gamma,
            condition24,
            condition25_sup,
            condition25,
            witness,
            m_matrix,
            omega_inf: omega.inf,
            p_inv_sq: omega.delta_dir,
            p_inv: omega.p_inv,
            psi: omega.psi,
            error_abscissa: abscissa(ConsensusSign::Eq19),
            error_abscissa_eq10: abscissa(ConsensusSign::Eq10),
        }
    }
}

/// The parts of `Ω(δ) = Ω(∞) − δ⁻¹ diag(P̄_i⁻²)` (eq. 24, corrected sign).
struct Omega {
    /// `Ω(∞)`.
    inf: DMatrix<f64>,
    /// `diag(P̄_i⁻²)`.
    delta_dir: DMatrix<f64>,
    /// `diag(P̄_i⁻¹)`.
    p_inv: DMatrix<f64>,
    /// `Ψ = k₂ diag(P̄_i⁻¹) diag(Z_iᵀ) D̄ diag(Z_i)`.
    psi: DMatrix<f64>,
}

impl Omega {
    fn of(model: &Model, observers: &[RobotObserver], q: f64) -> Self {
        let (n, dim) = (model.n, model.dim());
        let p_inv: Vec<DMatrix<f64>> = observers
            .iter()
            .map(|o| {
                o.care
                    .p
                    .clone()
                    .try_inverse()
                    .unwrap_or_else(|| DMatrix::from_element(1, 1, f64::NAN))
            })
            .collect();
        // Ω(∞) block-diagonal part and the δ⁻¹ direction diag(P̄⁻²).
        let base: Vec<DMatrix<f64>> = observers
            .iter()
            .zip(&p_inv)
            .map(|(o, pi)| {
                let rinv = o.r.clone().try_inverse().unwrap_or_else(|| o.r.clone());
                pi * pi * q + o.h_bar.transpose() * rinv * &o.h_bar
            })
            .collect();
        let p_inv_sq: Vec<DMatrix<f64>> = p_inv.iter().map(|pi| pi * pi).collect();
        let diag_z = diag_of(observers, |o| &o.decomposition.z);
        // D̄ = 1_n ⊗ [D; 0].
        let mut d_bar = DMatrix::zeros(n * dim, n * dim);
        for i in 0..n {
            d_bar
                .view_mut((i * dim, 0), (2 * n, n * dim))
                .copy_from(&model.d);
        }
        let psi = block_diag(&p_inv) * model.k2 * diag_z.transpose() * &d_bar * &diag_z;
        Self {
            inf: block_diag(&base) - (&psi + psi.transpose()),
            delta_dir: block_diag(&p_inv_sq),
            p_inv: block_diag(&p_inv),
            psi,
        }
    }
}

/// `diag(M_i)` of one matrix per observer.
fn diag_of(
    observers: &[RobotObserver],
    m: impl Fn(&RobotObserver) -> &DMatrix<f64>,
) -> DMatrix<f64> {
    let blocks: Vec<DMatrix<f64>> = observers.iter().map(|o| m(o).clone()).collect();
    block_diag(&blocks)
}

/// `λ_min` of `diag(W_iᵀ)(𝓛_c ⊗ I_N) diag(W_i)` (∞ when empty) and
/// `ξ = ‖diag(W_iᵀ)(𝓛_c ⊗ I_N) diag(Z_i)‖₂` (0 when empty), the consensus terms of (25).
fn consensus_terms(model: &Model, observers: &[RobotObserver]) -> (f64, f64) {
    let (n, dim) = (model.n, model.dim());
    let diag_z = diag_of(observers, |o| &o.decomposition.z);
    let diag_w = diag_of(observers, |o| &o.decomposition.w);
    let lc = DMatrix::from_fn(n * dim, n * dim, |r, c| {
        if r % dim == c % dim {
            model.l_c[(r / dim, c / dim)]
        } else {
            0.0
        }
    });
    let ww = diag_w.transpose() * &lc * &diag_w;
    let lambda_min = if ww.nrows() == 0 {
        f64::INFINITY
    } else {
        min_sym_eigenvalue(&ww)
    };
    let wz = diag_w.transpose() * &lc * &diag_z;
    let xi = if wz.nrows() == 0 || wz.ncols() == 0 {
        0.0
    } else {
        wz.singular_values().iter().copied().fold(0.0, f64::max)
    };
    (lambda_min, xi)
}
