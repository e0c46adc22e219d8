//! Centralised relative Kalman filter (CRKF; the thesis's C-Edge-KF), in node-relative form.
//!
//! EUSIPCO (9a)–(9g) = thesis (5.6)–(5.12) filter the stacked edge states `x = B̄ᵀ z`
//! (dimension M·D) with `Σ_{0|0} = BᵀB ⊗ P`, process covariance `B̄ᵀ Q B̄` and the block-diagonal
//! measurement covariance `R`. That state lives in the (N−1)·D-dimensional range of `B̄ᵀ`:
//! with the node-relative state `ζ_n = z_n − z_0` (n = 1..N−1) we have `x = G ζ`, `G` = `B̄ᵀ`
//! without agent 0's rows, which has full column rank for a connected graph. The Kalman filter of
//! `x` is exactly the image under `G` of the Kalman filter of `ζ`:
//!
//! - `ζ̂_{0|0} = 0`, `Σ_{0|0} = (I + 1 1ᵀ) ⊗ P` (the image of (9a)–(9b));
//! - `ζ̂_{k|k−1} = ζ̂ + Δt (u_n − u_0)`, `Σ_{k|k−1} = Σ + Q_ζ`, `Q_ζ = S Q Sᵀ` ((9c)–(9d));
//! - update in information form, `Σ_{k|k} = (Σ_{k|k−1}⁻¹ + Gᵀ W⁻¹ G)⁻¹`,
//!   `ζ̂_{k|k} = ζ̂_{k|k−1} + Σ_{k|k} (Gᵀ W⁻¹ ȳ − Gᵀ W⁻¹ G ζ̂_{k|k−1})` ((9e)–(9g); `W = R/T`);
//! - `x̂_{k|k} = G ζ̂_{k|k}` and `tr Σ^x_{k|k} = tr(Σ_{k|k} GᵀG)`.
//!
//! The covariance is frozen once it has converged to rounding level
//! ([`crate::linalg::converged`]). One covariance step costs an (N−1)D-sized inversion instead of an M·D-sized one (18 vs 120 for
//! the hexagon); a test checks the traces against the edge-space recursion.
//!
//! # References
//! van der Marel & Rajan, EUSIPCO 2022, eq. (9); van der Marel, MSc thesis 2021, §5.2, Alg. 6.

use nalgebra::DMatrix;

use super::{EdgeModel, Estimator, StepInput};
use crate::linalg::{
    batch_gemv, batch_gemv_acc, converged, invert_spd, to_row_major, trace_of_product_sym,
};

/// The CRKF.
#[derive(Debug, Clone)]
pub struct Crkf {
    runs: usize,
    dim: usize,
    edges: Vec<(usize, usize)>,
    /// `W_e⁻¹` row-major per edge.
    w_inv: Vec<f64>,
    q: DMatrix<f64>,
    j: DMatrix<f64>,
    j_rm: Vec<f64>,
    gtg: DMatrix<f64>,
    sigma0: DMatrix<f64>,
    sigma: DMatrix<f64>,
    prior: DMatrix<f64>,
    info: DMatrix<f64>,
    work: DMatrix<f64>,
    next: DMatrix<f64>,
    sigma_rm: Vec<f64>,
    frozen: bool,
    zeta: Vec<f64>,
    b: Vec<f64>,
    s: Vec<f64>,
    x: Vec<f64>,
    trace: f64,
}

impl Crkf {
    /// For `runs` runs.
    ///
    /// # Panics
    /// If a measurement covariance is singular (the scenario check rejects that for `crkf`).
    pub fn new(m: &EdgeModel, runs: usize) -> Self {
        let d = m.dim;
        let nz = (m.agents - 1) * d;
        // g(e, n): coefficient of ζ_n (n ≥ 1) in x_e.
        let g = |e: usize, n: usize| {
            let (i, j) = m.edges[e];
            f64::from(u8::from(i == n)) - f64::from(u8::from(j == n))
        };
        let mut w_inv = Vec::with_capacity(m.num_edges() * d * d);
        let mut w_inv_m = Vec::with_capacity(m.num_edges());
        for w in &m.w {
            let inv = w
                .clone()
                .try_inverse()
                .expect("measurement covariance is positive definite");
            w_inv.extend(inv.transpose().iter().copied());
            w_inv_m.push(inv);
        }
        let mut j = DMatrix::zeros(nz, nz);
        let mut gtg = DMatrix::zeros(nz, nz);
        let mut q = DMatrix::zeros(nz, nz);
        let mut sigma0 = DMatrix::zeros(nz, nz);
        for a in 1..m.agents {
            for b in 1..m.agents {
                let (ra, rb) = ((a - 1) * d, (b - 1) * d);
                let qb = m.q_block(a, b) - m.q_block(a, 0) - m.q_block(0, b) + m.q_block(0, 0);
                q.view_mut((ra, rb), (d, d)).copy_from(&qb);
                let p = &m.p * if a == b { 2.0 } else { 1.0 };
                sigma0.view_mut((ra, rb), (d, d)).copy_from(&p);
                for (e, wi) in w_inv_m.iter().enumerate() {
                    let c = g(e, a) * g(e, b);
                    if c != 0.0 {
                        let mut v = j.view_mut((ra, rb), (d, d));
                        v += wi * c;
                        for k in 0..d {
                            gtg[(ra + k, rb + k)] += c;
                        }
                    }
                }
            }
        }
        let mut j_rm = vec![0.0; nz * nz];
        to_row_major(&j, &mut j_rm);
        let mut f = Self {
            runs,
            dim: d,
            edges: m.edges.clone(),
            w_inv,
            q,
            j,
            j_rm,
            gtg,
            sigma: sigma0.clone(),
            sigma0,
            prior: DMatrix::zeros(nz, nz),
            info: DMatrix::zeros(nz, nz),
            work: DMatrix::zeros(nz, nz),
            next: DMatrix::zeros(nz, nz),
            sigma_rm: vec![0.0; nz * nz],
            frozen: false,
            zeta: vec![0.0; nz * runs],
            b: vec![0.0; nz * runs],
            s: vec![0.0; d * runs],
            x: vec![0.0; m.num_edges() * d * runs],
            trace: 0.0,
        };
        f.reset();
        f
    }

