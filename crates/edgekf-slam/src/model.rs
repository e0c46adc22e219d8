//! The plant of §2–3: robots, landmarks, measurements and the formation/manoeuvre control.
//!
//! State (eq. 14): `x = [p_1; …; p_n; m_1; …; m_m] ∈ ℝ^{2(n+m)}`, robot-major, `x` then `y` per point.
//!
//! - Robots (eq. 1) `ṗ_i = u_i¹ + u_i² (+ ω_i)`, landmarks (eq. 2) `ṁ_l = 0`.
//! - Control (eqs. 3–4, 11): `u_i¹ = ṗ_c* − k₁ (p_c − p_c*)` with the true centroid (Assumption 3);
//!   `u_i² = −k₂ Σ_{j∈N_i⁺} a_ij (p_i − p_j − (p_i* − p_j*)) − k₂ Σ_{l∈N_i⁻} a_il (p̂_i^i − p̂_l^i − (p_i* − p_l*))`:
//!   the measured graph G⁺ acts on the true relative positions, the estimation graph G⁻ on robot i's estimates.
//! - Closed loop (eqs. 12, 14): `ẋ = A x + B u + d + G ω` with
//!   `A = blkdiag(1_n ⊗ (−k₁/n)(1_nᵀ ⊗ I₂) − k₂ (𝓛_f ⊗ I₂), 0)`,
//!   `u = 1_n ⊗ (ṗ_c* + k₁ p_c*) + k₂ (𝓛_f ⊗ I₂) P*` (the paper prints `p_c*` for the first `ṗ_c*`),
//!   `d = [−k₂ D E; 0]`, `D = blkdiag_i([Γ_i 𝓛⁻, 0_{1×m}] ⊗ I₂)`, `G = [I_{2n}; 0]`.
//! - Measurements (eqs. 15–17): `y_i = H_i x + ν_i`, rows in the order own position `p_i` (the "origin"
//!   observation), `p_i − p_j` for each `j ∈ N_i⁺`, `p_i − m_l` for each `l ∈ M_i`, both by increasing index.

use crate::graph::neighbours;
use nalgebra::{DMatrix, DVector, Vector2};

/// The linear model of eqs. (12)–(17), built from checked inputs (see [`crate::Scenario`]).
#[derive(Debug, Clone)]
pub struct Model {
    /// Number of robots `n`.
    pub n: usize,
    /// Number of landmarks `m`.
    pub m: usize,
    /// Manoeuvre gain `k₁` (eq. 3).
    pub k1: f64,
    /// Formation gain `k₂` (eq. 4).
    pub k2: f64,
    /// Communication Laplacian `𝓛_c` (Assumption 4).
    pub l_c: DMatrix<f64>,
    /// Measurement Laplacian `𝓛⁺` (directed, Assumption 1).
    pub l_plus: DMatrix<f64>,
    /// Formation Laplacian `𝓛_f` (undirected).
    pub l_f: DMatrix<f64>,
    /// Estimation Laplacian `𝓛⁻ = 𝓛_f − 𝓛⁺`.
    pub l_minus: DMatrix<f64>,
    /// Landmark sets `M_i` (0-based, increasing).
    pub landmark_sets: Vec<Vec<usize>>,
    /// Desired positions `P* = [p_1*; …; p_n*]` (`2n`).
    pub p_star: DVector<f64>,
    /// Centroid reference `p_c*(0)`.
    pub centroid_start: Vector2<f64>,
    /// Centroid reference velocity `ṗ_c*` (constant): `p_c*(t) = p_c*(0) + ṗ_c* t`.
    pub centroid_velocity: Vector2<f64>,
    /// `A` of eq. (14), `N × N`, `N = 2(n + m)`.
    pub a: DMatrix<f64>,
    /// `B = G = [I_{2n}; 0]` of eq. (14), `N × 2n`.
    pub b: DMatrix<f64>,
    /// `D` of eq. (12), `2n × nN`: `D E` stacks `Σ_{l} 𝓛⁻_il (e_i[p_i] − e_i[p_l])`.
    pub d: DMatrix<f64>,
    /// `H_i` of eqs. (16)–(17), one per robot.
    pub h: Vec<DMatrix<f64>>,
    /// `N_i⁺` with weights `a_ij` (increasing `j`).
    pub measured: Vec<Vec<(usize, f64)>>,
    /// `N_i⁻` with weights (increasing `l`).
    pub estimated: Vec<Vec<(usize, f64)>>,
    /// Communication neighbours `N_i^c` with weights.
    pub communicating: Vec<Vec<(usize, f64)>>,
}

