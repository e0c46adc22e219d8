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
//! One covariance step costs an (N−1)D-sized inversion instead of an M·D-sized one (18 vs 120 for
//! the hexagon); a test checks the traces against the edge-space recursion. The covariance is
//! frozen once it has converged to rounding level ([`crate::linalg::converged`]).
//!
//! **Faults**: the information of the measurements that did not arrive is left out
//! (`J = Σ_{observed e} G_eᵀ W_e⁻¹ G_e`); the gain then depends on each run's faults, so each run
//! carries its own covariance. The centralised filter is a benchmark: it assumes one node
//! receives every measurement and input.
//!
//! # References
//! van der Marel & Rajan, EUSIPCO 2022, eq. (9); van der Marel, MSc thesis 2021, §5.2, Alg. 6.

use std::sync::Arc;

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use super::{
    parse_options, Breakdown, Configured, Consistency, Cost, Estimator, EstimatorKind, Model,
    Options, Reads, Step,
};
use crate::linalg::{
    batch_gemv, batch_gemv_acc, converged, invert_spd, to_row_major, trace_of_product_sym,
};

/// `kind = "crkf"`.
#[derive(Debug, Clone, Copy)]
pub struct Kind;

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NoOptions {}

impl EstimatorKind for Kind {
    fn name(&self) -> &'static str {
        "crkf"
    }
    fn about(&self) -> &'static str {
        "centralised relative Kalman filter (EUSIPCO eq. 9), exact node-relative form"
    }
    fn configure(&self, o: &Options, m: &Model) -> Result<Arc<dyn Configured>, String> {
        parse_options::<NoOptions>(o)?;
        if m.r().iter().any(|r| r.clone().cholesky().is_none()) {
            return Err(
                "crkf runs in information form and needs positive definite measurement covariances (noise.sigma_v > 0)"
                    .into(),
            );
        }
        Ok(Arc::new(Config))
    }
}

#[derive(Debug, Clone, Copy)]
struct Config;

impl Configured for Config {
    fn options(&self) -> Options {
        Options::new()
    }
    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        Box::new(Crkf::new(m, samples, runs, self.shared_gain(m)))
    }
    fn cost(&self, m: &Model) -> Cost {
        let nz = ((m.agents() - 1) * m.dim()) as f64;
        let md = (m.num_edges() * m.dim()) as f64;
        // Two Cholesky inversions (≈ nz³ each with the solves) and the products around them per
        // covariance step: ≈ 4 nz³ operations in time (measured: 7.7 s per step at nz = 1998,
        // the Speed chapter's 1,000 agents; `edgekf bench --cost` at small nz).
        let inv = 4.0 * nz * nz * nz;
        if self.shared_gain(m) {
            Cost {
                bytes_per_run: (nz + md) * 8.0 * 2.0,
                bytes_shared: 8.0 * nz * nz * 8.0,
                flops_per_run_step: 2.0 * nz * nz + 4.0 * md,
                flops_shared_step: inv,
            }
        } else {
            Cost {
                bytes_per_run: (nz + md) * 8.0 * 2.0 + 6.0 * nz * nz * 8.0,
                bytes_shared: 0.0,
                flops_per_run_step: inv + 4.0 * md,
                flops_shared_step: 0.0,
            }
        }
    }
    fn consistency(&self, m: &Model) -> Consistency {
        if m.measurement_faults() {
            Consistency::Approximate(
                "departed agents stop (no input, no process noise), which its model does not know",
            )
        } else {
            Consistency::Exact
        }
    }
}

/// One covariance recursion of ζ: shared by all runs, or of one run.
#[derive(Debug, Clone)]
struct NodeCov {
    sigma: DMatrix<f64>,
    prior: DMatrix<f64>,
    info: DMatrix<f64>,
    work: DMatrix<f64>,
    next: DMatrix<f64>,
    sigma_rm: Vec<f64>,
    frozen: bool,
    trace: f64,
}