    /// Posterior covariance of the node-relative state ζ.
    pub fn node_covariance(&self) -> &DMatrix<f64> {
        &self.sigma
    }

    fn covariance_step(&mut self) {
        self.prior.copy_from(&self.sigma);
        self.prior += &self.q;
        assert!(
            invert_spd(&self.prior, &mut self.work, &mut self.info),
            "CRKF prior covariance is positive definite"
        );
        self.info += &self.j;
        assert!(
            invert_spd(&self.info, &mut self.work, &mut self.next),
            "CRKF information matrix is positive definite"
        );
        self.frozen = converged(&self.next, &self.sigma);
        std::mem::swap(&mut self.next, &mut self.sigma);
        to_row_major(&self.sigma, &mut self.sigma_rm);
        self.trace = trace_of_product_sym(&self.sigma, &self.gtg);
    }
}

impl Estimator for Crkf {
    fn reset(&mut self) {
        self.sigma.copy_from(&self.sigma0);
        self.trace = trace_of_product_sym(&self.sigma, &self.gtg);
        self.frozen = false;
        self.zeta.fill(0.0);
        self.x.fill(0.0);
    }

    fn step(&mut self, input: &StepInput<'_>) {
        if !self.frozen {
            self.covariance_step();
        }
        let (r, d) = (self.runs, self.dim);
        let nz = self.sigma.nrows();
        // Prediction: ζ_n += Δt (u_n − u_0).
        for n in 1..=nz / d {
            for k in 0..d {
                let zrow = &mut self.zeta[((n - 1) * d + k) * r..((n - 1) * d + k + 1) * r];
                let un = &input.u_prev[(n * d + k) * r..(n * d + k + 1) * r];
                let u0 = &input.u_prev[k * r..(k + 1) * r];
                for ((z, a), b) in zrow.iter_mut().zip(un).zip(u0) {
                    *z += input.dt * (a - b);
                }
            }
        }
        // b = Gᵀ W⁻¹ ȳ − J ζ̂⁻.
        batch_gemv(&self.j_rm, nz, nz, &self.zeta, &mut self.b, r);
        for v in &mut self.b {
            *v = -*v;
        }
        for (e, &(i, j)) in self.edges.iter().enumerate() {
            self.s.fill(0.0);
            batch_gemv_acc(
                &self.w_inv[e * d * d..(e + 1) * d * d],
                d,
                &input.y[e * d * r..(e + 1) * d * r],
                &mut self.s,
                r,
            );
            for (node, sign) in [(i, 1.0), (j, -1.0)] {
                if node > 0 {
                    let rows = &mut self.b[(node - 1) * d * r..node * d * r];
                    for (bv, sv) in rows.iter_mut().zip(&self.s) {
                        *bv += sign * sv;
                    }
                }
            }
        }
        batch_gemv_acc(&self.sigma_rm, nz, &self.b, &mut self.zeta, r);
        // x̂_e = ζ̂_i − ζ̂_j with ζ̂_0 = 0.
        for (e, &(i, j)) in self.edges.iter().enumerate() {
            let xe = &mut self.x[e * d * r..(e + 1) * d * r];
            xe.fill(0.0);
            if i > 0 {
                for (xv, zv) in xe.iter_mut().zip(&self.zeta[(i - 1) * d * r..i * d * r]) {
                    *xv += zv;
                }
            }
            if j > 0 {
                for (xv, zv) in xe.iter_mut().zip(&self.zeta[(j - 1) * d * r..j * d * r]) {
                    *xv -= zv;
                }
            }
        }
    }

    fn estimates(&self) -> &[f64] {
        &self.x
    }

    fn cov_trace(&self) -> f64 {
        self.trace
    }
}
