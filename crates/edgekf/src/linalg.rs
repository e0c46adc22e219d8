//! Small dense linear algebra that works in place on preallocated storage, so that the step loop
//! allocates nothing, plus the lockstep "one gain, many runs" products.
//!
//! Batched arrays hold one row per state component and one column per Monte Carlo run, stored
//! row-major with the runs innermost and contiguous (`row * runs + r`): a gain computed once per
//! step is applied to every run with unit-stride inner loops the compiler vectorises.

use nalgebra::DMatrix;

/// Solves `A X = B` in place (`b` becomes `X`) for symmetric positive definite `a`, factorising
/// `a` in place (it holds the Cholesky factor afterwards). No allocation: the matrix is moved into
/// nalgebra's factorisation and back. Returns `false` (leaving `a` zero-sized contents unchanged
/// in shape) if `a` is not positive definite.
pub fn spd_solve_in_place(a: &mut DMatrix<f64>, b: &mut DMatrix<f64>) -> bool {
    let (r, c) = a.shape();
    let m = std::mem::replace(a, DMatrix::zeros(0, 0));
    match nalgebra::Cholesky::new(m) {
        Some(chol) => {
            chol.solve_mut(b);
            *a = chol.unpack();
            true
        }
        None => {
            *a = DMatrix::zeros(r, c);
            false
        }
    }
}

/// Inverts the symmetric positive definite `a` into `out`, using `work` (same size) for the
/// factor. Returns `false` if `a` is not positive definite.
pub fn invert_spd(a: &DMatrix<f64>, work: &mut DMatrix<f64>, out: &mut DMatrix<f64>) -> bool {
    work.copy_from(a);
    out.fill(0.0);
    out.fill_diagonal(1.0);
    if !spd_solve_in_place(work, out) {
        return false;
    }
    symmetrize(out);
    true
}

/// `c = a b + beta c` for column-major dense matrices, without allocating (nalgebra's `gemm`
/// hands large-enough products to `matrixmultiply`, which allocates packing buffers per call).
pub fn gemm_nn(c: &mut DMatrix<f64>, a: &DMatrix<f64>, b: &DMatrix<f64>, beta: f64) {
    let (m, kk) = a.shape();
    let n = b.ncols();
    debug_assert_eq!(b.nrows(), kk);
    debug_assert_eq!(c.shape(), (m, n));
    let (a, b) = (a.as_slice(), b.as_slice());
    let c = c.as_mut_slice();
    for j in 0..n {
        let cj = &mut c[j * m..(j + 1) * m];
        if beta == 0.0 {
            cj.fill(0.0);
        } else if beta != 1.0 {
            cj.iter_mut().for_each(|v| *v *= beta);
        }
        for k in 0..kk {
            let bkj = b[j * kk + k];
            for (cv, av) in cj.iter_mut().zip(&a[k * m..(k + 1) * m]) {
                *cv += av * bkj;
            }
        }
    }
}

/// `c = aᵀ b + beta c` for column-major dense matrices, without allocating.
pub fn gemm_tn(c: &mut DMatrix<f64>, a: &DMatrix<f64>, b: &DMatrix<f64>, beta: f64) {
    let (kk, m) = a.shape();
    let n = b.ncols();
    debug_assert_eq!(b.nrows(), kk);
    debug_assert_eq!(c.shape(), (m, n));
    let (a, b) = (a.as_slice(), b.as_slice());
    let c = c.as_mut_slice();
    for j in 0..n {
        let bj = &b[j * kk..(j + 1) * kk];
        for i in 0..m {
            let dot: f64 = a[i * kk..(i + 1) * kk]
                .iter()
                .zip(bj)
                .map(|(x, y)| x * y)
                .sum();
            c[j * m + i] = dot
                + if beta == 0.0 {
                    0.0
                } else {
                    beta * c[j * m + i]
                };
        }
    }
}

