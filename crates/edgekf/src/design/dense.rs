//! Dense kernels of the interior-point method: products split over two (or more) threads,
//! the inverse of a factorised SPD matrix, and the smallest eigenvalue of a congruence
//! `F⁻¹ A F⁻ᵀ` (the step length to the boundary of the PSD cone).
//!
//! Matrix products go to nalgebra's `gemm` (the `matrixmultiply` kernels, ≈ 25 GFlop/s on one
//! core of this machine); for large operands the columns of the result are split into chunks
//! computed on rayon's pool. Results do not depend on the number of threads: every column is
//! computed by the same kernel call on the same data.

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};
use rayon::prelude::*;

/// Below this many multiply–adds a product runs on the calling thread.
const PAR_FLOPS: usize = 1 << 22;

/// Column chunk width of parallel products (a multiple of the 4- and 8-wide kernels).
fn chunk_width(cols: usize) -> usize {
    let threads = rayon::current_num_threads().max(1);
    cols.div_ceil(2 * threads).max(64)
}

/// `a b`.
pub(crate) fn par_mul(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let (n, k) = a.shape();
    let cols = b.ncols();
    if n * k * cols < PAR_FLOPS {
        return a * b;
    }
    let mut out = DMatrix::zeros(n, cols);
    let w = chunk_width(cols);
    out.as_mut_slice()
        .par_chunks_mut(n * w)
        .enumerate()
        .for_each(|(c, chunk)| {
            let c0 = c * w;
            let nc = chunk.len() / n;
            let mut view = nalgebra::DMatrixViewMut::from_slice(chunk, n, nc);
            view.gemm(1.0, a, &b.columns(c0, nc), 0.0);
        });
    out
}

/// `aᵀ b` (a transposed copy of `a` and [`par_mul`]: nalgebra's `gemm_tr` runs column by column
/// through matrix–vector products, ≈ 10× slower than the packed kernels here).
pub(crate) fn par_mul_tr(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    par_mul(&a.transpose(), b)
}

/// Fills every column `c` of `h` by `fill(c, column)`, in parallel when `h` is large.
pub(crate) fn par_columns(h: &mut DMatrix<f64>, fill: impl Fn(usize, &mut [f64]) + Sync) {
    let n = h.nrows();
    if n == 0 {
        return;
    }
    if n * h.ncols() < 1 << 16 {
        h.as_mut_slice()
            .chunks_mut(n)
            .enumerate()
            .for_each(|(c, col)| fill(c, col));
    } else {
        h.as_mut_slice()
            .par_chunks_mut(n)
            .enumerate()
            .for_each(|(c, col)| fill(c, col));
    }
}

/// Below this order the direct nalgebra routines are used (blocking does not pay).
const BLOCK: usize = 128;

/// The inverse of a lower-triangular matrix (only its lower triangle is read), by recursive
/// blocking: `[A 0; B C]⁻¹ = [A⁻¹ 0; −C⁻¹ B A⁻¹  C⁻¹]`, so that almost all of the `n³/3`
/// multiply–adds are matrix products.
pub(crate) fn tri_inverse_lower(l: &DMatrix<f64>) -> DMatrix<f64> {
    let n = l.nrows();
    if n <= BLOCK {
        let mut inv = DMatrix::identity(n, n);
        l.solve_lower_triangular_mut(&mut inv);
        inv.fill_upper_triangle(0.0, 1);
        return inv;
    }
    let k = n / 2;
    let a = l.view((0, 0), (k, k)).into_owned();
    let b = l.view((k, 0), (n - k, k)).into_owned();
    let c = l.view((k, k), (n - k, n - k)).into_owned();
    let (ai, ci) = rayon::join(|| tri_inverse_lower(&a), || tri_inverse_lower(&c));
    let lower_left = -par_mul(&ci, &par_mul(&b, &ai));
    let mut inv = DMatrix::zeros(n, n);
    inv.view_mut((0, 0), (k, k)).copy_from(&ai);
    inv.view_mut((k, 0), (n - k, k)).copy_from(&lower_left);
    inv.view_mut((k, k), (n - k, n - k)).copy_from(&ci);
    inv
}

/// The Cholesky factorisation `A = F Fᵀ` of a symmetric positive definite matrix (only its lower
/// triangle is read), or `None` if `A` is not numerically positive definite. Above order 128 by
/// recursive blocking, `F₂₁ = A₂₁ F₁₁⁻ᵀ` and `F₂₂ = chol(A₂₂ − F₂₁ F₂₁ᵀ)`, so that the work is in
/// matrix products (nalgebra's unblocked factorisation runs at ≈ 3.5 GFlop/s here).
pub(crate) fn cholesky(a: DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    let n = a.nrows();
    if n <= BLOCK {
        return Cholesky::new(a);
    }
    let f = chol_lower(&a)?;
    Some(Cholesky::pack_dirty(f))
}

