//! The distributed observer of §4, eq. (19), and its linear error dynamics, eq. (21).
//!
//! Per robot `i`: `x̂̇_i = A x̂_i + B u + K_i (y_i − H_i x̂_i) + γ W_i W_iᵀ Σ_{j∈N_i^c} a_ij (x̂_j − x̂_i)` with the
//! orthogonal Kalman decomposition `T_i = [Z_i W_i]` (eq. 18, [`crate::linalg::kalman_decomposition`]) and
//! `K_i = Z_i P̄_i H̄_iᵀ R_i⁻¹`, `P̄_i` the stabilising solution of the CARE (eq. 20)
//! `Ā_i¹¹ P̄ + P̄ (Ā_i¹¹)ᵀ + Ḡ_i Q Ḡ_iᵀ − P̄ H̄_iᵀ R_i⁻¹ H̄_i P̄ = 0`, `Ā_i¹¹ = Z_iᵀ A Z_i`, `H̄_i = H_i Z_i`.
//!
//! The paper never defines `G_i`; with the plant's `G` (noise on the robots only) the landmark modes of `Ā_i¹¹`
//! (eigenvalue 0) get no weight and the Hamiltonian has eigenvalues on the imaginary axis
//! ([`printed_care`]). The design weight used here is `Ḡ_i Q Ḡ_iᵀ = Z_iᵀ Q Z_i` with `Q = q I_N`, i.e. `q I_r`.
//!
//! Eq. (10) prints the consensus with the opposite sign, `γ M_i Σ a_ij (x̂_i − x̂_j)`: that makes the unobservable
//! errors diverge (see [`error_system_matrix`] with [`ConsensusSign::Eq10`]). Eq. (19)'s sign is used.

use crate::care::{self, CareError, CareSolution};
use crate::linalg::{kalman_decomposition, KalmanDecomposition};
use crate::model::Model;
use nalgebra::{Complex, DMatrix};

/// One robot's observer: decomposition, CARE solution and gain.
#[derive(Debug, Clone)]
pub struct RobotObserver {
    /// `T_i = [Z_i W_i]` (eq. 18).
    pub decomposition: KalmanDecomposition,
    /// `Ā_i¹¹ = Z_iᵀ A Z_i`.
    pub a11: DMatrix<f64>,
    /// `H̄_i = H_i Z_i`.
    pub h_bar: DMatrix<f64>,
    /// `R_i` (measurement weight).
    pub r: DMatrix<f64>,
    /// The CARE (eq. 20) solution with its verification.
    pub care: CareSolution,
    /// `K̄_i = P̄_i H̄_iᵀ R_i⁻¹`.
    pub k_bar: DMatrix<f64>,
    /// `K_i = Z_i K̄_i` (eq. 19).
    pub k: DMatrix<f64>,
    /// The consensus projector `W_i W_iᵀ`.
    pub w_proj: DMatrix<f64>,
}

impl RobotObserver {
    /// Dimension `r_i` of the observable part.
    pub fn observable_dim(&self) -> usize {
        self.decomposition.z.ncols()
    }
}

/// Designs robot `i`'s observer with `Q = q I` and `R_i = r_i I`.
///
/// # Errors
/// The [`CareError`] of eq. (20) (e.g. no stabilising solution).
pub fn design_robot(model: &Model, i: usize, q: f64, r_i: f64) -> Result<RobotObserver, CareError> {
    let h = &model.h[i];
    let decomposition = kalman_decomposition(&model.a, h);
    let z = &decomposition.z;
    if z.ncols() == 0 {
        // Nothing observable at the model's scale (e.g. a gain so large that the rank test
        // sees every measurement direction as zero): there is no CARE to solve.
        return Err(CareError::NoConvergence {
            what: "Kalman decomposition (no observable direction at this scale)",
        });
    }
    let a11 = z.transpose() * &model.a * z;
    let h_bar = h * z;
    let rows = h.nrows();
    let r = DMatrix::identity(rows, rows) * r_i;
    let r_inv = DMatrix::identity(rows, rows) / r_i;
    let s = h_bar.transpose() * &r_inv * &h_bar;
    let w = DMatrix::identity(z.ncols(), z.ncols()) * q;
    let care = care::solve(&a11, &s, &w)?;
    let k_bar = &care.p * h_bar.transpose() * &r_inv;
    let k = z * &k_bar;
    let w_proj = &decomposition.w * decomposition.w.transpose();
    Ok(RobotObserver {
        decomposition,
        a11,
        h_bar,
        r,
        care,
        k_bar,
        k,
        w_proj,
    })
}