impl NodeCov {
    fn new(sigma0: &DMatrix<f64>, gtg: &DMatrix<f64>) -> Self {
        let nz = sigma0.nrows();
        let mut c = Self {
            sigma: sigma0.clone(),
            prior: DMatrix::zeros(nz, nz),
            info: DMatrix::zeros(nz, nz),
            work: DMatrix::zeros(nz, nz),
            next: DMatrix::zeros(nz, nz),
            sigma_rm: vec![0.0; nz * nz],
            frozen: false,
            trace: 0.0,
        };
        to_row_major(&c.sigma, &mut c.sigma_rm);
        c.trace = trace_of_product_sym(&c.sigma, gtg);
        c
    }

    /// `Σ ← ((Σ + Q)⁻¹ + J)⁻¹`; `false` when a matrix is not positive definite.
    fn step(
        &mut self,
        q: &DMatrix<f64>,
        j: &DMatrix<f64>,
        gtg: &DMatrix<f64>,
        partial: bool,
    ) -> bool {
        self.prior.copy_from(&self.sigma);
        self.prior += q;
        if !invert_spd(&self.prior, &mut self.work, &mut self.info) {
            return false;
        }
        self.info += j;
        if !invert_spd(&self.info, &mut self.work, &mut self.next) {
            return false;
        }
        self.frozen = !partial && converged(&self.next, &self.sigma);
        std::mem::swap(&mut self.next, &mut self.sigma);
        to_row_major(&self.sigma, &mut self.sigma_rm);
        self.trace = trace_of_product_sym(&self.sigma, gtg);
        self.trace.is_finite()
    }
}

/// The CRKF.
#[derive(Debug, Clone)]
pub struct Crkf {
    runs: usize,
    dim: usize,
    edges: Vec<(usize, usize)>,
    /// `W_e⁻¹` per edge, row-major (for the batched products) and as matrices.
    w_inv: Vec<f64>,
    w_inv_m: Vec<DMatrix<f64>>,
    q: DMatrix<f64>,
    j: DMatrix<f64>,
    j_rm: Vec<f64>,
    gtg: DMatrix<f64>,
    /// One shared recursion, or one per run.
    covs: Vec<NodeCov>,
    shared: bool,
    /// Per-run information matrix scratch.
    j_run: DMatrix<f64>,
    zeta: Vec<f64>,
    b: Vec<f64>,
    s: Vec<f64>,
    /// One edge's measurement means (D rows × runs), formed as they are read.
    y_edge: Vec<f64>,
    x: Vec<f64>,
    breakdown: Option<Breakdown>,
}

