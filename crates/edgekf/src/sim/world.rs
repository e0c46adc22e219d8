//! The world stage: the per-run random streams, the draws of each step in a documented, stable
//! order, the noise factors, and the targets.
//!
//! Run `r` draws from its own xoshiro256++ stream seeded from `(seed, r)` ([`crate::rng`]: normals
//! from its ziggurat, drawn for four runs at a time in SIMD lanes, each run's values those of
//! its own stream), in this order:
//! 1. at the start: the initial positions (N·D standard normals);
//! 2. every step k: the measurement-mean noise (M·D normals, only when R ≠ 0), the process noise
//!    (N·D normals, only when Q ≠ 0), the chapter 6 link-failure uniforms (M, only when an
//!    estimator has `0 < P_fail < 1`), the availability uniforms (M, only when `0 < λ < 1`).
//!
//! New draws are appended, never reordered: that order is part of the reproducibility contract.
//!
//! With random departures, run `r`'s departing agents come from a stream of their own
//! (`departure_subsets`), so none of the draws above depends on the share that leaves: the
//! values of a sweep over the share are the same runs until the departures (common random
//! numbers), and a larger share's departing agents include a smaller share's.

use nalgebra::DMatrix;
use rand::Rng;

use crate::control::maneuver::{target_positions, Trajectory};
use crate::estimate::Target;
use crate::linalg::{batch_gemv, psd_factor, to_row_major, with_avx2};
use crate::rng::{Stream, Streams};