/// The lower Cholesky factor (upper triangle zero) by recursive blocking.
fn chol_lower(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = a.nrows();
    if n <= BLOCK {
        return Cholesky::new(a.clone()).map(|c| c.l());
    }
    let k = n / 2;
    let f11 = chol_lower(&a.view((0, 0), (k, k)).into_owned())?;
    let f11_inv = tri_inverse_lower(&f11);
    let a21 = a.view((k, 0), (n - k, k)).into_owned();
    let f21 = par_mul(&a21, &f11_inv.transpose());
    let mut a22 = a.view((k, k), (n - k, n - k)).into_owned();
    a22 -= par_mul(&f21, &f21.transpose());
    let f22 = chol_lower(&a22)?;
    let mut f = DMatrix::zeros(n, n);
    f.view_mut((0, 0), (k, k)).copy_from(&f11);
    f.view_mut((k, 0), (n - k, k)).copy_from(&f21);
    f.view_mut((k, k), (n - k, n - k)).copy_from(&f22);
    Some(f)
}

/// `A⁻¹` from the Cholesky factor `A = F Fᵀ`: `F⁻ᵀ F⁻¹`.
pub(crate) fn spd_inverse(chol: &Cholesky<f64, Dyn>) -> DMatrix<f64> {
    let n = chol.l_dirty().nrows();
    if n <= BLOCK {
        return symmetrise(chol.inverse());
    }
    let finv = tri_inverse_lower(chol.l_dirty());
    symmetrise(par_mul_tr(&finv, &finv))
}

/// `(F⁻¹)ᵀ` for the lower-triangular Cholesky factor `F` (so `x F⁻ᵀ` orthonormalises the
/// columns of `x` when `F Fᵀ = xᵀ x`).
pub(crate) fn inv_factor_transpose(chol: &Cholesky<f64, Dyn>) -> DMatrix<f64> {
    tri_inverse_lower(chol.l_dirty()).transpose()
}

/// `(a + aᵀ) / 2`.
pub(crate) fn symmetrise(mut a: DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    for c in 0..n {
        for r in c + 1..n {
            let v = 0.5 * (a[(r, c)] + a[(c, r)]);
            a[(r, c)] = v;
            a[(c, r)] = v;
        }
    }
    a
}

/// Above this order the step length uses Lanczos instead of a dense eigenvalue solver.
const LANCZOS_FROM: usize = 80;

/// Smallest eigenvalue of `F⁻¹ A F⁻ᵀ` for symmetric `A`, `F` the Cholesky factor in `chol`:
/// dense (two triangular solves and a tridiagonal eigensolver) up to order 80, Lanczos with
/// full reorthogonalisation above. The Lanczos value approximates the smallest eigenvalue from
/// above, so a step computed from it can overshoot the boundary slightly; the interior-point
/// method checks every step by a Cholesky factorisation and backtracks.
pub(crate) fn min_eig_congruence(chol: &Cholesky<f64, Dyn>, a: &DMatrix<f64>) -> f64 {
    let f = chol.l_dirty();
    let n = f.nrows();
    if n <= LANCZOS_FROM {
        let mut k = a.clone();
        f.solve_lower_triangular_mut(&mut k);
        let mut k = k.transpose();
        f.solve_lower_triangular_mut(&mut k);
        let k = symmetrise(k);
        return k.symmetric_eigenvalues().min();
    }
    let op = |v: &DVector<f64>| -> DVector<f64> {
        let mut u = v.clone();
        f.tr_solve_lower_triangular_mut(&mut u);
        let mut w = a * u;
        f.solve_lower_triangular_mut(&mut w);
        w
    };
    lanczos_min(n, op)
}