impl Crkf {
    /// For `runs` runs with `samples` measurements per step; `shared` selects one covariance for
    /// all runs (valid without measurement faults).
    ///
    /// # Panics
    /// If a measurement covariance is singular (the kind refuses that).
    pub fn new(m: &Model, samples: usize, runs: usize, shared: bool) -> Self {
        let d = m.dim();
        let nz = (m.agents() - 1) * d;
        let mut w_inv = Vec::with_capacity(m.num_edges() * d * d);
        let mut w_inv_m = Vec::with_capacity(m.num_edges());
        for w in &m.mean_cov(samples) {
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
        for a in 1..m.agents() {
            for b in 1..m.agents() {
                let (ra, rb) = ((a - 1) * d, (b - 1) * d);
                let qb = m.q_block(a, b) - m.q_block(a, 0) - m.q_block(0, b) + m.q_block(0, 0);
                q.view_mut((ra, rb), (d, d)).copy_from(&qb);
                let p = m.p() * if a == b { 2.0 } else { 1.0 };
                sigma0.view_mut((ra, rb), (d, d)).copy_from(&p);
            }
        }
        for (e, wi) in w_inv_m.iter().enumerate() {
            add_edge_information(&mut j, m.edges()[e], d, wi);
            let (i, k) = m.edges()[e];
            for (a, ca) in [(i, 1.0), (k, -1.0)] {
                for (b, cb) in [(i, 1.0), (k, -1.0)] {
                    if a > 0 && b > 0 {
                        for c in 0..d {
                            gtg[((a - 1) * d + c, (b - 1) * d + c)] += ca * cb;
                        }
                    }
                }
            }
        }
        let mut j_rm = vec![0.0; nz * nz];
        to_row_major(&j, &mut j_rm);
        let proto = NodeCov::new(&sigma0, &gtg);
        let covs = if shared {
            vec![proto]
        } else {
            vec![proto; runs]
        };
        Self {
            runs,
            dim: d,
            edges: m.edges().to_vec(),
            w_inv,
            w_inv_m,
            q,
            j_run: DMatrix::zeros(nz, nz),
            j,
            j_rm,
            gtg,
            covs,
            shared,
            zeta: vec![0.0; nz * runs],
            b: vec![0.0; nz * runs],
            s: vec![0.0; d * runs],
            y_edge: vec![0.0; d * runs],
            x: vec![0.0; m.num_edges() * d * runs],
            breakdown: None,
        }
    }

    /// Posterior covariance of the node-relative state ζ (of run `r` for the per-run path).
    pub fn node_covariance(&self, r: usize) -> &DMatrix<f64> {
        &self.covs[if self.shared { 0 } else { r }].sigma
    }

    fn fail(&mut self) {
        self.breakdown.get_or_insert(Breakdown {
            what: "the CRKF covariance lost positive definiteness".into(),
        });
    }

    /// Prediction: `ζ_n += Δt (u_n − u_0)`.
    fn predict(&mut self, s: &Step<'_>) {
        let (r, d) = (self.runs, self.dim);
        for n in 1..=self.q.nrows() / d {
            for k in 0..d {
                let zrow = &mut self.zeta[((n - 1) * d + k) * r..((n - 1) * d + k + 1) * r];
                let un = &s.u_prev[(n * d + k) * r..(n * d + k + 1) * r];
                let u0 = &s.u_prev[k * r..(k + 1) * r];
                for ((z, a), b) in zrow.iter_mut().zip(un).zip(u0) {
                    *z += s.dt * (a - b);
                }
            }
        }
    }

    /// The update run by run (measurements fail run by run): each run's information from its
    /// observed edges, its covariance, then `ζ̂ += Σ (b − J ζ̂⁻)`. False when a covariance lost
    /// positive definiteness.
    fn correct_per_run(&mut self, s: &Step<'_>) -> bool {
        let (r, d, nz) = (self.runs, self.dim, self.q.nrows());
        self.b.fill(0.0);
        self.information_vector(s);
        for run in 0..r {
            self.j_run.fill(0.0);
            let mut partial = false;
            for (e, wi) in self.w_inv_m.iter().enumerate() {
                if s.faults.observed(e, run) {
                    add_edge_information(&mut self.j_run, self.edges[e], d, wi);
                } else {
                    partial = true;
                }
            }
            let c = &mut self.covs[run];
            if (!c.frozen || partial) && !c.step(&self.q, &self.j_run, &self.gtg, partial) {
                return false;
            }
            // ζ̂ += Σ (b − J ζ̂⁻) for this run.
            for a in 0..nz {
                let mut v = self.b[a * r + run];
                for c2 in 0..nz {
                    v -= self.j_run[(a, c2)] * self.zeta[c2 * r + run];
                }
                self.b[a * r + run] = v;
            }
            for a in 0..nz {
                let mut v = 0.0;
                for c2 in 0..nz {
                    v += c.sigma_rm[a * nz + c2] * self.b[c2 * r + run];
                }
                self.zeta[a * r + run] += v;
            }
        }
        true
    }

    /// `x̂_e = ζ̂_i − ζ̂_j` with `ζ̂_0 = 0`.
    fn edge_estimates(&mut self) {
        let block = self.runs * self.dim;
        let node = |n: usize| (n > 0).then(|| &self.zeta[(n - 1) * block..n * block]);
        for (e, &(i, j)) in self.edges.iter().enumerate() {
            edge_estimate_row(&mut self.x[e * block..(e + 1) * block], node(i), node(j));
        }
    }

    /// `b = Gᵀ W⁻¹ ȳ` over the observed edges (runs innermost).
    fn information_vector(&mut self, s: &Step<'_>) {
        let (r, d) = (self.runs, self.dim);
        let faults = s.faults.measurement_faults();
        for (e, &(i, j)) in self.edges.iter().enumerate() {
            s.means.edges_into(e, &mut self.y_edge);
            let w = &self.w_inv[e * d * d..(e + 1) * d * d];
            if d == 2 && !faults {
                add_edge_vector2(w, &self.y_edge, &mut self.b, (i, j), r);
                continue;
            }
            self.s.fill(0.0);
            batch_gemv_acc(w, d, &self.y_edge, &mut self.s, r);
            if faults {
                for (run, &seen) in s.faults.observed_row(e).iter().enumerate() {
                    if !seen {
                        for c in 0..d {
                            self.s[c * r + run] = 0.0;
                        }
                    }
                }
            }
            add_to_agents(&mut self.b, &self.s, (i, j), d * r);
        }
    }
}

/// `b_i += s`, `b_j −= s` (`s`: one edge's vector, `block` = D·runs values; agent 0 has no rows).
fn add_to_agents(b: &mut [f64], s: &[f64], (i, j): (usize, usize), block: usize) {
    for (node, sign) in [(i, 1.0), (j, -1.0)] {
        if node > 0 {
            let rows = &mut b[(node - 1) * block..node * block];
            for (bv, sv) in rows.iter_mut().zip(s) {
                *bv += sign * sv;
            }
        }
    }
}

/// `b_i += W⁻¹ ȳ_e`, `b_j −= W⁻¹ ȳ_e` for edge `(i, j)` with D = 2 (`w`: `W⁻¹` row-major, `y`:
/// the edge's means, 2 rows × runs): the general path's operations in one pass. Its product
/// starts at zero and skips zero entries of `W⁻¹`; here a skipped term is `+0`, which adds
/// nothing because a sum `0 + a` is never `−0` — so the bits are the general path's.
#[inline]
fn add_edge_vector2(w: &[f64], y: &[f64], b: &mut [f64], (i, j): (usize, usize), runs: usize) {
    let k: [f64; 4] = w.try_into().expect("a 2 × 2 matrix");
    let (y0, y1) = y[..2 * runs].split_at(runs);
    let block = 2 * runs;
    let (lo, hi) = (i.min(j), i.max(j));
    if hi == 0 {
        return;
    }
    // b_i gains the product, b_j loses it; agent 0 has no rows (ζ_0 = 0).
    let (sign_lo, sign_hi) = if i < j { (1.0, -1.0) } else { (-1.0, 1.0) };
    let (head, tail) = b.split_at_mut((hi - 1) * block);
    let (h0, h1) = tail[..block].split_at_mut(runs);
    let mut lo_rows = (lo > 0).then(|| head[(lo - 1) * block..lo * block].split_at_mut(runs));
    let from = crate::linalg::avx2_prefix!({
        let lo = lo_rows
            .as_mut()
            .map(|(l0, l1)| (&mut **l0, &mut **l1, sign_lo));
        edge_vector2_avx2(k, (y0, y1), lo, (h0, h1, sign_hi))
    });
    for r in from..runs {
        let (s0, s1) = product2(k, y0[r], y1[r]);
        if let Some((l0, l1)) = lo_rows.as_mut() {
            l0[r] += sign_lo * s0;
            l1[r] += sign_lo * s1;
        }
        h0[r] += sign_hi * s0;
        h1[r] += sign_hi * s1;
    }
}

/// [`add_edge_vector2`]'s loop over the runs, four at a time in AVX2 registers, up to the last
/// multiple of four (returned): the same operations in the same order — a zero entry's term is
/// `+0` (the product masked), no fused multiply–add — so the same bits, without the set-up the
/// compiler generates for each edge's loop. `lo` is the lower agent's rows and sign (none for
/// agent 0), `hi` the higher agent's.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn edge_vector2_avx2(
    k: [f64; 4],
    (y0, y1): (&[f64], &[f64]),
    lo: Option<(&mut [f64], &mut [f64], f64)>,
    (h0, h1, sign_hi): (&mut [f64], &mut [f64], f64),
) -> usize {
    use std::arch::x86_64::*;
    let runs = y0.len();
    assert!(y1.len() == runs && h0.len() == runs && h1.len() == runs);
    let full = runs - runs % 4;
    let kv = k.map(|c| _mm256_set1_pd(c));
    let mask = k.map(|c| _mm256_castsi256_pd(_mm256_set1_epi64x(if c != 0.0 { -1 } else { 0 })));
    let term = |c: usize, v: __m256d| _mm256_and_pd(_mm256_mul_pd(kv[c], v), mask[c]);
    let zero = _mm256_setzero_pd();
    let shi = _mm256_set1_pd(sign_hi);
    let (py0, py1, ph0, ph1) = (y0.as_ptr(), y1.as_ptr(), h0.as_mut_ptr(), h1.as_mut_ptr());
    let lo = lo.map(|(l0, l1, s)| {
        assert!(l0.len() == runs && l1.len() == runs);
        (l0.as_mut_ptr(), l1.as_mut_ptr(), _mm256_set1_pd(s))
    });
    let mut r = 0;
    while r < full {
        // SAFETY: r + 4 ≤ runs, within every row (their lengths asserted above).
        unsafe {
            let (v0, v1) = (_mm256_loadu_pd(py0.add(r)), _mm256_loadu_pd(py1.add(r)));
            let s0 = _mm256_add_pd(_mm256_add_pd(zero, term(0, v0)), term(1, v1));
            let s1 = _mm256_add_pd(_mm256_add_pd(zero, term(2, v0)), term(3, v1));
            let acc = |p: *mut f64, sign: __m256d, s: __m256d| {
                _mm256_storeu_pd(p, _mm256_add_pd(_mm256_loadu_pd(p), _mm256_mul_pd(sign, s)));
            };
            if let Some((l0, l1, slo)) = lo {
                acc(l0.add(r), slo, s0);
                acc(l1.add(r), slo, s1);
            }
            acc(ph0.add(r), shi, s0);
            acc(ph1.add(r), shi, s1);
        }
        r += 4;
    }
    full
}

