//! Small-matrix Kalman kernels, and the per-run single-edge filter bank.
//!
//! - [`joseph_step`]: one D × D covariance/gain step in Joseph form (closed form for D = 2), the
//!   one piece of arithmetic shared by every single-edge filter, so the shared-gain and per-run
//!   filters produce the same bits for the same inputs.
//! - [`EdgeCov`]: the covariance recursion of one edge, frozen once it has converged to rounding
//!   level — the shared-gain RKF keeps one per edge; it is also the piece to embed on an agent.
//! - [`EdgeBank`]: one covariance per (edge, run) as structure of arrays — `Σ` packed
//!   (`D(D+1)/2` unique entries), gain, frozen flag, each a flat array with the runs innermost —
//!   for filters whose gain depends on each run's data (lost links, intermittent observations,
//!   predicted inputs). Each (edge, run) step applies the same [`joseph_step`] as [`EdgeCov`].

use nalgebra::SMatrix;

/// A D × D matrix.
pub type Mat<const D: usize> = SMatrix<f64, D, D>;

/// One Kalman covariance/gain step in Joseph form for an update with the full edge observed:
/// `K = Σ⁻ (Σ⁻ + W)⁻¹`, `Σ⁺ = (I − K) Σ⁻ (I − K)ᵀ + K W Kᵀ` (symmetrised). Returns `None` if the
/// innovation covariance `Σ⁻ + W` is not positive definite (or not finite).
#[inline]
pub fn joseph_step<const D: usize>(prior: &Mat<D>, w: &Mat<D>) -> Option<(Mat<D>, Mat<D>)> {
    if D == 2 {
        return joseph_2x2(prior, w);
    }
    let s = prior + w;
    if (0..D).any(|i| !(s[(i, i)] > 0.0 && s[(i, i)].is_finite())) {
        return None;
    }
    let inv = s.try_inverse()?;
    if !inv.iter().all(|v| v.is_finite()) {
        return None;
    }
    let k = prior * inv;
    let a = Mat::<D>::identity() - k;
    let post = a * prior * a.transpose() + k * w * k.transpose();
    Some((0.5 * (post + post.transpose()), k))
}

/// [`joseph_step`] for D = 2 in closed form (both matrices symmetric), about three times faster
/// than the generic path.
#[inline]
fn joseph_2x2<const D: usize>(p: &Mat<D>, w: &Mat<D>) -> Option<(Mat<D>, Mat<D>)> {
    let (p11, p12, p22) = (p[(0, 0)], p[(0, 1)], p[(1, 1)]);
    let (w11, w12, w22) = (w[(0, 0)], w[(0, 1)], w[(1, 1)]);
    let (s11, s12, s22) = (p11 + w11, p12 + w12, p22 + w22);
    let det = s11 * s22 - s12 * s12;
    if !(det > 0.0 && det.is_finite() && s11 > 0.0) {
        return None;
    }
    let r = 1.0 / det;
    let (i11, i12, i22) = (s22 * r, -s12 * r, s11 * r);
    let (k11, k12) = (p11 * i11 + p12 * i12, p11 * i12 + p12 * i22);
    let (k21, k22) = (p12 * i11 + p22 * i12, p12 * i12 + p22 * i22);
    let (a11, a12, a21, a22) = (1.0 - k11, -k12, -k21, 1.0 - k22);
    // A Σ Aᵀ
    let (m11, m12) = (a11 * p11 + a12 * p12, a11 * p12 + a12 * p22);
    let (m21, m22) = (a21 * p11 + a22 * p12, a21 * p12 + a22 * p22);
    let (c11, c12) = (m11 * a11 + m12 * a12, m11 * a21 + m12 * a22);
    let (c21, c22) = (m21 * a11 + m22 * a12, m21 * a21 + m22 * a22);
    // K W Kᵀ
    let (n11, n12) = (k11 * w11 + k12 * w12, k11 * w12 + k12 * w22);
    let (n21, n22) = (k21 * w11 + k22 * w12, k21 * w12 + k22 * w22);
    let (d11, d12) = (n11 * k11 + n12 * k12, n11 * k21 + n12 * k22);
    let (d21, d22) = (n21 * k11 + n22 * k12, n21 * k21 + n22 * k22);
    let off = 0.5 * ((c12 + d12) + (c21 + d21));
    let mut post = Mat::<D>::zeros();
    post[(0, 0)] = c11 + d11;
    post[(1, 1)] = c22 + d22;
    post[(0, 1)] = off;
    post[(1, 0)] = off;
    let mut k = Mat::<D>::zeros();
    k[(0, 0)] = k11;
    k[(0, 1)] = k12;
    k[(1, 0)] = k21;
    k[(1, 1)] = k22;
    Some((post, k))
}