/// Smallest eigenvalue of the symmetric operator `op` on `Rⁿ` by Lanczos with full
/// reorthogonalisation, from a fixed start vector; at most 60 steps, stopped when the smallest
/// Ritz value moves by less than 1e-4 relative over 5 steps.
pub(crate) fn lanczos_min(n: usize, op: impl Fn(&DVector<f64>) -> DVector<f64>) -> f64 {
    const MAX_STEPS: usize = 60;
    // A fixed start vector with no special structure (a low-discrepancy sequence).
    let mut q = DVector::from_fn(n, |i, _| {
        ((i as f64 + 1.0) * 0.618_033_988_749_895).fract() - 0.5
    });
    q /= q.norm();
    let mut basis: Vec<DVector<f64>> = Vec::with_capacity(MAX_STEPS);
    let mut alpha = Vec::with_capacity(MAX_STEPS);
    let mut beta: Vec<f64> = Vec::with_capacity(MAX_STEPS);
    let mut history: Vec<f64> = Vec::new();
    for step in 0..MAX_STEPS.min(n) {
        let mut w = op(&q);
        let a = q.dot(&w);
        alpha.push(a);
        basis.push(q.clone());
        for _ in 0..2 {
            for b in &basis {
                let c = b.dot(&w);
                w.axpy(-c, b, 1.0);
            }
        }
        let b = w.norm();
        let k = alpha.len();
        let mut t = DMatrix::zeros(k, k);
        for i in 0..k {
            t[(i, i)] = alpha[i];
            if i + 1 < k {
                t[(i, i + 1)] = beta[i];
                t[(i + 1, i)] = beta[i];
            }
        }
        let ritz = t.symmetric_eigenvalues().min();
        history.push(ritz);
        let scale = alpha.iter().fold(0.0_f64, |m, v| m.max(v.abs())).max(b);
        if b <= 1e-12 * scale.max(f64::MIN_POSITIVE) {
            return ritz;
        }
        if step >= 10 {
            let old = history[history.len() - 6];
            if (old - ritz).abs() <= 1e-4 * ritz.abs().max(1e-12 * scale) {
                return ritz;
            }
        }
        beta.push(b);
        q = w / b;
    }
    *history.last().expect("at least one Lanczos step")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parallel_products_match_the_plain_ones() {
        let a = DMatrix::from_fn(300, 200, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
        let b = DMatrix::from_fn(200, 250, |i, j| ((i * 5 + j * 2) % 13) as f64 - 6.0);
        // Integer-valued entries: both products are exact.
        assert_eq!(par_mul(&a, &b), &a * &b);
        let c = DMatrix::from_fn(300, 250, |i, j| ((i + 3 * j) % 7) as f64 - 3.0);
        assert_eq!(par_mul_tr(&a, &c), a.transpose() * &c);
    }

    #[test]
    fn inverse_and_congruence() {
        let n = 40;
        let b = DMatrix::from_fn(n, n, |i, j| ((i * 13 + j * 7) % 17) as f64 / 17.0);
        let a = &b * b.transpose() + DMatrix::<f64>::identity(n, n);
        let chol = Cholesky::new(a.clone()).unwrap();
        let inv = spd_inverse(&chol);
        // ‖A A⁻¹ − I‖ at round-off times cond(A) (≈ 1e3 here).
        assert!((&a * &inv - DMatrix::<f64>::identity(n, n)).amax() < 1e-10);
        // F⁻¹ A F⁻ᵀ = I, so its smallest eigenvalue is 1; for −A it is −1.
        assert!((min_eig_congruence(&chol, &a) - 1.0).abs() < 1e-10);
        assert!((min_eig_congruence(&chol, &(-&a)) + 1.0).abs() < 1e-10);
    }

    #[test]
    fn blocked_inverses_and_lanczos() {
        let n = 333;
        let b = DMatrix::from_fn(n, n, |i, j| ((i * 13 + j * 7) % 17) as f64 / 17.0 - 0.4);
        let a = &b * b.transpose() / n as f64 + DMatrix::<f64>::identity(n, n);
        let chol = Cholesky::new(a.clone()).unwrap();
        // Blocked path (n > 128): A A⁻¹ = I to round-off times cond(A) (≤ 1e3 here).
        let inv = spd_inverse(&chol);
        assert!((&a * &inv - DMatrix::<f64>::identity(n, n)).amax() < 1e-11);
        // The blocked factorisation reproduces nalgebra's.
        let blocked = cholesky(a.clone()).unwrap();
        assert!((blocked.l() - chol.l()).amax() < 1e-12);
        // Lanczos path (n > 80) against the dense eigenvalues of F⁻¹ C F⁻ᵀ.
        let c = DMatrix::from_fn(n, n, |i, j| (((i + 1) * (j + 1)) % 23) as f64 / 23.0 - 0.5);
        let c = symmetrise(c);
        let f = chol.l();
        let finv = tri_inverse_lower(&f);
        let exact = symmetrise(&finv * &c * finv.transpose())
            .symmetric_eigenvalues()
            .min();
        let approx = min_eig_congruence(&chol, &c);
        // Lanczos converges to the extreme eigenvalue from above; 1e-3 relative is what the
        // step length needs (it is checked by a factorisation anyway).
        assert!(
            approx >= exact - 1e-9 && (approx - exact).abs() <= 1e-3 * exact.abs(),
            "{approx} vs {exact}"
        );
    }
}