/// `tr(a b)` for symmetric `b` (= Σ a_ij b_ij), without allocating.
pub fn trace_of_product_sym(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    a.as_slice()
        .iter()
        .zip(b.as_slice())
        .map(|(x, y)| x * y)
        .sum()
}

/// Whether `new` differs from `old` by at most `8 ε max|old|` in every entry: a covariance
/// recursion that has converged to rounding level (further steps only add rounding noise).
pub fn converged(new: &DMatrix<f64>, old: &DMatrix<f64>) -> bool {
    let tol = 8.0 * f64::EPSILON * old.amax();
    new.iter()
        .zip(old.iter())
        .all(|(x, y)| (x - y).abs() <= tol)
}

/// Replaces `a` by `(a + aᵀ) / 2`.
pub fn symmetrize(a: &mut DMatrix<f64>) {
    let n = a.nrows();
    for i in 0..n {
        for j in i + 1..n {
            let m = 0.5 * (a[(i, j)] + a[(j, i)]);
            a[(i, j)] = m;
            a[(j, i)] = m;
        }
    }
}

/// A symmetric PSD square root factor `C` with `C Cᵀ = a`: the Cholesky factor when `a` is
/// positive definite, otherwise `V Λ^{1/2}` from the eigendecomposition. `None` if `a` has an
/// eigenvalue below `−tol · max|λ|` (not PSD) or is not symmetric.
pub fn psd_factor(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = a.nrows();
    if a.ncols() != n || a.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let scale = a.amax().max(f64::MIN_POSITIVE);
    for i in 0..n {
        for j in 0..i {
            if (a[(i, j)] - a[(j, i)]).abs() > 1e-12 * scale {
                return None;
            }
        }
    }
    if a.iter().all(|&v| v == 0.0) {
        return Some(DMatrix::zeros(n, n));
    }
    if let Some(c) = a.clone().cholesky() {
        return Some(c.unpack());
    }
    let eig = a.clone().symmetric_eigen();
    let lmax = eig.eigenvalues.amax();
    if eig.eigenvalues.iter().any(|&v| v < -1e-10 * lmax) {
        return None;
    }
    let mut f = eig.eigenvectors.clone();
    for (j, &v) in eig.eigenvalues.iter().enumerate() {
        let s = v.max(0.0).sqrt();
        f.column_mut(j).scale_mut(s);
    }
    Some(f)
}

/// `x[a] += Σ_b k[a, b] · v[b]` for every run: one gain (`n × n`, row-major slice) applied to a
/// batch of `n` rows by `runs` columns.
#[inline]
pub fn batch_gemv_acc(k: &[f64], n: usize, v: &[f64], x: &mut [f64], runs: usize) {
    debug_assert_eq!(k.len(), n * n);
    debug_assert!(v.len() >= n * runs && x.len() >= n * runs);
    with_avx2(
        #[inline(always)]
        || gemv_panels(k, (n, n), v, x, runs, Start::FromX),
    );
}

/// `x[a] = Σ_b m[a, b] · v[b]` for every run, with `m` a dense `rows × cols` row-major matrix.
#[inline]
pub fn batch_gemv(m: &[f64], rows: usize, cols: usize, v: &[f64], x: &mut [f64], runs: usize) {
    debug_assert!(m.len() >= rows * cols);
    debug_assert!(v.len() >= cols * runs && x.len() >= rows * runs);
    // AVX2 without fused multiply–add: the bits of the portable code.
    with_avx2(
        #[inline(always)]
        || gemv_panels(m, (rows, cols), v, x, runs, Start::Zero),
    );
}

/// Where a batched product's sums start: at zero, or at the output's values.
#[derive(Clone, Copy, PartialEq)]
enum Start {
    Zero,
    FromX,
}

/// Runs whose sums the batched products keep in registers together: with two rows of the
/// matrix at a time, eight AVX2 vectors — eight independent chains of additions, and each
/// vector of `v` loaded once for both rows.
const RUN_BLOCK: usize = 16;