/// The CARE (eq. 20) exactly as printed, with `Ḡ_i = Z_iᵀ G` and the plant's `G = [I_{2n}; 0]`, `Q = q I_{2n}`.
#[derive(Debug, Clone)]
pub struct PrintedCare {
    /// The Hamiltonian eigenvalue closest to the imaginary axis.
    pub closest_eigenvalue: Complex<f64>,
    /// `‖𝓗‖_F`, the scale for the closest eigenvalue.
    pub hamiltonian_norm: f64,
    /// Number of Hamiltonian eigenvalues with `|Re λ| ≤` [`care::IMAG_AXIS_TOL`]`·‖𝓗‖_F`.
    pub on_axis: usize,
    /// What the solver says.
    pub result: Result<CareSolution, CareError>,
}

/// Evaluates the CARE as printed for robot `i` (see [`PrintedCare`]).
pub fn printed_care(model: &Model, obs: &RobotObserver, q: f64) -> PrintedCare {
    let z = &obs.decomposition.z;
    let g_bar = z.transpose() * &model.b; // G = B = [I_2n; 0]
    let w = &g_bar * g_bar.transpose() * q;
    let r_inv = obs.r.clone().try_inverse().unwrap_or_else(|| obs.r.clone());
    let s = obs.h_bar.transpose() * r_inv * &obs.h_bar;
    let ham = care::hamiltonian(&obs.a11, &s, &w);
    let hamiltonian_norm = ham.norm();
    let eig = crate::linalg::eigenvalues(&ham).unwrap_or_default();
    let on_axis = eig
        .iter()
        .filter(|z| z.re.abs() <= care::IMAG_AXIS_TOL * hamiltonian_norm)
        .count();
    let closest_eigenvalue = eig
        .iter()
        .copied()
        .fold(Complex::new(f64::INFINITY, 0.0), |b, z| {
            if z.re.abs() < b.re.abs() {
                z
            } else {
                b
            }
        });
    PrintedCare {
        closest_eigenvalue,
        hamiltonian_norm,
        on_axis,
        result: care::solve(&obs.a11, &s, &w),
    }
}

/// Sign of the consensus term.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConsensusSign {
    /// Eq. (19): `+γ W W ᵀ Σ a_ij (x̂_j − x̂_i)` (used).
    Eq19,
    /// Eq. (10) as printed: `+γ M_i Σ a_ij (x̂_i − x̂_j)` with `M_i = W_i W_iᵀ`.
    Eq10,
}

/// The matrix of the linear error dynamics (eq. 21), `Ė = 𝒜 E + diag(K_i) ν − 1_n ⊗ G ω`:
/// `𝒜 = diag(A − K_i H_i) ∓ γ diag(W_i W_iᵀ)(𝓛_c ⊗ I_N) + k₂ (1_n ⊗ [D; 0])` (`−d = k₂ [D E; 0]`).
pub fn error_system_matrix(
    model: &Model,
    observers: &[RobotObserver],
    gamma: f64,
    sign: ConsensusSign,
) -> DMatrix<f64> {
    let n = model.n;
    let dim = model.dim();
    let mut m = DMatrix::zeros(n * dim, n * dim);
    let g = match sign {
        ConsensusSign::Eq19 => gamma,
        ConsensusSign::Eq10 => -gamma,
    };
    for (i, ob) in observers.iter().enumerate().take(n) {
        let diag = &model.a - &ob.k * &model.h[i];
        m.view_mut((i * dim, i * dim), (dim, dim)).copy_from(&diag);
        for j in 0..n {
            let lij = model.l_c[(i, j)];
            let mut blk = m.view_mut((i * dim, j * dim), (dim, dim));
            blk -= &ob.w_proj * (g * lij);
        }
        // + k2 [D E; 0] in the robot rows of every e_i.
        let mut rows = m.view_mut((i * dim, 0), (2 * n, n * dim));
        rows += &model.d * model.k2;
    }
    m
}
