//! Four Joseph-form covariance recursions at once, one per SIMD lane: the JRKF's shared-gain
//! step (EUSIPCO eq. 14d–14g; thesis 5.22–5.25) for four agents whose joint blocks have the
//! same size.
//!
//! Every lane performs exactly the operations of the scalar step (`jrkf::Block::covariance_step`
//! with nalgebra's Cholesky factor and triangular solves), in the same order and without fused
//! multiply–adds, so each lane's bits are the scalar step's bits; only the lanes run side by
//! side (AVX2 through [`with_avx2`]). Test: `lanes_give_the_bits_of_the_scalar_step`.
//!
//! The matrices are column-major with the lanes innermost: entry `(r, c)` of lane `l` is
//! `m[c * n + r][l]`.

use nalgebra::DMatrix;

use crate::linalg::{with_avx2, Const, Size};

/// Recursions per pack.
pub(super) const LANES: usize = 4;

type Lane = [f64; LANES];

#[inline(always)]
fn lanes(f: impl Fn(usize) -> f64) -> Lane {
    std::array::from_fn(f)
}

/// Four agents' recursions of one block size `n` (`n × n`, lanes interleaved).
#[derive(Debug, Clone)]
pub(super) struct Pack {
    n: usize,
    /// `W` is block diagonal with blocks of this size (`D`, or `n` if not).
    wd: usize,
    /// The recursion (shared block) in each lane; lanes past `used` repeat lane 0's.
    members: [usize; LANES],
    used: usize,
    q: Vec<Lane>,
    w: Vec<Lane>,
    sigma: Vec<Lane>,
    /// `Kᵀ` of the last step (the gains [`Pack::read`] gives).
    kt: Vec<Lane>,
}

/// The scratch of a pack's step, shared by the packs one thread steps (it stays in cache
/// while the packs' own `Q`, `W`, `Σ`, `Kᵀ` stream through).
#[derive(Debug, Clone, Default)]
pub(super) struct Work {
    prior: Vec<Lane>,
    s: Vec<Lane>,
    at: Vec<Lane>,
    tmp: Vec<Lane>,
}

impl Work {
    /// Scratch for blocks up to `n × n`.
    pub(super) fn new(n: usize) -> Self {
        let z = vec![[0.0; LANES]; n * n];
        Self {
            prior: z.clone(),
            s: z.clone(),
            at: z.clone(),
            tmp: z,
        }
    }
}

/// What one step did in each lane.
#[derive(Debug, Clone, Copy)]
pub(super) struct LaneStep {
    /// The innovation covariance was positive definite and the posterior is finite.
    pub(super) ok: [bool; LANES],
    /// The posterior moved by no more than rounding ([`crate::linalg::converged`]).
    pub(super) converged: [bool; LANES],
}

impl Pack {
    /// A pack of `members` (1 to 4 recursions of size `n`), each given as `(Q_i, W_i, Σ_i)`;
    /// `d`: the edge dimension (`W_i = bdiag(R_ij / T)` has `d × d` blocks).
    pub(super) fn new(members: &[(usize, [&DMatrix<f64>; 3])], d: usize) -> Self {
        assert!(
            !members.is_empty() && members.len() <= LANES,
            "a pack holds 1 to {LANES} recursions"
        );
        let n = members[0].1[0].nrows();
        let lane_of = |l: usize| members[l.min(members.len() - 1)].1;
        let gather = |which: usize| -> Vec<Lane> {
            (0..n * n)
                .map(|k| lanes(|l| lane_of(l)[which].as_slice()[k]))
                .collect()
        };
        let block_diag = d > 0
            && n % d == 0
            && members.iter().all(|(_, m)| {
                let w = m[1];
                (0..n).all(|i| (0..n).all(|j| i / d == j / d || w[(i, j)] == 0.0))
            });
        Self {
            n,
            wd: if block_diag { d } else { n },
            members: std::array::from_fn(|l| members[l.min(members.len() - 1)].0),
            used: members.len(),
            q: gather(0),
            w: gather(1),
            sigma: gather(2),
            kt: vec![[0.0; LANES]; n * n],
        }
    }

    /// The recursions it holds.
    pub(super) fn members(&self) -> &[usize] {
        &self.members[..self.used]
    }