/// The body of [`batch_gemv`] and [`batch_gemv_acc`]: two rows of `m` at a time, each block of
/// runs' sums in registers over the whole row (zero entries of `m` skipped), in the order
/// `((s + m₀ v₀) + m₁ v₁) + …` with `s` zero or the output's value — whatever the blocking, so
/// the bits do not depend on the number of runs or how they are chunked.
#[inline(always)]
fn gemv_panels(
    m: &[f64],
    (rows, cols): (usize, usize),
    v: &[f64],
    x: &mut [f64],
    runs: usize,
    start: Start,
) {
    let mut a = 0;
    while a + 2 <= rows {
        gemv_panel::<2>(m, cols, a, v, x, runs, start);
        a += 2;
    }
    if a < rows {
        gemv_panel::<1>(m, cols, a, v, x, runs, start);
    }
}

/// Rows `a..a + R` of the product for every run: blocks of [`RUN_BLOCK`] runs, then the last
/// runs in blocks of 8, 4, 2 and 1.
#[inline(always)]
fn gemv_panel<const R: usize>(
    m: &[f64],
    cols: usize,
    a: usize,
    v: &[f64],
    x: &mut [f64],
    runs: usize,
    start: Start,
) {
    let rows = &m[a * cols..(a + R) * cols];
    let out = &mut x[a * runs..(a + R) * runs];
    let mut c = 0;
    while c + RUN_BLOCK <= runs {
        gemv_block::<R, RUN_BLOCK>(rows, cols, v, out, (runs, c), start);
        c += RUN_BLOCK;
    }
    if c + 8 <= runs {
        gemv_block::<R, 8>(rows, cols, v, out, (runs, c), start);
        c += 8;
    }
    if c + 4 <= runs {
        gemv_block::<R, 4>(rows, cols, v, out, (runs, c), start);
        c += 4;
    }
    if c + 2 <= runs {
        gemv_block::<R, 2>(rows, cols, v, out, (runs, c), start);
        c += 2;
    }
    if c < runs {
        gemv_block::<R, 1>(rows, cols, v, out, (runs, c), start);
    }
}

/// Runs `c..c + W` of `R` rows (`rows`: their entries of `m`, `out`: their outputs).
#[inline(always)]
fn gemv_block<const R: usize, const W: usize>(
    rows: &[f64],
    cols: usize,
    v: &[f64],
    out: &mut [f64],
    (runs, c): (usize, usize),
    start: Start,
) {
    let mut acc = [[0.0; W]; R];
    if start == Start::FromX {
        for (i, acc_i) in acc.iter_mut().enumerate() {
            *acc_i = out[i * runs + c..i * runs + c + W]
                .try_into()
                .expect("a block");
        }
    }
    for b in 0..cols {
        let k: [f64; R] = std::array::from_fn(|i| rows[i * cols + b]);
        if k.iter().all(|&kb| kb == 0.0) {
            continue;
        }
        let vb: &[f64; W] = v[b * runs + c..b * runs + c + W]
            .try_into()
            .expect("a block");
        for (acc_i, &kb) in acc.iter_mut().zip(&k) {
            if kb != 0.0 {
                for l in 0..W {
                    acc_i[l] += kb * vb[l];
                }
            }
        }
    }
    for (i, acc_i) in acc.iter().enumerate() {
        out[i * runs + c..i * runs + c + W].copy_from_slice(acc_i);
    }
}

/// Copies a dense matrix into a row-major slice.
pub fn to_row_major(m: &DMatrix<f64>, out: &mut [f64]) {
    let c = m.ncols();
    for i in 0..m.nrows() {
        for j in 0..c {
            out[i * c + j] = m[(i, j)];
        }
    }
}