/// Seed of run `r`'s stream (SplitMix64 finaliser of the pair).
pub fn run_seed(seed: u64, r: usize) -> u64 {
    let mut x = seed
        ^ (r as u64)
            .wrapping_add(1)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// Seed of run `r`'s departure stream: [`run_seed`] apart from its main stream.
fn departure_seed(seed: u64, r: usize) -> u64 {
    run_seed(seed, r) ^ 0xD1B5_4A32_D192_ED03
}

/// Per run of `range`, `count` of `candidates` drawn from the run's departure stream (a partial
/// Fisher–Yates shuffle: one uniform integer per departing agent), so the subsets are nested:
/// the first `count` of any larger draw.
pub(crate) fn departure_subsets(
    seed: u64,
    range: std::ops::Range<usize>,
    candidates: &[usize],
    count: usize,
) -> Vec<Vec<usize>> {
    range
        .map(|r| {
            let mut rng = Stream::seed_from_u64(departure_seed(seed, r));
            let mut pool = candidates.to_vec();
            let count = count.min(pool.len());
            for k in 0..count {
                let j = rng.random_range(k..pool.len());
                pool.swap(k, j);
            }
            pool.truncate(count);
            pool
        })
        .collect()
}

/// A square-root factor `C` (`C Cᵀ = Σ`) applied to batches, in the cheapest exact form.
#[derive(Debug, Clone)]
pub(crate) enum Factor {
    /// Σ = 0.
    Zero,
    /// Diagonal Σ: the standard deviations.
    Diagonal(Vec<f64>),
    /// Σ = A ⊗ I_D: `chol(A)` (n × n) in panels of [`KRON_ROWS`] rows ([`panels`]), applied
    /// per coordinate.
    Kron { a: Vec<f64>, n: usize, d: usize },
    /// Dense, row-major.
    Dense { c: Vec<f64>, n: usize },
}

impl Factor {
    /// The factor of a checked PSD covariance of `n·d` rows (`d` the spatial dimension).
    pub(crate) fn of(cov: &DMatrix<f64>, d: usize) -> Self {
        let nd = cov.nrows();
        if cov.iter().all(|&v| v == 0.0) {
            return Factor::Zero;
        }
        let diagonal = (0..nd).all(|i| (0..nd).all(|j| i == j || cov[(i, j)] == 0.0));
        if diagonal {
            return Factor::Diagonal((0..nd).map(|i| cov[(i, i)].max(0.0).sqrt()).collect());
        }
        let n = nd / d;
        let kron = d > 1
            && (0..n).all(|a| {
                (0..n).all(|b| {
                    let v = cov[(a * d, b * d)];
                    (0..d).all(|x| {
                        (0..d).all(|y| {
                            let want = if x == y { v } else { 0.0 };
                            cov[(a * d + x, b * d + y)].to_bits() == want.to_bits()
                        })
                    })
                })
            });
        if kron {
            let a = DMatrix::from_fn(n, n, |i, j| cov[(i * d, j * d)]);
            // The panels' sums stop at the diagonal: a lower-triangular (Cholesky) factor only
            // (a singular A's eigenvector factor goes the dense way).
            let lower = |f: &DMatrix<f64>| (0..n).all(|i| (i + 1..n).all(|j| f[(i, j)] == 0.0));
            if let Some(f) = psd_factor(&a).filter(lower) {
                return Factor::Kron {
                    a: panels(&f),
                    n,
                    d,
                };
            }
        }
        let f = psd_factor(cov).expect("checked PSD");
        let mut c = vec![0.0; nd * nd];
        to_row_major(&f, &mut c);
        Factor::Dense { c, n: nd }
    }

    pub(crate) fn is_zero(&self) -> bool {
        matches!(self, Factor::Zero)
    }

    /// `out = C ξ` for a batch (rows × runs, runs innermost).
    pub(crate) fn apply(&self, xi: &[f64], out: &mut [f64], runs: usize) {
        match self {
            Factor::Zero => out.fill(0.0),
            Factor::Diagonal(s) => {
                for (row, sd) in s.iter().enumerate() {
                    let span = row * runs..(row + 1) * runs;
                    for (o, x) in out[span.clone()].iter_mut().zip(&xi[span]) {
                        *o = sd * x;
                    }
                }
            }
            Factor::Kron { a, n, d } => kron_apply(a, *n, *d * runs, xi, out),
            Factor::Dense { c, n } => batch_gemv(c, *n, *n, xi, out, runs),
        }
    }
}

/// `out = (C ⊗ I) ξ` for a lower-triangular `C` (`n × n`, row-major, zeros above the
/// diagonal): agent i's rows (`w = D · runs` values, contiguous) are `Σ_{j ≤ i} C_ij ξ_j`.
/// Four agents at a time share one pass over ξ (4·w independent sums, so the additions do not
/// wait on each other). Each value is summed in the order j = 0, 1, …, i from 0 (the zeros above
/// the diagonal add nothing), so the bits are those of one agent at a time.
fn kron_apply(a: &[f64], n: usize, w: usize, xi: &[f64], out: &mut [f64]) {
    match w {
        // One run in 2-D or 3-D (the 1,000-agent studies): the sums in registers.
        2 => kron_split::<2>(a, n, xi, out, 0..n, KRON_SPLITS),
        3 => kron_split::<3>(a, n, xi, out, 0..n, KRON_SPLITS),
        _ => kron_wide(a, n, w, xi, out),
    }
}

/// Agents four at a time share one pass over ξ (4·w independent sums).
const KRON_ROWS: usize = 4;

fn kron_wide(a: &[f64], n: usize, w: usize, xi: &[f64], out: &mut [f64]) {
    out.fill(0.0);
    let mut i = 0;
    while i < n {
        let rows = KRON_ROWS.min(n - i);
        let block = &mut out[i * w..(i + rows) * w];
        let panel = &a[i * n..][..KRON_ROWS * n];
        for j in 0..i + rows {
            let x = &xi[j * w..(j + 1) * w];
            for (r, o) in block.chunks_exact_mut(w).enumerate() {
                let c = panel[j * KRON_ROWS + r];
                for (o, x) in o.iter_mut().zip(x) {
                    *o += c * x;
                }
            }
        }
        i += rows;
    }
}

/// From this many agents the one-run factor is applied by two threads (rows split in halves of
/// equal work; `2^KRON_SPLITS` parts): each row's sums are the same, so are the bits.
const KRON_PARALLEL: usize = 256;
const KRON_SPLITS: u32 = 2;

/// [`kron_small`] of `rows` (`out` holds those rows), split in two parts of equal work (row `i`
/// costs `i + 1` products) `depth` times over, the parts run by [`rayon::join`].
fn kron_split<const W: usize>(
    a: &[f64],
    n: usize,
    xi: &[f64],
    out: &mut [f64],
    rows: std::ops::Range<usize>,
    depth: u32,
) {
    let (lo, hi) = (rows.start, rows.end);
    // The middle of the work, on a panel boundary.
    let mid = (((lo * lo + hi * hi) as f64 / 2.0).sqrt() as usize).next_multiple_of(KRON_ROWS);
    if depth == 0 || n < KRON_PARALLEL || mid <= lo || mid >= hi {
        kron_small::<W>(a, n, xi, out, rows);
        return;
    }
    let (first, second) = out.split_at_mut((mid - lo) * W);
    rayon::join(
        || kron_split::<W>(a, n, xi, first, lo..mid, depth - 1),
        || kron_split::<W>(a, n, xi, second, mid..hi, depth - 1),
    );
}

/// [`kron_wide`] for `w = W` values per agent, the 4·W sums in registers, for the agents `rows`
/// (whole panels but the last; `out` holds those rows): for each value, one 4-wide product of
/// the panel's column `j` (four agents' coefficients, contiguous) — AVX2 without fused
/// multiply–adds, so the bits of one sum at a time.
fn kron_small<const W: usize>(
    a: &[f64],
    n: usize,
    xi: &[f64],
    out: &mut [f64],
    rows: std::ops::Range<usize>,
) {
    with_avx2(
        #[inline(always)]
        || {
            let (start, end) = (rows.start, rows.end);
            let mut i = start;
            while i < end {
                let rows = KRON_ROWS.min(n - i);
                let cols = i + rows;
                let panel = &a[i * n..][..KRON_ROWS * cols];
                let mut acc = [[0.0f64; KRON_ROWS]; W];
                for (c, x) in panel
                    .chunks_exact(KRON_ROWS)
                    .zip(xi[..cols * W].chunks_exact(W))
                {
                    for (acc, x) in acc.iter_mut().zip(x) {
                        for (s, c) in acc.iter_mut().zip(c) {
                            *s += c * x;
                        }
                    }
                }
                for r in 0..rows {
                    for (v, acc) in acc.iter().enumerate() {
                        out[(i - start + r) * W + v] = acc[r];
                    }
                }
                i += rows;
            }
        },
    );
}

/// A lower-triangular `f` (n × n) in panels of [`KRON_ROWS`] rows: panel `p` holds rows
/// `4p..4p+4` column after column (`a[p·4n + 4j + r] = f[4p + r, j]`; rows past `n` are zero),
/// so four agents' coefficients of one column are one contiguous load.
fn panels(f: &DMatrix<f64>) -> Vec<f64> {
    let n = f.nrows();
    let mut a = vec![0.0; n.div_ceil(KRON_ROWS) * KRON_ROWS * n];
    for i in 0..n {
        for j in 0..n {
            a[(i / KRON_ROWS) * KRON_ROWS * n + j * KRON_ROWS + i % KRON_ROWS] = f[(i, j)];
        }
    }
    a
}

/// What the world draws every step, for a chunk of runs (runs innermost).
#[derive(Debug, Clone)]
pub(crate) struct Draws {
    /// Measurement normals η (M·D rows), when R ≠ 0.
    pub(crate) eta: Vec<f64>,
    /// Process normals ξ (N·D rows), when Q ≠ 0.
    pub(crate) xi: Vec<f64>,
    /// Link-failure uniforms (M rows), when needed.
    pub(crate) comm: Vec<f64>,
    /// Availability uniforms (M rows), when needed.
    pub(crate) avail: Vec<f64>,
}

/// The per-run streams of a chunk and the per-step draws.
#[derive(Debug, Clone)]
pub(crate) struct World {
    streams: Streams,
    pub(crate) draws: Draws,
    md: usize,
    nd: usize,
    m: usize,
    draw_eta: bool,
    draw_xi: bool,
    draw_comm: bool,
    draw_avail: bool,
}

impl World {
    /// The streams of runs `range` and buffers for the draws this scenario needs.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        seed: u64,
        range: std::ops::Range<usize>,
        m: usize,
        md: usize,
        nd: usize,
        draw_eta: bool,
        draw_xi: bool,
        draw_comm: bool,
        draw_avail: bool,
    ) -> Self {
        let runs = range.len();
        Self {
            streams: Streams::new(range.map(|r| run_seed(seed, r))),
            draws: Draws {
                eta: vec![0.0; if draw_eta { md * runs } else { 0 }],
                xi: vec![0.0; if draw_xi { nd * runs } else { 0 }],
                comm: vec![0.0; if draw_comm { m * runs } else { 0 }],
                avail: vec![0.0; if draw_avail { m * runs } else { 0 }],
            },
            md,
            nd,
            m,
            draw_eta,
            draw_xi,
            draw_comm,
            draw_avail,
        }
    }

    /// Runs in the chunk.
    pub(crate) fn runs(&self) -> usize {
        self.streams.len()
    }

    /// Initial positions `z_1 = μ + C_P ξ` (N·D rows × runs), drawn first in every stream.
    pub(crate) fn initial_positions(&mut self, mean: &[f64], cov: &DMatrix<f64>, z: &mut [f64]) {
        let d = mean.len();
        let n = self.nd / d;
        let runs = self.streams.len();
        let f = psd_factor(cov).expect("checked PSD");
        let mut xi = vec![0.0; d];
        self.streams.each(|lr, st| {
            for i in 0..n {
                for x in xi.iter_mut() {
                    *x = st.normal();
                }
                for a in 0..d {
                    let mut v = mean[a];
                    for (b, x) in xi.iter().enumerate() {
                        v += f[(a, b)] * x;
                    }
                    z[(i * d + a) * runs + lr] = v;
                }
            }
        });
    }

    /// The draws of one step, in the fixed per-run order.
    pub(crate) fn draw_step(&mut self) {
        // Each run's stream draws in the documented order (η, then ξ, then the link and
        // availability uniforms, each by row); `Streams` fills rows × runs buffers.
        let runs = self.streams.len();
        let d = &mut self.draws;
        if self.draw_eta {
            self.streams.fill_normals(&mut d.eta[..self.md * runs]);
        }
        if self.draw_xi {
            self.streams.fill_normals(&mut d.xi[..self.nd * runs]);
        }
        if self.draw_comm {
            self.streams.fill_uniforms(&mut d.comm[..self.m * runs]);
        }
        if self.draw_avail {
            self.streams.fill_uniforms(&mut d.avail[..self.m * runs]);
        }
    }
}