/// One edge's estimates `x` from its agents' rows of `ζ̂` (agent 0 has none: `None`), in one pass.
fn edge_estimate_row(x: &mut [f64], zi: Option<&[f64]>, zj: Option<&[f64]>) {
    let from = crate::linalg::avx2_prefix!(edge_estimate_avx2(x, zi, zj));
    for (k, xv) in x.iter_mut().enumerate().skip(from) {
        *xv = edge_estimate(zi.map(|z| z[k]), zj.map(|z| z[k]));
    }
}

/// One value of `x̂_ij = ζ̂_i − ζ̂_j` as `(0 + ζ̂_i) − ζ̂_j` (agent 0's `ζ̂ = 0` has no row: `None`).
#[inline(always)]
fn edge_estimate(zi: Option<f64>, zj: Option<f64>) -> f64 {
    let mut x = 0.0;
    if let Some(v) = zi {
        x += v;
    }
    if let Some(v) = zj {
        x -= v;
    }
    x
}

/// [`edge_estimate`] for four values at a time in AVX2 registers, up to the last multiple of
/// four of `x.len()` (returned): the same operations, so the same bits, in one pass instead
/// of three.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn edge_estimate_avx2(x: &mut [f64], zi: Option<&[f64]>, zj: Option<&[f64]>) -> usize {
    use std::arch::x86_64::*;
    let n = x.len();
    assert!(zi.is_none_or(|z| z.len() == n) && zj.is_none_or(|z| z.len() == n));
    let full = n - n % 4;
    let (pi, pj, px) = (
        zi.map(<[f64]>::as_ptr),
        zj.map(<[f64]>::as_ptr),
        x.as_mut_ptr(),
    );
    let mut k = 0;
    while k < full {
        // SAFETY: k + 4 ≤ n, within every slice (their lengths asserted above).
        unsafe {
            let mut v = _mm256_setzero_pd();
            if let Some(p) = pi {
                v = _mm256_add_pd(v, _mm256_loadu_pd(p.add(k)));
            }
            if let Some(p) = pj {
                v = _mm256_sub_pd(v, _mm256_loadu_pd(p.add(k)));
            }
            _mm256_storeu_pd(px.add(k), v);
        }
        k += 4;
    }
    full
}