/// Whether `new` differs from `old` by at most `8 ε max|old|` in every entry: a recursion that
/// has converged to rounding level (further steps only add rounding noise).
#[inline]
pub fn settled<const D: usize>(new: &Mat<D>, old: &Mat<D>) -> bool {
    let tol = 8.0 * f64::EPSILON * old.amax();
    new.iter()
        .zip(old.iter())
        .all(|(a, b)| (a - b).abs() <= tol)
}

/// The covariance recursion of one edge, frozen once converged to rounding level.
///
/// This is also the piece to embed on a real agent: one `EdgeCov` per neighbour, a D-vector
/// estimate, and per step the prediction with the communicated inputs and the update with the
/// mean of the T measurements.
///
/// ```
/// use edgekf::estimate::batch::EdgeCov;
/// use nalgebra::{Matrix2, Vector2};
///
/// let q = Matrix2::new(2e-6, 0.0, 0.0, 2e-6); // Q_ij = B̄_ijᵀ Q B̄_ij
/// let w = Matrix2::new(1e-3, 3e-4, 3e-4, 1e-3); // R_ij / T
/// let mut cov = EdgeCov::<2>::new(Matrix2::identity() * 2.0); // Σ_{0|0} = 2P
/// let mut z = Vector2::zeros(); // ẑ_{0|0}
/// let (dt, u_i, u_j) = (1e-3, Vector2::new(0.1, 0.0), Vector2::new(0.0, 0.2));
/// for _ in 0..1000 {
///     let y_mean = Vector2::new(1.0, -0.5); // mean of this step's T measurements of z_i − z_j
///     z += dt * (u_i - u_j); // (5c)
///     cov.step(&q, &w, None, true).expect("positive definite"); // (5d), (5e), (5g)
///     z += cov.gain * (y_mean - z); // (5f)
/// }
/// assert!(cov.sigma.trace() < 0.01);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeCov<const D: usize> {
    /// Posterior covariance `Σ_{k|k}`.
    pub sigma: Mat<D>,
    /// Gain `K_k` (zero after a step without observation).
    pub gain: Mat<D>,
    /// Converged: the next step would change nothing beyond rounding.
    pub frozen: bool,
}

impl<const D: usize> EdgeCov<D> {
    /// Starts at `Σ_{0|0}`.
    pub fn new(sigma0: Mat<D>) -> Self {
        Self {
            sigma: sigma0,
            gain: Mat::<D>::zeros(),
            frozen: false,
        }
    }

    /// One predict–update covariance step with process covariance `q` (plus `extra`, an input
    /// prediction's covariance, which unfreezes) and measurement covariance `w`; without an
    /// observation only the prediction runs and the gain is zero.
    ///
    /// # Errors
    /// `Err(())` when the innovation covariance is not positive definite; the state is left
    /// unchanged.
    #[inline]
    #[allow(clippy::result_unit_err)]
    pub fn step(
        &mut self,
        q: &Mat<D>,
        w: &Mat<D>,
        extra: Option<&Mat<D>>,
        observed: bool,
    ) -> Result<(), ()> {
        if self.frozen && extra.is_none() && observed {
            return Ok(());
        }
        let mut prior = self.sigma + q;
        if let Some(x) = extra {
            prior += x;
        }
        if !observed {
            self.sigma = prior;
            self.gain = Mat::<D>::zeros();
            self.frozen = false;
            return Ok(());
        }
        let (post, k) = joseph_step(&prior, w).ok_or(())?;
        self.frozen = extra.is_none() && settled(&post, &self.sigma);
        self.sigma = post;
        self.gain = k;
        Ok(())
    }
}