    /// One covariance step in every lane whose `frozen` is false (the others keep their
    /// posterior), in `work` (sized for this block or larger). Then [`Pack::read`] gives each
    /// stepped lane's posterior and gain.
    pub(super) fn step(&mut self, work: &mut Work, frozen: [bool; LANES]) -> LaneStep {
        let mut out = LaneStep {
            ok: [true; LANES],
            converged: [false; LANES],
        };
        with_avx2(
            #[inline(always)]
            || match self.n {
                // The common sizes (D = 2 with 3 to 7 edges, D = 3 with 6) unrolled.
                6 => self.joseph(Const::<6>, work, &mut out, frozen),
                8 => self.joseph(Const::<8>, work, &mut out, frozen),
                10 => self.joseph(Const::<10>, work, &mut out, frozen),
                12 => self.joseph(Const::<12>, work, &mut out, frozen),
                14 => self.joseph(Const::<14>, work, &mut out, frozen),
                18 => self.joseph(Const::<18>, work, &mut out, frozen),
                n => self.joseph(n, work, &mut out, frozen),
            },
        );
        out
    }

    /// Lane `l`'s posterior `Σ` and gain `K` (row-major, as `jrkf::Block::gain`), after
    /// [`Pack::step`].
    pub(super) fn read(&self, l: usize, sigma: &mut DMatrix<f64>, gain: &mut [f64]) {
        for (v, x) in sigma.as_mut_slice().iter_mut().zip(&self.sigma) {
            *v = x[l];
        }
        // `gain[a n + b] = K[a, b] = Kᵀ[b, a]`: the column-major `Kᵀ` in order.
        for (v, x) in gain.iter_mut().zip(&self.kt) {
            *v = x[l];
        }
    }

    #[inline(always)]
    fn joseph(
        &mut self,
        size: impl Size,
        work: &mut Work,
        out: &mut LaneStep,
        frozen: [bool; LANES],
    ) {
        let n = size.get();
        let nn = n * n;
        let Self {
            wd,
            q,
            w,
            sigma,
            kt,
            ..
        } = self;
        let Work { prior, s, at, tmp } = work;
        // Slices of the matrices' exact length (a constant for a `Const` size), so the
        // compiler knows every index below is in bounds.
        let (wd, q, w) = (*wd, &q[..nn], &w[..nn]);
        let (sigma, prior, s) = (&mut sigma[..nn], &mut prior[..nn], &mut s[..nn]);
        let (kt, at, tmp) = (&mut kt[..nn], &mut at[..nn], &mut tmp[..nn]);
        for k in 0..nn {
            let p = lanes(|l| sigma[k][l] + q[k][l]);
            prior[k] = p;
            s[k] = lanes(|l| p[l] + w[k][l]);
            kt[k] = p;
        }
        cholesky(size, s, &mut out.ok);
        solve(size, s, kt);
        for c in 0..n {
            for r in 0..n {
                let id = if r == c { 1.0 } else { 0.0 };
                let k = kt[c * n + r];
                at[c * n + r] = lanes(|l| id - k[l]);
            }
        }
        // Σ⁺ = A Σ⁻ Aᵀ + K W Kᵀ with A = I − K (Joseph form), as `gemm_nn`/`gemm_tn` order it.
        gemm_nn(size, tmp, prior, at);
        gemm_tn(size, s, at, tmp, false);
        block_diag_nn(size, wd, tmp, w, kt);
        gemm_tn(size, s, kt, tmp, true);
        for i in 0..n {
            for j in i + 1..n {
                let (a, b) = (s[j * n + i], s[i * n + j]);
                let m = lanes(|l| 0.5 * (a[l] + b[l]));
                s[j * n + i] = m;
                s[i * n + j] = m;
            }
        }
        // `converged`: no entry moved by more than `8 ε max|Σ|` (the largest move against the
        // tolerance; the posterior is finite, or the lane fails); frozen lanes keep their `Σ`.
        let (mut amax, mut moved, mut nan): (Lane, Lane, Lane) = Default::default();
        for (y, x) in sigma.iter_mut().zip(s.iter()) {
            amax = lanes(|l| amax[l].max(y[l].abs()));
            moved = lanes(|l| moved[l].max((x[l] - y[l]).abs()));
            // `x · 0` is 0 for a finite `x` and NaN otherwise.
            nan = lanes(|l| nan[l] + x[l] * 0.0);
            *y = lanes(|l| if frozen[l] { y[l] } else { x[l] });
        }
        for l in 0..LANES {
            out.converged[l] = !frozen[l] && moved[l] <= 8.0 * f64::EPSILON * amax[l];
            out.ok[l] &= frozen[l] || nan[l] == 0.0;
        }
    }
}