/// Eigenvalues `(re, im)` of a general real square matrix from its real Schur form, with the
/// iterations capped (nalgebra's `complex_eigenvalues` iterates without bound and can stall on
/// clustered, nearly defective spectra such as the slow modes of a closed loop at small Δt);
/// a second attempt uses a looser deflation threshold (1e-10 instead of ε). `None` when
/// neither converges.
pub fn eigenvalues_general(m: &DMatrix<f64>) -> Option<Vec<(f64, f64)>> {
    let cap = 2_000 * m.nrows().max(1);
    let schur = nalgebra::linalg::Schur::try_new(m.clone(), f64::EPSILON, cap)
        .or_else(|| nalgebra::linalg::Schur::try_new(m.clone(), 1e-10, cap))?;
    Some(
        schur
            .complex_eigenvalues()
            .iter()
            .map(|c| (c.re, c.im))
            .collect(),
    )
}

/// A size known at compile time ([`Const`]) or at run time (`usize`): small kernels take their
/// dimensions as `impl Size`, so the common blocks get their loops unrolled — the same
/// operations in the same order, so the same bits as at the run-time size.
pub(crate) trait Size: Copy {
    fn get(self) -> usize;
}

/// A compile-time size.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Const<const N: usize>;

impl<const N: usize> Size for Const<N> {
    #[inline(always)]
    fn get(self) -> usize {
        N
    }
}

impl Size for usize {
    #[inline(always)]
    fn get(self) -> usize {
        self
    }
}

/// How many leading values `$kernel` — an AVX2 kernel (`#[target_feature(enable = "avx2")]`)
/// that returns how many it computed — computed when the CPU has AVX2, else 0: the caller's
/// portable loop does the rest from there, so the kernel may stop at the last full vector.
macro_rules! avx2_prefix {
    ($kernel:expr) => {{
        #[allow(unused_mut)]
        let mut done = 0usize;
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above), all that the kernels ask.
            done = unsafe { $kernel };
        }
        done
    }};
}
pub(crate) use avx2_prefix;