/// The batched closed-form 2 × 2 Joseph step over the runs of one edge (structure of arrays):
/// `Q`, `W` and the input-prediction covariance as `[11, 12, 22]` entries.
#[derive(Debug, Clone, Copy)]
struct Joseph2 {
    q: [f64; 3],
    w: [f64; 3],
    x: [f64; 3],
}

impl Joseph2 {
    /// Runs per vector (4 × f64 in AVX2).
    const LANES: usize = 4;

    /// Runs the step; returns the number of runs whose innovation covariance is not positive
    /// definite. On x86-64 with AVX2 the same loop is compiled for 4-wide vectors (no fused
    /// multiply–add: the bits are those of the scalar code).
    fn run(
        &self,
        cov: [&mut [f64]; 3],
        gain: [&mut [f64]; 4],
        frozen: &mut [bool],
        lost: &[bool],
        observed: &[bool],
    ) -> usize {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above).
                return unsafe { self.run_avx2(cov, gain, frozen, lost, observed) };
            }
        }
        self.dispatch(cov, gain, frozen, lost, observed)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(
        &self,
        cov: [&mut [f64]; 3],
        gain: [&mut [f64]; 4],
        frozen: &mut [bool],
        lost: &[bool],
        observed: &[bool],
    ) -> usize {
        self.dispatch(cov, gain, frozen, lost, observed)
    }

    /// Runs the whole vectors of [`Joseph2::LANES`] runs in place, and the last runs (fewer than
    /// a vector) through a padded copy, so that no run takes the slow scalar remainder loop. The
    /// padding lanes are unobserved (they never count as failures) and are dropped.
    #[inline(always)]
    fn dispatch(
        &self,
        cov: [&mut [f64]; 3],
        gain: [&mut [f64]; 4],
        frozen: &mut [bool],
        lost: &[bool],
        observed: &[bool],
    ) -> usize {
        const L: usize = Joseph2::LANES;
        let runs = frozen.len();
        let main = runs - runs % L;
        let [c, c12, c22] = cov;
        let [g11, g12, g21, g22] = gain;
        let (c, ct) = c[..runs].split_at_mut(main);
        let (c12, c12t) = c12[..runs].split_at_mut(main);
        let (c22, c22t) = c22[..runs].split_at_mut(main);
        let (g11, g11t) = g11[..runs].split_at_mut(main);
        let (g12, g12t) = g12[..runs].split_at_mut(main);
        let (g21, g21t) = g21[..runs].split_at_mut(main);
        let (g22, g22t) = g22[..runs].split_at_mut(main);
        let (frozen, frozent) = frozen.split_at_mut(main);
        let (lost, lostt) = lost[..runs].split_at(main);
        let (observed, observedt) = observed[..runs].split_at(main);
        let mut bad = self.specialised([c, c12, c22], [g11, g12, g21, g22], frozen, lost, observed);
        let tail = runs - main;
        if tail > 0 {
            // Σ = I in the padding lanes keeps their arithmetic finite.
            let (mut pc, mut pc12, mut pc22) = ([1.0; L], [0.0; L], [1.0; L]);
            let mut pg = [[0.0; L]; 4];
            let (mut pf, mut pl, mut po) = ([false; L], [false; L], [false; L]);
            pc[..tail].copy_from_slice(ct);
            pc12[..tail].copy_from_slice(c12t);
            pc22[..tail].copy_from_slice(c22t);
            for (p, g) in pg.iter_mut().zip([&*g11t, &*g12t, &*g21t, &*g22t]) {
                p[..tail].copy_from_slice(g);
            }
            pf[..tail].copy_from_slice(frozent);
            pl[..tail].copy_from_slice(lostt);
            po[..tail].copy_from_slice(observedt);
            let [p11, p12, p21, p22] = &mut pg;
            bad += self.specialised(
                [&mut pc, &mut pc12, &mut pc22],
                [p11, p12, p21, p22],
                &mut pf,
                &pl,
                &po,
            );
            ct.copy_from_slice(&pc[..tail]);
            c12t.copy_from_slice(&pc12[..tail]);
            c22t.copy_from_slice(&pc22[..tail]);
            for (g, p) in [g11t, g12t, g21t, g22t].into_iter().zip(&pg) {
                g.copy_from_slice(&p[..tail]);
            }
            frozent.copy_from_slice(&pf[..tail]);
        }
        bad
    }

    /// [`Joseph2::body`] specialised for the common cases — no run frozen, every run observed —
    /// where the selects they need fold away (the same bits: they would select the same values).
    #[inline(always)]
    fn specialised(
        &self,
        cov: [&mut [f64]; 3],
        gain: [&mut [f64]; 4],
        frozen: &mut [bool],
        lost: &[bool],
        observed: &[bool],
    ) -> usize {
        // `contains` on bytes is a vectorised search (an `any` loop here was 8 % of the kernel).
        let any_frozen = frozen.contains(&true);
        let all_observed = !observed.contains(&false);
        match (any_frozen, all_observed) {
            (false, true) => self.body::<false, true>(cov, gain, frozen, lost, observed),
            (false, false) => self.body::<false, false>(cov, gain, frozen, lost, observed),
            (true, true) => self.body::<true, true>(cov, gain, frozen, lost, observed),
            (true, false) => self.body::<true, false>(cov, gain, frozen, lost, observed),
        }
    }

    /// One step per run: `EdgeCov::step` and `joseph_2x2`, operation for operation, written
    /// without branches so that it vectorises. `FROZEN = false` promises that no run is frozen,
    /// `ALL_OBSERVED = true` that every run is observed.
    #[inline(always)]
    fn body<const FROZEN: bool, const ALL_OBSERVED: bool>(
        &self,
        cov: [&mut [f64]; 3],
        gain: [&mut [f64]; 4],
        frozen: &mut [bool],
        lost: &[bool],
        observed: &[bool],
    ) -> usize {
        let [c, c12, c22] = cov;
        let [g11, g12, g21, g22] = gain;
        let runs = c.len();
        let [q11, q12, q22] = self.q;
        let [w11, w12, w22] = self.w;
        let [x11, x12, x22] = self.x;
        // Equal lengths, stated once, let the compiler drop the bounds checks and vectorise.
        let (c, c12, c22) = (&mut c[..runs], &mut c12[..runs], &mut c22[..runs]);
        let (g11, g12, g21, g22) = (
            &mut g11[..runs],
            &mut g12[..runs],
            &mut g21[..runs],
            &mut g22[..runs],
        );
        let (frozen, lost, observed) = (&mut frozen[..runs], &lost[..runs], &observed[..runs]);
        let mut bad = 0usize;
        for r in 0..runs {
            let (s11, s12, s22) = (c[r], c12[r], c22[r]);
            let (l, o) = (lost[r], ALL_OBSERVED || observed[r]);
            // Σ⁻ = Σ + Q (+ Δt² Σ_n), in EdgeCov::step's order of operations.
            let (a11, a12, a22) = (s11 + q11, s12 + q12, s22 + q22);
            let p11 = if l { a11 + x11 } else { a11 };
            let p12 = if l { a12 + x12 } else { a12 };
            let p22 = if l { a22 + x22 } else { a22 };
            // The closed-form Joseph step of `joseph_2x2`.
            let (t11, t12, t22) = (p11 + w11, p12 + w12, p22 + w22);
            let det = t11 * t22 - t12 * t12;
            // Non-short-circuit logic keeps the loop free of branches (it vectorises).
            let ok = (det > 0.0) & (det < f64::INFINITY) & (t11 > 0.0);
            let rd = 1.0 / det;
            let (i11, i12, i22) = (t22 * rd, -t12 * rd, t11 * rd);
            let (k11, k12) = (p11 * i11 + p12 * i12, p11 * i12 + p12 * i22);
            let (k21, k22) = (p12 * i11 + p22 * i12, p12 * i12 + p22 * i22);
            let (b11, b12, b21, b22) = (1.0 - k11, -k12, -k21, 1.0 - k22);
            let (m11, m12) = (b11 * p11 + b12 * p12, b11 * p12 + b12 * p22);
            let (m21, m22) = (b21 * p11 + b22 * p12, b21 * p12 + b22 * p22);
            let (d11, d12) = (m11 * b11 + m12 * b12, m11 * b21 + m12 * b22);
            let (d21, d22) = (m21 * b11 + m22 * b12, m21 * b21 + m22 * b22);
            let (n11, n12) = (k11 * w11 + k12 * w12, k11 * w12 + k12 * w22);
            let (n21, n22) = (k21 * w11 + k22 * w12, k21 * w12 + k22 * w22);
            let (e11, e12) = (n11 * k11 + n12 * k12, n11 * k21 + n12 * k22);
            let (e21, e22) = (n21 * k11 + n22 * k12, n21 * k21 + n22 * k22);
            let u11 = d11 + e11;
            let u22 = d22 + e22;
            let u12 = 0.5 * ((d12 + e12) + (d21 + e21));
            // Converged to rounding level (`settled`): no entry moves by more than 8 ε max|Σ|.
            let tol = 8.0 * f64::EPSILON * s11.abs().max(s12.abs()).max(s22.abs());
            let still = ((u11 - s11).abs() <= tol)
                & ((u12 - s12).abs() <= tol)
                & ((u22 - s22).abs() <= tol);
            let keep = FROZEN && (frozen[r] & !l & o);
            bad += usize::from(o & !keep & !ok);
            // Observed: the Joseph posterior; not observed: the prior, zero gain; frozen: as is.
            // Every entry is stored unconditionally through a bitwise select (`pick`): a
            // conditional store would compile to masked vector stores, which are slow on some
            // CPUs (on this machine's AMD EPYC they were half of this kernel's time).
            c[r] = pick(keep, s11, pick(o, u11, p11));
            c12[r] = pick(keep, s12, pick(o, u12, p12));
            c22[r] = pick(keep, s22, pick(o, u22, p22));
            g11[r] = pick(keep, g11[r], pick(o, k11, 0.0));
            g12[r] = pick(keep, g12[r], pick(o, k12, 0.0));
            g21[r] = pick(keep, g21[r], pick(o, k21, 0.0));
            g22[r] = pick(keep, g22[r], pick(o, k22, 0.0));
            frozen[r] = keep | (o & !l & still);
        }
        bad
    }
}