/// `s ← L` (lower triangle) with `L Lᵀ = s`, in nalgebra's order (left-looking, column by
/// column: `s[j.., j] −= L[j, k] L[j.., k]` for `k < j` in turn, then the square root and
/// the divisions).
#[inline(always)]
fn cholesky(size: impl Size, s: &mut [Lane], ok: &mut [bool; LANES]) {
    let n = size.get();
    for j in 0..n {
        let at = j * n + j;
        fold4(
            s,
            (n - j, j),
            |m, o| m[at + o],
            |m, acc, o, k| {
                let (f, x) = (m[k * n + j], m[k * n + j + o]);
                lanes(|l| acc[l] - f[l] * x[l])
            },
            |m, o, v| m[at + o] = v,
        );
        let v = s[at];
        for l in 0..LANES {
            // nalgebra refuses a zero diagonal and one without a square root (< 0, NaN).
            ok[l] &= v[l] > 0.0;
        }
        let den = lanes(|l| v[l].sqrt());
        s[at] = den;
        for y in &mut s[at + 1..(j + 1) * n] {
            *y = lanes(|l| y[l] / den[l]);
        }
    }
}

/// `kt ← (L Lᵀ)⁻¹ kt`: nalgebra's forward substitution (`b[r] −= b[i] L[r, i]` for `i < r`
/// in turn, then `/ L[r, r]`) and back substitution (`b[i] = (b[i] − L[i+1.., i] · b[i+1..])
/// / L[i, i]`, its dot products summed in eight accumulators), row by row with the columns
/// side by side.
#[inline(always)]
fn solve(size: impl Size, s: &[Lane], kt: &mut [Lane]) {
    let n = size.get();
    for r in 0..n {
        let d = s[r * n + r];
        fold4(
            kt,
            (n, r),
            |m, c| m[c * n + r],
            |m, acc, c, i| {
                let (b, x) = (m[c * n + i], s[i * n + r]);
                lanes(|l| acc[l] - b[l] * x[l])
            },
            |m, c, v| m[c * n + r] = lanes(|l| v[l] / d[l]),
        );
    }
    for i in (0..n).rev() {
        let (d, col) = (s[i * n + i], &s[i * n + i + 1..(i + 1) * n]);
        for b in kt.chunks_exact_mut(n) {
            let (head, tail) = b.split_at_mut(i + 1);
            let dot = nalgebra_dot(col, tail);
            let bi = head[i];
            head[i] = lanes(|l| (bi[l] - dot[l]) / d[l]);
        }
    }
}

/// For each output `o in 0..count`: `acc = init(m, o)`, then `acc = step(m, acc, o, k)` for
/// `k in 0..len` in turn, then `put(m, o, acc)` — each output's operations in the order of the
/// one-at-a-time loop, four outputs interleaved (independent dependency chains). `step` may
/// read entries of `m` that no output of the same call writes.
#[inline(always)]
fn fold4(
    m: &mut [Lane],
    (count, len): (usize, usize),
    init: impl Fn(&[Lane], usize) -> Lane,
    step: impl Fn(&[Lane], Lane, usize, usize) -> Lane,
    put: impl Fn(&mut [Lane], usize, Lane),
) {
    let mut o = 0;
    while o + 4 <= count {
        let mut acc: [Lane; 4] = std::array::from_fn(|t| init(m, o + t));
        for k in 0..len {
            for (t, a) in acc.iter_mut().enumerate() {
                *a = step(m, *a, o + t, k);
            }
        }
        for (t, a) in acc.into_iter().enumerate() {
            put(m, o + t, a);
        }
        o += 4;
    }
    for o in o..count {
        let mut acc = init(m, o);
        for k in 0..len {
            acc = step(m, acc, o, k);
        }
        put(m, o, acc);
    }
}

/// nalgebra's dot product of dynamic vectors (eight accumulators over blocks of eight, combined
/// as `(a0 + a4) + … + (a3 + a7)`, then the tail), lane by lane.
#[inline(always)]
fn nalgebra_dot(x: &[Lane], y: &[Lane]) -> Lane {
    let len = x.len();
    let mut acc = [[0.0; LANES]; 8];
    let mut i = 0;
    while len - i >= 8 {
        for (t, a) in acc.iter_mut().enumerate() {
            let (p, q) = (x[i + t], y[i + t]);
            *a = lanes(|l| a[l] + p[l] * q[l]);
        }
        i += 8;
    }
    let mut res = [0.0; LANES];
    for t in 0..4 {
        let (a, b) = (acc[t], acc[t + 4]);
        res = lanes(|l| res[l] + (a[l] + b[l]));
    }
    for k in i..len {
        let (p, q) = (x[k], y[k]);
        res = lanes(|l| res[l] + p[l] * q[l]);
    }
    res
}