/// Asks the CPU to bring `v` into its caches (one prefetch per 64-byte line; no effect on any
/// value). For data the next step of a loop will read that the hardware prefetcher cannot guess:
/// a batch in an allocation of its own, read after another's.
#[inline]
pub(crate) fn prefetch<T>(v: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T1};
        let (p, bytes) = (v.as_ptr().cast::<i8>(), std::mem::size_of_val(v));
        for o in (0..bytes).step_by(64) {
            // SAFETY: a prefetch reads nothing and cannot fault; `p + o` is inside `v`.
            unsafe { _mm_prefetch::<_MM_HINT_T1>(p.add(o)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = v;
}

/// Runs `f` compiled for AVX2 when the CPU has it: `f`, an `#[inline(always)]` closure, is
/// inlined into an AVX2 function, so its loops over the runs vectorise 4 wide (no fused
/// multiply–add: the bits are those of the portable code).
#[inline(always)]
pub(crate) fn with_avx2(f: impl FnOnce()) {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2")]
        unsafe fn avx2(f: impl FnOnce()) {
            f();
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { avx2(f) };
            return;
        }
    }
    f();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_inverse_roundtrip() {
        let a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let mut w = a.clone();
        let mut inv = a.clone();
        assert!(invert_spd(&a, &mut w, &mut inv));
        let id = &a * &inv;
        assert!((id - DMatrix::identity(3, 3)).amax() < 1e-14);
        let f = psd_factor(&a).unwrap();
        assert!((&f * f.transpose() - &a).amax() < 1e-14);
        let b = DMatrix::from_fn(3, 3, |i, j| (i + 2 * j) as f64 - 1.5);
        let mut c = DMatrix::from_element(3, 3, 1.0);
        gemm_nn(&mut c, &a, &b, 2.0);
        assert!((&c - (&a * &b + DMatrix::from_element(3, 3, 2.0))).amax() < 1e-13);
        gemm_tn(&mut c, &b, &a, 0.0);
        assert!((&c - b.transpose() * &a).amax() < 1e-13);
        assert!((trace_of_product_sym(&b, &a) - (&b * &a).trace()).abs() < 1e-12);
        // A singular PSD matrix still has a factor; an indefinite one has none.
        let s = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        let f = psd_factor(&s).unwrap();
        assert!((&f * f.transpose() - &s).amax() < 1e-14);
        assert!(psd_factor(&DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0])).is_none());
    }

    /// Values with exact zeros, negative zeros and both signs, from a fixed sequence.
    fn values(n: usize, seed: u64) -> Vec<f64> {
        (0..n as u64)
            .map(|i| match (i * 7 + seed) % 11 {
                0 => 0.0,
                1 => -0.0,
                k => ((i * 7919 + seed * 104_729) % 1_000) as f64 / 137.0 - 3.5 + k as f64,
            })
            .collect()
    }

    #[test]
    fn batched_products_are_the_row_by_row_sums_bit_for_bit() {
        // Every tail of the run blocking (16, 8, 4, 2, 1), odd row counts (a last row alone),
        // zero entries skipped: each output is `((s + m₀ v₀) + m₁ v₁) + …` over the nonzero
        // entries, `s` zero or the output's value.
        for rows in [1, 2, 3, 5, 18] {
            for cols in [1, 2, 7, 18] {
                for runs in [1, 2, 3, 4, 7, 8, 15, 16, 17, 31, 50] {
                    let m = values(rows * cols, 1);
                    let v = values(cols * runs, 2);
                    let x0 = values(rows * runs, 3);
                    let reference = |start: bool| -> Vec<u64> {
                        let mut out = Vec::with_capacity(rows * runs);
                        for a in 0..rows {
                            for r in 0..runs {
                                let mut acc = if start { x0[a * runs + r] } else { 0.0 };
                                for b in 0..cols {
                                    if m[a * cols + b] != 0.0 {
                                        acc += m[a * cols + b] * v[b * runs + r];
                                    }
                                }
                                out.push(acc.to_bits());
                            }
                        }
                        out
                    };
                    let mut x = x0.clone();
                    batch_gemv(&m, rows, cols, &v, &mut x, runs);
                    let bits: Vec<u64> = x.iter().map(|v| v.to_bits()).collect();
                    assert_eq!(bits, reference(false), "{rows} × {cols}, {runs} runs");
                    if rows == cols {
                        let mut x = x0.clone();
                        batch_gemv_acc(&m, rows, &v, &mut x, runs);
                        let bits: Vec<u64> = x.iter().map(|v| v.to_bits()).collect();
                        assert_eq!(bits, reference(true), "{rows} × {cols}, {runs} runs, acc");
                    }
                }
            }
        }
        // A zero entry adds nothing — not even `+0` to a `−0` sum, nor `0 · ∞`.
        for runs in [1, 5, 16, 50] {
            let v: Vec<f64> = [f64::INFINITY; 50][..runs]
                .iter()
                .chain(&[1.5; 50][..runs])
                .copied()
                .collect();
            let mut x = vec![-0.0; runs];
            batch_gemv_acc(&[0.0], 1, &v, &mut x, runs);
            assert!(x.iter().all(|v| v.to_bits() == (-0.0f64).to_bits()));
            // Two rows at a time, each with its own zero.
            let mut x = vec![-0.0; 2 * runs];
            batch_gemv_acc(&[0.0, 2.0, 1.0, 0.0], 2, &v, &mut x, runs);
            assert!(x[..runs].iter().all(|&v| v == 3.0), "{x:?}");
            assert!(x[runs..].iter().all(|&v| v == f64::INFINITY), "{x:?}");
            batch_gemv(&[0.0, 2.0], 1, 2, &v, &mut x, runs);
            assert!(x[..runs].iter().all(|&v| v == 3.0), "{x:?}");
        }
    }
}