/// `if c { a } else { b }` as a bitwise select: the same bits, and no branch or masked store
/// when the compiler vectorises the loop around it.
#[inline(always)]
pub(crate) fn pick(c: bool, a: f64, b: f64) -> f64 {
    let m = 0u64.wrapping_sub(u64::from(c));
    f64::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

/// Number of unique entries of a symmetric D × D matrix.
pub const fn packed_len(d: usize) -> usize {
    d * (d + 1) / 2
}

/// The per-run single-edge filter bank: for every directed edge `e` and run `r`, the posterior
/// covariance (packed upper triangle), the last gain and a frozen flag, stored as structure of
/// arrays with the runs innermost (`[(e · S + s) · runs + r]`), plus the estimates
/// (`[(e · D + a) · runs + r]`, the engine's batch layout).
#[derive(Debug, Clone)]
pub struct EdgeBank<const D: usize> {
    runs: usize,
    edges: usize,
    cov: Vec<f64>,
    gain: Vec<f64>,
    frozen: Vec<bool>,
    /// Estimates `x̂_{k|k}` (MD rows × runs).
    pub x: Vec<f64>,
}

impl<const D: usize> EdgeBank<D> {
    const S: usize = packed_len(D);

    /// Every edge starts at its `Σ_{0|0}` and `x̂_{0|0} = 0`.
    pub fn new(sigma0: &[Mat<D>], runs: usize) -> Self {
        let edges = sigma0.len();
        let s = Self::S;
        let mut cov = vec![0.0; edges * s * runs];
        for (e, m) in sigma0.iter().enumerate() {
            for r in 0..runs {
                Self::store_into(&mut cov, runs, e, r, m);
            }
        }
        Self {
            runs,
            edges,
            cov,
            gain: vec![0.0; edges * D * D * runs],
            frozen: vec![false; edges * runs],
            x: vec![0.0; edges * D * runs],
        }
    }

    /// Runs in the bank.
    pub fn runs(&self) -> usize {
        self.runs
    }

    #[inline]
    fn store_into(cov: &mut [f64], runs: usize, e: usize, r: usize, m: &Mat<D>) {
        let mut s = 0;
        for a in 0..D {
            for b in a..D {
                cov[(e * Self::S + s) * runs + r] = m[(a, b)];
                s += 1;
            }
        }
    }

    /// `Σ` of edge `e` in run `r`.
    #[inline]
    pub fn sigma(&self, e: usize, r: usize) -> Mat<D> {
        let mut m = Mat::<D>::zeros();
        let mut s = 0;
        for a in 0..D {
            for b in a..D {
                let v = self.cov[(e * Self::S + s) * self.runs + r];
                m[(a, b)] = v;
                m[(b, a)] = v;
                s += 1;
            }
        }
        m
    }

    /// `tr Σ` of edge `e` in run `r`.
    #[inline]
    pub fn trace(&self, e: usize, r: usize) -> f64 {
        let mut t = 0.0;
        let mut s = 0;
        for a in 0..D {
            for b in a..D {
                if a == b {
                    t += self.cov[(e * Self::S + s) * self.runs + r];
                }
                s += 1;
            }
        }
        t
    }

    /// The covariance step of edge `e` in run `r` ([`EdgeCov::step`] on the stored state):
    /// process covariance `q`, optional input-prediction covariance `extra`, measurement
    /// covariance `w`, and whether the edge was observed.
    ///
    /// # Errors
    /// `Err(())` when the innovation covariance is not positive definite.
    #[inline]
    #[allow(clippy::result_unit_err)]
    pub fn covariance_step(
        &mut self,
        e: usize,
        r: usize,
        q: &Mat<D>,
        w: &Mat<D>,
        extra: Option<&Mat<D>>,
        observed: bool,
    ) -> Result<(), ()> {
        let f = e * self.runs + r;
        let mut c = EdgeCov {
            sigma: self.sigma(e, r),
            gain: Mat::<D>::zeros(),
            frozen: self.frozen[f],
        };
        if c.frozen && extra.is_none() && observed {
            return Ok(());
        }
        c.step(q, w, extra, observed)?;
        Self::store_into(&mut self.cov, self.runs, e, r, &c.sigma);
        self.frozen[f] = c.frozen;
        for a in 0..D {
            for b in 0..D {
                self.gain[((e * D + a) * D + b) * self.runs + r] = c.gain[(a, b)];
            }
        }
        Ok(())
    }

    /// The mean step of edge `e` in run `r`: `x̂ ← x̂ + Δx̂` (prediction increment), then
    /// `x̂ ← x̂ + K (ȳ − x̂)` with the gain of the last covariance step (zero without observation),
    /// in the same order of operations as the shared-gain filters, so equal gains give equal bits.
    #[inline]
    pub fn mean_step(&mut self, e: usize, r: usize, increment: &[f64; D], y: &[f64]) {
        let runs = self.runs;
        let mut innov = [0.0; D];
        for a in 0..D {
            let row = (e * D + a) * runs + r;
            self.x[row] += increment[a];
            innov[a] = y[row] - self.x[row];
        }
        for a in 0..D {
            let row = (e * D + a) * runs + r;
            for (b, v) in innov.iter().enumerate() {
                let k = self.gain[((e * D + a) * D + b) * runs + r];
                if k != 0.0 {
                    self.x[row] += k * v;
                }
            }
        }
    }

    /// Number of edges.
    pub fn edges(&self) -> usize {
        self.edges
    }

    /// The covariance step of edge `e` for every run at once ([`EdgeBank::covariance_step`] per
    /// run, bit for bit): `lost[r]` adds the input-prediction covariance `extra`, `observed[r]`
    /// says whether the edge was measured. For D = 2 this is a branch-free loop over the runs
    /// (structure of arrays) that the compiler vectorises.
    ///
    /// # Errors
    /// `Err(n)` with the number of runs whose innovation covariance is not positive definite.
    pub fn covariance_step_all(
        &mut self,
        e: usize,
        q: &Mat<D>,
        w: &Mat<D>,
        extra: &Mat<D>,
        lost: &[bool],
        observed: &[bool],
    ) -> Result<(), usize> {
        if D != 2 {
            for r in 0..self.runs {
                self.covariance_step(e, r, q, w, lost[r].then_some(extra), observed[r])
                    .map_err(|()| 1usize)?;
            }
            return Ok(());
        }
        let runs = self.runs;
        let (c, rest) = self.cov[e * 3 * runs..(e + 1) * 3 * runs].split_at_mut(runs);
        let (c12, c22) = rest.split_at_mut(runs);
        let g = &mut self.gain[e * 4 * runs..(e + 1) * 4 * runs];
        let (g11, rest) = g.split_at_mut(runs);
        let (g12, rest) = rest.split_at_mut(runs);
        let (g21, g22) = rest.split_at_mut(runs);
        let frozen = &mut self.frozen[e * runs..(e + 1) * runs];
        let k = Joseph2 {
            q: [q[(0, 0)], q[(0, 1)], q[(1, 1)]],
            w: [w[(0, 0)], w[(0, 1)], w[(1, 1)]],
            x: [extra[(0, 0)], extra[(0, 1)], extra[(1, 1)]],
        };
        let bad = k.run([c, c12, c22], [g11, g12, g21, g22], frozen, lost, observed);
        if bad == 0 {
            Ok(())
        } else {
            Err(bad)
        }
    }

    /// The mean step of edge `e` for every run: `x̂ ← x̂ + Δx̂` with the increments `inc`
    /// (D rows × runs), then `x̂ ← x̂ + K (ȳ − x̂)` with each run's gain.
    #[inline(always)]
    pub fn mean_step_all(&mut self, e: usize, inc: &[f64], y: &[f64]) {
        let runs = self.runs;
        if D != 2 {
            for r in 0..runs {
                let i: [f64; D] = std::array::from_fn(|a| inc[a * runs + r]);
                self.mean_step(e, r, &i, y);
            }
            return;
        }
        let (x0, x1) = self.x[e * 2 * runs..(e + 1) * 2 * runs].split_at_mut(runs);
        let (y0, y1) = y[e * 2 * runs..(e + 1) * 2 * runs].split_at(runs);
        let (i0, i1) = inc[..2 * runs].split_at(runs);
        let g = &self.gain[e * 4 * runs..(e + 1) * 4 * runs];
        let (g11, rest) = g.split_at(runs);
        let (g12, rest) = rest.split_at(runs);
        let (g21, g22) = rest.split_at(runs);
        let (x0, x1, y0, y1, i0, i1) = (
            &mut x0[..runs],
            &mut x1[..runs],
            &y0[..runs],
            &y1[..runs],
            &i0[..runs],
            &i1[..runs],
        );
        let (g11, g12, g21, g22) = (&g11[..runs], &g12[..runs], &g21[..runs], &g22[..runs]);
        for r in 0..runs {
            let a = x0[r] + i0[r];
            let b = x1[r] + i1[r];
            let (v0, v1) = (y0[r] - a, y1[r] - b);
            x0[r] = a + g11[r] * v0 + g12[r] * v1;
            x1[r] = b + g21[r] * v0 + g22[r] * v1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_2x2_matches_the_generic_joseph_form() {
        let p = Mat::<2>::new(0.7, 0.2, 0.2, 0.4);
        let w = Mat::<2>::new(0.01, 0.003, 0.003, 0.02);
        let (post, k) = joseph_step(&p, &w).unwrap();
        let kk = p * (p + w).try_inverse().unwrap();
        let a = Mat::<2>::identity() - kk;
        let want = a * p * a.transpose() + kk * w * kk.transpose();
        assert!((post - want).amax() < 1e-15 && (k - kk).amax() < 1e-15);
        assert_eq!(post[(0, 1)].to_bits(), post[(1, 0)].to_bits());
        // Not positive definite: refused, no panic.
        assert!(joseph_step(&Mat::<2>::zeros(), &Mat::<2>::zeros()).is_none());
        assert!(joseph_step(&Mat::<3>::zeros(), &Mat::<3>::zeros()).is_none());
        let nan = Mat::<2>::from_element(f64::NAN);
        assert!(joseph_step(&nan, &w).is_none());
    }

    #[test]
    fn bank_equals_edge_cov_bit_for_bit() {
        let q = Mat::<2>::new(1e-6, 2e-7, 2e-7, 1e-6);
        let w = Mat::<2>::new(1e-3, 3e-4, 3e-4, 1e-3);
        let x = Mat::<2>::identity() * 1e-5;
        let s0 = Mat::<2>::identity() * 2.0;
        let mut one = EdgeCov::new(s0);
        let mut bank = EdgeBank::<2>::new(&[s0, s0], 3);
        for k in 0..500 {
            let extra = (k % 7 == 3).then_some(&x);
            let obs = k % 11 != 5;
            one.step(&q, &w, extra, obs).unwrap();
            bank.covariance_step(1, 2, &q, &w, extra, obs).unwrap();
            let got = bank.sigma(1, 2);
            for (a, b) in got.iter().zip(one.sigma.iter()) {
                assert_eq!(a.to_bits(), b.to_bits(), "step {k}");
            }
        }
        // The batched kernel gives the same bits, run by run, for run counts that fill whole
        // vectors or leave a padded tail, through every specialisation: losses and missed
        // observations first (nothing frozen), then every run observed and nothing lost, so
        // that runs freeze, then losses again among frozen runs.
        for runs in [1usize, 3, 4, 7, 9] {
            let mut all = EdgeBank::<2>::new(&[s0], runs);
            let mut per = EdgeBank::<2>::new(&[s0], runs);
            let mut froze = false;
            for k in 0..1500usize {
                let phase = k / 500;
                let lost: Vec<bool> = (0..runs).map(|r| phase != 1 && (k + r) % 7 == 3).collect();
                let obs: Vec<bool> = (0..runs)
                    .map(|r| phase == 1 || (k * 3 + r) % 11 != 5)
                    .collect();
                all.covariance_step_all(0, &q, &w, &x, &lost, &obs).unwrap();
                for r in 0..runs {
                    per.covariance_step(0, r, &q, &w, lost[r].then_some(&x), obs[r])
                        .unwrap();
                    for (a, b) in all.sigma(0, r).iter().zip(per.sigma(0, r).iter()) {
                        assert_eq!(a.to_bits(), b.to_bits(), "{runs} runs, step {k} run {r}");
                    }
                }
                assert_eq!(all.gain, per.gain);
                assert_eq!(all.frozen, per.frozen);
                froze |= all.frozen.contains(&true);
            }
            assert!(froze, "{runs} runs: the frozen path was exercised");
        }
        // The other runs and edges were not touched.
        assert_eq!(bank.sigma(0, 2), s0);
        assert_eq!(bank.sigma(1, 0), s0);
    }
}