/// `A` of eq. (14): the robot block `1_n ⊗ (−k₁/n)(1_nᵀ ⊗ I₂) − k₂ (𝓛_f ⊗ I₂)`, zero landmark block.
pub fn system_matrix(n: usize, m: usize, k1: f64, k2: f64, l_f: &DMatrix<f64>) -> DMatrix<f64> {
    let dim = 2 * (n + m);
    let mut a = DMatrix::zeros(dim, dim);
    for i in 0..n {
        for j in 0..n {
            let v = -k1 / n as f64 - k2 * l_f[(i, j)];
            a[(2 * i, 2 * j)] = v;
            a[(2 * i + 1, 2 * j + 1)] = v;
        }
    }
    a
}

/// `H_i` of eqs. (16)–(17) for robot `i` (0-based) with measured robots `measured` and landmarks `landmarks`
/// (both increasing). Rows: `p_i`; `p_i − p_j` per measured `j`; `p_i − m_l` per landmark `l`.
///
/// Eq. (17) as printed gives, for `j < i`, the blocks `[0_{2(j−1)}, −I₂, 0_{2i−2−2j}, I₂, 0_{n−i}]` whose widths
/// sum to `n + i`, not `2n`: the last block is `0_{2(n−i)}`. Here the blocks are placed by index.
pub fn measurement_matrix(
    n: usize,
    m: usize,
    i: usize,
    measured: &[usize],
    landmarks: &[usize],
) -> DMatrix<f64> {
    let rows = 2 * (1 + measured.len() + landmarks.len());
    let mut h = DMatrix::zeros(rows, 2 * (n + m));
    let mut put = |r: usize, col_block: usize, sign: f64| {
        h[(2 * r, 2 * col_block)] = sign;
        h[(2 * r + 1, 2 * col_block + 1)] = sign;
    };
    put(0, i, 1.0);
    for (k, &j) in measured.iter().enumerate() {
        put(1 + k, i, 1.0);
        put(1 + k, j, -1.0);
    }
    for (k, &l) in landmarks.iter().enumerate() {
        put(1 + measured.len() + k, i, 1.0);
        put(1 + measured.len() + k, n + l, -1.0);
    }
    h
}

/// `D` of eq. (12) (`2n × n·2(n+m)`): block row `i` is `[Γ_i 𝓛⁻, 0_{1×m}] ⊗ I₂` acting on `e_i`.
pub fn estimation_coupling(n: usize, m: usize, l_minus: &DMatrix<f64>) -> DMatrix<f64> {
    let dim = 2 * (n + m);
    let mut d = DMatrix::zeros(2 * n, n * dim);
    for i in 0..n {
        for j in 0..n {
            let v = l_minus[(i, j)];
            d[(2 * i, i * dim + 2 * j)] = v;
            d[(2 * i + 1, i * dim + 2 * j + 1)] = v;
        }
    }
    d
}