/// The targets at step k and k + 1, recomputed each step from the trajectory.
#[derive(Debug, Clone)]
pub(crate) struct Targets {
    pub(crate) now: Target,
    pub(crate) next: Target,
}

impl Targets {
    pub(crate) fn new(n: usize, d: usize) -> Self {
        let t = Target {
            theta: vec![0.0; d * d],
            shift: vec![0.0; d],
            positions: vec![0.0; n * d],
            velocities: vec![0.0; n * d],
        };
        Self {
            now: t.clone(),
            next: t,
        }
    }

    /// `Z*(t_k)` and `Z*(t_{k+1})` (no allocation).
    pub(crate) fn update(
        &mut self,
        traj: &dyn Trajectory,
        config: &[f64],
        d: usize,
        k: usize,
        dt: f64,
    ) {
        for (t, tgt) in [
            (k as f64 * dt, &mut self.now),
            ((k + 1) as f64 * dt, &mut self.next),
        ] {
            let s = traj.at(t, d);
            target_positions(&s, config, d, &mut tgt.positions, &mut tgt.velocities);
            tgt.theta.copy_from_slice(&s.theta[..d * d]);
            tgt.shift.copy_from_slice(&s.shift[..d]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Stream;

    /// Applying the factor to each unit vector gives the columns of `C`, and `C Cᵀ` is the
    /// covariance — through the Kronecker path (distinct points: `Q_A` positive definite,
    /// Cholesky) and through the dense one (two agents at one point: `Q_A` singular, its factor
    /// eigenvectors, which the panels' sums up to the diagonal would cut short).
    #[test]
    fn factor_reproduces_the_covariance() {
        let kernel = crate::noise::Kernel::default();
        let distinct: Vec<f64> = (0..9)
            .flat_map(|i| {
                let a = i as f64 * 0.7;
                [a.cos() * (1.0 + 0.1 * i as f64), a.sin()]
            })
            .collect();
        let mut twice = distinct.clone();
        twice[2..4].copy_from_slice(&distinct[..2]);
        for (pts, kron) in [(&distinct, true), (&twice, false)] {
            let qa = crate::noise::agent_covariance(&kernel, pts, 2);
            let cov = qa.kronecker(&DMatrix::identity(2, 2));
            let f = Factor::of(&cov, 2);
            let nd = cov.nrows();
            let mut c = DMatrix::zeros(nd, nd);
            let (mut e, mut col) = (vec![0.0; nd], vec![0.0; nd]);
            for k in 0..nd {
                e.fill(0.0);
                e[k] = 1.0;
                f.apply(&e, &mut col, 1);
                c.column_mut(k).copy_from_slice(&col);
            }
            let err = (&c * c.transpose() - &cov).amax();
            assert!(
                err < 1e-12,
                "C Cᵀ − Q off by {err:e} (Kronecker path: {kron})"
            );
            assert_eq!(matches!(f, Factor::Kron { .. }), kron);
        }
    }

    /// The register path (2 or 3 values per agent) gives the bits of the general one, and both
    /// (reading the factor in panels) equal the plain sum over j ≤ i of the row-major factor,
    /// for a number of agents that is not a multiple of four.
    #[test]
    fn kron_paths_agree_bit_for_bit() {
        // 11 agents: one thread, a partial panel; 301: split between threads (in a pool of two).
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("pool");
        for n in [11, KRON_PARALLEL + 45] {
            pool.install(|| kron_paths_agree(n));
        }
    }

    fn kron_paths_agree(n: usize) {
        let mut st = Stream::seed_from_u64(5);
        let a: Vec<f64> = (0..n * n)
            .map(|k| if k % n <= k / n { st.normal() } else { 0.0 })
            .collect();
        let p = panels(&DMatrix::from_row_slice(n, n, &a));
        for w in [2, 3] {
            let xi: Vec<f64> = (0..n * w).map(|_| st.normal()).collect();
            let (mut small, mut wide) = (vec![0.0; n * w], vec![0.0; n * w]);
            kron_apply(&p, n, w, &xi, &mut small);
            kron_wide(&p, n, w, &xi, &mut wide);
            for i in 0..n {
                for e in 0..w {
                    let mut s = 0.0;
                    for j in 0..=i {
                        s += a[i * n + j] * xi[j * w + e];
                    }
                    assert_eq!(
                        small[i * w + e].to_bits(),
                        s.to_bits(),
                        "w = {w}, agent {i}"
                    );
                    assert_eq!(wide[i * w + e].to_bits(), s.to_bits(), "w = {w}, agent {i}");
                }
            }
        }
    }
}