/// `c = a b` (`n × n`), as [`crate::linalg::gemm_nn`] with `beta = 0` sums: from zero, in `k`.
#[inline(always)]
fn gemm_nn(size: impl Size, c: &mut [Lane], a: &[Lane], b: &[Lane]) {
    let n = size.get();
    tiles(size, c, |k, i| a[k * n + i], b, [0.0; LANES], |_, v| v);
}

/// `c = a b` for `a` block diagonal with `d × d` blocks: [`gemm_nn`]'s sums without the
/// products of `a`'s zeros, which add `±0` to a partial sum that is never `−0` (it starts at
/// `+0`), so the same bits while `b` is finite.
#[inline(always)]
fn block_diag_nn(size: impl Size, d: usize, c: &mut [Lane], a: &[Lane], b: &[Lane]) {
    let n = size.get();
    for j in 0..n {
        for i in 0..n {
            let k0 = i - i % d;
            let mut acc = [0.0; LANES];
            for k in k0..k0 + d {
                let (x, y) = (a[k * n + i], b[j * n + k]);
                acc = lanes(|l| acc[l] + x[l] * y[l]);
            }
            c[j * n + i] = acc;
        }
    }
}

/// `c = aᵀ b (+ c if acc)`, as [`crate::linalg::gemm_tn`] sums: each dot product from `−0` in
/// `k` (`Iterator::sum`), then `+ 0` or `+ 1·c`.
#[inline(always)]
fn gemm_tn(size: impl Size, c: &mut [Lane], a: &[Lane], b: &[Lane], acc: bool) {
    let n = size.get();
    let fin = |old: Lane, dot: Lane| {
        if acc {
            lanes(|l| dot[l] + 1.0 * old[l])
        } else {
            lanes(|l| dot[l] + 0.0)
        }
    };
    tiles(size, c, |k, i| a[i * n + k], b, [-0.0; LANES], fin);
}

/// `c[i, j] = fin(c[i, j], Σ_k x(k, i) b[k, j])` (`n × n`), each sum from `start` in `k`
/// order: a matrix product in tiles of 4 × 2 outputs (eight independent sums in registers, each
/// `x` and `b` entry loaded once per tile), the edges one output at a time.
#[inline(always)]
fn tiles(
    size: impl Size,
    c: &mut [Lane],
    x: impl Fn(usize, usize) -> Lane,
    b: &[Lane],
    start: Lane,
    fin: impl Fn(Lane, Lane) -> Lane,
) {
    let n = size.get();
    let one = |i: usize, j: usize| {
        let bj = &b[j * n..(j + 1) * n];
        let mut s = start;
        for (k, y) in bj.iter().enumerate() {
            let v = x(k, i);
            s = lanes(|l| s[l] + v[l] * y[l]);
        }
        s
    };
    let mut j = 0;
    while j + 2 <= n {
        let (b0, b1) = (&b[j * n..(j + 1) * n], &b[(j + 1) * n..(j + 2) * n]);
        let mut i = 0;
        while i + 4 <= n {
            let mut s = [[start; 2]; 4];
            for k in 0..n {
                let y = [b0[k], b1[k]];
                for (t, st) in s.iter_mut().enumerate() {
                    let v = x(k, i + t);
                    for (u, su) in st.iter_mut().enumerate() {
                        *su = lanes(|l| su[l] + v[l] * y[u][l]);
                    }
                }
            }
            for (t, st) in s.iter().enumerate() {
                for (u, su) in st.iter().enumerate() {
                    let o = (j + u) * n + i + t;
                    c[o] = fin(c[o], *su);
                }
            }
            i += 4;
        }
        for i in i..n {
            for j in j..j + 2 {
                c[j * n + i] = fin(c[j * n + i], one(i, j));
            }
        }
        j += 2;
    }
    for j in j..n {
        for i in 0..n {
            c[j * n + i] = fin(c[j * n + i], one(i, j));
        }
    }
}