impl Model {
    /// Builds the model from checked inputs (Laplacians already validated, landmark sets sorted and in range).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        k1: f64,
        k2: f64,
        l_c: DMatrix<f64>,
        l_plus: DMatrix<f64>,
        l_f: DMatrix<f64>,
        m: usize,
        landmark_sets: Vec<Vec<usize>>,
        p_star: DVector<f64>,
        centroid_start: Vector2<f64>,
        centroid_velocity: Vector2<f64>,
    ) -> Self {
        let n = l_c.nrows();
        let l_minus = &l_f - &l_plus;
        let a = system_matrix(n, m, k1, k2, &l_f);
        let dim = 2 * (n + m);
        let mut b = DMatrix::zeros(dim, 2 * n);
        b.view_mut((0, 0), (2 * n, 2 * n)).fill_with_identity();
        let d = estimation_coupling(n, m, &l_minus);
        let measured: Vec<Vec<(usize, f64)>> = (0..n).map(|i| neighbours(&l_plus, i)).collect();
        let estimated: Vec<Vec<(usize, f64)>> = (0..n).map(|i| neighbours(&l_minus, i)).collect();
        let communicating: Vec<Vec<(usize, f64)>> = (0..n).map(|i| neighbours(&l_c, i)).collect();
        let h = (0..n)
            .map(|i| {
                let js: Vec<usize> = measured[i].iter().map(|&(j, _)| j).collect();
                measurement_matrix(n, m, i, &js, &landmark_sets[i])
            })
            .collect();
        Self {
            n,
            m,
            k1,
            k2,
            l_c,
            l_plus,
            l_f,
            l_minus,
            landmark_sets,
            p_star,
            centroid_start,
            centroid_velocity,
            a,
            b,
            d,
            h,
            measured,
            estimated,
            communicating,
        }
    }

    /// State dimension `N = 2(n + m)`.
    pub fn dim(&self) -> usize {
        2 * (self.n + self.m)
    }

    /// Centroid reference `p_c*(t)`.
    pub fn centroid_reference(&self, t: f64) -> Vector2<f64> {
        self.centroid_start + self.centroid_velocity * t
    }

    /// `B u(t)` of eq. (14) (`N`): robots `ṗ_c* + k₁ p_c*(t) + k₂ Σ_j 𝓛_f,ij p_j*`, landmarks 0.
    pub fn input(&self, t: f64) -> DVector<f64> {
        let mut u = DVector::zeros(self.dim());
        self.input_into(t, &mut u);
        u
    }

    /// [`Model::input`] into a buffer of length `N`.
    pub(crate) fn input_into(&self, t: f64, u: &mut DVector<f64>) {
        u.fill(0.0);
        let base = self.centroid_velocity + self.centroid_reference(t) * self.k1;
        for i in 0..self.n {
            for c in 0..2 {
                let mut v = base[c];
                for j in 0..self.n {
                    v += self.k2 * self.l_f[(i, j)] * self.p_star[2 * j + c];
                }
                u[2 * i + c] = v;
            }
        }
    }

    /// The control `u_i = u_i¹ + u_i²` of eqs. (3)–(4) for every robot (`2n`), from the true state `x` (for the
    /// centroid and the measured relative positions of G⁺) and each robot's own estimate `x̂_i` (for G⁻).
    pub fn control(&self, t: f64, x: &[f64], xhat: &[&[f64]]) -> DVector<f64> {
        let mut u = DVector::zeros(2 * self.n);
        self.control_into(t, x, xhat, u.as_mut_slice());
        u
    }

    /// [`Model::control`] into a slice of length `2n`.
    pub(crate) fn control_into(&self, t: f64, x: &[f64], xhat: &[&[f64]], u: &mut [f64]) {
        let n = self.n;
        let mut pc = [0.0; 2];
        for i in 0..n {
            pc[0] += x[2 * i];
            pc[1] += x[2 * i + 1];
        }
        let pcs = self.centroid_reference(t);
        for v in &mut pc {
            *v /= n as f64;
        }
        for i in 0..n {
            for c in 0..2 {
                let ps = |j: usize| self.p_star[2 * j + c];
                let mut v = self.centroid_velocity[c] - self.k1 * (pc[c] - pcs[c]);
                for &(j, a) in &self.measured[i] {
                    v -= self.k2 * a * (x[2 * i + c] - x[2 * j + c] - (ps(i) - ps(j)));
                }
                let est = xhat[i];
                for &(l, a) in &self.estimated[i] {
                    v -= self.k2 * a * (est[2 * i + c] - est[2 * l + c] - (ps(i) - ps(l)));
                }
                u[2 * i + c] = v;
            }
        }
    }

    /// Number of measurement rows of robot `i`: `2(1 + |N_i⁺| + |M_i|)`.
    pub fn measurement_rows(&self, i: usize) -> usize {
        self.h[i].nrows()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measurement_rows_in_the_documented_order() {
        // n = 3, m = 2, robot 1 measures robot 0 and landmark 1.
        let h = measurement_matrix(3, 2, 1, &[0], &[1]);
        assert_eq!(h.shape(), (6, 10));
        let x = DVector::from_vec((0..10).map(|k| k as f64 * k as f64).collect());
        let y = &h * &x;
        // own p_1 = (x2, x3) = (4, 9); p_1 − p_0 = (4 − 0, 9 − 1); p_1 − m_1 = (4 − 64, 9 − 81).
        assert_eq!(y.as_slice(), &[4.0, 9.0, 4.0, 8.0, -60.0, -72.0]);
    }

    #[test]
    fn a_has_the_centroid_and_formation_blocks() {
        let lf = DMatrix::from_row_slice(2, 2, &[1.0, -1.0, -1.0, 1.0]);
        let a = system_matrix(2, 1, 2.0, 3.0, &lf);
        // −k1/n − k2 l_f: diag −1 − 3 = −4, off-diag −1 + 3 = 2.
        assert!((a[(0, 0)] + 4.0).abs() < 1e-15 && (a[(1, 3)] - 2.0).abs() < 1e-15);
        assert!(a.view((4, 0), (2, 6)).iter().all(|v| *v == 0.0));
    }
}
