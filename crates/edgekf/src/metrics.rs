//! Performance measures as pure functions (the engine's named metrics are in
//! [`crate::sim::metrics`]).

use nalgebra::SMatrix;

/// Procrustes error of positions `z` against the configuration `p` (thesis Def. 2.9):
/// `min_{t, Ω ᵀΩ = I} ‖Z Ω + 1 tᵀ − P‖_F / N`, solved by centring both and the SVD of `Z_cᵀ P_c`
/// (orthogonal Procrustes; reflections allowed, as `Ωᵀ Ω = I` allows them).
///
/// `z(i, d)` returns coordinate `d` of agent `i`; `p` is agent-major.
pub fn procrustes<const D: usize>(n: usize, z: impl Fn(usize, usize) -> f64, p: &[f64]) -> f64 {
    procrustes_where::<D>(n, |_| true, z, p)
}

/// [`procrustes`] over the agents with `present(i)`, divided by their number (the agents that
/// left no longer count; Li & Rajan S3). `NaN` when fewer than two agents are present.
pub fn procrustes_where<const D: usize>(
    n: usize,
    present: impl Fn(usize) -> bool,
    z: impl Fn(usize, usize) -> f64,
    p: &[f64],
) -> f64 {
    let count = (0..n).filter(|&i| present(i)).count();
    if count < 2 {
        return f64::NAN;
    }
    let c = count as f64;
    let mut zc = [0.0; D];
    let mut pc = [0.0; D];
    for i in (0..n).filter(|&i| present(i)) {
        for d in 0..D {
            zc[d] += z(i, d) / c;
            pc[d] += p[i * D + d] / c;
        }
    }
    let mut m = SMatrix::<f64, D, D>::zeros();
    for i in (0..n).filter(|&i| present(i)) {
        for a in 0..D {
            for b in 0..D {
                m[(a, b)] += (z(i, a) - zc[a]) * (p[i * D + b] - pc[b]);
            }
        }
    }
    if !m.iter().all(|v| v.is_finite()) {
        return f64::NAN;
    }
    let Some(omega) = orthogonal_factor(&m) else {
        return f64::NAN;
    };
    let mut ss = 0.0;
    for i in (0..n).filter(|&i| present(i)) {
        for b in 0..D {
            let mut v = -(p[i * D + b] - pc[b]);
            for a in 0..D {
                v += (z(i, a) - zc[a]) * omega[(a, b)];
            }
            ss += v * v;
        }
    }
    ss.sqrt() / c
}

/// `U Vᵀ` from the SVD `M = U Σ Vᵀ`: the orthogonal matrix nearest to `M` (stack only); `None`
/// if the SVD does not converge (only for extreme inputs).
fn orthogonal_factor<const D: usize>(m: &SMatrix<f64, D, D>) -> Option<SMatrix<f64, D, D>> {
    match D {
        1 => Some(SMatrix::from_fn(
            |_, _| if m[(0, 0)] < 0.0 { -1.0 } else { 1.0 },
        )),
        2 => {
            let svd = nalgebra::Matrix2::from_fn(|i, j| m[(i, j)]).try_svd(
                true,
                true,
                f64::EPSILON,
                1000,
            )?;
            let o = svd.u? * svd.v_t?;
            Some(SMatrix::from_fn(|i, j| o[(i, j)]))
        }
        3 => {
            let svd = nalgebra::Matrix3::from_fn(|i, j| m[(i, j)]).try_svd(
                true,
                true,
                f64::EPSILON,
                1000,
            )?;
            let o = svd.u? * svd.v_t?;
            Some(SMatrix::from_fn(|i, j| o[(i, j)]))
        }
        _ => unreachable!("dimensions are 1, 2 or 3"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn procrustes_ignores_rigid_motions_and_sees_shape_changes() {
        let p = [0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0, 1.0];
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let moved: Vec<f64> = (0..4)
            .flat_map(|i| {
                [
                    c * p[2 * i] - s * p[2 * i + 1] + 5.0,
                    s * p[2 * i] + c * p[2 * i + 1] - 1.0,
                ]
            })
            .collect();
        assert!(procrustes::<2>(4, |i, d| moved[2 * i + d], &p) < 1e-14);
        let mirrored: Vec<f64> = (0..4).flat_map(|i| [-p[2 * i], p[2 * i + 1]]).collect();
        assert!(procrustes::<2>(4, |i, d| mirrored[2 * i + d], &p) < 1e-14);
        let mut bent = p;
        bent[7] += 0.4;
        let e = procrustes::<2>(4, |i, d| bent[2 * i + d], &p);
        assert!(e > 0.01 && e < 0.4 / 4.0 + 1e-12, "{e}");
    }
}