/// `W⁻¹ v` as `batch_gemv_acc` sums it from zero (a zero entry's term is `+0`: see above).
#[inline(always)]
fn product2([k0, k1, k2, k3]: [f64; 4], v0: f64, v1: f64) -> (f64, f64) {
    let term = |kc: f64, v: f64| if kc != 0.0 { kc * v } else { 0.0 };
    (
        (0.0 + term(k0, v0)) + term(k1, v1),
        (0.0 + term(k2, v0)) + term(k3, v1),
    )
}

/// `J += G_eᵀ W_e⁻¹ G_e` for edge `(i, j)` in node-relative coordinates.
fn add_edge_information(j: &mut DMatrix<f64>, (a, b): (usize, usize), d: usize, wi: &DMatrix<f64>) {
    for (p, cp) in [(a, 1.0), (b, -1.0)] {
        for (q, cq) in [(a, 1.0), (b, -1.0)] {
            if p > 0 && q > 0 {
                // Entry by entry: `view += wi * c` would allocate the product (this runs in
                // the step loop, per run, when measurements fail); the same floating-point
                // operations in the same order.
                let c = cp * cq;
                let (r0, c0) = ((p - 1) * d, (q - 1) * d);
                for col in 0..d {
                    for row in 0..d {
                        j[(r0 + row, c0 + col)] += wi[(row, col)] * c;
                    }
                }
            }
        }
    }
}

impl Estimator for Crkf {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        // Each edge's means formed as `information_vector` reads them.
        Reads::MEANS.forming_means()
    }
    fn step(&mut self, s: &Step<'_>) {
        if self.breakdown.is_some() {
            return;
        }
        self.predict(s);
        let (r, nz) = (self.runs, self.q.nrows());
        if self.shared {
            if !self.covs[0].frozen && !self.covs[0].step(&self.q, &self.j, &self.gtg, false) {
                self.fail();
                return;
            }
            // b = Gᵀ W⁻¹ ȳ − J ζ̂⁻.
            batch_gemv(&self.j_rm, nz, nz, &self.zeta, &mut self.b, r);
            for v in &mut self.b {
                *v = -*v;
            }
            self.information_vector(s);
            batch_gemv_acc(&self.covs[0].sigma_rm, nz, &self.b, &mut self.zeta, r);
        } else if !self.correct_per_run(s) {
            self.fail();
            return;
        }
        self.edge_estimates();
    }

    fn estimates(&self) -> &[f64] {
        &self.x
    }

    fn cov_trace(&self, _s: &Step<'_>, out: &mut [f64]) {
        if self.shared {
            out.fill(self.covs[0].trace);
        } else {
            for (o, c) in out.iter_mut().zip(&self.covs) {
                *o = c.trace;
            }
        }
    }

    fn breakdown(&self) -> Option<&Breakdown> {
        self.breakdown.as_ref()
    }

    fn covariances(&self, r: usize) -> Vec<DMatrix<f64>> {
        vec![self.node_covariance(r).clone()]
    }

    /// `Cov(ζ_i − ζ_j) = Σ_ii + Σ_jj − Σ_ij − Σ_ji` in node space (`ζ_0 = 0`: agent 0's blocks
    /// are zero), the edge's block of `G Σ Gᵀ`.
    fn edge_covariance(&self, e: usize, r: usize, out: &mut [f64]) -> bool {
        let (i, j) = self.edges[e];
        let (d, s) = (self.dim, self.node_covariance(r));
        let block = |p: usize, q: usize, a: usize, b: usize| {
            if p == 0 || q == 0 {
                0.0
            } else {
                s[((p - 1) * d + a, (q - 1) * d + b)]
            }
        };
        for a in 0..d {
            for b in 0..d {
                out[a * d + b] =
                    block(i, i, a, b) + block(j, j, a, b) - block(i, j, a, b) - block(j, i, a, b);
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_edge_estimates_have_the_bits_of_three_passes() {
        use crate::step::tests::{bits, mixed};
        for n in 1..20 {
            let (a, b) = (mixed(n, 7), mixed(n, 8));
            for (zi, zj) in [(Some(&a), Some(&b)), (None, Some(&b)), (Some(&a), None)] {
                // What `edge_estimates` did before it was one pass: fill, add, subtract.
                let mut want = vec![0.0; n];
                if let Some(z) = zi {
                    want.iter_mut().zip(z).for_each(|(x, v)| *x += v);
                }
                if let Some(z) = zj {
                    want.iter_mut().zip(z).for_each(|(x, v)| *x -= v);
                }
                let (zi, zj) = (zi.map(Vec::as_slice), zj.map(Vec::as_slice));
                let mut got = vec![f64::NAN; n];
                edge_estimate_row(&mut got, zi, zj);
                assert_eq!(bits(&got), bits(&want), "{n} values");
            }
        }
    }

    #[test]
    fn the_fused_edge_vector_has_the_bits_of_the_general_path() {
        // W⁻¹ with and without zero entries, edges at agent 0 (no rows) and between others in
        // both orders; means with zeros of both signs, pairs whose two terms are both `−0` (the
        // sum from `+0` is then `+0`, which an agent's row at `−0` shows) and infinities (a zero
        // entry's term is skipped, not `0 · ∞`); agents' rows random or all `−0` (as `−J ζ̂` has
        // them); every run count from 1 to 19, and 50.
        use crate::step::tests::{bits, mixed};
        let inverses = [
            [2.5, -0.75, -0.75, 2.5],
            [4.0, 0.0, 0.0, 4.0],
            [0.0, 1.5, -2.0, 0.0],
        ];
        for w in inverses {
            for edge in [(0, 2), (3, 0), (1, 4), (4, 1), (0, 0)] {
                for runs in (1..20).chain([50]) {
                    let mut y = mixed(2 * runs, 9);
                    for r in 0..runs {
                        if r % 5 == 0 {
                            (y[r], y[runs + r]) = (-0.0, 0.0);
                        }
                        if r % 7 == 3 {
                            y[r] = f64::INFINITY;
                        }
                    }
                    for b0 in [mixed(4 * 2 * runs, 10), vec![-0.0; 4 * 2 * runs]] {
                        let mut fused = b0.clone();
                        add_edge_vector2(&w, &y, &mut fused, edge, runs);
                        // The general path of `information_vector`.
                        let mut general = b0.clone();
                        let mut s = vec![0.0; 2 * runs];
                        batch_gemv_acc(&w, 2, &y, &mut s, runs);
                        add_to_agents(&mut general, &s, edge, 2 * runs);
                        assert_eq!(bits(&fused), bits(&general), "{w:?} {edge:?} {runs} runs");
                    }
                }
            }
        }
    }
}
